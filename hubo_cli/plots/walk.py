"""A walk seen from above: the footprints, the CoM path and the ZMP (reference and measured),
as the multi-layer paper's walking figures."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from hubo_cli.plots import save_figure  # noqa: E402


def plot_walk(footprints: list[dict], corners_m: np.ndarray, com_ref_m: np.ndarray,
              com_m: np.ndarray, zmp_ref_m: np.ndarray, zmp_m: np.ndarray,
              path: str | Path, title: str = "") -> Path:
    """Plot a walk on the floor (world x forward, y left; millimetres).

    Args:
        footprints: the soles on the floor, dicts with ``side``, ``x_m``, ``y_m``, ``yaw_rad``
            (the start feet first, then every footstep).
        corners_m: a sole's corners in its own frame (4 x 3, m).
        com_ref_m, com_m: the pattern's and the measured CoM (n x 2, m).
        zmp_ref_m, zmp_m: the reference and the measured ZMP (n x 2, m; NaN rows skipped).
        path: the PNG to write.
        title: the plot's title.
    """
    fig, ax = plt.subplots(figsize=(8.0, 6.0), dpi=120)
    for k, foot in enumerate(footprints):
        c, s = math.cos(foot["yaw_rad"]), math.sin(foot["yaw_rad"])
        xy = [(foot["x_m"] + c * px - s * py, foot["y_m"] + s * px + c * py)
              for px, py in corners_m[:, :2]]
        colour = "#1f77b4" if foot["side"] == "right" else "#ff7f0e"
        ax.add_patch(Polygon(np.array(xy) * 1000, closed=True, fill=False, ec=colour,
                             lw=1.0, alpha=0.5 if k < 2 else 0.9))
    measured = zmp_m[np.all(np.isfinite(zmp_m), axis=1)]
    ax.plot(measured[:, 0] * 1000, measured[:, 1] * 1000, ".", color="#7f7f7f", ms=1.0,
            alpha=0.4, label="ZMP measured (ankle F/T)")
    ax.plot(zmp_ref_m[:, 0] * 1000, zmp_ref_m[:, 1] * 1000, "-", color="#d62728", lw=1.2,
            label="ZMP reference")
    ax.plot(com_ref_m[:, 0] * 1000, com_ref_m[:, 1] * 1000, "--", color="#2ca02c", lw=1.4,
            label="CoM pattern (preview control)")
    ax.plot(com_m[:, 0] * 1000, com_m[:, 1] * 1000, "-", color="#9467bd", lw=1.0,
            label="CoM measured")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x forward (mm)")
    ax.set_ylabel("y left (mm)")
    ax.set_title(title or "walk: footprints (right blue, left orange), CoM and ZMP")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
