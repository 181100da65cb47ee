"""The hardware driver from the command line: missing libach, option checks, the fake daemon,
and a task through real ach channels (the last two need libach and are skipped without it)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from realtime_support import needs_libach
from task_files import DRILL_STANCE, raise_and_hold

from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log
from hubo_cli.drivers.hardware import STALE_AFTER_S, STALE_GRACE_S
from hubo_cli.model import load_model

SHM = Path("/dev/shm")
MODEL = load_model()

# raise the drill, hold it: a task of about 4 s
SHORT_TASK = raise_and_hold("short-move", 0.2, stance=DRILL_STANCE)


def _run(args: list[str], env: dict | None = None):
    return CliRunner().invoke(main, args, env=env)


def test_without_libach_the_hardware_driver_says_what_to_install(tmp_path):
    task = tmp_path / "short.toml"
    task.write_text(SHORT_TASK)
    result = _run(["task", "run", str(task), "--driver", "hardware", "--arm",
                   "--out", str(tmp_path / "run")],
                  env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
    assert result.exit_code == 3, result.output
    assert "libach is not available" in result.output
    assert "github.com/golems/ach" in result.output and "HUBO_LIBACH" in result.output
    assert "without a robot use --dry-run" in result.output
    assert "Traceback" not in result.output


def test_a_json_command_ending_in_a_device_error_prints_one_json_document(tmp_path):
    """--json: the error that ends the command before any summary is one JSON document on
    stdout (its line and hint still on stderr), with the documented exit code. (``hubo
    teleop --replay`` with --json does the same, measured by hand: its imports cost about
    20 s in a fresh worker.)"""
    task = tmp_path / "short.toml"
    task.write_text(SHORT_TASK)
    result = _run(["task", "run", str(task), "--driver", "hardware", "--arm", "--json",
                   "--out", str(tmp_path / "run")],
                  env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
    assert result.exit_code == 3, result.output
    document = json.loads(result.stdout)
    assert document["exit_code"] == 3 and "libach is not available" in document["error"]
    assert "--dry-run" in document["hint"] and "libach is not available" in result.stderr


def test_a_task_run_ending_in_a_device_failure_prints_its_summary_as_json(capsys):
    """A run whose loop ended in a device failure (summary.json written) prints its summary
    with the failure under --json, then exits with the failure's code (main printed nothing)."""
    import click

    from hubo_cli.cli.task import _finish
    from hubo_cli.errors import DeviceError

    class Loop:
        ended = "device"

        def failure(self, run_dir):
            return DeviceError("the robot's state stopped at 1.10 s")

    done = type("Done", (), {"loop": Loop(), "run_dir": Path("runs/x"),
                             "summary": {"ended": "device", "completed": False}})()
    with click.Context(main) as ctx, pytest.raises(DeviceError):
        _finish(ctx, done, True, lambda: None)
    document = json.loads(capsys.readouterr().out)
    assert document["ended"] == "device" and document["exit_code"] == 3
    assert document["failure"] == "the robot's state stopped at 1.10 s"


