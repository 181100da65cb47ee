"""The per-period arithmetic of :mod:`hubo_cli.teleop.target`, compiled with numba.

Each period the target previews each arm's way to its target (:func:`path_swing_m`: how far
the hand strays from a straight line on it) and measures each hand (:func:`hand_errors`: its
pose from the measured joints, its errors to the goal); the hand mapper checks each operator
sample and maps it (:func:`operator_pose_plausible`, :func:`free_goal`). Done with numpy each
was a dozen or more small-array calls; here each is one compiled call.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, chain_fk, matmul4, pose_error


@nb.njit(**JIT)
def path_swing_m(path, base, offset, alpha, a, d, end):
    """The largest distance (m) of the hand from the segment between its first and last
    positions, over the interior rows of ``path`` (k x 6 joints, rad; k >= 3), the chain as
    in :func:`hubo_cli.kinematics.dh.chain_fk`."""
    k = path.shape[0]
    T = np.empty((4, 4))
    points = np.empty((k, 3))
    for i in range(k):
        chain_fk(path[i], base, offset, alpha, a, d, end, T)
        points[i, 0], points[i, 1], points[i, 2] = T[0, 3], T[1, 3], T[2, 3]
    l0 = points[k - 1, 0] - points[0, 0]
    l1 = points[k - 1, 1] - points[0, 1]
    l2 = points[k - 1, 2] - points[0, 2]
    length2 = l0 * l0 + l1 * l1 + l2 * l2
    worst = 0.0
    for i in range(1, k - 1):
        p0 = points[i, 0] - points[0, 0]
        p1 = points[i, 1] - points[0, 1]
        p2 = points[i, 2] - points[0, 2]
        along = 0.0
        if not length2 < 1e-18:
            along = min(max((p0 * l0 + p1 * l1 + p2 * l2) / length2, 0.0), 1.0)
        e0, e1, e2 = p0 - along * l0, p1 - along * l1, p2 - along * l2
        worst = max(worst, e0 * e0 + e1 * e1 + e2 * e2)
    return math.sqrt(worst)


@nb.njit(**JIT)
def hand_errors(q, base, offset, alpha, a, d, end, corrected, lift_m, T_S_N, T_goal, world,
                T_actual):
    """One hand measured: its tool pose in S from the arm's measured joints ``q`` (rad; the
    chain as in :func:`~hubo_cli.kinematics.dh.chain_fk`) into ``T_actual`` (4x4, m): through
    the measured neck frame ``T_S_N`` (4x4) if ``corrected``, else lifted by ``lift_m``.
    Returns its position and orientation errors to ``T_goal`` (m, rad) and, if ``world``, the
    position error of the tool through ``T_S_N`` (m; else NaN)."""
    T_N_E = np.empty((4, 4))
    chain_fk(q, base, offset, alpha, a, d, end, T_N_E)
    if corrected:
        matmul4(T_S_N, T_N_E, T_actual)
    else:
        T_actual[:, :] = T_N_E
        T_actual[2, 3] += lift_m
    position_m, rotation_rad = pose_error(T_actual, T_goal)
    world_m = math.nan
    if world:
        T_S_E = np.empty((4, 4))
        matmul4(T_S_N, T_N_E, T_S_E)
        dx, dy, dz = (T_goal[0, 3] - T_S_E[0, 3], T_goal[1, 3] - T_S_E[1, 3],
                      T_goal[2, 3] - T_S_E[2, 3])
        world_m = math.sqrt(dx * dx + dy * dy + dz * dz)
    return position_m, rotation_rad, world_m


@nb.njit(**JIT)
def operator_pose_plausible(T_O, max_range_m):
    """The operator's hand pose (4x4) is finite and its position within ``max_range_m`` on
    each axis."""
    for i in range(4):
        for j in range(4):
            if not math.isfinite(T_O[i, j]):
                return False
    return max(abs(T_O[0, 3]), abs(T_O[1, 3]), abs(T_O[2, 3])) <= max_range_m


@nb.njit(**JIT)
def free_goal(T_O, T_O_ref, T_S_hand0, last_mapped, scale, max_step_m, min_turn_cos, T_goal):
    """The free mode's hand goal into ``T_goal`` (4x4): the orientation (R_now R_ref^T)
    R_hand0, the position p_hand0 + scale (p_now - p_ref). Returns whether it lies within
    ``max_step_m`` of ``last_mapped``'s position and turns from ``last_mapped``'s orientation
    by an angle whose cosine is at least ``min_turn_cos``."""
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = (T_O[i, 0] * T_O_ref[j, 0] + T_O[i, 1] * T_O_ref[j, 1]
                       + T_O[i, 2] * T_O_ref[j, 2])
    step2 = 0.0
    trace = 0.0
    for i in range(3):
        for j in range(3):
            T_goal[i, j] = (A[i, 0] * T_S_hand0[0, j] + A[i, 1] * T_S_hand0[1, j]
                            + A[i, 2] * T_S_hand0[2, j])
            trace += T_goal[i, j] * last_mapped[i, j]  # trace(R_last^T R_goal)
        T_goal[i, 3] = T_S_hand0[i, 3] + scale * (T_O[i, 3] - T_O_ref[i, 3])
        step = T_goal[i, 3] - last_mapped[i, 3]
        step2 += step * step
        T_goal[3, i] = 0.0
    T_goal[3, 3] = 1.0
    return math.sqrt(step2) <= max_step_m and (trace - 1.0) / 2.0 >= min_turn_cos


@nb.njit(**JIT)
def max_abs_difference(x, y):
    """``np.max(np.abs(x - y))`` of two vectors (NaN if any difference is NaN)."""
    worst = 0.0
    for i in range(x.shape[0]):
        d = abs(x[i] - y[i])
        if d != d:
            return d
        if d > worst:
            worst = d
    return worst


@nb.njit(**JIT)
def tilt_rad(q_wxyz):
    """:func:`hubo_cli.geometry.tilt_rad_of_quat_wxyz` of one quaternion (4,) w, x, y, z (any
    norm): the same libm calls, as a float."""
    return 2.0 * math.atan2(math.hypot(q_wxyz[1], q_wxyz[2]), math.hypot(q_wxyz[0], q_wxyz[3]))
