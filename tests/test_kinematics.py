"""Closed-form IK against FK: all eight candidates, singular cases, mirror symmetry, choice."""

import numba as nb
import numpy as np
import pytest

from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.choice import limb_candidates
from hubo_cli.kinematics.dh import PARALLEL_MIN_ROWS, in_threads, pose_error

LIMBS = ["right-arm", "left-arm", "right-leg", "left-leg"]
MIRROR_SIGNS = {"arm": np.array([1, -1, -1, 1, -1, 1]), "leg": np.array([-1, -1, 1, 1, 1, -1])}
PAPER_Q_RIGHT = np.array([-0.9914, -0.3651, -0.8339, -1.1618, -1.6542, 0.8894])
PAPER_Q_LEFT = np.array([-1.1853, 0.1213, 1.1383, -1.2893, -1.8826, -1.1184])


def _near_singular(limb, q, margin=1e-3):
    """Elbow/knee almost straight, or shoulder/hip roll almost at +-pi/2 (q: (6,) or (N, 6))."""
    q = np.asarray(q)
    return (np.abs(np.sin(q[..., 3])) < margin) | (np.abs(np.cos(q[..., 1])) < margin)


def _pose_errors(T, T_goal):
    """:func:`pose_error` over arrays of transforms (..., 4, 4): position (m), angle (rad)."""
    pos = np.linalg.norm(T[..., :3, 3] - T_goal[..., :3, 3], axis=-1)
    E = np.swapaxes(T_goal[..., :3, :3], -1, -2) @ T[..., :3, :3]
    v = np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0],
                  E[..., 1, 0] - E[..., 0, 1]], axis=-1)
    cos_angle = 0.5 * (np.trace(E, axis1=-2, axis2=-1) - 1.0)
    return pos, np.arctan2(0.5 * np.linalg.norm(v, axis=-1), cos_angle)


@pytest.mark.parametrize("name", LIMBS)
def test_all_eight_candidates_reproduce_the_pose(name, rng):
    limb = get_limb(name, "drill")
    Q = limb.random_q(rng, 10_000)
    T_goals = limb.fk_batch(Q)
    out = np.empty((len(Q), 8, 6))
    exact = np.zeros((len(Q), 8), dtype=np.bool_)
    for k in range(len(Q)):
        limb_candidates(T_goals[k], limb.chain, limb.lengths_m, limb.spec.is_arm, Q[k], out[k],
                        exact[k])
    # every candidate's FK against its goal, all at once
    T_c = limb.fk_batch(out.reshape(-1, 6)).reshape(len(Q), 8, 4, 4)
    pos, rot = _pose_errors(T_c, T_goals[:, None])
    k = 123  # the array errors are pose_error's
    assert np.allclose([pos[k, 0], rot[k, 0]], pose_error(T_c[k, 0], T_goals[k]), atol=1e-12)
    failed = (np.maximum(pos, rot).max(axis=1) > 1e-9) | ~exact.all(axis=1)
    original_missing = ((np.abs(out - Q[:, None]).max(axis=2).min(axis=1) > 1e-6)
                        & ~_near_singular(limb, Q))
    assert failed.sum() <= 100, f"{failed.sum()} of 10000 configurations failed"
    assert _near_singular(limb, Q[failed], 1e-2).all(), "a failure is not near-singular"
    assert not original_missing.any()


@pytest.mark.parametrize("q", [
    [0.3, -0.2, 0.4, 0.0, 0.5, 0.1],              # case 1: elbow straight
    [0.3, -np.pi / 2, 0.4, -1.0, 0.5, 0.1],       # case 2: right shoulder roll at -pi/2
    [0.3, -np.pi / 2, 0.4, 0.0, 0.5, 0.1],        # case 3: both
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],               # arm hanging straight down
])
def test_right_arm_singular_configurations_are_exact(q):
    limb = get_limb("right-arm", "hand")
    q = np.array(q)
    result = limb.solve(limb.fk(q), q)
    assert result.status == "exact"
    assert result.position_error_m < 1e-12 and result.rotation_error_rad < 1e-12
    for c in limb.candidates(limb.fk(q), q):
        assert c.exact, c


