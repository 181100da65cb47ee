"""Trading one arm joint for another (hubo_cli/teleop/trade.py): the box-constrained least
squares is exact, nothing is traded where every joint can follow, and where one cannot the
others make up for it within their limits."""

from __future__ import annotations

import daqp
import numpy as np
import pytest

from hubo_cli.kinematics import get_limb
from hubo_cli.model import load_model
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.teleop.lead import GoalVelocity, tracking_target
from hubo_cli.teleop.trade import HORIZON_S, OFFSET_CAP_RAD, _box_lsq, traded_goal

DT = 0.005
Q_READY = np.array([-0.3, -0.4, 0.0, -1.2, 0.0, 0.0])  # a bent right arm, inside its limits


@pytest.fixture(scope="module")
def arm():
    model = load_model(limits="teleop")
    limits = JointLimits.from_model(model).subset(np.arange(24)[model.limb_slice("right-arm")])
    limb = get_limb("right-arm", "hand")
    return limits, limb, limb.fk_chain


def test_the_box_least_squares_is_exact_against_daqp():
    """Random 6-variable problems (ill-conditioned ones included, the box containing zero or
    not): the active set's objective within 1e-12 of daqp's, its answer inside the box."""
    rng = np.random.default_rng(8)
    for _ in range(300):
        A = rng.normal(size=(6, 6)) * rng.uniform(0.01, 1.0, 6)
        A[rng.integers(0, 6, rng.integers(0, 4))] = 0.0  # rank 3-6, as near a singular arm
        H = A.T @ A + 1e-6 * np.eye(6)
        f = rng.normal(size=6) * 0.01
        lo = rng.uniform(-0.2, 0.05, 6)
        hi = lo + rng.uniform(0.0, 0.2, 6) * (rng.uniform(size=6) > 0.15)  # some lo = hi
        y = np.zeros(6)
        _box_lsq(H, f, lo, hi, y)
        x, _, exitflag, _ = daqp.solve(H, f, np.zeros((0, 6)), hi, lo,
                                       np.zeros(6, dtype=np.int32))
        assert exitflag == 1  # daqp's optimum
        assert np.all(y >= lo - 1e-15) and np.all(y <= hi + 1e-15)
        assert 0.5 * y @ H @ y + f @ y <= 0.5 * x @ H @ x + f @ x + 1e-12


def test_nothing_is_traded_where_every_joint_can_follow(arm):
    """Joints on their goal and moving with it, or a state not finite: the goal as it was."""
    limits, _, chain = arm
    v_goal = np.array([0.3, -0.2, 0.1, 0.4, -0.3, 0.2])
    out, short = traded_goal(Q_READY, v_goal, Q_READY, v_goal, limits, chain)
    assert short == 0 and np.array_equal(out, Q_READY)
    q = Q_READY.copy()
    q[3] = np.nan
    out, short = traded_goal(Q_READY, v_goal, q, np.zeros(6), limits, chain)
    assert short == 0 and np.array_equal(out, Q_READY)


def test_the_others_make_up_for_a_joint_that_cannot_follow(arm):
    """The elbow at rest 0.2 rad behind a goal moving at 0.5 rad/s (it cannot be there within
    HORIZON_S at its acceleration), the other joints on the goal: the elbow keeps its goal,
    the others are offset within the cap and the limits, and the hand's position HORIZON_S
    ahead (the elbow as near the goal as it can be) is nearer the goal's than untraded."""
    limits, limb, chain = arm
    v_goal = np.zeros(6)
    v_goal[3] = 0.5
    q = Q_READY.copy()
    q[3] -= 0.2
    v = v_goal.copy()
    v[3] = 0.0
    out, short = traded_goal(Q_READY, v_goal, q, v, limits, chain)
    assert short == 1
    assert out[3] == Q_READY[3]
    assert np.all(np.abs(out - Q_READY) <= OFFSET_CAP_RAD + 1e-12)
    assert np.all(out >= limits.lower_rad) and np.all(out <= limits.upper_rad)
    g = Q_READY + v_goal * HORIZON_S
    x = g.copy()
    x[3] = q[3] + 0.5 * 0.9 * limits.acceleration_rad_s2[3] * HORIZON_S**2  # as near as it can
    traded = x + (out - Q_READY)
    traded[3] = x[3]
    p_goal = limb.fk(g)[:3, 3]
    before = np.linalg.norm(limb.fk(x)[:3, 3] - p_goal)
    after = np.linalg.norm(limb.fk(traded)[:3, 3] - p_goal)
    # measured (deterministic numerics): 95.6 mm untraded, 81.0 mm traded: the others can
    # move only 0.032 rad off their own way in HORIZON_S at their 0.8 rad/s^2
    assert after < 0.9 * before, (before, after)


