"""The ideal driver's ankle sensors read a robot standing still (hubo_cli/drivers/floor.py):
the soles on the floor carry the whole weight with their total centre of pressure under the
centre of mass, a foot in the air reads its own weight alone. References: pinocchio's
centerOfMass, the legs' FK and the hanging readings of main (what the sensors read with
nothing touching them)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hubo_cli.drivers.floor import FLOOR_BAND_M
from hubo_cli.drivers.registry import make_driver
from hubo_cli.estimation.wrenches import (
    hanging_readings,
    measured_mask,
    sensor_chains,
    sensor_loads,
)
from hubo_cli.geometry import quat_wxyz_to_matrix, rpy_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import ARMS, LEGS, load_model
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture
from hubo_cli.state import ANKLE_SENSORS, FT_SENSORS, GRAVITY_M_S2

MODEL = load_model()
LEG = {name: (Limb(MODEL, name), MODEL.limb_slice(name)) for name in LEGS}
ROBOT = load_pin_robot(MODEL, floating=True)
DATA = ROBOT.model.createData()
WEIGHT_N = GRAVITY_M_S2 * sum(inertia.mass for inertia in ROBOT.model.inertias)
TOL_N = 1e-9 * WEIGHT_N  # rounding: the kernel and pinocchio add the same masses
TOL_M = 1e-9


def _hanging(q: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """What the sensors read with nothing touching them (the ideal driver before this)."""
    masses, coms = sensor_loads(MODEL, False)
    out = np.empty((len(FT_SENSORS), 6))
    hanging_readings(q, quat, *sensor_chains(MODEL), masses, coms, GRAVITY_M_S2,
                     measured_mask(), out)
    return out


def _standing(q: np.ndarray):
    """The driver's state in ``q``, the world rotation, the soles' world poses (right,
    left: rotation's last column and origin), the floor's part of each ankle reading and the
    CoM (world axes, from the torso's origin)."""
    state = make_driver("ideal", MODEL).start(q)
    R = quat_wxyz_to_matrix(state.imu_quat_wxyz)
    T_world_torso = np.eye(4)
    T_world_torso[:3, :3] = R
    com = pin.centerOfMass(ROBOT.model, DATA, ROBOT.configuration(state.q_rad, T_world_torso))
    hanging = _hanging(state.q_rad, state.imu_quat_wxyz)
    soles, floor = [], []
    for sensor, leg in zip(ANKLE_SENSORS, LEGS, strict=True):
        limb, part = LEG[leg]
        soles.append(T_world_torso @ limb.fk(state.q_rad[part]))
        floor.append(state.ft[sensor] - hanging[FT_SENSORS.index(sensor)])
    return state, soles, floor, com, hanging


def _cop_world(T_world_sole: np.ndarray, wrench: np.ndarray) -> np.ndarray:
    """A sole's centre of pressure in the world's xy from its sensor's f_z, m_x, m_y."""
    fz, mx, my = wrench[2], wrench[3], wrench[4]
    return (T_world_sole @ np.array([-my / fz, mx / fz, 0.0, 1.0]))[:2]


def _assert_carried(soles, floor, com, loaded):
    """The loaded soles carry the weight, their total CoP under the CoM; the others nothing."""
    total, moment = 0.0, np.zeros(2)
    for T, w, down in zip(soles, floor, loaded, strict=True):
        if not down:
            assert np.all(w == 0.0)
            continue
        assert abs(T[2, 2] - 1.0) < 1e-12  # flat: the floor's push is the sole's f_z
        assert w[2] > 0.0
        total += w[2]
        moment += w[2] * _cop_world(T, w)
    assert abs(total - WEIGHT_N) < TOL_N
    assert np.allclose(moment / total, com[:2], rtol=0.0, atol=TOL_M)


def test_home_posture_both_soles_carry_the_weight_under_the_com():
    q = home_posture(MODEL)
    _, soles, floor, com, _ = _standing(q)
    _assert_carried(soles, floor, com, (True, True))
    # the rule: each sole's CoP the same offset from its centre, inside its polygon
    centre = np.array([MODEL.feet.forward_m, 0.0, 0.0, 1.0])
    offsets = [_cop_world(T, w) - (T @ centre)[:2] for T, w in zip(soles, floor, strict=True)]
    assert np.allclose(offsets[0], offsets[1], rtol=0.0, atol=TOL_M)
    half = np.array([MODEL.feet.length_m, MODEL.feet.width_m]) / 2
    assert np.all(np.abs(offsets[0]) < half)
    # nearly symmetric: each sole carries about half (the arms' small asymmetry)
    assert abs(floor[0][2] - floor[1][2]) < 0.05 * WEIGHT_N


@settings(max_examples=20, deadline=None, derandomize=True)
@given(st.lists(st.floats(-0.15, 0.15), min_size=6, max_size=6),
       st.floats(-0.05, 0.05), st.floats(-0.04, 0.06), st.floats(-0.2, 0.2),
       st.lists(st.floats(0.0, 1.0), min_size=12, max_size=12))
def test_both_soles_down_carry_the_weight_under_the_com(dq_right, dx, dy, yaw, arms):
    """Random right-leg joints, the left sole placed flat beside it (random step, width and
    turn; the leg's IK), random arms: the CoM anywhere, the weight always under it."""
    q = home_posture(MODEL)
    right, right_part = LEG["right-leg"]
    left, left_part = LEG["left-leg"]
    T_N_right0, T_N_left0 = right.fk(q[right_part]), left.fk(q[left_part])
    T_right_left = np.linalg.inv(T_N_right0) @ T_N_left0
    q[right_part] = np.clip(q[right_part] + dq_right, right.lower_rad, right.upper_rad)
    step = np.eye(4)
    step[:3, :3] = rpy_to_matrix(0.0, 0.0, yaw)
    step[:3, 3] = (dx, dy, 0.0)
    result = left.solve(right.fk(q[right_part]) @ T_right_left @ step, q[left_part])
    assume(result.status == "exact" and result.position_error_m < 1e-9)  # in reach
    q[left_part] = result.q_rad
    for arm, fractions in zip(ARMS, (arms[:6], arms[6:]), strict=True):
        part = MODEL.limb_slice(arm)
        q[part] = MODEL.lower_rad[part] + np.array(fractions) * (
            MODEL.upper_rad[part] - MODEL.lower_rad[part])
    _, soles, floor, com, _ = _standing(q)
    _assert_carried(soles, floor, com, (True, True))


@pytest.mark.parametrize("lifted", [0, 1])
def test_a_foot_in_the_air_reads_its_weight_alone(lifted):
    q = home_posture(MODEL)
    limb, part = LEG[LEGS[lifted]]
    q[part] = q[part] + np.array([0.0, 0.0, -0.2, 0.4, -0.2, 0.0])  # hip, knee, ankle pitch
    state, soles, floor, com, hanging = _standing(q)
    assert soles[lifted][2, 3] - soles[1 - lifted][2, 3] > 4 * FLOOR_BAND_M
    k = FT_SENSORS.index(ANKLE_SENSORS[lifted])
    assert np.array_equal(state.ft[ANKLE_SENSORS[lifted]], hanging[k])
    assert hanging[k][2] < 0.0  # the foot's weight hangs on it
    _assert_carried(soles, floor, com, (lifted == 1, lifted == 0))
    for sensor in FT_SENSORS[:2]:  # the hands read their weight as before
        assert np.array_equal(state.ft[sensor], hanging[FT_SENSORS.index(sensor)])

