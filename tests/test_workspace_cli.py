"""``hubo workspace-map`` through click's CliRunner: files, JSON, both arms, Ctrl-C."""

import json

import numpy as np
from click.testing import CliRunner

from hubo_cli.cli.main import main


def run(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_listed_in_help():
    result = run("--help")
    assert "workspace-map" in result.output
    assert run("workspace-map", "--help").exit_code == 0


def test_writes_run_folder_and_prints_answer(tmp_path):
    out = tmp_path / "run"
    result = run("workspace-map", "--resolution", "20", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert "wall distance (mm)" in result.output and "joints at min y" in result.output
    for name in ("workspace.npz", "summary.json", "workspace-fig4-right.png",
                 "width-vs-distance.png"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    for key in ("best_distance_mm", "width_mm", "height_mm", "resolution_mm", "points",
                "seconds", "rectangle"):
        assert key in summary
    assert summary["resolution_mm"] == 20
    assert all(p["reachable"] for p in summary["paper_points"])
    with np.load(out / "workspace.npz") as data:
        masks = data["right_masks"]
        assert masks.shape == (len(data["right_x_m"]), len(data["right_z_m"]),
                               len(data["right_y_m"]))
        assert np.array_equal(data["right_reachable"], masks != 0)
        assert summary["points"] == masks.size


def test_json_both_arms(tmp_path):
    result = run("workspace-map", "--arm", "both", "--resolution", "25", "--no-refine",
                 "--limits", "team-code", "--out", str(tmp_path), "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["arm"] == "both" and set(data["arms"]) == {"right", "left"}
    right, left = data["arms"]["right"], data["arms"]["left"]
    # team-code limits are mirror-symmetric: same widths, mirrored ends
    assert left["width_mm"] == right["width_mm"]
    assert left["segment"]["y_max_mm"] == -right["segment"]["y_min_mm"]
    assert (tmp_path / "workspace-fig4-left.png").exists()


def test_bad_orientation_is_a_one_line_error(tmp_path):
    result = CliRunner().invoke(main, ["workspace-map", "--orientation", "sideways", "--out",
                                       str(tmp_path)])
    assert result.exit_code == 2
    assert "unknown orientation" in result.output and "Traceback" not in result.output


def test_ctrl_c_stops_cleanly(tmp_path, monkeypatch):
    import hubo_cli.workspace as workspace

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(workspace, "compute_map", interrupted)
    result = CliRunner().invoke(main, ["workspace-map", "--out", str(tmp_path / "run")])
    assert result.exit_code == 130
    assert result.output.strip() == "interrupted"
    assert not (tmp_path / "run").exists()  # nothing half-written


def test_reversed_range_is_a_usage_error(tmp_path):
    """--x-range 650 300 (or a reversed --z-range) is refused as click refuses a bad value
    (exit 2, one error line, nothing computed), never swapped silently."""
    for option, values in (("--x-range", ("650", "300")), ("--z-range", ("100", "-100"))):
        out = tmp_path / option.strip("-")
        result = run("workspace-map", option, *values, "--resolution", "20", "--out", str(out))
        assert result.exit_code == 2, result.output
        errors = [line for line in result.output.splitlines() if line.startswith("Error")]
        assert len(errors) == 1 and f"'{option}'" in errors[0] and "reversed" in errors[0]
        assert not out.exists()
