"""The multi-layer paper's Fig. 4 from a toe-heel walk's log: (a) each sole's CoP along it,
planned and measured, (b) the ZMP and the CoM along the walk, reference and estimated,
(c) each sole's angle, planned and estimated."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.plots import save_figure  # noqa: E402

SIDES = ("right", "left")
COLOURS = {"right": "#1f77b4", "left": "#ff7f0e"}


def plot_toe_heel(t_s: np.ndarray, columns: dict[str, np.ndarray], path: str | Path,
                  title: str = "") -> Path:
    """Plot Fig. 4 for a walk.

    Args:
        t_s: the periods' times (s).
        columns: the walk's log columns by name (``walk.<side>_cop_ref_m``, ``walk.<side>
            _cop_m``, ``walk.<side>_angle_ref_rad``, ``walk.<side>_angle_rad``,
            ``walk.zmp_ref_x_m``, ``walk.zmp_x_m``, ``walk.com_ref_x_m``, ``com_x_m``).
        path: the PNG to write.
        title: the figure's title.
    """
    fig, axes = plt.subplots(3, 1, figsize=(9.0, 9.0), dpi=110, sharex=True)
    ax = axes[0]
    for side in SIDES:
        ax.plot(t_s, 1000 * columns[f"walk.{side}_cop_ref_m"], color=COLOURS[side],
                label=f"{side} planned")
        ax.plot(t_s, 1000 * columns[f"walk.{side}_cop_m"], ".", ms=1.0, color=COLOURS[side],
                alpha=0.5, label=f"{side} measured")
    ax.set_ylabel("CoP along the sole (mm)")
    ax.set_title("(a) CoP offsets (> 0 toward the toe; measured while loaded)")
    ax.legend(loc="upper right", ncols=2, fontsize=8)
    ax = axes[1]
    ax.plot(t_s, columns["walk.zmp_ref_x_m"], color="#2ca02c", label="ZMP reference (eq. 4)")
    ax.plot(t_s, columns["walk.zmp_x_m"], ".", ms=1.0, color="#2ca02c", alpha=0.4,
            label="ZMP estimated")
    ax.plot(t_s, columns["walk.com_ref_x_m"], color="#d62728", label="CoM reference")
    ax.plot(t_s, columns["com_x_m"], "--", color="#d62728", label="CoM estimated")
    ax.set_ylabel("x (m)")
    ax.set_title("(b) ZMP and CoM along the walk")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[2]
    for side in SIDES:
        ax.plot(t_s, np.degrees(columns[f"walk.{side}_angle_ref_rad"]), color=COLOURS[side],
                label=f"{side} planned")
        ax.plot(t_s, np.degrees(columns[f"walk.{side}_angle_rad"]), "--", color=COLOURS[side],
                label=f"{side} estimated")
    ax.set_ylabel("foot angle (deg)")
    ax.set_xlabel("time (s)")
    ax.set_title("(c) foot angle offsets (> 0 on the toe, < 0 on the heel)")
    ax.legend(loc="upper right", ncols=2, fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)
