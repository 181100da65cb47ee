"""How far the arm would lag behind a planned cut: the plan's joint targets followed, offline,
by the pipeline's own jerk-limited follower, before anything moves.

The pipeline keeps every joint within its velocity, acceleration and jerk limits whatever the
plan asks, so a cut faster than the arm follows leaves the bit behind its path: mostly at the
corners, where each joint turns (the joints' jerk limits, not the velocity or acceleration the
plan asks, set how fast: cut-rectangle's corners speeding up at 2,000 mm/s^2 ask 16 times an
acceleration limit at 10 mm/s and the bit still followed, 1.3 mm RMS on the simulated Hubo).
Pre-flight runs the arm's joints of each cut through :class:`~hubo_cli.motion.tracker.
JointTracker` (every ``DECIMATION``-th period, at that period: within 0.3 mm of every period's
run, a twentieth of the time) and measures the bit's lag by the arm's forward kinematics. A cut
whose lag exceeds the outcome check's limit (:data:`LAG_LIMIT_RMS_MM`: it would not complete)
is refused. Measured (RMS over the cut, mm): the shipped cuts 1.1-1.3; cut-rectangle at 20, 30
and 40 mm/s 3.0, 5.2 and 7.7 (9.1 with 2,000 mm/s^2 corners); cut-slot at 100 and 150 mm/s
38 and 52.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.kinematics.interpolate import trapezoid_timing
from hubo_cli.kinematics.limb import Limb
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.tasks.spec import Step
from hubo_cli.tasks.too_fast import mm_text

DECIMATION = 5  # the follower runs every 5th period (25 ms)
# A cut whose bit misses its path by more than this (RMS over the cut, mm) does not complete:
# the outcome check's limit (tasks.runner's PATH_MISS_RMS_MM) and pre-flight's. Healthy runs
# measured 1.2-2.4 mm (every shipped cut, perturbed robots, force control with the wall 15 mm
# off, each balancer, the hardware dry run; docs/history/safety.md, round 17); not a task
# file's setting.
LAG_LIMIT_RMS_MM = 20.0
SUGGESTED_SHARE = 0.8  # the speed suggested lags at most this share of the limit


@dataclass(frozen=True)
class CutLag:
    """A cut whose bit would lag behind its path more than the limit.

    Attributes:
        step: the cut (a ``follow`` step).
        rms_m: the bit's lag behind its planned position, RMS over the cut (m).
        max_m: its largest (m).
        possible_m_s: a speed the arm follows within :data:`SUGGESTED_SHARE` of the limit
            (the cut's joint path re-timed at that speed; m/s).
    """

    step: Step
    rms_m: float
    max_m: float
    possible_m_s: float

    def message(self) -> str:
        """One line: the cut, its speed, the lag, and the speed the arm follows."""
        return (f"{self.step.label} ({self.step.kind}) at {mm_text(self.step.speed_m_s)} mm/s: "
                f"the arm, within its joints' limits, would lag {self.rms_m * 1000:.0f} mm RMS "
                f"behind the path ({self.max_m * 1000:.0f} mm at most; a cut may miss "
                f"{LAG_LIMIT_RMS_MM:g}); it follows about {mm_text(self.possible_m_s)} mm/s")

    def fix(self) -> str:
        """What to change (a hint)."""
        return (f"cut at {mm_text(self.possible_m_s)} mm/s or less: the step's speed_mm_s "
                "(--speed for the shipped cuts)")


def lagging_cuts(steps: tuple[Step, ...] | list[Step], arm: Limb, limits: JointLimits,
                 q_arm_rad: np.ndarray, goal_m: np.ndarray, step_index: np.ndarray,
                 dt_s: float, cut_accel_m_s2: float) -> list[CutLag]:
    """The cuts whose bit would lag more than :data:`LAG_LIMIT_RMS_MM` RMS.

    Args:
        steps: the task's steps.
        arm: the working arm (its forward kinematics, with the tool).
        limits: that arm's joint limits (the pipeline's).
        q_arm_rad: (N, 6) the plan's joint targets of that arm, one row per period.
        goal_m: (N, 3) the tool's planned position (m).
        step_index: (N,) the step each row belongs to.
        dt_s: the control period (s).
        cut_accel_m_s2: a cut's acceleration at its corners unless its step sets one.
    """
    out = []
    for k, step in enumerate(steps):
        rows = np.nonzero(step_index == k)[0]
        if step.kind != "follow" or len(rows) < 2:
            continue
        path = _CutPath(q_arm_rad[rows], goal_m[rows], step, step.accel_m_s2 or cut_accel_m_s2,
                        dt_s)
        rms, peak = path.lag(arm, limits, step.speed_m_s)
        if rms * 1000 <= LAG_LIMIT_RMS_MM:
            continue
        slow, fast = 0.0, step.speed_m_s  # bisection on the speed
        for _ in range(7):
            mid = 0.5 * (slow + fast)
            if path.lag(arm, limits, mid)[0] * 1000 <= SUGGESTED_SHARE * LAG_LIMIT_RMS_MM:
                slow = mid
            else:
                fast = mid
        out.append(CutLag(step, rms, peak, max(slow, step.speed_m_s / 128)))
    return out


class _CutPath:
    """A cut's joint path by the distance the bit has come along it, re-timed at another
    speed as the plan would time it (each edge speeding up and slowing down at ``accel``)."""

    def __init__(self, q: np.ndarray, goal_m: np.ndarray, step: Step, accel_m_s2: float,
                 dt_s: float) -> None:
        self.q, self.accel, self.dt_s = q, accel_m_s2, dt_s
        self.s_m = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(goal_m, axis=0),
                                                                   axis=1))])
        corners = np.asarray(step.points_m, dtype=float)
        edges = list(np.linalg.norm(np.diff(corners, axis=0), axis=1))
        join = self.s_m[-1] - sum(edges)  # from where the bit was to the path's start
        self.edges_m = [e for e in ([join] if join > 1e-6 else []) + edges if e > 1e-9]

    def lag(self, arm: Limb, limits: JointLimits, speed_m_s: float) -> tuple[float, float]:
        """RMS and largest lag (m) of the bit along this path at ``speed_m_s``, the arm's
        joints followed every ``DECIMATION`` periods."""
        step_s = self.dt_s * DECIMATION
        s_new = []
        start = 0.0
        for edge in self.edges_m:
            duration, ramp = trapezoid_timing(edge, speed_m_s, self.accel)
            t = np.arange(0.0, duration, step_s)
            a = edge / (ramp * (duration - ramp))  # the ramps' acceleration
            along = np.where(t < ramp, 0.5 * a * t**2,
                             np.where(t > duration - ramp,
                                      edge - 0.5 * a * np.maximum(duration - t, 0.0)**2,
                                      a * ramp * (t - 0.5 * ramp)))
            s_new.append(start + along)
            start += edge
        s_new = np.concatenate([*s_new, [start]])
        target = np.column_stack([np.interp(s_new, self.s_m, self.q[:, j])
                                  for j in range(self.q.shape[1])])
        tracker = JointTracker(limits, step_s, "phase")
        tracker.reset(target[0])
        followed = np.array([tracker.track(row) for row in target])
        lag = np.linalg.norm(arm.fk_batch(followed)[:, :3, 3] - arm.fk_batch(target)[:, :3, 3],
                             axis=1)
        return float(np.sqrt(np.mean(lag**2))), float(lag.max())
