"""The nearest reachable pose on a branch: Jacobian, branches, the search, speed scale, reports."""

import numpy as np
import pytest

from hubo_cli.errors import ConfigError
from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.arm_reach import ArmReach, ReachSettings
from hubo_cli.kinematics.choice import (
    EXACT,
    NEAREST,
    STATUS_NAMES,
    limb_candidates,
    solve_limb_on_branch,
)
from hubo_cli.kinematics.conditioning import SingularityScale, condition_number
from hubo_cli.kinematics.reach import branch_box, branch_of, jacobian, nearest_on_branch
from hubo_cli.teleop.hand_report import max_excursion_m, steady_mask

READY_RIGHT = np.array([0.0, -0.15, 0.0, -1.4, 0.0, 0.0])
MARGINS = np.array([0.1, 0.55, 0.55])


@pytest.fixture
def limb():
    return get_limb("right-arm", "hand")


def _nearest(limb, T, q0, branch, margins=MARGINS, w_rot=0.05, iterations=10):
    q = np.empty(6)
    pos, rot, _ = nearest_on_branch(T, limb.chain, limb.lower_rad, limb.upper_rad, q0, branch,
                                    margins, 1.0, w_rot, iterations, q)
    return q, pos, rot


def test_jacobian_matches_finite_differences(limb, rng):
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T, J = np.empty((4, 4)), np.empty((6, 6))
    for q in limb.random_q(rng, 20):
        jacobian(q, base, offset, alpha, a, d, end, T, J)
        assert np.allclose(T, limb.fk(q), atol=1e-12)
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = 1e-7
            T2 = limb.fk(q + dq)
            W = (T2[:3, :3] @ T[:3, :3].T - np.eye(3)) / 1e-7
            assert np.allclose((T2[:3, 3] - T[:3, 3]) / 1e-7, J[:3, i], atol=1e-5)
            assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], J[3:, i], atol=1e-5)


def test_candidate_index_is_the_branch(limb, rng):
    out, exact = np.empty((8, 6)), np.zeros(8, dtype=np.bool_)
    checked = 0
    for q in limb.random_q(rng, 200):
        if min(abs(np.sin(q[3])), abs(np.cos(q[4])), abs(np.cos(q[1]))) < 0.05:
            continue  # near a boundary (case formulas reassign theta5)
        limb_candidates(limb.fk(q), limb.chain, limb.lengths_m, True, q, out, exact)
        assert [branch_of(c) for c in out] == list(range(8))
        checked += 1
    assert checked > 100


def test_branch_box_keeps_the_margins(limb):
    lo, hi = np.empty(6), np.empty(6)
    branch_box(READY_RIGHT, branch_of(READY_RIGHT), MARGINS, limb.lower_rad, limb.upper_rad,
               lo, hi)
    assert hi[3] == pytest.approx(-np.arcsin(0.1))            # elbow 0.1 rad from straight
    assert lo[4] == pytest.approx(-np.arccos(0.55)) and hi[4] == pytest.approx(np.arccos(0.55))
    assert lo[1] == pytest.approx(-np.arccos(0.55)) and hi[1] == pytest.approx(0.3)  # limit


def test_reachable_goal_on_the_branch_is_exact(limb, rng):
    branch = branch_of(READY_RIGHT)
    for _ in range(20):
        q_goal = READY_RIGHT + rng.uniform(-0.2, 0.2, 6)
        q = np.empty(6)
        status, pos, rot = solve_limb_on_branch(limb.fk(q_goal), limb.chain, limb.lengths_m,
                                                limb.lower_rad, limb.upper_rad, READY_RIGHT,
                                                branch, MARGINS, 1.0, 0.05, 10, q)
        assert status == EXACT and pos < 1e-9 and rot < 1e-9
        assert np.allclose(q, q_goal, atol=1e-6)


