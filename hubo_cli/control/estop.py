"""The EmergencyStopper with motion reverting (paper eq. 15, hrpsys-base EmergencyStopper).

States (hrpsys' table, plus the revert of the paper):

========  ==============================================================================
release   pass the input through
stop      latched at t_emer: go back to the input of t_emer - T1 (``revert_s``), taking at
          least T2 (``stop_s``), then
hold      output that posture until :meth:`EmergencyStopper.release` is called
recover   after release, join the live input again; re-planned every period so that it
          arrives no sooner than ``recover_s`` (2.5 s) after the release, then ``release``
finish    latched while the target's phase stops itself (a walk in mid-step: the store's
          :data:`~hubo_cli.control.phase.PHASE_STOP`): pass the phase's own stopping motion
          through until it says it stands (then ``hold`` that posture); a phase that does not
          settle within its ``within_s`` (at most ``MAX_FINISH_S``) or stops saying how it
          stops is braked (``stop``, as the freeze preset) and held where it came to rest;
          released while it passes the phase's motion, ``release`` at once (the output is
          that motion: nothing to blend, and a blend would play it late)
========  ==============================================================================

Reverting a walk in mid-step does not keep the robot up (the swing foot comes back down where
it lifted off while the centre of mass travels on), so a walking phase finishes its step into
a double-support stance instead. Which stop a run gets is not a choice a task file or a
target can make: every latch is still this stopper's (logged as a ``stop`` event, flagged
``estop``, held until released); the phase only supplies the motion into the stance, within a
deadline this stopper enforces, and says so in the log (mode code 4) and in the run's events (a
``finish`` event beside the ``stop``).

Every transition is a jerk-limited ruckig trajectory started from the output's own position,
velocity and acceleration (:class:`~hubo_cli.motion.tracker.JointTracker`), so the revert obeys the
joint limits: when the limits cannot turn the motion around within T2 the revert takes longer
and still ends exactly on the posture of t_emer - T1 (no overshoot past it). The revert first
brakes to rest at the emergency braking limits (as the wrist-torque stop, flag
``estop-brake``), then goes back under the trajectories' limits, by t_emer + T2 where they
allow it: braking at the trajectories' 0.8 rad/s^2 and 4 rad/s^3, an arm moving at 0.75
rad/s ran on 0.5 rad for a second before turning, and a hand that had met an object where the
plan did not expect it (the valve seen 195 mm to the left) kept pushing it and tipped the
robot. The freeze preset
(T1 = T2 = one period, hrpsys' default) brakes as hard as the limits allow and holds where it
stopped.

A stop on the wrist torque relieves the wrist instead: the load on the tool comes from driving
it through the material, and eq. 15's revert, which drives the tool back along its path within
T2, adds load instead of removing it. So the ``relieve`` stop brakes every joint as fast as the
emergency braking limits allow (as the revert does before it goes back)
(:meth:`JointLimits.for_emergency_brake`; flag ``estop-brake`` lets the limiter admit them),
then follows the path the store's :data:`~hubo_cli.control.keys.WRIST_RELIEF` returns for the
braked posture (the task backs the tool out of the wall along its normal, checked against the
wall) on a minimum-jerk
time scale of at least ``RELIEF_S`` within those limits, and holds its end; without a relief
(or when it returns None) it holds where it braked.

Wrench references (eq. 15 for forces; option ``wrench_reference``): the stopper reads the
hand wrenches the motion asks for (:data:`~hubo_cli.control.wrench.HAND_WRENCH_PLAN`) and
passes them on (:data:`~hubo_cli.control.wrench.HAND_WRENCH_REF`, what the ImpedanceController
pushes with). A stop that reverts the motion reverts them with it: they blend on a minimum-jerk
profile over T2 to the references of t_emer - T1; a freeze or a wrist-torque stop blends them
to zero over T2 (the hand stops pushing). They hold while the stop holds, and after a release
blend back to the live references over the recovery time. A hard stop (a ``hard`` request,
which the ``hard-estop`` instance downstream answers by freezing the joints) blends them to
zero over this stopper's T2 too, and holds zero until the release: the hard stopper sits after
the ImpedanceController, so the hand cannot move to meet a force while it holds, and a held
nonzero reference would have force tracking move the spring's centre toward the wall all the
while (up to ``max_offset_m``, pushed in once released); at zero the centre decays and the
release starts from no push, as after a freeze. The wrench references live in this stopper
only: without it (``--no-estop``) they pass from the plan to the controller unreverted.

The flag is latched: any request from an enabled source (``cycle.estop_requests``, a call to
:meth:`stop` -- e.g. from the operator's key or, through :func:`stop_on_signal`, a signal -- or
a wrist torque above ``model.safety["wrist_torque_limit_nm"]``: the bending moment of the
estimate's wrist wrenches, the hand's and the tool's weight and inertia removed, ``WRENCHES``)
stops; only an explicit release lets go, and a request that is still present in the next period
stops again.
The pipeline uses two instances: ``estop`` early in the chain and ``hard-estop`` after the
balance and collision layers; ``estop`` writes its mode every period
(:data:`~hubo_cli.control.keys.STOP_MODE`, what a target reads of it).
"""

