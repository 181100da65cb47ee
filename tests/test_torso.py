"""The measured torso pose (the estimation layer's floating base seen from the stance frame) and
the hand-goal correction that holds a tool in the stance frame while the body leans."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.dataflow import Store
from hubo_cli.estimation.base import FloatingBase
from hubo_cli.estimation.keys import (
    CONTACT,
    QUAT_WORLD_TORSO,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
)
from hubo_cli.geometry import rpy_to_quat_wxyz
from hubo_cli.kinematics.torso import (
    CorrectionSettings,
    MeasuredTorso,
    TorsoCorrection,
    torso_in_stance,
)
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import load_model
from hubo_cli.state import FT_SENSORS, RobotState

MODEL = load_model()
ARM = "right-arm"
SL = MODEL.limb_slice(ARM)
DT = MODEL.control_period_s
Q_ARM = np.array([-0.6444, -0.3933, 0.2581, -1.82, -1.9082, -0.3289])  # the bit ahead


@pytest.fixture(scope="module")
def body():
    return WholeBody(MODEL, {ARM: "drill"})


def _lean(body, q, pitch_rad=0.0, roll_rad=0.0):
    """T_S_N of a body leaning about its soles (a lean the leg joints do not show)."""
    return torso_in_stance(body, q, rpy_to_quat_wxyz(roll_rad, pitch_rad, 0.0))


def _working_pose(body):
    q = body.solve({}, body.q_home, lift_m=-0.03).q_rad
    q[SL] = Q_ARM
    return q


def test_the_home_posture_is_the_stance_frame_and_a_crouch_lowers_it(body):
    assert np.allclose(torso_in_stance(body, body.q_home), np.eye(4), atol=1e-9)
    assert np.allclose(torso_in_stance(body, body.q_home, [1.0, 0.0, 0.0, 0.0]), np.eye(4),
                       atol=1e-9)
    q = _working_pose(body)
    T = torso_in_stance(body, q)
    assert T[2, 3] == pytest.approx(-0.03, abs=1e-6)
    assert np.allclose(T[:3, :3], np.eye(3), atol=1e-9)


def test_an_imu_lean_tilts_the_torso_about_the_soles(body):
    q = body.q_home
    pitch = np.radians(1.0)  # leaning forward: the torso's z axis tips toward +x
    T = torso_in_stance(body, q, rpy_to_quat_wxyz(0.0, pitch, 0.0))
    height = -body.T_S_sole["right-leg"][2, 3]  # neck above the soles
    assert T[2, 0] == pytest.approx(-np.sin(pitch), abs=1e-9)
    assert T[0, 3] == pytest.approx(height * np.sin(pitch), rel=1e-6)  # the neck moves forward
    assert abs(T[1, 3]) < 1e-9


def _estimate(q, quats, gyro_rad_s=(0.0, 0.0, 0.0)):
    """The estimation layer's floating base (estimation/base.py) standing on both soles with
    the joints ``q`` through the attitudes ``quats``, one a period: the store after each."""
    base = FloatingBase(MODEL)
    store = Store()
    store[WRENCHES] = {name: np.array([0.0, 0.0, 250.0, 0.0, 0.0, 0.0]) for name in FT_SENSORS}
    store[CONTACT] = (True, True)
    for k, quat in enumerate(quats):
        store[QUAT_WORLD_TORSO] = np.asarray(quat, dtype=float)
        state = RobotState(k * DT, q, np.zeros_like(q), imu_gyro_rad_s=np.array(gyro_rad_s))
        (base.update if k else base.reset)(state, store)
        yield store


def test_the_measured_torso_is_the_estimates_seen_from_the_stance(body):
    """S is placed where the estimated soles stand; the estimate's lean then shows as the
    stance's kinematics give it (the body tipping about its soles), under any IMU yaw."""
    q = _working_pose(body)
    pitch = np.radians(1.0)
    for yaw_deg in (0.0, 30.0, -170.0):  # the IMU's yaw is no heading: it never shows
        torso = MeasuredTorso(body)
        quats = [rpy_to_quat_wxyz(0.0, 0.0, np.radians(yaw_deg)),
                 rpy_to_quat_wxyz(0.0, pitch, np.radians(yaw_deg))]
        T_S_N = [torso(store[T_WORLD_TORSO], store[T_WORLD_SOLES])
                 for store in _estimate(q, quats)]
        assert np.allclose(T_S_N[0], torso_in_stance(body, q), atol=1e-9)
        assert np.allclose(T_S_N[1], _lean(body, q, pitch_rad=pitch), atol=1e-9)


