"""Bad input and operator mistakes: every case gets a one-line error and its exit code, before
anything moves, and no file the user owns is changed (issue: operator safety and bad input).

The table drives ``hubo`` through click's CliRunner with the ideal driver and short streams.
"""

import json
import math
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import COMMANDS, main
from hubo_cli.dataflow import Store
from hubo_cli.errors import InputError
from hubo_cli.fastrak.capture import CHUNK_HEAD, parse_capture, read_recording_bytes
from hubo_cli.resources import data_file
from hubo_cli.runs import MARKER, make_run_dir

FREE_CSV = data_file("trajectories", "two-hand-free.csv")
FREE_CAPTURE = data_file("trajectories", "two-hand-free.fastrak")
SLOT = data_file("tasks", "cut-slot.toml")


def _short_log(path: Path, rows: int = 250) -> Path:
    """The first ~2 s of the shipped two-hand pose log."""
    lines = FREE_CSV.read_text().splitlines()[:rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _jumpy_log(path: Path) -> Path:
    """A pose log whose samples jump by two metres most of the time (tracker garbage within
    the tracker's 3 m range: a kilometre is refused at load, test_fastrak_capture.py)."""
    lines = FREE_CSV.read_text().splitlines()[:250]
    out, seen = [lines[0]], {}
    for line in lines[1:]:
        cells = line.split(",")
        k = seen[cells[1]] = seen.get(cells[1], -1) + 1  # this station's own count
        if k % 6 > 0:  # each station's first pose good, then 2.5 m either side of it
            cells[2] = "2.5" if k % 2 else "-2.5"
        out.append(",".join(cells))
    path.write_text("\n".join(out) + "\n")
    return path


def _suspect_log(path: Path) -> Path:
    """A pose log whose every record carries an out-of-envelope status letter."""
    lines = FREE_CSV.read_text().splitlines()[:250]
    path.write_text("\n".join([lines[0]] + [line.rstrip(",") + ",x" for line in lines[1:]])
                    + "\n")
    return path


def _retimed_log(path: Path, times) -> Path:
    """The short pose log with its rows' times changed by ``times(k, t_s) -> t_s``."""
    lines = FREE_CSV.read_text().splitlines()[:250]
    out = [lines[0]]
    for k, line in enumerate(lines[1:]):
        cells = line.split(",")
        cells[0] = repr(times(k, float(cells[0])))
        out.append(",".join(cells))
    path.write_text("\n".join(out) + "\n")
    return path


def _ascii_labelled_capture(path: Path) -> Path:
    """The shipped binary capture whose header says ASCII: no record decodes."""
    path.write_bytes(FREE_CAPTURE.read_bytes().replace(b'"format": "binary"',
                                                       b'"format": "ascii"', 1))
    return path


def _corrupt_chunk(path: Path, extra: int) -> Path:
    """The shipped capture with one chunk's length field garbled."""
    blob = read_recording_bytes(FREE_CAPTURE)
    cap = parse_capture(blob)
    pos = blob.index(b"\n", blob.index(b"\n") + 1) + 1
    for _ in range(len(cap.chunk_ends) // 3):
        _, n = CHUNK_HEAD.unpack_from(blob, pos)
        pos += CHUNK_HEAD.size + n
    t_s, n = CHUNK_HEAD.unpack_from(blob, pos)
    bad = bytearray(blob)
    CHUNK_HEAD.pack_into(bad, pos, t_s, n + extra)
    path.write_bytes(bytes(bad))
    return path


def _task_with(path: Path, old: str, new: str) -> Path:
    text = SLOT.read_text()
    assert old in text
    path.write_text(text.replace(old, new))
    return path


def _unreachable_task(path: Path) -> Path:
    path.write_text("""name = "far"
[stance]
wall_distance_mm = 470.0
centre_mm = [0.0, 0.0]
[[steps]]
kind = "move"
to_mm = [900.0, 0.0]
depth_mm = -50.0
duration_s = 0.5
""")
    return path


# id -> (argument builder (tmp path -> argv), exit code, text the message must hold)
CASES = {
    "width-3000": (lambda d: ["task", "cut-rectangle", "--width", "3000", "--driver", "ideal"],
                   2, "at most 1000"),
    "height-5000": (lambda d: ["task", "cut-rectangle", "--height", "5000"], 2, "at most 1000"),
    "task-speed-1e9": (lambda d: ["task", "cut-rectangle", "--speed", "1e9"], 2, "at most 500"),
    "task-out-proc": (lambda d: ["task", "cut-slot", "--out", "/proc/hubo-no-such/run"], 2,
                      "cannot create the run folder"),
    "task-out-under-file": (lambda d: ["task", "cut-slot", "--out", str(d / "f.txt" / "sub")],
                            2, "is a file"),
    "task-garbage": (lambda d: ["task", "run", str(_bytes(d / "garbage.toml"))], 2,
                     "not a text file"),
    "task-wait-1e9": (lambda d: ["task", "run", str(_task_with(
        d / "w.toml", "duration_s = 1.0", "duration_s = 1e9"))], 2, "at most 600"),
    "task-revert-1e9": (lambda d: ["task", "run", str(_task_with(
        d / "r.toml", "revert_s = 0.5", "revert_s = 1e9"))], 2, "at most 5"),
    "task-speed-and-set": (lambda d: ["task", "cut-rectangle", "--speed", "20", "--set",
                                      "speed_mm_s=30"], 2, "both set speed_mm_s"),
    "task-unused-parameter": (lambda d: ["task", "cut-slot", "--set", "length_mm=50"], 2,
                              "no parameter 'length_mm'"),
    "task-unreachable": (lambda d: ["task", "run", str(_unreachable_task(d / "far.toml")),
                                    "--driver", "ideal", "--out", str(d / "far-run")], 4,
                         "refused in pre-flight"),
    "workspace-out-proc": (lambda d: ["workspace-map", "--out", "/proc/hubo-no-such/run"], 2,
                           "cannot create the run folder"),
    # review 20: a stand shorter than one control period rounded to no period: internal error
    "sim-duration-1e-300": (lambda d: ["sim", "--duration", "1e-300", "--out",
                                       str(d / "short-run")], 2, "one control period"),
    # round 30: an unknown --limits was "the hip strategy needs the 'walking' set, not 'nope'"
    "sim-limits-unknown": (lambda d: ["sim", "--limits", "nope", "--out", str(d / "lim")], 2,
                           "unknown limit set 'nope'"),
    "sim-out-under-file": (lambda d: ["sim", "--duration", "0.1", "--out",
                                      str(d / "f.txt" / "sub")], 2, "is a file"),
    "teleop-out-under-file": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                         "--driver", "ideal", "--out", str(d / "f.txt" / "sub")],
                              2, "is a file"),
    "teleop-out-user-folder": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                          "--driver", "ideal", "--out", str(d / "mine")],
                               2, "not a hubo run"),
    "teleop-speed-1e-9": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                     "--speed", "1e-9", "--duration", "0.004"], 2,
                          "at least 0.01"),
    "teleop-log-gap-1e300": (lambda d: ["teleop", "--replay", str(_retimed_log(
        d / "g.csv", lambda k, t: 1e300 if k == 120 else t)), "--duration", "2"], 2,
        "more than 3600 s after"),
    "teleop-log-one-time": (lambda d: ["teleop", "--replay", str(_retimed_log(
        d / "o.csv", lambda k, t: 1.0))], 2, "every row has the same time"),
    "decode-no-record": (lambda d: ["fastrak", "decode", str(_ascii_labelled_capture(
        d / "a.fastrak"))], 2, "no valid FASTRAK records"),
    "task-nested-deeply": (lambda d: ["task", "show", str(_task_with(
        d / "deep.toml", 'name = "cut-slot"', "a = " + "[" * 10000 + "]" * 10000 + "\nname = "
        '"deep"'))], 2,
        "nested too deeply"),
    "workspace-x-nan": (lambda d: ["workspace-map", "--x-range", "nan", "300", "--out",
                                   str(d / "ws")], 2, "must be finite"),
    "workspace-orientation-nan": (lambda d: ["workspace-map", "--orientation", "nan,0,0",
                                             "--out", str(d / "ws")], 2, "is not finite"),
    # round 15: a ValueError (exit 1), or 76 s and 3.8 GB for a grid 20 m deep
    "workspace-x-1e308": (lambda d: ["workspace-map", "--x-range", "-1e308", "1e308", "--out",
                                     str(d / "ws")], 2, "within ±1000 mm"),
    "workspace-x-20-m": (lambda d: ["workspace-map", "--x-range", "0", "20000", "--out",
                                    str(d / "ws")], 2, "within ±1000 mm"),
    "workspace-grid-too-fine": (lambda d: ["workspace-map", "--resolution", "1", "--out",
                                           str(d / "ws")], 2, "points (at most 20,000,000)"),
    "workspace-orientation-1e308": (lambda d: ["workspace-map", "--orientation", "1e308,0,0",
                                               "--out", str(d / "ws")], 2, "beyond ±360"),
    # round 15: the times of a pose log that cannot be replayed, named before anything moves
    "teleop-log-time-back": (lambda d: ["teleop", "--replay", str(_retimed_log(
        d / "b.csv", lambda k, t: t - 3.0 if k >= 124 else t))], 2,
        "line 126: t_s -1.9638 s is earlier than the row before it (1.02787 s)"),
    "teleop-log-dense": (lambda d: ["teleop", "--replay", str(_retimed_log(
        d / "n.csv", lambda k, t: 1.0 + t * 1e-7))], 2, "249 records within"),
    "teleop-replay-empty": (lambda d: ["teleop", "--replay", ""], 2, "no recording given"),
    "task-run-empty": (lambda d: ["task", "run", ""], 2, "no task given"),
    "teleop-port-empty": (lambda d: ["teleop", "--port", ""], 2, "no serial port given"),
    "record-port-empty": (lambda d: ["record", "--port", "", "--out",
                                     str(d / "c.fastrak")], 2, "no serial port given"),
    "teleop-clutch-after-the-end": (lambda d: ["teleop", "--replay", str(_short_log(
        d / "s.csv")), "--clutch", "1e308"], 2, "after the replay's end"),
    "teleop-map-5": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                "--map", "5=right-arm"], 2, "stations 1-4"),
    "teleop-map-missing": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                      "--map", "3=right-arm"], 2, "has no station 3"),
    "teleop-two-stations-one-arm": (lambda d: ["teleop", "--replay",
                                               str(_short_log(d / "s.csv")), "--map",
                                               "1=left-arm", "--map", "2=left-arm"],
                                    2, "both drive the left-arm"),
    "teleop-wall-5000": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                    "--mode", "drill", "--wall-distance", "5000", "--out",
                                    str(d / "wall-run")], 2, "at most 1000 mm"),
    # a wall out of reach is one kind of error: exit 4 in teleop as in a task's pre-flight
    "teleop-wall-800": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                   "--mode", "drill", "--wall-distance", "800", "--out",
                                   str(d / "wall-run")], 4, "reaches nothing"),
    "teleop-wall-550": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                   "--mode", "drill", "--wall-distance", "550", "--out",
                                   str(d / "wall-run")], 4, "cannot reach the wall"),
    "teleop-wall-negative": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                        "--mode", "drill", "--wall-distance", "-100"],
                             2, "positive distance"),
    "teleop-duration-negative": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                            "--duration", "-1"], 2, "positive number"),
    "teleop-reconnect-timeout-zero": (lambda d: ["teleop", "--port", "/dev/null",
                                                 "--reconnect-timeout", "0"],
                                      2, "positive number"),
    "teleop-reconnect-timeout-on-a-replay": (lambda d: ["teleop", "--replay",
                                                        str(_short_log(d / "s.csv")),
                                                        "--reconnect-timeout", "1"],
                                             2, "applies to a live tracker"),
    "teleop-baud-on-a-replay": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                           "--baud", "9600"], 2, "applies to a live tracker"),
    "teleop-clutch-negative": (lambda d: ["teleop", "--replay", str(_short_log(d / "s.csv")),
                                          "--clutch", "-1"], 2, "not a time"),
    "teleop-baud-negative": (lambda d: ["teleop", "--port", "/dev/null", "--baud", "-5"], 2,
                             "not a FASTRAK baud rate"),
    "teleop-corrupt-chunk": (lambda d: ["teleop", "--replay",
                                        str(_corrupt_chunk(d / "bad.fastrak", 1_000_000)),
                                        "--driver", "ideal"], 2, "claims"),
    "teleop-mostly-rejected": (lambda d: ["teleop", "--replay", str(_jumpy_log(d / "j.csv")),
                                          "--driver", "ideal", "--out", str(d / "j-run")], 2,
                               "were rejected"),
    "teleop-no-input": (lambda d: ["teleop", "--replay", str(_suspect_log(d / "x.csv")),
                                   "--driver", "ideal", "--out", str(d / "x-run")], 2,
                        "no operator input"),
    "fk-nan": (lambda d: ["fk", "right-arm", "nan", "0", "0", "0", "0", "0"], 2, "NaN"),
    "ik-prev-nan": (lambda d: ["ik", "right-arm", "--xyz", "400", "-200", "0", "--prev", "nan",
                               "0", "0", "0", "0", "0"], 2, "NaN"),
    "ik-xyz-and-matrix": (lambda d: ["ik", "right-arm", "--xyz", "400", "-200", "0",
                                     "--matrix", *"1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1".split()], 2,
                          "both give the goal"),
    "ik-1e300": (lambda d: ["ik", "right-arm", "--xyz", "1e300", "0", "0"], 2,
                 "beyond 1,000,000"),
    "emulate-duration-negative": (lambda d: ["fastrak", "emulate", "--pty", "--duration", "-1"],
                                  2, "positive number"),
    "record-over-existing": (lambda d: ["record", "--port", "/dev/null", "--out",
                                        str(_owned(d / "mine.fastrak"))], 2, "exists"),
    "decode-over-existing-csv": (lambda d: ["fastrak", "decode", str(_copy_capture(d))], 2,
                                 "exists"),
    # round 12: what round 11's review left open
    "decode-output-list-100000": (lambda d: ["fastrak", "decode", str(_capture_with(
        d / "l.fastrak", output_list=[2] * 100_000))], 2, "(199,999 characters)"),
    "decode-output-list-decodes-nothing": (lambda d: ["fastrak", "decode", str(_capture_with(
        d / "z.fastrak", output_list=[2, 11, *[0] * 100_000, 1]))], 2, "(200,006 characters)"),
    "decode-output-list-text": (lambda d: ["fastrak", "decode", str(_capture_with(
        d / "t.fastrak", output_list="x"))], 2, "output_list is 'x', not a list of whole"),
    "decode-baud-nan": (lambda d: ["fastrak", "decode", str(_capture_with(
        d / "n.fastrak", baud=math.nan))], 2, "baud is nan, not a baud rate"),
    "decode-baud-infinite": (lambda d: ["fastrak", "decode", str(_capture_with(
        d / "i.fastrak", baud=math.inf))], 2, "baud is inf, not a baud rate"),
    "task-speed-1e-300": (lambda d: ["task", "show", str(_task_with(
        d / "s.toml", "speed_mm_s = 10.0", "speed_mm_s = 1e-300"))], 2, "at least 0.1, got 1e-300"),
    "task-list-20000": (lambda d: ["task", "show", str(_task_with(
        d / "l.toml", "speed_mm_s = 10.0", f"speed_mm_s = {[1.0] * 20_000}"))], 2,
        "(20,000 items)"),
    "task-integer-5000-digits": (lambda d: ["task", "show", str(_task_with(
        d / "i.toml", "speed_mm_s = 10.0", "speed_mm_s = 1" + "0" * 5000))], 2,
        "an integer too long to read"),
    "set-nested-deeply": (lambda d: ["task", "cut-rectangle", "--set",
                                     "width_mm=" + "[" * 5000 + "]" * 5000], 2,
                          "lists nested too deeply"),
    "set-integer-5000-digits": (lambda d: ["sweep", "cut-slot", "--set",
                                           "speed_mm_s=[" + "9" * 5000 + "]"], 2,
                                "an integer too long to read"),
    "task-dev-zero": (lambda d: ["task", "run", "/dev/zero"], 2, "a device, not a task file"),
    "task-folder": (lambda d: ["task", "show", str(d / "mine")], 2, "a folder, not a task file"),
    "ik-batch-1e300": (lambda d: ["ik", "right-arm", "--batch", str(_batch_csv(
        d / "b.csv", 1e300)), "--out", str(d / "out.csv")], 2, "T03 1e+300 is beyond 1,000,000"),
    "ik-batch-byte-order-mark": (lambda d: ["ik", "right-arm", "--batch", str(_batch_csv(
        d / "b.csv", 0.4, bom=True)), "--out", str(d / "out.csv")], 0, "exact 1"),
}


