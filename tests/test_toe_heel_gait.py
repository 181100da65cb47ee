"""Toe-heel walking in the pattern (eq. 4, Fig. 4 wired into make_gait): the ZMP reference is
the toe-heel plan's, a rolling sole keeps its edge on the floor, the swing foot's rows and
pitch, the legs reach the rolled soles; the LIP stabilizer's CoP references (no simulator)."""

import math

import numpy as np
import pytest

from hubo_cli.control.lip_feedback import LipFeedback
from hubo_cli.control.wrench_distribution import WrenchDistributor
from hubo_cli.walking.body import WalkingBody, pose_of_row, walking_posture
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps
from hubo_cli.walking.gait import make_gait
from hubo_cli.walking.stabilizer import LipStabilizer, SoleDamper, StabilizerGains
from hubo_cli.walking.support import planned_contacts
from hubo_cli.walking.toe_heel import ToeHeelParams, sole_edges_m


@pytest.fixture(scope="module", params=[(1.0, 0.0, 0.0), (0.4, 0.1, 0.3), (-0.2, 0.0, 0.0)])
def gait(request, walking_model, params):
    w = params.step_width_m / 2
    right, left = Footstep("right", 0.0, -w, 0.0), Footstep("left", 0.0, w, 0.0)
    steps = plan_footsteps(right, left, Stance(*request.param), params)
    return make_gait(right, left, steps, params, walking_model.control_period_s, 0.59, 0.0,
                     0.02, com_start_m=np.array([0.01, 0.0]),
                     toe_heel=ToeHeelParams.from_model(walking_model), sole=walking_model.feet)


def sole_points(T_world_sole, x_m):
    """World points of the sole's bottom edge lines at x (m) along it, both sides."""
    return [T_world_sole @ np.array([x_m, y, 0.0, 1.0]) for y in (-0.06, 0.06)]


def test_the_phases_scale_to_the_walking_step(walking_model, params):
    phases = ToeHeelParams.from_model(walking_model).scaled_to(params.step_s)
    assert phases.step_s == pytest.approx(params.step_s)
    # the robot file's 1.0 s step: the paper's phases unchanged
    if params.step_s == pytest.approx(1.0):
        assert phases.phase_s == pytest.approx((0.05, 0.25, 0.4, 0.25, 0.05))


def test_zmp_reference_is_eq_4_after_the_lead_in(gait, params):
    lead = int(round(params.start_s / gait.period_s))
    np.testing.assert_allclose(gait.zmp_ref_m[lead:], gait.toe_heel.zmp_m[lead:], atol=1e-12)
    np.testing.assert_allclose(gait.zmp_ref_m[0], [0.01, 0.0], atol=0.01)  # starts under CoM
    assert np.all(np.isfinite(gait.zmp_ref_m)) and np.all(np.isfinite(gait.com.com_m))
    jumps = np.linalg.norm(np.diff(gait.zmp_ref_m, axis=0), axis=1)
    assert jumps.max() < 0.01  # continuous: under 10 mm a period


def test_a_sole_on_the_ground_keeps_its_pivot_on_the_floor(gait, walking_model):
    """In support, a rolling sole's pivot edge is on the floor where its footstep puts it;
    a flat one lies flat; in the air the lowest point of the sole is never below the floor."""
    plan = gait.toe_heel
    toe, heel = sole_edges_m(walking_model.feet)
    rolled = 0
    for k in range(0, gait.n, 3):
        for column, side in enumerate(("right", "left")):
            angle = float(plan.foot_angle_rad[k, column])
            T = pose_of_row(gait.feet[side][k], angle)
            lowest = min(p[2] for x in (toe, heel) for p in sole_points(T, x))
            assert lowest >= -1e-9
            if gait.support[k, column]:
                pivot = float(plan.pivot_m[k, column]) if angle != 0.0 else 0.0
                for p in sole_points(T, pivot):
                    assert p[2] == pytest.approx(0.0, abs=1e-9)
                rolled += angle != 0.0
    if gait.steps[0].x_m > 0.1:  # a forward walk rolls its soles while they carry load
        assert rolled > 0


