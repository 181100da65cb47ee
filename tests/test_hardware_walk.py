"""Walking and standing on the hardware driver (issue 35 part 3): the start posture a run
through hubo-ach checks, the simulated daemon's push, the commands' refusals, and (needs libach,
skipped with the reason without it) a short walk through the simulated daemon measured
against the daemon's truth, then the daemon killed mid-walk.

The 1 m walk and the 120 N push with ``--step`` take real time (about 15 s each plus the
daemon's start and need real-time priority on a loaded machine): their figures are in
docs/history/hardware.md, the walk's measured with ``tools/daemon_walk.py --run``.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from realtime_support import needs_libach
from tool_support import load_tool

from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log
from hubo_cli.drivers.hubo_ach_faults import PUSH_FOR_S, parse_push
from hubo_cli.errors import InputError, SafetyError
from hubo_cli.model import load_model
from hubo_cli.posture import START_TOLERANCE_RAD, check_stands_in, home_posture
from tests.test_hardware_cli import _wait_published, channel_names  # noqa: F401

MODEL = load_model()


def test_a_robot_off_the_start_posture_is_refused_naming_the_joint():
    rng = np.random.default_rng(35)
    home = home_posture(MODEL)
    for _ in range(50):
        q = home + rng.uniform(-0.9, 0.9) * START_TOLERANCE_RAD
        check_stands_in(MODEL, q, home, "walking")  # within: nothing raised
        i = int(rng.integers(len(q)))
        bad = q.copy()
        bad[i] = home[i] + rng.choice([-1, 1]) * rng.uniform(1.01, 40) * START_TOLERANCE_RAD
        with pytest.raises(SafetyError, match=MODEL.joint_names[i]) as refused:
            check_stands_in(MODEL, bad, home, "walking")
        assert "--posture walking" in refused.value.hint
    bad = home.copy()
    bad[3] = math.nan  # an unreadable encoder is not a posture
    with pytest.raises(SafetyError, match=MODEL.joint_names[3]):
        check_stands_in(MODEL, bad, home, "standing")


@pytest.mark.parametrize("spec", ["", "120", "120,at=", "120,at=-1", "nan,at=1", "-5,at=1",
                                  "1e9,at=1", "120,at=1,dir=up", "120,at=1,for=0",
                                  "120,at=1,for=inf", "120,at=1,at=2", "120,when=1",
                                  "120,at=1,dir", "\x00,at=1", "120;at=1"])
def test_a_bad_push_is_refused_clearly(spec):
    with pytest.raises(InputError, match="--push") as refused:
        parse_push(spec)
    assert "\n" not in refused.value.message and "--push" in refused.value.hint


def test_a_push_is_read():
    push = parse_push(" 120 , at=2.5, dir=left ")
    assert (push.force_n, push.at_s, push.direction, push.for_s) == (120, 2.5, "left",
                                                                     PUSH_FOR_S)
    assert parse_push(push.describe()) == push


@pytest.mark.parametrize("args, code, words", [
    (["sim", "--driver", "hardware", "--arm", "--push", "30"], 2, "--push needs the simulator"),
    (["sim", "--push-direction", "left", "--sink", "file"], 2, "only apply to the hardware"),
    (["walk", "--to", "1", "0", "0", "--driver", "hardware"], 4, "not armed"),
    (["sim", "--driver", "hardware", "--step"], 4, "not armed"),
    (["hardware", "sim-daemon", "--push", "120"], 2, "at=S"),
    (["hardware", "sim-daemon", "--posture", "sitting"], 2, "sitting"),
])
def test_the_commands_refuse_clearly_on_the_hardware_driver(tmp_path, args, code, words):
    result = CliRunner().invoke(main, [*args, *(["--out", str(tmp_path / "run")]
                                                if args[0] != "hardware" else [])])
    assert result.exit_code == code, result.output
    assert words in result.output and "Traceback" not in result.output


def _daemon(ref: str, state: str, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "hubo_cli.cli.main", "hardware", "sim-daemon", "--ach-ref", ref,
         "--ach-state", state, "--posture", "walking", *extra],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _walk(ref: str, state: str, out: Path, goal: str):
    return CliRunner().invoke(main, ["walk", "--to", *goal.split(), "--driver", "hardware",
                                     "--arm", "--ach-ref", ref, "--ach-state", state, "--out",
                                     str(out), "--json"])


@needs_libach
@pytest.mark.physical
def test_a_short_walk_through_the_simulated_daemon_arrives_and_a_killed_daemon_ends_the_next(
        tmp_path, channel_names):  # noqa: F811 (the fixture imported above)
    """One ``sim-daemon --posture walking --truth-log``: a 0.3 m walk with ``--driver hardware
    --arm`` arrives where the daemon's truth says (tools/daemon_walk.py), no fall; the next
    walk, its daemon SIGKILLed once references flow, ends ``device``, exit 3, one line, the
    references braked to rest. (The truth log is read as the killed daemon left it: whole
    rows, line-buffered, under the temporary name of :func:`hubo_cli.outputs.replacing`.)

    Measured on this 2-core machine (load 6-9, no real-time priority, five runs): true final
    error 0.4-1.3 mm, true tilt 8.4-8.9 deg (the gait's lean: the sim driver's 1 m walk 8.5);
    bounded at 15 mm (the issue's) and the fall's tilt. The kill ended the run 1.4-1.5 s later.
    One run of the five lost the daemon's state in the first walk (exit 3) at load 8.6, cause
    not found. The test takes 33-41 s (two walks in real time, the daemon's start)."""
    import threading

    from hubo_cli.drivers.ach import load_libach

    daemon_walk = load_tool("daemon_walk")
    lib = load_libach()
    ref, state = channel_names
    daemon = _daemon(ref, state, "--truth-log", str(tmp_path / "truth.csv"))
    killed_s = []

    def kill_once_walking() -> None:
        _wait_published(lib, ref, timeout_s=120)  # references flow: the walk runs
        time.sleep(2.0)
        daemon.send_signal(signal.SIGKILL)
        killed_s.append(time.monotonic())

    try:
        _wait_published(lib, state)
        walked = _walk(ref, state, tmp_path / "walk", "0.3 0 0")
        killer = threading.Thread(target=kill_once_walking, daemon=True)
        killer.start()
        killed = _walk(ref, state, tmp_path / "killed", "1 0 0")
        exited_s = time.monotonic()
        killer.join(timeout=5)
    finally:
        if daemon.poll() is None:
            daemon.kill()
        daemon.wait()
    assert walked.exit_code == 0, walked.output
    summary = json.loads(walked.stdout)
    assert not summary["fell"] and summary["ended"] == "done"
    (truth_log,) = tmp_path.glob(".truth.*.part.csv")
    truth = np.loadtxt(truth_log, delimiter=",", skiprows=1, ndmin=2)
    found = daemon_walk.walk_truth(load_log(tmp_path / "walk"), truth, (0.3, 0.0, 0.0))
    print(f"0.3 m walk: {found}; estimated {summary['estimated_final_error_mm']:.1f} mm")
    assert found["final_error_mm"] <= 15.0 and not found["fell"]

    assert killed.exit_code == 3, killed.output
    lines = [line for line in killed.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "robot state lost" in lines[0] and "braked" in lines[0]
    assert "Traceback" not in killed.output
    summary = json.loads((tmp_path / "killed" / "summary.json").read_text())
    assert summary["ended"] == "device" and summary["stale_state_periods"] > 0
    cmd = load_log(tmp_path / "killed").joints("cmd")
    assert np.all(np.abs(cmd[-1] - cmd[-2]) < 1e-6)  # at rest at the end: held
    print(f"killed mid-walk: exit 3 {exited_s - killed_s[0]:.2f} s after the kill")
    # bounded generously for a loaded machine (the driver's own 0.9 s of stale state and
    # grace are tested in test_hardware_cli)
    assert exited_s - killed_s[0] < 30.0