def test_the_imus_yaw_turning_does_not_turn_the_measured_torso(body):
    """A Hubo's IMU has no heading reference (the simulator's reported the true one): a yaw
    that drifts in the attitude with the gyro still and the feet planted turns nothing."""
    q = _working_pose(body)
    torso = MeasuredTorso(body)
    quats = [rpy_to_quat_wxyz(0.0, 0.0, np.radians(0.05 * k)) for k in range(200)]
    for store in _estimate(q, quats):
        T_S_N = torso(store[T_WORLD_TORSO], store[T_WORLD_SOLES])
    assert abs(np.arctan2(T_S_N[1, 0], T_S_N[0, 0])) < 1e-9
    assert np.allclose(T_S_N, torso_in_stance(body, q), atol=1e-9)


def test_the_stance_is_placed_once_and_a_garbled_estimate_keeps_the_last_pose(body):
    rng = np.random.default_rng(7)
    torso = MeasuredTorso(body)
    garbled = np.full((4, 4), np.nan)
    assert np.array_equal(torso(garbled, garbled[None].repeat(2, 0)), np.eye(4))  # nothing yet
    for _ in range(50):  # S anywhere on the floor, facing anywhere
        torso = MeasuredTorso(body)
        heading, x, y = rng.uniform(-np.pi, np.pi), *rng.uniform(-3.0, 3.0, 2)
        T_world_S = np.eye(4)
        T_world_S[:2, :2] = [[np.cos(heading), -np.sin(heading)],
                             [np.sin(heading), np.cos(heading)]]
        T_world_S[:2, 3] = x, y
        soles = np.array([T_world_S @ body.T_S_sole[leg] for leg in ("right-leg", "left-leg")])
        T_S_N = _lean(body, body.q_home, *rng.uniform(-0.05, 0.05, 2))
        assert np.allclose(torso(T_world_S @ T_S_N, soles), T_S_N, atol=1e-9)
        moved = soles.copy()
        moved[:, :3, 3] += 0.1  # the soles' estimate moves later (a step): S does not
        assert np.allclose(torso(T_world_S @ T_S_N, moved), T_S_N, atol=1e-9)
        assert np.allclose(torso(garbled, moved), T_S_N, atol=1e-9)


def test_a_leaning_torso_moves_the_arm_goal_so_the_bit_stays_in_the_stance_frame(body):
    q = _working_pose(body)
    goal = torso_in_stance(body, q) @ body.arms[ARM].fk(q[SL])
    T_S_N = _lean(body, q, pitch_rad=np.radians(1.0), roll_rad=np.radians(-0.5))  # measured
    correction = TorsoCorrection(body, (ARM,), DT)
    for _ in range(int(3.0 / DT)):  # 18 mm of lean at 10 mm/s, then the low-pass settles
        q_out = correction(q, T_S_N)
    uncorrected = (T_S_N @ body.arms[ARM].fk(q[SL]))[:3, 3]
    corrected = (T_S_N @ body.arms[ARM].fk(q_out[SL]))[:3, 3]
    assert np.linalg.norm(uncorrected - goal[:3, 3]) > 0.008  # the lean carries the bit 1 cm
    assert np.linalg.norm(corrected - goal[:3, 3]) < 2e-4
    # the right way: a forward lean carries the bit forward and down, so the arm pulls it back
    # and up in the neck frame
    bit_N_before = body.arms[ARM].fk(q[SL])[:3, 3]
    bit_N_after = body.arms[ARM].fk(q_out[SL])[:3, 3]
    assert bit_N_after[0] < bit_N_before[0] - 0.005
    assert np.allclose(q_out[:SL.start], q[:SL.start]) and np.allclose(q_out[SL.stop:],
                                                                       q[SL.stop:])


