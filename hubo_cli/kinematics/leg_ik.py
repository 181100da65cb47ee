"""Closed-form inverse kinematics of a HUBO 2+ leg: all eight candidates (paper II-D).

The paper's equations with the printed typos fixed (C4 uses lL4 squared, not cubed; theta3
needs a half turn when cos theta2 > 0, as theta1 does when it is < 0), solved on
^6T_0 (the hip seen from the sole frame). Candidate k uses the signs (theta4, theta5, theta2)
= bits (2, 1, 0) of k, a set bit meaning the negative square root. A straight knee
(theta4 = 0) needs no special case: both theta4 roots coincide and the equations stay regular.
The hip-roll singularity (cos theta2 = 0, a leg swung sideways by 90 degrees, far outside the
limits) keeps the previous hip yaw.
"""

from __future__ import annotations

import math

import numba as nb

from hubo_cli.kinematics.arm_ik import (
    SINGULAR_EPS,
    _real_sqrt,
    drop_branch,
    outside,
    unit_clip,
    wrap_to_pi,
)
from hubo_cli.kinematics.dh import INDEX, JIT


@nb.njit(**JIT)
def leg_candidates(T60, lL3, lL4, lL5, q_prev, out, exact, lower, upper):
    """Solve the leg IK from ^6T_0 into ``out`` (8 x 6); ``exact[k]`` says no root was clipped.

    Args:
        T60: the hip frame 0 seen from DH frame 6 at the sole (4x4, metres).
        lL3, lL4, lL5: thigh, shin and ankle->sole lengths (m).
        q_prev: previous joints (6,), used only in the hip-roll singularity.
        out: (8, 6) array receiving the candidates (rad).
        exact: (8,) boolean array; False where a square root had a negative argument.
        lower, upper: joint limits to prune with, as in :func:`arm_candidates` (empty: no pruning).
    """
    nx, ny = T60[0, 0], T60[1, 0]
    sx, sy = T60[0, 1], T60[1, 1]
    ax, ay, az = T60[0, 2], T60[1, 2], T60[2, 2]
    px, py, pz = T60[0, 3], T60[1, 3], T60[2, 3]
    pxl = px + lL5
    C4, ok4 = unit_clip((pxl * pxl + py * py + pz * pz - lL3 * lL3 - lL4 * lL4)
                        / (2.0 * lL3 * lL4))
    root4 = _real_sqrt(1.0 - C4 * C4)
    rxy = math.sqrt(pxl * pxl + py * py)
    th6_base = math.atan2(py, -pxl)
    for i4 in range(2):
        S4 = root4 if i4 == 0 else -root4
        th4 = math.atan2(S4, C4)
        if outside(th4, INDEX[3], lower, upper):
            drop_branch(out, exact, i4 * 4, INDEX[4])
            continue
        psi = math.atan2(S4 * lL3, C4 * lL3 + lL4)
        for i5 in range(2):
            r = rxy if i5 == 0 else -rxy
            th5 = wrap_to_pi(math.atan2(-pz, r) - psi)
            C45 = math.cos(th4 + th5)
            th6 = th6_base
            if C45 * lL3 + math.cos(th5) * lL4 < 0.0:
                th6 = wrap_to_pi(th6 + math.pi)
            if outside(th5, INDEX[4], lower, upper) or outside(th6, INDEX[5], lower, upper):
                drop_branch(out, exact, i4 * 4 + i5 * 2, INDEX[2])
                continue
            S6, C6 = math.sin(th6), math.cos(th6)
            S2, ok2 = unit_clip(S6 * ax + C6 * ay)
            root2 = _real_sqrt(1.0 - S2 * S2)
            th345 = math.atan2(az, C6 * ax - S6 * ay)
            for i2 in range(2):
                C2 = root2 if i2 == 0 else -root2
                th2 = math.atan2(S2, C2)
                k = i4 * 4 + i5 * 2 + i2
                if abs(C2) < SINGULAR_EPS:
                    th1 = q_prev[0]
                else:
                    th1 = math.atan2(S6 * sx + C6 * sy, S6 * nx + C6 * ny)
                    if C2 < 0.0:
                        th1 = wrap_to_pi(th1 + math.pi)
                # (a'z, C6 a'x - S6 a'y) = -C2 (S345, C345): the half turn when C2 > 0 is
                # missing from the printed equation.
                th3 = th345 - th4 - th5
                if C2 > 0.0:
                    th3 = th3 + math.pi
                out[k, 0] = th1
                out[k, 1] = th2
                out[k, 2] = wrap_to_pi(th3)
                out[k, 3] = th4
                out[k, 4] = th5
                out[k, 5] = th6
                exact[k] = ok4 and ok2