def test_the_legs_reach_the_rolled_soles(walking_model, params):
    w = params.step_width_m / 2
    right, left = Footstep("right", 0.0, -w, 0.0), Footstep("left", 0.0, w, 0.0)
    gait = make_gait(right, left, plan_footsteps(right, left, Stance(0.6, 0.0, 0.2), params),
                     params, walking_model.control_period_s, 0.59, 0.0, 0.02,
                     toe_heel=ToeHeelParams.from_model(walking_model), sole=walking_model.feet)
    assert np.any(gait.toe_heel.foot_angle_rad != 0.0)
    q_start, T_world_neck = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    body = WalkingBody(walking_model, q_start, T_world_neck, params.lean_rad_per_m)
    plan = body.solve(gait)
    # in the air with the toe rolled, the swing ankle's roll reaches its Table IV limit under
    # the leaned torso: 1.8 mm off the goal at most (deterministic, both code paths)
    assert plan.worst_ik_error_m < 0.0025
    legs = slice(12, 24)
    assert np.all(plan.q_rad[:, legs] >= walking_model.lower_rad[legs] - 1e-9)
    assert np.all(plan.q_rad[:, legs] <= walking_model.upper_rad[legs] + 1e-9)


def test_pose_of_row_turns_the_sole_about_its_y_axis():
    T = pose_of_row(np.array([0.1, 0.2, 0.0, 0.5]), 0.3)
    R = T[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    c, s = math.cos(0.5), math.sin(0.5)
    np.testing.assert_allclose(R[:, 1], [-s, c, 0.0], atol=1e-12)  # the axis it turns about
    assert R[2, 0] == pytest.approx(-math.sin(0.3))  # heel up: the sole's x points down
    np.testing.assert_allclose(pose_of_row(np.array([0.1, 0.2, 0.0, 0.5]), 0.0),
                               pose_of_row(np.array([0.1, 0.2, 0.0, 0.5])))


def test_lip_stabilizer_references_stay_on_the_soles(gait, walking_model):
    """Every period of the walk, undisturbed and with the CoM 20 mm off: each sole the
    pattern has down gets a reference CoP inside its margined outline (on its edge when it
    rolls), one in the air gets none; never a NaN."""
    stabilizer = LipStabilizer(LipFeedback.from_model(walking_model, gait.com_height_m),
                               WrenchDistributor.from_model(walking_model), 38.7)
    box = stabilizer.distributor.box_local_m
    contacts = planned_contacts(gait)
    com, velocity = gait.com.com_m, gait.com.com_velocity_m_s
    for error in ((0.0, 0.0), (0.02, -0.02)):
        for k in range(0, gait.n, 7):
            refs = stabilizer.cop_references(com[k], velocity[k], gait.zmp_ref_m[k],
                                             com[k] + error, velocity[k], gait.zmp_ref_m[k],
                                             contacts[k])
            for column in range(2):
                if contacts[k][column] is None:
                    assert refs[column] is None
                elif refs[column] is not None:
                    x, y = refs[column]
                    assert box[0] - 1e-9 <= x <= box[1] + 1e-9
                    assert box[2] - 1e-9 <= y <= box[3] + 1e-9
            assert np.all(np.isfinite(stabilizer.zmp_command_m))


def test_a_damper_with_a_reference_cop_holds_that_cop():
    """A sole whose measured CoP is its reference does not turn; 20 mm toward the toe from
    it, it turns its toe up (as without a reference, from the safe region's edge)."""
    damper = SoleDamper(StabilizerGains(), (-0.09, 0.13, -0.065, 0.065), 0.005)
    fz = 300.0
    for _ in range(50):
        damper.update(np.array([0, 0, fz, 0.0, -fz * 0.1, 0]), (0.1, 0.0))
    np.testing.assert_allclose(damper.delta_rad, 0.0, atol=1e-12)
    for _ in range(50):
        damper.update(np.array([0, 0, fz, 0.0, -fz * 0.12, 0]), (0.1, 0.0))
    assert damper.delta_rad[1] < -1e-3  # pitch < 0: the toe up