@pytest.mark.parametrize("q", [[0.3, np.pi / 2, 0.4, -1.0, 0.5, 0.1],
                               [0.3, np.pi / 2, 0.4, 0.0, 0.5, 0.1]])
def test_left_arm_shoulder_singularities_are_exact(q):
    limb = get_limb("left-arm", "hand")
    q = np.array(q)
    assert all(c.exact for c in limb.candidates(limb.fk(q), q))


@pytest.mark.parametrize("name", ["right-leg", "left-leg"])
def test_straight_knee_is_exact(name):
    limb = get_limb(name)
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    result = limb.solve(limb.fk(q))
    assert result.status == "exact" and np.allclose(result.q_rad, 0.0, atol=1e-9)
    assert all(c.exact for c in limb.candidates(limb.fk(q), q))


@pytest.mark.parametrize("kind", ["arm", "leg"])
def test_left_and_right_are_mirror_images(kind, rng):
    """Hand and sole frames mirror through the x-z plane (the drill only sits on the right)."""
    right, left = get_limb(f"right-{kind}", "hand"), get_limb(f"left-{kind}", "hand")
    M = np.diag([1.0, -1.0, 1.0, 1.0])
    signs = MIRROR_SIGNS[kind]
    Q = right.random_q(rng, 500)
    assert np.allclose(left.fk_batch(Q * signs), M @ right.fk_batch(Q) @ M, atol=1e-12)
    # the limits mirror too, except the wrist yaw the paper lists identically for both arms
    mirrored = [j for j in range(6) if not (kind == "arm" and j == 4)]
    lo_mirror = np.where(signs > 0, right.lower_rad, -right.upper_rad)
    hi_mirror = np.where(signs > 0, right.upper_rad, -right.lower_rad)
    assert np.allclose(left.lower_rad[mirrored], lo_mirror[mirrored])
    assert np.allclose(left.upper_rad[mirrored], hi_mirror[mirrored])


