"""Plot files: a figure saved without its placeholder layout engine (drawn once) has the
pixels of the same figure saved the usual way (drawn twice)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.plots import save_figure  # noqa: E402


def _figure():
    rng = np.random.default_rng(2)
    fig, ax = plt.subplots(figsize=(5.0, 3.5), dpi=80)
    xy = np.cumsum(rng.normal(size=(2000, 2)), axis=0)
    ax.plot(xy[:, 0], xy[:, 1], lw=1.0, label="walk")
    ax.plot(xy[::7, 0], xy[::7, 1], ".", ms=2, label="every 7th")
    ax.set_title("a title\nover two lines")
    ax.set_xlabel("x (mm)")
    ax.legend(loc="best")  # its place is searched against the data in each draw
    fig.tight_layout()
    return fig


def test_save_figure_gives_the_pixels_of_savefig(tmp_path):
    usual = _figure()
    usual.savefig(tmp_path / "usual.png")
    plt.close(usual)
    path = save_figure(_figure(), tmp_path / "once.png")
    assert path == tmp_path / "once.png"
    a, b = mpimg.imread(tmp_path / "usual.png"), mpimg.imread(tmp_path / "once.png")
    assert a.shape == b.shape and np.array_equal(a, b)
    assert not plt.get_fignums()  # closed