from __future__ import annotations

import math
import signal
from collections import deque
from collections.abc import Callable, Iterable

import numpy as np

from hubo_cli.control.keys import STOP_MODE, WRIST_RELIEF
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.phase import PHASE_STOP, PhaseStop
from hubo_cli.control.status import SafetyEvent, StopperStatus
from hubo_cli.control.stop_choice import SOFT_SOURCES
from hubo_cli.control.wrench import HAND_WRENCH_PLAN, HAND_WRENCH_REF, wrench_of
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.geometry import (
    MIN_JERK_PEAK_ACCELERATION,
    MIN_JERK_PEAK_JERK,
    MIN_JERK_PEAK_VELOCITY,
    min_jerk,
)
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import JointLimits, hold_nan
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.state import RobotState

HARD_SOURCES = ("hard",)
RECOVER_S = 2.5          # hrpsys default_recover_time
RELIEF_S = 0.25          # the shortest move along the relief path (s)
WRIST_SENSORS = ("right-wrist", "left-wrist")

MODES = ("release", "stop", "hold", "recover", "finish")
LATCHED_MODES = ("stop", "hold", "finish")  # the stop holds the robot (recover: blending back)
MAX_FINISH_S = 5.0       # a phase stopping itself settles within this long, or is braked
RELIEVE_SOURCES = frozenset({"wrist-torque"})  # stops that brake hard and relieve the tool
BRAKE_FLAG = "estop-brake"  # the stopper brakes at the emergency limits this period


def wrist_torque_nm(wrench: np.ndarray | None) -> float:
    """The bending moment on the wrist (N m): |(m_x, m_y)| of a wrist wrench in the sensor's
    frame, whose z runs along the forearm (the two moments across the forearm that Hubo's wrist
    sensor reads); 0 when the sensor is absent."""
    return 0.0 if wrench is None else math.hypot(float(wrench[3]), float(wrench[4]))
MODE_CODE = {name: i for i, name in enumerate(MODES)}


class WrenchRevert:
    """The stopper's wrench references: their history over T1 and the blend of a stop, a hold
    and a recovery (see the module docstring). Wrenches are arm -> 6-vector (N, N m)."""

    def __init__(self, history_len: int) -> None:
        self.history: deque[dict] = deque([{}] * history_len, maxlen=history_len)
        self.out: dict[str, np.ndarray] = {}
        self._from: dict[str, np.ndarray] = {}
        self._to: dict[str, np.ndarray] | None = {}  # None: the live references
        self._t0_s = 0.0
        self._blend_s = 0.0

    def clear(self) -> None:
        self.history.extend([{}] * self.history.maxlen)
        self.out, self._from, self._to = {}, {}, {}

    def start(self, t_s: float, blend_s: float, to: dict | None) -> None:
        """Blend from the current output to ``to`` (None: the live references) over
        ``blend_s`` from ``t_s``."""
        self._from = {arm: w.copy() for arm, w in self.out.items()}
        self._to = to
        self._t0_s, self._blend_s = t_s, blend_s

    def update(self, t_s: float, live: dict | None, mode: str) -> dict[str, np.ndarray]:
        """This period's references for the stopper in ``mode`` with the motion's ``live``."""
        now = {}
        for arm in (live or {}):
            w = wrench_of(live, arm)
            if w is not None:
                now[arm] = w.copy()
        self.history.append(now)
        if mode == "release":
            self.out = now
            return self.out
        to = now if self._to is None else self._to
        u = 1.0 if self._blend_s <= 0 else float(min_jerk(min(1.0, max(
            0.0, (t_s - self._t0_s) / self._blend_s))))
        zero = np.zeros(6)
        self.out = {arm: (1.0 - u) * self._from.get(arm, zero) + u * to.get(arm, zero)
                    for arm in set(self._from) | set(to)}
        return self.out


