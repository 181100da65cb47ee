"""Toe-heel contact (eq. 4, Fig. 4): the swing foot's CoP and angle through the five phases,
reversed backward, flat for short steps; the reference ZMP of random walks stays in the
support polygon and moves continuously; bad parameters and footsteps."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from robot_file_support import robot_file_with

from hubo_cli.errors import ConfigError
from hubo_cli.model import load_model
from hubo_cli.walking.footsteps import Footstep
from hubo_cli.walking.toe_heel import (
    ToeHeelParams,
    ankle_offset,
    plan_toe_heel_walk,
    sole_edges_m,
    swing_profile,
)


@pytest.fixture(scope="module")
def params(model):
    return ToeHeelParams.from_model(model)


def test_the_robot_file_has_the_papers_phases(params, model):
    assert params.phase_s == (0.05, 0.25, 0.4, 0.25, 0.05)  # Fig. 4's caption
    assert params.step_s == pytest.approx(1.0)
    toe, heel = sole_edges_m(model.feet)
    assert toe == pytest.approx(model.feet.forward_m + model.feet.length_m / 2)
    assert heel == pytest.approx(model.feet.forward_m - model.feet.length_m / 2)


def test_the_five_phases_forward(params, model):
    toe, heel = sole_edges_m(model.feet)
    ends = np.cumsum(params.phase_s)
    starts = ends - np.asarray(params.phase_s)
    mid = (starts + ends) / 2
    th_toe, th_heel = params.toe_angle_rad, params.heel_angle_rad
    t = np.array([0.0, mid[0], ends[0], mid[1], ends[1] - 1e-9, mid[2], ends[2] - 1e-9, mid[3],
                  ends[3] - 1e-9, mid[4], ends[4]])
    cop, angle, pivot = swing_profile(t, params, model.feet, 1)
    np.testing.assert_allclose(cop, [0, toe / 2, toe, toe, toe, (toe + heel) / 2, heel, heel,
                                     heel, heel / 2, 0], atol=1e-6)
    # minimum jerk: half way at each phase's middle, the ends reached at rest
    np.testing.assert_allclose(angle, [0, 0, 0, th_toe / 2, th_toe, (th_toe - th_heel) / 2,
                                       -th_heel, -th_heel / 2, 0, 0, 0], atol=1e-6)
    assert pivot[3] == pytest.approx(toe) and pivot[7] == pytest.approx(heel)
    # in (iii) the pivot follows the angle: half way through the roll, half way along the sole
    assert pivot[5] == pytest.approx((toe + heel) / 2, abs=1e-6)


def test_backward_is_forward_reversed_and_short_steps_land_flat(params, model):
    t = np.linspace(0, params.step_s, 401)
    forward = swing_profile(t, params, model.feet, 1)
    backward = swing_profile(t, params, model.feet, -1)
    for f, b in zip(forward, backward, strict=True):
        np.testing.assert_allclose(b, f[::-1], atol=1e-12)
    flat = swing_profile(t, params, model.feet, 0)
    assert all(np.all(a == 0) for a in flat)


def test_the_angle_is_smooth_and_rests_at_the_phase_boundaries(params, model):
    """Minimum-jerk pieces: continuous angle and angular rate everywhere; the rate is zero at
    each boundary of phases (ii)-(iv)."""
    dt = 1e-4
    t = np.arange(0, params.step_s + dt / 2, dt)
    _, angle, _ = swing_profile(t, params, model.feet, 1)
    rate = np.diff(angle) / dt
    # the fastest a 0.35 rad min-jerk move over 0.25 s turns: 1.875 * 0.35 / 0.25 = 2.6 rad/s
    assert np.abs(rate).max() < 3.0
    assert np.abs(np.diff(rate)).max() * 1 < 0.05  # no jump in the rate between samples
    for boundary in np.cumsum(params.phase_s)[:4]:
        k = int(round(boundary / dt))
        assert abs(rate[min(k, len(rate) - 1)]) < 0.01


def test_ankle_offset_keeps_the_pivot_in_place():
    for angle, pivot in ((0.35, 0.13), (-0.087, -0.09), (0.2, 0.0)):
        dx, dz = ankle_offset(angle, pivot)
        c, s = math.cos(angle), math.sin(angle)
        # the pivot (pivot, 0, 0) of the turned sole (about +y: x -> (c x, -s x)), moved
        np.testing.assert_allclose([c * pivot + dx, -s * pivot + dz], [pivot, 0.0], atol=1e-12)
    assert ankle_offset(0.35, 0.13)[1] > 0  # rolling on the toe lifts the ankle


def _walk(params, model, steps, double_support_s=0.3):
    right, left = Footstep("right", 0.0, -0.12, 0.0), Footstep("left", 0.0, 0.12, 0.0)
    return plan_toe_heel_walk(right, left, steps, params, model.feet, double_support_s, 0.005)


def test_a_two_step_walk_as_fig_4(params, model):
    steps = [Footstep("left", 0.2, 0.12, 0.0), Footstep("right", 0.2, -0.12, 0.0)]
    plan = _walk(params, model, steps)
    assert plan.t_s[-1] == pytest.approx(2 * 0.5 + 2 * params.step_s)
    assert set(plan.direction[plan.swing >= 0]) == {1}
    # eq. 4: the ZMP is the CoPs' blend; r is 0 or 1 in single support
    np.testing.assert_allclose(plan.zmp_m, (1 - plan.ratio)[:, None] * plan.cop_m[:, 0]
                               + plan.ratio[:, None] * plan.cop_m[:, 1])
    single = (plan.swing >= 0) & (plan.ratio != 0.5)
    in_single = single & ((plan.ratio == 0) | (plan.ratio == 1))
    assert in_single.sum() > 0.5 * (plan.swing >= 0).sum()
    # the left foot (first swing) rolls on its toe, then on its heel; the right stays flat
    first = plan.swing == 1
    assert plan.foot_angle_rad[first, 1].max() == pytest.approx(params.toe_angle_rad)
    assert plan.foot_angle_rad[first, 1].min() == pytest.approx(-params.heel_angle_rad)
    assert np.all(plan.foot_angle_rad[first, 0] == 0)
    # standing at the end: the ZMP between the feet, at x = 0.2
    np.testing.assert_allclose(plan.zmp_m[-1], [0.2, 0.0], atol=1e-9)


def _inside_soles(point, plan_row_poses, feet, sides, tol=1e-9) -> bool:
    """Whether ``point`` lies in the convex hull of the given soles (their corners)."""
    from hubo_cli.control.wrench_distribution import convex_hull, project_into_polygon
    corners = []
    for side in sides:
        x, y, yaw = plan_row_poses[side]
        c, s = math.cos(yaw), math.sin(yaw)
        corners.append(feet.sole_corners_m()[:, :2] @ np.array([[c, -s], [s, c]]).T + (x, y))
    hull = convex_hull(np.vstack(corners))
    nearest, _ = project_into_polygon(np.asarray(point, dtype=float), hull)
    return float(np.linalg.norm(nearest - point)) < tol


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), double_support=st.floats(0.05, 0.6))
def test_random_walks_keep_the_zmp_in_the_support_polygon(params, model, seed,
                                                          double_support):
    """Forward, backward, sideways and turning steps: the reference ZMP is inside the soles
    on the ground (both in double support, the stance sole in single support) and moves at
    most a sole's length per double support (no jump between periods)."""
    rng = np.random.default_rng(seed)
    feet = {"right": Footstep("right", 0.0, -0.12, 0.0), "left": Footstep("left", 0.0, 0.12, 0.0)}
    steps = []
    side = "left" if rng.random() < 0.5 else "right"
    for _ in range(int(rng.integers(1, 6))):
        other = feet["right" if side == "left" else "left"]
        yaw = other.yaw_rad + rng.uniform(-0.3, 0.3)
        lateral = (0.24 if side == "left" else -0.24) + rng.uniform(-0.03, 0.03)
        forward = rng.uniform(-0.15, 0.25)
        x = other.x_m + forward * math.cos(yaw) - lateral * math.sin(yaw)
        y = other.y_m + forward * math.sin(yaw) + lateral * math.cos(yaw)
        feet[side] = Footstep(side, x, y, yaw)
        steps.append(feet[side])
        side = "right" if side == "left" else "left"
    plan = _walk(params, model, steps, double_support)
    for k in range(0, len(plan.t_s), 3):
        poses = {"right": plan.foot_pose[k, 0], "left": plan.foot_pose[k, 1]}
        if plan.ratio[k] in (0.0, 1.0):
            sides = ["left"] if plan.ratio[k] == 1.0 else ["right"]
        else:
            sides = ["right", "left"]
        assert _inside_soles(plan.zmp_m[k], poses, model.feet, sides), (k, plan.t_s[k])
    step = np.linalg.norm(np.diff(plan.zmp_m, axis=0), axis=1)
    # the farthest two CoPs can be (0.45 m of feet and soles) crossed within one double
    # support, sampled at 5 ms, plus the CoP's own fastest move (toe to heel in phase (i))
    bound = 0.5 * 0.005 / double_support + 0.2 * 0.005 / min(params.phase_s)
    assert step.max() < bound


