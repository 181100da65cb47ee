"""The manipulation experiments at a glance (Figs. 11-12 of the multi-layer paper): the
capture-point error against the support's edges, the hand force, the object's angle and the
torso tilt over time, the emergency stop shaded."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.falls import FALL_TILT_DEG  # noqa: E402
from hubo_cli.plots import save_figure, shade_emergency_stop  # noqa: E402

AXIS_COLOURS = {"x": "#d62728", "y": "#ff7f0e"}


def plot_manipulation(log, summary: dict, path: str | Path) -> Path:
    """Three panels over time: the capture-point error along x and y with the support
    polygon's edges (shrunk by the monitor's margin) as thresholds; the wrist sensor's reading
    of the hand's load (the force along the forearm, the bending moment against the wrist's
    limit); the object's angle with the torso tilt.

    Args:
        log: the run's :class:`~hubo_cli.control.log.LogData` (the capture-point monitor's
            columns and :class:`~hubo_cli.experiments.manipulation.ManipulationTargets`').
        summary: the run's summary (``experiment``, ``case``, ``estop``, ``fell`` ...).
        path: the PNG to write.
    """
    t = log["t_s"]
    fig, (ax_cp, ax_f, ax_a) = plt.subplots(3, 1, figsize=(8.0, 7.6), dpi=120, sharex=True,
                                            gridspec_kw={"height_ratios": [2.0, 1.5, 1.1]})
    for a in (ax_cp, ax_f, ax_a):
        shade_emergency_stop(a, log, summary, label=a is ax_cp)
        a.grid(alpha=0.3)
    span = 50.0
    for axis, colour in AXIS_COLOURS.items():
        ref = log[f"cp_ref_{axis}_m"]
        error_mm = log[f"cp_error_{axis}_m"] * 1000
        low_mm = (log[f"support_min_{axis}_m"] - ref) * 1000
        high_mm = (log[f"support_max_{axis}_m"] - ref) * 1000
        ax_cp.plot(t, error_mm, color=colour, lw=1.6, label=f"CP error {axis}")
        ax_cp.plot(t, low_mm, "--", color=colour, lw=0.9, alpha=0.8,
                   label=f"support edge {axis} - margin")
        ax_cp.plot(t, high_mm, "--", color=colour, lw=0.9, alpha=0.8)
        finite = np.isfinite(error_mm) & np.isfinite(low_mm) & np.isfinite(high_mm)
        if finite.any():  # the thresholds well in view; a fall's huge error runs off the top
            edge = float(np.max(np.abs(np.concatenate([low_mm[finite], high_mm[finite]]))))
            err = float(np.max(np.abs(error_mm[finite])))
            span = max(span, 1.3 * edge, min(1.15 * err, 3.0 * edge))
    ax_cp.set_ylim(-span, span)
    ax_cp.set_ylabel("CP error [mm]")
    ax_cp.legend(loc="upper left", fontsize=7, framealpha=0.9, ncol=3)
    outcome = ("fell" if summary["fell"] else "tipped (a sole off the floor)"
               if summary["tipped"] else "stayed up")
    if summary.get("overloaded"):
        outcome += ", arm overloaded"
    if summary.get("wrist_overloaded"):
        outcome += ", wrist overloaded"
    ax_cp.set_title(f"{summary['experiment']} ({summary['case']}), emergency stop "
                    f"{summary['estop']}: {outcome}", fontsize=10)
    # Hubo's wrist sensor: the force along the forearm and the bending moment (a force across
    # the forearm shows only as the moment it makes at its lever)
    ax_f.plot(t, log["hand_axial_n"], color="#111111", lw=1.5,
              label="f_z along the forearm (+ pulls the hand out)")
    ax_f.set_ylabel("wrist f_z [N]")
    ax_m = ax_f.twinx()
    ax_m.plot(t, log["wrist_moment_nm"], color="#9467bd", lw=1.0, alpha=0.85,
              label="bending moment |m_x, m_y|")
    if summary.get("wrist_limit_nm") is not None:
        ax_m.axhline(summary["wrist_limit_nm"], color="#9467bd", ls="--", lw=0.9,
                     label=f"wrist limit {summary['wrist_limit_nm']:g} N m "
                           f"(beyond it {summary['wrist_over_limit_s']:.2f} s)")
    ax_m.set_ylabel("wrist moment [N m]", color="#9467bd")
    lines = ax_f.get_legend_handles_labels()
    more = ax_m.get_legend_handles_labels()
    ax_f.legend(lines[0] + more[0], lines[1] + more[1], loc="upper left", fontsize=7,
                framealpha=0.9, ncol=2)
    object_name = "valve" if summary["experiment"] == "turn-valve" else "door"
    ax_a.plot(t, log["object_angle_deg"], color="#8c564b", lw=1.6,
              label=f"{object_name} angle")
    ax_a.axhline(summary["planned_deg"], color="#8c564b", ls=":", lw=1.0,
                 label=f"planned {summary['planned_deg']:g} deg")
    ax_a.plot(t, log["tilt_deg"], color="#17becf", lw=1.3, label="torso tilt")
    ax_a.axhline(FALL_TILT_DEG, color="#555555", ls=":", lw=1.0,
                 label=f"fall {FALL_TILT_DEG:.0f} deg")
    ax_a.set_ylabel("angle [deg]")
    ax_a.set_xlabel("time [s]")
    ax_a.legend(loc="upper left", fontsize=7, framealpha=0.9, ncol=4)
    fig.align_ylabels()
    fig.tight_layout()
    return save_figure(fig, path)
