"""Input loss on a live tracker: the hands hold; when the tracker is back they keep holding until
the operator re-centres (clutch), so the goal never jumps to where the operator's hand went
meanwhile; a tracker that does not come back ends the run with exit 3 and a plain message.

Real parts throughout: the emulated FASTRAK on a pseudo-terminal, the live reader (pyserial),
the teleoperation target and the ideal driver. Waits are bounded by generous deadlines.
"""

import json
import threading
import time

import numpy as np
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.drivers.registry import make_driver
from hubo_cli.estimation.build import build_estimator
from hubo_cli.fastrak.emulator import make_emulator
from hubo_cli.fastrak.opener import open_source
from hubo_cli.input.fastrak import FastrakInput
from hubo_cli.posture import home_posture
from hubo_cli.teleop.mapping import HandMapper
from hubo_cli.teleop.session import TeleopSettings, approach_paths, prepare
from hubo_cli.teleop.target import TeleopTarget

FAST = {"settle_s": 0.05, "command_gap_s": 0.0}
DEADLINE_S = 20.0


class Operator:
    """Runs the target period by period against the ideal driver, in real time."""

    def __init__(self, model, target, driver) -> None:
        self.target, self.driver = target, driver
        self.state = driver.read()
        self.estimator = build_estimator(model, period_s=driver.period_s)  # as the loop does
        target.store = self.estimator.reset(self.state)
        self.t_s = 0.0
        self.dt_s = model.control_period_s
        self.flags: list[set[str]] = []
        self.goals: list[np.ndarray] = []

    def step(self) -> None:
        q, info = self.target(self.t_s, self.state)
        self.driver.send(q)
        self.state = self.driver.step()
        self.estimator.update(self.state)
        self.flags.append(set(info.get("flags", ())))
        goal = self.target.goals.get("right-arm")
        self.goals.append(goal[:3, 3].copy())
        self.t_s += self.dt_s
        time.sleep(self.dt_s)

    def run_until(self, condition) -> bool:
        deadline = time.monotonic() + DEADLINE_S
        while not condition() and time.monotonic() < deadline:
            self.step()
        return condition()


def test_hands_hold_after_input_loss_until_the_operator_recentres(model):
    emu = make_emulator(stations=1).start()
    try:
        settings = TeleopSettings(port=emu.port_name, station_arm={1: "right-arm"})
        _, body, mapping, scene = prepare(settings)
        with open_source(port=emu.port_name, silence_timeout_s=0.3, **FAST) as source:
            driver = make_driver("ideal", model)
            with driver:
                driver.start(home_posture(model))
                target = TeleopTarget(model, FastrakInput(source, {1: "right-arm"}),
                                      HandMapper(mapping), body,
                                      approach_paths(body, ["right-arm"], scene),
                                      home_posture(model), live=True)
                op = Operator(model, target, driver)
                hand = target.hands["right-arm"]
                assert op.run_until(lambda: target.samples_used > 30)  # operating, calibrated
                emu.device.continuous = False  # the unit goes silent (e.g. a loose cable)
                assert op.run_until(lambda: hand.stale)
                assert op.run_until(lambda: hand.needs_clutch)  # reconnected, input is back
                held = op.goals[-1].copy()
                n_back = len(op.goals)
                time.sleep(0.5)  # the operator's hand goes on moving meanwhile
                for _ in range(60):
                    op.step()
                assert source.stats.reconnects == 1
                assert all(np.array_equal(g, held) for g in op.goals[n_back:])  # holds
                assert all("holding" in f for f in op.flags[-50:])
                target.keys.clutch = True  # the operator re-centres
                used = target.samples_used
                assert op.run_until(lambda: target.samples_used > used + 20)
                assert not hand.needs_clutch
                after = np.array(op.goals[n_back + 60:])
                steps = np.linalg.norm(np.diff(np.vstack([held, after]), axis=0), axis=1)
                assert steps.max() < 0.01  # no jump: motion resumes from the held goal
    finally:
        emu.close()


def _close_once_running(emu, run_dir) -> threading.Thread:
    """Close the emulator (for good) once the run's loop stores its log, the tracker has
    streamed 1 s of records and the operator has taken over (the approach lasts 2.1 s; the
    poses queued before the take-over are not followed): the tracker goes away while the
    hands follow it, however slow the start."""

    def close() -> None:
        deadline = time.monotonic() + 2 * DEADLINE_S
        while time.monotonic() < deadline and not (
                emu.records_sent >= 120 and (run_dir / "log.rows").exists()):
            time.sleep(0.05)
        time.sleep(2.5)
        emu.close()

    watcher = threading.Thread(target=close, daemon=True)
    watcher.start()
    return watcher


def test_lost_tracker_ends_with_exit_3_and_a_plain_message(tmp_path):
    emu = make_emulator(stations=2).start()
    run_dir = tmp_path / "run"
    watcher = _close_once_running(emu, run_dir)
    # a 1 s reconnect timeout (the default, 10 s, only makes the same end later)
    result = CliRunner().invoke(main, ["teleop", "--port", emu.port_name, "--driver", "ideal",
                                       "--duration", "60", "--reconnect-timeout", "1",
                                       "--out", str(run_dir)])
    watcher.join()
    assert result.exit_code == 3, result.output
    assert "DeviceError" not in result.output and "Traceback" not in result.output
    assert "error: FASTRAK on" in result.output and "reconnecting failed for 1 s" in result.output
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["input_kind"] == "port" and summary["samples_used"] > 0


def test_a_tracker_silent_for_a_while_is_reported_at_the_end(tmp_path):
    """The tracker sends nothing for 1.5 s mid-run (under --reconnect-timeout): the hands hold
    and the run goes on to exit 0, as designed, and its end says for how long and where the
    input was flagged stale (main: exit 0 and no word of it; the summary's statuses only)."""
    emu = make_emulator(stations=2).start()
    run_dir = tmp_path / "run"
    silent: dict = {}
    next_record = emu.device.next_record

    def record(t_s):
        if "from" in silent and silent["from"] <= time.monotonic() < silent["from"] + 1.5:
            return b""
        return next_record(t_s)

    emu.device.next_record = record

    def go_silent() -> None:
        deadline = time.monotonic() + 2 * DEADLINE_S
        while time.monotonic() < deadline and not (
                emu.records_sent >= 120 and (run_dir / "log.rows").exists()):
            time.sleep(0.05)
        silent["from"] = time.monotonic() + 3.0  # once the hands follow (calibrated)

    watcher = threading.Thread(target=go_silent, daemon=True)
    watcher.start()
    try:
        result = CliRunner().invoke(main, ["teleop", "--port", emu.port_name, "--driver",
                                           "ideal", "--duration", "7", "--out", str(run_dir)])
    finally:
        watcher.join()
        emu.close()
    assert result.exit_code == 0, result.output
    stale = json.loads((run_dir / "summary.json").read_text())["stale_input"]
    # measured: 0.455 s flagged stale for the 1.5 s silence, from 2.76 s (then the hands hold
    # for a re-centre: status "holding"); the bounds are the flag's, not the silence's
    assert stale is not None and 0.1 < stale["longest_s"] <= stale["total_s"] < 3.0, stale
    assert "input stale for" in result.output and emu.port_name in result.output
