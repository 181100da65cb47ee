"""Plots of a task run: the wrist torque over time against its limit."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.plots import STOP_COLOUR, save_figure  # noqa: E402

EDGE_COLOURS = {1: ("#c6dbef", "horizontal edge"), 2: ("#fdd0a2", "vertical edge")}


def plot_wrist_torque(log, path: str | Path, *, limit_nm: float, title: str = "",
                      stop_times_s=()) -> Path:
    """The wrist's bending moment (N m) over the run with the limit, the cut's horizontal and
    vertical edges shaded and each emergency stop marked.

    Args:
        log: the run's :class:`~hubo_cli.control.log.LogData` (needs ``task_wrist_torque_nm``,
            ``edge_code``).
        path: the PNG to write.
        limit_nm: the wrist torque limit (N m).
        title: the plot's title.
        stop_times_s: times of the emergency stops (s).
    """
    t = log["t_s"]
    torque = log["task_wrist_torque_nm"]
    edge = log["edge_code"]
    fig, ax = plt.subplots(figsize=(9.0, 4.2), dpi=120)
    for code, (colour, label) in EDGE_COLOURS.items():
        on = edge == code
        if on.any():
            ax.fill_between(t, 0, 1, where=on, transform=ax.get_xaxis_transform(),
                            color=colour, alpha=0.7, lw=0, label=label)
    ax.plot(t, torque, color="#1f77b4", lw=1.0, label="wrist bending moment |(my, mz)|")
    ax.axhline(limit_nm, color="#d62728", ls="--", lw=1.3, label=f"limit {limit_nm:g} N m")
    for i, t_stop in enumerate(stop_times_s):
        ax.axvline(t_stop, color=STOP_COLOUR, lw=1.2,
                   label="emergency stop" if i == 0 else None)
    finite = np.asarray(torque, dtype=float)
    finite = finite[np.isfinite(finite)]  # (none during a walk: no wrist reading yet)
    top = max(limit_nm * 1.25, float(finite.max()) * 1.1 if len(finite) else 0.0)
    ax.set_ylim(0, top)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("wrist torque (N m)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, ncol=3, framealpha=0.9)
    fig.tight_layout()
    return save_figure(fig, path)
