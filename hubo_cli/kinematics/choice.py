"""Choosing one of the eight IK candidates (paper II-E, improved), compiled with numba.

Rule, per target:

1. *exact*: among candidates inside the joint limits whose FK reaches the target (checked, not
   assumed), take the one closest to the previous joints, or with the smallest sum of squares
   when there are none;
2. *capped*: otherwise cap every candidate to the limits, run FK, and take the one whose end
   frame lands closest to the target position, if it is within ``hold_m`` (5 cm);
3. *held*: otherwise keep the previous joints;
4. *unreachable*: as 3 but with no previous joints to keep (the capped best is returned).

:func:`solve_limb_on_branch` is the rule used while operating (teleoperation): the exact
candidate on the arm's current IK branch, or else *nearest*: the reachable pose on that branch
nearest to the goal, position first (:mod:`.reach`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.kinematics.arm_ik import arm_candidates
from hubo_cli.kinematics.dh import (
    JIT,
    TRUE,
    chain_fk,
    in_threads,
    invert4,
    matmul4,
    pose_error,
)
from hubo_cli.kinematics.leg_ik import leg_candidates
from hubo_cli.kinematics.reach import branch_box, nearest_on_branch

EXACT = 0
CAPPED = 1
HELD = 2
UNREACHABLE = 3
NEAREST = 4
STATUS_NAMES = ("exact", "capped", "held", "unreachable", "nearest")

EXACT_POS_TOL_M = 1e-6
EXACT_ROT_TOL_RAD = 1e-6


@nb.njit(**JIT)
def limb_candidates(T_goal, chain, lengths, is_arm, q_prev, out, exact):
    """All eight candidates for a goal end frame in the neck frame.

    Args:
        T_goal: goal end-effector pose T_N_E (4x4, m).
        chain: (base, base_inv, offset, alpha, a, d, end, end_inv) of the limb.
        lengths: the three lengths the limb's IK needs (m).
        is_arm: arm equations if True, leg equations otherwise.
        q_prev: previous joints (rad), used by the singular cases.
        out, exact: (8, 6) and (8,) outputs.
    """
    scratch = np.empty((3, 4, 4))
    no_limits = np.empty(0)
    _candidates_into(T_goal, chain, lengths, is_arm, q_prev, out, exact, scratch, no_limits,
                     no_limits)


@nb.njit(**JIT)
def _candidates_into(T_goal, chain, lengths, is_arm, q_prev, out, exact, scratch, lower, upper):
    """:func:`limb_candidates` with scratch space (3 x 4 x 4) and optional pruning limits."""
    base_inv, end_inv = chain[1], chain[7]
    matmul4(base_inv, T_goal, scratch[0])
    matmul4(scratch[0], end_inv, scratch[1])
    invert4(scratch[1], scratch[2])
    if is_arm:
        arm_candidates(scratch[2], lengths[0], lengths[1], lengths[2], q_prev, out, exact,
                       lower, upper)
    else:
        leg_candidates(scratch[2], lengths[0], lengths[1], lengths[2], q_prev, out, exact,
                       lower, upper)


@nb.njit(**JIT)
def _within(q, lower, upper):
    for j in range(6):
        if q[j] < lower[j] or q[j] > upper[j]:
            return False
    return True


@nb.njit(**JIT)
def _copy6(q, out):
    """out[:] = q for joint vectors, as a loop: an array assignment compiles numba's
    shape-mismatch error message (string formatting, seconds on every cold cache)."""
    for j in range(6):
        out[j] = q[j]


@nb.njit(**JIT)
def _distance2(q, q_prev, has_prev):
    s = 0.0
    for j in range(6):
        e = q[j] - q_prev[j] if has_prev else q[j]
        s += e * e
    return s


@nb.njit(**JIT)
def solve_limb(T_goal, chain, lengths, is_arm, lower, upper, q_prev, has_prev, hold_m, allow_cap,
               q_out):
    """Choose a solution for one goal; returns (status, position error m, rotation error rad).

    ``allow_cap=False`` skips step 2-4 work for callers that only need reachability (the
    workspace map): an unreachable goal then returns UNREACHABLE at once with infinite errors.
    """
    base, base_inv, offset, alpha, a, d, end, end_inv = chain
    work = np.empty((4, 4, 4))  # one allocation: 3 scratch transforms + the FK result
    T = work[3]
    cands = np.empty((9, 6))    # 8 candidates + the capped vector
    capped = cands[8]
    flags = np.zeros(16, dtype=np.bool_)
    exact = flags[:8]
    usable = flags[8:]
    # first pass prunes branches as soon as a joint leaves its limits (cheap common case)
    _candidates_into(T_goal, chain, lengths, is_arm, q_prev, cands, exact, work, lower, upper)
    for k in range(8):
        usable[k] = exact[k] and _within(cands[k], lower, upper)
    while True:  # best usable candidate, verified by FK; drop it if FK disagrees
        best = -1
        best_d = np.inf
        for k in range(8):
            if usable[k]:
                dk = _distance2(cands[k], q_prev, has_prev)
                if dk < best_d:
                    best_d = dk
                    best = k
        if best < 0:
            break
        chain_fk(cands[best], base, offset, alpha, a, d, end, T)
        pos, rot = pose_error(T, T_goal)
        if pos <= EXACT_POS_TOL_M and rot <= EXACT_ROT_TOL_RAD:
            _copy6(cands[best], q_out)
            return EXACT, pos, rot
        usable[best] = False
    if not allow_cap:
        for j in range(6):
            q_out[j] = np.nan
        return UNREACHABLE, np.inf, np.inf
    # nothing exact within the limits: all eight candidates, unpruned, for capping
    no_limits = np.empty(0)
    _candidates_into(T_goal, chain, lengths, is_arm, q_prev, cands, exact, work, no_limits,
                     no_limits)
    best_pos = np.inf
    best_rot = np.inf
    for k in range(8):
        for j in range(6):
            capped[j] = min(max(cands[k, j], lower[j]), upper[j])
        chain_fk(capped, base, offset, alpha, a, d, end, T)
        pos, rot = pose_error(T, T_goal)
        if pos < best_pos or (pos == best_pos and rot < best_rot):
            best_pos = pos
            best_rot = rot
            _copy6(capped, q_out)
    if best_pos <= hold_m:
        status = EXACT if best_pos <= EXACT_POS_TOL_M and best_rot <= EXACT_ROT_TOL_RAD else CAPPED
        return status, best_pos, best_rot
    if has_prev:
        _copy6(q_prev, q_out)
        chain_fk(q_prev, base, offset, alpha, a, d, end, T)
        pos, rot = pose_error(T, T_goal)
        return HELD, pos, rot
    return UNREACHABLE, best_pos, best_rot


@nb.njit(**JIT)
def solve_limb_rows(T_goals, chain, lengths, is_arm, lower, upper, q_prevs, has_prev, hold_m,
                    allow_cap, q_out, status, pos_err, rot_err):
    """:func:`solve_limb` over N goals (N x 4 x 4; q_prevs N x 6) into the N-row outputs."""
    for i in range(T_goals.shape[0]):
        s, p, r = solve_limb(T_goals[i], chain, lengths, is_arm, lower, upper, q_prevs[i],
                             has_prev, hold_m, allow_cap, q_out[i])
        status[i] = s
        pos_err[i] = p
        rot_err[i] = r


def solve_limb_batch(T_goals, chain, lengths, is_arm, lower, upper, q_prevs, has_prev, hold_m,
                     allow_cap):
    """:func:`solve_limb` over N goals (N x 4 x 4, C-contiguous) on all cores; q_prevs is N x 6.

    Returns (q (N x 6), status int8 (N,), position errors (N,), rotation errors (N,)).
    """
    n = T_goals.shape[0]
    q_out = np.empty((n, 6))
    status = np.empty(n, dtype=np.int8)
    pos_err = np.empty(n)
    rot_err = np.empty(n)

    def run(i0: int, i1: int) -> None:
        solve_limb_rows(T_goals[i0:i1], chain, lengths, is_arm, lower, upper, q_prevs[i0:i1],
                        has_prev, hold_m, allow_cap, q_out[i0:i1], status[i0:i1],
                        pos_err[i0:i1], rot_err[i0:i1])

    in_threads(n, run)
    return q_out, status, pos_err, rot_err


@nb.njit(**JIT)
def solve_limb_on_branch(T_goal, chain, lengths, lower, upper, q_prev, branch, margins, w_pos,
                         w_rot, iterations, q_out):
    """Solve an arm goal without leaving ``branch``; returns (status, position m, rotation rad).

    EXACT: the closed form's candidate on the branch (within the limits and ``margins`` inside
    the branch, or no closer to its boundary than ``q_prev``; FK-verified; the one
    closest to ``q_prev`` if two qualify). Otherwise NEAREST: at most
    ``iterations`` damped least-squares steps from ``q_prev`` (within the limits) toward the pose
    nearest to the goal on the branch, weighted by ``w_pos`` (1/m) and ``w_rot`` (m/rad)
    (:func:`hubo_cli.kinematics.reach.nearest_on_branch`).
    """
    # numba's on-disk cache of this function holds nearest_on_branch compiled in and is checked
    # against this file only: a change to the search must come with a change here
    base, base_inv, offset, alpha, a, d, end, end_inv = chain
    work = np.empty((4, 4, 4))
    T = work[3]
    cands = np.empty((8, 6))
    exact = np.zeros(8, dtype=np.bool_)
    _candidates_into(T_goal, chain, lengths, TRUE[0], q_prev, cands, exact, work, lower, upper)
    box = np.empty((2, 6))
    branch_box(q_prev, branch, margins, lower, upper, box[0], box[1])
    best = -1
    best_d = np.inf
    for k in range(8):
        if exact[k] and _within(cands[k], box[0], box[1]):
            dk = _distance2(cands[k], q_prev, TRUE[0])
            if dk < best_d:
                chain_fk(cands[k], base, offset, alpha, a, d, end, T)
                pos, rot = pose_error(T, T_goal)
                if pos <= EXACT_POS_TOL_M and rot <= EXACT_ROT_TOL_RAD:
                    best_d = dk
                    best = k
    if best >= 0:
        _copy6(cands[best], q_out)
        chain_fk(q_out, base, offset, alpha, a, d, end, T)
        pos, rot = pose_error(T, T_goal)
        return EXACT, pos, rot
    pos, rot, _ = nearest_on_branch(T_goal, chain, lower, upper, q_prev, branch, margins, w_pos,
                                    w_rot, iterations, q_out)
    return NEAREST, pos, rot
