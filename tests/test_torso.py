"""The measured torso pose (leg encoders + IMU) and the hand-goal correction that holds a tool in
the stance frame while the body leans."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.geometry import matrix_to_quat_wxyz, rotation_exp, rpy_to_matrix, rpy_to_quat_wxyz
from hubo_cli.kinematics.torso import (
    IMU_HEADING_TIME_CONSTANT_S,
    CorrectionSettings,
    TorsoCorrection,
    TorsoEstimator,
    torso_in_stance,
)
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import load_model
from hubo_cli.state import RobotState

MODEL = load_model()
ARM = "right-arm"
SL = MODEL.limb_slice(ARM)
DT = MODEL.control_period_s
Q_ARM = np.array([-0.6444, -0.3933, 0.2581, -1.82, -1.9082, -0.3289])  # the bit ahead


@pytest.fixture(scope="module")
def body():
    return WholeBody(MODEL, {ARM: "drill"})


def _state(q, pitch_rad=0.0, roll_rad=0.0, t_s=0.0):
    return RobotState(t_s, q, np.zeros_like(q), imu_quat_wxyz=rpy_to_quat_wxyz(roll_rad,
                                                                              pitch_rad, 0.0))


def _measured(state):
    """A state and the attitude the estimate gives with it (here the IMU's reading)."""
    return state, state.imu_quat_wxyz


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


def test_a_leaning_torso_moves_the_arm_goal_so_the_bit_stays_in_the_stance_frame(body):
    q = _working_pose(body)
    goal = torso_in_stance(body, q) @ body.arms[ARM].fk(q[SL])
    lean = _state(q, pitch_rad=np.radians(1.0), roll_rad=np.radians(-0.5))
    correction = TorsoCorrection(body, (ARM,), DT)
    for _ in range(int(3.0 / DT)):  # 18 mm of lean at 10 mm/s, then the low-pass settles
        q_out = correction(q, lean, lean.imu_quat_wxyz)
    T_S_N = torso_in_stance(body, q, lean.imu_quat_wxyz)  # what the robot measures
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
    correction(q, *_measured(_state(q)))
    lever = np.linalg.norm(body.arms[ARM].fk(q[SL])[:3, 3])
    max_step = (settings.max_speed_m_s + lever * settings.max_rate_rad_s) * DT
    bit = body.arms[ARM].fk(correction(q, *_measured(_state(q)))[SL])[:3, 3]
    for k in range(int(5.0 / DT)):  # an IMU step of 10 degrees
        fallen = _state(q, pitch_rad=np.radians(10.0), t_s=(k + 1) * DT)
        after = body.arms[ARM].fk(correction(q, *_measured(fallen))[SL])[:3, 3]
        assert np.linalg.norm(after - bit) <= max_step * 1.05
        bit = after
    assert np.linalg.norm(correction.rotation_rad) == pytest.approx(settings.max_tilt_rad,
                                                                    abs=1e-8)
    assert np.linalg.norm(correction.offset_m) <= settings.max_offset_m + 1e-12


def test_the_imu_heading_is_referenced_at_the_first_measurement(body):
    """The feet twisting on the floor turn the body with no hip-yaw motion: the IMU sees it,
    relative to its heading when the estimator first measured, through its low-pass."""
    q = _working_pose(body)
    estimator = TorsoEstimator(body)

    def heading_deg(yaw_deg, t_s):
        state = RobotState(t_s, q, np.zeros_like(q), imu_quat_wxyz=rpy_to_quat_wxyz(
            0.0, 0.0, np.radians(yaw_deg)))
        T = estimator(state, state.imu_quat_wxyz)
        return np.degrees(np.arctan2(T[1, 0], T[0, 0]))

    assert heading_deg(30.0, 0.0) == pytest.approx(0.0, abs=1e-9)  # the stance's heading
    tau = IMU_HEADING_TIME_CONSTANT_S
    assert heading_deg(30.5, tau) == pytest.approx(0.5 * (1 - np.exp(-1.0)), abs=1e-6)
    assert heading_deg(30.5, 8 * tau) == pytest.approx(0.5, abs=1e-3)


def test_the_estimator_takes_a_slow_lean_from_the_imu_and_not_its_noise(body):
    """A lean the leg joints do not show (a tilted floor, soft soles) is measured whole once
    the IMU's low-pass has settled; the IMU's per-reading noise (0.2 deg, as on the perturbed
    robots) moves the measured bit a fraction of what the raw IMU orientation would."""
    q = _working_pose(body)
    rng = np.random.default_rng(3)
    estimator = TorsoEstimator(body)
    T_N_E = body.arms[ARM].fk(q[SL])
    R_lean = rpy_to_matrix(np.radians(-0.3), np.radians(0.5), 0.0)
    lean = matrix_to_quat_wxyz(R_lean)
    fused, raw = [], []
    for k in range(int(5.0 / DT)):
        imu = matrix_to_quat_wxyz(rotation_exp(rng.normal(0.0, np.radians(0.2), 3)) @ R_lean)
        state = RobotState(k * DT, q, np.zeros_like(q), imu_quat_wxyz=imu)
        fused.append((estimator(state, state.imu_quat_wxyz) @ T_N_E)[:3, 3])
        raw.append((torso_in_stance(body, q, imu, estimator.imu_heading_rad) @ T_N_E)[:3, 3])
    fused, raw = np.array(fused[-400:]), np.array(raw[-400:])  # the last 2 s
    # the heading is referenced at the first (noisy) reading, the IMU's only heading reference
    truth = (torso_in_stance(body, q, lean, estimator.imu_heading_rad) @ T_N_E)[:3, 3]
    assert np.linalg.norm(fused.mean(axis=0) - truth) < 3e-4  # the lean is measured whole
    assert np.linalg.norm(truth - (T_N_E[:3, 3])) > 5e-3      # (it moves the bit 5+ mm)
    spread_fused = np.linalg.norm(fused.std(axis=0))
    spread_raw = np.linalg.norm(raw.std(axis=0))
    assert spread_raw > 3e-3           # the raw IMU: millimetres from period to period
    assert spread_fused < spread_raw / 5


def test_a_garbled_measurement_leaves_the_correction_as_it_was(body):
    q = _working_pose(body)
    correction = TorsoCorrection(body, (ARM,), DT)
    for _ in range(100):
        correction(q, *_measured(_state(q, pitch_rad=np.radians(0.5))))
    before = correction.deviation()
    garbled = _state(q)
    garbled.imu_quat_wxyz = np.array([np.nan, 0.0, 0.0, 0.0])
    q_out = correction(q, garbled, garbled.imu_quat_wxyz)
    assert np.all(np.isfinite(q_out)) and np.allclose(correction.deviation(), before)
    assert correction.weight[ARM] == 1.0


def _torso_in_stance_numpy(body, q, imu_quat_wxyz=None, imu_heading_rad=None):
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
        if imu_heading_rad is None:
            heading = np.mean([np.arctan2(R[1, 0], R[0, 0]) for R in R_legs])
            R = yaw(heading - np.arctan2(R_imu[1, 0], R_imu[0, 0])) @ R_imu
        else:
            R = yaw(-imu_heading_rad) @ R_imu
    p = (body.T_S_sole["right-leg"][:3, 3] + body.T_S_sole["left-leg"][:3, 3]
         - R @ (p_soles[0] + p_soles[1])) / 2
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def test_the_compiled_torso_pose_is_the_numpy_formula(body):
    """torso_in_stance runs compiled (kinematics/torso_kernels.py): the same numbers as the numpy
    formula for random leg postures (up to legs turned 3 rad apart, the rotation mean's half
    turn branch), IMU orientations and headings."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        q = body.q_home + rng.normal(0.0, 0.3, body.q_home.shape)
        if rng.random() < 0.2:
            q[body.model.limb_slice("left-leg").start] += 3.0  # a hip yaw far off
        quat = rng.normal(size=4)
        heading = float(rng.uniform(-np.pi, np.pi))
        for args in ((), (quat,), (quat, heading)):
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
    lean = _state(q, pitch_rad=np.radians(1.0), roll_rad=np.radians(-0.5))
    T_S_N = torso_in_stance(body, q, lean.imu_quat_wxyz)
    fading = CorrectionSettings(nearest_max_position_m=0.0)  # the former rule: fade out
    for settings, holds in ((CorrectionSettings(), True), (fading, False)):
        correction = TorsoCorrection(body, (ARM,), DT, settings)
        for _ in range(int(3.0 / DT)):
            q_out = correction(q, lean, lean.imu_quat_wxyz)
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


class _EstimatorNumpy:
    """The former numpy formulation of TorsoEstimator, as a reference for the compiled one."""

    def __init__(self, body):
        self.body, self.heading, self.offset, self.t_s = body, None, None, 0.0
        self.tau = np.array([0.5, 0.5, IMU_HEADING_TIME_CONSTANT_S])

    def __call__(self, state):
        from hubo_cli.geometry import quat_wxyz_to_matrix, rotation_log

        def yaw(a):
            return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0],
                             [0.0, 0.0, 1.0]])

        body, q = self.body, state.q_rad
        R_legs, p_soles = [], []
        for leg in ("right-leg", "left-leg"):
            T_N_sole = body.legs[leg].fk(q[body.model.limb_slice(leg)])
            R_legs.append(body.T_S_sole[leg][:3, :3] @ T_N_sole[:3, :3].T)
            p_soles.append(T_N_sole[:3, 3])
        R_enc = R_legs[0] @ rotation_exp(rotation_log(R_legs[0].T @ R_legs[1]) / 2)
        if np.all(np.isfinite(state.imu_quat_wxyz)):
            R_imu = quat_wxyz_to_matrix(state.imu_quat_wxyz)
            if self.heading is None:
                legs = np.mean([np.arctan2(R[1, 0], R[0, 0]) for R in R_legs])
                self.heading = np.arctan2(R_imu[1, 0], R_imu[0, 0]) - legs
            alpha = 1.0 if self.offset is None else -np.expm1(
                -max(0.0, state.time_s - self.t_s) / self.tau)
            offset = np.zeros(3) if self.offset is None else self.offset
            raw = rotation_log(R_enc.T @ yaw(-self.heading) @ R_imu)
            self.offset, self.t_s = offset + alpha * (raw - offset), state.time_s
        R = R_enc @ rotation_exp(np.zeros(3) if self.offset is None else self.offset)
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = (body.T_S_sole["right-leg"][:3, 3] + body.T_S_sole["left-leg"][:3, 3]
                    - R @ (p_soles[0] + p_soles[1])) / 2
        return T


def test_the_compiled_estimator_is_the_numpy_formula(body):
    """TorsoEstimator runs as one compiled call a period (kinematics/torso_kernels.py): the same
    poses and filter state as the numpy formula over a run of leaning, swaying readings with
    garbled IMU readings, an uneven period and a second call with the same reading."""
    rng = np.random.default_rng(11)
    compiled, reference = TorsoEstimator(body), _EstimatorNumpy(body)
    q0 = _working_pose(body)
    t_s = 0.0
    for k in range(600):
        q = q0 + rng.normal(0.0, 0.05, q0.shape)
        imu = rpy_to_quat_wxyz(*rng.normal(0.0, 0.05, 3)) * rng.uniform(0.9, 1.1)
        if k % 97 == 3:
            imu = np.array([np.nan, 0.0, 0.0, 0.0])
        t_s += DT * (3 if k % 50 == 7 else 1)
        state = RobotState(t_s, q, np.zeros_like(q), imu_quat_wxyz=imu)
        T_ref = reference(state)
        assert np.allclose(compiled(state, imu), T_ref, rtol=0, atol=1e-12)
        assert np.allclose(compiled(state, imu), T_ref, rtol=0, atol=1e-12)  # the same reading
    assert compiled.imu_heading_rad == pytest.approx(reference.heading, abs=1e-12)
    assert np.allclose(compiled.imu_offset_rad, reference.offset, rtol=0, atol=1e-12)
    assert np.linalg.norm(reference.offset) > 1e-3  # the IMU's part is not trivial