def _follow(arm, goal_of, duration_s: float, trade: bool) -> np.ndarray:
    """An arm's tracker following the joint goal ``goal_of(t)`` as the teleop target drives
    it (the goal's velocity, the intercept; traded or not): the hand's position errors (m)."""
    limits, limb, chain = arm
    tracker = JointTracker(limits, DT)
    goal = GoalVelocity(limits, DT)
    tracker.reset(goal_of(0.0))
    errors = []
    for ti in np.arange(0.0, duration_s, DT):
        target = goal_of(ti)
        v_goal = goal.update(target, follow=True)
        given = traded_goal(target, v_goal, tracker.q, tracker.v, limits, chain)[0] if trade \
            else target
        q, v, _ = tracking_target(v_goal, given, tracker.q, tracker.v, limits)
        assert np.all(q >= limits.lower_rad) and np.all(q <= limits.upper_rad)
        tracker.track(q, target_v_rad_s=v)
        errors.append(np.linalg.norm(limb.fk(tracker.q)[:3, 3] - limb.fk(goal_of(ti + DT))[:3, 3]))
    return np.array(errors)


def test_a_stroke_one_joint_cannot_follow_leaves_the_hand_nearer_its_goal(arm):
    """A goal whose elbow starts a 0.6 rad/s stroke at once (from rest, beyond its
    0.8 rad/s^2) while the other joints move at 0.06 rad/s: the traded arm's hand stays nearer
    the goal's than the arm whose joints each follow their own goal."""
    direction = np.array([0.1, -0.1, 0.1, 1.0, 0.1, -0.1])

    def stroke(t_s):
        s = min(max(t_s - 0.2, 0.0), 0.6)
        return Q_READY + direction * 0.6 * s

    rms = {trade: float(np.sqrt(np.mean(_follow(arm, stroke, 1.5, trade) ** 2)))
           for trade in (False, True)}
    # measured (deterministic numerics): 39.5 mm RMS untraded, 32.4 mm traded (with the
    # elbow at 0.9 / 1.2 rad/s, beyond its speed limit, 75 -> 72 and 115 -> 112 mm)
    assert rms[True] < 0.9 * rms[False], rms


def test_the_largest_advance_is_the_brute_force_one():
    """_max_advance against integrating the fastest speed profile (full acceleration up to
    the speed limit, or slowing down to it from above) in small steps."""
    from hubo_cli.teleop.trade import _max_advance
    for v in (-1.5, -0.3, 0.0, 0.4, 0.99, 1.0, 1.5):
        for h in (0.05, 0.3, 1.0):
            n = 20000
            dt, x, speed = h / n, 0.0, v
            for _ in range(n):
                step = min(max(1.0 - speed, -0.72 * dt), 0.72 * dt)  # towards 1.0 rad/s
                x += (speed + step / 2) * dt
                speed += step
            assert _max_advance(v, 0.72, 1.0, h) == pytest.approx(x, abs=1e-6)


def test_a_joint_braking_into_its_limit_trades_continuously(arm):
    """The elbow 0.05-0.06 rad above its lower limit moving toward it at 0.3 rad/s, its goal
    at the limit, another joint's goal moving: the traded goal moves by little for a small
    change of the state (an interval that collapsed onto the joint when braking could not
    stop short of the limit moved the wrist by 0.06 rad for a 0.2 mrad step)."""
    limits, _, chain = arm
    elbow, lower = 3, limits.lower_rad[3]
    goal = Q_READY.copy()
    goal[elbow] = lower
    v_goal = np.zeros(6)
    v_goal[0] = 0.2
    v = np.zeros(6)
    v[elbow] = -0.3
    outs = []
    for gap in np.linspace(0.05, 0.06, 51):
        q = Q_READY.copy()
        q[elbow] = lower + gap
        out, _ = traded_goal(goal, v_goal, q, v, limits, chain)
        assert np.all(out >= limits.lower_rad) and np.all(out <= limits.upper_rad)
        outs.append(out)
    assert np.max(np.abs(np.diff(outs, axis=0))) < 0.01
