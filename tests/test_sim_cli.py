"""``hubo sim``: text and JSON reports, run folder, bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main


@pytest.mark.physical
def test_json_report_on_a_clean_stdout(tmp_path):
    out = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "hubo_cli.cli.main", "sim", "--duration", "0.3",
                           "--json", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)  # nothing but the JSON object on stdout
    assert {"max_tilt_deg", "feet_flat", "fell", "realtime_factor"} <= set(report)
    assert report["fell"] is False and report["feet_flat"] is True
    # tilt 0.010 deg on both code paths (AVX-512 / portable): 190x under the bound
    assert 0 <= report["max_tilt_deg"] < 2 and report["realtime_factor"] > 0
    assert (out / "snapshot.png").read_bytes()[:4] == b"\x89PNG"
    assert json.loads((out / "summary.json").read_text())["push_n"] == 0.0
    assert report["push_direction"] == [1.0, 0.0, 0.0]  # the default, as the summary gives it
    # the limit set the options decided, and why, in the report too (not only in words)
    assert report["limit_set"] == "walking"
    assert report["limit_set_reason"] == "the hip strategy needs its legs' speed"


def test_text_report(tmp_path):
    result = CliRunner().invoke(main, ["sim", "--duration", "0.2", "--no-balance", "--out",
                                       str(tmp_path)])
    assert result.exit_code == 0, result.output
    for words in ("max tilt", "feet flat", "fell", "real-time factor", "snapshot.png",
                  "leg limits        table4"):
        assert words in result.output
    # the files it lists are the ones it wrote (the summary's list; log.json and log.parquet too)
    written = sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))
    files = json.loads((tmp_path / "summary.json").read_text())["files"]
    assert sorted(files) == written and ", ".join(files) in result.output


def test_bad_duration_is_an_input_error(tmp_path):
    result = CliRunner().invoke(main, ["sim", "--duration", "0", "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "duration" in result.output


def test_push_direction_reaches_the_run_and_a_bad_one_is_refused(tmp_path, monkeypatch):
    # only the wiring is under test here (the pushes themselves are in
    # test_balance_default.py): the run is replaced by a look at the push it was given
    import hubo_cli.session as session

    pushes = []

    def run_in(setup, target, *args):
        pushes.append((target.push_world_n.tolist(), target.push_at_s))
        raise SystemExit(0)

    monkeypatch.setattr(session, "_run_in", run_in)
    result = CliRunner().invoke(main, ["sim", "--duration", "1.2", "--push", "60",
                                       "--push-direction", "right", "--out",
                                       str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert pushes == [([0.0, -60.0, 0.0], 1.0)]
    bad = CliRunner().invoke(main, ["sim", "--push", "60", "--push-direction", "up",
                                    "--out", str(tmp_path / "bad")])
    assert bad.exit_code == 2
    assert "push-direction" in bad.output


@pytest.mark.parametrize("command", [["sim", "--duration", "1.19", "--push", "60"],
                                     ["sim", "--duration", "0.5", "--push", "100", "--json"],
                                     ["sweep", "sim", "--set", "duration=2,0.5", "--set",
                                      "push=100", "--seeds", "0", "--workers", "0"]])
def test_a_stand_that_ends_before_its_push_is_refused(tmp_path, command):
    """Review 22: `hubo sim --duration 0.5 --push 100` said "push 100 N forward for 0.2 s at
    t = 1 s ... fell no", exit 0: the stand had ended before the push came. The push (1 s for
    0.2 s) must end within the stand; nothing runs before the refusal."""
    from hubo_cli.experiments.standing import check_standing_args
    from hubo_cli.model import load_model

    result = CliRunner().invoke(main, [*command, "--out", str(tmp_path / "run")])
    assert result.exit_code == 2, result.output
    assert "ends before the push does" in result.output
    assert not (tmp_path / "run").exists()
    check_standing_args(1.2, 60.0, load_model())  # the push ends with the stand: it is felt
    check_standing_args(0.5, 0.0, load_model())  # no push, no bound
    check_standing_args(0.5, 60.0, load_model(), push_at_s=0.2, push_duration_s=0.3)


def test_the_push_directions_offered_are_the_ones_the_experiment_knows():
    from hubo_cli.cli.sim import sim
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS

    option = next(p for p in sim.params if p.name == "push_direction")
    assert set(option.type.choices) == set(PUSH_DIRECTIONS)


@pytest.mark.parametrize("balance", ["default", "paper", "off"])
@pytest.mark.parametrize("step", [False, True])
@pytest.mark.parametrize("hip", [False, True])
@pytest.mark.parametrize("limit_set", [None, "table4", "walking"])
def test_the_limit_set_is_decided_once_in_the_options(balance, step, hip, limit_set):
    """Every combination of --balance, --step, --no-hip and --limits: stepping or the hip
    strategy (default balancer only, not with a step) run on the walking set, and a named set
    they cannot run on is refused; without them the named set or Table IV's."""
    from hubo_cli.errors import ConfigError
    from hubo_cli.experiments.standing import standing_options

    needs_walking = step or (hip and balance == "default")
    if needs_walking and limit_set == "table4":
        with pytest.raises(ConfigError, match="walking"):
            standing_options(1.0, balance=balance, step=step, hip_strategy=hip,
                             limit_set=limit_set)
        return
    options = standing_options(1.0, balance=balance, step=step, hip_strategy=hip,
                               limit_set=limit_set)
    expected = "walking" if needs_walking else (limit_set or "table4")
    assert options.safety.limit_set == expected
    assert options.safety.hip_strategy == (hip and not step and balance == "default")
    assert options.safety.balance_choice == balance and options.step == step
    # the hip strategy's runs stand braced (crouched), the default balancer's others standing
    assert options.posture == ("braced" if options.safety.hip_strategy else
                               "standing" if balance == "default" else "home")