@pytest.mark.parametrize("daemon", ["fake-daemon", "sim-daemon"])
def test_without_libach_the_daemons_say_so_and_offer_no_dry_run(tmp_path, daemon):
    """The stand-in daemons have no --dry-run: their hint does not offer one."""
    result = _run(["hardware", daemon, "--duration", "0.1"],
                  env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
    assert result.exit_code == 3 and "libach is not available" in result.output
    assert "HUBO_LIBACH" in result.output and "--dry-run" not in result.output


@pytest.mark.parametrize("args, message", [
    (["--driver", "sim", "--ach-ref", "x"], "only apply to the hardware driver"),
    (["--driver", "ideal", "--dry-run"], "only apply to the hardware driver"),
    (["--driver", "sim", "--ref-mode", "direct"], "only apply to the hardware driver"),
    (["--driver", "sim", "--arm"], "--arm only apply to the hardware driver"),  # main: ran
    (["--driver", "hardware", "--dry-run", "--sink", "ach"], "contradicts"),
    (["--driver", "hardware", "--dry-run", "--ach-state", "s"], "no ach channel"),
])
def test_contradicting_hardware_options_are_refused(tmp_path, args, message):
    task = tmp_path / "short.toml"
    task.write_text(SHORT_TASK)
    result = _run(["task", "run", str(task), *args, "--out", str(tmp_path / "run")])
    assert result.exit_code == 2, result.output
    assert message in result.output


def test_the_dry_run_writes_462_byte_frames_into_the_run_folder(tmp_path):
    task = tmp_path / "short.toml"
    task.write_text(SHORT_TASK)
    run = tmp_path / "run"
    result = _run(["task", "run", str(task), "--driver", "hardware", "--dry-run",
                   "--ref-mode", "filtered", "--out", str(run), "--json"],
                  env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
    assert result.exit_code == 0, result.output
    frames = (run / "hubo-ref.bin").stat().st_size
    log = load_log(run)
    assert frames % 462 == 0 and frames // 462 >= len(log) - 1
    from hubo_cli.drivers.hardware import read_ref_frames

    assert all(np.all(f.mode == 0) for f in read_ref_frames(run / "hubo-ref.bin")[-3:])
    summary = json.loads((run / "summary.json").read_text())
    assert summary["hw_ref_mode"] == "filtered" and summary["hw_trip"] is None
    # the echo's motors are ideal: the filter's lag is expected, not a servo error
    assert summary["hw_max_servo_error_rad"] < 1e-9
    assert summary["hw_round_trip_ms"]["median"] is not None
    assert summary["hw_state_age_ms"]["median"] is None  # a simulated clock: no age
    # the driver's own numbers reach the log: one frame put per period
    seq = log["hw_ref_seq"]
    assert np.all(np.diff(seq[np.isfinite(seq)]) >= 0) and np.nanmax(seq) >= len(log) - 50


def test_a_live_session_on_the_hardware_driver_runs_in_real_time(tmp_path):
    """A live tracker on the hardware driver (dry run: frames into the run folder) for 4 s of
    wall time writes 4 s of 200 Hz frames, within 2 %, never faster than real time (measured:
    one period over)."""
    from hubo_cli.fastrak.emulator import make_emulator

    emu = make_emulator(stations=1).start()
    run = tmp_path / "run"
    try:
        started = time.perf_counter()
        result = _run(["teleop", "--port", emu.port_name, "--driver", "hardware", "--dry-run",
                       "--map", "1=right-arm", "--duration", "4", "--out", str(run),
                       "--json"], env={"HUBO_LIBACH": str(tmp_path / "missing-libach.so")})
        wall_s = time.perf_counter() - started
    finally:
        emu.close()
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["speed"] == 1.0
    frames = (run / "hubo-ref.bin").stat().st_size // 462
    loop_s = frames * MODEL.control_period_s
    assert abs(loop_s - summary["smooth_stop_s"] - 4.0) <= 0.08  # the duration, then the brake
    assert loop_s <= wall_s * 1.02  # never ahead of the wall clock
    refused = _run(["teleop", "--port", "/dev/null", "--driver", "hardware", "--dry-run",
                    "--speed", "4", "--out", str(tmp_path / "r2")])
    assert refused.exit_code == 2 and "real time" in refused.output


def _wait_for(path: Path, timeout_s: float = 20.0) -> None:
    end = time.monotonic() + timeout_s
    while not path.exists():
        assert time.monotonic() < end, f"{path} did not appear"
        time.sleep(0.05)


@needs_libach
def test_a_task_closes_the_loop_through_the_fake_daemon(tmp_path):
    tag = f"hubotest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    ref, state = f"{tag}-ref", f"{tag}-state"
    daemon = subprocess.Popen(
        [sys.executable, "-m", "hubo_cli.cli.main", "hardware", "fake-daemon", "--ach-ref", ref,
         "--ach-state", state, "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        _wait_for(SHM / f"achshm-{state}")
        task = tmp_path / "short.toml"
        task.write_text(SHORT_TASK)
        run = tmp_path / "run"
        result = _run(["task", "run", str(task), "--driver", "hardware", "--arm", "--ach-ref",
                       ref, "--ach-state", state, "--echo-sensors", "--out", str(run),
                       "--json"])  # (the fake daemon's sensors read 0: declared made up)
    finally:
        daemon.send_signal(signal.SIGTERM)
        out, err = daemon.communicate(timeout=20)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["completed"] and summary["driver"] == "hardware"
    stats = json.loads(out)
    assert daemon.returncode == 0, err
    assert stats["error"] is None
    assert stats["frame_sizes"] == {"462": stats["ref_frames"]}  # every frame, exactly 462 B
    log = load_log(run)
    assert stats["ref_frames"] >= len(log)
    # the joints read back from hubo-state follow the commands within the reference filter's
    # lag: at most (L - 1) of the largest per-period step, plus 3 periods between processes
    cmd, q = log.joints("cmd"), log.joints("q")
    step = np.max(np.abs(np.diff(cmd, axis=0)), axis=0)
    moved = step > 1e-6
    assert moved.sum() >= 6
    L = MODEL.hubo_ach["ref_filter_length"]
    lag = np.max(np.abs(q - cmd), axis=0)
    assert np.all(lag[moved] <= (L - 1 + 3) * step[moved]), lag / step
    assert np.all(lag[~moved] < 1e-9)
    assert not (SHM / f"achshm-{ref}").exists() and not (SHM / f"achshm-{state}").exists()


# a slow move (30 mm in 8 s) long enough to kill the daemon in the middle of it
SLOW_TASK = SHORT_TASK + """
[[steps]]
kind = "move"
name = "approach slowly"
depth_mm = -20.0
duration_s = 8.0
"""


def _daemon(ref: str, state: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "hubo_cli.cli.main", "hardware", "fake-daemon", "--ach-ref", ref,
         "--ach-state", state], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture
def channel_names():
    """Unique ``hubo-ref`` and ``hubo-state`` names, unlinked afterwards whatever happened."""
    tag = f"hubotest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    names = (f"{tag}-ref", f"{tag}-state")
    yield names
    from hubo_cli.drivers.ach import load_libach

    for name in names:
        load_libach().unlink(name)


def _wait_published(lib, name: str, timeout_s: float = 60.0) -> None:
    """Wait until a daemon publishes on channel ``name`` (it is running)."""
    from hubo_cli.drivers.hubo_ach_daemon import channel_published

    end = time.monotonic() + timeout_s
    while not channel_published(lib, name):
        assert time.monotonic() < end, f"nothing publishes {name}"


@needs_libach
@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_daemon_killed_mid_move_ends_the_run_braked_with_exit_3(tmp_path, how,
                                                                  channel_names):
    """hubo-daemon dies in the middle of a slow move: the run ends ``device``, exit 3, with
    one line; the references brake to rest within the joints' limits and hold (no jump); the
    summary counts the stale periods. After a SIGKILL the channels stay, the last reference on
    them is the hold, and the next daemon takes them over and removes them at its end.

    Measured on this 2-core machine at load 8: the driver ended the run 1.10-1.12 s after its
    last fresh state (the brake from the slow move is short); the wall-clock figures are
    printed (``-s``) and bounded generously below."""
    import re

    from hubo_cli.drivers.ach import load_libach
    from hubo_cli.drivers.hubo_ach import HuboRef, decode_ref

    lib = load_libach()
    ref, state = channel_names
    task = tmp_path / "slow.toml"
    task.write_text(SLOW_TASK)
    run, err_path = tmp_path / "run", tmp_path / "stderr.txt"
    daemon, client = _daemon(ref, state), None
    try:
        _wait_for(SHM / f"achshm-{state}")
        with err_path.open("w") as err_file:
            client = subprocess.Popen(
                [sys.executable, "-m", "hubo_cli.cli.main", "task", "run", str(task),
                 "--driver", "hardware", "--arm", "--ach-ref", ref, "--ach-state", state,
                 "--echo-sensors",
                 "--out", str(run)], stdout=subprocess.DEVNULL, stderr=err_file)
        end = time.monotonic() + 240
        while "short-move: run," not in err_path.read_text():  # the 8 s move has begun
            assert client.poll() is None and time.monotonic() < end, err_path.read_text()
            time.sleep(0.05)
        daemon.send_signal(how)
        killed_s = time.time()
        daemon.wait(timeout=20)
        client.wait(timeout=300)
        exited_s = time.time()
    finally:
        for process in (daemon, client):
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
    err = err_path.read_text()
    assert client.returncode == 3, err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "robot state lost" in lines[0] and "braked" in lines[0], err
    assert "Traceback" not in err and "internal error" not in err
    summary = json.loads((run / "summary.json").read_text())
    assert summary["ended"] == "device" and "robot state lost" in summary["error"]
    assert summary["completed"] is False
    # the driver's own clock: 0.1 s without state, 0.8 s of grace, the brake (short here);
    # measured 0.90-0.93 s (1.10-1.13 s with a 1 s grace), bounded at 1.5 s as the issue asks
    stale_s = float(re.search(r"for ([0-9.]+) s", summary["error"]).group(1))
    assert STALE_AFTER_S + STALE_GRACE_S - 0.01 <= stale_s <= 1.5
    # the periods run in that wall time: 179 and 88 measured at load 8 (a loaded machine's
    # loop runs late and re-anchors), 200 on time
    assert 20 <= summary["stale_state_periods"] <= 1.5 / MODEL.control_period_s
    # the wall clock of the whole machine, generous for its load
    loop_end_s = (run / "log.csv").stat().st_mtime - killed_s
    print(f"{how.name}: loop ended {loop_end_s:.2f} s, process exited "
          f"{exited_s - killed_s:.2f} s after the kill; driver: {stale_s:.2f} s stale")
    assert loop_end_s < 3.0
    assert exited_s - killed_s < 60.0

    log = load_log(run)
    onset = next(i for i, f in enumerate(log.flags) if "stale-state" in f)
    assert all("stale-state" in f for f in log.flags[onset:])
    cmd = log.joints("cmd")
    step = np.abs(np.diff(cmd, axis=0))
    assert np.all(step <= MODEL.velocity_rad_s * MODEL.control_period_s * 1.001)  # no jump
    braking = step[onset:]
    assert np.all(np.diff(braking, axis=0) <= MODEL.acceleration_rad_s2
                  * MODEL.control_period_s**2 * 1.001 + 1e-12)  # only slowing down
    assert np.all(braking[-1] < 1e-6)  # at rest at the end: held

    if how == signal.SIGKILL:  # the channels stay: the hold is on them, a new daemon takes over
        frame = HuboRef()
        with lib.open(ref) as channel:
            channel.get(frame)
        held = decode_ref(bytes(frame)).ref_rad[[MODEL.hubo_ach["index"][n]
                                                 for n in MODEL.joint_names]]
        assert np.allclose(held, cmd[-1], atol=1e-9)
        second = _daemon(ref, state)
        try:
            _wait_published(lib, state)
            second.send_signal(signal.SIGTERM)
            _, err2 = second.communicate(timeout=20)
        finally:
            if second.poll() is None:
                second.kill()
                second.wait()
        assert second.returncode == 0, err2
        assert f"replacing {ref}, {state} left over from a dead daemon" in err2
    assert not (SHM / f"achshm-{ref}").exists() and not (SHM / f"achshm-{state}").exists()
