"""The workspace map of one arm: reachability over a grid, widest segments, largest rectangles.

Criterion (paper IV, made precise): for every wall distance x, the widest contiguous horizontal
segment of tool positions (any height z) that is reachable on ONE IK branch, so that the drill
can sweep it without flipping the arm; the best stance is the x with the widest such segment.
Beyond the paper, the largest axis-aligned rectangle in the wall plane reachable on one branch
is found for every x as well (the largest hole a task can cut from that stance).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.errors import InputError, quoted
from hubo_cli.workspace.cache import cache_key, load_masks, save_masks
from hubo_cli.workspace.grid import Grid, make_grid, orientation_matrix, reach_sphere
from hubo_cli.workspace.limbs import arm_limb
from hubo_cli.workspace.reach import BranchReach
from hubo_cli.workspace.refine import refine_widest
from hubo_cli.workspace.results import Rectangle, Segment, mm
from hubo_cli.workspace.search import (
    largest_rectangles,
    longest_runs,
    pick_best_x,
    widest_per_x,
)

ARMS = ("right", "left")
DEFAULT_X_RANGE_M = (0.30, 0.65)
DEFAULT_RESOLUTION_M = 0.005
POINTS_PER_CHUNK = 200_000  # grid points per kernel call (progress and Ctrl-C granularity)

# Paper section IV: the right arm's joints at the two ends of its 390 mm segment (rad).
PAPER_SEGMENT_Q_RAD = (
    np.array([-0.9914, -0.3651, -0.8339, -1.1618, -1.6542, 0.8894]),  # far right (min y)
    np.array([-1.1853, 0.1213, 1.1383, -1.2893, -1.8826, -1.1184]),   # far left (max y)
)
MIRROR_Q = np.array([1.0, -1.0, -1.0, 1.0, -1.0, 1.0])  # right-arm joints -> mirrored left arm
PAPER_BEST = {"wall_distance_mm": 484.0, "width_mm": 390.0, "height_mm": 75.0}

Progress = Callable[[str, int, int], None]


@dataclass
class WorkspaceMap:
    """One arm's workspace at a fixed tool orientation, and what the searches found.

    Per-point arrays have the grid's layout (nx, nz, ny); per-distance arrays have nx entries.

    Attributes:
        arm, tool, params, limits, orientation: what was mapped.
        R_N_E: the tool orientation in the neck frame (3x3).
        grid: the grid of tool positions (m).
        masks: branch masks (uint8): bit k set when IK candidate k reaches the point exactly
            within the joint limits.
        run_length, run_start, run_z_index, run_branch: the widest one-branch run of every x
            slice (number of points, first y index, z index, branch).
        rect_cells: (nx, 5) per x, the largest one-branch rectangle as
            (branch, z0, z1, y0, y1) inclusive indices (-1 when none).
        best_index: the x index of the widest segment on the grid.
        widest: the widest segment (refined when asked, else the grid's).
        widest_grid: the grid's widest segment.
        best_rectangle: the largest rectangle over all x.
        seconds: wall-clock time of the whole computation.
    """

    arm: str
    tool: str
    params: str
    limits: str
    orientation: str
    R_N_E: np.ndarray
    grid: Grid
    masks: np.ndarray
    run_length: np.ndarray
    run_start: np.ndarray
    run_z_index: np.ndarray
    run_branch: np.ndarray
    rect_cells: np.ndarray
    best_index: int
    widest: Segment
    widest_grid: Segment
    best_rectangle: Rectangle
    seconds: float
    reach: BranchReach = field(repr=False)

    @property
    def reachable(self) -> np.ndarray:
        """Reachable on any branch (bool, nx x nz x ny): what ``Limb.solve`` calls exact."""
        return self.masks != 0

    @property
    def widths_m(self) -> np.ndarray:
        """Widest one-branch segment per wall distance (m; NaN where nothing is reachable)."""
        w = (self.run_length - 1) * self.grid.resolution_m
        return np.where(self.run_length > 0, w, np.nan)

    @property
    def rect_widths_m(self) -> np.ndarray:
        """Width of the largest rectangle per wall distance (m; NaN where none)."""
        r = self.rect_cells
        return np.where(r[:, 0] >= 0, (r[:, 4] - r[:, 3]) * self.grid.resolution_m, np.nan)

    @property
    def rect_heights_m(self) -> np.ndarray:
        """Height of the largest rectangle per wall distance (m; NaN where none)."""
        r = self.rect_cells
        return np.where(r[:, 0] >= 0, (r[:, 2] - r[:, 1]) * self.grid.resolution_m, np.nan)

    @property
    def paper_setup(self) -> bool:
        """True for the paper's study (drill orthogonal to the wall), where its numbers apply."""
        return self.tool == "drill" and self.orientation == "wall"

    def paper_ends(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The paper's two segment ends through this map's arm (mirrored for the left arm).

        Returns:
            (q_rad (2, 6), P_m (2, 3), masks (2,)): the joints, where the tool lands, and the
            branch masks of those points in this map.
        """
        Q = np.array(PAPER_SEGMENT_Q_RAD)
        if self.arm == "left":
            Q = Q * MIRROR_Q
        P = np.array([self.reach.limb.fk(q)[:3, 3] for q in Q])
        return Q, P, self.query(P)

    def query(self, P_m) -> np.ndarray:
        """Branch masks (uint8, N) at arbitrary tool positions P_m (N x 3, m)."""
        return self.reach.points(P_m)

    def segment_at(self, i: int) -> Segment | None:
        """The widest one-branch segment of x slice ``i`` (None when nothing is reachable)."""
        n = int(self.run_length[i])
        if n == 0:
            return None
        g = self.grid
        s = int(self.run_start[i])
        return self._segment(float(g.x_m[i]), float(g.z_m[self.run_z_index[i]]),
                             float(g.y_m[s]), float(g.y_m[s + n - 1]), int(self.run_branch[i]))

    def rectangle_at(self, i: int) -> Rectangle | None:
        """The largest one-branch rectangle of x slice ``i`` (None when nothing is reachable)."""
        b, z0, z1, y0, y1 = (int(v) for v in self.rect_cells[i])
        if b < 0:
            return None
        g = self.grid
        return Rectangle(float(g.x_m[i]), float(g.y_m[y0]), float(g.y_m[y1]), float(g.z_m[z0]),
                         float(g.z_m[z1]), b)

    def _segment(self, x_m, z_m, y_min_m, y_max_m, branch) -> Segment:
        limb = self.reach.limb
        q = []
        for y in (y_min_m, y_max_m):
            T = np.eye(4)
            T[:3, :3] = self.R_N_E
            T[:3, 3] = (x_m, y, z_m)
            q.append(limb.candidates(T)[branch].q_rad)
        return Segment(x_m, z_m, y_min_m, y_max_m, branch, q[0], q[1])

    def summary(self) -> dict:
        """The figures of summary.json (mm at the edge), for this arm."""
        w = self.widest
        return {
            "arm": self.arm,
            "tool": self.tool,
            "params": self.params,
            "limits": self.limits,
            "orientation": self.orientation,
            "best_distance_mm": mm(w.wall_distance_m),
            "width_mm": mm(w.width_m),
            "height_mm": mm(w.z_m),
            "resolution_mm": mm(self.grid.resolution_m),
            "points": self.grid.points,
            "reachable_points": int(np.count_nonzero(self.masks)),
            "seconds": round(self.seconds, 3),
            "segment": w.to_json(),
            "segment_grid": self.widest_grid.to_json(),
            "rectangle": self.best_rectangle.to_json(),
            "criterion": "widest contiguous horizontal segment reachable on one IK branch",
        }


def _check(arm: str, resolution_m: float) -> None:
    if arm not in ARMS:
        raise InputError(f"unknown arm {quoted(arm)}", hint="use right or left")
    if resolution_m < 0.0005:
        raise InputError(f"resolution {resolution_m * 1000:g} mm is finer than 0.5 mm",
                         hint="use --resolution 1 or coarser; 5 mm takes about a second")


def compute_map(arm: str = "right", tool: str = "drill", orientation: str = "wall",
                params: str = "as-built", limits: str = "table4",
                resolution_m: float = DEFAULT_RESOLUTION_M,
                x_range_m: tuple[float, float] = DEFAULT_X_RANGE_M, refine: bool = True,
                progress: Progress | None = None, cache: bool = False,
                z_range_m: tuple[float, float] | None = None) -> WorkspaceMap:
    """Map one arm's tool workspace at a fixed orientation and search it.

    Args:
        arm: ``right`` or ``left`` (the left arm holds the tool as a mirror image, see
            :mod:`.limbs`).
        tool: arm tool frame (``drill``, ``hand`` or ``none``).
        orientation: ``wall`` (tool x straight forward) or ``"roll,pitch,yaw"`` in degrees.
        params, limits: model parameter set and joint-limit set.
        resolution_m: grid step (m), the same in x, y and z.
        x_range_m: first and last wall distance from the neck (m); (A, A) for one distance.
        refine: zoom in on the widest segment for sub-millimetre numbers (see :mod:`.refine`).
        progress: called as ``progress(stage, done, total)`` while computing.
        cache: reuse (or store) the branch masks in the user's cache folder
            (:mod:`hubo_cli.workspace.cache`).
        z_range_m: heights to consider (m); default all the arm can reach; (A, A) pins the
            segment to one height.

    Returns:
        a :class:`WorkspaceMap`. Raises :class:`InputError` if no grid point is reachable.
    """
    _check(arm, resolution_m)
    t0 = time.perf_counter()
    limb = arm_limb(arm, tool, params, limits)
    R = orientation_matrix(orientation)
    sphere = reach_sphere(limb, R)
    grid = make_grid(sphere, resolution_m, x_range_m, z_range_m)
    reach = BranchReach(limb, R, sphere)
    key = cache_key(limb, R, grid) if cache else None
    masks = load_masks(key, grid.shape) if cache else None
    if masks is None:
        nx, nz, ny = grid.shape
        chunk = max(1, POINTS_PER_CHUNK // (ny * nz))
        stage = f"{arm} arm: solving IK"
        masks = reach.grid(grid, chunk, None if progress is None else
                           (lambda done, total: progress(stage, done, total)))
        if cache:
            save_masks(key, masks)
    if not masks.any():
        raise InputError(f"the {arm} arm's tool reaches no grid point at this orientation",
                         hint="widen --x-range or choose another --orientation")
    result = analyse(masks, grid, reach, arm, tool, params, limits, orientation)
    if refine:
        if progress is not None:
            progress(f"{arm} arm: refining", 0, 1)
        seg = result.widest_grid
        x, z, y0, y1 = refine_widest(reach, seg.wall_distance_m, seg.z_m, seg.branch,
                                     resolution_m, (grid.y_m[0], grid.y_m[-1]),
                                     x_bounds_m=(grid.x_m[0], grid.x_m[-1]),
                                     z_bounds_m=(grid.z_m[0], grid.z_m[-1]))
        result.widest = result._segment(x, z, y0, y1, seg.branch)
        if progress is not None:
            progress(f"{arm} arm: refining", 1, 1)
    result.seconds = time.perf_counter() - t0
    return result


def analyse(masks: np.ndarray, grid: Grid, reach: BranchReach, arm: str, tool: str, params: str,
            limits: str, orientation: str) -> WorkspaceMap:
    """Run the segment and rectangle searches over branch masks (grid answers, no refining)."""
    nx = masks.shape[0]
    length, start = longest_runs(masks)
    iz, branch = widest_per_x(length, grid.z_m)
    ix = np.arange(nx)
    run_length = length[ix, iz, branch]
    run_start = start[ix, iz, branch]
    rects = largest_rectangles(masks)  # (nx, 8, 5): score, z0, z1, y0, y1
    rb = np.argmax(rects[:, :, 0], axis=1)
    best_rect = rects[ix, rb]
    rect_cells = np.column_stack([np.where(best_rect[:, 0] >= 0, rb, -1), best_rect[:, 1:]])
    best = pick_best_x(run_length)
    result = WorkspaceMap(arm, tool, params, limits, orientation, reach.R_N_E, grid, masks,
                          run_length, run_start, iz, branch, rect_cells, best, None, None, None,
                          0.0, reach)
    result.widest_grid = result.segment_at(best)
    result.best_rectangle = result.rectangle_at(pick_best_x(best_rect[:, 0]))
    result.widest = result.widest_grid
    return result