def _capture_with(path: Path, **header) -> Path:
    """The shipped capture with some of its header's fields replaced."""
    blob = FREE_CAPTURE.read_bytes()
    start = blob.index(b"\n") + 1
    end = blob.index(b"\n", start)
    fields = json.loads(blob[start:end]) | header
    path.write_bytes(blob[:start] + json.dumps(fields).encode() + blob[end:])
    return path


def _batch_csv(path: Path, x_m: float, bom: bool = False) -> Path:
    """One pose (the drill's frame, x_m forward of the neck) for ``hubo ik --batch``."""
    header = ",".join(f"T{i}{j}" for i in range(4) for j in range(4))
    row = f"1,0,0,{x_m!r},0,1,0,-0.2,0,0,1,0,0,0,0,1"
    path.write_text(header + "\n" + row + "\n", encoding="utf-8-sig" if bom else "utf-8")
    return path


def _bytes(path: Path) -> Path:
    path.write_bytes(b"\xff\xfe\x00garbage\x81")
    return path


def _owned(path: Path) -> Path:
    path.write_text("the user's own file\n")
    return path


def _copy_capture(d: Path) -> Path:
    capture = d / "s.fastrak"
    shutil.copy(FREE_CAPTURE, capture)
    _owned(d / "s.csv")
    return capture


