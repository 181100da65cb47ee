"""A robot that follows wrongly is device trouble (round 17, hubo_cli/control/following.py):
encoders that jump, an estimate that runs away on them, a joint that stops while its plan moves
less than the limiter's band; and a dry run's state age judged in the echo's own time. On main
each of these ran to the end (or, for the dry run on a busy machine, lost its state)."""

from __future__ import annotations

import dataclasses
import re
import time

import numpy as np
import pytest
from control_support import Recorder, assert_within_limits, ideal

from hubo_cli.control.following import STILL_COMMAND_RAD, STILL_S
from hubo_cli.control.limiter import TRACKING_ERROR_LIMIT_RAD
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.drivers.hardware import HardwareDriver
from hubo_cli.estimation.build import build_estimator
from hubo_cli.estimation.keys import T_WORLD_TORSO

DT = 0.005


class Faulty(Recorder):
    """The ideal robot, its measured joints changed from ``at_s`` on by ``fault(q, t_s)``."""

    def __init__(self, driver, at_s: float, fault) -> None:
        super().__init__(driver)
        self.at_s, self.fault = at_s, fault

    def step(self):
        state = self.driver.step()
        if state.time_s < self.at_s:
            return state
        return dataclasses.replace(state, q_rad=self.fault(state.q_rad.copy(), state.time_s))


def _sway(q0, joint: int, amplitude_rad: float):
    """The joint goes ``amplitude_rad`` out and back over 2 s, then holds."""
    def target(t_s, state):
        q = q0.copy()
        q[joint] -= amplitude_rad * np.sin(np.pi * min(t_s, 2.0) / 2.0)
        return q, {}
    return target


def test_encoders_that_jump_are_device_trouble(model):
    """Every joint reads +-0.12 rad alternating every 0.1 s (the review's case): under the
    0.2 rad servo check and the band's 0.09 rad progress, each flip 48 rad/s. The run ends
    ``device`` at the first jump, braked within the limits (main: finished)."""
    def noise(q, t_s):
        return q + 0.12 * (1.0 if int(t_s / 0.1) % 2 else -1.0)

    robot = Faulty(ideal(model), 0.5, noise)
    q0 = robot.read().q_rad.copy()
    result = ControlLoop(robot, build_pipeline(model), _sway(q0, 3, 0.1)).run(3.0)
    assert result.ended == "device", result.error
    assert result.exception.exit_code == 3
    assert re.match(r"implausible measurement: \w+ jumped 0\.12\d rad in 5 ms", result.error)
    assert (result.periods - result.stop_periods) * DT == pytest.approx(0.5, abs=0.02)
    assert_within_limits(model, robot.commands(q0), DT)


def test_a_joint_that_stops_while_its_plan_moves_under_the_band_is_device_trouble(model):
    """REB stops 0.3 s in while its plan goes 0.1 rad out and back (under the 0.18 rad band:
    never held there, so main finished): STILL_S after its command went STILL_COMMAND_RAD
    away, ``device``."""
    reb = model.joint_names.index("REB")
    robot = Faulty(ideal(model), 0.3, None)
    frozen = {}

    def freeze(q, t_s):
        q[reb] = frozen.setdefault("q", q[reb])
        return q

    robot.fault = freeze
    q0 = robot.read().q_rad.copy()
    result = ControlLoop(robot, build_pipeline(model), _sway(q0, reb, 0.1)).run(3.0)
    assert result.ended == "device", result.error
    assert result.error.startswith("the robot does not follow: REB has not moved")
    assert 0.3 + STILL_S - 0.02 < (result.periods - result.stop_periods) * DT < 1.5
    assert STILL_COMMAND_RAD < 0.1 < TRACKING_ERROR_LIMIT_RAD
    assert_within_limits(model, robot.commands(q0), DT)


def test_a_following_robot_under_the_same_plan_finishes(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    reb = model.joint_names.index("REB")
    result = ControlLoop(robot, build_pipeline(model), _sway(q0, reb, 0.1)).run(3.0)
    assert result.ended == "finished", result.error


def test_a_torso_estimated_metres_up_is_device_trouble_before_a_module_acts(model):
    """The estimate's torso leaves the heights a robot on the floor can hold: ``device`` in
    the period it happened, no module run on it (main: the balancer acted on it)."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    estimator = build_estimator(model, period_s=DT)
    update, periods = estimator.update, []

    def running_away(state):
        update(state)
        periods.append(state.time_s)
        if len(periods) > 100:
            T = estimator.store[T_WORLD_TORSO].copy()
            T[2, 3] += 0.01 * (len(periods) - 100)  # 2 m/s up
            estimator.store[T_WORLD_TORSO] = T

    estimator.update = running_away
    loop = ControlLoop(robot, build_pipeline(model), _sway(q0, 3, 0.0), estimator=estimator)
    result = loop.run(3.0)
    assert result.ended == "device", result.error
    assert result.error.startswith("implausible measurement: the torso is estimated 1.")
    assert 100 + 30 < len(periods) < 100 + 50  # 0.33-0.43 m over a ~1 m torso


def test_a_busy_machine_does_not_lose_a_dry_runs_state(model, tmp_path):
    """The dry run's echo has no robot to be late for: a 0.15 s pause of this process inside a
    step (a busy machine) is no lost state (main: the stale brake, then StateLost, exit 3)."""
    with HardwareDriver(model, armed=True, sink="file",
                        sink_path=tmp_path / "hubo-ref.bin") as driver:
        q = driver.start().q_rad.copy()
        check, paused = driver.thermal.check, []

        def pausing(*args):
            if len(paused) == 10:
                time.sleep(0.15)  # (after the state was taken as fresh)
            paused.append(1)
            return check(*args)

        driver.thermal.check = pausing
        flags = []
        for _ in range(300):  # 1.5 s: past the 0.8 s grace
            driver.send(q)
            flags += driver.step().flags
    assert not {"stale-state", "stale-hold"} & set(flags)


def test_the_echo_judges_freshness_in_its_own_time_a_daemon_by_the_wall_clock():
    from hubo_cli.drivers.hubo_ach_io import AchStateSource, EchoSource, StateSource

    assert AchStateSource.clock_s is StateSource.clock_s  # time.monotonic
    echo = EchoSource(DT, 40)
    echo.open(np.zeros(42))
    for _ in range(20):
        echo.advance(np.zeros(42), np.ones(42, dtype=np.int16))
    assert echo.clock_s() == pytest.approx(20 * DT)
