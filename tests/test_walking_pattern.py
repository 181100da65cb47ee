"""Walking pattern: preview control, footsteps, swing feet and the legs' joints (no simulator)."""

import math

import numpy as np
import pytest

from hubo_cli.control.capture_point import CapturePointMonitor, convex_hull, outside_distance
from hubo_cli.control.phase import SUPPORT_PLAN, SupportPlan
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError, InputError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
)
from hubo_cli.model import load_model
from hubo_cli.state import RobotState
from hubo_cli.walking.body import WalkingBody, pose_of_row, walking_posture
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps, stance_of
from hubo_cli.walking.gait import cruise_profile, make_gait, smoothstep5, swing_rows
from hubo_cli.walking.params import walking_params
from hubo_cli.walking.preview import com_from_zmp, preview_gains

GOALS = [(1.0, 0.0, 0.0), (0.0, 0.3, 0.0), (0.5, 0.2, 0.5), (-0.2, -0.1, -0.4)]


def start_feet(params):
    w = params.step_width_m
    return Footstep("right", 0.0, -w / 2, 0.0), Footstep("left", 0.0, w / 2, 0.0)


def goal_stance(goal):
    return Stance(*goal)


def test_preview_gains_match_kajita():
    """Kajita 2003 Fig. 6 (T = 5 ms, z_c = 0.8 m, Q = 1, R = 1e-6): the preview gain decays to
    about zero within 1.6 s; the integral gain is positive and the first preview gain is -G_i."""
    gains = preview_gains(0.005, 0.8, 1.6)
    assert len(gains.preview) == 320
    assert gains.integral > 0
    assert gains.preview[0] == pytest.approx(-gains.integral)
    assert abs(gains.preview[-1]) < 0.01 * abs(gains.preview[0])


@pytest.mark.physical
def test_preview_tracks_a_step_reference():
    """A 0.1 m ZMP step seen 1.6 s ahead: the cart-table ZMP follows within 2 mm after the
    step's first 0.1 s and the CoM ends on the new ZMP."""
    gains = preview_gains(0.005, 0.6, 1.6)
    ref = np.zeros((1200, 2))
    ref[400:, 1] = 0.1
    path = com_from_zmp(ref, gains)
    error = np.abs(path.zmp_m - ref)[:, 1]
    # measured 0.31 mm and 0.005 mm on both code paths (AVX-512 / portable): 16x and 420x
    assert error[:380].max() < 0.005  # moving ahead of the step costs a small excursion
    assert error[420:].max() < 0.002
    assert path.com_m[-1, 1] == pytest.approx(0.1, abs=0.001)


def test_preview_rejects_bad_settings():
    with pytest.raises(ConfigError):
        preview_gains(0.005, -0.6)
    with pytest.raises(ConfigError):
        com_from_zmp(np.full((10, 2), np.nan), preview_gains(0.005, 0.6))


@pytest.mark.parametrize("goal", GOALS)
def test_footsteps_respect_limits_and_end_at_goal(params, goal):
    right, left = start_feet(params)
    steps = plan_footsteps(right, left, goal_stance(goal), params)
    assert len(steps) % 2 == 0 and steps
    feet = {"right": right, "left": left}
    for step in steps:
        other = feet["left" if step.side == "right" else "right"]
        seen = Stance(other.x_m, other.y_m, other.yaw_rad).relative(
            Stance(step.x_m, step.y_m, step.yaw_rad))
        forward, sideways, turn = seen
        assert -params.max_step_backward_m - 1e-9 <= forward <= params.max_step_forward_m + 1e-9
        # the feet stay apart (never crossed) and within the lateral limit of the nominal width
        width = abs(sideways)
        assert params.step_width_m - 2 * params.max_step_lateral_m - 1e-9 <= width
        assert width <= params.step_width_m + 2 * params.max_step_lateral_m + 1e-9
        assert abs(turn) <= params.max_turn_rad + 1e-9
        # the hips only turn the toes out: the left foot's heading never below the right's
        feet[step.side] = step
        assert feet["left"].yaw_rad >= feet["right"].yaw_rad - 1e-9
    end = stance_of(feet["right"], feet["left"])
    assert math.hypot(end.x_m - goal[0], end.y_m - goal[1]) < 1e-9
    assert end.yaw_rad == pytest.approx(goal[2], abs=1e-9)


