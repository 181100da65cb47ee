"""Helpers shared by the control tests: a recording driver wrapper, limit checks and the
estimate of a hand-made state."""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.drivers.registry import make_driver
from hubo_cli.estimation.base import FloatingBase
from hubo_cli.estimation.centre_of_mass import CentreOfMass
from hubo_cli.estimation.estimator import Estimator
from hubo_cli.estimation.keys import CONTACT, QUAT_WORLD_TORSO, WRENCHES
from hubo_cli.estimation.observer import Observer

VEL_TOL = 1e-6   # relative tolerance on finite-difference velocity
ACC_TOL = 1e-6   # relative tolerance on finite-difference acceleration
ABS_TOL = 1e-7   # absolute slack (rad/s, rad/s^2) for rounding


class Recorder:
    """Wraps a driver and records every command the loop sends (and stop calls)."""

    def __init__(self, driver) -> None:
        self.driver = driver
        self.sent: list[np.ndarray] = []
        self.stops = 0

    def __getattr__(self, name):
        return getattr(self.driver, name)

    def send(self, q):
        self.sent.append(np.array(q, dtype=float))
        return self.driver.send(q)

    def step(self):
        return self.driver.step()

    def stop(self):
        self.stops += 1
        return self.driver.stop()

    def commands(self, q0: np.ndarray) -> np.ndarray:
        """All commands with the start posture twice in front (the command at rest)."""
        return np.vstack([q0, q0] + self.sent)


def ideal(model, q0=None) -> Recorder:
    """A started ideal driver wrapped in a Recorder."""
    driver = make_driver("ideal", model)
    driver.start(q0)
    return Recorder(driver)


def limit_violations(model, commands: np.ndarray, dt: float) -> dict[str, float]:
    """Worst excess over each limit (0 when within): position (rad), velocity and acceleration
    (as ratios minus one), plus the count of non-finite entries."""
    lower, upper = model.lower_rad, model.upper_rad
    v = np.diff(commands, axis=0) / dt
    a = np.diff(commands, 2, axis=0) / dt**2
    vmax, amax = model.velocity_rad_s, model.acceleration_rad_s2
    return {
        "nonfinite": float(np.count_nonzero(~np.isfinite(commands))),
        "position": float(max(0.0, np.max(commands - upper) - 1e-9,
                              np.max(lower - commands) - 1e-9)),
        "velocity": float(max(0.0, np.max(np.abs(v) - vmax * (1 + VEL_TOL) - ABS_TOL))),
        "acceleration": float(max(0.0, np.max(np.abs(a) - amax * (1 + ACC_TOL) - ABS_TOL))),
    }


def assert_within_limits(model, commands: np.ndarray, dt: float) -> None:
    """Fail with the worst excesses if any command breaks a limit or is not finite."""
    bad = limit_violations(model, commands, dt)
    assert bad == {"nonfinite": 0.0, "position": 0.0, "velocity": 0.0, "acceleration": 0.0}, bad


def assert_within_braking_limits(model, commands: np.ndarray, dt: float) -> None:
    """Fail if any command breaks a position or velocity limit, or accelerates harder than the
    emergency braking limits (the stopper's revert and wrist-torque stop brake at those)."""
    from hubo_cli.motion.limits import JointLimits

    brake = JointLimits.from_model(model).for_emergency_brake(model)
    bad = limit_violations(model, commands, dt)
    assert bad["nonfinite"] == bad["position"] == bad["velocity"] == 0.0, bad
    a = np.diff(commands, 2, axis=0) / dt**2
    assert np.all(np.abs(a) <= brake.acceleration_rad_s2 * (1 + ACC_TOL) + ABS_TOL), \
        float(np.max(np.abs(a) / brake.acceleration_rad_s2))


def sensed_cycle(t_s: float, dt_s: float, state, **fields):
    """A :class:`~hubo_cli.control.module.Cycle` whose store holds the estimate's wrenches as
    the test's state gives them (taken as already compensated: a module's unit test)."""
    from hubo_cli.control.module import Cycle
    from hubo_cli.estimation.keys import WRENCHES

    cycle = Cycle(t_s, dt_s, **fields)
    cycle.store[WRENCHES] = state.ft
    return cycle


def compensated_wrenches(model, state, tools=None) -> dict:
    """The estimate's wrenches of one state (RemoveForceOffset with the state's attitude): the
    sensors' readings with the hand's, the tool's and the foot's weight removed."""
    from hubo_cli.estimation.build import build_estimator
    from hubo_cli.estimation.keys import WRENCHES

    return build_estimator(model, tools or {}).reset(state)[WRENCHES]


class SensedAsGiven(Observer):
    """Test input for the estimate: the attitude as the state's IMU reads it, the contact
    given, the wrenches as the sensors read them (no filter, no debounce, no offsets removed),
    so that a module test controls exactly what the module is shown."""

    name = "sensed-as-given"
    writes = (QUAT_WORLD_TORSO, CONTACT, WRENCHES)

    def __init__(self, contact: tuple[bool, bool] = (True, True)) -> None:
        self.contact = contact

    def update(self, state, store) -> None:
        store[QUAT_WORLD_TORSO] = np.asarray(state.imu_quat_wxyz, dtype=float)
        store[CONTACT] = self.contact
        store[WRENCHES] = state.ft


def body_estimator(model, contact: tuple[bool, bool] = (True, True),
                   drill: bool = False) -> Estimator:
    """The estimation layer's floating base and centre of mass (est-body's observers) on
    :class:`SensedAsGiven`'s inputs: the estimate a module sees of a hand-made state."""
    return Estimator([SensedAsGiven(contact), FloatingBase(model),
                      CentreOfMass(model, model.control_period_s, drill=drill)])


_ESTIMATORS: dict[tuple[int, tuple[bool, bool]], Estimator] = {}


def estimate_of(model, state, contact: tuple[bool, bool] = (True, True)) -> Store:
    """A store holding :func:`body_estimator`'s estimate of ``state`` as at the start of a
    run (its own store: the estimators are kept per model and contact)."""
    key = (id(model), contact)
    if key not in _ESTIMATORS:
        _ESTIMATORS[key] = body_estimator(model, contact)
    estimator = _ESTIMATORS[key]
    estimated = estimator.reset(state)
    store = Store()
    for written in estimator.writes:
        store[written] = estimated[written]
    return store