# a run's progress line (hubo_cli.cli.live_view: "teleop operate: samples 4 | e-stop ready ...")
PROGRESS_LINE = re.compile(r"^teleop \w+: samples \d+ \| ")


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_gives_one_line_and_its_exit_code(case, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _owned(tmp_path / "f.txt")
    (tmp_path / "mine").mkdir()
    _owned(tmp_path / "mine" / "log.csv")
    build, code, text = CASES[case]
    argv = build(tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    result = CliRunner().invoke(main, argv)
    output = result.output
    assert "Traceback" not in output and "internal error" not in output, output
    assert not isinstance(result.exception, Exception) or isinstance(
        result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == code, output
    assert text in output, output
    # no input echoed whole (round 12: 200 kB); the progress lines of a run that goes on (one
    # every 2 s of wall clock, about 300 characters each) are left out: a loaded machine prints
    # more of them (teleop-mostly-rejected: 1524 characters with two at load 5, 2216 with four
    # at load 8, the rest 880)
    echoed = "\n".join(line for line in output.splitlines() if not PROGRESS_LINE.match(line))
    assert len(echoed) < 2000, output[:2000]
    for path, data in before.items():  # nothing the user had was changed
        assert path.read_bytes() == data, path
    # a refused run leaves no run folder behind
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())
    for name in ("far-run", "wall-run"):
        assert not (tmp_path / name).exists()


def test_run_folder_reused_only_by_the_same_command(tmp_path):
    first = make_run_dir("teleop", tmp_path / "run")
    (first / "log.csv").write_text("from the first run\n")
    assert make_run_dir("teleop", tmp_path / "run") == first  # --out given again
    with pytest.raises(InputError, match="already holds a 'hubo teleop' run"):
        make_run_dir("sim", tmp_path / "run")
    assert (first / MARKER).read_text().strip() == "teleop"


def test_a_reused_run_folder_loses_the_previous_runs_files_and_keeps_the_users(tmp_path):
    """Review 28: an e-stopped cut run into the folder of a completed one kept its path.png
    beside the new summary. The previous run's listed files (and its summary) go once the
    next run holds the folder; a file it did not list, or a path that leads out, stays."""
    from hubo_cli.runs import release_run_dir

    first = make_run_dir("task-cut", tmp_path / "run")
    outside = tmp_path / "outside.png"
    for path in (first / "path.png", first / "notes.txt", outside):
        path.write_text("kept?")
    (first / "summary.json").write_text(json.dumps(
        {"files": ["path.png", "summary.json", "../outside.png", MARKER, 7]}))
    release_run_dir(first)
    again = make_run_dir("task-cut", tmp_path / "run")
    assert sorted(p.name for p in again.iterdir()) == [MARKER, "notes.txt"]
    assert outside.exists() and (again / MARKER).read_text().strip() == "task-cut"
    (again / "path.png").write_text("the new run's")
    assert make_run_dir("task-cut", again) == again  # the same run's second hold clears nothing
    assert (again / "path.png").exists()
    release_run_dir(again)
    release_run_dir(again)


def _commands(argv=(), command=main, ctx=None):
    """Every command's words down the ``hubo`` tree (the group's first), with its command."""
    ctx = ctx or click.Context(main, info_name="hubo")
    yield list(argv), command
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            yield from _commands([*argv, name], sub, click.Context(sub, info_name=name))


def test_every_help_lists_the_exit_codes_and_teleop_the_keys():
    runner = CliRunner()
    seen = 0
    for argv, _ in _commands():
        result = runner.invoke(main, [*argv, "--help"])
        assert result.exit_code == 0, argv
        assert "Exit codes:" in result.output and "4 refused for safety" in result.output, argv
        seen += 1
    assert seen >= len(COMMANDS) + 6  # the task and fastrak subcommands too
    keys = runner.invoke(main, ["teleop", "--help"]).output
    for key in ("space", "release", "re-centre", "q, Esc"):
        assert key in keys


def test_a_usage_error_of_a_json_command_is_one_json_document():
    """With --json, click's usage errors (an unknown option, a value missing or of the wrong
    type, a bad choice) print one JSON document on stdout with exit code 2, as every other way
    a command ends; --help still prints its text (exit 0)."""
    runner = CliRunner()
    with_json = [argv for argv, command in _commands()
                 if any(p.name == "as_json" for p in command.params)]
    assert len(with_json) >= 10
    for argv in with_json:
        result = runner.invoke(main, [*argv, "--json", "--bogus"], prog_name="hubo")
        assert result.exit_code == 2, argv
        document = json.loads(result.stdout)
        assert document["exit_code"] == 2 and "--bogus" in document["error"], argv
        assert document["hint"] == f"see 'hubo {' '.join(argv)} -h'", argv
        assert document["error"].splitlines()[0] in result.stderr, argv  # said there too
    for args, said in ((["walk", "--json", "--to", "1"], "'--to' requires 3 arguments"),
                       (["teleop", "--json", "--scale", "x"], "'x' is not a valid float"),
                       (["walk", "--to", "1", "0", "0", "--gait", "bogus", "--json"], "bogus"),
                       (["walk", "--json"], "Missing option '--to'")):
        result = runner.invoke(main, args)
        assert result.exit_code == 2 and said in json.loads(result.stdout)["error"], args
    for args in (["walk", "--bogus", "--", "--json"], ["walk", "--bogus"]):  # not asked for
        result = runner.invoke(main, args)
        assert result.exit_code == 2 and result.stdout == "", args
    result = runner.invoke(main, ["walk", "--json", "--help"], prog_name="hubo")
    assert result.exit_code == 0 and result.stdout.startswith("Usage: hubo walk")


@pytest.mark.slow
def test_piped_teleop_prints_progress_lines_and_counts_stops(tmp_path):
    log = _short_log(tmp_path / "s.csv")
    result = CliRunner().invoke(main, ["teleop", "--replay", str(log), "--driver", "ideal",
                                       "--speed", "1", "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    # progress while it runs (every 2 s; the replay takes a few seconds in real time)
    assert re.search(r"teleop (approach|operate|settle): samples \d+ \|", result.stderr)
    assert "e-stop ready" in result.stderr
    assert "e-stops 0 (released 0)" in result.stdout


@pytest.mark.skipif(sys.platform != "linux", reason="signals as on Linux")
def test_sigterm_ends_like_ctrl_c_with_a_summary(tmp_path):
    log = _short_log(tmp_path / "s.csv", rows=2000)
    run = tmp_path / "run"
    hubo = Path(sys.executable).with_name("hubo")
    process = subprocess.Popen([str(hubo), "teleop", "--replay", str(log), "--driver", "ideal",
                                "--speed", "1", "--out", str(run)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (run / "log.rows").exists() and time.monotonic() < deadline:  # running
            time.sleep(0.1)
        time.sleep(1.0)
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, err
    assert "Traceback" not in err
    assert (run / "summary.json").exists()
    assert (run / "log.csv").exists() and not (run / "log.rows").exists()  # the log finished
    assert "interrupted" in out


@pytest.mark.physical
def test_collision_layer_keeps_the_commanded_posture_apart(model, tmp_path):
    """The operator's goal goes deep into the body: the command stays clear (logged)."""
    from hubo_cli.control.log import load_log
    from hubo_cli.control.loop import ControlLoop
    from hubo_cli.control.pipeline import build_pipeline
    from hubo_cli.drivers.registry import make_driver
    from hubo_cli.posture import home_posture

    robot = make_driver("ideal", model)
    robot.start(home_posture(model))
    q0 = robot.read().q_rad.copy()
    inward = q0.copy()
    inward[1] = 0.3        # right shoulder rolled in: forearm through the pelvis
    inward[7] = -0.3       # and the left one too
    modules = build_pipeline(model, ["otg", "collision", "limiter"])

    def target(t_s, state):
        return (inward if t_s < 2.0 else q0), {}

    ControlLoop(robot, modules, target, log_path=tmp_path).run(duration_s=4.0)
    columns = load_log(tmp_path).columns  # (the final smooth stop's rows have no module data)
    # measured on both code paths (AVX-512 / portable): the goal 45.6 mm inside (4.6x), the
    # command 10.6 mm clear
    assert np.nanmin(columns["collision_ahead_m"]) < -0.01        # the goal went inside
    assert np.nanmin(columns["collision_distance_m"]) > -0.001    # the command never did



def test_setting_a_parameter_the_task_never_uses_is_refused(tmp_path):
    from hubo_cli.errors import ConfigError
    from hubo_cli.tasks.spec import load_task

    path = tmp_path / "t.toml"
    path.write_text(SLOT.read_text().replace("[parameters]\n", "[parameters]\nlength_mm = 300.0\n"))
    assert load_task(path).parameters["length_mm"] == 300.0  # declaring it is harmless
    with pytest.raises(ConfigError, match="never uses"):
        load_task(path, {"length_mm": 50.0})
    assert load_task(path, {"speed_mm_s": 20.0}).steps[2].speed_m_s == pytest.approx(0.02)


@pytest.mark.physical
def test_the_way_back_from_a_collision_hold_does_not_cross_the_body(model):
    """Two clear postures whose straight joint-space way between crosses the torso (the left
    wrist through it): held at the first, the input then at the second; the recovery must hold
    short of the body rather than pass through it (without that check it reaches -9 mm)."""
    from hubo_cli.control.collision import CollisionDetector
    from hubo_cli.control.module import Cycle
    from hubo_cli.posture import home_posture
    from hubo_cli.state import RobotState

    dt = model.control_period_s
    a, b = home_posture(model), home_posture(model)
    a[:12] = [-1.57, -0.31, -0.64, -2.4, -1.9, 0.7, 0.42, 0.19, 0.78, -2.17, 0.53, 0.3]
    b[:12] = [-1.98, -0.82, 0.91, -0.6, 0.68, 0.9, 1.02, 1.82, -0.34, -2.41, -1.69, -0.65]
    detector = CollisionDetector(model, dt)
    way = [detector.checker.check(a + s * (b - a)).distance_m for s in np.linspace(0, 1, 101)]
    assert min(way[0], way[-1]) > 0.03 and min(way) < -0.01  # the premise
    inside = a + np.linspace(0, 1, 101)[int(np.argmin(way))] * (b - a)
    state = RobotState(0.0, a, np.zeros(len(a)))
    detector.reset(a, state, Store())
    distances = []
    for k in range(int(6.0 / dt)):
        q_in = a if k < 20 else (inside if k < 60 else b)  # into the body, then beyond it
        detector.update(q_in, state, Cycle(k * dt, dt))
        distances.append(detector.last_clearance.distance_m)
    assert detector.events  # it held
    assert min(distances) > 0.0  # 10.2 mm clear on both code paths (AVX-512 / portable)


def test_a_push_after_the_walk_ends_is_named(tmp_path, monkeypatch):
    """``--push-at 3600`` on a walk of a few seconds never pushed, exit 0, no word (round 15):
    the walk's result names what never came, and the command warns."""
    from hubo_cli.experiments import walk as walk_module

    def walked(model, goal, disturbances, out, **_):
        return walk_module.WalkResult(
            fell=False, stopped_s=None, stood=True, shifts=0, touchdowns_early=0,
            liftoff_waits=0, landing_waits=0, reaims=0, final_error_mm=1.0,
            final_error_deg=0.1, estimated_final_error_mm=1.0, estimated_final_error_deg=0.1,
            steps=4, average_speed_m_s=0.1, zmp_inside_fraction=1.0, walking_s=4.2,
            ended="done", estop_events=0, footsteps=[], gait="normal", run_dir=Path(out),
            unplayed=tuple(d for d in disturbances if d.at_s > 4.2))

    monkeypatch.setattr(walk_module, "walk", walked)
    result = CliRunner().invoke(main, ["walk", "--to", "0.3", "0", "0", "--push", "50",
                                       "--push-at", "3600", "--out", str(tmp_path / "w")])
    assert result.exit_code == 0, result.output
    assert "the walk ended before 3600 s: its push there never came" in result.output
    result = CliRunner().invoke(main, ["walk", "--to", "0.3", "0", "0", "--push", "50",
                                       "--push-at", "2", "--out", str(tmp_path / "v")])
    assert "never came" not in result.output


def test_a_walk_on_the_ideal_driver_is_refused_in_one_line():
    """The ideal driver has no floor (it stands the robot on its lower sole): every walk on
    it stopped on the capture point at 1.08 s, exit 1 (review 20). Refused before anything
    runs, exit 2, naming the drivers that walk."""
    result = CliRunner().invoke(main, ["walk", "--to", "0.001", "0", "0", "--driver", "ideal"])
    assert result.exit_code == 2, result.output
    assert "the ideal driver has none" in result.output and "--driver sim" in result.output
    assert "Traceback" not in result.output
