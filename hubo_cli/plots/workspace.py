"""Plots of a workspace map: the paper's Fig. 4 view and width against wall distance.

Matplotlib with the Agg backend (files only, no window). Millimetres on every axis.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch, Rectangle  # noqa: E402

from hubo_cli.plots import save_figure  # noqa: E402
from hubo_cli.workspace import PAPER_BEST, WorkspaceMap  # noqa: E402
from hubo_cli.workspace.grid import reach_sphere  # noqa: E402

# 0 outside the arm's length, 1 unreachable, 2 reachable on another branch, 3 on the segment's
_COLOURS = ListedColormap(["#f2f2f2", "#d62728", "#98df8a", "#2ca02c"])
_LEGEND = [Patch(color="#2ca02c", label="reachable (segment's IK branch)"),
           Patch(color="#98df8a", label="reachable (other branch only)"),
           Patch(color="#d62728", label="not reachable (within arm's length)"),
           Patch(color="#f2f2f2", label="beyond the arm's length")]


def _classes(masks: np.ndarray, inside: np.ndarray, branch: int) -> np.ndarray:
    c = np.where(inside, 1, 0)
    c = np.where(masks != 0, 2, c)
    return np.where(masks & (1 << branch), 3, c)


def _paper_points_mm(wmap: WorkspaceMap) -> np.ndarray:
    """The paper's two segment ends through this map's arm (mirrored on the left), in mm."""
    return wmap.paper_ends()[1] * 1000


def plot_fig4(wmap: WorkspaceMap, path: str | Path) -> Path:
    """The Fig. 4 view at the best wall distance: front (y-z) and top (x-y) slices.

    Green: the tool reaches the point with the bit orthogonal to the wall; red: it does not.
    The widest segment is drawn in black, the largest rectangle of that distance dashed, and
    the paper's two segment ends (section IV) as stars.
    """
    g = wmap.grid
    seg = wmap.widest_grid
    i = wmap.best_index
    sphere = reach_sphere(wmap.reach.limb, wmap.R_N_E)
    c = sphere.centre_m
    X, Z, Y = np.meshgrid(g.x_m, g.z_m, g.y_m, indexing="ij")
    inside = (X - c[0]) ** 2 + (Y - c[1]) ** 2 + (Z - c[2]) ** 2 <= sphere.radius_m ** 2
    cls = _classes(wmap.masks, inside, seg.branch)
    mm = 1000.0
    step = g.resolution_m * mm
    fig, (ax_front, ax_top) = plt.subplots(1, 2, figsize=(14, 7.5))
    y_ext = (g.y_m[0] * mm - step / 2, g.y_m[-1] * mm + step / 2)
    z_ext = (g.z_m[0] * mm - step / 2, g.z_m[-1] * mm + step / 2)
    x_ext = (g.x_m[0] * mm - step / 2, g.x_m[-1] * mm + step / 2)
    ax_front.imshow(cls[i], origin="lower", extent=(*y_ext, *z_ext), cmap=_COLOURS, vmin=0,
                    vmax=3, interpolation="nearest", aspect="equal")
    ax_front.plot([seg.y_min_m * mm, seg.y_max_m * mm], [seg.z_m * mm] * 2, "k-", lw=3,
                  label=f"widest segment {seg.width_m * mm:.0f} mm")
    rect = wmap.rectangle_at(i)
    if rect is not None:
        ax_front.add_patch(Rectangle((rect.y_min_m * mm, rect.z_min_m * mm), rect.width_m * mm,
                                     rect.height_m * mm, fill=False, ls="--", lw=2, ec="k",
                                     label=f"largest rectangle {rect.width_m * mm:.0f} x "
                                           f"{rect.height_m * mm:.0f} mm"))
    paper = _paper_points_mm(wmap) if wmap.paper_setup else None
    iz = int(np.argmin(np.abs(g.z_m - seg.z_m)))
    ax_top.imshow(cls[:, iz, :], origin="lower", extent=(*y_ext, *x_ext), cmap=_COLOURS, vmin=0,
                  vmax=3, interpolation="nearest", aspect="equal")
    ax_top.plot([seg.y_min_m * mm, seg.y_max_m * mm], [seg.wall_distance_m * mm] * 2, "k-",
                lw=3)
    mirrored = " (mirrored)" if wmap.arm == "left" else ""
    for ax, cols in ((ax_front, (1, 2)), (ax_top, (1, 0))) if wmap.paper_setup else ():
        ax.plot(paper[:, cols[0]], paper[:, cols[1]], "*", color="gold", mec="k", ms=16,
                label=f"paper IV ends{mirrored} (x = {paper[0, 0]:.0f} mm, "
                      f"z = {paper[0, 2]:.0f} mm)")
    ax_front.set(xlabel="y (mm, + is the robot's left)", ylabel="z above the neck (mm)",
                 title=f"wall at x = {g.x_m[i] * mm:.0f} mm (front view)")
    ax_top.set(xlabel="y (mm, + is the robot's left)", ylabel="x, wall distance (mm)",
               title=f"top view at z = {g.z_m[iz] * mm:.0f} mm")
    for ax in (ax_front, ax_top):
        ax.invert_xaxis()  # seen from behind the robot: its left on the left
        ax.grid(alpha=0.3)
    fig.legend(handles=_LEGEND + ax_front.get_legend_handles_labels()[0], loc="lower center",
               ncol=4, fontsize=9, frameon=False)
    w = wmap.widest
    paper_note = (f" (paper: {PAPER_BEST['width_mm']:.0f} mm at "
                  f"{PAPER_BEST['wall_distance_mm']:.0f} mm, z = {PAPER_BEST['height_mm']:.0f} mm)"
                  if wmap.paper_setup else "")
    fig.suptitle(f"{wmap.arm} arm, {wmap.tool}, {wmap.params} lengths, {wmap.limits} limits, "
                 f"orientation {wmap.orientation}: widest one-branch segment "
                 f"{w.width_m * mm:.1f} mm at x = {w.wall_distance_m * mm:.1f} mm, "
                 f"z = {w.z_m * mm:.1f} mm{paper_note}", fontsize=10)
    fig.tight_layout(rect=(0, 0.11, 1, 0.96))
    return save_figure(fig, path, dpi=110)


def plot_widths(maps: list[WorkspaceMap], path: str | Path) -> Path:
    """Widest one-branch segment and largest rectangle against wall distance, per arm."""
    mm = 1000.0
    fig, ax = plt.subplots(figsize=(10, 6))
    colours = {"right": "tab:blue", "left": "tab:purple"}
    for wmap in maps:
        col = colours.get(wmap.arm, "tab:blue")
        x = wmap.grid.x_m * mm
        ax.plot(x, wmap.widths_m * mm, "-", color=col, lw=2,
                label=f"{wmap.arm} arm: widest segment (one branch)")
        ax.plot(x, wmap.rect_widths_m * mm, "--", color=col,
                label=f"{wmap.arm} arm: largest rectangle, width")
        ax.plot(x, wmap.rect_heights_m * mm, ":", color=col,
                label=f"{wmap.arm} arm: largest rectangle, height")
        w = wmap.widest
        ax.plot([w.wall_distance_m * mm], [w.width_m * mm], "o", color=col, ms=9, mec="k",
                label=f"{wmap.arm} best: {w.width_m * mm:.0f} mm at "
                      f"{w.wall_distance_m * mm:.0f} mm")
    first = maps[0]
    if first.paper_setup:
        ax.plot([PAPER_BEST["wall_distance_mm"]], [PAPER_BEST["width_mm"]], "*", color="gold",
                mec="k", ms=16, label="paper IV: 390 mm at 484 mm")
    ax.set(xlabel="wall distance from the neck, x (mm)", ylabel="mm",
           title=f"{first.tool}, {first.params} lengths, {first.limits} limits, "
                 f"{first.grid.resolution_m * mm:g} mm grid")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)
