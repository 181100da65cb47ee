"""Stand-ins for hubo-daemon: the robot side of ``hubo-ref`` / ``hubo-state`` without a robot.

One daemon contract (:class:`HuboDaemon`), two bodies behind it. Every 5 ms
(``HUBO_LOOP_PERIOD``, absolute deadlines on ``CLOCK_MONOTONIC``) the daemon reads every frame
put on ``hubo-ref`` since its last period, checks each is exactly ``sizeof(hubo_ref_t)``
(hubo-daemon exits on a mismatch; this one stops and records why), hands the newest to its body
and publishes the body's ``hubo_state`` with ``time`` = ``CLOCK_MONOTONIC`` seconds, as
hubo-daemon does: the period's scheduled start, so that two states are as far apart in
``time`` as the body stepped between them (a late period run at once to catch up, stamped when
it ran, showed a sim daemon's joint moving 2.5 times as fast as it did: round 30, an
"implausible measurement" in CI). The bodies: :class:`EchoBody` (``hubo hardware
fake-daemon``) puts the joints at hubo-daemon's reference filter output (mode 0,
``HUBO_REF_FILTER_LENGTH`` 40; mode 1 direct), an ideal motor, with a level IMU and zero
wrenches;
:class:`~hubo_cli.drivers.hubo_ach_sim_body.PhysicsBody` (``hubo hardware sim-daemon``) drives
the simulated robot's motors with that filter output and publishes what the simulator measures.
A controller talking to either closes its loop through real ach channels.

Each period's work (read, body, publish) is timed; a period whose work ends past its deadline is
an overrun, and :class:`DaemonStats` keeps their count and the loop times' distribution.

Faults on request (:mod:`hubo_cli.drivers.hubo_ach_faults`): the daemon withholds states
(``missing``) or publishes old ones (``late``); the body plays those of its motors (``frozen``,
``hot``) if it has motors to play them with.

Channels it finds already there are either another daemon's (a new state frame within
``LIVE_CHECK_S``: refused, two writers would fight) or left over from a daemon that died
without removing them (a kill -9, a crash): those are replaced by fresh ones (their frame sizes
and contents are not trusted) and removed at the end like the ones it created.
"""

from __future__ import annotations

import ctypes
import threading
import time
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.ach import ACH_EEXIST, ACH_MISSED_FRAME, ACH_OK, AchError, Libach
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, StateFrame
from hubo_cli.drivers.hubo_ach_faults import BODY_FAULTS, Fault
from hubo_cli.errors import DeviceError

REF_FRAMES = 64    # ring sizes of the channels this daemon creates
STATE_FRAMES = 16
LIVE_CHECK_S = 0.1  # 20 of hubo-daemon's periods: a live daemon publishes within it
LOOP_BIN_S = 1e-5   # loop times are kept as a histogram of 10 us bins (bounded memory) ...
LOOP_BINS = 10_000  # ... up to 0.1 s (longer ones count in the last bin)


@dataclass
class DaemonStats:
    """What the daemon saw.

    Attributes:
        periods: periods run.
        ref_frames: ``hubo-ref`` frames read (every one, in order).
        frame_sizes: how many frames of each size were read (bytes -> count).
        missed_ref_frames: frames overwritten in the ring before they were read.
        late_periods: periods that started more than one period late (the loop re-anchors its
            deadlines then rather than run a burst of periods).
        overruns: periods whose work (read, body, publish) ended past their deadline.
        loop_time_counts: the periods' work times, a histogram of :data:`LOOP_BIN_S` bins.
        faults: each requested fault and when it began (s after the first reference frame;
            None: not yet).
        states_withheld: periods whose state was not published (``missing``).
        states_late: periods that published an old state (``late``).
        error: why the daemon stopped early ("" if it did not).
    """

    periods: int = 0
    ref_frames: int = 0
    frame_sizes: dict[int, int] = field(default_factory=dict)
    missed_ref_frames: int = 0
    late_periods: int = 0
    overruns: int = 0
    loop_time_counts: np.ndarray = field(default_factory=lambda: np.zeros(LOOP_BINS, np.int64))
    faults: dict[str, float | None] = field(default_factory=dict)
    states_withheld: int = 0
    states_late: int = 0
    error: str = ""

    def loop_time_s(self, quantile: float) -> float | None:
        """A quantile (0-1) of the periods' work time (s, to the bin's upper edge); None before
        any period."""
        total = int(self.loop_time_counts.sum())
        if total == 0:
            return None
        k = int(np.searchsorted(np.cumsum(self.loop_time_counts), quantile * total))
        return (min(k, LOOP_BINS - 1) + 1) * LOOP_BIN_S

    def summary(self) -> dict:
        """The statistics as plain numbers (JSON): loop times in ms, overrun share in %."""
        median, p99 = self.loop_time_s(0.5), self.loop_time_s(0.99)
        return {"periods": self.periods, "ref_frames": self.ref_frames,
                "frame_sizes": self.frame_sizes, "missed_ref_frames": self.missed_ref_frames,
                "late_periods": self.late_periods, "overruns": self.overruns,
                "overrun_percent": (100.0 * self.overruns / self.periods if self.periods
                                    else 0.0),
                "loop_ms_median": None if median is None else median * 1e3,
                "loop_ms_p99": None if p99 is None else p99 * 1e3,
                "faults": dict(self.faults), "states_withheld": self.states_withheld,
                "states_late": self.states_late, "error": self.error or None}


