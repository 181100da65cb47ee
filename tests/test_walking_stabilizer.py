"""The walking stabilizer's feedback laws and the second preview stage (no simulator)."""

import math

import numpy as np
import pytest
from walking_support import standing_walk, wrench_at

from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import CONTACT, T_WORLD_SOLES, T_WORLD_TORSO
from hubo_cli.geometry import quat_wxyz_to_matrix, rigid_inverse
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model
from hubo_cli.state import RobotState
from hubo_cli.walking.body import WalkingBody, multibody_zmp, walking_posture
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps
from hubo_cli.walking.gait import make_gait
from hubo_cli.walking.params import walking_params
from hubo_cli.walking.stabilizer import SoleDamper, StabilizerGains, TorsoOffset, Touchdown
from hubo_cli.walking.support import zmp_outside_m

DT = 0.005
SOLE = (-0.09, 0.13, -0.065, 0.065)  # the sole box in its own frame (m)


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


def test_the_rigid_inverse_is_the_inverse():
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = rng.normal(size=4)
        T = np.eye(4)
        T[:3, :3] = quat_wxyz_to_matrix(q / np.linalg.norm(q))
        T[:3, 3] = rng.normal(size=3)
        assert np.allclose(rigid_inverse(T), np.linalg.inv(T), atol=1e-12)
        assert np.allclose(rigid_inverse(np.array([T, np.eye(4)]))[0], np.linalg.inv(T),
                           atol=1e-12)


CORNERS = np.array([[-0.11, -0.065, 0.0], [0.11, -0.065, 0.0], [0.11, 0.065, 0.0],
                    [-0.11, 0.065, 0.0]])


def test_a_zmp_between_the_soles_lies_inside_their_hull():
    """Two soles 0.24 m apart in contact: a ZMP a quarter of the way from the right one to the
    left lies inside their hull by the distance to its nearest edge (the toe line, 0.11 m
    ahead); with neither in contact, or no ZMP, there is no hull to measure."""
    poses = np.array([np.eye(4), np.eye(4)])  # right, left
    poses[:, :2, 3] = (1.0, -0.12), (1.0, 0.12)
    zmp = np.array([1.0, -0.06])
    assert zmp_outside_m(zmp, poses, CORNERS, (True, True)) == pytest.approx(-0.11, abs=1e-12)
    assert zmp_outside_m(zmp, poses, CORNERS, (False, False)) == float("inf")
    assert zmp_outside_m(np.full(2, np.nan), poses, CORNERS, (True, True)) == float("inf")
    for half_known in ((1.0, np.nan), (np.nan, -0.06), (np.inf, -0.06)):  # one axis unknown
        assert zmp_outside_m(np.array(half_known), poses, CORNERS, (True, False)) == math.inf


def test_one_sole_in_contact_measures_against_its_own_outline():
    """One sole in contact: the hull is the sole itself (its corners counter-clockwise), a ZMP
    5 mm inside its outer edge lies 5 mm inside, one on that edge is not inside, and the other
    sole's place does not count."""
    poses = np.array([np.eye(4), np.eye(4)])  # right, left
    poses[1, 1, 3] = 0.24
    inside = zmp_outside_m(np.array([0.0, -0.06]), poses, CORNERS, (True, False))
    assert inside == pytest.approx(-0.005, abs=1e-9)
    assert zmp_outside_m(np.array([0.0, -0.065]), poses, CORNERS, (True, False)) > -0.001
    assert zmp_outside_m(np.array([0.0, 0.12]), poses, CORNERS, (True, False)) > 0.05


@pytest.mark.physical
def test_torso_offset_reaches_the_legs_with_the_hip_yaw_at_its_limit():
    """Standing with the feet ahead, each hip yaw sits at its joint limit (0): with the feet
    toed in by a hundredth of a degree, as the simulator reads them after a few steps, the
    legs' IK reaches the soles' goals only capped to the limits (a few microradians off), and
    the torso offset must still move the legs. A torso that the IMU reads 1 deg pitched
    forward puts the measured CoM ahead of the pattern's; the offset moves the torso back, so
    both soles move forward in its frame by the offset (and sideways by its part from the
    ZMP's feedback). Before, the offset grew while the legs never followed it."""
    model, q_start, _, target, _ = standing_walk((0.3, 0.0, 0.0), StabilizerGains(),
                                                 right_yaw_rad=1e-4, pitch_rad=np.radians(1.0))
    for k in range(60):  # 0.3 s of the start's double support, the robot on the pattern
        state = RobotState(time_s=k * DT, q_rad=q_start.copy(), dq_rad_s=np.zeros_like(q_start))
        q, _ = target(k * DT, state)
        q_plan = target.plan.q_rad[k]
    offset = target.torso_offset.offset_m
    # -14.2 mm on both code paths (AVX-512 / portable): 2.8x; the soles follow it equally on both
    assert offset[0] < -0.005  # pulled back by more than 5 mm
    for name in ("right-leg", "left-leg"):
        leg, part = Limb(model, name), model.limb_slice(name)
        moved = leg.fk(q[part])[:3, 3] - leg.fk(q_plan[part])[:3, 3]
        assert moved[:2] == pytest.approx(-offset, abs=0.001)