def test_no_steps_when_already_there(params):
    right, left = start_feet(params)
    assert plan_footsteps(right, left, Stance(0.0, 0.0, 0.0), params) == []


def test_too_far_is_refused(params):
    right, left = start_feet(params)
    with pytest.raises(InputError):
        plan_footsteps(right, left, Stance(100.0, 0.0, 0.0), params)


@pytest.fixture(scope="module")
def forward_gait(params):
    right, left = start_feet(params)
    steps = plan_footsteps(right, left, Stance(0.45, 0.0, 0.0), params)
    return make_gait(right, left, steps, params, 0.005, 0.59, 0.0, 0.02)


@pytest.mark.physical
def test_one_metre_forward_averages_over_a_tenth_of_a_metre_a_second(params):
    """The walk 1 m forward (``hubo walk --to 1.0 0 0``, the walk's ``average_speed_m_s``: the
    goal's distance over the time from the start to the last step's end, lead-in included)
    averages at least 0.1 m/s with a margin when no correction follows (the robot file's step
    length and timing: 0.112 m/s)."""
    right, left = start_feet(params)
    steps = plan_footsteps(right, left, Stance(1.0, 0.0, 0.0), params)
    gait = make_gait(right, left, steps, params, 0.005, 0.59, 0.0, 0.02)
    walking_s = (np.nonzero(gait.step_index >= 0)[0][-1] + 1) * gait.period_s
    # the plan's whole periods, the same on every CPU (0.112 on both code paths, AVX-512 /
    # portable): what is checked is the step length and timing, not a measured figure
    assert 1.0 / walking_s >= 0.105


@pytest.mark.physical
def test_pattern_zmp_tracks_and_stays_in_support(forward_gait, walking_model):
    """The cart-table ZMP of the CoM path follows the reference within 3 mm after the lead-in
    and lies inside the support polygon (the soles on the ground) in every period."""
    gait = forward_gait
    lead_in = int(round(1.0 / gait.period_s))
    error = np.linalg.norm(gait.com.zmp_m - gait.zmp_ref_m, axis=1)
    # measured on both code paths (AVX-512 / portable): 0.50 mm (6x), and the ZMP at least
    # 44.6 mm inside the soles (8.9x the 5 mm)
    assert error[lead_in:].max() < 0.003
    corners = walking_model.feet.sole_corners_m()
    for k in range(lead_in, gait.n, 5):
        points = []
        for column, side in enumerate(("right", "left")):
            if gait.support[k, column]:
                x, y, _, yaw = gait.feet[side][k]
                c, s = math.cos(yaw), math.sin(yaw)
                points += [(x + c * px - s * py, y + s * px + c * py) for px, py, _ in corners]
        assert outside_distance(convex_hull(np.array(points)), gait.com.zmp_m[k]) < -0.005


@pytest.mark.physical
def test_swing_feet_lift_and_land_flat(forward_gait, params):
    gait = forward_gait
    for column, side in enumerate(("right", "left")):
        z = gait.feet[side][:, 2]
        swinging = ~gait.support[:, column]
        # the planned heights, equal on both code paths (AVX-512 / portable)
        assert z[swinging].max() == pytest.approx(params.swing_height_m, rel=0.01)
        assert np.all(z[~swinging] == 0.0)  # on the ground: flat on the floor
        # the foot moves horizontally only while it is up
        moving = np.linalg.norm(np.diff(gait.feet[side][:, :2], axis=0), axis=1) > 1e-9
        assert np.all(z[1:][moving] >= 0.09 * params.swing_height_m)


