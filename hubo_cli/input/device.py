"""The input device contract: open, read hand poses stamped with their own time, close.

The operator's frame O has the robot's axes: x forward, y left, z up (metres). A device turns
whatever it measures into :class:`HandPose` objects: which hand (``"left"`` or ``"right"``), the
hand's pose in O, and the time the pose was sampled on the device's clock (not the time it was
read). The teleoperation maps only motion relative to a reference pose (see
:mod:`hubo_cli.teleop.mapping`), so O's origin is the device's own.

A consumer calls ``read_until(t_s)`` once per control cycle and asks ``is_stale(hand, now_s)``
before trusting a hand's latest pose. Recordings and generated streams release every pose whose
time is at or before ``t_s`` (so they run as fast as the caller's clock); live devices deliver
everything received so far and never block for more than a few milliseconds.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from hubo_cli.timeline import OnTimeline, Timeline

HANDS = ("right", "left")
ARM_OF_HAND = {"right": "right-arm", "left": "left-arm"}  # the robot arm a hand drives
HAND_OF_ARM = {arm: hand for hand, arm in ARM_OF_HAND.items()}


@dataclass(frozen=True, eq=False)
class HandPose:
    """One hand's pose at one instant.

    Attributes:
        hand: ``"right"`` or ``"left"``.
        T_operator_hand: (4,4) the hand's pose in the operator's frame O (m).
        t_s: when it was sampled, seconds on the device's clock.
        reliable: False when the device doubts the value (e.g. a tracker out of its envelope):
            the hand holds, but the input is not stale.
        engaged: False while the operator holds the clutch: the hand holds and, on release,
            the next pose becomes the new reference.
    """

    hand: str
    T_operator_hand: np.ndarray
    t_s: float
    reliable: bool = True
    engaged: bool = True

    @property
    def position_m(self) -> np.ndarray:
        """The hand's position in O (m)."""
        return self.T_operator_hand[:3, 3]


class InputDevice(ABC):
    """Where the operator's hand poses come from; a context manager.

    Attributes:
        hands: the hands the device delivers.
        info: what the device is (kind, path or port, ...), for the run's summary.
        live: its clock is the wall clock (a live device) rather than the caller's.
    """

    hands: tuple[str, ...]
    info: dict
    live = False

    def __init__(self) -> None:
        self._last_seen: dict[str, float] = {}

    # -- what every device implements ----------------------------------------------------
    @abstractmethod
    def _read(self, t_s: float) -> list[HandPose]:
        """New poses: up to time ``t_s`` (recording) or all received so far (live)."""

    @abstractmethod
    def now_s(self) -> float:
        """The device's clock, seconds since it started."""

    # -- shared behaviour ------------------------------------------------------------------
    def read_until(self, t_s: float) -> list[HandPose]:
        """New poses, oldest first: those sampled at or before ``t_s`` (a recording or a
        generated stream) or every one received since the last call (live; ``t_s`` ignored).

        Raises:
            DeviceError: a live device was lost and could not be reconnected.
        """
        poses = self._read(t_s)
        for pose in poses:
            self._last_seen[pose.hand] = max(pose.t_s, self._last_seen.get(pose.hand, -math.inf))
        return poses

    def last_seen_s(self, hand: str) -> float | None:
        """Sample time of the newest pose delivered for ``hand``, or None if never seen."""
        return self._last_seen.get(hand)

    def looked_s(self) -> float:
        """Up to when the device has looked at its input, on its own clock (a live reader's
        latest completed read); ``inf`` when the caller's clock releases the poses."""
        return math.inf

    def is_stale(self, hand: str, now_s: float, timeout_s: float = 0.25) -> bool:
        """True if ``hand`` has delivered nothing sampled within ``timeout_s`` before ``now_s``,
        or before the device last looked at its input if that is earlier: input is judged by
        its own timestamps, so a caller running late does not make fresh input stale."""
        last = self._last_seen.get(hand)
        return last is None or min(now_s, self.looked_s()) - last > timeout_s

    @property
    def done(self) -> bool:
        """True once a recording or a generated stream has delivered everything."""
        return False

    @property
    def recorded_s(self) -> float | None:
        """How long a recording or a generated stream lasts (s); None for a live device."""
        return None

    def stats(self) -> dict:
        """Counters of what the device has read, for the run's summary."""
        return {}

    def close(self) -> None:
        """Release the port or file (idempotent)."""

    def __enter__(self) -> InputDevice:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class RecordedInput(OnTimeline, InputDevice):
    """Hand poses known in advance (a decoded recording, a generated stream), released by the
    caller's clock.

    Args:
        poses: every pose, in any order (sorted by time here, stably).
        info: what the stream is.
    """

    def __init__(self, poses: list[HandPose], info: dict) -> None:
        super().__init__()
        self._timeline = Timeline(poses, lambda pose: pose.t_s)
        self.info = info
        self.hands = tuple(h for h in HANDS if any(p.hand == h for p in self._timeline.items))

    def _read(self, t_s: float) -> list[HandPose]:
        return self._timeline.take_until(t_s)