class DaemonBody(ABC):
    """What stands behind the channels: it takes the reference in force each period and says
    what the robot's state is.

    Attributes:
        fault_kinds: the motor faults it plays (:meth:`begin_fault`).
    """

    fault_kinds: tuple[str, ...] = ()

    def begin_fault(self, fault: Fault) -> None:
        """Start a motor fault (one of :attr:`fault_kinds`) now."""
        raise ValueError(f"{type(self).__name__} has no motors to play {fault.kind!r}")

    @abstractmethod
    def advance(self, ref_rad: np.ndarray, mode: np.ndarray, period_s: float) -> None:
        """One period with the reference ``ref_rad`` (42, rad) in hubo-ach's ``mode`` per joint."""

    @abstractmethod
    def state(self, time_s: float) -> StateFrame:
        """The state to publish now (``time_s``: the daemon's clock)."""

    @property
    @abstractmethod
    def joints_rad(self) -> np.ndarray:
        """The joints' current positions (hubo-ach order, rad)."""

    @property
    def target_rad(self) -> np.ndarray:
        """The motors' reference now (the filter's output), which stays in force until a client
        sends one (by default the joints' positions)."""
        return self.joints_rad

    def close(self) -> None:
        """Release what the body holds (nothing by default)."""


class EchoBody(DaemonBody):
    """Ideal motors: the joints are at hubo-daemon's reference filter output (the fake daemon).

    Args:
        posture_rad: the 42 joints' start positions (hubo-ach order, rad).
        filter_length: ``HUBO_REF_FILTER_LENGTH``.
    """

    def __init__(self, posture_rad, filter_length: int = hubo_ach.REF_FILTER_LENGTH) -> None:
        posture = np.asarray(posture_rad, dtype=float)
        if posture.shape != (JOINT_COUNT,) or not np.all(np.isfinite(posture)):
            raise ValueError(f"posture must be {JOINT_COUNT} finite angles (rad)")
        self.filter_length = filter_length
        self._filtered = posture.copy()
        self._vel = np.zeros(JOINT_COUNT)

    def advance(self, ref_rad: np.ndarray, mode: np.ndarray, period_s: float) -> None:
        previous = self._filtered
        self._filtered = hubo_ach.reference_filter(previous, ref_rad, mode, self.filter_length)
        self._vel = (self._filtered - previous) / period_s

    def state(self, time_s: float) -> StateFrame:
        return StateFrame(time_s, np.zeros(3), np.zeros(3), np.zeros((4, 3)),
                          self._filtered.copy(), self._vel.copy())

    @property
    def joints_rad(self) -> np.ndarray:
        return self._filtered.copy()