@pytest.mark.physical
def test_joint_plan_reaches_the_feet_within_limits(forward_gait, walking_model, params):
    """The legs' IK reaches every sole goal; the joints stay within the walking limit set's
    velocity (0 < v <= limit) and the whole-body CoM follows the pattern's within 1.2 mm
    (0.77 mm on both code paths, AVX-512 / portable: 1.56x)."""
    q_start, T_world_neck = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    body = WalkingBody(walking_model, q_start, T_world_neck, params.lean_rad_per_m)
    plan = body.solve(forward_gait)
    assert plan.worst_ik_error_m < 1e-6
    legs = slice(12, 24)
    assert np.all(plan.q_rad[:, legs] >= walking_model.lower_rad[legs] - 1e-9)
    assert np.all(plan.q_rad[:, legs] <= walking_model.upper_rad[legs] + 1e-9)
    velocity = np.abs(np.diff(plan.q_rad, axis=0)) / forward_gait.period_s
    assert np.all(velocity.max(axis=0) <= walking_model.velocity_rad_s + 1e-9)
    assert np.abs(plan.com_m[:, :2] - forward_gait.com.com_m).max() < 0.0012


def test_capture_point_uses_the_planned_support(walking_model, params):
    """With the left foot in the air (a swing) and the CoM between the feet, the measured
    contacts alone put the CP outside the right sole; the walk's planned support (the swing
    foot counted where it lands, :class:`SupportPlan`) keeps it inside."""

    q, _ = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    monitor = CapturePointMonitor(walking_model, walking_model.control_period_s)
    w = params.step_width_m / 2
    store = Store()  # the estimate: the CoM standing still between the soles, the left one up
    store[T_WORLD_SOLES] = np.array([pose_of_row(np.array([0.0, -w, 0.0, 0.0])),
                                     pose_of_row(np.array([0.0, w, 0.02, 0.0]))])
    store[CONTACT] = (True, False)
    store[COM_WORLD] = np.array([0.0, 0.0, 0.6])
    store[COM_VELOCITY_WORLD] = np.zeros(3)
    store[CAPTURE_POINT_WORLD] = np.zeros(2)

    def flagged() -> bool:
        monitor.reset(q, None, store)
        return any([monitor.measure(RobotState(time_s=0.005 * k, q_rad=q, dq_rad_s=0 * q),
                                    store) for k in range(5)])

    assert flagged() and monitor.outside_m > 0.03
    store[SUPPORT_PLAN] = SupportPlan(np.array([pose_of_row(np.array([0.0, -w, 0.0, 0.0])),
                                                pose_of_row(np.array([0.1, w, 0.0, 0.0]))]))
    assert not flagged() and monitor.outside_m < -0.03
    store[SUPPORT_PLAN] = None  # the phase has ended: the estimated soles again
    assert flagged()


def test_the_monitor_counts_a_swinging_foot_that_still_carries(walking_model, params):
    """At a late hand-off (the plan has the right foot swinging, counted at its landing place,
    while its ankle sensor still reads it carrying and the left foot lands late) the
    capture point between the two soles is inside the support: main's monitor stopped the fast
    2 m walks of AVX-512 and portable seed 22 there, and with the stop relaxed neither fell
    (docs/history/walking.md, round 18). Once the estimate has the foot off the floor the
    plan's support alone counts again."""

    q, _ = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    monitor = CapturePointMonitor(walking_model, walking_model.control_period_s)
    w = params.step_width_m / 2
    right = pose_of_row(np.array([0.0, -w, 0.01, 0.0]))  # where it stands, 10 mm up
    left = pose_of_row(np.array([0.25, w, 0.0, 0.0]))
    landing = pose_of_row(np.array([0.5, -w, 0.0, 0.0]))
    store = Store()
    store[T_WORLD_SOLES] = np.array([right, left])
    store[COM_WORLD] = np.array([0.12, 0.0, 0.6])
    store[COM_VELOCITY_WORLD] = np.zeros(3)
    store[CAPTURE_POINT_WORLD] = np.array([0.12, 0.0])

    def flagged(contact: tuple[bool, bool], swinging: tuple[bool, bool]) -> bool:
        store[CONTACT] = contact
        store[SUPPORT_PLAN] = SupportPlan(np.array([landing, left]), None, swinging)
        monitor.reset(q, None, store)
        return any([monitor.measure(RobotState(time_s=0.005 * k, q_rad=q, dq_rad_s=0 * q),
                                    store) for k in range(5)])

    assert not flagged((True, False), (True, False)) and monitor.outside_m < -0.03
    assert flagged((False, True), (True, False)) and monitor.outside_m > 0.03
    assert flagged((True, True), (False, False))  # a plan with both feet down: as it says


