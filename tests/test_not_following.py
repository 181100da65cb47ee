"""A robot that does not follow its commands is device trouble (round 16): a joint held at the
soft error limiter's tracking band too long (hubo_cli/control/limiter.py, NotFollowing), or
hubo-daemon's refWait kept set (hubo_cli/drivers/hardware.py, RefWaitError). On main neither
could end a run: the band keeps every command within 0.18 rad of the measured joint, so the
0.2 rad servo-error check never trips, and it is skipped while refWait is set."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from control_support import Recorder, assert_within_limits, ideal
from task_files import DRILL_STANCE, raise_and_hold

from hubo_cli.control.following import STILL_S
from hubo_cli.control.limiter import NOT_FOLLOWING_S, TRACKING_ERROR_LIMIT_RAD
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.drivers.hardware import REF_WAIT_MAX_S, HardwareDriver
from hubo_cli.errors import DeviceError

DT = 0.005
SPEED_RAD_S = 0.5


class Frozen(Recorder):
    """A robot whose joints never move from where they started (the state keeps coming);
    ``creep_rad``: they read that much either side of it, alternating every 0.1 s (a joint
    that moves, a little, without getting anywhere)."""

    def __init__(self, driver, creep_rad: float = 0.0) -> None:
        super().__init__(driver)
        self.q0 = driver.read().q_rad.copy()
        self.creep_rad = creep_rad

    def step(self):
        state = self.driver.step()
        side = 1.0 if int(state.time_s / 0.1) % 2 else -1.0
        return dataclasses.replace(state, q_rad=self.q0 + side * self.creep_rad,
                                   dq_rad_s=np.zeros_like(self.q0))


def _away(q0):
    def target(t_s, state):
        q = q0.copy()
        q[0] -= SPEED_RAD_S * t_s  # RSP, forward, for 4 s
        return q, {}
    return target


@pytest.mark.parametrize("creep_rad", [0.0, 0.002], ids=["still", "creeping"])
def test_a_frozen_robot_is_device_trouble_and_the_command_is_braked(model, creep_rad):
    """Still: the joint has not moved for STILL_S while its command went STILL_COMMAND_RAD
    away: the run ends ``device`` (exit 3) with the loop's brake, 0.5 s in (round 16: 1.59 s,
    at the band's hold). Creeping (reading +-2 mrad: not still): the command reaches the band
    some 0.36 s in (0.18 rad at 0.5 rad/s, after the trajectory generator's start: measured
    0.59 s) and is held there; NOT_FOLLOWING_S later the run ends the same way (round 15: the
    run went on to its end, ``finished``)."""
    robot = Frozen(ideal(model), creep_rad)
    q0 = robot.q0.copy()
    result = ControlLoop(robot, build_pipeline(model), _away(q0)).run(4.0)
    assert result.ended == "device", result.error
    assert isinstance(result.exception, DeviceError) and result.exception.exit_code == 3
    ran_s = (result.periods - result.stop_periods) * DT
    if creep_rad:
        assert result.error.startswith("the robot does not follow: RSP held")
        reached_s = TRACKING_ERROR_LIMIT_RAD / SPEED_RAD_S
        assert reached_s + NOT_FOLLOWING_S < ran_s < reached_s + NOT_FOLLOWING_S + 0.5
    else:
        assert result.error.startswith("the robot does not follow: RSP has not moved")
        assert STILL_S - 0.01 < ran_s < STILL_S + 0.2
    assert result.stop_periods > 0  # braked to rest within the limits, no jump
    assert_within_limits(model, robot.commands(q0), DT)


def test_a_robot_that_follows_never_trips(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    result = ControlLoop(robot, build_pipeline(model), _away(q0)).run(4.0)
    assert result.ended == "finished", result.error


def test_refwait_kept_set_trips_after_its_bound(model, tmp_path):
    """hubo-daemon says refWait in every state: the servo-error check cannot run, and after
    REF_WAIT_MAX_S the driver trips (exit 3, the last reference held; main: never)."""
    with HardwareDriver(model, armed=True, sink="file",
                        sink_path=tmp_path / "hubo-ref.bin") as driver:
        driver.start()
        advance = driver.source.advance

        def waiting(ref_rad, mode):
            return dataclasses.replace(advance(ref_rad, mode), ref_wait=True)

        driver.source.advance = waiting
        q = driver.read().q_rad.copy()
        with pytest.raises(DeviceError, match="refWait") as trip:
            for _ in range(400):
                driver.send(q)
                driver.step()
        assert trip.value.exit_code == 3 and driver.servo_off
        assert driver.read().time_s == pytest.approx(0.8 + REF_WAIT_MAX_S, abs=0.02)


# the drill moved 150 mm sideways in 1 s, then held
MOVE_AND_HOLD = raise_and_hold("move-and-hold", 1.5, stance=DRILL_STANCE, to_mm=(-150.0, 100.0))


@pytest.mark.parametrize("ref_wait", [False, True], ids=["frozen", "refwait"])
def test_a_dead_robot_does_not_complete_a_task(tmp_path, monkeypatch, ref_wait):
    """The review's frozen robot (the hardware dry run's echo replaced by joints that never
    move; or refWait kept set) on a short task: exit 3, one line, summary ``device`` (main:
    "completed", exit 0)."""
    import json

    from click.testing import CliRunner

    from hubo_cli.cli.main import main
    from hubo_cli.drivers import hardware, hubo_ach_io
    from hubo_cli.drivers.hubo_ach import JOINT_COUNT, StateFrame

    class Dead(hubo_ach_io.EchoSource):
        def open(self, pos0_rad):
            self._pos0, self._t = np.array(pos0_rad, dtype=float), 0.0
            return self._frame()

        def advance(self, ref_rad, mode):
            self._t += self.period_s
            return self._frame()

        def _frame(self):
            return StateFrame(self._t, np.zeros(3), np.zeros(3), np.zeros((4, 3)),
                              self._pos0.copy(), np.zeros(JOINT_COUNT), ref_wait=ref_wait)

    monkeypatch.setattr(hardware, "EchoSource", Dead)
    task, run = tmp_path / "move.toml", tmp_path / "run"
    task.write_text(MOVE_AND_HOLD)
    result = CliRunner().invoke(main, ["task", "run", str(task), "--driver", "hardware",
                                       "--arm", "--dry-run", "--out", str(run)])
    assert result.exit_code == 3, result.output
    said = "refWait" if ref_wait else "the robot does not follow"
    assert f"error: {said}" in result.output or said in result.output, result.output
    summary = json.loads((run / "summary.json").read_text())
    assert summary["ended"] == "device" and summary["completed"] is False
