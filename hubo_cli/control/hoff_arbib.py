"""The Hoff-Arbib interpolator (paper eq. 1), the alternative to ruckig as the first module.

Eq. 1 gives the jerk that takes the current state (x, v, a) to the goal with zero velocity and
acceleration in the remaining time t_ha:

    jerk = -9 a / t_ha - 36 v / t_ha^2 + 60 (x_goal - x) / t_ha^3

Integrated over one period it is the quintic that hrpsys-base's SequencePlayer evaluates
(``interpolator.cpp``); re-issuing it every period with the shrinking remaining time gives an
online minimum-jerk tracker. The remaining time of a new goal is the shortest that keeps a
rest-to-rest minimum-jerk move within every joint's velocity, acceleration and jerk limits
(peaks 1.875 D/T, 5.774 D/T^2, 60 D/T^3), so the soft error limiter rarely has to step in.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.otg import STALE_TIMEOUT_S, TargetInput
from hubo_cli.dataflow import Store
from hubo_cli.geometry import (
    MIN_JERK_PEAK_ACCELERATION,
    MIN_JERK_PEAK_JERK,
    MIN_JERK_PEAK_VELOCITY,
)
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import JointLimits
from hubo_cli.state import RobotState


def hoff_arbib_step(x, v, a, goal, t_rem_s: float, dt_s: float):
    """Advance (x, v, a) by one period of eq. 1 toward ``goal`` with ``t_rem_s`` remaining.

    Works on scalars or arrays (rad, rad/s, rad/s^2). When no more than one period remains the
    state lands on the goal at rest. Returns the new (x, v, a).
    """
    if t_rem_s <= dt_s:
        goal = np.asarray(goal, dtype=float)
        return goal.copy(), np.zeros_like(goal), np.zeros_like(goal)
    T = t_rem_s
    A = (goal - (x + v * T + 0.5 * a * T * T)) / T**3
    B = -(v + a * T) / T**2
    C = -a / T
    c3 = 10 * A - 4 * B + 0.5 * C
    c4 = (-15 * A + 7 * B - C) / T
    c5 = (6 * A - 3 * B + 0.5 * C) / T**2
    t = dt_s
    x_new = x + v * t + 0.5 * a * t**2 + c3 * t**3 + c4 * t**4 + c5 * t**5
    v_new = v + a * t + 3 * c3 * t**2 + 4 * c4 * t**3 + 5 * c5 * t**4
    a_new = a + 6 * c3 * t + 12 * c4 * t**2 + 20 * c5 * t**3
    return x_new, v_new, a_new


def hoff_arbib_duration(distance_rad, velocity_rad_s, limits: JointLimits,
                        min_time_s: float) -> float:
    """The shortest common remaining time (s) for moving ``distance_rad`` (per joint) from
    ``velocity_rad_s`` within the limits, floored at ``min_time_s``."""
    d = np.abs(np.asarray(distance_rad, dtype=float))
    v0 = np.abs(np.asarray(velocity_rad_s, dtype=float))
    times = np.concatenate([
        MIN_JERK_PEAK_VELOCITY * d / limits.velocity_rad_s,
        np.sqrt(MIN_JERK_PEAK_ACCELERATION * d / limits.acceleration_rad_s2),
        np.cbrt(MIN_JERK_PEAK_JERK * d / limits.jerk_rad_s3),
        3.0 * v0 / limits.acceleration_rad_s2,  # room to turn a running joint around
    ])
    return float(max(min_time_s, times.max()))


class HoffArbibGenerator(Module):
    """The ``hoff-arbib`` module: eq. 1 interpolation toward the latest target.

    Args:
        model: the robot model (limits).
        dt_s: the control period (s).
        min_time_s: shortest interpolation time of a new goal (s).
        stale_timeout_s: stop (hold the goal reached so far) after this long without a target.
        limits: override the model's limits (tests).

    Same input conventions and flags as :class:`~hubo_cli.control.otg.TrajectoryGenerator`.
    """

    name = "hoff-arbib"
    log_columns = ("hoff_arbib_remaining_s",)

    def __init__(self, model: RobotModel, dt_s: float, min_time_s: float = 0.1,
                 stale_timeout_s: float = STALE_TIMEOUT_S,
                 limits: JointLimits | None = None) -> None:
        self.limits = limits or JointLimits.from_model(model)
        self.dt_s = float(dt_s)
        self.min_time_s = float(min_time_s)
        self.input = TargetInput(self.limits, stale_timeout_s)
        n = self.limits.size
        self.x = np.zeros(n)
        self.v = np.zeros(n)
        self.a = np.zeros(n)
        self.goal = np.zeros(n)
        self.remaining_s = 0.0
        self._stopping = False

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        q = np.where(np.isfinite(q_rad), q_rad, state.q_rad).astype(float)
        self.input.reset(q)
        self.x = q.copy()
        self.v = np.zeros_like(q)
        self.a = np.zeros_like(q)
        self.goal = self.input.target.copy()
        self.remaining_s = 0.0
        self._stopping = False

    def _set_goal(self, goal: np.ndarray) -> None:
        self.goal = goal.copy()
        self.remaining_s = hoff_arbib_duration(goal - self.x, self.v, self.limits,
                                               self.min_time_s)

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        stale = self.input.take(q_rad, cycle)
        if stale:
            if not self._stopping:
                # stop where a brake at the acceleration limit would land, then hold there
                ahead = self.x + self.v * np.abs(self.v) / (2 * self.limits.acceleration_rad_s2)
                self._set_goal(self.limits.clip(ahead))
                self._stopping = True
        else:
            self._stopping = False
            if not np.array_equal(self.input.target, self.goal):
                self._set_goal(self.input.target)
        self.x, self.v, self.a = hoff_arbib_step(self.x, self.v, self.a, self.goal,
                                                 self.remaining_s, self.dt_s)
        self.remaining_s = max(0.0, self.remaining_s - self.dt_s)
        cycle.info["hoff_arbib_remaining_s"] = self.remaining_s
        return self.x.copy()