def test_measured_feet_a_fraction_of_a_mm_off_take_no_extra_steps(params):
    """Feet measured 0.1 mm and 0.001 rad off their nominal places walk 1 m forward in the
    same steps as nominal feet (each at most the forward limit), not in two more."""
    right, left = start_feet(params)
    nominal = plan_footsteps(right, left, Stance(1.0, 0.0, 0.0), params)
    measured = plan_footsteps(Footstep("right", -1e-4, right.y_m, 1e-3),
                              Footstep("left", -1.1e-4, left.y_m, 1e-3),
                              Stance(1.0, 0.0, 0.0), params)
    assert len(measured) == len(nominal)
    forward = [b.x_m - a.x_m for a, b in zip(measured, measured[1:], strict=False)]
    assert max(forward) <= params.max_step_forward_m + 0.002


@pytest.mark.physical
def test_sideways_walk_keeps_the_ankle_rolls_off_their_limits(walking_model, params):
    """Walking 0.3 m to the left, the ankle rolls stay 0.03 rad and the hip rolls 0.01 rad
    inside Table IV's limits: the swing sole lands flat instead of on its edge (with 0.26 m
    feet and 0.05 m lateral steps the swing ankle's roll sat at its 0.3 rad limit and the
    simulated robot fell)."""
    right, left = start_feet(params)
    steps = plan_footsteps(right, left, Stance(0.0, 0.3, 0.0), params)
    gait = make_gait(right, left, steps, params, 0.005, 0.59, 0.0, 0.02)
    q_start, T_world_neck = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    body = WalkingBody(walking_model, q_start, T_world_neck, params.lean_rad_per_m)
    plan = body.solve(gait)
    assert plan.worst_ik_error_m < 1e-6
    names = list(walking_model.joint_names)
    # the hips only abduct: the stance hip is held a little off its 0 limit by the lean.
    # Measured on both code paths (AVX-512 / portable): ankles 0.054 / 0.056 rad inside (1.8x
    # the 0.03), hips 0.033 / 0.032 rad (3.2x the 0.01)
    for joint, margin in (("RAR", 0.03), ("LAR", 0.03), ("RHR", 0.01), ("LHR", 0.01)):
        i = names.index(joint)
        q = plan.q_rad[:, i]
        inside = min(q.min() - walking_model.lower_rad[i], walking_model.upper_rad[i] - q.max())
        assert inside >= margin, (joint, inside)


@pytest.mark.parametrize("ramp", [0.5, 0.3, 0.2, 0.05])
def test_the_swing_cruise_profile_is_smooth_and_bounded(ramp):
    """0 -> 1 without a jump in position or speed; 0.5 is the quintic itself; the peak speed
    is 1 / (1 - 14 ramp / 15) times the mean (the quintic's 1.875)."""
    u = np.linspace(0.0, 1.0, 20001)
    s = cruise_profile(u, ramp)
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0, abs=1e-12)
    speed = np.diff(s) / np.diff(u)
    assert np.all(speed >= 0.0)
    assert speed.max() == pytest.approx(1.0 / (1.0 - 14.0 * ramp / 15.0), rel=1e-3)
    assert np.abs(np.diff(speed)).max() < 0.01  # continuous speed (0.0012 at ramp 0.05)
    if ramp == 0.5:
        assert np.array_equal(s, smoothstep5(u))


