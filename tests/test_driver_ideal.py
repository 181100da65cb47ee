"""The compiled command check every driver applies, and the ideal driver's compiled period,
against the numpy reference they replaced: the same commands and flags, velocities and IMU (leg
FK, lower sole flat), bit for bit."""

from __future__ import annotations

import numpy as np

from hubo_cli.drivers import checks
from hubo_cli.drivers.registry import make_driver
from hubo_cli.geometry import matrix_to_quat_wxyz
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, load_model

MODEL = load_model()
N = len(MODEL.joint_names)
LEG_PARTS = [(Limb(MODEL, name), MODEL.limb_slice(name)) for name in LEGS]


def _reference_imu(q: np.ndarray) -> np.ndarray:
    T_N_soles = [leg.fk(q[part]) for leg, part in LEG_PARTS]
    T_N_sole = min(T_N_soles, key=lambda T: T[2, 3])
    return matrix_to_quat_wxyz(T_N_sole[:3, :3].T)


def _reference_check(last: np.ndarray, q_cmd: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The command check as numpy arithmetic: NaN/inf keep the last command, then clip."""
    q = np.array(q_cmd, dtype=float)
    flags = []
    frozen = ~np.isfinite(q)
    if frozen.any():
        q[frozen] = last[frozen]
        flags.append(checks.NAN_REF)
    clipped = np.minimum(np.maximum(q, MODEL.lower_rad), MODEL.upper_rad)
    if (np.abs(clipped - q) > 1e-9).any():
        flags.append(checks.LIMIT_CLIP)
    return clipped, flags


def _commands(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Commands within, beyond and at the limits, with NaN and infinite entries."""
    lower, upper = MODEL.lower_rad, MODEL.upper_rad
    span = upper - lower
    out = []
    for k in range(n):
        q = rng.uniform(lower - 0.2 * span, upper + 0.2 * span) if k % 2 else \
            rng.uniform(lower, upper)
        if k % 5 == 0:
            q[rng.integers(N)] = np.nan
        if k % 7 == 0:
            q[rng.integers(N)] = -np.inf
        if k % 11 == 0:
            i = rng.integers(N)
            q[i] = upper[i] + 5e-10  # rounding at a limit: clipped without a flag
        out.append(q)
    return out


def test_period_matches_the_numpy_reference():
    rng = np.random.default_rng(7)
    driver = make_driver("ideal", MODEL)
    state = driver.start()
    assert np.array_equal(state.imu_quat_wxyz, _reference_imu(state.q_rad))
    flagged = set()
    for q_cmd in _commands(rng, 300):
        last = driver._cmd.copy()
        q_prev = state.q_rad.copy()
        expected, flags = _reference_check(last, q_cmd)
        checked, checked_flags, frozen = checks.sanitize_command(MODEL, last, q_cmd)
        assert np.array_equal(checked, expected) and checked_flags == flags
        assert np.array_equal(frozen, ~np.isfinite(q_cmd))
        applied = driver.send(q_cmd)
        state = driver.step()
        assert np.array_equal(applied, expected)
        assert np.array_equal(state.q_rad, expected)
        assert np.array_equal(state.dq_rad_s, (expected - q_prev) / MODEL.control_period_s)
        assert np.array_equal(state.imu_quat_wxyz, _reference_imu(expected))
        assert state.flags == tuple(flags)
        flagged.update(flags)
    assert flagged == {checks.NAN_REF, checks.LIMIT_CLIP}  # both paths were exercised


def test_state_arrays_are_the_callers_own():
    driver = make_driver("ideal", MODEL)
    driver.start()
    q = MODEL.lower_rad + 0.5 * (MODEL.upper_rad - MODEL.lower_rad)
    applied = driver.send(q[::-1][::-1])  # a view: copied before the compiled check
    state = driver.step()
    applied += 1.0
    state.q_rad += 1.0
    assert np.array_equal(driver.step().q_rad, q)
    assert np.array_equal(driver.read().dq_rad_s, np.zeros(N))
