"""Per-branch reachability of tool positions at a fixed orientation, batched with numba.

A *branch* is one of the arm IK's eight sign choices (bits 2, 1, 0 of the candidate index =
negative root for theta4, theta5, theta2; see :mod:`hubo_cli.kinematics.arm_ik`). Within one
branch the joints move continuously with the target, so a set of points reachable on one branch
can be swept without flipping the arm. For every point the kernels return an 8-bit mask: bit k
set when candidate k is exact, inside the joint limits and verified by FK: the test
:func:`hubo_cli.kinematics.choice.solve_limb` uses, so ``mask != 0`` is the same as
``Limb.solve_batch(..., allow_cap=False).status == 0``.
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
import numpy as np

from hubo_cli.kinematics import Limb
from hubo_cli.kinematics.choice import (
    EXACT_POS_TOL_M,
    EXACT_ROT_TOL_RAD,
    _candidates_into,
    _within,
)
from hubo_cli.kinematics.dh import JIT, TRUE, chain_fk, in_threads, pose_error
from hubo_cli.workspace.grid import Grid, ReachSphere

SPHERE_MARGIN_M = 1e-6  # points this far outside the reach sphere are skipped without IK


@nb.njit(**JIT)
def _point_mask(T_goal, chain, lengths, lower, upper, centre, r2_max, cands, exact, q_prev,
                work):
    """Branch mask (uint8 bits) of one goal T_N_E; the last four arguments are scratch
    ((8, 6), (8,), zeros (6,) and (4, 4, 4))."""
    dx = T_goal[0, 3] - centre[0]
    dy = T_goal[1, 3] - centre[1]
    dz = T_goal[2, 3] - centre[2]
    if dx * dx + dy * dy + dz * dz > r2_max:
        return 0
    base, base_inv, offset, alpha, a, d, end, end_inv = chain
    # candidates pruned at the first joint outside the limits, as the choice step does
    _candidates_into(T_goal, chain, lengths, TRUE[0], q_prev, cands, exact, work, lower, upper)
    T_fk = work[3]
    mask = 0
    for k in range(8):
        if exact[k] and _within(cands[k], lower, upper):
            chain_fk(cands[k], base, offset, alpha, a, d, end, T_fk)
            pos, rot = pose_error(T_fk, T_goal)
            if pos <= EXACT_POS_TOL_M and rot <= EXACT_ROT_TOL_RAD:
                mask |= 1 << k
    return mask


@nb.njit(**JIT)
def _row_masks(P_m, R, chain, lengths, lower, upper, centre, r2_max, out):
    """Branch masks of tool positions P_m at one orientation R into ``out``: P_m is (rows, n,
    3), ``out`` uint8 (rows, n); each row with its own scratch space."""
    rows, n = P_m.shape[0], P_m.shape[1]
    for row in range(rows):
        T = np.zeros((4, 4))
        for r in range(3):
            for c in range(3):
                T[r, c] = R[r, c]
        T[3, 3] = 1.0
        cands = np.empty((8, 6))
        exact = np.zeros(8, dtype=np.bool_)
        q_prev = np.zeros(6)
        work = np.empty((4, 4, 4))
        for j in range(n):
            for r in range(3):
                T[r, 3] = P_m[row, j, r]
            out[row, j] = _point_mask(T, chain, lengths, lower, upper, centre, r2_max, cands,
                                      exact, q_prev, work)


def point_masks(P_m, R, chain, lengths, lower, upper, centre, r2_max) -> np.ndarray:
    """:func:`_row_masks` with the rows split over the cores: uint8 (rows, n). (One kernel
    serves both the grid and single points, and it is serial: a parallel kernel costs seconds
    to compile.)"""
    out = np.zeros(P_m.shape[:2], dtype=np.uint8)
    in_threads(P_m.shape[0], lambda i0, i1: _row_masks(
        P_m[i0:i1], R, chain, lengths, lower, upper, centre, r2_max, out[i0:i1]))
    return out


class BranchReach:
    """Per-branch reachability of one arm's tool at one orientation.

    Args:
        limb: the arm (its parameter set, limit set and tool).
        R_N_E: tool orientation in the neck frame (3x3).
        sphere: the reach sphere for that orientation (points outside it are not solved).
    """

    def __init__(self, limb: Limb, R_N_E: np.ndarray, sphere: ReachSphere) -> None:
        self.limb = limb
        self.R_N_E = np.ascontiguousarray(R_N_E, dtype=float)
        self._args = (limb.chain, limb.lengths_m, limb.lower_rad, limb.upper_rad,
                      np.ascontiguousarray(sphere.centre_m, dtype=float),
                      (sphere.radius_m + SPHERE_MARGIN_M) ** 2)

    def points(self, P_m) -> np.ndarray:
        """Branch masks (uint8, N) of tool positions P_m (N x 3, m)."""
        P = np.ascontiguousarray(np.atleast_2d(P_m), dtype=float)
        return point_masks(P.reshape(-1, 1, 3), self.R_N_E, *self._args)[:, 0]

    def grid(self, grid: Grid, chunk: int = 8,
             progress: Callable[[int, int], None] | None = None) -> np.ndarray:
        """Branch masks over ``grid``: uint8 (nx, nz, ny), solved ``chunk`` x-slices at a time.

        ``progress(done, total)`` is called after every chunk of x slices (a KeyboardInterrupt
        therefore lands between chunks, never inside the compiled kernel).
        """
        out = np.empty(grid.shape, dtype=np.uint8)
        nx = len(grid.x_m)
        for i0 in range(0, nx, chunk):
            i1 = min(i0 + chunk, nx)
            P = np.empty((i1 - i0, len(grid.z_m), len(grid.y_m), 3))  # rows along y
            P[..., 0] = grid.x_m[i0:i1, None, None]
            P[..., 1] = grid.y_m
            P[..., 2] = grid.z_m[:, None]
            out[i0:i1] = point_masks(P.reshape(-1, len(grid.y_m), 3), self.R_N_E,
                                     *self._args).reshape(P.shape[:3])
            if progress is not None:
                progress(i1, nx)
        return out
