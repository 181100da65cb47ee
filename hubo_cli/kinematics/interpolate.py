"""Timed Cartesian paths: straight lines with minimum-jerk timing and slerped orientation.

Used for the teleop approach (bring the tool to its start pose without sweeping through the
scene) and by scripted tasks (move, plunge, follow, retract). Poses are 4x4 transforms (m).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hubo_cli.geometry import min_jerk, rotation_exp, rotation_log


def trapezoid(t_s: float, duration_s: float, ramp_s: float) -> float:
    """Progress 0 -> 1 at time t_s of a trapezoidal speed profile: constant acceleration for
    ``ramp_s``, constant speed, constant deceleration for ``ramp_s`` (ramp_s <= duration / 2)."""
    t = min(max(t_s, 0.0), duration_s)
    ramp = min(ramp_s, duration_s / 2)
    if ramp <= 0:
        return t / duration_s
    v = 1.0 / (duration_s - ramp)  # the peak speed of a unit distance
    if t < ramp:
        return 0.5 * v / ramp * t * t
    if t <= duration_s - ramp:
        return v * (t - ramp / 2)
    left = duration_s - t
    return 1.0 - 0.5 * v / ramp * left * left


def trapezoid_timing(distance_m: float, speed_m_s: float, accel_m_s2: float
                     ) -> tuple[float, float]:
    """(duration s, ramp s) of a trapezoidal move over ``distance_m`` cruising at
    ``speed_m_s`` with ``accel_m_s2`` (a triangle when the distance is too short to cruise)."""
    ramp = speed_m_s / accel_m_s2
    if distance_m >= speed_m_s * ramp:
        return distance_m / speed_m_s + ramp, ramp
    ramp = float(np.sqrt(distance_m / accel_m_s2))
    return 2 * ramp, ramp


@dataclass(frozen=True)
class PoseSegment:
    """A straight move from ``T_start`` to ``T_end`` in ``duration_s``, orientation interpolated
    along the geodesic. Profiles: ``min-jerk``, ``linear`` (constant speed) and ``trapezoid``
    (constant speed between acceleration and deceleration ramps of ``ramp_s``, for cutting)."""

    T_start: np.ndarray
    T_end: np.ndarray
    duration_s: float
    profile: str = "min-jerk"
    ramp_s: float = 0.0

    def at(self, t_s: float) -> np.ndarray:
        """The pose t_s seconds into the segment (clamped to its ends)."""
        s = 1.0 if self.duration_s <= 0 else t_s / self.duration_s
        if self.profile == "min-jerk":
            s = min_jerk(s)
        elif self.profile == "trapezoid" and self.duration_s > 0:
            s = trapezoid(t_s, self.duration_s, self.ramp_s)
        else:
            s = min(max(s, 0.0), 1.0)
        T = np.zeros((4, 4))
        T[3, 3] = 1.0
        T[:3, 3] = self.T_start[:3, 3] + s * (self.T_end[:3, 3] - self.T_start[:3, 3])
        R = self._R_unturned
        T[:3, :3] = self.T_start[:3, :3] @ rotation_exp(s * self._turn) if R is None else R
        return T

    @cached_property
    def _R_unturned(self) -> np.ndarray | None:
        """The orientation of every pose of a segment that does not turn (computed as
        :meth:`at` would, once), else None."""
        if np.any(self._turn):
            return None
        return self.T_start[:3, :3] @ rotation_exp(0.0 * self._turn)

    @cached_property
    def _turn(self) -> np.ndarray:
        """The rotation from the start to the end orientation (rotation vector, rad)."""
        return rotation_log(self.T_start[:3, :3].T @ self.T_end[:3, :3])


def segment_duration(T_start: np.ndarray, T_end: np.ndarray, speed_m_s: float,
                     turn_rad_s: float = 0.5, minimum_s: float = 0.2) -> float:
    """How long a min-jerk move should take so its mean speed is ``speed_m_s`` (and its mean
    turn rate ``turn_rad_s``)."""
    distance = float(np.linalg.norm(T_end[:3, 3] - T_start[:3, 3]))
    turn = float(np.linalg.norm(rotation_log(T_start[:3, :3].T @ T_end[:3, :3])))
    return max(distance / speed_m_s, turn / turn_rad_s, minimum_s)


class PosePath:
    """Segments played one after the other; ``at(t)`` is the pose at time t (s)."""

    def __init__(self, segments: list[PoseSegment]) -> None:
        self.segments = list(segments)
        self.starts_s = np.cumsum([0.0] + [s.duration_s for s in self.segments])

    @property
    def duration_s(self) -> float:
        return float(self.starts_s[-1])

    def index_at(self, t_s: float) -> int:
        """The segment playing at time t (the last one after the end)."""
        k = int(np.searchsorted(self.starts_s, t_s, side="right")) - 1
        return min(max(k, 0), len(self.segments) - 1)

    def at(self, t_s: float) -> np.ndarray:
        k = self.index_at(t_s)
        return self.segments[k].at(t_s - self.starts_s[k])
