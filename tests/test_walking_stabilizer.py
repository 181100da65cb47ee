"""The walking stabilizer's feedback laws and the second preview stage (no simulator)."""

import numpy as np
import pytest

from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model
from hubo_cli.state import FT_SENSORS, RobotState, Truth
from hubo_cli.walking.body import WalkingBody, multibody_zmp, walking_posture
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps
from hubo_cli.walking.gait import make_gait
from hubo_cli.walking.params import walking_params
from hubo_cli.walking.stabilizer import SoleDamper, StabilizerGains, TorsoOffset, Touchdown
from hubo_cli.walking.target import (
    WalkTarget,
    imu_z_axis,
    measured_zmp,
    rigid_inverse,
    tilt_between,
)

DT = 0.005
SOLE = (-0.09, 0.13, -0.065, 0.065)  # the sole box in its own frame (m)


def wrench_at(px, py, fz=380.0):
    """The ground's wrench on a sole whose centre of pressure is (px, py) in the sole frame."""
    return np.array([0.0, 0.0, fz, fz * py, -fz * px, 0.0])


def test_sole_turns_away_from_the_edge_it_presses_and_returns():
    gains = StabilizerGains()
    damper = SoleDamper(gains, SOLE, DT)
    for _ in range(20):  # on the toe, on the inner (left) edge
        delta = damper.update(wrench_at(0.13, 0.065)).copy()
    assert delta[1] < -0.001  # pitch: toe up
    assert delta[0] > 0.001   # roll: left edge up
    pressed = np.abs(delta).max()
    for _ in range(int(3 * gains.time_constant_s / DT)):  # centred: only the leak acts
        delta = damper.update(wrench_at(0.02, 0.0))
    assert np.abs(delta).max() < 0.1 * pressed
    damper.update(wrench_at(0.13, 0.065))
    for _ in range(int(5 * gains.swing_time_constant_s / DT)):  # unloaded: back to the pattern
        delta = damper.update(np.zeros(6))
    assert np.abs(delta).max() < 1e-4


def test_sole_inside_the_safe_region_is_left_alone():
    damper = SoleDamper(StabilizerGains(), SOLE, DT)
    for _ in range(50):
        delta = damper.update(wrench_at(0.05, -0.03))
    assert np.abs(delta).max() == 0.0


def test_an_early_touchdown_stops_the_descent_then_fades():
    gains = StabilizerGains()
    touchdown = Touchdown(gains, DT)
    assert touchdown.update(True, 0.004, 0.0) == 0.0  # in the air: the pattern
    assert touchdown.update(True, 0.003, 300.0) == pytest.approx(0.0)  # touched at 3 mm
    for height in (0.002, 0.001, 0.0):  # the pattern goes on down, the sole stays
        lift = touchdown.update(True, height, 300.0)
    assert lift == pytest.approx(0.003)
    assert touchdown.update(True, 0.02, 300.0) < 0.003  # high in the swing: no touchdown
    for _ in range(int(5 * gains.touchdown_time_constant_s / DT)):  # on the ground: fades
        lift = touchdown.update(False, 0.0, 300.0)
    assert lift < 0.01 * 0.003


def test_torso_offset_pulls_the_com_back_and_is_bounded():
    gains = StabilizerGains()
    torso = TorsoOffset(gains, DT)
    offset = torso.update(None, np.zeros(2), np.array([0.01, 0.0]), np.zeros(2))
    assert offset[0] < 0.0  # the CoM ahead of the pattern: the torso moves back
    for _ in range(2000):
        offset = torso.update(np.array([1.0, 1.0]), np.zeros(2), np.zeros(2), np.zeros(2))
    assert np.hypot(*offset) == pytest.approx(gains.max_offset_m)
    with pytest.raises(ConfigError):
        StabilizerGains(k_com=float("nan"))


@pytest.mark.physical
def test_second_preview_stage_cancels_the_swing_legs_zmp():
    """The legs' and torso's momentum move the multi-body ZMP tens of mm from the reference;
    after the second preview stage it stays within 16 mm (away from the standing ends).
    Measured on both code paths (AVX-512 / portable): 44.9 mm before (1.8x the 25 mm), 10.1 mm
    after (bound 1.58x)."""
    model = load_model(limits="walking")
    params = walking_params(model)
    w = params.step_width_m / 2
    right, left = Footstep("right", 0.0, -w, 0.0), Footstep("left", 0.0, w, 0.0)
    steps = plan_footsteps(right, left, Stance(0.4, 0.0, 0.0), params)
    gait = make_gait(right, left, steps, params, DT, 0.59, 0.0, 0.02)
    q_start, T_world_neck = walking_posture(model, params.step_width_m, params.crouch_m)
    body = WalkingBody(model, q_start, T_world_neck, params.lean_rad_per_m)
    inner = slice(int(1.0 / DT), -int(1.0 / DT))
    before = multibody_zmp(body, body.solve(gait), 0.0, DT) - gait.zmp_ref_m
    _, plan = body.solve_corrected(gait, 0.0, params.preview_s, params.zmp_weight,
                                   params.jerk_weight)
    after = multibody_zmp(body, plan, 0.0, DT) - gait.zmp_ref_m
    assert np.abs(before[inner]).max() > 0.025
    assert np.abs(after[inner]).max() < 0.016


