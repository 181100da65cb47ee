"""The emergency-stop experiment (paper IV-C) on the simulated robot, both ways, and its CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from control_support import assert_within_braking_limits

from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log
from hubo_cli.experiments.push_wall import FALL_TILT_DEG, run_push_wall

pytestmark = pytest.mark.slow

SUMMARY_KEYS = {"estop", "fell", "max_tilt_deg", "t_emergency_s", "max_cp_error_mm"}


def _commands_ok(model, run_dir):
    log = load_log(run_dir)
    commands = log.joints("cmd")
    commands = np.vstack([commands[:1], commands[:1], commands])
    # the stop's revert brakes at the emergency limits before it goes back
    assert_within_braking_limits(model, commands, model.control_period_s)
    return log


@pytest.mark.physical
def test_push_wall_forward_with_estop_stays_up(model, tmp_path):
    result = run_push_wall(model, "forward", estop=True, out=tmp_path, end_s=5.0)
    s = result.summary
    # measured the same on both code paths (AVX-512 / portable): tilt 3.25 deg (bound 3.1x),
    # stop at 2.09 s (2.1x inside its window), elbows bent back 0.37 rad (3.7x), final tilt
    # 0.0016 deg; since the revert brakes at the emergency limits (this code path only): tilt
    # 1.53 deg (6.5x), stop at 2.09 s, elbows bent back 0.18 rad (1.8x: they run on less before
    # they turn), final tilt 0.0006 deg
    assert SUMMARY_KEYS <= set(s)
    assert s["estop"] == "on" and not s["fell"] and not s["tipped"] and s["max_tilt_deg"] < 10.0
    assert s["t_emergency_s"] is not None and s["emergency_sources"] == ["capture-point"]
    assert 1.0 < s["t_emergency_s"] < 4.5          # during the commanded push
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["fell"] is False and on_disk["t_emergency_s"] == s["t_emergency_s"]
    assert (tmp_path / "cp_error.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    log = _commands_ok(model, tmp_path)
    after = log["t_s"] >= s["t_emergency_s"]
    assert np.all(log["estop_mode_code"][after & np.isfinite(log["estop_mode_code"])] >= 1)
    # the push reverts: both elbows, which straighten while pushing, bend back again
    cmd = log.joints("cmd")[after]
    for joint in ("REB", "LEB"):
        elbow = cmd[:, log.joint_names.index(joint)]
        assert elbow.max() - elbow[-1] > 0.1, joint
    assert log["tilt_deg"][np.isfinite(log["tilt_deg"])][-1] < 3.0  # standing again


@pytest.mark.physical
def test_push_wall_forward_without_estop_falls(model, tmp_path):
    result = run_push_wall(model, "forward", estop=False, out=tmp_path)
    s = result.summary
    assert s["estop"] == "off" and s["t_emergency_s"] is None
    # fell to 90.4 deg on both code paths (AVX-512 / portable)
    assert s["fell"] and s["tipped"] and s["max_tilt_deg"] > FALL_TILT_DEG
    assert s["t_cp_flag_s"] is not None            # the monitor saw it coming
    assert "estop_mode_code" not in load_log(tmp_path).columns


@pytest.mark.physical
def test_cli_push_wall_left(tmp_path):
    out = tmp_path / "run"
    result = CliRunner().invoke(main, ["task", "push-wall", "--direction", "left", "--json",
                                       "--out", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["direction"] == "left" and summary["estop"] == "on"
    assert not summary["fell"] and not summary["tipped"]  # on both code paths
    assert summary["t_emergency_s"] is not None  # 1.38 s on both code paths
    assert (out / "log.csv").exists() and (out / "cp_error.png").exists()
    assert "task.toml" in summary["files"]  # the text that ran, as every task's run folder
    assert 'direction = "forward"' in (out / "task.toml").read_text()  # the file's default


def test_cli_task_group_lists_push_wall():
    result = CliRunner().invoke(main, ["task", "--help"])
    assert result.exit_code == 0 and "push-wall" in result.output
    result = CliRunner().invoke(main, ["task", "push-wall", "--direction", "up"])
    assert result.exit_code == 2 and "up" in result.output
