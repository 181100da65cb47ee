"""Per-joint limits shared by the pipeline modules, and the braking rule they all respect."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from hubo_cli.model import RobotModel

TARGET_SPEED_SHARE = 0.9  # [chosen] of a joint's speed limit, the most a target velocity asks
                          # (the trajectory generator's own tracking keeps the rest)


@dataclass(frozen=True)
class JointLimits:
    """Position, velocity, acceleration and jerk limits for every joint of a command vector.

    Attributes:
        lower_rad, upper_rad: position limits (rad).
        velocity_rad_s, acceleration_rad_s2, jerk_rad_s3: symmetric limits (positive).
    """

    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    acceleration_rad_s2: np.ndarray
    jerk_rad_s3: np.ndarray

    @classmethod
    def from_model(cls, model: RobotModel) -> JointLimits:
        """The 24 limb joints' limits from the robot file."""
        return cls(model.lower_rad.copy(), model.upper_rad.copy(), model.velocity_rad_s.copy(),
                   model.acceleration_rad_s2.copy(), model.jerk_rad_s3.copy())

    @property
    def size(self) -> int:
        return len(self.lower_rad)

    def subset(self, index) -> JointLimits:
        """The limits of some joints only (``index``: indices or a boolean mask)."""
        return JointLimits(self.lower_rad[index], self.upper_rad[index],
                           self.velocity_rad_s[index], self.acceleration_rad_s2[index],
                           self.jerk_rad_s3[index])

    def for_emergency_brake(self, model: RobotModel) -> JointLimits:
        """These limits with every joint's acceleration and jerk raised to the robot file's
        emergency braking values (``[safety] estop_brake_acceleration_rad_s2`` and
        ``estop_brake_jerk_rad_s3``; never lowered): the wrist-torque stop brakes at what the
        drives can do, not at the trajectories' shaping limits. Unchanged when the file has no
        such values."""
        accel = model.safety.get("estop_brake_acceleration_rad_s2")
        jerk = model.safety.get("estop_brake_jerk_rad_s3")
        if accel is None or jerk is None:
            return self
        return JointLimits(self.lower_rad, self.upper_rad, self.velocity_rad_s,
                           np.maximum(self.acceleration_rad_s2, float(accel)),
                           np.maximum(self.jerk_rad_s3, float(jerk)))

    def clip(self, q_rad: np.ndarray) -> np.ndarray:
        """``q_rad`` clamped into the position limits (rad)."""
        return np.minimum(np.maximum(q_rad, self.lower_rad), self.upper_rad)


@nb.njit(cache=True, nogil=True)
def brake_speed(room_rad: float, accel_rad_s2: float, dt_s: float) -> float:
    """Largest speed (rad/s) over the next period that can still stop within ``room_rad``.

    A command stepping at v for one period then braking at ``accel_rad_s2`` per period travels
    v dt + (v - a dt / 2)^2 / (2 a) at most; this returns the v that makes it equal to the room,
    so a sequence that keeps to it never passes the end of the room. No room -> 0.
    """
    if room_rad <= 0.0:
        return 0.0
    if room_rad <= 0.5 * accel_rad_s2 * dt_s * dt_s:
        return room_rad / dt_s
    return math.sqrt(2.0 * accel_rad_s2 * room_rad) - 0.5 * accel_rad_s2 * dt_s


def braking_distance(v_rad_s: np.ndarray, a_rad_s2: np.ndarray, limits: JointLimits) -> np.ndarray:
    """Signed distance (rad) a jerk-limited brake from velocity v and acceleration a covers.

    First the acceleration along the motion is ramped to zero at the jerk limit (the speed still
    grows by a^2 / 2j), then a symmetric stop at the acceleration and jerk limits follows:
    v^2 / 2a_max + v a_max / 2j when the acceleration limit is reached, v sqrt(v / j) when not.
    """
    out = np.empty(len(v_rad_s))
    _braking_distance(np.asarray(v_rad_s, dtype=float), np.asarray(a_rad_s2, dtype=float),
                      limits.acceleration_rad_s2, limits.jerk_rad_s3, out)
    return out


@nb.njit(cache=True, nogil=True)
def braking_distance_of(v: float, a: float, amax: float, jmax: float) -> float:
    """:func:`braking_distance` of one joint (compiled, for kernels)."""
    speed = abs(v)
    direction = 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
    along = max(a * direction, 0.0)           # acceleration pushing onward
    lead = speed * along / jmax + along**3 / (3 * jmax ** 2)
    speed += along * along / (2 * jmax)
    if speed > amax * amax / jmax:
        stop = speed * speed / (2 * amax) + speed * amax / (2 * jmax)
    else:
        stop = speed * math.sqrt(speed / jmax)
    return direction * (lead + stop)


@nb.njit(cache=True, nogil=True)
def _braking_distance(v, a, amax, jmax, out) -> None:
    for i in range(v.shape[0]):
        out[i] = braking_distance_of(v[i], a[i], amax[i], jmax[i])


@nb.njit(cache=True, nogil=True)
def hold_nan(q_rad, held_rad, out_rad) -> None:
    """``out_rad`` = ``q_rad`` with each entry that is not finite taken from ``held_rad``
    (``np.where(np.isfinite(q_rad), q_rad, held_rad)`` in one compiled pass)."""
    for i in range(q_rad.shape[0]):
        x = q_rad[i]
        out_rad[i] = x if np.isfinite(x) else held_rad[i]


@nb.njit(cache=True, nogil=True)
def all_finite(x) -> bool:
    """``np.isfinite(x).all()`` of a vector in one compiled pass."""
    for i in range(x.shape[0]):
        if not np.isfinite(x[i]):
            return False
    return True