def test_per_period_geometry_in_floats_matches_numpy():
    """The stabilizer's per-period helpers (plain floats, for the period budget) agree with
    the matrix formulas: the tilt turns one axis onto the other and is a rotation, the IMU's
    z axis is its rotation's third column, the rigid inverse is the inverse."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        a, b = rng.normal(size=3), rng.normal(size=3)
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        columns = np.zeros((3, 3))  # the kernels take a column of a rotation, as the target
        columns[:, 2] = a           # passes it: one compiled signature, not two
        R = tilt_between(columns[:, 2], b)
        assert np.allclose(R @ a, b, atol=1e-12) and np.allclose(R @ R.T, np.eye(3), atol=1e-12)
        q = rng.normal(size=4)
        assert np.allclose(imu_z_axis(q), quat_wxyz_to_matrix(q / np.linalg.norm(q))[:, 2],
                           atol=1e-12)
        T = np.eye(4)
        T[:3, :3] = quat_wxyz_to_matrix(q / np.linalg.norm(q))
        T[:3, 3] = rng.normal(size=3)
        assert np.allclose(rigid_inverse(T), np.linalg.inv(T), atol=1e-12)
        assert np.allclose(rigid_inverse(np.array([T, np.eye(4)]))[0], np.linalg.inv(T),
                           atol=1e-12)


def test_measured_zmp_weights_the_soles_and_measures_the_hull():
    """Two soles 0.24 m apart, the right one carrying three quarters at its centre: the ZMP
    lies a quarter of the way to the left sole, inside their hull by the distance to its
    nearest edge (the soles' toe line, 0.11 m ahead of the centre with forward_m 0)."""
    corners = np.array([[-0.11, -0.065, 0.0], [0.11, -0.065, 0.0], [0.11, 0.065, 0.0],
                        [-0.11, 0.065, 0.0]])
    poses = np.array([np.eye(4), np.eye(4)])  # right, left
    poses[:, :2, 3] = (1.0, -0.12), (1.0, 0.12)
    zmp, outside = measured_zmp(poses, np.array([wrench_at(0.0, 0.0, 300.0),
                                                 wrench_at(0.0, 0.0, 100.0)]), corners)
    assert zmp == pytest.approx([1.0, -0.06], abs=1e-12)
    assert outside == pytest.approx(-0.11, abs=1e-12)
    none, far = measured_zmp(poses, np.array([wrench_at(0.0, 0.0, 5.0),
                                              wrench_at(0.0, 0.0, 5.0)]), corners)
    assert none is None and far == float("inf")


def test_one_loaded_sole_measures_against_its_own_outline():
    """One loaded sole: the hull is the sole itself (its corners counter-clockwise), a CoP 5 mm
    inside its outer edge lies 5 mm inside, one on that edge is not inside."""
    corners = np.array([[-0.11, -0.065, 0.0], [0.11, -0.065, 0.0], [0.11, 0.065, 0.0],
                        [-0.11, 0.065, 0.0]])
    poses = np.array([np.eye(4), np.eye(4)])  # right, left
    poses[1, 1, 3] = 0.24
    idle = wrench_at(0.0, 0.0, 0.0)
    zmp, outside = measured_zmp(poses, np.array([wrench_at(0.0, -0.06, 300.0), idle]), corners)
    assert zmp == pytest.approx([0.0, -0.06], abs=1e-12)
    assert outside == pytest.approx(-0.005, abs=1e-9)
    _, on_edge = measured_zmp(poses, np.array([wrench_at(0.0, -0.065, 300.0), idle]), corners)
    assert on_edge > -0.001


def test_contact_wrenches_average_a_jumping_reading_and_follow_a_landing():
    """A sole's F_z jumping between 0 and 760 N every period (what the simulated sensor reads
    at transitions) averages to about 380 N and keeps the sole in contact; a landing from 0 to
    380 N is followed at 5 Hz: past 25 N within 2 periods, 63 % within about 32 ms."""
    from hubo_cli.walking.target import ContactWrenches

    wrenches = ContactWrenches(DT)
    unread = np.full(6, np.nan)
    readings = []
    for k in range(200):
        filtered = wrenches.update(np.array([wrench_at(0.01, 0.0, 760.0 * (k % 2)), unread]))
        readings.append(filtered[0, 2])
    assert np.isnan(filtered[1]).all()  # a sole never read stays unknown
    assert min(readings[100:]) > 300.0 and max(readings[100:]) < 460.0
    landing = ContactWrenches(DT)
    landing.update(np.array([unread, wrench_at(0.0, 0.0, 0.0)]))
    fz = [landing.update(np.array([unread, wrench_at(0.0, 0.0, 380.0)]))[1, 2]
          for _ in range(12)]
    assert fz[1] > 25.0
    assert 0.5 * 380.0 < fz[5] < 0.75 * 380.0


class StandingWorld:
    """The soles and the torso of the walking posture, where a simulator reports them; the
    right sole turned by ``right_yaw_rad`` about its vertical."""

    def __init__(self, model, q_rad, T_world_neck, right_yaw_rad=0.0):
        self.poses = {"torso": T_world_neck}
        for frame, name in (("right_sole", "right-leg"), ("left_sole", "left-leg")):
            T_neck_sole = Limb(model, name).fk(q_rad[model.limb_slice(name)])
            self.poses[frame] = T_world_neck @ T_neck_sole
        turn = np.eye(4)
        c, s = np.cos(right_yaw_rad), np.sin(right_yaw_rad)
        turn[:2, :2] = ((c, -s), (s, c))
        self.poses["right_sole"] = self.poses["right_sole"] @ turn

    def frame_pose(self, frame):
        return self.poses[frame].copy()


@pytest.mark.physical
def test_torso_offset_reaches_the_legs_with_the_hip_yaw_at_its_limit():
    """Standing with the feet ahead, each hip yaw sits at its joint limit (0): with the feet
    toed in by a hundredth of a degree, as the simulator reads them after a few steps, the
    legs' IK reaches the soles' goals only capped to the limits (a few microradians off), and
    the torso offset must still move the legs. A torso that the IMU reads 1 deg pitched
    forward puts the measured CoM ahead of the pattern's; the offset moves the torso back, so
    both soles move forward in its frame by the offset (and sideways by its part from the
    ZMP's feedback). Before, the offset grew while the legs never followed it."""
    model = load_model("as-built", "walking")
    params = walking_params(model)
    q_start, T_world_neck = walking_posture(model, params.step_width_m, params.crouch_m)
    target = WalkTarget(model, params, (0.3, 0.0, 0.0), q_start, T_world_neck, corrections=0,
                        stabilizer=StabilizerGains())
    target.attach(StandingWorld(model, q_start, T_world_neck, right_yaw_rad=1e-4), [],
                  Store())
    pitch = np.radians(1.0)
    ft = {name: np.zeros(6) for name in FT_SENSORS}
    ft["right-ankle"] = ft["left-ankle"] = wrench_at(0.0, 0.0, 190.0)
    for k in range(60):  # 0.3 s of the start's double support, the robot on the pattern
        q_plan = target.plan.q_rad[k]
        state = RobotState(time_s=k * DT, q_rad=q_plan.copy(), dq_rad_s=np.zeros_like(q_plan),
                           imu_quat_wxyz=np.array([np.cos(pitch / 2), 0.0, np.sin(pitch / 2),
                                                   0.0]),
                           ft=ft, truth=Truth(T_world_neck, (True, True),
                                              np.array([1.0, 0.0, 0.0, 0.0])))
        q, _ = target(k * DT, state)
    offset = target.torso_offset.offset_m
    # -14.2 mm on both code paths (AVX-512 / portable): 2.8x; the soles follow it equally on both
    assert offset[0] < -0.005  # pulled back by more than 5 mm
    for name in ("right-leg", "left-leg"):
        leg, part = Limb(model, name), model.limb_slice(name)
        moved = leg.fk(q[part])[:3, 3] - leg.fk(q_plan[part])[:3, 3]
        assert moved[:2] == pytest.approx(-offset, abs=0.001)


def test_the_compiled_com_offset_from_a_sole_is_the_matrix_formula(model):
    """``_com_from_sole`` (one compiled call a period) against the same quantity built from the
    leg's FK and matrix products: R = tilt(plan z -> IMU z) @ R_plan, then R @ (c - p_sole)."""
    from hubo_cli.geometry import rpy_to_matrix
    from hubo_cli.kinematics.limb import Limb
    from hubo_cli.walking.target import _com_from_sole

    rng = np.random.default_rng(7)
    for leg in ("right-leg", "left-leg"):
        limb = Limb(model, leg)
        for _ in range(200):
            q_leg = limb.random_q(rng)
            com_in_neck = rng.uniform(-0.3, 0.3, 3)
            T_plan = np.eye(4)  # the plan's pose: the kernel gets a view, as the target passes it
            T_plan[:3, :3] = rpy_to_matrix(*rng.uniform(-0.2, 0.2, 2), rng.uniform(-np.pi, np.pi))
            R_plan = T_plan[:3, :3]
            q_imu = rng.normal(size=4)
            R = tilt_between(R_plan[:, 2], imu_z_axis(q_imu)) @ R_plan
            expected = (R @ (com_in_neck - limb.fk(q_leg)[:3, 3]))[:2]
            got = _com_from_sole(q_leg, limb.chain, com_in_neck, R_plan, q_imu)
            assert np.allclose(got, expected, rtol=0, atol=1e-12)
