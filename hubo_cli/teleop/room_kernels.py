"""The collision room's per-step arithmetic (:mod:`hubo_cli.teleop.room`), compiled with numba.

Each was several small numpy calls a step of the clear search; each gives what they gave, to
the last bit where the result becomes a joint target (the same operations in the same order).
"""

from __future__ import annotations

import math

import numba as nb

from hubo_cli.kinematics.dh import JIT
from hubo_cli.kinematics.reach import jacobian, rotation_error


@nb.njit(**JIT)
def weighted_error(q, base, offset, alpha, a, d, end, T_goal, w, T, J, e):
    """The clear search's error at the arm's joints ``q`` (rad; the chain as in
    :func:`~hubo_cli.kinematics.dh.chain_fk`): the hand's pose into ``T`` and its Jacobian
    into ``J`` (:func:`~hubo_cli.kinematics.reach.jacobian`), into ``e`` the position error
    ``T_goal``'s minus the hand's (m) and the rotation error (rad), each row times ``w``.
    Returns |e|^2 (summed in order: within a rounding of numpy's ``e @ e``)."""
    jacobian(q, base, offset, alpha, a, d, end, T, J)
    for i in range(3):
        e[i] = T_goal[i, 3] - T[i, 3]
    rotation_error(T, T_goal, e[3:])
    c = 0.0
    for i in range(6):
        e[i] *= w[i]
        c += e[i] * e[i]
    return c


@nb.njit(**JIT)
def clipped_step(q, first, dq, scale, lo, hi, out):
    """``out`` = ``q`` with its entries ``first``... moved by ``scale dq`` and clipped to
    [``lo``, ``hi``] (as ``np.minimum(np.maximum(q + scale * dq, lo), hi)`` for the finite,
    ordered bounds :func:`~hubo_cli.kinematics.reach.branch_box` gives: a NaN in ``q`` or
    ``dq`` stays NaN; a NaN bound would be ignored, where numpy's would give NaN)."""
    for i in range(q.shape[0]):
        out[i] = q[i]
    for j in range(dq.shape[0]):
        v = q[first + j] + scale * dq[j]
        if v < lo[j]:
            v = lo[j]
        if v > hi[j]:
            v = hi[j]
        out[first + j] = v


@nb.njit(**JIT)
def goal_within(T_was, T_goal, max_m, min_cos):
    """``T_goal`` (4x4) lies within ``max_m`` of ``T_was``'s position and its rotation from
    ``T_was``'s has a cosine of at least ``min_cos`` ((trace(R_was^T R_goal) - 1) / 2)."""
    dx = T_goal[0, 3] - T_was[0, 3]
    dy = T_goal[1, 3] - T_was[1, 3]
    dz = T_goal[2, 3] - T_was[2, 3]
    if math.sqrt(dx * dx + dy * dy + dz * dz) > max_m:
        return False
    trace = 0.0
    for i in range(3):
        for k in range(3):
            trace += T_was[k, i] * T_goal[k, i]
    return (trace - 1.0) / 2.0 >= min_cos