def test_the_swing_travel_and_ramp_are_checked(params):
    with pytest.raises(ConfigError):
        params.with_changes(swing_ramp_fraction=0.6)
    with pytest.raises(ConfigError):
        params.with_changes(swing_travel_fraction=1.2)
    for end in (0.7, 1.01, float("nan")):  # before the travel's length, past the phase, NaN
        with pytest.raises(ConfigError, match="swing_travel_end_fraction"):
            params.with_changes(swing_travel_end_fraction=end)


def test_the_gaits_are_the_robot_files(walking_model, params, tmp_path):
    """``normal`` is the [walking] table, ``fast`` its sub-table's changes; an unknown gait is
    bad input, a sub-table naming a field that is no walking parameter a bad robot file."""
    from hubo_cli.errors import InputError
    from hubo_cli.walking.params import gait_names

    assert gait_names(walking_model) == ("normal", "fast")
    assert walking_params(walking_model, "normal") == params
    fast = walking_params(walking_model, "fast")
    assert fast.step_width_m == params.step_width_m and fast.crouch_m == params.crouch_m
    assert fast.step_s < params.step_s  # the same start posture, shorter steps
    with pytest.raises(InputError, match="no gait 'run'"):
        walking_params(walking_model, "run")
    text = walking_model.source.read_text().replace(
        "[walking.fast]\n", "[walking.fast]\nstride_m = 0.3\n")
    bad = tmp_path / "hubo2plus.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match="walking.fast.stride_m"):
        walking_params(load_model("as-built", "walking", path=bad), "fast")
    # a bad value in the sub-table is named there, not in [walking] (whose value is fine)
    # (the fast gait's own travel end replaced: one key each)
    nan = tmp_path / "nan" / "hubo2plus.toml"
    nan.parent.mkdir()
    nan.write_text(walking_model.source.read_text().replace(
        "swing_travel_end_fraction = 0.86", "swing_travel_end_fraction = nan"))
    with pytest.raises(ConfigError, match=r"walking\.fast\.swing_travel_end_fraction"):
        walking_params(load_model("as-built", "walking", path=nan), "fast")
    # a sub-table named after the [walking] table's own gait would never be read
    normal = tmp_path / "normal" / "hubo2plus.toml"
    normal.parent.mkdir()
    normal.write_text(text.replace("[walking.fast]\nstride_m = 0.3\n",
                                   "[walking.normal]\nsingle_support_s = -1\n[walking.fast]\n"))
    with pytest.raises(ConfigError, match="walking.normal"):
        walking_params(load_model("as-built", "walking", path=normal))


def test_a_gait_answers_pushes_by_its_step_not_its_name(walking_model, tmp_path):
    """The landing wait while walking, the floor reach and the momentum strategy are on for a
    gait whose steps last PUSH_RESPONSES_MIN_STEP_S or longer (the normal gait's 1.0 s), off
    for the fast gait's 0.75 s; a gait added to the robot file gets them by its step; a
    toe-heel walk has no floor reach and no momentum strategy. Once a walk stops, every
    flat-foot gait's landings wait. A gait without them has its capture-point monitor judge
    against the soles where the estimate stands them (the same fact)."""
    from hubo_cli.walking.stabilizer import StabilizerGains
    from hubo_cli.walking.target import WalkTarget
    from hubo_cli.walking.toe_heel import ToeHeelParams

    path = tmp_path / "hubo2plus.toml"
    path.write_text(walking_model.source.read_text().replace(
        "[walking.fast]\n", "[walking.quick]\nsingle_support_s = 0.65\ndouble_support_s = 0.2\n"
        "[walking.stroll]\nsingle_support_s = 0.9\n[walking.fast]\n"))
    model = load_model("as-built", "walking", path=path)

    def responses(gait, toe_heel=None):
        params = walking_params(model, gait)
        q_start, T_world_neck = walking_posture(model, params.step_width_m, params.crouch_m)
        target = WalkTarget(model, params, (1.0, 0.0, 0.0), q_start, T_world_neck,
                            stabilizer=StabilizerGains(), toe_heel=toe_heel)
        assert target.landing_wait is (params.answers_pushes or toe_heel is None)
        assert target.support_where_standing is not params.answers_pushes
        return target.landing_wait_walking, target.floor_reach, target.momentum

    on, off = (True, True, True), (False, False, False)
    assert [responses(g) for g in ("normal", "stroll", "quick", "fast")] == [on, on, off, off]
    assert responses("normal", ToeHeelParams.from_model(model)) == (True, False, False)


