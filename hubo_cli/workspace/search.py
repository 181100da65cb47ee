"""Searches over a map's branch masks: widest horizontal segments and largest rectangles.

Sizes are measured between grid points: a run of n reachable points spans (n - 1) steps. Both
searches work per IK branch: every point of a segment or rectangle is reachable on the same
branch, so the drill can sweep it without flipping the arm.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT

N_BRANCHES = 8


@nb.njit(**JIT)
def longest_runs(masks):
    """Longest run of consecutive points along y, per x slice, z row and branch.

    Args:
        masks: branch masks, uint8 (nx, nz, ny).

    Returns:
        (length, start): int32 arrays (nx, nz, 8), the run's number of points and its first y
        index (the first longest run when several tie; length 0 and start -1 when empty).
    """
    nx, nz, ny = masks.shape
    length = np.zeros((nx, nz, N_BRANCHES), dtype=np.int32)
    start = np.full((nx, nz, N_BRANCHES), -1, dtype=np.int32)
    for row in range(nx * nz):
        i = row // nz
        k = row % nz
        for b in range(N_BRANCHES):
            bit = 1 << b
            run = 0
            for j in range(ny):
                if masks[i, k, j] & bit:
                    run += 1
                    if run > length[i, k, b]:
                        length[i, k, b] = run
                        start[i, k, b] = j - run + 1
                else:
                    run = 0
    return length, start


@nb.njit(**JIT)
def _largest_rectangle(masks_x, bit):
    """Largest (ny - 1) * (nz - 1) rectangle of points with ``bit`` set in one x slice (nz, ny).

    The histogram method: row by row, ``heights[j]`` counts the set points ending at this row
    in column j, and a stack finds, for every bar, the widest span at least that tall. Every
    maximal rectangle is seen once, and the size measure grows with width and height, so the
    best maximal rectangle is the best rectangle. Returns (score, z0, z1, y0, y1) as inclusive
    indices; score -1 when no point has the bit.
    """
    nz, ny = masks_x.shape
    heights = np.zeros(ny + 1, dtype=np.int64)  # sentinel 0 at the end empties the stack
    stack = np.empty(ny + 1, dtype=np.int64)
    best = (-1, -1, -1, -1, -1)
    for k in range(nz):
        for j in range(ny):
            heights[j] = heights[j] + 1 if masks_x[k, j] & bit else 0
        top = 0
        for j in range(ny + 1):
            while top > 0 and heights[stack[top - 1]] >= heights[j]:
                h = heights[stack[top - 1]]
                top -= 1
                left = stack[top - 1] + 1 if top > 0 else 0
                w = j - left
                if h > 0:
                    score = (w - 1) * (h - 1)
                    if score > best[0]:
                        best = (score, k - h + 1, k, left, j - 1)
            stack[top] = j
            top += 1
    return best


@nb.njit(**JIT)
def largest_rectangles(masks):
    """:func:`_largest_rectangle` for every x slice and branch: int64 (nx, 8, 5)."""
    nx = masks.shape[0]
    out = np.full((nx, N_BRANCHES, 5), -1, dtype=np.int64)
    for row in range(nx * N_BRANCHES):
        i = row // N_BRANCHES
        b = row % N_BRANCHES
        r = _largest_rectangle(masks[i], 1 << b)
        for f in range(5):
            out[i, b, f] = r[f]
    return out


def widest_per_x(length: np.ndarray, z_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every x slice, the (z index, branch) of its longest run.

    Ties go to the row nearest the neck height (smallest |z|), then to the lowest branch.

    Returns:
        (iz, branch): int arrays (nx,); the run length is ``length[i, iz[i], branch[i]]``.
    """
    nx, nz, nb_ = length.shape
    # order rows by |z| so that argmax (first maximum) prefers rows near z = 0
    order = np.argsort(np.abs(z_m), kind="stable")
    flat = length[:, order, :].reshape(nx, nz * nb_)
    best = np.argmax(flat, axis=1)
    return order[best // nb_], best % nb_


def pick_best_x(scores: np.ndarray) -> int:
    """Index of the highest score; ties go to the middle of the (first) tied stretch of x.

    On a grid the widest width is often reached by several neighbouring wall distances; the
    middle one is the safest stance (it tolerates standing a little nearer or farther).
    """
    top = scores.max()
    tied = np.flatnonzero(scores == top)
    first_run = tied[: np.argmax(np.diff(np.append(tied, tied[-1] + 2)) > 1) + 1]
    return int(first_run[(len(first_run) - 1) // 2])
