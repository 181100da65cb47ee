"""One short walk on the simulated robot through the whole pipeline, driven by the CLI."""

import json

import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main

pytestmark = [pytest.mark.slow,
              pytest.mark.xdist_group("walking-sim")]  # module-scoped runs: one worker


@pytest.fixture(scope="module")
def short_walk(tmp_path_factory):
    """hubo walk --to 0.3 0 0 --corrections 0 --json: four steps, about 7.4 s simulated."""
    out = tmp_path_factory.mktemp("walk") / "run"
    result = CliRunner().invoke(main, ["walk", "--to", "0.3", "0", "0", "--corrections", "0",
                                       "--json", "--out", str(out)])
    return result, out


@pytest.mark.physical
def test_walk_prints_its_figures(short_walk):
    result, _ = short_walk
    assert result.exit_code == 0, result.output
    fields = json.loads(result.stdout)
    for key in ("fell", "final_error_mm", "final_error_deg", "steps", "average_speed_m_s",
                "zmp_inside_fraction"):
        assert key in fields
    assert fields["steps"] == 4  # on both code paths (AVX-512 / portable)


@pytest.mark.physical
def test_walk_goes_forward_without_falling(short_walk):
    result, out = short_walk
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fell"] is False
    assert summary["ended"] == "done"
    assert summary["estop_events"] == []
    assert summary["duration_s"] <= 10.0  # 6.51 s on both code paths: 1.5x
    assert "walk.png" in summary["files"] and (out / "walk.png").exists()
    # four 75 mm steps: the stance moved most of the 0.3 m (the feet slip a few cm at most;
    # measured 0.19-0.48 mm, AVX-512 / portable)
    assert summary["final_error_mm"] < 60.0
    assert summary["zmp_inside_fraction"] >= 0.99
    last = summary["footsteps"][-1]
    assert last["x_m"] == pytest.approx(0.3, abs=0.002)


@pytest.mark.physical
def test_the_estimate_follows_the_walking_robot(short_walk):
    """The estimation layer's torso position (the legs anchored at the loaded sole) against the
    simulator's, both in the log, over the whole walk (no slip on the nominal robot)."""
    import numpy as np

    from hubo_cli.control.log import load_log

    _, out = short_walk
    log = load_log(out)
    error = np.array([log[f"est_torso_{axis}_m"] - log[f"torso_{axis}_m"] for axis in "xyz"])
    walked = np.all(np.isfinite(error), axis=0)
    assert walked.sum() > 1000
    # measured (AVX-512): 0.70 mm across, 0.61 mm in height at most; bounds about 3x
    assert np.max(np.hypot(*error[:2, walked])) < 2.0e-3
    assert np.max(np.abs(error[2, walked])) < 2.0e-3


@pytest.mark.physical
def test_the_torso_offset_holds_in_the_patterns_settle(short_walk):
    """After the last step's landing the stabilizer's torso offset holds: its integrating CoM
    feedback, left on there, wound up and set the soles' loads chattering in fast seed 1's
    settle before the hop that felled it (docs/history/walking.md, "The walk's own settle")."""
    import numpy as np

    from hubo_cli.control.log import load_log

    log = load_log(short_walk[1])
    step = np.asarray(log["walk.step"])
    settle = (np.arange(len(step)) > np.nonzero(step >= 0)[0][-1]) & np.isfinite(step)
    assert settle.sum() > 100  # the pattern's settle is logged (1.5 s on the short walk)
    for axis in "xy":
        offset = np.asarray(log[f"walk.offset_{axis}_m"])[settle]
        assert np.ptp(offset) == 0.0  # held, not slowly drifting


def test_walk_refuses_a_bad_goal():
    result = CliRunner().invoke(main, ["walk", "--to", "inf", "0", "0"])
    assert result.exit_code == 2
    assert "finite" in result.output


@pytest.fixture(scope="module")
def side_walk(tmp_path_factory):
    """hubo walk --to 0 0.12 0 --corrections 0: six steps to the left, the feet's spacing
    changing by the full lateral limit on each, about 8.5 s simulated."""
    out = tmp_path_factory.mktemp("side") / "run"
    result = CliRunner().invoke(main, ["walk", "--to", "0", "0.12", "0", "--corrections", "0",
                                       "--json", "--out", str(out)])
    return result, out


@pytest.mark.physical
def test_walk_sideways_without_falling(side_walk):
    """Sideways steps widen and narrow the stance by 2 x 30 mm; the robot (which fell walking
    0.3 m sideways with 0.05 m lateral steps) arrives standing, near the goal."""
    result, out = side_walk
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fell"] is False
    assert summary["ended"] == "done"
    assert summary["estop_events"] == []
    assert summary["steps"] == 6
    # one plan, no correction: the feet slip about 10 mm over 0.3 m sideways (measured 1.6-1.9
    # mm and 0.05-0.09 deg, AVX-512 / portable: 20x and 30x)
    assert summary["final_error_mm"] < 40.0
    assert summary["final_error_deg"] < 3.0
    # the estimate's ZMP inside the hull of the soles the estimate has in contact
    assert summary["zmp_inside_fraction"] >= 0.95
    last = summary["footsteps"][-2:]
    assert sorted(s["y_m"] for s in last) == pytest.approx([0.0, 0.24], abs=0.002)


@pytest.mark.physical
@pytest.mark.parametrize("seed", [4, 11])
def test_perturbed_walk_lands_its_steps_where_planned(tmp_path, seed):
    """Perturbed robots 4 (foot friction 0.46, the floor tilted 0.38 deg) and 11 walk 1 m on
    the estimate without a correction. The stabilizer's torso offset and touchdown hold reach
    the legs, so the feet do not slip off their steps at the landings (robot 4 ended 9.9 mm off
    when they did not; the goal is 10 mm)."""
    out = tmp_path / "run"
    result = CliRunner().invoke(main, ["walk", "--to", "1.0", "0", "0", "--perturb", str(seed),
                                       "--corrections", "0", "--json", "--out", str(out)])
    assert result.exit_code == 0, result.output
    fields = json.loads(result.stdout)
    assert fields["fell"] is False
    assert fields["steps"] == 8
    # against the truth: since the floating base keeps its gyro turn's pivot continuous
    # (round 5), robot 11 ends 1.67 mm off on AVX-512 and 8.50 mm on the portable path (3.17
    # mm before the change there; the estimate's own error fell, 5.97 -> 4.57 mm: the truth's
    # slip is what the legs cannot see). The bound is the 10 mm itself, 1.18x the
    # portable figure: less than the usual 1.5x margin, because a looser bound would no
    # longer test the requirement (docs/history/walking.md, end of round 5)
    assert fields["final_error_mm"] < 10.0
    # the estimate's own figure: 2.15 / 2.68 mm measured (the 20 seeds: up to 7.7 mm)
    assert fields["estimated_final_error_mm"] < 12.0
    assert fields["average_speed_m_s"] >= 0.1  # the plan's 1 m in 8.9 s: 0.112 on every run
    # the estimate's ZMP inside the estimate's contact hull: 1.0 / 0.959 measured (the 20
    # seeds: 0.940-1.0); the misses lie at the transitions, where the contact's debounce
    # still counts a sole that has left
    assert fields["zmp_inside_fraction"] >= 0.9
