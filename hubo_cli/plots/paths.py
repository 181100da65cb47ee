"""Commanded vs actual end-effector path in a plane (the paper's Fig. 5), and signals over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.plots import STOP_COLOUR, save_figure  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}


MIN_SPAN_MM = 20.0  # a path smaller than this is drawn on axes this wide, marked "did not move"
ARROWS = 6  # direction-of-travel arrows along the commanded path
HOLE_COLOUR = "#8c564b"


def _arrows(ax, xy: np.ndarray, colour: str) -> int:
    """Arrows along a path (n x 2) at :data:`ARROWS` even steps of its length, pointing the
    way it was travelled; returns how many were drawn."""
    finite = xy[np.all(np.isfinite(xy), axis=1)]
    if len(finite) < 2:
        return 0
    step = np.linalg.norm(np.diff(finite, axis=0), axis=1)
    along = np.r_[0.0, np.cumsum(step)]
    if along[-1] <= 0:
        return 0
    drawn = 0
    for s in (np.arange(ARROWS) + 0.5) / ARROWS * along[-1]:
        i = int(np.searchsorted(along, s))
        j = int(np.searchsorted(along, s + 0.02 * along[-1]))  # 2 % further on: its heading
        i, j = min(i, len(finite) - 2), min(max(j, i + 1), len(finite) - 1)
        ax.annotate("", xy=finite[j], xytext=finite[i], zorder=6, gid="direction-arrow",
                    arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.5,
                                    mutation_scale=16, shrinkA=0, shrinkB=0))
        drawn += 1
    return drawn


def path_figure(commanded_m: np.ndarray, actual_m: np.ndarray, *, plane: str = "yz",
                title: str = "", rms_error_mm: float | None = None,
                mirror_first_axis: bool = True, frame: str = "the neck frame",
                actual_label: str = "actual end effector",
                hole_m: np.ndarray | None = None, hole_rms_error_mm: float | None = None,
                stops_m: np.ndarray | None = None):
    """The figure of :func:`plot_path_comparison` (same arguments but the file), open."""
    i, j = AXES[plane[0]], AXES[plane[1]]
    fig, ax = plt.subplots(figsize=(7.0, 5.9), dpi=120)
    mm = 1000.0
    if hole_m is not None and len(hole_m):  # wide and light under the lines: seen beside them
        ax.plot(hole_m[:, i] * mm, hole_m[:, j] * mm, "-", color=HOLE_COLOUR, lw=7,
                alpha=0.3, solid_capstyle="round", solid_joinstyle="round", zorder=1,
                label="hole cut in the wall (drawn wide, under the lines)")
    ax.plot(commanded_m[:, i] * mm, commanded_m[:, j] * mm, "--", color="#d62728", lw=1.6,
            zorder=3, label="commanded (operator / task)")
    ax.plot(actual_m[:, i] * mm, actual_m[:, j] * mm, "-", color="#1f77b4", lw=1.4,
            alpha=0.9, zorder=4, label=actual_label)
    if len(actual_m):
        # the start larger and under the end: both seen where a closed path ends at its start
        ax.plot(actual_m[0, i] * mm, actual_m[0, j] * mm, "o", color="#2ca02c", ms=12,
                zorder=7, label="start")
        ax.plot(actual_m[-1, i] * mm, actual_m[-1, j] * mm, "s", color="k", ms=5, zorder=7,
                label="end")
    if stops_m is not None and len(stops_m):
        ax.plot(stops_m[:, i] * mm, stops_m[:, j] * mm, "X", color=STOP_COLOUR, ms=12,
                mec="w", zorder=8, label="emergency stop")
    ax.set_aspect("equal", adjustable="datalim")
    points = np.vstack([commanded_m[:, [i, j]], actual_m[:, [i, j]]]) * mm
    points = points[np.all(np.isfinite(points), axis=1)]
    span = points.max(axis=0) - points.min(axis=0) if len(points) else np.zeros(2)
    # (a path that did not move has no direction worth an arrow: tremor's would point anywhere)
    if span.max() >= MIN_SPAN_MM and _arrows(ax, commanded_m[:, [i, j]] * mm, "#d62728"):
        ax.plot([], [], marker=r"$\rightarrow$", color="#d62728", ls="none", ms=12,
                label="direction of travel")
    if len(points) and span.max() < MIN_SPAN_MM:
        centre = 0.5 * (points.max(axis=0) + points.min(axis=0))
        ax.set_aspect("equal", adjustable="box")  # the limits below are kept
        ax.set_xlim(centre[0] - MIN_SPAN_MM / 2, centre[0] + MIN_SPAN_MM / 2)
        ax.set_ylim(centre[1] - MIN_SPAN_MM / 2, centre[1] + MIN_SPAN_MM / 2)
        ax.text(0.5, 0.04, f"did not move: {span.max():.1f} mm at most "
                           f"(axes kept {MIN_SPAN_MM:g} mm wide)",
                transform=ax.transAxes, ha="center", fontsize=10, gid="did-not-move",
                bbox=dict(boxstyle="round", fc="#fff3cd", ec="#c9a227"))
    if mirror_first_axis:
        ax.invert_xaxis()
    ax.set_xlabel(f"{plane[0]} in {frame} (mm)" + (" — robot's left is left"
                                                          if mirror_first_axis else ""))
    ax.set_ylabel(f"{plane[1]} in {frame} (mm)")
    ax.grid(True, alpha=0.3)
    heading = title
    if rms_error_mm is not None:
        heading += f"\nRMS error {rms_error_mm:.2f} mm"
    if hole_rms_error_mm is not None:
        heading += f", hole {hole_rms_error_mm:.2f} mm"
    ax.set_title(heading)
    # below the plot: never over the path
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8,
              frameon=False)
    fig.tight_layout()
    return fig


def plot_path_comparison(commanded_m: np.ndarray, actual_m: np.ndarray, path: str | Path, *,
                         plane: str = "yz", title: str = "", rms_error_mm: float | None = None,
                         mirror_first_axis: bool = True, frame: str = "the neck frame",
                         actual_label: str = "actual end effector",
                         hole_m: np.ndarray | None = None,
                         hole_rms_error_mm: float | None = None,
                         stops_m: np.ndarray | None = None) -> Path:
    """Plot two 3-D paths (N x 3, metres) projected on a plane, in millimetres, with arrows
    for the direction of travel, start and end marks, and where given the hole the tool made
    in the world and the emergency stops. A path that spans less than :data:`MIN_SPAN_MM` is
    drawn on axes that wide and marked "did not move" (tremor is not magnified).

    Args:
        commanded_m, actual_m: the commanded and the actual end-effector positions.
        path: the PNG to write.
        plane: two axis letters, e.g. ``"yz"`` (the wall plane seen from behind the robot).
        title: the plot's title.
        rms_error_mm: printed on the plot when given.
        mirror_first_axis: draw the first axis growing to the left (so that +y, the robot's
            left, is on the left as seen from behind the robot).
        frame: the frame the positions are in (axis labels).
        actual_label: what the actual path is (e.g. the bit by the encoders' kinematics).
        hole_m: the hole in the wall (M x 3, m, same frame): the bit's world path where its
            flutes were in the wall; drawn wide and light under the two paths.
        hole_rms_error_mm: the hole's RMS error, printed on the plot when given.
        stops_m: where the tool was at each emergency stop (K x 3, m, same frame).
    """
    return save_figure(path_figure(
        commanded_m, actual_m, plane=plane, title=title, rms_error_mm=rms_error_mm,
        mirror_first_axis=mirror_first_axis, frame=frame, actual_label=actual_label,
        hole_m=hole_m, hole_rms_error_mm=hole_rms_error_mm, stops_m=stops_m), path)


def plot_signals(t_s: np.ndarray, signals: dict[str, np.ndarray], path: str | Path, *,
                 ylabel: str, title: str = "", limit: float | None = None,
                 limit_label: str = "limit") -> Path:
    """Plot named signals against time, with an optional horizontal limit line."""
    fig, ax = plt.subplots(figsize=(8.0, 4.2), dpi=120)
    for name, values in signals.items():
        ax.plot(t_s, values, lw=1.2, label=name)
    if limit is not None:
        ax.axhline(limit, color="#d62728", ls="--", lw=1.2, label=limit_label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)