@pytest.mark.parametrize("key,value", [("phase_s", "[0.1, 0.2, 0.3]"),
                                       ("phase_s", "[0.1, -0.2, 0.3, 0.2, 0.1]"),
                                       ("phase_s", "[0, 0, 0, 0, 0]"),
                                       ("phase_s", '"fast"'),
                                       ("toe_angle_rad", "-0.1"), ("heel_angle_rad", "2.0"),
                                       ("min_step_m", "nan")])
def test_bad_parameters_are_refused(model, tmp_path, key, value):
    bad = load_model(path=robot_file_with(model, tmp_path, "toe_heel", key, value))
    with pytest.raises(ConfigError, match="toe_heel"):
        ToeHeelParams.from_model(bad)


def test_other_phase_times_are_parameters(model):
    slow = ToeHeelParams((0.1, 0.3, 0.5, 0.3, 0.1), 0.2, 0.1, 0.05)
    plan = plan_toe_heel_walk(Footstep("right", 0, -0.12, 0), Footstep("left", 0, 0.12, 0),
                              [Footstep("left", 0.2, 0.12, 0)], slow, model.feet, 0.3, 0.005,
                              stand_s=0.0)
    assert plan.t_s[-1] == pytest.approx(1.3)
    k = int(round(0.4 / 0.005))  # the end of (ii): on the toe, fully rolled
    assert plan.foot_angle_rad[k - 1, 1] == pytest.approx(0.2, abs=1e-3)


@pytest.mark.parametrize("steps,match", [
    ([Footstep("left", 0.2, 0.12, 0), Footstep("left", 0.4, 0.12, 0)], "twice"),
    ([Footstep("middle", 0.2, 0.0, 0)], "side"),
    ([Footstep("left", float("nan"), 0.12, 0)], "finite")])
def test_bad_footsteps_are_refused(params, model, steps, match):
    with pytest.raises(ConfigError, match=match):
        _walk(params, model, steps)


@pytest.mark.parametrize("double_support,period", [(0.0, 0.005), (1.0, 0.005), (0.3, 0.0),
                                                   (0.3, float("nan")), (float("inf"), 0.005)])
def test_bad_timing_is_refused(params, model, double_support, period):
    with pytest.raises(ConfigError):
        plan_toe_heel_walk(Footstep("right", 0, -0.12, 0), Footstep("left", 0, 0.12, 0),
                           [], params, model.feet, double_support, period)
