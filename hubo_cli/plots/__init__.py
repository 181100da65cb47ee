"""Plots users would rather look at than read (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

STOP_COLOUR = "#c2188b"  # emergency stops, in every plot
STOP_SHADE = "#f7b6d2"  # the periods the emergency stopper reverted or held


def save_figure(fig, path: str | Path, **savefig_options) -> Path:
    """Write a figure already laid out (``fig.tight_layout()``) to ``path`` and close it.

    ``tight_layout`` leaves matplotlib's inert layout engine on the figure, and ``savefig`` draws
    a figure with any engine once more, without rendering, before the draw it renders: the
    whole layout (ticks, texts, the legend's best place) computed twice. Saved without the
    engine it is drawn once, to the same pixels. A write that fails is
    :func:`hubo_cli.outputs.write_error`'s error, naming ``path``.
    """
    import matplotlib.pyplot as plt

    from hubo_cli.outputs import write_error

    fig.set_layout_engine(None)
    path = Path(path)
    try:
        fig.savefig(path, **savefig_options)
    except OSError as exc:  # a full disk names the file (exit 3), anything else is exit 2
        raise write_error(path, exc, hint="check the run folder's path") from None
    finally:
        plt.close(fig)
    return path


def shade_emergency_stop(ax, log, summary: dict, label: bool) -> None:
    """On ``ax`` (time on x): the periods the emergency stopper reverted or held (the log's
    ``estop_mode_code``) shaded, labelled when ``label``, and the time the stop was flagged
    (the summary's ``t_emergency_s``) a line."""
    import numpy as np

    t = log["t_s"]
    active = (log["estop_mode_code"] > 0.5 if "estop_mode_code" in log.columns
              else np.zeros(len(t), dtype=bool))
    if active.any():
        ax.fill_between(t, 0, 1, where=active, transform=ax.get_xaxis_transform(),
                        color=STOP_SHADE, alpha=0.55, lw=0,
                        label="emergency stop (revert, hold)" if label else None)
    if summary.get("t_emergency_s") is not None:
        ax.axvline(summary["t_emergency_s"], color=STOP_COLOUR, lw=1.0)
