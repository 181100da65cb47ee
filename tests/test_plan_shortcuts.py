"""Pre-flight's shortcuts give exactly what the per-period computation they replace gives:
the legs' solve reused while the lift and shift hold, a non-turning segment's orientation
computed once, and the lift filter in Python floats."""

import numpy as np
import pytest

from hubo_cli.geometry import rotation_exp
from hubo_cli.kinematics.interpolate import PoseSegment
from hubo_cli.kinematics.wholebody import LiftFilter, WholeBody
from hubo_cli.model import LEGS
from hubo_cli.tasks.plan import (
    LEGS_ACCEL_M_S2,
    LEGS_SPEED_M_S,
    LEGS_TIME_CONSTANT_S,
    lift_filter,
    make_plan,
)
from hubo_cli.tasks.spec import load_task


def _reference_legs(body: WholeBody, q_prev: np.ndarray, lift_m: float, shift_m: float
                    ) -> dict[str, np.ndarray]:
    """The legs solved afresh for one period, as every period was before."""
    T_N_S = np.eye(4)
    T_N_S[0, 3], T_N_S[2, 3] = -shift_m, -lift_m
    return {name: body.legs[name].solve(T_N_S @ body.T_S_sole[name],
                                        q_prev[body.model.limb_slice(name)]).q_rad
            for name in LEGS}


@pytest.mark.parametrize("task", ["cut-slot", "cut-rectangle", "cut-rectangle-force"])
def test_a_plans_legs_are_those_of_a_fresh_solve_every_period(model, task):
    """Every period's leg joints (level stretches reuse the last solve) equal a fresh solve
    from the previous period's joints with that period's lift and shift."""
    spec = load_task(task)
    plan = make_plan(spec, model)
    body, shift, limb = plan.body, plan.placement.shift_m, plan.spec.stance.limb
    assert plan.preflight.ok and plan.preflight.unguided is None  # (the force cut's guide)
    lift = lift_filter(spec)
    lift.reset(body.lift_for({limb: plan.T_first_S}))  # as make_plan runs it
    q_prev, lift_prev, level = plan.q_first_rad, None, 0
    for i, (q, goal) in enumerate(zip(plan.q_rad, plan.goal_S_m, strict=True)):
        T = np.eye(4)
        T[:3, 3] = goal
        lift_m = lift.step(body.lift_for({limb: T}), plan.dt_s)
        for name, q_leg in _reference_legs(body, q_prev, lift_m, shift).items():
            assert np.array_equal(q[model.limb_slice(name)], q_leg), (task, i, name)
        level += lift_m == lift_prev
        q_prev, lift_prev = q, lift_m
    assert level > len(plan.q_rad) // 5  # the shortcut was taken (level cuts, waits)


def test_the_leg_shortcut_needs_the_same_lift_shift_and_joints(model):
    body = WholeBody(model, {"right-arm": "drill"})
    T = np.eye(4)
    T[:3, 3] = [0.45, -0.25, -0.08]
    first = body.solve({"right-arm": T}, None, lift_m=-0.05, shift_m=0.0)
    for lift, shift, q_prev in ((-0.05, 0.0, first.q_rad), (-0.06, 0.0, first.q_rad),
                                (-0.06, 0.01, first.q_rad), (-0.06, 0.01, body.q_home)):
        got = body.solve({"right-arm": T}, q_prev, lift_m=lift, shift_m=shift)
        for name, q_leg in _reference_legs(body, q_prev, lift, shift).items():
            assert np.array_equal(got.legs[name].q_rad, q_leg)
    moved = body.solve({"right-arm": T}, None, lift_m=-0.12, shift_m=0.0)
    assert abs(body.lift_of(moved.q_rad) - body.lift_of(first.q_rad) + 0.07) < 1e-6


def test_a_non_turning_segment_has_the_orientation_of_the_full_formula():
    R = rotation_exp([0.1, -0.4, 0.2])
    T_a, T_b = np.eye(4), np.eye(4)
    T_a[:3, :3] = T_b[:3, :3] = R
    T_b[:3, 3] = [0.0, 0.15, -0.1]
    straight = PoseSegment(T_a, T_b, 2.0, profile="trapezoid", ramp_s=0.2)
    T_c = T_b.copy()
    T_c[:3, :3] = rotation_exp([0.3, 0.0, 0.0]) @ R
    turning = PoseSegment(T_a, T_c, 2.0)
    for t in np.linspace(-0.1, 2.1, 23):
        got = straight.at(t)
        assert np.array_equal(got[:3, :3], R @ rotation_exp(0.0 * straight._turn))
        T = turning.at(t)
        assert np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)
    assert np.allclose(turning.at(2.0)[:3, :3], T_c[:3, :3], atol=1e-12)
    assert not np.allclose(turning.at(1.0)[:3, :3], R, atol=1e-3)


def _reference_lift_step(f: dict, wanted_m: float, dt_s: float) -> float:
    """LiftFilter.step as it was written with numpy scalars."""
    alpha = dt_s / (LEGS_TIME_CONSTANT_S + dt_s)
    f["smoothed"] += alpha * (wanted_m - f["smoothed"])
    gap = f["smoothed"] - f["lift"]
    speed = float(np.clip(gap / dt_s, -LEGS_SPEED_M_S, LEGS_SPEED_M_S))
    stop = float(np.sqrt(2 * LEGS_ACCEL_M_S2 * abs(gap)))
    speed = float(np.clip(speed, -stop, stop))
    speed = float(np.clip(speed, f["speed"] - LEGS_ACCEL_M_S2 * dt_s,
                          f["speed"] + LEGS_ACCEL_M_S2 * dt_s))
    f["speed"] = speed
    f["lift"] += speed * dt_s
    return f["lift"]


def test_the_lift_filter_in_python_floats_matches_numpy():
    rng = np.random.default_rng(3)
    wanted = np.concatenate([np.full(200, 0.0), np.full(300, -0.1), rng.normal(0, 0.05, 500),
                             np.linspace(-0.1, 0.05, 400)])
    lift = LiftFilter(LEGS_SPEED_M_S, LEGS_TIME_CONSTANT_S, LEGS_ACCEL_M_S2)
    lift.reset(0.02)
    ref = {"smoothed": 0.02, "lift": 0.02, "speed": 0.0}
    for w in wanted:
        assert lift.step(float(w), 0.005) == _reference_lift_step(ref, float(w), 0.005)
    assert abs(lift.lift_m - 0.02) > 0.01  # it moved
