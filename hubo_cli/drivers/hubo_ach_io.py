"""Where the hardware driver's references go and its states come from.

Sinks take one packed ``hubo_ref`` frame (462 bytes) per period: :class:`AchRefSink` puts it on
hubo-ach's ``hubo-ref`` channel, :class:`FileRefSink` appends it to a file or named pipe (dry
runs; the same bytes the channel would get). Sources give one state per period:
:class:`AchStateSource` waits for hubo-daemon's next ``hubo-state`` frame (so the robot's own
200 Hz clock paces the driver), :class:`EchoSource` applies hubo-daemon's reference filter to
the references (dry runs without a robot).
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import time
from abc import ABC, abstractmethod
from pathlib import Path

import numpy as np

from hubo_cli.drivers import hubo_ach
from hubo_cli.drivers.ach import ACH_MISSED_FRAME, ACH_OK, AchChannel, Libach
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, StateFrame
from hubo_cli.errors import DeviceError


class RefSink(ABC):
    """Takes one ``hubo_ref`` frame per period."""

    @abstractmethod
    def put(self, frame: bytes) -> bool:
        """Send one frame; False when it was dropped (a full pipe)."""

    @abstractmethod
    def close(self) -> None:
        """Release the channel or file; safe to call twice."""


class StateSource(ABC):
    """Gives the robot's state once per period.

    Attributes:
        wall_clock: the state's ``time`` is this computer's ``CLOCK_MONOTONIC`` (a daemon on
            it), so the state's age can be measured; False for a simulated clock.
    """

    wall_clock = False

    @abstractmethod
    def open(self, pos0_rad: np.ndarray) -> StateFrame | None:
        """Start; the first state (None if none came). ``pos0_rad`` (42, rad) is the posture a
        simulated source starts in; a real source reports the measured one."""

    @abstractmethod
    def advance(self, ref_rad: np.ndarray, mode: np.ndarray) -> StateFrame | None:
        """The state one period later, given the reference in force; None if no new state."""

    @abstractmethod
    def close(self) -> None:
        """Release the channel; safe to call twice."""

    def clock_s(self) -> float:
        """The time a state's freshness is judged by (s): this computer's wall clock for a
        real daemon's states (a late one is late for the robot too)."""
        return time.monotonic()


class AchRefSink(RefSink):
    """``ach_put`` on the reference channel (``hubo-ref``)."""

    def __init__(self, lib: Libach, name: str) -> None:
        self.name = name
        self.channel = lib.open(name)

    def put(self, frame: bytes) -> bool:
        self.channel.put(frame)
        return True

    def close(self) -> None:
        self.channel.close()


class FileRefSink(RefSink):
    """Frames appended to a file, or written to a named pipe without waiting for a reader.

    Args:
        path: the file (created or truncated) or pipe (created if absent).
        fifo: make it a named pipe; a full pipe drops the frame.
    """

    def __init__(self, path: str | Path, fifo: bool = False) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if fifo:
                if self.path.exists() and not stat.S_ISFIFO(self.path.stat().st_mode):
                    self.path.unlink()
                if not self.path.exists():
                    os.mkfifo(self.path)
                # read-write so that opening never waits for a reader
                self._fd = os.open(self.path, os.O_RDWR | os.O_NONBLOCK)
            else:
                self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        except OSError as exc:
            raise DeviceError(f"cannot open the reference sink {self.path}: {exc.strerror}",
                              hint="check the folder is writable") from None

    def put(self, frame: bytes) -> bool:
        try:
            os.write(self._fd, frame)
        except BlockingIOError:
            return False
        except OSError as exc:
            if exc.errno == errno.EAGAIN:
                return False
            raise
        return True

    def close(self) -> None:
        if self._fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = -1


class EchoSource(StateSource):
    """hubo-daemon's reference filter applied to the references, with an ideal motor: the
    joints are where the filtered reference is (a dry run without a robot).

    Args:
        period_s: the control period (s).
        filter_length: ``HUBO_REF_FILTER_LENGTH``.
    """

    def __init__(self, period_s: float, filter_length: int) -> None:
        self.period_s = period_s
        self.filter_length = filter_length
        self._pos = np.zeros(JOINT_COUNT)
        self._t = 0.0

    def open(self, pos0_rad: np.ndarray) -> StateFrame:
        self._pos = np.array(pos0_rad, dtype=float)
        self._t = 0.0
        return self._frame(np.zeros(JOINT_COUNT))

    def advance(self, ref_rad: np.ndarray, mode: np.ndarray) -> StateFrame:
        previous = self._pos
        self._pos = hubo_ach.reference_filter(previous, ref_rad, mode, self.filter_length)
        self._t += self.period_s
        return self._frame((self._pos - previous) / self.period_s)

    def clock_s(self) -> float:
        """The echo's own time (s): one period a step, however long the step took on this
        computer (a dry run has no robot to be late for: a busy machine's pause between two
        steps is not a lost state)."""
        return self._t

    def _frame(self, vel_rad_s: np.ndarray) -> StateFrame:
        return StateFrame(self._t, np.zeros(3), np.zeros(3), np.zeros((4, 3)), self._pos.copy(),
                          vel_rad_s)

    def close(self) -> None:
        """Nothing to release."""


class AchStateSource(StateSource):
    """The newest ``hubo-state`` frame, waiting for the daemon's next one each period.

    Args:
        lib: libach.
        name: the state channel (``hubo-state``).
        wait_s: how long :meth:`advance` waits for a new frame before reporting none (a third
            of it after a period without one, so that a dead daemon does not slow the
            caller's 200 Hz loop while it brakes).
        start_timeout_s: how long :meth:`open` waits for the first frame.

    Attributes:
        missed_frames: frames the daemon published that were never read (ACH_MISSED_FRAME).
    """

    wall_clock = True  # hubo-daemon's CLOCK_MONOTONIC (through achd: another computer's)

    def __init__(self, lib: Libach, name: str, wait_s: float, start_timeout_s: float) -> None:
        self.name = name
        self.wait_s = wait_s
        self.start_timeout_s = start_timeout_s
        self.missed_frames = 0
        self._late = False
        self._buffer = hubo_ach.HuboState()
        self.channel: AchChannel = lib.open(name)

    def open(self, pos0_rad: np.ndarray) -> StateFrame | None:
        return self._get(self.start_timeout_s)

    def advance(self, ref_rad: np.ndarray, mode: np.ndarray) -> StateFrame | None:
        frame = self._get(self.wait_s / 3 if self._late else self.wait_s)
        self._late = frame is None
        return frame

    def _get(self, wait_s: float) -> StateFrame | None:
        status, size = self.channel.get(self._buffer, last=True, wait_s=wait_s)
        if status not in (ACH_OK, ACH_MISSED_FRAME):
            return None  # nothing new before the deadline
        if status == ACH_MISSED_FRAME:
            self.missed_frames += 1
        if size != hubo_ach.STATE_SIZE:
            raise DeviceError(
                f"a {self.name} frame of {size} bytes; hubo_state_t is {hubo_ach.STATE_SIZE}",
                hint="the daemon was built from another hubo.h (this driver follows hubo-ach "
                     "0.1.20131101, the late-2013 develop branch)")
        return hubo_ach.decode_state(bytes(self._buffer))

    def close(self) -> None:
        self.channel.close()