def test_goal_on_another_branch_only_keeps_the_branch(limb):
    q_other = READY_RIGHT.copy()
    q_other[4] = 2.0  # wrist yaw beyond 90 deg: cos(theta5) < 0, another branch
    branch = branch_of(READY_RIGHT)
    assert branch_of(q_other) != branch
    q = np.empty(6)
    status, _, _ = solve_limb_on_branch(limb.fk(q_other), limb.chain, limb.lengths_m,
                                        limb.lower_rad, limb.upper_rad, READY_RIGHT, branch,
                                        MARGINS, 1.0, 0.05, 10, q)
    assert status == NEAREST and branch_of(q) == branch
    assert abs(np.cos(q[4])) >= 0.55 - 1e-9


def test_out_of_reach_goal_gives_the_nearest_position_within_limits(limb, rng):
    """Against sampling: no sampled configuration on the branch (within the margins) lands
    closer to a goal far beyond reach than the search (run to convergence)."""
    T_goal = limb.fk(READY_RIGHT)
    T_goal[:3, 3] += [0.35, -0.10, -0.25]   # well outside the arm's reach
    branch = branch_of(READY_RIGHT)
    q, pos, _ = _nearest(limb, T_goal, READY_RIGHT, branch, w_rot=1e-3, iterations=400)
    assert np.all(q >= limb.lower_rad) and np.all(q <= limb.upper_rad)
    assert branch_of(q) == branch and abs(np.sin(q[3])) >= 0.1 - 1e-9
    lo, hi = np.empty(6), np.empty(6)
    branch_box(READY_RIGHT, branch, MARGINS, limb.lower_rad, limb.upper_rad, lo, hi)
    samples = rng.uniform(lo, hi, size=(200_000, 6))
    sampled = np.min(np.linalg.norm(limb.fk_batch(samples)[:, :3, 3] - T_goal[:3, 3], axis=1))
    assert pos <= sampled + 1e-4
    assert pos > 0.05   # and the goal really is out of reach


def test_nearest_pose_moves_continuously_with_the_goal(limb):
    """A goal sliding 1 mm per call out of reach: no jump of the joints (a branch flip is a
    radian or more; the exact path itself speeds up as the elbow straightens)."""
    branch = branch_of(READY_RIGHT)
    T0 = limb.fk(READY_RIGHT)
    q = READY_RIGHT.copy()
    steps = []
    for k in range(400):
        T = T0.copy()
        T[:3, 3] += np.array([0.0006, -0.0002, -0.0008]) * k
        q_next, _, _ = _nearest(limb, T, q, branch)
        steps.append(np.max(np.abs(q_next - q)))
        q = q_next
    assert max(steps) < 0.2 and np.median(steps) < 0.02   # rad per 1 mm of goal motion
    assert np.linalg.norm(limb.fk(q)[:3, 3] - T[:3, 3]) > 0.02  # it did end out of reach


def test_reach_settings_are_validated():
    with pytest.raises(ConfigError):
        ReachSettings(mode="closest")
    with pytest.raises(ConfigError):
        ReachSettings(orientation_weight_m_per_rad=0.0)
    with pytest.raises(ConfigError):
        ArmReach(get_limb("right-leg"))


def test_paper_mode_is_the_five_centimetre_rule(limb):
    T_far = limb.fk(READY_RIGHT)
    T_far[0, 3] += 0.5
    reach = ArmReach(limb, ReachSettings(mode="paper"))
    reach.start(READY_RIGHT)
    assert reach.solve(T_far, READY_RIGHT).status == "held"
    nearest = ArmReach(limb)
    nearest.start(READY_RIGHT)
    assert nearest.solve(T_far, READY_RIGHT).status == "nearest"



