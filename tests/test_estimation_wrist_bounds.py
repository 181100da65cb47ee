"""The wrists' inertia compensation's bounds (hubo_cli/estimation/wrenches.py): a glitching
gyro or a bad but in-range accelerometer neither stops a free still hand nor hides a real
overload from the wrist-torque stop for longer than the stated burst."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hubo_cli.control.estop import EmergencyStopper, wrist_torque_nm
from hubo_cli.control.module import Cycle
from hubo_cli.drivers.hardware import HardwareDriver
from hubo_cli.drivers.ideal import IdealDriver
from hubo_cli.estimation.build import build_estimator
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.estimation.wrenches import (
    INERTIA_BURST_PERIODS,
    INERTIA_LARGE_NM,
    INERTIA_SMALL_NM,
)
from hubo_cli.posture import home_posture

DT = 0.005


def _start(model, drill: bool):
    with IdealDriver(model, drill=drill) as driver:
        return driver.start(home_posture(model))


def _periods_to_stop(model, estimator, states) -> int | None:
    """The first period (1-based) the wrist-torque stop asks to stop, None if it never does."""
    store = estimator.reset(states[0])
    stopper = EmergencyStopper(model, DT, sources=("wrist-torque",))
    stopper.reset(states[0].q_rad, states[0], store)
    for k, state in enumerate(states[1:], start=1):
        estimator.update(state)
        cycle = Cycle(k * DT, DT, store=store)
        stopper.update(state.q_rad, state, cycle)
        if "wrist-torque" in cycle.estop_requests:
            return k
    return None


@pytest.mark.parametrize("seed", range(4))
def test_a_gyro_glitch_on_a_still_free_hand_changes_nothing(model, seed):
    """One period's gyro off by 0.5-30 rad/s (inside its 35 rad/s range, so not rejected) on
    a still robot, the accelerometer at rest: the wrists read exactly what they read without
    the glitch (the inertia is removed only while the accelerometer departs from the
    attitude's gravity), so the stop does not fire (before the bounds: a 0.86 rad/s glitch
    stopped it)."""
    rng = np.random.default_rng(seed)
    drill = bool(seed % 2)
    state = _start(model, drill)
    tools = {"right-arm": "drill"} if drill else {}
    clean = build_estimator(model, tools, DT)
    glitched = build_estimator(model, tools, DT)
    clean.reset(state)
    glitched.reset(state)
    for k in range(8):
        gyro = state.imu_gyro_rad_s.copy()
        if k in (2, 5):
            axis = rng.normal(size=3)
            gyro = gyro + rng.uniform(0.5, 30.0) * axis / np.linalg.norm(axis)
        a = clean.update(state)[WRENCHES]
        b = glitched.update(replace(state, imu_gyro_rad_s=gyro))[WRENCHES]
        for wrist in ("right-wrist", "left-wrist"):
            np.testing.assert_array_equal(a[wrist], b[wrist])
    assert _periods_to_stop(model, build_estimator(model, tools, DT), [state] + [
        replace(state, imu_gyro_rad_s=np.array([0.0, 30.0 * (-1) ** k, 0.0]))
        for k in range(20)]) is None


@pytest.mark.parametrize("seed", range(6))
def test_a_bad_accelerometer_cannot_hide_an_overload_beyond_the_burst(model, seed):
    """A held hand loaded with a 1.5 N m contact moment (over the 1.21 N m limit by more than
    INERTIA_SMALL_NM) and an accelerometer that reads a finite, in-range (< 157 m/s^2) but
    wrong specific force, stuck or new every period (the worst found before the bounds:
    1.6 N m compensated down to 0.07 N m, indefinitely): every period the compensated
    moment stays within INERTIA_LARGE_NM of the contact's, never more than
    INERTIA_SMALL_NM under it for over INERTIA_BURST_PERIODS periods in a row, and the
    stop fires within INERTIA_BURST_PERIODS + 1 periods."""
    rng = np.random.default_rng(100 + seed)
    drill = bool(seed % 2)
    state = _start(model, drill)
    tools = {"right-arm": "drill"} if drill else {}
    direction = rng.normal(size=2)
    contact = np.zeros(6)
    contact[3:5] = 1.5 * direction / np.linalg.norm(direction)
    ft = {k: np.array(v) for k, v in state.ft.items()}
    ft["right-wrist"] = ft["right-wrist"] + contact
    held = replace(state, ft=ft)
    # seeds 0-3 stuck (a 30 m/s^2 sideways, a zero, a random reading), 4-5 new every period
    stuck = [[30.0, 0.0, 9.81], [0.0, 30.0, 9.81], [0.0, 0.0, 0.0], rng.uniform(-90, 90, 3)]
    states = [held] + [replace(held, imu_accel_m_s2=np.array(
        stuck[seed] if seed < 4 else rng.uniform(-90.0, 90.0, 3))) for _ in range(40)]
    estimator = build_estimator(model, tools, DT)
    estimator.reset(held)
    hidden = 0  # periods in a row with more than INERTIA_SMALL_NM taken off the contact
    for s in states[1:]:
        moment = wrist_torque_nm(estimator.update(s)[WRENCHES]["right-wrist"])
        assert moment >= 1.5 - INERTIA_LARGE_NM - 1e-9
        hidden = hidden + 1 if moment < 1.5 - INERTIA_SMALL_NM - 1e-9 else 0
        assert hidden <= INERTIA_BURST_PERIODS
    stop = _periods_to_stop(model, build_estimator(model, tools, DT), states)
    assert stop is not None and stop <= INERTIA_BURST_PERIODS + 1


def test_the_hardware_driver_removes_no_inertia(model):
    """hubo-ach reports no accelerations (its accelerometer is rebuilt from the tilt): the
    hardware driver says so and its estimate removes the hands' weight alone, whatever the
    accelerometer reads."""
    assert HardwareDriver.accel_measured is False and IdealDriver.accel_measured is True
    state = _start(model, False)
    weight_only = build_estimator(model, {}, DT, accel_measured=False)
    reference = build_estimator(model, {}, DT)
    weight_only.reset(state)
    reference.reset(state)
    still = reference.update(state)[WRENCHES]
    for accel in ([30.0, 0.0, 9.81], [0.0, -40.0, 0.0]):
        jolted = weight_only.update(replace(state, imu_accel_m_s2=np.array(accel),
                                            imu_gyro_rad_s=np.array([3.0, 0.0, 0.0])))
        for wrist in ("right-wrist", "left-wrist"):
            np.testing.assert_array_equal(jolted[WRENCHES][wrist], still[wrist])


def test_the_loop_builds_the_hardware_estimate_without_inertia(model, tmp_path):
    """The control loop builds its estimate with the driver's ``accel_measured``: on the
    hardware driver the wrists' compensation removes no inertia."""
    from hubo_cli.control.loop import ControlLoop
    from hubo_cli.estimation.wrenches import RemoveForceOffset

    with HardwareDriver(model, armed=True, sink="file",
                        sink_path=tmp_path / "hubo-ref.bin") as driver:
        state = driver.start()
        stopper = EmergencyStopper(model, driver.period_s, sources=("wrist-torque",))
        loop = ControlLoop(driver, [stopper], lambda t_s, s: (state.q_rad, {}), speed=None)
    offsets = [o for o in loop.estimator.observers if isinstance(o, RemoveForceOffset)]
    assert len(offsets) == 1 and not offsets[0]._inertial.any()
