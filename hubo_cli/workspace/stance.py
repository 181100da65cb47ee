"""Where the robot should stand to cut a hole: the ``auto`` stance of scripted tasks.

:func:`best_stance` answers "how far from the wall (neck to wall, along x) should the robot
stand, and which rectangle of the wall can the tool then reach on one IK branch". Without a
requested size it returns the stance with the largest reachable rectangle (area). With a
requested size it returns the stance where that size fits with the most room: the largest
rectangle of the requested aspect ratio that is reachable, with the requested hole centred in
it.

``vertical="legs"`` follows the paper's own reasoning (IV, III-A): the legs raise and lower the
body, so the arm only has to sweep horizontally at one height. The stance is then the one with
the widest one-branch horizontal segment, ``rectangle`` is that segment (zero height) and the
requested hole is centred on it; its vertical extent is the legs' job.

The branch masks are cached on disk (:mod:`hubo_cli.workspace.cache`), so after the first call
for a parameter set an answer takes milliseconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from hubo_cli.errors import InputError, quoted
from hubo_cli.kinematics.dh import JIT
from hubo_cli.workspace.maps import (
    DEFAULT_RESOLUTION_M,
    DEFAULT_X_RANGE_M,
    WorkspaceMap,
    compute_map,
)
from hubo_cli.workspace.results import Rectangle
from hubo_cli.workspace.search import N_BRANCHES, pick_best_x


@dataclass(frozen=True)
class StanceResult:
    """The answer of :func:`best_stance`.

    Attributes:
        wall_distance_m: neck-to-wall distance along the neck frame's x (m).
        rectangle: the largest reachable rectangle at that distance (of the requested aspect
            ratio when a size was asked for).
        cut: the requested hole centred in ``rectangle`` (None when no size was asked for, or
            when it fits nowhere).
        fits: False when a size was asked for and no stance reaches it (``rectangle`` is then
            the largest rectangle of any shape).
        vertical: ``arm`` (the arm reaches the whole hole) or ``legs`` (the arm sweeps one
            height; the legs move the body for the rest).
        arm, tool, params, limits, orientation, resolution_m: what was asked.
    """

    wall_distance_m: float
    rectangle: Rectangle
    cut: Rectangle | None
    fits: bool
    vertical: str
    arm: str
    tool: str
    params: str
    limits: str
    orientation: str
    resolution_m: float

    @property
    def rectangle_bounds_m(self) -> tuple[float, float, float, float]:
        """(y_min, y_max, z_min, z_max) of :attr:`rectangle` in the neck frame (m)."""
        r = self.rectangle
        return r.y_min_m, r.y_max_m, r.z_min_m, r.z_max_m


@nb.njit(**JIT)
def _window_fits(sums, nh, nw):
    """First (z0, y0) of an all-set nh x nw window in an integral image, or (-1, -1)."""
    nz, ny = sums.shape[0] - 1, sums.shape[1] - 1
    need = nh * nw
    for z0 in range(nz - nh + 1):
        for y0 in range(ny - nw + 1):
            total = (sums[z0 + nh, y0 + nw] - sums[z0, y0 + nw] - sums[z0 + nh, y0]
                     + sums[z0, y0])
            if total == need:
                return z0, y0
    return -1, -1


@nb.njit(**JIT)
def largest_fits(masks, aspect):
    """Per x slice, the widest all-set window of a fixed aspect ratio on one branch.

    Args:
        masks: branch masks (nx, nz, ny) uint8.
        aspect: height / width of the rectangle.

    Returns:
        int64 (nx, 4): (steps wide, branch, z0, y0) per x (steps wide -1 when none); a
        rectangle w steps wide is ceil(w * aspect) steps tall.
    """
    nx, nz, ny = masks.shape
    out = np.full((nx, 4), -1, dtype=np.int64)
    for i in range(nx):
        sums = np.zeros((nz + 1, ny + 1), dtype=np.int64)
        for b in range(N_BRANCHES):
            bit = 1 << b
            for k in range(nz):
                row = 0
                for j in range(ny):
                    row += 1 if masks[i, k, j] & bit else 0
                    sums[k + 1, j + 1] = sums[k, j + 1] + row
            if sums[nz, ny] == 0:
                continue
            lo, hi = out[i, 0], ny  # widths (in steps) known to fit / known not to fit
            while hi - lo > 1:
                w = (lo + hi) // 2
                h = math.ceil(w * aspect - 1e-9)
                z0, y0 = _window_fits(sums, h + 1, w + 1) if h < nz else (-1, -1)
                if z0 >= 0:
                    lo = w
                    out[i, 0] = w
                    out[i, 1] = b
                    out[i, 2] = z0
                    out[i, 3] = y0
                else:
                    hi = w
    return out


def best_stance(tool: str = "drill", arm: str = "right", size_m: tuple[float, float] | None = None,
                params: str = "as-built", limits: str = "table4", orientation: str = "wall",
                resolution_m: float = DEFAULT_RESOLUTION_M,
                x_range_m: tuple[float, float] = DEFAULT_X_RANGE_M,
                cache: bool = True, vertical: str = "arm",
                wall_distance_m: float | None = None) -> StanceResult:
    """The stance distance from which the tool reaches the largest rectangle of the wall.

    Args:
        tool: arm tool frame (``drill`` by default: the bit's middle, bit along x).
        arm: ``right`` or ``left``.
        size_m: (width, height) of a hole to cut (m); None for the largest hole of any shape.
        params, limits: model parameter set and joint-limit set.
        orientation: tool orientation (``wall``: orthogonal to a wall facing the robot).
        resolution_m: grid step (m). Rectangles are snapped to the grid, all grid points inside
            reachable.
        x_range_m: the wall distances considered (m).
        cache: keep the underlying map's masks in the user's cache folder.
        vertical: ``arm`` (the whole hole within the arm's reach) or ``legs`` (the arm sweeps
            one height, the legs move the body up and down; see the module docstring).
        wall_distance_m: stand at this distance (m, the nearest grid slice) instead of
            searching for the best one; ``vertical="arm"`` with a ``size_m`` only.

    Returns:
        a :class:`StanceResult` (``fits`` False when a requested size is reachable nowhere).
    """
    if size_m is not None and not (size_m[0] > 0 and size_m[1] > 0):
        raise InputError(f"hole size must be positive, got {size_m}",
                         hint="give width and height in metres, e.g. (0.15, 0.10)")
    if vertical not in ("arm", "legs"):
        raise InputError(f"unknown vertical mode {quoted(vertical)}", hint="use 'arm' or 'legs'")
    wmap = compute_map(arm, tool, orientation, params, limits, resolution_m, x_range_m,
                       refine=False, cache=cache)
    common = dict(vertical=vertical, arm=arm, tool=tool, params=params, limits=limits,
                  orientation=orientation, resolution_m=resolution_m)
    if wall_distance_m is not None and (vertical != "arm" or size_m is None):
        raise InputError("a fixed wall distance needs a hole size and vertical='arm'",
                         hint="pass size_m=(width, height)")
    if vertical == "legs":
        return _legs_stance(wmap, size_m, common)
    if size_m is not None:
        fixed = None if wall_distance_m is None else int(np.argmin(np.abs(wmap.grid.x_m
                                                                          - wall_distance_m)))
        found = _fit_size(wmap, size_m, fixed)
        if found is not None:
            rect, cut, fits = found
            return StanceResult(rect.wall_distance_m, rect, cut, fits, **common)
        if fixed is not None:
            empty = Rectangle(float(wmap.grid.x_m[fixed]), 0.0, 0.0, 0.0, 0.0, -1)
            return StanceResult(empty.wall_distance_m, empty, None, False, **common)
    rect = wmap.best_rectangle
    return StanceResult(rect.wall_distance_m, rect, None, size_m is None, **common)


def _fit_size(wmap: WorkspaceMap, size_m: tuple[float, float],
              fixed_index: int | None = None) -> tuple[Rectangle, Rectangle, bool] | None:
    """The stance where a hole of ``size_m`` fits with the most room: (the largest window of
    its shape, the hole centred in it, True), or None. At a fixed x slice (``fixed_index``) a
    window too small for the hole still places it: (window, hole centred on it, False)."""
    width_m, height_m = size_m
    g = wmap.grid
    res = g.resolution_m
    fits = largest_fits(wmap.masks, height_m / width_m)
    steps = fits[:, 0]
    big_enough = steps * res >= width_m - 1e-9
    if fixed_index is not None:
        i = fixed_index
        if steps[i] <= 0:
            return None
    elif not big_enough.any():
        return None
    else:
        i = pick_best_x(np.where(big_enough, steps, -1))
    w, b, z0, y0 = (int(v) for v in fits[i])
    h = math.ceil(w * height_m / width_m - 1e-9)
    x = float(g.x_m[i])
    rect = Rectangle(x, float(g.y_m[y0]), float(g.y_m[y0 + w]), float(g.z_m[z0]),
                     float(g.z_m[z0 + h]), b)
    _, yc, zc = rect.centre_m
    cut = Rectangle(x, yc - width_m / 2, yc + width_m / 2, zc - height_m / 2, zc + height_m / 2, b)
    return rect, cut, bool(big_enough[i])


def _legs_stance(wmap: WorkspaceMap, size_m: tuple[float, float] | None,
                 common: dict) -> StanceResult:
    """Stance by the widest one-branch segment; the hole is centred on it."""
    seg = wmap.widest_grid
    line = Rectangle(seg.wall_distance_m, seg.y_min_m, seg.y_max_m, seg.z_m, seg.z_m,
                     seg.branch)
    if size_m is None:
        return StanceResult(seg.wall_distance_m, line, None, True, **common)
    width_m, height_m = size_m
    if width_m > seg.width_m + 1e-9:
        return StanceResult(seg.wall_distance_m, line, None, False, **common)
    yc = 0.5 * (seg.y_min_m + seg.y_max_m)
    cut = Rectangle(seg.wall_distance_m, yc - width_m / 2, yc + width_m / 2,
                    seg.z_m - height_m / 2, seg.z_m + height_m / 2, seg.branch)
    return StanceResult(seg.wall_distance_m, line, cut, True, **common)