@pytest.mark.parametrize("field, value", [("single_support_s", 1e-300),
                                          ("single_support_s", 0.004),
                                          ("single_support_s", 1e7), ("settle_s", 1e9)])
def test_the_phases_durations_are_bounded(params, field, value):
    """A step of a period or less moves the foot's reference in jumps; a huge one makes a plan
    too large to hold: both are a bad file, named."""
    with pytest.raises(ConfigError, match=field):
        params.with_changes(**{field: value})


def test_the_default_swing_ends_its_travel_in_the_middle(params):
    """swing_travel_end_fraction 0.9 with 0.8 of travel is the former middle, to the bit."""
    start, end = Footstep("left", 0.0, 0.12, 0.0), Footstep("left", 0.28, 0.12, 0.0)
    rows = swing_rows(start, end, 140, 0.02, 0.0, 0.8, 0.5, params.swing_travel_end_fraction)
    assert np.array_equal(rows, swing_rows(start, end, 140, 0.02, 0.0, 0.8, 0.5))


def test_the_fast_gait_walks_two_metres_at_a_fifth_of_a_metre_a_second(walking_model):
    """Issue 37's 2 m at 0.2 m/s as `hubo walk --gait fast` plans it: 12 steps, 0.209 m/s
    from the start to the last step's end; the legs' joints within hubo-motion-rt's MaxSpeed
    (2.5 rad/s; the plan with its multi-body correction peaks at 2.48, the same on both code
    paths); coming down, the swing foot has stopped travelling before it is lower than 3 mm
    (it touched down still sliding when it travelled until it was a fraction of a mm up)."""
    fast = walking_params(walking_model, "fast")
    q_start, T_world_neck = walking_posture(walking_model, fast.step_width_m, fast.crouch_m)
    right, left = start_feet(fast)
    steps = plan_footsteps(right, left, Stance(2.0, 0.0, 0.0), fast)
    gait = make_gait(right, left, steps, fast, 0.005, 0.59, 0.0, 0.02)
    walking_s = (np.nonzero(gait.step_index >= 0)[0][-1] + 1) * gait.period_s
    assert len(steps) == 12 and 2.0 / walking_s >= 0.2
    body = WalkingBody(walking_model, q_start, T_world_neck, fast.lean_rad_per_m)
    gait, plan = body.solve_corrected(gait, 0.0, fast.preview_s, fast.zmp_weight,
                                      fast.jerk_weight)
    assert plan.worst_ik_error_m < 1e-6
    assert np.abs(np.diff(plan.q_rad[:, 12:24], axis=0)).max() / gait.period_s < 2.5
    for side in ("right", "left"):
        rows = gait.feet[side]
        landing = (np.abs(np.diff(rows[:, 0])) > 1e-9) & (np.diff(rows[:, 2]) < 0)
        assert rows[1:, 2][landing].min() > 0.003  # 3.3 mm at its last travelling period


