"""Closed-form inverse kinematics of a HUBO 2+ arm: all eight candidates (paper II-B).

The equations are the paper's with its printed typos fixed (C4 uses lA3 squared, not cubed; the
theta1/theta3 numerators and denominators carry a factor cos(theta2), whose sign is applied
here), solved on the inverse transform ^6T_0: n', s', a', p' are the columns of (^0T_6)^-1, the
shoulder seen from the wrist frame. Singular cases (paper cases 1-3):

1. elbow straight (sin theta4 = 0): theta3 and theta5 are collinear; theta3 keeps its previous
   value and theta5 takes up the difference;
2. shoulder roll at +-pi/2 (cos theta2 = 0): theta1 and theta3 are collinear; theta3 keeps its
   previous value and theta1 takes up the difference;
3. both: theta1 and theta3 keep their previous values and theta5 takes up the difference.

Candidate k uses the signs (theta4, theta5, theta2) = bits (2, 1, 0) of k, a set bit meaning the
negative square root. Everything is metres and radians.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import INDEX, JIT

SINGULAR_EPS = 1e-7  # |sin theta4| or |cos theta2| below this is treated as exactly singular
ROOT_TOL = 1e-12     # a cosine or sine this far beyond +-1 is rounding, not out of reach


@nb.njit(**JIT)
def wrap_to_pi(angle):
    """Wrap an angle (rad) to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@nb.njit(**JIT)
def _real_sqrt(x):
    """sqrt of the real part: the paper's real(sqrt(.)), 0 for a negative argument."""
    return math.sqrt(x) if x > 0.0 else 0.0


@nb.njit(**JIT)
def unit_clip(x):
    """(x clipped to [-1, 1], True if x was within rounding of that range): a sine or cosine
    beyond it means the target is out of reach for that branch (only the real part is kept)."""
    return min(max(x, -1.0), 1.0), abs(x) <= 1.0 + ROOT_TOL


@nb.njit(**JIT)
def outside(value, j, lower, upper):
    """True when pruning is on (lower is not empty) and joint j's value is outside its limits."""
    return lower.shape[0] == 6 and (value < lower[j] or value > upper[j])


@nb.njit(**JIT)
def drop_branch(out, exact, k0, count):
    """Mark candidates k0 .. k0+count-1 as pruned (NaN joints, not exact)."""
    for k in range(k0, k0 + count):
        for j in range(6):
            out[k, j] = np.nan
        exact[k] = False