@pytest.mark.parametrize("name", LIMBS)
def test_far_out_of_reach_is_never_exact(name, rng):
    limb = get_limb(name, "drill")
    direction = rng.normal(size=(1000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    T = np.tile(np.eye(4), (1000, 1, 1))
    T[:, :3, 3] = limb.T_N_base[:3, 3] + direction * rng.uniform(1.5, 5.0, size=(1000, 1))
    batch = limb.solve_batch(T)
    assert not np.any(batch.status == 0)
    assert np.all(batch.position_error_m > 0.5)
    for k in range(0, 1000, 50):
        assert not any(c.exact for c in limb.candidates(T[k]))
        assert limb.solve(T[k]).status == "unreachable"


def test_paper_drill_points_reproduce_section_iv():
    """The paper's two extreme joint vectors (section IV), as-built lengths, 7-inch drill."""
    limb = get_limb("right-arm", "drill")
    T_right, T_left = limb.fk(PAPER_Q_RIGHT), limb.fk(PAPER_Q_LEFT)
    for T in (T_right, T_left):
        assert T[0, 3] * 1000 == pytest.approx(484, abs=1)
        assert T[2, 3] * 1000 == pytest.approx(75, abs=1)
        assert np.degrees(np.arccos(np.clip(T[0, 0], -1, 1))) < 0.01  # bit along N's x
    assert (T_left[1, 3] - T_right[1, 3]) * 1000 == pytest.approx(390, abs=2)


def test_table1_lengths_put_the_points_elsewhere():
    limb = get_limb("right-arm", "drill", params="table1")
    T_right, T_left = limb.fk(PAPER_Q_RIGHT), limb.fk(PAPER_Q_LEFT)
    assert T_right[0, 3] * 1000 == pytest.approx(401, abs=2)
    assert (T_left[1, 3] - T_right[1, 3]) * 1000 == pytest.approx(362, abs=2)


def test_choice_prefers_previous_joints_then_smallest_norm():
    limb = get_limb("right-arm", "drill")
    T = limb.fk(PAPER_Q_RIGHT)
    exact_in_limits = [c for c in limb.candidates(T) if c.exact and c.within_limits]
    assert exact_in_limits
    smallest = min(exact_in_limits, key=lambda c: float(np.sum(c.q_rad ** 2)))
    assert np.allclose(limb.solve(T).q_rad, smallest.q_rad)
    assert np.allclose(limb.solve(T, PAPER_Q_RIGHT).q_rad, PAPER_Q_RIGHT, atol=1e-9)


def test_capped_held_and_unreachable():
    limb = get_limb("right-arm", "drill")
    T = limb.fk(PAPER_Q_RIGHT)
    # a little beyond the reach: capped to the limits, within 5 cm, and says how far it misses
    near = T.copy()
    near[1, 3] -= 0.02
    capped = limb.solve(near, PAPER_Q_RIGHT)
    assert capped.status in ("capped", "held")
    if capped.status == "capped":
        assert 1e-6 < capped.position_error_m <= 0.05
        assert np.all(capped.q_rad >= limb.lower_rad) and np.all(capped.q_rad <= limb.upper_rad)
        assert capped.position_error_m == pytest.approx(
            np.linalg.norm(limb.fk(capped.q_rad)[:3, 3] - near[:3, 3]))
    far = T.copy()
    far[0, 3] += 1.0
    held = limb.solve(far, PAPER_Q_RIGHT)
    assert held.status == "held" and np.array_equal(held.q_rad, PAPER_Q_RIGHT)
    assert held.position_error_m == pytest.approx(1.0)
    assert limb.solve(far).status == "unreachable"


def test_capped_solution_is_reported_when_within_five_centimetres():
    """A goal just outside the joint limits but within 5 cm after capping is 'capped'."""
    limb = get_limb("right-arm", "hand")
    q = np.array([0.0, 0.0, 0.0, -0.5, 0.0, 0.0])
    q_out = q.copy()
    q_out[0] = limb.upper_rad[0] + 0.05  # shoulder pitch 0.05 rad past its limit
    T = limb.fk(q_out)
    result = limb.solve(T, q)
    assert result.status == "capped"
    assert 0 < result.position_error_m < 0.05
    assert result.q_rad[0] == pytest.approx(limb.upper_rad[0])


@pytest.mark.parametrize("name", LIMBS)
def test_batch_equals_scalar(name, rng):
    limb = get_limb(name, "drill")
    Q = limb.random_q(rng, 300)
    T = limb.fk_batch(Q)
    T[::3, 0, 3] += 0.3  # some unreachable goals too
    batch = limb.solve_batch(T, Q)
    for i in range(len(Q)):
        one = limb.solve(T[i], Q[i])
        assert one.status == batch.status_names()[i]
        assert np.allclose(one.q_rad, batch.q_rad[i])


def test_fk_batch_equals_scalar(rng):
    limb = get_limb("left-arm", "hand")
    Q = limb.random_q(rng, 50)
    assert np.allclose(limb.fk_batch(Q), np.array([limb.fk(q) for q in Q]), atol=1e-15)


@pytest.mark.parametrize("n", [0, 1, PARALLEL_MIN_ROWS * 2 - 1, 1000])
def test_in_threads_runs_every_row_once(n):
    """The batched kernels' row split: contiguous parts covering every row exactly once, one
    part per numba thread (at most one per PARALLEL_MIN_ROWS rows)."""
    runs = []
    in_threads(n, lambda i0, i1: runs.append((i0, i1)))
    runs.sort()
    assert runs[0][0] == 0 and runs[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(runs[:-1], runs[1:], strict=True))
    assert len(runs) == max(1, min(nb.get_num_threads(), n // PARALLEL_MIN_ROWS))
