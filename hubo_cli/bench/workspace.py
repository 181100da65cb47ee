"""Workspace-map figures: the default map (right arm, drill, 5 mm) end to end and by stage."""

from __future__ import annotations

import os
import tempfile
import time

import numba
import numpy as np

from hubo_cli.workspace import best_stance, compute_map
from hubo_cli.workspace.grid import reach_sphere
from hubo_cli.workspace.maps import analyse
from hubo_cli.workspace.refine import refine_widest


def run(report) -> None:
    compute_map(resolution_m=0.01)  # load (or compile) the kernels outside the timings
    threads = numba.get_num_threads()
    t0 = time.perf_counter()
    wmap = compute_map()  # the command's default: 5 mm, 300-650 mm, refined
    total = time.perf_counter() - t0
    g = wmap.grid
    sphere = reach_sphere(wmap.reach.limb, wmap.R_N_E)
    X, Z, Y = np.meshgrid(g.x_m, g.z_m, g.y_m, indexing="ij", sparse=True)
    c = sphere.centre_m
    solved = int(np.count_nonzero((X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2
                                  <= sphere.radius_m ** 2))
    note = f"{g.points:,} points ({solved:,} within arm's length get IK), {threads} threads"
    report("default map at 5 mm, total (solve + search + refine)", total, "s",
           f"target < 10 s; {note}")
    report("default map at 5 mm, points per second", g.points / total, "points/s", note)
    t0 = time.perf_counter()
    masks = wmap.reach.grid(g)
    solve = time.perf_counter() - t0
    report("per-branch IK over the grid", solve, "s", f"{g.points / solve / 1e6:.1f} M points/s")
    t0 = time.perf_counter()
    analyse(masks, g, wmap.reach, "right", "drill", "as-built", "table4", "wall")
    report("segment and rectangle searches", time.perf_counter() - t0, "s")
    seg = wmap.widest_grid
    t0 = time.perf_counter()
    refine_widest(wmap.reach, seg.wall_distance_m, seg.z_m, seg.branch, g.resolution_m,
                  (g.y_m[0], g.y_m[-1]))
    report("refining the widest segment", time.perf_counter() - t0, "s")
    with tempfile.TemporaryDirectory() as cache:
        old = os.environ.get("HUBO_CACHE_DIR")
        os.environ["HUBO_CACHE_DIR"] = cache
        try:
            t0 = time.perf_counter()
            best_stance()
            cold = time.perf_counter() - t0
            t0 = time.perf_counter()
            best_stance(size_m=(0.15, 0.10))
            warm = time.perf_counter() - t0
        finally:
            if old is None:
                os.environ.pop("HUBO_CACHE_DIR")
            else:
                os.environ["HUBO_CACHE_DIR"] = old
    report("best_stance, empty cache", cold, "s")
    report("best_stance with a hole size, cached masks", warm, "s")
