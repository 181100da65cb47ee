"""Refining a grid's widest segment to (nearly) exact numbers.

A grid finds the widest segment to within one step. Here the search zooms in: a local grid of
+-1 step around the segment's (x, z) at a step ``factor`` times finer (with the full y range at
that step) picks the best row again, ``levels`` times over; then both ends of the winning row
are bisected along y to 1e-9 m. The result is exact for the row it lands on and within
resolution / factor**levels of the best (x, z) near the grid's answer.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.workspace.grid import Grid, _lattice
from hubo_cli.workspace.reach import BranchReach
from hubo_cli.workspace.search import longest_runs

BISECT_TOL_M = 1e-9
MAX_MOVES = 40  # window moves per zoom level while climbing


def _bisect_edge(reach: BranchReach, inside_m: np.ndarray, outside_m: np.ndarray,
                 bit: int) -> np.ndarray:
    """Move two points together until they straddle the branch's edge by < BISECT_TOL_M.

    ``inside_m`` is reachable on the branch, ``outside_m`` is not; both (3,). Returns the last
    inside point.
    """
    inside = inside_m.astype(float)
    outside = outside_m.astype(float)
    while np.linalg.norm(outside - inside) > BISECT_TOL_M:
        mid = 0.5 * (inside + outside)
        if reach.points(mid[None])[0] & bit:
            inside = mid
        else:
            outside = mid
    return inside


def refine_widest(reach: BranchReach, x_m: float, z_m: float, branch: int, step_m: float,
                  y_bounds_m: tuple[float, float], levels: int = 2, factor: int = 5,
                  x_bounds_m: tuple[float, float] = (-np.inf, np.inf),
                  z_bounds_m: tuple[float, float] = (-np.inf, np.inf),
                  ) -> tuple[float, float, float, float]:
    """Zoom in on the widest row of one branch near (x_m, z_m).

    Args:
        reach: the arm's per-branch reachability.
        x_m, z_m: the grid's best row (m).
        branch: the IK branch to keep (0-7).
        step_m: the grid's resolution (m).
        y_bounds_m: the y range to scan (m).
        levels, factor: number of zoom levels and the step ratio between levels.
        x_bounds_m, z_bounds_m: the search stays within these (m).

    Returns:
        (x_m, z_m, y_min_m, y_max_m) of the widest row found, ends bisected.
    """
    bit = 1 << branch
    offsets = np.arange(-factor, factor + 1)
    centre_dist = np.abs(offsets)[:, None] + np.abs(offsets)[None, :]
    edge = {0, 2 * factor}
    y0 = y1 = None
    for _ in range(levels):
        step_m /= factor
        ys = _lattice(y_bounds_m[0], y_bounds_m[1], step_m)
        for _ in range(MAX_MOVES):  # climb: move the window while its best row is on its edge
            xs = np.clip(x_m + offsets * step_m, *x_bounds_m)
            zs = np.clip(z_m + offsets * step_m, *z_bounds_m)
            masks = reach.grid(Grid(xs, ys, zs, step_m), chunk=len(xs))
            length, start = longest_runs(masks)
            runs = length[:, :, branch].astype(np.int64)
            # the longest run; ties go to the candidate nearest the window's centre (clipped
            # duplicates at a bound tie with each other, and the nearest one wins)
            ix, iz = np.unravel_index(np.argmax(runs * 1000 - centre_dist), runs.shape)
            if runs[ix, iz] == 0:
                break
            moved = (float(xs[ix]), float(zs[iz])) != (x_m, z_m)
            x_m, z_m = float(xs[ix]), float(zs[iz])
            s, n = start[ix, iz, branch], runs[ix, iz]
            y0, y1 = float(ys[s]), float(ys[s + n - 1])
            y_step = step_m
            if not moved or (ix not in edge and iz not in edge):
                break
    if y0 is None:
        raise ValueError("refine_widest: no point of the branch near the starting row")
    lo = _bisect_edge(reach, np.array([x_m, y0, z_m]), np.array([x_m, y0 - y_step, z_m]), bit)
    hi = _bisect_edge(reach, np.array([x_m, y1, z_m]), np.array([x_m, y1 + y_step, z_m]), bit)
    return x_m, z_m, float(lo[1]), float(hi[1])