def test_the_correction_is_bounded_and_never_jumps(body):
    q = _working_pose(body)
    settings = CorrectionSettings()
    correction = TorsoCorrection(body, (ARM,), DT, settings)
    correction(q, _lean(body, q))
    lever = np.linalg.norm(body.arms[ARM].fk(q[SL])[:3, 3])
    max_step = (settings.max_speed_m_s + lever * settings.max_rate_rad_s) * DT
    bit = body.arms[ARM].fk(correction(q, _lean(body, q))[SL])[:3, 3]
    fallen = _lean(body, q, pitch_rad=np.radians(10.0))
    for _ in range(int(5.0 / DT)):  # a measured step of 10 degrees
        after = body.arms[ARM].fk(correction(q, fallen)[SL])[:3, 3]
        assert np.linalg.norm(after - bit) <= max_step * 1.05
        bit = after
    assert np.linalg.norm(correction.rotation_rad) == pytest.approx(settings.max_tilt_rad,
                                                                    abs=1e-8)
    assert np.linalg.norm(correction.offset_m) <= settings.max_offset_m + 1e-12


def test_a_garbled_measurement_leaves_the_correction_as_it_was(body):
    q = _working_pose(body)
    correction = TorsoCorrection(body, (ARM,), DT)
    for _ in range(100):
        correction(q, _lean(body, q, pitch_rad=np.radians(0.5)))
    before = correction.deviation()
    garbled = _lean(body, q)
    garbled[1, 2] = np.nan
    q_out = correction(q, garbled)
    assert np.all(np.isfinite(q_out)) and np.allclose(correction.deviation(), before)
    assert correction.weight[ARM] == 1.0


