"""Collision room at the edge of reach: arm targets keep out of the collision detector's band.

The pipeline's collision detector (:mod:`hubo_cli.control.collision`) holds the arms when the
command, where it is or where it would stop, comes closer than its tolerance (10 mm) to the body.
An operator's goal that passes just outside the body (a hand brushing past the torso) would trip
that hold although nothing is wrong. :class:`CollisionRoom` treats such postures as not
reachable: an arm target closer than ``room_m`` to the body is pushed back to ``room_m`` along
the gradient of the closest pair's distance with respect to the joints of the arms in that pair
(a few Newton steps, finite differences), so the hand slides along the band instead of stopping
at it; if that fails, the target goes as far as it can along its step from the last target
(bisection). A target never goes deeper into the band than the last one was.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.control.collision import TOLERANCE_M, SelfCollisionChecker
from hubo_cli.model import ARMS, RobotModel

ROOM_M = TOLERANCE_M + 0.005  # the detector's band and 5 mm for the command's braking look-ahead
NEWTON_STEPS = 3
BISECTIONS = 8
DIFF_RAD = 1e-4              # finite-difference step of the distance's gradient


class CollisionRoom:
    """Keeps arm targets at least ``room_m`` from the body (see the module docstring).

    Args:
        model: the robot model (URDF, limits).
        drill: the right hand holds the drill (its capsules are checked too).
        room_m: the clearance an arm target keeps (m).
        arms: the arms that may be moved (the driven ones).

    Attributes:
        pushed_periods: per arm, how many calls moved its target out of the band.
        last_clearance_m: the closest pair's distance at the last returned target (m).
    """

    def __init__(self, model: RobotModel, drill: bool = False, room_m: float = ROOM_M,
                 arms: tuple[str, ...] = ARMS) -> None:
        self.model = model
        self.room_m = float(room_m)
        self.checker = SelfCollisionChecker(model, drill=drill)
        self.arms = tuple(arms)
        self.lower = np.asarray(model.lower_rad, dtype=float)
        self.upper = np.asarray(model.upper_rad, dtype=float)
        self._index = {arm: np.arange(len(model.joint_names))[model.limb_slice(arm)]
                       for arm in self.arms}
        self._link_arm = {f"{joint}_link": arm for arm in self.arms
                          for joint in model.limb(arm).joints}
        if drill and "right-arm" in self.arms:
            self._link_arm["drill"] = "right-arm"
        self.pushed_periods = dict.fromkeys(self.arms, 0)
        self.last_clearance_m = np.inf

    def _arms_of(self, pair: tuple[str, str]) -> list[str]:
        found = []
        for name in pair:
            arm = self._link_arm.get(name.rsplit("_", 1)[0])
            if arm is not None and arm not in found:
                found.append(arm)
        return found

    def _distance(self, q_rad: np.ndarray) -> tuple[float, tuple[str, str]]:
        c = self.checker.check(q_rad)
        return c.distance_m, c.pair

    def keep(self, q_prev_rad: np.ndarray, q_next_rad: np.ndarray) -> np.ndarray:
        """The target to use instead of ``q_next_rad`` (24 joints, rad) after ``q_prev_rad``."""
        q_next = np.asarray(q_next_rad, dtype=float)
        d, pair = self._distance(q_next)
        if d >= self.room_m:
            self.last_clearance_m = d
            return q_next
        q = q_next.copy()
        moved: set[str] = set()
        for _ in range(NEWTON_STEPS):
            arms = self._arms_of(pair)
            if not arms:  # the legs alone: nothing an arm target can do
                break
            index = np.concatenate([self._index[a] for a in arms])
            grad = np.empty(len(index))
            for k, i in enumerate(index):
                q_d = q.copy()
                q_d[i] += DIFF_RAD
                grad[k] = (self._distance(q_d)[0] - d) / DIFF_RAD
            norm2 = float(grad @ grad)
            if not np.isfinite(norm2) or norm2 < 1e-12:
                break
            q[index] = np.clip(q[index] + grad * (self.room_m + 1e-4 - d) / norm2,
                               self.lower[index], self.upper[index])
            moved.update(arms)
            d, pair = self._distance(q)
            if d >= self.room_m:
                return self._done(q, d, moved)
        arm_index = np.concatenate([self._index[a] for a in self.arms])
        q_prev = q_next.copy()  # the legs as asked, the arms where they were
        q_prev[arm_index] = np.asarray(q_prev_rad, dtype=float)[arm_index]
        d_prev = self._distance(q_prev)[0]
        if d_prev < self.room_m:  # already inside: never deeper than the last target
            best, d_best = (q, d) if d >= d_prev else (q_prev, d_prev)
            return self._done(best, d_best, moved or set(self._arms_of(pair)))
        lo, hi = 0.0, 1.0  # the furthest clear point of the arms' step from the last target
        for _ in range(BISECTIONS):
            mid = (lo + hi) / 2
            if self._distance(q_prev + mid * (q_next - q_prev))[0] >= self.room_m:
                lo = mid
            else:
                hi = mid
        q = q_prev + lo * (q_next - q_prev)
        moved = {a for a in self.arms if np.any(q_next[self._index[a]] != q[self._index[a]])}
        return self._done(q, self._distance(q)[0], moved)

    def _done(self, q: np.ndarray, d: float, moved: set[str]) -> np.ndarray:
        self.last_clearance_m = d
        for arm in moved:
            self.pushed_periods[arm] += 1
        return q