class HuboDaemon:
    """hubo-daemon's channel behaviour around a :class:`DaemonBody`, in this thread
    (:meth:`run`) or a background one (:meth:`start`).

    Args:
        lib: libach.
        body: what stands behind the channels (closed with the daemon, or when it cannot
            start).
        ref_channel, state_channel: channel names (``hubo-ref``, ``hubo-state``).
        period_s: the loop period (``HUBO_LOOP_PERIOD``).
        create: create the channels (replacing ones left over from a dead daemon; refusing
            ones another daemon publishes) and unlink them on :meth:`close`.
        faults: faults to play (:mod:`hubo_cli.drivers.hubo_ach_faults`).
        scheduled: other things to do once, on the faults' clock: (seconds after the first
            reference frame, a function of no arguments), e.g. place a wall.

    Attributes:
        created: the channels this daemon created (and removes at the end).
        replaced: those of them that were left over from an earlier daemon.

    Raises:
        DeviceError: another daemon publishes the state channel.
        ValueError: a motor fault the body cannot play.
    """

    def __init__(self, lib: Libach, body: DaemonBody, ref_channel: str = hubo_ach.CHAN_REF,
                 state_channel: str = hubo_ach.CHAN_STATE,
                 period_s: float = hubo_ach.LOOP_PERIOD_S, create: bool = True,
                 faults: tuple[Fault, ...] = (),
                 scheduled: tuple[tuple[float, Callable[[], None]], ...] = ()) -> None:
        self.lib = lib
        self.body = body
        self.faults = tuple(faults)
        self.ref_channel, self.state_channel = ref_channel, state_channel
        self.period_s = period_s
        self.stats = DaemonStats()
        self.created: list[str] = []
        self.replaced: list[str] = []
        self._ref_chan = self._state_chan = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ref = body.target_rad
        self._mode = np.zeros(JOINT_COUNT, dtype=np.int16)
        self._buffer = (ctypes.c_uint8 * (hubo_ach.REF_SIZE + 256))()
        self._ref_periods: int | None = None  # periods since the first reference frame
        self._pending = list(self.faults)
        self._scheduled = list(scheduled)
        self.stats.faults = {f.describe(): None for f in self.faults}
        late = [round(f.by_s / period_s) for f in self.faults if f.kind == "late"]
        self._history: deque[bytes] = deque(maxlen=max(late, default=0) + 1)
        try:
            unplayable = [f.kind for f in self.faults
                          if f.kind in BODY_FAULTS and f.kind not in body.fault_kinds]
            if unplayable:
                raise ValueError(f"{type(body).__name__} has no motors to play "
                                 f"{', '.join(unplayable)}")
            if create:
                self._create_channels()
            self._ref_chan = lib.open(ref_channel)
            self._state_chan = lib.open(state_channel)
            self._drain()  # frames left on hubo-ref by an earlier writer are not this run's
            self._publish()
        except BaseException:  # the channels this daemon created do not outlive it
            self.close()
            raise

    # ------------------------------------------------------------------ running
    def start(self) -> HuboDaemon:
        """Run the loop in a background thread (again after :meth:`stop`); returns self."""
        self.stop()
        self._stop.clear()
        self._thread = threading.Thread(target=self.run, name="hubo-daemon", daemon=True)
        self._thread.start()
        return self

    def run(self, duration_s: float | None = None) -> DaemonStats:
        """Run the loop here until :meth:`stop` (or for ``duration_s``)."""
        stats = self.stats
        next_s = time.monotonic()
        end_s = None if duration_s is None else next_s + duration_s
        while not self._stop.is_set() and (end_s is None or next_s < end_s):
            began_s = time.monotonic()
            self.period(next_s)
            if stats.error:
                break
            done_s = time.monotonic()
            stats.loop_time_counts[min(int((done_s - began_s) / LOOP_BIN_S), LOOP_BINS - 1)] += 1
            next_s += self.period_s
            delay = next_s - done_s
            if delay > 0:
                time.sleep(delay)
            else:
                stats.overruns += 1
                if delay < -self.period_s:
                    stats.late_periods += 1
                    next_s = done_s  # re-anchor rather than burst
        return stats

    def period(self, time_s: float | None = None) -> None:
        """One daemon period: read the references, advance the body, publish the state stamped
        ``time_s`` (``CLOCK_MONOTONIC`` s; None: now). A failure stops the daemon with
        :attr:`DaemonStats.error` set (as hubo-daemon exits)."""
        try:
            self._read_refs()
        except AchError as exc:
            self.stats.error = str(exc)
        if self.stats.error:
            return
        self._begin_faults()
        self.body.advance(self._ref, self._mode, self.period_s)
        self._publish(time_s)
        self.stats.periods += 1
        if self._ref_periods is not None:
            self._ref_periods += 1

    def fault_time_s(self) -> float | None:
        """The faults' clock: the body's time since the first reference frame (periods run
        times the period, s: a loaded machine's late periods do not advance it, so a fault
        meets the simulated robot where it would on a quiet one); None before that frame."""
        return None if self._ref_periods is None else self._ref_periods * self.period_s

    def request_stop(self) -> None:
        """Ask the loop to end after the current period (safe from a signal handler)."""
        self._stop.set()

    def stop(self) -> None:
        """Stop the loop thread (if any) and wait for it."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def close(self) -> None:
        """Stop, close the channels, unlink the ones this daemon created, close the body."""
        self.stop()
        for channel in (self._ref_chan, self._state_chan):
            if channel is not None:
                channel.close()
        self._ref_chan = self._state_chan = None
        self.unlink()
        self.body.close()

    def unlink(self) -> None:
        """Remove the channels this daemon created."""
        for name in self.created:
            self.lib.unlink(name)
        self.created = []

    def __enter__(self) -> HuboDaemon:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def joints_rad(self) -> np.ndarray:
        """The joints' current positions (hubo-ach order, rad)."""
        return self.body.joints_rad

    # ------------------------------------------------------------------ internals
    def _create_channels(self) -> None:
        if channel_published(self.lib, self.state_channel):
            raise DeviceError(f"another daemon publishes {self.state_channel}: two would "
                              "fight over the robot",
                              hint="stop it first, or give this one other channels "
                                   "(--ach-ref, --ach-state)")
        for name, frames, size in ((self.ref_channel, REF_FRAMES, hubo_ach.REF_SIZE),
                                   (self.state_channel, STATE_FRAMES, hubo_ach.STATE_SIZE)):
            try:
                try:
                    self.lib.create(name, frames, size)
                except AchError as exc:
                    if exc.status != ACH_EEXIST:
                        raise
                    self.lib.unlink(name)  # left over from a dead daemon: take it over
                    self.lib.create(name, frames, size)
                    self.replaced.append(name)
            except AchError:
                self.unlink()
                raise
            self.created.append(name)

    def _drain(self) -> None:
        while self._ref_chan.get(self._buffer, last=True)[0] in (ACH_OK, ACH_MISSED_FRAME):
            pass

    def _read_refs(self) -> None:
        while True:
            status, size = self._ref_chan.get(self._buffer, last=False)
            if status not in (ACH_OK, ACH_MISSED_FRAME):
                return
            stats = self.stats
            stats.ref_frames += 1
            stats.frame_sizes[size] = stats.frame_sizes.get(size, 0) + 1
            if status == ACH_MISSED_FRAME:
                stats.missed_ref_frames += 1
            if size != hubo_ach.REF_SIZE:
                stats.error = (f"a {self.ref_channel} frame of {size} bytes; hubo_ref_t is "
                               f"{hubo_ach.REF_SIZE} (hubo-daemon exits here)")
                return
            frame = hubo_ach.decode_ref(bytes(self._buffer)[:size])
            if not np.all(np.isfinite(frame.ref_rad)):
                stats.error = f"a {self.ref_channel} frame with a non-finite reference"
                return
            self._ref, self._mode = frame.ref_rad, frame.mode
            if self._ref_periods is None:
                self._ref_periods = 0

    def _begin_faults(self) -> None:
        t_s = self.fault_time_s()
        if t_s is None:
            return
        for fault in [f for f in self._pending if t_s >= f.at_s]:
            self._pending.remove(fault)
            if fault.kind in BODY_FAULTS:
                self.body.begin_fault(fault)
            self.stats.faults[fault.describe()] = round(t_s, 4)
        for item in [item for item in self._scheduled if t_s >= item[0]]:
            self._scheduled.remove(item)
            item[1]()

    def _publish(self, time_s: float | None = None) -> None:
        data = hubo_ach.encode_state(self.body.state(
            time.clock_gettime(time.CLOCK_MONOTONIC) if time_s is None else time_s))
        self._history.append(data)
        t_s = self.fault_time_s()
        if t_s is not None:
            for fault in self.faults:
                if fault.kind == "missing" and fault.active(t_s):
                    self.stats.states_withheld += 1
                    return
                if fault.kind == "late" and fault.active(t_s):
                    k = round(fault.by_s / self.period_s)  # periods ago
                    data = self._history[max(0, len(self._history) - 1 - k)]
                    self.stats.states_late += 1
                    break
        self._state_chan.put(data)