def _torso_in_stance_numpy(body, q, imu_quat_wxyz=None):
    """The former numpy formulation of torso_in_stance, as a reference for the compiled one."""
    from hubo_cli.geometry import quat_wxyz_to_matrix, rotation_exp, rotation_log

    def yaw(a):
        return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])

    R_legs, p_soles = [], []
    for leg in ("right-leg", "left-leg"):
        T_N_sole = body.legs[leg].fk(q[body.model.limb_slice(leg)])
        R_legs.append(body.T_S_sole[leg][:3, :3] @ T_N_sole[:3, :3].T)
        p_soles.append(T_N_sole[:3, 3])
    if imu_quat_wxyz is None:
        R = R_legs[0] @ rotation_exp(rotation_log(R_legs[0].T @ R_legs[1]) / 2)
    else:
        R_imu = quat_wxyz_to_matrix(imu_quat_wxyz)
        heading = np.mean([np.arctan2(R[1, 0], R[0, 0]) for R in R_legs])
        R = yaw(heading - np.arctan2(R_imu[1, 0], R_imu[0, 0])) @ R_imu
    p = (body.T_S_sole["right-leg"][:3, 3] + body.T_S_sole["left-leg"][:3, 3]
         - R @ (p_soles[0] + p_soles[1])) / 2
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def test_the_compiled_torso_pose_is_the_numpy_formula(body):
    """torso_in_stance runs compiled (kinematics/torso_kernels.py): the same numbers as the numpy
    formula for random leg postures (up to legs turned 3 rad apart, the rotation mean's half
    turn branch) and orientations."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        q = body.q_home + rng.normal(0.0, 0.3, body.q_home.shape)
        if rng.random() < 0.2:
            q[body.model.limb_slice("left-leg").start] += 3.0  # a hip yaw far off
        quat = rng.normal(size=4)
        for args in ((), (quat,)):
            assert np.allclose(torso_in_stance(body, q, *args),
                               _torso_in_stance_numpy(body, q, *args), rtol=0, atol=1e-12)


def test_the_compiled_correction_step_is_the_numpy_formula():
    """The correction's filter step runs compiled (kinematics/torso_kernels.py): the same
    offset, rotation, T_dev and inverse as the numpy formula, within and at its bounds."""
    import math

    from hubo_cli.geometry import rotation_exp, rotation_log
    from hubo_cli.kinematics.torso_kernels import follow_deviation

    def follow(now, raw, alpha, limit, max_step):
        wanted = now + alpha * (raw - now)
        if math.hypot(*wanted) > limit:
            wanted = wanted * (limit / math.hypot(*wanted))
        step = wanted - now
        if math.hypot(*step) > max_step:
            step = step * (max_step / math.hypot(*step))
        return now + step

    rng = np.random.default_rng(5)
    bounds = np.array([0.02, 5e-5, np.radians(2.0), np.radians(1.0) * 0.005])
    offset, rotation = np.zeros(3), np.zeros(3)
    for k in range(400):
        scale = 0.03 if k % 3 else 3e-4  # past the bounds, and within them
        T_cmd_inv, T_meas = np.eye(4), np.eye(4)
        T_meas[:3, :3] = rotation_exp(rng.normal(0.0, scale, 3))
        T_meas[:3, 3] = rng.normal(0.0, scale, 3)
        T_cmd_inv[:3, :3] = rotation_exp(rng.normal(0.0, 0.01, 3))
        raw = T_cmd_inv @ T_meas
        offset_ref = follow(offset, raw[:3, 3], 0.05, bounds[0], bounds[1])
        rotation_ref = follow(rotation, rotation_log(raw[:3, :3]), 0.05, bounds[2], bounds[3])
        T_dev, T_dev_inv = np.empty((4, 4)), np.empty((4, 4))
        follow_deviation(T_cmd_inv, T_meas, offset, rotation, 0.05, bounds, T_dev, T_dev_inv)
        assert np.allclose(offset, offset_ref, rtol=0, atol=1e-15)
        assert np.allclose(rotation, rotation_ref, rtol=0, atol=1e-15)
        assert np.allclose(T_dev[:3, :3], rotation_exp(rotation_ref), rtol=0, atol=1e-14)
        assert np.allclose(T_dev @ T_dev_inv, np.eye(4), rtol=0, atol=1e-14)
        offset, rotation = offset_ref, rotation_ref  # the next step from the same state


def test_at_a_wrist_limit_the_correction_holds_the_bit_and_lets_its_orientation_give(body):
    # the wrist pitch 5 mrad from its limit (the slot's first pose stands 39 mrad from it): a
    # forward lean asks for more than that, so the exact corrected goal is out of the limits
    limb = body.arms[ARM]
    q = _working_pose(body)
    q[SL.stop - 1] = limb.lower_rad[5] + 0.005
    goal = torso_in_stance(body, q) @ limb.fk(q[SL])
    T_S_N = _lean(body, q, pitch_rad=np.radians(1.0), roll_rad=np.radians(-0.5))
    fading = CorrectionSettings(nearest_max_position_m=0.0)  # the former rule: fade out
    for settings, holds in ((CorrectionSettings(), True), (fading, False)):
        correction = TorsoCorrection(body, (ARM,), DT, settings)
        for _ in range(int(3.0 / DT)):
            q_out = correction(q, T_S_N)
        T_S_E = T_S_N @ limb.fk(q_out[SL])
        assert not limb.solve(np.linalg.inv(correction.deviation()) @ limb.fk(q[SL]),
                              q[SL]).exact
        assert np.all(q_out[SL] >= limb.lower_rad - 1e-9)
        error_m = np.linalg.norm(T_S_E[:3, 3] - goal[:3, 3])
        if holds:
            assert correction.weight[ARM] == 1.0 and error_m < 2e-4
            tilt = np.arccos(np.clip((np.trace(goal[:3, :3].T @ T_S_E[:3, :3]) - 1) / 2, -1, 1))
            assert tilt <= settings.nearest_max_rotation_rad
        else:
            assert correction.weight[ARM] < 0.9 and error_m > 1e-3