@pytest.mark.physical
def test_a_new_plan_from_the_estimate_does_not_apply_the_torso_offset_again():
    """The legs hold the torso offset (here pulled back by a torso the IMU reads 1 deg pitched
    forward, as in the test above); the estimate then puts the torso where they hold it, and a
    new plan starts from it (a correction walk, :meth:`WalkTarget._plan`). Its first period's
    leg joints continue the last ones: the plan already carries the offset, so the offset and
    the legs' correction start again from zero. Kept, they moved the torso by the offset a
    second time in one period (pushed seed 17 of tools/walk_disturbances.py: 28 mm back, the
    hips 4-5 deg; the capture point went behind the heels, and on the portable path the
    capture-point stop's stance tipped over them backward)."""
    model, q_start, _, target, store = standing_walk((0.3, 0.0, 0.0), StabilizerGains(),
                                                     pitch_rad=np.radians(1.0))
    for k in range(60):
        state = RobotState(time_s=k * DT, q_rad=q_start.copy(), dq_rad_s=np.zeros_like(q_start))
        q, _ = target(k * DT, state)
    assert target.torso_offset.offset_m[0] < -0.005  # the legs hold the torso back
    right = model.limb_slice("right-leg")
    store[T_WORLD_TORSO] = store[T_WORLD_SOLES][0] @ rigid_inverse(
        Limb(model, "right-leg").fk(q[right]))
    target._plan(target.plan.q_rad[target.k - 1], 60 * DT)
    q_next, _ = target(60 * DT, state)
    legs = np.r_[right, model.limb_slice("left-leg")]
    # 0.62 deg on both code paths (AVX-512 / portable; the ankles' and hips' pitch: the new
    # plan's CoM is from the last plan's joints); the offset applied again: 2.39 deg on both
    assert np.degrees(np.max(np.abs(q_next[legs] - q[legs]))) < 1.2


def test_a_correction_starts_from_the_joints_last_sent_while_the_legs_correction_lags():
    """The torso offset has moved 25 mm sideways at once, further than the legs' correction
    follows in a period (LEG_STEP_RAD: it keeps its last value), and a correction's plan is made
    then from the joints last sent, as the loop makes it (:meth:`WalkTarget._plan`): its first
    period's leg joints continue the ones last sent, the soles held where those joints hold
    them, the CoM where they hold it and the torso turned from the estimated one onto the
    pattern's lean over the lead-in. Perturbed robot 8's fast 2 m walk had its legs' targets
    jump 67 mrad in one period at its correction's start, hopped and was stopped by the
    capture-point monitor; portable robot 1's jumped 15 mrad with the soles held alone, and fell
    in its correction walk (docs/history/walking.md, round 14)."""
    model, q_start, _, target, store = standing_walk((0.3, 0.0, 0.0), StabilizerGains())
    state = RobotState(time_s=0.0, q_rad=q_start.copy(), dq_rad_s=np.zeros_like(q_start))
    for k in range(60):
        q, _ = target(k * DT, state)
    target.torso_offset.offset_m[:] = (0.0, 0.025)
    q, _ = target(60 * DT, state)
    right = model.limb_slice("right-leg")
    store[T_WORLD_TORSO] = store[T_WORLD_SOLES][0] @ rigid_inverse(
        Limb(model, "right-leg").fk(q[right]))
    target._plan(target._sent_q, 61 * DT)
    q_next, _ = target(61 * DT, state)
    legs = np.r_[right, model.limb_slice("left-leg")]
    # 0.36 mrad (the next periods' own steps 0.37-0.47); the lean not blended in: 5.56; the CoM
    # from the plan's last row as well: 6.02 (both code paths alike: no physics)
    assert np.max(np.abs(q_next[legs] - q[legs])) < 1.5e-3


