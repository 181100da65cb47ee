"""Safety is weakened only by an explicit command-line choice (issue 32, part 1), and output
that cannot be encoded is replaced (part 9).

A task file or ``--set`` may add stop sources and lower the wrist-torque limit; every other
spelling of removing a source or raising the limit is refused (exit 2, one line naming
``--estop-sources``) before anything runs, with no file changed. ``--estop-sources`` and
``--no-estop`` remove sources; on the hardware driver only with ``--accept-reduced-safety``
(exit 4 without). What ran is in summary.json, task.toml and the start line.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import random
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from task_files import raise_and_hold

from hubo_cli.cli.main import main
from hubo_cli.control.stop_choice import (
    SOFT_SOURCES,
    TASK_SOURCES,
    ActiveStops,
    StopChoice,
    decide_stops,
)
from hubo_cli.errors import InputError, SafetyError
from hubo_cli.resources import data_file
from hubo_cli.tasks.spec import load_task

CUT_SLOT = data_file("tasks", "cut-slot.toml")
PUSH_WALL = data_file("tasks", "push-wall.toml")
ROBOT_LIMIT_NM = 1.21  # robots/hubo2plus/hubo2plus.toml [safety]

# raise the drill and hold it: about 2 s of simulated time
SHORT_TASK = raise_and_hold("short-hold", 0.2)


def _toml_list(sources) -> str:
    return "[" + ", ".join(f'"{s}"' for s in sources) + "]"


def _weakening_source_lists(rng: random.Random, n: int = 6) -> list[list[str]]:
    """Source lists that lack at least one of a task's sources: the empty list, every subset
    of the soft sources that misses one, shuffled and with repeats (a sample of n)."""
    lists = [[]]
    for size in range(1, len(SOFT_SOURCES) + 1):
        for combo in itertools.combinations(SOFT_SOURCES, size):
            if not set(TASK_SOURCES) <= set(combo):
                lists.append(list(combo))
    picked = [[]] + rng.sample(lists[1:], n - 1)
    for sources in picked[1:]:
        rng.shuffle(sources)
        if rng.random() < 0.5:
            sources.append(sources[0])  # a repeat does not make up for a missing source
    return picked


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _cli(args: list[str], env: dict | None = None):
    return CliRunner().invoke(main, args, env=env)


def _assert_refused(result, code: int, *words: str) -> None:
    """Exit ``code``; one ``error:`` line (and its hint) naming ``words``; no traceback."""
    assert result.exit_code == code, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    lines = result.output.strip().splitlines()
    errors = [line for line in lines if line.startswith("error:")]
    assert len(errors) == 1 and len(lines) <= 2, result.output
    assert "Traceback" not in result.output and "internal error" not in result.output
    for word in words:
        assert word in result.output, (word, result.output)


SEED = 32  # the hostile variants are drawn; any seed must pass


@pytest.mark.parametrize("sources", _weakening_source_lists(random.Random(SEED)))
def test_set_cannot_remove_a_stop_source(tmp_path, sources):
    out = tmp_path / "run"
    result = _cli(["task", "cut-slot", "--set", "speed_mm_s=150",
                   "--set", f"safety.estop_sources={_toml_list(sources).replace(' ', '')}",
                   "--out", str(out)])
    _assert_refused(result, 2, "safety.estop_sources", "--estop-sources", "set on the command")
    assert not out.exists()


@pytest.mark.parametrize("sources", _weakening_source_lists(random.Random(SEED + 1)))
def test_a_task_file_cannot_remove_a_stop_source(tmp_path, sources):
    text = CUT_SLOT.read_text()
    line = 'estop_sources = ["operator", "capture-point", "wrist-torque"]'
    assert line in text
    task = tmp_path / "weak.toml"
    task.write_text(text.replace(line, f"estop_sources = {_toml_list(sources)}"))
    before = _digest(task)
    result = _cli(["task", "run", str(task), "--out", str(tmp_path / "run")])
    _assert_refused(result, 2, f"{task}:", "safety.estop_sources", "--estop-sources")
    assert _digest(task) == before and not (tmp_path / "run").exists()


def test_a_parameter_cannot_carry_a_removal_either(tmp_path):
    """The list behind a task parameter: its default or --set."""
    text = CUT_SLOT.read_text().replace(
        'estop_sources = ["operator", "capture-point", "wrist-torque"]',
        'estop_sources = "$stops"').replace(
        "[parameters]", '[parameters]\nstops = ["operator", "capture-point", "wrist-torque"]')
    task = tmp_path / "param.toml"
    task.write_text(text)
    assert load_task(task).safety.estop_sources == TASK_SOURCES
    for value in ("[]", '["operator"]', '["wrist-torque","stale-input"]'):
        result = _cli(["task", "run", str(task), "--set", f"stops={value}",
                       "--out", str(tmp_path / "run")])
        _assert_refused(result, 2, "--estop-sources")
    task.write_text(text.replace('stops = ["operator", "capture-point", "wrist-torque"]',
                                 'stops = ["capture-point"]'))
    _assert_refused(_cli(["task", "run", str(task)]), 2, "the file's default", "--estop-sources")


@pytest.mark.parametrize("limit", [ROBOT_LIMIT_NM + 0.01, 1.5, 49.9])
def test_no_limit_above_the_robot_files(tmp_path, limit):
    result = _cli(["task", "cut-slot", "--set", f"safety.wrist_torque_limit_nm={limit}"])
    _assert_refused(result, 2, "safety.wrist_torque_limit_nm", f"{ROBOT_LIMIT_NM:g} N m")
    task = tmp_path / "high.toml"
    task.write_text(CUT_SLOT.read_text().replace("wrist_torque_limit_nm = 1.21",
                                                 f"wrist_torque_limit_nm = {limit}"))
    _assert_refused(_cli(["task", "run", str(task)]), 2, f"{task}:",
                    "safety.wrist_torque_limit_nm")


def test_a_file_or_set_may_tighten(tmp_path):
    spec = load_task("cut-slot", {"safety.estop_sources": [*SOFT_SOURCES, "operator"],
                                  "safety.wrist_torque_limit_nm": 0.9})
    assert spec.safety.estop_sources == SOFT_SOURCES  # in order, once each
    assert spec.safety.wrist_torque_limit_nm == pytest.approx(0.9)
    text = SHORT_TASK + '\n[safety]\nestop_sources = ["stale-input", "wrist-torque", ' \
                        '"capture-point", "operator"]\n'
    task = tmp_path / "tight.toml"
    task.write_text(text)
    assert load_task(task).safety.estop_sources == SOFT_SOURCES
    # no [safety] table: the task's sources and the robot file's limit
    task.write_text(SHORT_TASK)
    assert load_task(task).safety.estop_sources == TASK_SOURCES
    assert load_task(task).safety.wrist_torque_limit_nm == pytest.approx(ROBOT_LIMIT_NM)


@pytest.mark.parametrize("how", [["--set", "estop=false"], ["--set", "estop=FALSE"], "false",
                                 "0", '"no"'])
def test_the_push_wall_stopper_is_turned_off_on_the_command_line_only(tmp_path, how):
    if isinstance(how, str):  # the task file's own value
        task = tmp_path / "push.toml"
        task.write_text(PUSH_WALL.read_text().replace("estop = true", f"estop = {how}"))
        args = ["task", "run", str(task)]
    else:
        args = ["task", "push-wall", *how]
    result = _cli([*args, "--out", str(tmp_path / "run")])
    _assert_refused(result, 2, "parameters.estop", "--no-estop")


@pytest.mark.parametrize("text", ["", ",", "bogus", "operator,,bogus", "none,operator",
                                  "Operator", "operator;capture-point"])
def test_bad_estop_sources_are_refused(text):
    with pytest.raises(InputError):
        StopChoice.from_options(False, text, False)
    result = _cli(["task", "cut-slot", "--estop-sources", text])
    _assert_refused(result, 2, "--estop-sources")


def test_only_the_command_line_removes_and_the_hardware_needs_a_second_option(tmp_path):
    choice = StopChoice.from_options(False, "wrist-torque,operator", False)
    assert choice.sources == ("operator", "wrist-torque")
    stops = decide_stops(TASK_SOURCES, choice, "sim")
    assert stops == ActiveStops(("operator", "wrist-torque"), ("capture-point",),
                                "--estop-sources operator,wrist-torque")
    assert decide_stops(TASK_SOURCES, StopChoice(), "hardware").removed == ()
    added = decide_stops(TASK_SOURCES, StopChoice(sources=SOFT_SOURCES), "hardware")
    assert added.removed == () and added.sources == SOFT_SOURCES  # adding needs no consent
    for weaker in (StopChoice(no_estop=True), StopChoice(sources=("operator",)),
                   StopChoice(sources=())):
        with pytest.raises(SafetyError):
            decide_stops(TASK_SOURCES, weaker, "hardware")
        confirmed = StopChoice(weaker.no_estop, weaker.sources, accept_reduced=True)
        assert decide_stops(TASK_SOURCES, confirmed, "hardware").removed
    with pytest.raises(InputError):
        StopChoice.from_options(True, "operator", False)
    # from the command line: refused before the driver is even opened (no libach here)
    env = {"HUBO_LIBACH": str(tmp_path / "missing-libach.so")}
    task = tmp_path / "short.toml"
    task.write_text(SHORT_TASK)
    for option in (["--no-estop"], ["--estop-sources", "capture-point"],
                   ["--estop-sources", "none"]):
        result = _cli(["task", "run", str(task), "--driver", "hardware", "--arm", *option,
                       "--out", str(tmp_path / "run")], env=env)
        _assert_refused(result, 4, "--accept-reduced-safety", "nothing moved")
        confirmed = _cli(["task", "run", str(task), "--driver", "hardware", "--arm", *option,
                          "--accept-reduced-safety", "--out", str(tmp_path / "run")], env=env)
        assert confirmed.exit_code == 3 and "libach is not available" in confirmed.output
    assert not (tmp_path / "run").exists()
    replay = data_file("trajectories", "two-hand-free.csv")
    before = _digest(replay)
    result = _cli(["teleop", "--replay", str(replay), "--driver", "hardware", "--arm",
                   "--estop-sources", "operator", "--out", str(tmp_path / "run")], env=env)
    _assert_refused(result, 4, "capture-point, wrist-torque and stale-input stops",
                    "--accept-reduced-safety")
    assert _digest(replay) == before and not (tmp_path / "run").exists()


def test_an_inline_safety_table_is_checked_the_same(tmp_path):
    text = CUT_SLOT.read_text()
    start = text.index("[safety]")
    end = text.index("[[steps]]")
    task = tmp_path / "inline.toml"
    # an inline table must come before the first table header: put it at the top
    task.write_text('safety = { estop_sources = ["capture-point"] }\n'
                    + text[:start] + text[end:])
    _assert_refused(_cli(["task", "run", str(task)]), 2, "safety.estop_sources",
                    "--estop-sources capture-point")


@pytest.fixture(scope="module")
def reduced_runs(tmp_path_factory):
    """The short task on the ideal driver with --estop-sources and with --no-estop."""
    root = tmp_path_factory.mktemp("reduced")
    task = root / "short.toml"
    task.write_text(SHORT_TASK)
    runs = {}
    for name, option in (("sources", ["--estop-sources", "capture-point"]),
                         ("none", ["--no-estop"]), ("default", [])):
        result = _cli(["task", "run", str(task), "--driver", "ideal", *option,
                       "--out", str(root / name)])
        runs[name] = (result, json.loads((root / name / "summary.json").read_text()),
                      (root / name / "task.toml").read_text())
    return runs


def test_what_ran_is_printed_written_and_noted(reduced_runs):
    result, summary, copy = reduced_runs["sources"]
    assert result.exit_code == 0, result.output
    assert ("safety: e-stop sources: capture-point; REMOVED by --estop-sources capture-point: "
            "operator, wrist-torque") in result.stderr
    assert summary["estop_enabled"] is True and summary["estop_sources"] == ["capture-point"]
    assert summary["estop_removed"] == {"sources": ["operator", "wrist-torque"],
                                        "by": "--estop-sources capture-point"}
    assert "# safety of this run: e-stop sources capture-point;" in copy
    assert "removed on the command line: operator, wrist-torque" in copy

    result, summary, copy = reduced_runs["none"]
    assert result.exit_code == 0, result.output
    assert "e-stop sources: none (no soft emergency stop); REMOVED by --no-estop" in result.stderr
    assert summary["estop_enabled"] is False and summary["estop_sources"] == []
    assert "estop" not in summary["pipeline"]
    assert "# safety of this run: e-stop sources none;" in copy

    result, summary, copy = reduced_runs["default"]
    assert result.exit_code == 0, result.output
    assert summary["estop_sources"] == list(TASK_SOURCES) and summary["estop_removed"] is None
    assert "e-stop sources operator, capture-point, wrist-torque; wrist torque limit 1.21" in copy
    assert summary["finished_by_operator"] is False


def test_output_that_cannot_be_encoded_is_replaced(tmp_path):
    """PYTHONIOENCODING=ascii: the em dash and degree signs become '?', never an error."""
    env = {**os.environ, "PYTHONIOENCODING": "ascii",
           "PYTHONPATH": os.pathsep.join(sys.path)}
    hubo = [sys.executable, "-m", "hubo_cli.cli.main"]
    shown = subprocess.run([*hubo, "task", "show", "cut-rectangle"], env=env,
                           capture_output=True, timeout=120)
    assert shown.returncode == 0, shown.stderr
    assert b"cut-rectangle ? Drill" in shown.stdout and not shown.stderr
    task = tmp_path / "caf\u00e9 \u00b0.toml"
    task.write_text(SHORT_TASK.replace("Raise the drill", "Raise the drill 10\u00b0 \u2014 hold"))
    shown = subprocess.run([*hubo, "task", "show", str(task), "--json"], env=env,
                           capture_output=True, timeout=120)
    assert shown.returncode == 0 and b"internal error" not in shown.stderr
    missing = subprocess.run([*hubo, "task", "run", str(tmp_path / "n\u00b0.toml")], env=env,
                             capture_output=True, timeout=120)
    assert missing.returncode == 2 and missing.stderr.count(b"error:") == 1
    assert b"Traceback" not in missing.stderr and b"internal error" not in missing.stderr
