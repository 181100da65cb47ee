"""The swing foot kept over the floor while a side push rolls the body over the stance sole's
outer edge (issue 37's pushes toward the stance foot; docs/history/walking.md, round 11).

Pushed sideways toward the stance foot in single support, the robot rolls onto that sole's
outer edge: the torso, the stance leg and the swing leg turn together about the edge, so the
swing foot, fixed in the torso's frame, rises with the body (pushed seed 6 at 60 N: 0.19 rad
of roll, the swing foot about 45 mm higher than planned and rolled with it). The body then rolls
back with the measured ZMP on that outer edge the whole way, gaining speed toward the swing
side, and the swing foot, planned down meanwhile, reaches the floor only 0.3 s after its
landing, when the capture point is already at its outer edge: the robot rolls on over that foot
and falls (round 7's rebound).

:class:`FloorReach` turns each swing leg's sole goal, in the torso's frame, against the
estimated torso's roll from the planned one (beyond REACH_DEAD_RAD, toward the stance side only,
at most REACH_MAX_RAD, changing at most REACH_RATE_RAD_S), about the stance sole's outer edge:
the body's roll about that edge is taken back out of the swing foot, which so keeps its planned
height and attitude over the floor and lands flat, on time, where the rebound brings the
capture point. A leg planned down and in contact gives its turn back at REACH_RETURN_RAD_S,
also while the other swings (at most REACH_STOP_RAD in a walk that goes on). A turn
beyond REACH_STOP_RAD marks the walk :attr:`FloorReach.tipped`: the walk stops once that foot
has landed (the step finished into a double-support stance, as the capture-point monitor's
stop does).
"""

from __future__ import annotations

import math

import numpy as np

REACH_DEAD_RAD = math.radians(2.0)  # [chosen] the torso's roll from the planned one beyond
                        # this is taken out of a swing foot (unpushed walking: under 0.0069 rad,
                        # round 9). 1 deg acted in pushed seed 8's steps after a push away from
                        # the stance foot (12 mrad of turn) and that walk fell (main: stood)
REACH_MAX_RAD = 0.25    # [chosen] ... at most this much (pushed seed 6 at 60 N rolled 0.19 rad)
REACH_RATE_RAD_S = 0.8  # [chosen] ... changing at most this fast. The knee moves about 2.6
                        # times the turn and the legs' correction LEG_STEP_RAD a period or holds:
                        # a turn growing faster than about 0.38 rad/s holds that leg's correction
                        # (round 11's review; the 60 N test's grew at 0.37 rad/s)
REACH_STOP_RAD = 0.01   # [chosen] a turn beyond this (the body tipped over the stance sole's
                        # edge beyond the dead band) stops the walk once the foot has landed
                        # (:meth:`~hubo_cli.walking.target.WalkTarget._caught`): walking on,
                        # pushed seed 6 at 60 N (turn 0.097 rad) and seed 58 at 50 N caught the
                        # rebound and fell two steps later; pushed seed 8 (0.043 rad) fell in its
                        # correction walk. Stopped at once (0.05 rad, a 1 deg dead band) instead
                        # of at the landing, seed 8 fell. At 0.03 pushed seed 19's walk (0.027
                        # rad, AVX-512) went on instead of stopping (it arrived 26 mm off)
REACH_RETURN_RAD_S = 0.3  # [chosen] a leg planned down and in contact gives its turn back so
                          # (at 0.1 rad/s with both soles loaded, as the pitch's levelling, the
                          # landed leg kept 0.074 rad through seed 6's next step, which bounced)


def _turn_about(axis: np.ndarray, angle_rad: float, point: np.ndarray) -> np.ndarray:
    """The rigid transform (4x4) turning by ``angle_rad`` about the line through ``point``
    along the unit ``axis`` (Rodrigues)."""
    x, y, z = axis
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    K = np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))
    R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = point - R @ point
    return T


class FloorReach:
    """Each leg's turn (rad, about the torso's x axis, signed as the torso's roll) taken out of
    its sole goal while it swings and the body rolls over the other sole's outer edge."""

    def __init__(self, half_width_m: float, dt_s: float) -> None:
        self.half_width_m = half_width_m  # the sole's outer edge from its origin (m)
        self.dt_s = dt_s
        self.angle_rad = np.zeros(2)  # right, left
        self.tipped = False  # a turn went beyond REACH_STOP_RAD

    def reset(self) -> None:
        self.angle_rad[:] = 0.0
        self.tipped = False

    def update(self, roll_error_rad: float, support: tuple[bool, bool],
               contact: tuple[bool, bool]) -> None:
        """One period: ``roll_error_rad`` the estimated torso's roll from the planned one
        (about its x axis; > 0 rolls the right side down), ``support`` the pattern's soles
        down and ``contact`` the estimate's (right, left)."""
        back = REACH_RETURN_RAD_S * self.dt_s
        step = REACH_RATE_RAD_S * self.dt_s
        for column in range(2):
            angle = float(self.angle_rad[column])
            if support[column] and contact[column]:
                self.angle_rad[column] = angle - min(max(angle, -back), back)
            elif not (support[column] or contact[column]) and support[1 - column] \
                    and math.isfinite(roll_error_rad):
                toward = 1.0 if column == 1 else -1.0  # the stance side's roll: right down > 0
                wanted = toward * min(max(toward * roll_error_rad - REACH_DEAD_RAD, 0.0),
                                      REACH_MAX_RAD)
                self.angle_rad[column] = angle + min(max(wanted - angle, -step), step)
            # (on the floor, the other one swinging; no estimate of the torso: it holds)
        right, left = self.angle_rad.tolist()  # (plain floats: numpy's reductions cost more)
        self.tipped = self.tipped or abs(right) > REACH_STOP_RAD or abs(left) > REACH_STOP_RAD

    def turns(self, T_neck_soles: np.ndarray) -> np.ndarray | None:
        """The transforms (2 x 4 x 4, in the torso's frame) to apply to the sole goals
        ``T_neck_soles`` (right, left) this period: each leg's turn taken back out about the
        other sole's outer edge, along that sole's x axis; None when neither leg is turned."""
        right, left = self.angle_rad.tolist()
        if not (right or left):
            return None
        out = np.empty((2, 4, 4))
        for column in range(2):
            stance = T_neck_soles[1 - column]
            outer = (-1.0 if column == 1 else 1.0) * self.half_width_m  # the right sole's
            edge = stance[:3, :3] @ np.array((0.0, outer, 0.0)) + stance[:3, 3]  # is at -y
            out[column] = _turn_about(stance[:3, 0], -float(self.angle_rad[column]), edge)
        return out
