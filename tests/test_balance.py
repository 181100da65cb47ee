"""The ankle balancer (paper III-C, eq. 11-12): signs and units on synthetic states, then
standing and pushes in the simulation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from control_support import estimate_of

from hubo_cli.control.balance import (
    K_C_RAD_S_PER_NM,
    K_R_RAD_S_PER_DEG,
    AnkleBalancer,
    ankle_axis_signs,
)
from hubo_cli.control.module import Cycle
from hubo_cli.experiments.standing import stand
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

pytestmark = pytest.mark.xdist_group("balance")  # module-scoped runs: one worker

MODEL = load_model()
DT = MODEL.control_period_s
NAMES = MODEL.joint_names
ANKLES = {leg: (NAMES.index(MODEL.limb(leg).joints[4]), NAMES.index(MODEL.limb(leg).joints[5]))
          for leg in ("right-leg", "left-leg")}


def _state(pitch_deg=0.0, roll_deg=0.0, moment_y=0.0, moment_x=0.0) -> RobotState:
    """A state with the torso turned about world y then x, and the same ground moment (N m,
    about the sole x and y axes) under both feet."""
    R = pin.rpy.rpyToMatrix(np.radians(roll_deg), np.radians(pitch_deg), 0.0)
    quat = pin.Quaternion(R)
    q = home_posture(MODEL)
    wrench = np.array([0.0, 0.0, 190.0, moment_x, moment_y, 0.0])
    ft = {"right-ankle": wrench.copy(), "left-ankle": wrench.copy(),
          "right-wrist": np.zeros(6), "left-wrist": np.zeros(6)}
    return RobotState(0.0, q, np.zeros_like(q), np.array([quat.w, quat.x, quat.y, quat.z]),
                      ft=ft)


def _offsets_after(state, periods=1, **gains):
    balancer = AnkleBalancer(MODEL, **gains)
    q0 = home_posture(MODEL)
    store = estimate_of(MODEL, state)
    balancer.reset(q0, state, store)
    q = q0
    for k in range(periods):
        q = balancer.update(q0, state, Cycle(k * DT, DT, store=store))
    return {leg: q[list(idx)] - q0[list(idx)] for leg, idx in ANKLES.items()}


def test_ankle_axes_point_along_sole_y_and_x():
    assert ankle_axis_signs(MODEL) == {"right-leg": (1.0, 1.0), "left-leg": (1.0, 1.0)}


def test_upright_and_unloaded_means_no_correction():
    for offsets in _offsets_after(_state(), periods=50).values():
        assert np.allclose(offsets, 0.0)


def test_tilt_term_has_the_documented_units_and_drives_the_body_back():
    # 1 degree forward: K_r rad/s per degree, integrated over 20 periods (0.1 s)
    offsets = _offsets_after(_state(pitch_deg=1.0), periods=20)
    for pitch, roll in offsets.values():
        assert pitch == pytest.approx(K_R_RAD_S_PER_DEG * 1.0 * 20 * DT, rel=1e-6)
        assert roll == pytest.approx(0.0, abs=1e-12)
    # leaning right (positive roll) rolls the ankles positive, which leans the body left
    for _pitch, roll in _offsets_after(_state(roll_deg=1.0), periods=20).values():
        assert roll == pytest.approx(K_R_RAD_S_PER_DEG * 20 * DT, rel=1e-3)


def test_moment_term_complies_with_the_ground_moment():
    # the ground pushes under the toes (moment about +y negative): the ankle yields, toes up
    offsets = _offsets_after(_state(moment_y=-10.0), periods=20)
    for pitch, roll in offsets.values():
        assert pitch == pytest.approx(-K_C_RAD_S_PER_NM * 10.0 * 20 * DT, rel=1e-6)
        assert roll == 0.0
    for _pitch, roll in _offsets_after(_state(moment_x=4.0), periods=20).values():
        assert roll == pytest.approx(K_C_RAD_S_PER_NM * 4.0 * 20 * DT, rel=1e-6)


def test_rates_and_offsets_are_bounded_and_stay_within_limits():
    offsets = _offsets_after(_state(pitch_deg=25.0, roll_deg=25.0), periods=2000,
                             max_rate_rad_s=0.2, max_offset_rad=0.1)
    for leg, (pitch, roll) in offsets.items():
        assert 0 < pitch <= 0.1 + 1e-12
        i_roll = ANKLES[leg][1]
        assert home_posture(MODEL)[i_roll] + roll <= MODEL.upper_rad[i_roll] + 1e-12
    one_period = _offsets_after(_state(pitch_deg=25.0), periods=1, max_rate_rad_s=0.2)
    assert one_period["right-leg"][0] == pytest.approx(0.2 * DT)


def test_a_bad_sensor_is_flagged_and_ignored():
    state = _state()
    state.ft["right-ankle"][3] = np.nan
    balancer = AnkleBalancer(MODEL)
    cycle = Cycle(0.0, DT, store=estimate_of(MODEL, state))
    q = balancer.update(home_posture(MODEL), state, cycle)
    assert np.all(np.isfinite(q))
    assert "balance-bad-sensor" in cycle.flags


# ------------------------------------------------------------------ in the simulation
@pytest.mark.physical
def test_standing_with_balance_stays_upright_with_flat_feet(tmp_path):
    result = stand(MODEL, duration_s=3.0, push_n=0.0, balance=True, out=tmp_path,
                   balance_mode="paper")
    assert not result.fell
    assert result.feet_flat
    # the paper's law leans with the load (1.1 deg after 20 s), where the default balancer
    # holds the body within 0.2 deg over the same 3 s (test_balance_default.py); measured
    # 0.753 deg on both code paths (AVX-512 / portable): 1.5x from 0.5, 2.7x from 2.0
    assert 0.5 < result.max_tilt_deg < 2.0
    # settling toward the lean where the two terms balance (about 1.07 deg after 30 s): the
    # last second drifts less than the first (measured 0.46 of it on both code paths; bound
    # 0.7 = 1.5x)
    first = np.ptp(result.tilts_deg[result.times_s <= 1.0])
    last = np.ptp(result.tilts_deg[result.times_s > 2.0])
    assert 0 < last < 0.7 * first


@pytest.fixture(scope="module")
def pushed(tmp_path_factory):
    return {balance: stand(MODEL, duration_s=2.5, push_n=30.0, balance=balance,
                           out=tmp_path_factory.mktemp(f"balance-{balance}"),
                           balance_mode="paper")
            for balance in (True, False)}


@pytest.mark.physical
def test_a_30_newton_push_is_absorbed_without_a_fall(pushed):
    for result in pushed.values():
        assert not result.fell
        assert result.feet_flat
        assert result.max_tilt_deg < 2.0  # measured 0.05-0.83 deg (both code paths): 2.4x


@pytest.mark.physical
def test_balance_keeps_the_feet_evenly_loaded_through_the_push(pushed):
    # eq. 11-12's compliance evens out the two feet (on the compliant soles; on rigid ones the
    # limiter's clamp turned it into rocking): over the second from the push on, the
    # difference of the two ankle moments stays several times smaller than with it off
    def mean_difference(result):
        window = (result.times_s > 1.0) & (result.times_s <= 2.0)
        return result.feet_moment_difference_nm[window].mean()

    # measured 0.31 against 4.07 N m (0.076 of it) on both code paths (AVX-512 / portable):
    # bound 0.3 = 3.9x. (The peaks, 6.08 and 6.41 N m, come at the push, before the compliance
    # acts, and differ by 5%: a knife edge, not asserted.)
    on, off = pushed[True], pushed[False]
    assert mean_difference(on) < 0.3 * mean_difference(off)