def test_an_unknown_standing_posture_is_refused(model):
    from hubo_cli.errors import ConfigError
    from hubo_cli.experiments.standing import posture_of

    with pytest.raises(ConfigError, match="posture"):
        posture_of(model, "crouched")


def test_a_limit_set_the_options_cannot_run_on_is_refused_before_the_run(tmp_path):
    for args in (["--step", "--limits", "table4"], ["--limits", "no-such-set"]):
        result = CliRunner().invoke(main, ["sim", "--duration", "0.1", *args,
                                           "--out", str(tmp_path / "run")])
        assert result.exit_code == 2, result.output
        assert "limit" in result.output
        assert not (tmp_path / "run").exists()


def test_a_stand_is_judged_against_the_robot_it_runs_on(model, tmp_path):
    """Round 21: the shortest stand is one period of the robot the run stands, not of the
    shipped file (main read ``load_model()``'s 5 ms whatever robot ran); a robot file's model
    keeps its file through another limit set (``stand`` and ``walk_to`` reload with one)."""
    from robot_file_support import robot_file_with

    from hubo_cli.errors import InputError
    from hubo_cli.experiments.standing import check_standing_args, stand
    from hubo_cli.model import load_model

    for period_s in (0.002, 0.0125, 0.04):  # the bound is each robot's own period
        folder = tmp_path / str(period_s)
        folder.mkdir()
        robot = load_model(path=robot_file_with(model, folder, "robot", "control_period_s",
                                                str(period_s)))
        check_standing_args(period_s, 0.0, robot)
        with pytest.raises(InputError, match=rf"\[{period_s:g}, 3600\]"):
            check_standing_args(period_s * (1 - 1e-9), 0.0, robot)
    slow = load_model(path=robot_file_with(model, tmp_path, "robot", "control_period_s", "0.01"))
    assert slow.control_period_s == 0.01 and model.control_period_s == 0.005
    check_standing_args(0.007, 0.0, model)  # more than the shipped robot's period
    with pytest.raises(InputError, match=r"duration must be in \[0.01, 3600\] s"):
        check_standing_args(0.007, 0.0, slow)
    with pytest.raises(InputError, match=r"\[0.01, 3600\]"):  # before anything runs
        stand(slow, 0.007, out=tmp_path / "run")
    assert not (tmp_path / "run").exists()
    walking = slow.with_limits("walking")
    assert walking.source == slow.source and walking.control_period_s == 0.01
    assert walking.limits_name == "walking" and walking is slow.with_limits("walking")
    assert model.with_limits("table4") is load_model()  # the shipped file, named or not