@nb.njit(**JIT)
def arm_candidates(T60, lA2, lA3, lA4, q_prev, out, exact, lower, upper):
    """Solve the arm IK from ^6T_0 into ``out`` (8 x 6); ``exact[k]`` says no root was clipped.

    Args:
        T60: the shoulder frame 0 seen from DH frame 6 (4x4, metres).
        lA2, lA3, lA4: upper arm, forearm, wrist->hand lengths (m).
        q_prev: previous joints (6,), used only in the singular cases.
        out: (8, 6) array receiving the candidates (rad).
        exact: (8,) boolean array; False where a square root had a negative argument (the
            target is out of reach for that branch and only the real part was kept).
        lower, upper: joint limits (6,) to prune with: a branch is abandoned (NaN, not exact) as
            soon as one of its joints is outside them. Pass empty arrays to get all eight.
    """
    nx, ny, nz = T60[0, 0], T60[1, 0], T60[2, 0]
    sx, sy, sz = T60[0, 1], T60[1, 1], T60[2, 1]
    ax, ay, az = T60[0, 2], T60[1, 2], T60[2, 2]
    px, py, pz = T60[0, 3], T60[1, 3], T60[2, 3]
    pxl = px + lA4
    C4, ok4 = unit_clip((pxl * pxl + py * py + pz * pz - lA2 * lA2 - lA3 * lA3)
                        / (2.0 * lA2 * lA3))
    root4 = _real_sqrt(1.0 - C4 * C4)
    psi = math.atan2(py, pxl)
    for i4 in range(2):
        S4 = root4 if i4 == 0 else -root4
        elbow_singular = abs(S4) < SINGULAR_EPS
        if elbow_singular:  # straight elbow: make it exact so the case-1 formulas hold
            S4 = 0.0
            C4 = 1.0 if C4 > 0.0 else -1.0
        th4 = math.atan2(S4, C4)
        if outside(th4, INDEX[3], lower, upper):
            drop_branch(out, exact, i4 * 4, INDEX[4])
            continue
        if elbow_singular:
            S5 = 0.0
            ok5 = True
        else:
            S5, ok5 = unit_clip(pz / (S4 * lA2))
        root5 = _real_sqrt(1.0 - S5 * S5)
        for i5 in range(2):
            C5 = root5 if i5 == 0 else -root5
            th5 = math.atan2(S5, C5)
            th6 = wrap_to_pi(math.atan2(S4 * C5 * lA2, -C4 * lA2 - lA3) - psi)
            if outside(th6, INDEX[5], lower, upper) or (
                    not elbow_singular and outside(th5, INDEX[4], lower, upper)):
                drop_branch(out, exact, i4 * 4 + i5 * 2, INDEX[2])
                continue
            S6, C6 = math.sin(th6), math.cos(th6)
            # u, v: the combinations of theta4..6 that recur in the orientation equations
            u = C4 * C6 - C5 * S4 * S6
            v = C4 * S6 + C5 * C6 * S4
            S45 = S4 * S5
            S2, ok2 = unit_clip(ax * u - ay * v - az * S45)
            root2 = _real_sqrt(1.0 - S2 * S2)
            for i2 in range(2):
                C2 = root2 if i2 == 0 else -root2
                shoulder_singular = abs(C2) < SINGULAR_EPS
                if shoulder_singular:  # shoulder roll at +-pi/2: make it exact for cases 2, 3
                    C2 = 0.0
                    S2 = 1.0 if S2 > 0.0 else -1.0
                th2 = math.atan2(S2, C2)
                k = i4 * 4 + i5 * 2 + i2
                if outside(th2, INDEX[1], lower, upper):
                    drop_branch(out, exact, k, INDEX[1])
                    continue
                if not shoulder_singular:
                    sgn = 1.0 if C2 > 0.0 else -1.0
                    S3 = (-ax * (C6 * S4 + C4 * C5 * S6) + ay * (S4 * S6 - C4 * C5 * C6)
                          - az * C4 * S5)
                    C3 = -ax * S5 * S6 - ay * C6 * S5 + az * C5
                    S1 = -nx * u + ny * v + nz * S45
                    C1 = sx * u - sy * v - sz * S45
                    th3 = math.atan2(sgn * S3, sgn * C3)
                    th1 = math.atan2(sgn * S1, sgn * C1)
                    if elbow_singular:  # case 1: theta3 held, theta5 takes the difference
                        thT = math.atan2(-C6 * ay - S6 * ax, az)
                        if C2 < 0.0:
                            thT = thT + math.pi
                        th3 = q_prev[2]
                        th5 = wrap_to_pi(thT - th3)
                else:
                    th3 = q_prev[2]
                    if not elbow_singular:  # case 2: theta1 takes the difference
                        thT = math.atan2(S6 * sy - C6 * sx, S6 * ny - C6 * nx)
                        if S4 < 0.0:
                            thT = thT + math.pi
                        if S2 > 0.0:
                            th1 = wrap_to_pi(thT + th3)
                        else:
                            th1 = wrap_to_pi(thT - th3)
                    else:  # case 3: theta1 and theta3 held, theta5 takes the difference
                        th1 = q_prev[0]
                        if S2 > 0.0:
                            thT = math.atan2(nz, -sz)
                            th5 = wrap_to_pi(th1 - th3 - thT)
                        else:
                            thT = math.atan2(-nz, sz)
                            th5 = wrap_to_pi(thT - th1 - th3)
                out[k, 0] = wrap_to_pi(th1)
                out[k, 1] = th2
                out[k, 2] = wrap_to_pi(th3)
                out[k, 3] = th4
                out[k, 4] = wrap_to_pi(th5)
                out[k, 5] = th6
                exact[k] = ok4 and ok5 and ok2
