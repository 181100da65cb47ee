"""Helpers shared by the control tests: a recording driver wrapper and limit checks."""

from __future__ import annotations

import numpy as np

from hubo_cli.drivers.registry import make_driver

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
