"""The default balancer's and the capture-point monitor's compiled periods give what their
Python forms gave: the balancer against its period written in Python floats and numpy, the
monitor's held reference CoM against a fresh one."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from hubo_cli.control.balance import (
    FEET,
    MAX_CORRECTION_ACCEL_RAD_S2,
    MAX_CORRECTION_RATE_RAD_S,
    SMOOTHING_S,
    DampingBalancer,
    _follow_offsets,
)
from hubo_cli.control.capture_point import CapturePointMonitor
from hubo_cli.control.module import Cycle
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    QUAT_WORLD_TORSO,
    T_WORLD_SOLES,
    WRENCHES,
)
from hubo_cli.posture import home_posture
from hubo_cli.state import FT_SENSORS, RobotState

TOL = 1e-12


class _PythonBalancer:
    """:class:`DampingBalancer`'s period as it was written in Python floats and numpy (its
    per-leg filter, :func:`_follow_offsets`, is checked against Python elsewhere)."""

    def __init__(self, balancer: DampingBalancer) -> None:
        self.b = balancer
        self.common = [0.0, 0.0]
        self.differential, self.offsets, self.rate = np.zeros((3, 2, 2))
        self.last_cmd: np.ndarray | None = None
        self.reference = 0.0

    def reference_moment(self, q_ref: np.ndarray) -> float:
        b = self.b
        if self.last_cmd is not None and (q_ref == self.last_cmd).all():
            return self.reference
        q = b._robot.configuration(q_ref, None)
        com = pin.centerOfMass(b._robot.model, b._data, q, False)
        x = 0.0
        for fid in b._sole_ids:
            oMf = pin.updateFramePlacement(b._robot.model, b._data, fid)
            x += float((oMf.rotation.T @ (com - oMf.translation))[0])
        self.last_cmd, self.reference = q_ref.copy(), -b._weight_n * x / 2
        return self.reference

    def update(self, q_rad: np.ndarray, state: RobotState, contact: tuple[bool, bool],
               dt: float) -> tuple[np.ndarray, bool]:
        b, bad = self.b, False
        q = np.array(q_rad, dtype=float)
        q_ref = np.where(np.isfinite(q), q, state.q_rad)
        moments = {}
        for leg, sensor in FEET:
            wrench = state.ft.get(sensor)
            moments[leg] = (0.0, 0.0) if wrench is None else (float(wrench[4]), float(wrench[3]))
        if not all(math.isfinite(m[0]) and math.isfinite(m[1]) for m in moments.values()):
            bad, moments = True, {leg: (0.0, 0.0) for leg, _ in FEET}
        roll, pitch = state.tilt_rad()
        tilt_deg = (math.degrees(pitch), math.degrees(roll))
        if not (math.isfinite(tilt_deg[0]) and math.isfinite(tilt_deg[1])):
            bad, tilt_deg = True, (0.0, 0.0)
        right, left = moments["right-leg"], moments["left-leg"]
        reference = self.reference_moment(q_ref)
        wrenches = [state.ft[s] for _, s in FEET if state.ft.get(s) is not None]
        fz = sum(float(w[2]) for w in wrenches)
        mean = [(right[0] + left[0]) / 2, (right[1] + left[1]) / 2]
        error = (mean[0] - reference / 2, mean[1]) if fz > 0.5 * b._weight_n else (0.0, 0.0)
        rate = [error[k] / b.damping + b.k_r * tilt_deg[k] - self.common[k] / b.common_leak_s
                for k in (0, 1)]
        moment_y = sum(float(w[4]) for w in wrenches)
        x_lo, x_hi = b._flat_x_m
        if b.edge_margin_m > 0 and fz > 0.5 * b._weight_n and not x_lo < -moment_y / fz < x_hi:
            rate[0] = -self.common[0] / b.common_leak_s
        self.common = [self.common[k] + rate[k] * dt for k in (0, 1)]
        both = all(contact)
        _follow_offsets(q, b._ankles, b._ankle_signs, *right, *left, *mean, *self.common, both,
                        self.differential, self.offsets, self.rate, b._lower, b._upper,
                        b.max_offset_rad, b.k_d, b.differential_leak_s,
                        MAX_CORRECTION_RATE_RAD_S, MAX_CORRECTION_ACCEL_RAD_S2 * dt,
                        SMOOTHING_S, dt)
        return q, bad


def _wrenches(rng, weight_n: float) -> dict[str, np.ndarray]:
    ft = {s: np.concatenate([rng.normal(0.0, 5.0, 2), [rng.normal(weight_n / 2, weight_n / 3)],
                             rng.normal(0.0, 20.0, 3)]) for s in FT_SENSORS}
    return ft


def test_compiled_balancer_period_matches_python(model):
    dt = model.control_period_s
    balancer = DampingBalancer(model)
    python = _PythonBalancer(balancer)
    rng = np.random.default_rng(11)
    q_home = home_posture(model)
    n = len(q_home)
    q = q_home.copy()
    rested = bad_seen = 0
    for period in range(600):
        if period % 5:  # every fifth period the command holds
            q = q + rng.normal(0.0, 2e-3, n)
        q_cmd = q.copy()
        if period % 9 == 0:
            q_cmd[rng.integers(n)] = math.nan  # a joint without a command
        quat = np.concatenate([[1.0], rng.normal(0.0, 0.03, 3)])
        ft = _wrenches(rng, balancer._weight_n)
        if period % 7 == 0:  # the left foot's pressure at its toe: the feet tip
            ft["left-ankle"][4] = -0.2 * ft["left-ankle"][2]
            rested += 1
        if period % 97 == 0:
            ft["right-ankle"][3] = math.nan
        if period % 53 == 0:
            del ft["left-ankle"]
        quat = quat / np.linalg.norm(quat)
        state = RobotState(period * dt, q_home + rng.normal(0.0, 1e-3, n), np.zeros(n),
                           imu_quat_wxyz=quat, ft=ft)
        store = Store()  # the estimate: the attitude as the IMU reads it here
        store[QUAT_WORLD_TORSO], store[CONTACT] = quat, (True, period % 4 != 0)
        store[WRENCHES] = ft  # and the wrenches as the sensors read them
        cycle = Cycle(period * dt, dt, store=store)
        got = balancer.update(q_cmd, state, cycle)
        expected, bad = python.update(q_cmd, state, store[CONTACT], dt)
        assert np.allclose(got, expected, rtol=0.0, atol=TOL, equal_nan=True), period
        assert np.array_equal(np.isnan(got), np.isnan(q_cmd))
        assert ("balance-bad-sensor" in cycle.flags) == bad, period
        bad_seen += bad
        assert np.allclose(balancer._offsets, python.offsets, rtol=0.0, atol=TOL), period
        assert abs(balancer._common[0] - python.common[0]) <= TOL
        assert abs(balancer._common[1] - python.common[1]) <= TOL
        assert abs(balancer.reference_moment_nm[0] - python.reference) <= TOL * 1e3
    assert bad_seen >= 5 and rested >= 50
    assert np.abs(python.offsets).max() > 1e-3  # the corrections moved: the test means something


def test_the_held_reference_matches_a_fresh_one(model):
    dt = model.control_period_s
    monitor = CapturePointMonitor(model, dt)
    rng = np.random.default_rng(13)
    poses = np.tile(np.eye(4), (2, 1, 1))
    poses[0, 1, 3], poses[1, 1, 3] = -0.1, 0.1
    store = Store()
    store[COM_WORLD], store[COM_VELOCITY_WORLD] = np.array([0.0, 0.0, 0.8]), np.zeros(3)
    store[CAPTURE_POINT_WORLD], store[CONTACT] = np.zeros(2), (True, True)
    store[T_WORLD_SOLES] = poses
    q_home = home_posture(model)
    state = RobotState(0.0, q_home, np.zeros(len(q_home)))
    monitor.measure(state, store, q_home)
    for k in range(40):
        q_cmd = q_home + (rng.normal(0.0, 0.05, len(q_home)) if k % 2 else 0.0)
        q_cmd[k % len(q_home)] = math.nan
        foot = k % 3 % 2
        held = monitor._reference_com(q_cmd, state, foot)  # maybe the kept one
        fresh = monitor._reference_com(q_cmd, state, foot)
        monitor._last_cmd[:] = math.nan  # forget: computed anew
        anew = monitor._reference_com(q_cmd, state, foot)
        # the commanded posture with the measured joints where it has none, in pinocchio
        q_pin = monitor.robot.configuration(np.where(np.isfinite(q_cmd), q_cmd, q_home), None)
        com = pin.centerOfMass(monitor.robot.model, monitor.data, q_pin, False)
        oMf = pin.updateFramePlacement(monitor.robot.model, monitor.data,
                                       monitor._sole_ids[foot])
        flat = monitor._flat_sole[foot]
        expected_ref = flat[:2, :3] @ oMf.actInv(com) + flat[:2, 3]
        for value in (held, fresh, anew):
            assert np.allclose(value, expected_ref, rtol=0.0, atol=TOL), k
