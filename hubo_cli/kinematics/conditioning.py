"""How close an arm is to a singular configuration, and how much to slow down there.

The measure is MoveIt Servo's: the condition number of the arm's Jacobian (largest over smallest
singular value), here with the linear rows divided by the arm's length (upper arm + forearm) so
that metres and radians weigh alike. It is about 9 at the free-mode ready pose (elbow bent 80 deg)
and grows as 11/|theta4| as the elbow straightens (case 1 of the paper) and without bound as the
wrist yaw nears +-90 deg or the shoulder roll +-90 deg (the other closed-form branch boundaries).

Joint speeds are scaled by MoveIt Servo's rule with its two thresholds: 1 below ``lower``,
falling linearly to ``floor`` at ``hard``; when the motion leads away from the singularity the
band is twice as wide (Servo's ``leaving_singularity_threshold_multiplier``). Unlike Servo, the
scale never reaches 0 (``floor``), so a goal path through a singularity is followed slowly
instead of halting there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.kinematics.limb import Limb
from hubo_cli.kinematics.reach import jacobian


def condition_number(limb: Limb, q_rad: np.ndarray) -> float:
    """The length-scaled Jacobian condition number of an arm at joints q (>= 1, inf if singular)."""
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    jacobian(np.ascontiguousarray(q_rad, dtype=float), base, offset, alpha, a, d, end, T, J)
    J[:3] /= float(limb.lengths_m[0] + limb.lengths_m[1])
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


@dataclass(frozen=True)
class SingularityScale:
    """Speed scale near singular configurations (MoveIt Servo's two-threshold rule).

    Attributes:
        lower: condition number where slowing starts (about 20 deg from a straight elbow).
        hard: condition number where the scale reaches ``floor`` (about 6 deg).
        leaving_multiplier: the band's width factor when moving away from the singularity.
        floor: the smallest scale (joint speeds never drop below floor x their limit).
    """

    lower: float = 30.0
    hard: float = 100.0
    leaving_multiplier: float = 2.0
    floor: float = 0.5

    @classmethod
    def off(cls) -> SingularityScale:
        """No slowing at all (``floor`` 1: joint speeds up to their limits everywhere)."""
        return cls(floor=1.0)

    def scale(self, kappa_now: float, kappa_next: float) -> float:
        """The speed scale (floor..1) for a move from condition number now to next."""
        kappa = max(kappa_now, kappa_next)
        if kappa <= self.lower:
            return 1.0
        upper = self.hard
        if kappa_next < kappa_now:  # leaving: slow less
            upper = self.lower + (self.hard - self.lower) * self.leaving_multiplier
        s = 1.0 - (1.0 - self.floor) * (kappa - self.lower) / (upper - self.lower)
        return float(min(1.0, max(self.floor, s)))
