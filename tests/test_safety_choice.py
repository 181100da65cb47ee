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
import tomllib
import unicodedata
from pathlib import Path

import pytest
from click.testing import CliRunner
from task_files import raise_and_hold

from hubo_cli.cli.main import main
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.stop_choice import (
    SOFT_SOURCES,
    TASK_SOURCES,
    ActiveStops,
    StopChoice,
    decide_stops,
)
from hubo_cli.errors import ConfigError, InputError, SafetyError
from hubo_cli.resources import data_file
from hubo_cli.runs import SHOWN_MAX_CHARS, check_run_dir, folder_name, shown_name
from hubo_cli.tasks.runner import _title_name, _with_safety_as_run
from hubo_cli.tasks.spec import Safety, load_task

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
    assert "# --estop-sources capture-point removed: operator, wrist-torque" in copy
    assert tomllib.loads(copy)["safety"]["estop_sources"] == ["capture-point"]

    result, summary, copy = reduced_runs["none"]
    assert result.exit_code == 0, result.output
    assert "e-stop sources: none (no soft emergency stop); REMOVED by --no-estop" in result.stderr
    assert summary["estop_enabled"] is False and summary["estop_sources"] == []
    assert "estop" not in summary["pipeline"]
    assert "# safety of this run: e-stop sources none;" in copy
    assert tomllib.loads(copy)["safety"]["estop_sources"] == []

    result, summary, copy = reduced_runs["default"]
    assert result.exit_code == 0, result.output
    assert summary["estop_sources"] == list(TASK_SOURCES) and summary["estop_removed"] is None
    assert "e-stop sources operator, capture-point, wrist-torque; wrist torque limit 1.21" in copy
    assert summary["finished_by_operator"] is False
    assert tomllib.loads(copy)["safety"] == {"estop_sources": list(TASK_SOURCES),
                                             "wrist_torque_limit_nm": ROBOT_LIMIT_NM,
                                             "revert_s": 0.5, "stop_s": 0.5}


def test_the_task_file_as_run_runs_again_with_the_same_option(reduced_runs, tmp_path):
    """The copy lists the reduced sources: loaded only when the command line chooses the
    sources again, and on the hardware still only with the second option."""
    copy = tmp_path / "task.toml"
    copy.write_text(reduced_runs["sources"][2])
    with pytest.raises(ConfigError, match="not remove the operator and wrist-torque") as no:
        load_task(copy)
    assert "--estop-sources capture-point" in no.value.hint
    again = load_task(copy, sources_on_command_line=True)
    assert again.safety.estop_sources == ("capture-point",)
    env = {"HUBO_LIBACH": str(tmp_path / "missing-libach.so")}
    result = _cli(["task", "run", str(copy), "--driver", "hardware", "--arm",
                   "--estop-sources", "capture-point", "--out", str(tmp_path / "run")], env=env)
    _assert_refused(result, 4, "--accept-reduced-safety", "operator and wrist-torque stops")
    _assert_refused(_cli(["task", "run", str(copy), "--out", str(tmp_path / "run")]), 2,
                    "--estop-sources capture-point")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("where", ["table", "inline", "none", "dotted"])
def test_the_copy_holds_the_safety_as_run(where):
    """The [safety] table of the task file as run, however the file spelled its own."""
    text = CUT_SLOT.read_text()
    start, end = text.index("[safety]"), text.index("[[steps]]")
    spelled = {"table": text,
               "inline": 'safety = { estop_sources = ["operator", "capture-point", '
                         '"wrist-torque"] }\n' + text[:start] + text[end:],
               "none": text[:start] + text[end:],
               "dotted": "safety.stop_s = 0.4\n" + text[:start] + text[end:]}[where]
    used = Safety(TASK_SOURCES, 1.0, 0.3, 0.2)
    profile = SafetyProfile(sources=TASK_SOURCES).with_stops(
        ActiveStops(("capture-point",), ("operator", "wrist-torque"), "--estop-sources x"))
    copy = _with_safety_as_run(spelled, profile, used)
    original = tomllib.loads(spelled)
    if where == "dotted":  # not a spelling it rewrites: kept, the header says what ran
        assert copy == spelled
        return
    data = tomllib.loads(copy)
    assert data["safety"] == {"estop_sources": ["capture-point"], "wrist_torque_limit_nm": 1.0,
                              "revert_s": 0.3, "stop_s": 0.2}
    assert {k: v for k, v in data.items() if k != "safety"} == {
        k: v for k, v in original.items() if k != "safety"}


@pytest.mark.parametrize("field", ["stop_s", "revert_s"])
@pytest.mark.parametrize("value", [0.5000001, 0.6, 5.0])
def test_no_slower_stop_than_the_robot_files(tmp_path, field, value):
    """T1 and T2 may only shrink: a longer stop is a weaker one (the robot file: 0.5 s)."""
    result = _cli(["task", "cut-slot", "--set", f"safety.{field}={value}",
                   "--out", str(tmp_path / "run")])
    _assert_refused(result, 2, f"safety.{field}", f"{value!r} s is above", "0.5 s",
                    "set on the command line")
    task = tmp_path / "slow.toml"
    text = CUT_SLOT.read_text()
    assert f"\n{field} = 0.5\n" in text
    task.write_text(text.replace(f"\n{field} = 0.5\n", f"\n{field} = {value}\n"))
    _assert_refused(_cli(["task", "run", str(task), "--out", str(tmp_path / "run")]), 2,
                    f"{task}:", f"safety.{field}")
    assert not (tmp_path / "run").exists()
    assert getattr(load_task("cut-slot", {f"safety.{field}": 0.3}).safety, field) == 0.3


def test_the_limit_message_shows_the_difference():
    with pytest.raises(ConfigError) as caught:
        load_task("cut-slot", {"safety.wrist_torque_limit_nm": 1.2100001})
    assert "1.2100001 N m is above the robot file's limit of 1.21 N m" in str(caught.value)


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


HOSTILE_NAMES = ["a\nb", "\x1b[31mred", "x\u202ey\u2066", "nul\x00", "line\u2028sep",
                 "[bold]markup[/]", "cost $\\frac{a$", "\t" * 300, "é日本 ok"]


@pytest.mark.parametrize("name", HOSTILE_NAMES)
def test_a_task_name_is_shown_safely(tmp_path, name):
    """No control, format or line-separator character reaches the terminal or a plot title,
    and the length is bounded; summary.json keeps the raw name (JSON escapes it)."""
    shown = shown_name(name)
    assert len(shown) <= SHOWN_MAX_CHARS
    assert not any(unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") for c in shown)
    assert shown == name or any(c in name for c in "\n\x1b\u202e\x00\u2028\t")
    assert "$" not in _title_name(name).replace(r"\$", "")
    task = tmp_path / "named.toml"
    task.write_text(SHORT_TASK.replace('name = "short-hold"', f"name = {json.dumps(name)}", 1))
    assert load_task(task).name == name
    result = _cli(["task", "show", str(task)])
    assert result.exit_code == 0, result.output
    first = result.output.splitlines()[0]
    assert first.startswith(shown), first  # markup in the name printed as text
    assert not any(unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") for c in first)


def test_the_out_hint_shows_the_cleaned_folder_name(tmp_path):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "mine.txt").write_text("a user's file")
    command = "task-x/../../../victim\x1b[2J"
    with pytest.raises(InputError) as caught:
        check_run_dir(command, out)
    assert f"runs/<time>-{folder_name(command)})" in caught.value.hint
    assert "../" not in caught.value.hint and "\x1b" not in caught.value.hint
