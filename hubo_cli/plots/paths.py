"""Commanded vs actual end-effector path in a plane (the paper's Fig. 5), and signals over time."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.plots import save_figure  # noqa: E402

AXES = {"x": 0, "y": 1, "z": 2}


def plot_path_comparison(commanded_m: np.ndarray, actual_m: np.ndarray, path: str | Path, *,
                         plane: str = "yz", title: str = "", rms_error_mm: float | None = None,
                         mirror_first_axis: bool = True, frame: str = "the neck frame",
                         actual_label: str = "actual end effector",
                         hole_m: np.ndarray | None = None,
                         hole_rms_error_mm: float | None = None) -> Path:
    """Plot two 3-D paths (N x 3, metres) projected on a plane, in millimetres, and where
    given the hole the tool made in the world.

    Args:
        commanded_m, actual_m: the commanded and the actual end-effector positions.
        actual_label: what the actual path is (e.g. the bit by the encoders' kinematics).
        hole_m: the hole in the wall (M x 3, m, same frame): the bit's world path where its
            flutes were in the wall; drawn as dots beside the other two.
        hole_rms_error_mm: the hole's RMS error, printed on the plot when given.
        path: the PNG to write.
        plane: two axis letters, e.g. ``"yz"`` (the wall plane seen from behind the robot).
        title: the plot's title.
        rms_error_mm: printed on the plot when given.
        mirror_first_axis: draw the first axis growing to the left (so that +y, the robot's
            left, is on the left as seen from behind the robot).
        frame: the frame the positions are in (axis labels).
    """
    i, j = AXES[plane[0]], AXES[plane[1]]
    fig, ax = plt.subplots(figsize=(7.0, 5.6), dpi=120)
    ax.plot(commanded_m[:, i] * 1000, commanded_m[:, j] * 1000, "--", color="#d62728", lw=1.6,
            label="commanded (operator / task)")
    ax.plot(actual_m[:, i] * 1000, actual_m[:, j] * 1000, "-", color="#1f77b4", lw=1.4,
            alpha=0.9, label=actual_label)
    if hole_m is not None and len(hole_m):
        ax.plot(hole_m[:, i] * 1000, hole_m[:, j] * 1000, ".", color="#8c564b", ms=3.0,
                alpha=0.5, zorder=1, label="hole in the wall (bit in the world, flutes in the "
                                           "wall)")
    if len(actual_m):
        ax.plot(actual_m[0, i] * 1000, actual_m[0, j] * 1000, "o", color="#2ca02c", ms=7,
                label="start")
    ax.set_aspect("equal", adjustable="datalim")
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
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


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
