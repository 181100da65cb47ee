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

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, kernel_array
from hubo_cli.kinematics.limb import Limb
from hubo_cli.kinematics.reach import jacobian

JACOBI_SWEEPS = 30  # one-sided Jacobi sweeps at most (a 6x6 Jacobian converges in 5-8)


def condition_number(limb: Limb, q_rad: np.ndarray) -> float:
    """The length-scaled Jacobian condition number of an arm at joints q (>= 1, inf if singular)."""
    base, _, offset, alpha, a, d, end, _ = limb.chain
    return _condition(kernel_array(q_rad), base, offset, alpha, a, d, end,
                      float(limb.lengths_m[0] + limb.lengths_m[1]))


@nb.njit(**JIT)
def _condition(q, base, offset, alpha, a, d, end, length_m):
    """:func:`condition_number` in one compiled call: the Jacobian, its linear rows divided by
    ``length_m``, its singular values by one-sided Jacobi rotations (Hestenes; the column
    norms once the columns are orthogonal, to a few ulps of LAPACK's)."""
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    jacobian(q, base, offset, alpha, a, d, end, T, J)
    for i in range(3):
        for j in range(6):
            J[i, j] /= length_m
    for _ in range(JACOBI_SWEEPS):
        rotated = False
        for i in range(5):
            for j in range(i + 1, 6):
                alpha_ii = beta_jj = gamma = 0.0
                for k in range(6):
                    alpha_ii += J[k, i] * J[k, i]
                    beta_jj += J[k, j] * J[k, j]
                    gamma += J[k, i] * J[k, j]
                if abs(gamma) <= 1e-15 * math.sqrt(alpha_ii * beta_jj):
                    continue
                rotated = True
                zeta = (beta_jj - alpha_ii) / (2.0 * gamma)
                t = math.copysign(1.0, zeta) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for k in range(6):
                    x, y = J[k, i], J[k, j]
                    J[k, i] = c * x - s * y
                    J[k, j] = s * x + c * y
        if not rotated:
            break
    largest, smallest = 0.0, math.inf
    for j in range(6):
        norm = 0.0
        for k in range(6):
            norm += J[k, j] * J[k, j]
        norm = math.sqrt(norm)
        largest = max(largest, norm)
        smallest = min(smallest, norm)
    return largest / smallest if smallest > 0 else math.inf


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
