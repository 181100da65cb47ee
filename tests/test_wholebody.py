"""Arm + leg height algorithm (paper III-A)."""

import numpy as np
import pytest

from hubo_cli.kinematics.wholebody import WholeBody


@pytest.fixture(scope="module")
def body(model):
    return WholeBody(model, {"right-arm": "drill"})


def _goal(x, y, z):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def test_legs_take_the_height_and_arms_the_rest(body, model):
    goal = _goal(0.45, -0.25, -0.08)
    result = body.solve({"right-arm": goal})
    assert result.lift_m == pytest.approx(-0.08)
    assert not result.lift_capped
    assert all(r.status == "exact" for r in result.legs.values())
    # the arm's end frame, seen from the stance frame (neck lifted by lift_m), is the goal
    arm = body.arms["right-arm"]
    T_N_E = arm.fk(result.q_rad[model.limb_slice("right-arm")])
    T_S_E = T_N_E.copy()
    T_S_E[2, 3] += result.lift_m
    if result.arms["right-arm"].status == "exact":
        assert np.allclose(T_S_E, goal, atol=1e-9)
    # the soles have not moved in the stance frame
    for name, leg in body.legs.items():
        T_N_sole = leg.fk(result.q_rad[model.limb_slice(name)])
        T_N_sole[2, 3] += result.lift_m
        assert np.allclose(T_N_sole, body.T_S_sole[name], atol=1e-9)


def test_height_beyond_the_legs_is_capped_and_arms_reach_further(body):
    lo, hi = body.lift_range_m
    result = body.solve({"right-arm": _goal(0.4, -0.25, -0.5)})
    assert result.lift_capped and result.lift_m == pytest.approx(lo)
    result = body.solve({"right-arm": _goal(0.4, -0.25, 0.3)})
    assert result.lift_capped and result.lift_m == pytest.approx(hi)


def test_two_hands_share_one_height(body):
    result = body.solve({"right-arm": _goal(0.4, -0.25, -0.02), "left-arm": _goal(0.4, 0.25, -0.1)})
    assert result.lift_m == pytest.approx(-0.06)


def test_lift_range_is_sane(body):
    lo, hi = body.lift_range_m
    assert -0.3 < lo < -0.05 and 0.0 < hi < 0.05


def test_the_legs_alone_are_solve_s_legs_to_the_last_bit(body, model):
    """legs_at (the teleop's every period) gives solve({})'s joints and lift exactly, sign
    of zero included, from drawn postures and lifts: inside the legs' range, beyond it, tiny,
    exactly 0, and not finite."""
    from hubo_cli.posture import home_posture

    rng = np.random.default_rng(3407)
    q_home = home_posture(model)
    lo, hi = body.lift_range_m
    lifts = [0.0, -0.0, lo, hi, lo - 0.1, hi + 0.1, 1e-300, np.nan, np.inf, -np.inf]
    for k in range(600):
        q = q_home + rng.normal(0.0, 0.05, q_home.shape) * (k % 3 != 0)
        lift = lifts[k] if k < len(lifts) else rng.uniform(lo - 0.05, hi + 0.05) * 10.0 ** (
            -rng.integers(0, 6))
        body._last_leg.clear()  # solve's own memory of the legs: compare with a fresh solve
        expected = body.solve({}, q, lift_m=lift)
        q_legs, lift_m = body.legs_at(q, lift)
        assert np.array_equal(q_legs, expected.q_rad, equal_nan=True), k
        assert np.array_equal(np.signbit(q_legs), np.signbit(expected.q_rad)), k
        assert lift_m == expected.lift_m or (np.isnan(lift_m) and np.isnan(expected.lift_m)), k


def test_lift_filter_is_smooth_and_speed_limited():
    from hubo_cli.kinematics.wholebody import LiftFilter

    f = LiftFilter(max_speed_m_s=0.02)
    f.reset(0.0)
    lifts = [f.step(-0.1, 0.005) for _ in range(2000)]
    assert np.all(np.abs(np.diff(lifts)) <= 0.02 * 0.005 + 1e-12)
    assert lifts[-1] == pytest.approx(-0.1, abs=1e-6)


@pytest.fixture(scope="module")
def balanced(model):
    return WholeBody(model, {"right-arm": "drill"}, com_control=True)


def test_com_control_puts_the_balance_point_over_the_soles_centre(balanced, body, model):
    goal = _goal(0.30, -0.15, -0.10)
    free = body.solve({"right-arm": goal})
    result = balanced.solve({"right-arm": goal})
    assert abs(result.balance_error_m) < 0.5e-3
    # the drill out in front puts the CoM ahead of the soles' centre: the waist goes back
    assert result.shift_m < -0.01
    assert balanced.shift_of(result.q_rad) == pytest.approx(result.shift_m, abs=1e-9)
    assert free.shift_m == 0.0
    # the hand keeps its goal in S: the arm solved in the shifted neck frame
    assert result.arms["right-arm"].status == "exact"
    T_N_E = balanced.arms["right-arm"].fk(result.q_rad[model.limb_slice("right-arm")])
    T_S_E = T_N_E.copy()
    T_S_E[0, 3] += result.shift_m
    T_S_E[2, 3] += result.lift_m
    assert np.allclose(T_S_E, goal, atol=1e-9)
    # the soles have not moved in S
    for name, leg in balanced.legs.items():
        T_N_sole = leg.fk(result.q_rad[model.limb_slice(name)])
        T_N_sole[0, 3] += result.shift_m
        T_N_sole[2, 3] += result.lift_m
        assert np.allclose(T_N_sole, balanced.T_S_sole[name], atol=1e-9)


def test_the_waist_follows_the_arm_continuously(balanced):
    result = balanced.solve({"right-arm": _goal(0.30, -0.15, -0.05)})
    shifts = []
    for k in range(400):  # the bit goes 10 cm down in 2 s, the legs crouch with it
        goal = _goal(0.30, -0.15, -0.05 - 0.10 * min(k, 200) / 200)
        result = balanced.solve({"right-arm": goal}, result.q_rad,
                                shift_m=balanced.next_shift(result))
        assert result.arms["right-arm"].status == "exact"
        shifts.append(result.shift_m)
    assert np.ptp(shifts) > 0.005                             # the waist did move
    assert np.abs(np.diff(shifts)).max() <= 0.5e-3 + 1e-12  # no jumps between periods
    assert abs(result.balance_error_m) < 0.5e-3               # and it catches up


def test_a_thrust_on_the_hand_moves_the_balance_point(balanced):
    goal = _goal(0.30, -0.15, -0.10)
    still = balanced.solve({"right-arm": goal})
    # the wall pushes the bit back (-x): the body leans into it, its waist further forward
    pushed = balanced.solve({"right-arm": goal}, hand_forces_n={"right-arm": [-20.0, 0, 0]})
    assert pushed.shift_m > still.shift_m + 0.01


def test_a_balance_point_outside_the_soles_is_refused(model):
    from hubo_cli.errors import ConfigError

    with pytest.raises(ConfigError):
        WholeBody(model, com_control=True, support_offset_m=0.2)
