"""Plot files: a figure saved without its placeholder layout engine (drawn once) has the
pixels of the same figure saved the usual way (drawn twice); the path plot says what each line
and mark is, which way the tool went, and that a hand did not move."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

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


# ------------------------------------------------------------------ the path plot
def _square_m(side_m: float = 0.1, n: int = 400) -> np.ndarray:
    """A square in the y-z plane travelled counter-clockwise in (y, z) from (0, 0) (N x 3, m)."""
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float) * side_m
    s = np.linspace(0, 4, n)
    k = np.minimum(s.astype(int), 3)
    yz = corners[k] + (s - k)[:, None] * (corners[k + 1] - corners[k])
    return np.column_stack([np.full(n, 0.4), yz])


def _legend_labels(fig) -> list[str]:
    return [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_the_path_plot_says_what_everything_is_and_which_way_it_went():
    from hubo_cli.plots.paths import ARROWS, path_figure

    goal = _square_m()
    actual = goal + 0.0005
    stops = actual[[150]]
    fig = path_figure(goal, actual, hole_m=actual[:300] + 0.001, stops_m=stops,
                      actual_label="bit measured")
    try:
        labels = _legend_labels(fig)
        for expected in ("commanded (operator / task)", "bit measured", "direction of travel",
                         "start", "end", "emergency stop"):
            assert expected in labels
        assert any(label.startswith("hole cut in the wall") for label in labels)
        ax = fig.axes[0]
        arrows = [a for a in ax.texts if a.get_gid() == "direction-arrow"]
        assert len(arrows) == ARROWS
        # each arrow points along the square's travel: its heading is the path's there
        yz = goal[:, 1:] * 1000
        for arrow in arrows:
            tail, head = np.asarray(arrow.xyann), np.asarray(arrow.xy)
            k = int(np.argmin(np.linalg.norm(yz - tail, axis=1)))
            tangent = yz[min(k + 5, len(yz) - 1)] - yz[k]
            assert np.dot(head - tail, tangent) > 0
        # the hole is drawn under the two paths and wider than them (seen beside them)
        hole = next(line for line in ax.lines if line.get_label().startswith("hole"))
        paths = [line for line in ax.lines if line.get_label() in ("bit measured",
                                                                    "commanded (operator / task)")]
        assert all(hole.get_zorder() < p.get_zorder()
                   and hole.get_linewidth() > 3 * p.get_linewidth() for p in paths)
        stop = next(line for line in ax.lines if line.get_label() == "emergency stop")
        assert np.allclose(np.c_[stop.get_xdata(), stop.get_ydata()], stops[:, 1:] * 1000)
        assert not [t for t in ax.texts if t.get_gid() == "did-not-move"]
    finally:
        plt.close(fig)


@pytest.mark.parametrize("tremor_mm", [0.0, 0.5, 3.0, 8.0])
def test_a_hand_that_did_not_move_is_drawn_on_20_mm_axes_with_a_note(tremor_mm):
    from hubo_cli.plots.paths import MIN_SPAN_MM, path_figure

    rng = np.random.default_rng(int(tremor_mm * 10))
    still = np.array([0.3, 0.25, 0.05]) + rng.uniform(-tremor_mm, tremor_mm, (300, 3)) / 2000
    fig = path_figure(np.repeat(still[:1], 300, axis=0), still)
    try:
        ax = fig.axes[0]
        fig.canvas.draw()
        for lo, hi in (ax.get_xlim(), ax.get_ylim()):
            assert abs(hi - lo) >= MIN_SPAN_MM - 1e-9  # tremor is not magnified
        notes = [t.get_text() for t in ax.texts if t.get_gid() == "did-not-move"]
        assert len(notes) == 1 and notes[0].startswith("did not move")
        assert not [t for t in ax.texts if t.get_gid() == "direction-arrow"]  # no way to go
    finally:
        plt.close(fig)
    moved = still + np.linspace(0, 0.05, 300)[:, None] * [0, 1, 0]  # a 50 mm sweep
    fig = path_figure(moved, moved)
    try:
        assert not [t for t in fig.axes[0].texts if t.get_gid() == "did-not-move"]
    finally:
        plt.close(fig)


def test_the_sweep_plot_shows_every_run_and_says_what_its_value_means():
    from hubo_cli.sweep import Row, sweep_figure

    rows = [Row("cut-rectangle", seed, {"speed_mm_s": speed}, completed=speed < 40,
                estop="" if speed < 40 else "wrist-torque", hole_rms_mm=1.0 + speed / 100)
            for seed in (1, 2) for speed in (10, 20, 40)]
    rows.append(Row("cut-rectangle", 3, {"speed_mm_s": 20}, completed=False, ended="refused"))
    fig = sweep_figure(rows)
    try:
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert labels == ["completed", "not completed (e-stop: wrist-torque)",
                          "not completed (e-stop: wrist-torque), no value (on the floor)"]
        marks = sum(len(c.get_offsets()) for c in fig.axes[0].collections)
        assert marks == len(rows)  # the refused run without a value is drawn too
        title = fig._suptitle.get_text()
        assert "7 runs, 4 completed" in title and "lower is better" in title
        assert fig.axes[0].get_xlabel() == "speed_mm_s (--set)"
    finally:
        plt.close(fig)
