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


def test_lift_filter_is_smooth_and_speed_limited():
    from hubo_cli.kinematics.wholebody import LiftFilter

    f = LiftFilter(max_speed_m_s=0.02)
    f.reset(0.0)
    lifts = [f.step(-0.1, 0.005) for _ in range(2000)]
    assert np.all(np.abs(np.diff(lifts)) <= 0.02 * 0.005 + 1e-12)
    assert lifts[-1] == pytest.approx(-0.1, abs=1e-6)