def test_a_fifth_of_a_metre_a_second_needs_the_swing_to_cruise(walking_model, params):
    """Issue 37's bound, as planned: 2 m in ten 0.223 m steps of 0.9 s (0.208 m/s from the
    start to the last step's end, the lead-in included) asks up to 3.4 rad/s of a leg joint
    (the pattern with its multi-body correction) with today's swing (the quintic over the
    middle 80 % of single support); travelling over 96 % of it and cruising between a 20 %
    speeding up and slowing down, 2.1 rad/s: within hubo-motion-rt's leg MaxSpeed, 2.5 rad/s
    (control.table; the walking set's 2.6 rad/s is above it). The sim robot fell on such
    gaits (docs/history/walking.md): this is the joints' bound only."""
    fast = params.with_changes(max_step_forward_m=0.223, single_support_s=0.7,
                               double_support_s=0.2, start_s=0.4)
    q_start, T_world_neck = walking_posture(walking_model, fast.step_width_m, fast.crouch_m)
    right, left = start_feet(fast)
    steps = plan_footsteps(right, left, Stance(2.0, 0.0, 0.0), fast)
    peaks = []
    for swing in ({}, {"swing_travel_fraction": 0.96, "swing_ramp_fraction": 0.2,
                       "swing_travel_end_fraction": 0.98}):
        walk = fast.with_changes(**swing)
        gait = make_gait(right, left, steps, walk, 0.005, 0.59, 0.0, 0.02)
        walking_s = (np.nonzero(gait.step_index >= 0)[0][-1] + 1) * gait.period_s
        assert 2.0 / walking_s >= 0.2  # whole periods of the plan, the same on every CPU
        body = WalkingBody(walking_model, q_start, T_world_neck, walk.lean_rad_per_m)
        gait, plan = body.solve_corrected(gait, 0.0, walk.preview_s, walk.zmp_weight,
                                          walk.jerk_weight)
        assert plan.worst_ik_error_m < 1e-6
        peaks.append(float(np.abs(np.diff(plan.q_rad[:, 12:24], axis=0)).max()
                           / gait.period_s))
    # the plan's figures, the same on both code paths: 3.38 and 2.07 rad/s
    assert peaks[0] > 3.0 and peaks[1] < 2.3


def test_a_correction_starts_where_the_legs_hold_the_soles(params):
    """A correction's pattern (:func:`hubo_cli.walking.lead_in.blend_from_held`) starts at the
    soles the legs hold and reaches the estimated ones, which it was planned from, by the first
    lift-off, without a jump; the swings are left as planned. Held soles drawn 5-20 mm and
    0.5-3 deg off, the first row moves at most a period's share of the quintic."""
    from hubo_cli.walking.lead_in import blend_from_held
    from hubo_cli.walking.support import SIDES

    right, left = start_feet(params)
    steps = plan_footsteps(right, left, Stance(0.1, 0.03, 0.0), params)
    rng = np.random.default_rng(37)
    for _ in range(5):
        gait = make_gait(right, left, steps, params, 0.005, 0.59, -0.008, 0.02)
        planned = {side: gait.feet[side].copy() for side in SIDES}
        held = np.tile(np.eye(4), (2, 1, 1))
        for column, foot in enumerate((right, left)):
            off = rng.uniform(0.005, 0.02, 3) * rng.choice([-1.0, 1.0], 3)
            turn = math.radians(rng.uniform(0.5, 3.0)) * rng.choice([-1.0, 1.0])
            c, s = math.cos(foot.yaw_rad + turn), math.sin(foot.yaw_rad + turn)
            held[column, :2, :2] = [[c, -s], [s, c]]
            held[column, :3, 3] = (foot.x_m + off[0], foot.y_m + off[1], -0.008 + off[2])
        lead = blend_from_held(gait, held)
        assert lead == np.flatnonzero(~gait.support.all(axis=1))[0]
        first = smoothstep5(1.0 / lead)
        for column, side in enumerate(SIDES):
            rows, T = gait.feet[side], held[column]
            start = np.array([T[0, 3], T[1, 3], T[2, 3], math.atan2(T[1, 0], T[0, 0])])
            aimed = planned[side][lead - 1]
            assert np.allclose(rows[0], start + first * (aimed - start), atol=1e-12)
            assert np.allclose(rows[lead - 1], aimed, atol=1e-12)
            assert np.array_equal(rows[lead:], planned[side][lead:])
            steps_between = np.abs(np.diff(rows[:lead], axis=0))
            assert np.all(steps_between <= 2.0 * np.abs(aimed - start) / lead + 1e-12)
