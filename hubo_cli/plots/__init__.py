"""Plots users would rather look at than read (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path


def save_figure(fig, path: str | Path, **savefig_options) -> Path:
    """Write a figure already laid out (``fig.tight_layout()``) to ``path`` and close it.

    ``tight_layout`` leaves matplotlib's inert layout engine on the figure, and ``savefig`` draws
    a figure with any engine once more, without rendering, before the draw it renders: the
    whole layout (ticks, texts, the legend's best place) computed twice. Saved without the
    engine it is drawn once, to the same pixels.
    """
    import matplotlib.pyplot as plt

    fig.set_layout_engine(None)
    path = Path(path)
    fig.savefig(path, **savefig_options)
    plt.close(fig)
    return path