class FakeHuboDaemon(HuboDaemon):
    """The daemon with ideal motors at the reference filter's output (:class:`EchoBody`).

    Args:
        lib: libach.
        posture_rad: the 42 joints' start positions (hubo-ach order, rad).
        filter_length: ``HUBO_REF_FILTER_LENGTH``; the other arguments as :class:`HuboDaemon`.
    """

    def __init__(self, lib: Libach, posture_rad, ref_channel: str = hubo_ach.CHAN_REF,
                 state_channel: str = hubo_ach.CHAN_STATE,
                 period_s: float = hubo_ach.LOOP_PERIOD_S,
                 filter_length: int = hubo_ach.REF_FILTER_LENGTH, create: bool = True) -> None:
        super().__init__(lib, EchoBody(posture_rad, filter_length), ref_channel, state_channel,
                         period_s, create)


def channel_published(lib: Libach, name: str) -> bool:
    """Whether a new frame comes on channel ``name`` within :data:`LIVE_CHECK_S` (a live
    writer); False when the channel does not exist or cannot be read (a writer killed in the
    middle of a put can leave it so)."""
    buffer = (ctypes.c_uint8 * (1 << 16))()  # any old frame size fits
    try:
        with lib.open(name) as channel:
            channel.get(buffer, last=True)  # what is there already is not news
            status, _ = channel.get(buffer, last=True, wait_s=LIVE_CHECK_S)
    except AchError:
        return False
    return status in (ACH_OK, ACH_MISSED_FRAME)