class EmergencyStopper(Module):
    """Latched emergency stop that reverts the motion (eq. 15) and holds until released.

    Args:
        model: the robot model (limits, wrist torque limit).
        dt_s: the control period (s).
        revert_s: T1, how far back the stop posture lies (s); default 0.5.
        stop_s: T2, the shortest time to reach it (s); default 0.5.
        recover_s: blend time back to the live input after release (s).
        sources: request names this instance reacts to (see SOFT_SOURCES, HARD_SOURCES).
        name: module name (``estop`` or ``hard-estop``); it prefixes the log column.
        limits: override the model's limits (tests).
        wrist_torque_limit_nm: override the model's wrist torque limit (N m).
        wrench_reference: pass the hand wrench references on, reverted with the motion (reads
            ``HAND_WRENCH_PLAN``, writes ``HAND_WRENCH_REF``; see the module docstring).

    Flags: ``estop`` while stopping, finishing or holding, ``recovering`` while blending
    back, ``estop-brake`` while it brakes at the emergency limits (a revert turning, a
    wrist-torque stop braking and relieving, a finish that lost its phase or its deadline).
    Info: ``<name>_mode_code`` (the index in :data:`MODES`: 0 release, 1 stop, 2 hold,
    3 recover, 4 finish), ``wrist_torque_nm``.

    Store: the wrist-torque stop follows ``WRIST_RELIEF`` (called once it has braked to rest,
    with the braked joint command; not written: hold where braked); ``estop`` writes
    ``STOP_MODE``.
    """

    def __init__(self, model: RobotModel, dt_s: float, revert_s: float = 0.5,
                 stop_s: float = 0.5, recover_s: float = RECOVER_S,
                 sources: tuple[str, ...] | set[str] = SOFT_SOURCES, name: str = "estop",
                 limits: JointLimits | None = None,
                 wrist_torque_limit_nm: float | None = None,
                 wrench_reference: bool = False) -> None:
        self.name = name
        self.limits = limits or JointLimits.from_model(model)
        self.dt_s = float(dt_s)
        self.revert_s = max(float(revert_s), self.dt_s)
        self.stop_s = max(float(stop_s), self.dt_s)
        self.recover_s = float(recover_s)
        self.sources = frozenset(sources)
        self.hard_sources = frozenset(HARD_SOURCES) - self.sources  # another instance's stops
        self.wrist_torque_limit_nm = float(
            model.safety.get("wrist_torque_limit_nm", np.inf) if wrist_torque_limit_nm is None
            else wrist_torque_limit_nm)
        self._key = name.replace("-", "_")
        self._mode_column = f"{self._key}_mode_code"
        self.log_columns = (self._mode_column,)
        self._wrist_torque = "wrist-torque" in self.sources
        if self._wrist_torque:
            self.log_columns += ("wrist_torque_nm",)
            self.reads, self.follows = (WRENCHES,), (WRIST_RELIEF,)
        if wrench_reference:
            self.reads, self.writes = self.reads + (HAND_WRENCH_PLAN,), (HAND_WRENCH_REF,)
        self._mode_key = STOP_MODE if name == "estop" else None
        if self._mode_key is not None:
            self.writes += (self._mode_key,)
            self.follows += (PHASE_STOP,)  # only the soft stopper lets a phase stop itself
        self.tracker = JointTracker(self.limits, self.dt_s)
        self.brake_tracker = JointTracker(self.limits.for_emergency_brake(model), self.dt_s)
        self._path = np.zeros((1, self.limits.size))  # the relief path being played
        self._path_s = np.zeros(1)  # its normalised arc positions (0 .. 1)
        self._path_periods = 1
        self._path_k = 0
        self._history_len = max(1, int(round(self.revert_s / self.dt_s))) + 1
        self.wrenches = WrenchRevert(self._history_len) if wrench_reference else None
        self.events: list[SafetyEvent] = []
        self._clear(np.zeros(self.limits.size))
        hold_nan(self.last_in, self.last_in, self.out1.copy())  # compile now, not in a period

    @classmethod
    def freeze(cls, model: RobotModel, dt_s: float, **options) -> EmergencyStopper:
        """The hrpsys default: T1 = T2 = one period (brake to a stop, hold there)."""
        return cls(model, dt_s, revert_s=dt_s, stop_s=dt_s, **options)

    @property
    def is_freeze(self) -> bool:
        return self.revert_s <= self.dt_s * 1.5

    def _clear(self, q: np.ndarray) -> None:
        self.mode = "release"
        self.history: deque[np.ndarray] = deque([q.copy()] * self._history_len,
                                                maxlen=self._history_len)
        self.last_in = q.copy()
        self.out1 = q.copy()
        self.out2 = q.copy()
        self.out3 = q.copy()
        self.hold_rad = q.copy()
        self.t_emer_s: float | None = None
        self.t_recover_end_s = 0.0
        self.t_finish_end_s = 0.0
        self._pending: set[str] = set()
        self._release = False
        self._brake_only = False
        self._relieving: str | None = None  # "brake", then "move" (wrist-torque stops)
        self._turning = False  # a revert still braking to rest (at the brake limits)
        self._relief_allowed = True  # a relief brake may play the store's WRIST_RELIEF
        self._hard_wrench: str | None = None  # a hard stop's wrenches: "stop", then "recover"
        self._hard_recover_end_s = 0.0
        if self.wrenches is not None:
            self.wrenches.clear()

    # ------------------------------------------------------------------ commands
    def stop(self, source: str = "operator") -> None:
        """Request a stop from ``source`` (latched at the next period if the source is enabled)."""
        self._pending.add(source)

    def release(self) -> None:
        """Release a latched stop: the output blends back to the live input."""
        self._release = True

    @property
    def stopped(self) -> bool:
        """True while stopping, holding or blending back."""
        return self.mode != "release"

    # ------------------------------------------------------------------ module
    def status(self) -> StopperStatus:
        """What a viewer shows of this stopper."""
        stops = [e for e in self.events if e.kind == "stop"]
        return StopperStatus(self.mode, tuple(sorted(self.sources)), len(stops),
                             stops[-1].sources if stops else ())

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        """Start released, passing ``q_rad`` through (deactivation releases, as in hrpsys)."""
        q = np.where(np.isfinite(q_rad), q_rad, state.q_rad).astype(float)
        self._clear(q)
        self.tracker.reset(q)

    def _requests(self, state: RobotState, cycle: Cycle) -> set[str]:
        wanted = set(self.sources.intersection(cycle.estop_requests))
        if self._pending:
            wanted |= self._pending & self.sources
            self._pending.clear()
        if self._wrist_torque:
            right, left = WRIST_SENSORS
            wrenches = cycle.store[WRENCHES]  # the hand's and the tool's weight and inertia removed
            torque = max(wrist_torque_nm(wrenches.get(right)), wrist_torque_nm(wrenches.get(left)))
            cycle.info["wrist_torque_nm"] = torque
            if torque > self.wrist_torque_limit_nm:
                wanted.add("wrist-torque")
                cycle.estop_requests.add("wrist-torque")
        return wanted

    def _output_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dt = self.dt_s
        v = (self.out1 - self.out2) / dt
        a = (self.out1 - 2 * self.out2 + self.out3) / dt**2
        return self.out1.copy(), v + 0.5 * a * dt, a

    def _latch(self, t_s: float, sources: set[str], phase_stop: PhaseStop | None) -> None:
        recovering = self.mode == "recover"
        self.tracker.reset(*self._output_state())
        self.t_emer_s = t_s
        self.events.append(SafetyEvent(t_s, "stop", tuple(sorted(sources))))
        if isinstance(phase_stop, PhaseStop) and not recovering:
            # the phase stops itself (a walk finishes its step): pass it through, see finish;
            # the summary's events say so beside the stop
            self.events.append(SafetyEvent(t_s, "finish", ()))
            self.mode, self._turning = "finish", False
            self.t_finish_end_s = t_s + min(max(float(phase_stop.within_s), 0.0),
                                            MAX_FINISH_S)
            self._relieving = None
            if self.wrenches is not None:
                self.wrenches.start(t_s, self.stop_s, {})
            return
        self.mode, self._relief_allowed = "stop", True
        # while blending back, the input of T1 ago may be far from the output: stop in place
        self._brake_only = self.is_freeze or recovering
        self.hold_rad = self.history[0].copy()
        self._relieving = None
        if sources & RELIEVE_SOURCES:
            self._relieving = "brake"
        # a revert or a relief turns the motion at the brake limits, from the output's motion
        # (reset at every latch: a relief also brakes on it when the stop only brakes)
        self.brake_tracker.reset(*self._output_state())
        self._turning = not (self._brake_only or self._relieving)
        if self.wrenches is not None:  # eq. 15 for the wrenches: back to t_emer - T1, or off
            back = self._brake_only or self._relieving or self._hard_wrench == "stop"
            self.wrenches.start(t_s, self.stop_s, {} if back else dict(self.wrenches.history[0]))

    def _hard_wrenches(self, cycle: Cycle) -> None:
        """A hard request blends the wrench references to zero over T2 and holds them there;
        a release blends them back to the live ones over the recovery time."""
        if self.hard_sources & cycle.estop_requests:
            if self._hard_wrench != "stop":
                self._hard_wrench = "stop"
                self.wrenches.start(cycle.t_s, self.stop_s, {})
        elif self._release and self._hard_wrench == "stop":
            self._hard_wrench = "recover"
            self._hard_recover_end_s = cycle.t_s + self.recover_s
            if self.mode not in ("stop", "hold"):  # else the soft stop's release blends back
                self.wrenches.start(cycle.t_s, self.recover_s, None)

    def _wrench_mode(self, t_s: float) -> str:
        """The mode the wrench references follow: this stopper's, or a hard stop's."""
        if self._hard_wrench == "stop":
            return "stop"
        if self._hard_wrench == "recover":
            if t_s < self._hard_recover_end_s or self.mode != "release":
                return "recover"
            self._hard_wrench = None
        return self.mode

    def _finish(self, q_in: np.ndarray, phase_stop: PhaseStop | None, t_s: float) -> np.ndarray:
        """One period of ``finish``: the phase's stopping motion ``q_in`` passes; once the
        phase stands, hold it; past the deadline, or when the phase no longer says how it
        stops, brake from the output's motion and hold where it comes to rest."""
        if isinstance(phase_stop, PhaseStop) and phase_stop.settled:
            self.hold_rad = q_in.copy()
            self.mode = "hold"
            return q_in
        if isinstance(phase_stop, PhaseStop) and t_s <= self.t_finish_end_s:
            return q_in
        lost = not isinstance(phase_stop, PhaseStop)
        self.events.append(SafetyEvent(t_s, "finish-lost" if lost else "finish-deadline", ()))
        # brake at the emergency limits (as a revert turns), then hold where it comes to rest
        self.brake_tracker.reset(*self._output_state())
        self._brake_only, self._relieving, self._turning = True, "brake", False
        self._relief_allowed = False  # a walk's legs: brake and hold, no wrist relief
        self.mode = "stop"
        return self._relieve(None)

    def _relieve(self, relief: Callable[[np.ndarray], np.ndarray | None] | None) -> np.ndarray:
        """One period of a wrist-torque stop: brake at the emergency limits, then play the
        ``relief`` path (the store's WRIST_RELIEF), then hold its end."""
        tracker = self.brake_tracker
        if self._relieving == "brake":
            out = tracker.brake()
            if not tracker.at_rest:
                return out
            path = None if relief is None else relief(out.copy())
            if path is None or not len(path) or not np.all(np.isfinite(path)):
                self.hold_rad = out.copy()
                self.mode, self._relieving = "hold", None
                return out
            self._start_path(np.vstack([out, self.limits.clip(np.atleast_2d(path))]))
        self._path_k += 1
        u = min_jerk(self._path_k / self._path_periods)
        out = np.array([np.interp(u, self._path_s, joint) for joint in self._path.T])
        if self._path_k >= self._path_periods:
            out = self.hold_rad.copy()
            self.mode, self._relieving = "hold", None
        return out

    def _start_path(self, path: np.ndarray) -> None:
        """Play ``path`` (from rest to rest) in the shortest multiple of the period, at least
        RELIEF_S, whose minimum-jerk peaks keep every joint within the braking limits."""
        steps = np.abs(np.diff(path, axis=0))
        arc = np.concatenate([[0.0], np.cumsum(steps.max(axis=1))])  # no joint moves further
        moving = steps.sum(axis=0) > 0
        lim = self.brake_tracker.limits
        if arc[-1] > 0:
            v, a, j = (x[moving].min() for x in (lim.velocity_rad_s, lim.acceleration_rad_s2,
                                                  lim.jerk_rad_s3))
            duration = max(RELIEF_S, MIN_JERK_PEAK_VELOCITY * arc[-1] / v,
                           math.sqrt(MIN_JERK_PEAK_ACCELERATION * arc[-1] / a),
                           math.cbrt(MIN_JERK_PEAK_JERK * arc[-1] / j))
        else:
            duration = self.dt_s
        self._path = path
        self._path_s = arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, len(path))
        self._path_periods = max(1, math.ceil(duration / self.dt_s - 1e-9))
        self._path_k = 0
        self.hold_rad = path[-1].copy()
        self._relieving = "move"

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q_in = np.empty(self.last_in.shape[0])
        hold_nan(np.ascontiguousarray(q_rad, dtype=float), self.last_in, q_in)
        last_in, self.last_in = self.last_in, q_in
        self.history.append(q_in)
        requests = self._requests(state, cycle)
        phase_stop = None if self._mode_key is None else cycle.store.get(PHASE_STOP)
        if requests and self.mode in ("release", "recover"):
            self._latch(cycle.t_s, requests, phase_stop)
        elif self._release and self.mode in ("stop", "hold", "finish"):
            if self.mode == "finish":
                # the output is the phase's own motion: join it at once (a blend would play
                # that open-loop motion late, a second stop meanwhile would only brake it)
                self.mode = "release"
            else:
                # blend back from the output, whoever made it (the phase's stance held, the
                # brake tracker turning, braking or relieving, or this tracker)
                self.tracker.reset(*self._output_state())
                self._relieving, self._turning = None, False
                self.mode = "recover"
                self.t_recover_end_s = cycle.t_s + self.recover_s
            if self.wrenches is not None:
                self.wrenches.start(cycle.t_s, self.recover_s, None)
            self.events.append(SafetyEvent(cycle.t_s, "release", ()))
        if self.wrenches is not None:
            self._hard_wrenches(cycle)
        self._release = False

        if self.mode == "finish":
            out = self._finish(q_in, phase_stop, cycle.t_s)
        elif self.mode == "release":
            out = q_in
        elif self.mode == "stop":
            if self._relieving:
                cycle.flags.add(BRAKE_FLAG)
                out = self._relieve(cycle.store.get(WRIST_RELIEF) if self._relief_allowed
                                    else None)
            elif self._brake_only:
                out = self.tracker.brake()
                if self.tracker.at_rest:
                    self.hold_rad = out.copy()
                    self.mode = "hold"
            elif self._turning:  # eq. 15's revert: first brake to rest at the brake limits
                cycle.flags.add(BRAKE_FLAG)
                out = self.brake_tracker.brake()
                if self.brake_tracker.at_rest:
                    self._turning = False
                    self.tracker.reset(out)
            else:  # ... then back to the posture of t_emer - T1 under the trajectory limits
                remaining = self.t_emer_s + self.stop_s - cycle.t_s
                out = self.tracker.track(self.hold_rad,
                                         min_duration_s=remaining if remaining > 0 else None)
                if self.tracker.finished:
                    out = self.hold_rad.copy()
                    self.mode = "hold"
        elif self.mode == "hold":
            out = self.hold_rad.copy()
            self.tracker.reset(out)
        else:  # recover
            remaining = self.t_recover_end_s - cycle.t_s
            w_in = (q_in - last_in) / self.dt_s
            out = self.tracker.track(q_in, min_duration_s=remaining if remaining > 0 else None,
                                     target_v_rad_s=w_in)
            if (remaining <= 0 and np.max(np.abs(out - q_in)) < 1e-6
                    and np.max(np.abs(self.tracker.v - w_in)) < 1e-3):
                out = q_in
                self.mode = "release"
        if self.mode in ("stop", "hold", "finish"):
            cycle.flags.add("estop")
        elif self.mode == "recover":
            cycle.flags.add("recovering")
        cycle.info[self._mode_column] = float(MODE_CODE[self.mode])
        if self._mode_key is not None:
            cycle.store[self._mode_key] = self.mode
        if self.wrenches is not None:
            cycle.store[HAND_WRENCH_REF] = self.wrenches.update(
                cycle.t_s, cycle.store.get(HAND_WRENCH_PLAN), self._wrench_mode(cycle.t_s))
        out = np.array(out, dtype=float)
        self.out3, self.out2, self.out1 = self.out2, self.out1, out
        return out


def stop_on_signal(stoppers: Iterable[EmergencyStopper], signum: int = signal.SIGUSR1,
                   source: str = "operator") -> Callable[[], None]:
    """Latch ``stoppers`` from ``source`` whenever the process receives ``signum`` (the
    operator's signal: ``kill -USR1 <pid>``). Call from the main thread; returns a function that
    puts the previous handler back."""
    targets = list(stoppers)
    previous = signal.getsignal(signum)

    def handler(received, frame) -> None:
        for stopper in targets:
            stopper.stop(source)

    signal.signal(signum, handler)
    return lambda: signal.signal(signum, previous)
