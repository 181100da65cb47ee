"""The stabilizer (hrpsys TPCC form on the waist): it moves the commanded CoM against a
measured CoM error, within its bounds, refuses bad settings, and the paper's mode runs
without it."""

from __future__ import annotations

import numpy as np
import pytest
from control_support import estimate_of

from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.stabilizer import Stabilizer
from hubo_cli.errors import ConfigError
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

DT = 0.005


def _state(model, pitch_deg: float = 0.0, q=None) -> RobotState:
    half = np.radians(pitch_deg) / 2
    quat = np.array([np.cos(half), 0.0, np.sin(half), 0.0])
    ft = {name: np.zeros(6) for name in ("right-wrist", "left-wrist")}
    for foot in ("right-ankle", "left-ankle"):
        ft[foot] = np.array([0.0, 0.0, 190.0, 0.0, 0.0, 0.0])
    q = home_posture(model) if q is None else q
    return RobotState(0.0, q, np.zeros(24), imu_quat_wxyz=quat, ft=ft)


@pytest.fixture(scope="module")
def stabilizer(model):
    return Stabilizer(model, DT, k_zmp=0.0)


def _run(stabilizer, model, state, periods):
    home = home_posture(model)
    store = estimate_of(model, state)
    stabilizer.reset(home, state, store)
    out, shifts = home, []
    for k in range(periods):
        out = stabilizer.update(home, state, Cycle(k * DT, DT, store=store))
        shifts.append(stabilizer.shift_m.copy())
    return out, np.array(shifts)


def test_a_robot_standing_as_commanded_gets_no_correction(stabilizer, model):
    out, shifts = _run(stabilizer, model, _state(model), 100)
    assert np.abs(shifts).max() < 1e-6
    assert np.abs(out - home_posture(model)).max() < 1e-5


def test_a_body_leaning_forward_is_moved_back_over_the_feet(stabilizer, model):
    home = home_posture(model)
    out, shifts = _run(stabilizer, model, _state(model, pitch_deg=1.0), 200)
    assert shifts[-1, 0] < -0.005  # the waist goes back
    assert abs(shifts[-1, 1]) < 1e-3
    # the command's CoM over the feet (torso upright) is behind the home posture's
    ref = stabilizer._com_in_feet(home)[0]
    moved = stabilizer._com_in_feet(out)[0]
    assert moved < ref - 0.004
    # and the soles stay flat under the upright torso: only the legs' pitch chain moved
    changed = np.nonzero(np.abs(out - home) > 1e-9)[0]
    names = {model.joint_names[i] for i in changed}
    assert names <= {"RHP", "RKN", "RAP", "LHP", "LKN", "LAP", "RHY", "LHY", "RHR", "LHR",
                     "RAR", "LAR"}


def test_the_correction_keeps_its_bounds(model):
    stabilizer = Stabilizer(model, DT, max_shift_m=0.01)
    _, shifts = _run(stabilizer, model, _state(model, pitch_deg=5.0), 600)
    rate = np.diff(shifts, axis=0) / DT
    accel = np.diff(rate, axis=0) / DT
    assert np.abs(shifts).max() <= 0.01 + 1e-12
    assert np.abs(rate).max() <= stabilizer.max_rate_m_s + 1e-9
    # (the last period before the bound may brake up to 10 % harder: whole periods)
    assert np.abs(accel).max() <= 1.1 * stabilizer.max_accel_m_s2
    assert stabilizer.hip_rad != 0.0  # saturated: the hips take the rest


def test_without_weight_on_the_feet_the_correction_returns(model):
    stabilizer = Stabilizer(model, DT, k_zmp=0.0)
    _, shifts = _run(stabilizer, model, _state(model, pitch_deg=1.0), 200)
    lifted = _state(model, pitch_deg=1.0)
    for foot in ("right-ankle", "left-ankle"):
        lifted.ft[foot] = np.zeros(6)
    home = home_posture(model)
    for k in range(600):
        stabilizer.update(home, lifted, Cycle(k * DT, DT, store=estimate_of(model, lifted)))
    assert abs(stabilizer.shift_m[0]) < 0.1 * abs(shifts[-1, 0])


@pytest.mark.parametrize("option", [{"k_com": -1.0}, {"k_zmp": -0.1}, {"max_shift_m": 0.0},
                                    {"max_accel_m_s2": float("nan")}, {"max_hip_rad": -0.1},
                                    {"com_offset_m": (0.2, 0.0)}, {"com_offset_m": (0.0, -0.3)},
                                    {"com_offset_m": (float("nan"), 0.0)}])
def test_bad_settings_are_refused(model, option):
    with pytest.raises(ConfigError):
        Stabilizer(model, DT, **option)


def test_a_com_reference_inside_the_feet_is_accepted(model):
    assert np.allclose(Stabilizer(model, DT, com_offset_m=(-0.03, 0.05)).com_offset_m,
                       (-0.03, 0.05))


def test_the_paper_mode_runs_without_the_stabilizer():
    assert "stabilizer" in SafetyProfile(stabilizer=True).order()
    assert "stabilizer" not in SafetyProfile().order()  # off by default, for now
    assert "stabilizer" not in SafetyProfile(balance_mode="paper", stabilizer=True).order()
    assert "stabilizer" not in SafetyProfile(balance=False, stabilizer=True).order()