@pytest.mark.parametrize("mode", ["nearest", "paper"])
def test_solve_into_is_solve_without_the_result_object(limb, rng, mode):
    reach = ArmReach(limb, ReachSettings(mode=mode))
    reach.start(READY_RIGHT)
    for k in range(60):  # reachable goals, and goals up to 0.6 m beyond the reach
        T = limb.fk(limb.random_q(rng))
        T[:3, 3] += rng.uniform(-0.3, 0.3, 3) * (k % 3)
        result = reach.solve(T, READY_RIGHT)
        q = np.empty(6)
        code, pos, rot = reach.solve_into(T, READY_RIGHT, q)
        assert STATUS_NAMES[code] == result.status
        assert (pos, rot) == (result.position_error_m, result.rotation_error_rad)
        assert np.array_equal(q, result.q_rad)
        # solve is solve_into's wrapper: the errors it reports are checked by the arm's own
        # forward kinematics (measured to 4.4e-16 m and rad)
        T_q = limb.fk(q)
        R_error = T_q[:3, :3].T @ T[:3, :3]
        assert np.linalg.norm(T_q[:3, 3] - T[:3, 3]) == pytest.approx(pos, abs=1e-9)
        angle_rad = np.arccos(np.clip((np.trace(R_error) - 1) / 2, -1, 1))
        assert angle_rad == pytest.approx(rot, abs=1e-6)

def test_branch_move_is_slow_and_ends_on_the_new_branch(limb):
    reach = ArmReach(limb)
    reach.start(READY_RIGHT)
    q_other = READY_RIGHT.copy()
    q_other[4] = 2.0
    found = reach.other_branch(limb.fk(q_other), READY_RIGHT)
    assert found is not None and branch_of(found) != reach.branch
    move = reach.plan_branch_move(READY_RIGHT, found, t_s=1.0)
    t = np.arange(1.0, 1.0 + move.duration_s + 0.01, 0.005)
    Q = np.array([move.at(ti)[0] for ti in t])
    speed = np.max(np.abs(np.diff(Q, axis=0)) / 0.005, axis=0)
    assert np.all(speed <= 0.25 * limb.spec.velocity_rad_s + 1e-3)
    assert move.at(t[-1])[1] and np.allclose(Q[-1], found)


def test_condition_number_grows_toward_the_straight_elbow(limb):
    kappas = []
    for elbow in (-1.4, -0.5, -0.2, -0.05):
        q = READY_RIGHT.copy()
        q[3] = elbow
        kappas.append(condition_number(limb, q))
    assert kappas == sorted(kappas) and kappas[0] < 15 and kappas[-1] > 150


def test_singularity_scale_has_two_thresholds():
    s = SingularityScale(lower=50, hard=100, floor=0.5)
    assert s.scale(20, 40) == 1.0
    assert s.scale(150, 200) == 0.5
    approaching, leaving = s.scale(70, 75), s.scale(75, 70)
    assert 0.5 < approaching < leaving < 1.0
    assert SingularityScale.off().scale(1e6, 1e9) == 1.0   # off: never slows


def test_max_excursion_uses_the_nearest_goal_within_a_second():
    t = np.arange(0.0, 4.0, 0.01)
    goals = np.column_stack([0.1 * t, np.zeros_like(t), np.zeros_like(t)])  # 10 cm/s along x
    lagging = np.concatenate([np.repeat(goals[:1], 50, axis=0), goals[:-50]])  # 0.5 s behind
    assert max_excursion_m(t, goals, lagging) < 1e-9
    swing = lagging.copy()
    swing[200, 1] = 0.08                        # one 8 cm sideways swing
    assert max_excursion_m(t, goals, swing) == pytest.approx(0.08, abs=1e-9)


def test_steady_following_starts_a_second_after_the_goal_comes_back_into_reach():
    t = np.arange(0.0, 6.0, 0.005)
    reachable = ~((t >= 2.0) & (t < 3.0))          # out of reach from 2 s to 3 s
    steady = steady_mask(t, reachable)
    assert steady[t < 2.0].all()                    # reachable from the start: no return
    assert not steady[(t >= 2.0) & (t < 3.99)].any()  # out of reach, then the return's second
    assert steady[t >= 4.0].all()
    assert steady_mask(t, reachable, return_window_s=0.5)[(t >= 3.5)].all()
    flicker = reachable & ~np.isclose(t, 4.5)       # one period out of reach again
    assert not steady_mask(t, flicker)[(t > 4.5) & (t < 5.49)].any()
    assert steady_mask(t[:0], reachable[:0]).shape == (0,)