@pytest.mark.parametrize("stop_after", [1, 10, 60])  # periods into the 0.55 s lead-in
def test_a_stop_in_a_corrections_lead_in_keeps_the_held_soles_moving_smoothly(stop_after):
    """A correction's pattern starts where the legs hold the soles and moves them onto the
    estimated ones over its lead-in (:func:`hubo_cli.walking.lead_in.blend_from_held`); a stop
    in that lead-in re-plans a stance where the feet are. It continues from the soles as they
    are held then, onto the estimate over HELD_BLEND_ROWS: re-planned from the estimate alone,
    the legs jumped 3.3-4.2 deg in one period (the estimated soles 8.7 mm low, the drift the
    fast gait's corrections meet: docs/history/walking.md, round 7)."""
    from hubo_cli.control.keys import STOP_MODE

    model, q_start, _, target, store = standing_walk((0.3, 0.0, 0.0), StabilizerGains())
    state = RobotState(time_s=0.0, q_rad=q_start.copy(), dq_rad_s=np.zeros_like(q_start))
    for k in range(60):
        q, _ = target(k * DT, state)
    soles = store[T_WORLD_SOLES].copy()
    soles[:, 2, 3] -= 0.0087
    store[T_WORLD_SOLES] = soles
    target._plan(target.plan.q_rad[target.k - 1], 60 * DT)
    legs = np.r_[model.limb_slice("right-leg"), model.limb_slice("left-leg")]
    steps_deg = []
    for j in range(stop_after + 40):
        if j >= stop_after:
            store[STOP_MODE] = "finish"
        q_next, _ = target((61 + j) * DT, state)
        steps_deg.append(np.degrees(np.max(np.abs(q_next[legs] - q[legs]))))
        q = q_next
    assert target.phase in ("stopping", "stood")
    # measured 0.01-0.05 deg a period from the stop on (both code paths alike: no physics)
    assert max(steps_deg[stop_after:]) < 0.5, steps_deg[stop_after:]


def test_a_swing_leg_is_pitched_against_the_torsos_pitch_and_holds_on_the_floor():
    """The walk's first period made its plan; then the estimated torso pitched back 3 deg with
    the right foot in contact and the left one swinging: the left hip pitch turns against the
    2 deg beyond the 1 deg dead band at 0.6 rad/s, the right leg keeps the pattern's joints.
    Landed while one sole is unloaded, the left leg keeps its turn; in the air again with the
    torso upright, it goes back at the same rate; with both soles planned down and in contact
    it goes back at LEVEL_RETURN_RAD_S, to exactly the pattern. Pitched back 20 deg, the turn
    stops at LEVEL_MAX_RAD. Inside the dead band, or without a finite torso estimate, the
    joints are the pattern's."""
    from hubo_cli.walking.target import (
        LEVEL_DEAD_RAD,
        LEVEL_MAX_RAD,
        LEVEL_RATE_RAD_S,
        LEVEL_RETURN_RAD_S,
    )

    model, q_start, T_world_neck, target, store = standing_walk((0.3, 0.0, 0.0),
                                                                StabilizerGains())
    target(0.0, RobotState(time_s=0.0, q_rad=q_start.copy(), dq_rad_s=np.zeros_like(q_start)))
    names = list(model.joint_names)
    right, left = names.index("RHP"), names.index("LHP")
    pattern = target.plan.q_rad[0]

    def pitched(deg: float) -> np.ndarray:
        T = T_world_neck.copy()
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        T[:3, :3] = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ T[:3, :3]
        return T

    def period(support, contact) -> np.ndarray:
        store[CONTACT] = contact
        q = pattern.copy()
        target._level_swing(support, q, float(target._torso_error_rad(0)[1]))
        return q

    swinging, standing = [True, False], [True, True]
    store[T_WORLD_TORSO] = pitched(-0.9)  # inside the dead band: untouched
    assert np.array_equal(period(swinging, (True, False)), pattern)
    store[T_WORLD_TORSO] = pitched(-3.0)
    step = LEVEL_RATE_RAD_S * model.control_period_s
    wanted = np.radians(3.0) - LEVEL_DEAD_RAD
    for k in range(1, 21):
        q = period(swinging, (True, False))
        assert q[right] == pattern[right]
        assert q[left] - pattern[left] == pytest.approx(min(k * step, wanted), abs=1e-9)
    store[T_WORLD_TORSO] = T_world_neck  # landed, one sole unloaded: held, torso upright
    assert period(standing, (True, False))[left] - pattern[left] == pytest.approx(wanted)
    assert period(swinging, (True, True))[left] - pattern[left] == pytest.approx(wanted)
    store[T_WORLD_TORSO] = np.full((4, 4), np.nan)  # no estimate: held, finite
    q = period(swinging, (True, False))
    assert np.all(np.isfinite(q)) and q[left] - pattern[left] == pytest.approx(wanted)
    store[T_WORLD_TORSO] = T_world_neck  # in the air again: back at the same rate
    assert period(swinging, (True, False))[left] - pattern[left] == pytest.approx(wanted - step)
    back = LEVEL_RETURN_RAD_S * model.control_period_s  # both soles loaded: back slowly
    for k in range(1, 4):
        q = period(standing, (True, True))
        assert q[left] - pattern[left] == pytest.approx(wanted - step - k * back, abs=1e-9)
        assert q[right] == pattern[right]
    for _ in range(round((wanted - step) / back)):
        q = period(standing, (True, True))
    assert q[left] == pattern[left] and q[right] == pattern[right]
    store[T_WORLD_TORSO] = pitched(-20.0)  # far beyond the cap
    for _ in range(round(LEVEL_MAX_RAD / step) + 10):
        q = period(swinging, (True, False))
    assert q[left] - pattern[left] == pytest.approx(LEVEL_MAX_RAD, abs=1e-12)
