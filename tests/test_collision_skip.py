"""The collision detector's Lipschitz skip: the bound never exceeds the exact distance, and a
detector that skips holds in the same period, with the same output, as one that checks always."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.control.collision import (
    FLAT_RAD,
    SHAPE_KINDS,
    CollisionDetector,
    SelfCollisionChecker,
    _lower_bound,
    _support,
    _witness_unique,
)
from hubo_cli.control.module import Cycle
from hubo_cli.dataflow import Store
from hubo_cli.model import LEGS
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

GJK_M = 1e-5  # coal's distances: exact to its GJK tolerance, 1e-6 m (ten times that here)


def _legs_mask(model) -> np.ndarray:
    legs = np.zeros(len(model.joint_names), dtype=bool)
    for name in LEGS:
        legs[model.limb_slice(name)] = True
    return legs


@pytest.mark.parametrize("drill", [False, True])
def test_the_lipschitz_bound_never_exceeds_the_exact_distance(model, drill):
    """Random postures q0 and random offsets (all joints, the legs alone, one arm alone; 1 mrad
    to 0.6 rad): every pair's exact distance at the input, on its way to the stopping posture
    and at corners of the box around q0 is at least the bound from q0, the smallest one at
    least what the detector's bound reports. Also when q0's distances came from a check that
    reused the pairs the legs do not move. coal's distances are exact to its GJK tolerance
    (1e-6 m; the detector keeps SKIP_MARGIN_M beyond the band), so the bound is allowed that."""
    rng = np.random.default_rng(11 + drill)
    lower, upper = model.lower_rad, model.upper_rad
    legs = _legs_mask(model)
    right = np.zeros_like(legs)
    right[model.limb_slice("right-arm")] = True
    anchor = SelfCollisionChecker(model, drill=drill)
    exact = SelfCollisionChecker(model, drill=drill)
    rate = anchor.rate_m_rad
    assert (rate >= 0).all() and rate.shape == (len(anchor.pair_names), len(lower))
    assert rate[:, legs].any() and rate[:, right].any()  # thighs move with the legs
    # the kernels' lists: every joint with a rate, in order (each moves one of its pair's shapes)
    for p in range(len(rate)):
        listed = anchor.pair_joints[p][anchor.pair_joints[p] >= 0]
        assert (np.diff(listed) > 0).all() and set(np.flatnonzero(rate[p] > 0.0)) <= set(listed)
        assert (anchor.pair_rates[p, :len(listed)] == rate[p, listed]).all()
    tightest_m = np.inf
    for k in range(60):
        q0 = rng.uniform(lower, upper)
        if k % 3 == 0:  # the legs moved alone since the last check: the split check
            anchor.check(np.where(legs, rng.uniform(lower, upper), q0))
        anchor.check(q0)
        d0 = anchor.pair_distances_m()
        moved = [np.ones_like(legs), legs, right][k % 3]
        size = rng.choice([0.001, 0.02, 0.1, 0.6])
        q_in, ahead = (np.clip(q0 + moved * rng.uniform(-size, size, q0.size), lower, upper)
                       for _ in range(2))
        near_m, _, far_m, _ = _lower_bound(q_in, ahead, np.tile(q0, (len(d0), 1)), d0,
                                           anchor.pair_joints, anchor.pair_rates)
        # the kernel loops over each pair's own joints: every joint with a rate, in order
        bound_in = [d0[p] - sum(rate[p, j] * abs(q_in[j] - q0[j])
                                for j in np.flatnonzero(rate[p] > 0.0)) for p in range(len(d0))]
        assert near_m == pytest.approx(min(bound_in), abs=1e-12)
        reach = np.maximum(np.abs(q_in - q0), np.abs(ahead - q0))
        corners = [q0 + reach * rng.choice([-1.0, 1.0], q0.size) for _ in range(2)]
        way = [q_in + s * (ahead - q_in) for s in (0.25, 0.5, 1.0)]
        for i, q in enumerate([q_in, *way, *corners]):
            exact.check(q)
            d = exact.pair_distances_m()
            bound = d0 - rate @ np.abs(q - q0)
            assert (d >= bound - GJK_M).all(), (k, i, float((d - bound).min()))
            assert d.min() >= far_m - GJK_M
            tightest_m = min(tightest_m, float((d - bound).min()))
        assert exact.check(q_in).distance_m >= near_m - GJK_M
    assert tightest_m < 0.05  # the samples came near the bound somewhere


@pytest.mark.parametrize("drill, repeatable", [(False, False), (True, False), (True, True)])
def test_check_near_is_exact_within_the_band_and_a_lower_bound_beyond(model, drill, repeatable):
    """Straight moves between random postures (in and out of the body; 30 steps each, one
    arm or every joint): check_near, which computes only the pairs whose bound from their own
    last distance comes within the band, reports the exact closest pair wherever that is
    within the band, and beyond it a value above the band and never above the exact one;
    each pair's stored distance stays exact at its stored posture, and bounds every later
    posture's exact distance. It computes few of the pairs."""
    rng = np.random.default_rng(5 + drill)
    lower, upper = model.lower_rad, model.upper_rad
    right = np.zeros(len(lower), dtype=bool)
    right[model.limb_slice("right-arm")] = True
    near = SelfCollisionChecker(model, drill=drill, repeatable=repeatable)
    exact = SelfCollisionChecker(model, drill=drill)
    band_m = 0.012
    a = home_posture(model)
    within = beyond = computed = 0
    for k in range(24):
        b = np.where(right if k % 2 else True, rng.uniform(lower, upper), a)
        for q in a + np.linspace(0.0, 1.0, 31)[1:, None] * (b - a):
            got, want = near.check_near(q, band_m), exact.check(q)
            computed += int((near.anchor_q == q).all(axis=1).sum())
            if want.distance_m <= band_m:
                within += 1
                assert abs(got.distance_m - want.distance_m) <= GJK_M, k
            else:
                beyond += 1
                assert band_m < got.distance_m <= want.distance_m + GJK_M, k
            bound = near.anchor_m - np.einsum("pj,pj->p", near.rate_m_rad,
                                              np.abs(q - near.anchor_q))
            assert (exact.pair_distances_m() >= bound - GJK_M).all(), k
        a = b
    assert within > 100 and beyond > 100  # both sides of the band were walked
    assert computed < 0.4 * 24 * 30 * len(near.pair_names)  # most pairs only bounded
    for p, q0 in enumerate(near.anchor_q):  # the stored distances are the exact ones
        exact.check(q0)
        assert abs(exact.pair_distances_m()[p] - near.anchor_m[p]) <= GJK_M, p


def test_a_repeatable_checker_gives_the_same_distances_at_the_same_joints(model):
    """The default checker's distances at the same joints differ after other postures were
    computed (pinocchio's requests start GJK from the last answer; measured: in about half of
    the pairs, up to 1.5e-6 m); the repeatable one's are the same to the last bit, computed
    again (``check``) or taken from the unmoved pairs (``check_near``), whatever came between."""
    rng = np.random.default_rng(21)
    lower, upper = model.lower_rad, model.upper_rad
    cached = SelfCollisionChecker(model, drill=True)
    repeatable = SelfCollisionChecker(model, drill=True, repeatable=True)
    near = SelfCollisionChecker(model, drill=True, repeatable=True)
    differed = 0
    for _ in range(40):
        q, between = rng.uniform(lower, upper, (2, len(lower)))
        first = []
        for checker in (cached, repeatable):
            checker.check(q)
            first.append(checker.pair_distances_m())
            checker.check(between)
            checker.check(q + 1e-3)  # the joints moved (every pair computed again)
            checker.check(q)
        differed += int((cached.pair_distances_m() != first[0]).any())
        assert np.array_equal(repeatable.pair_distances_m(), first[1])
        got = near.check_near(q, 0.05)
        anchors = near.anchor_q.copy()
        again = near.check_near(q, 0.05)  # nothing computed a second time: the same
        assert (again.distance_m, again.pair) == (got.distance_m, got.pair)
        assert np.array_equal(near.anchor_q, anchors)
        near.check_near(between, 0.05)
        near.check_near(np.where(rng.random(len(q)) < 0.5, between, q), 0.05)
        later = near.check_near(q, 0.05)  # within the band: exact to GJK's tolerance
        if min(later.distance_m, got.distance_m) <= 0.05:
            assert abs(later.distance_m - got.distance_m) <= GJK_M
    assert differed > 10  # the default checker's did differ


def _support_span(kind: str, R: np.ndarray, n: np.ndarray) -> list[np.ndarray]:
    """The supports as the Python code had them (the compiled :func:`_support` is held to it):
    the directions along which a shape touches its supporting plane of normal +-n."""
    if kind == "point":
        return []
    if kind == "flat":
        return [R[:, 0], R[:, 1]]
    cos = (n @ R).tolist()
    if kind == "box":
        return [R[:, k] for k in range(3) if abs(cos[k]) < FLAT_RAD]
    along = abs(cos[2])
    if along < FLAT_RAD:
        return [R[:, 2]]
    if kind == "cylinder" and 1.0 - along * along < FLAT_RAD * FLAT_RAD:
        return [R[:, 0], R[:, 1]]
    return []


def _witness_not_unique(span_1: list, span_2: list) -> bool:
    if not span_1 or not span_2:
        return False
    if len(span_1) == 2 or len(span_2) == 2:
        return True
    sine = np.cross(span_1[0], span_2[0])
    return np.sqrt(sine @ sine) < FLAT_RAD


def _span(kind: str, R: np.ndarray, n: np.ndarray) -> int:
    return _support(SHAPE_KINDS.index(kind), R, n, np.empty(3))


def test_the_witness_points_are_unique_unless_flat_meets_flat():
    """The supports' shapes: a sphere touches at a point; a box at a corner, along an edge or a
    face as the normal meets its axes; a cylinder at its rim, along its side or its cap. Two
    supports meet in more than a point when one is a face and the other not a point, or both
    are parallel edges (then distance_gradient declines)."""
    R = np.eye(3)
    x, z = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    tilted = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
    assert _span("point", R, x) == 0
    assert _span("box", R, x) == 2 and _span("box", R, tilted) == 0
    assert _span("box", R, np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)) == 1
    assert _span("cylinder", R, z) == 2 and _span("capsule", R, z) == 0
    assert _span("cylinder", R, x) == 1
    assert _span("cylinder", R, tilted) == 0
    box, cylinder = SHAPE_KINDS.index("box"), SHAPE_KINDS.index("cylinder")
    Rz = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # its z along x
    assert not _witness_unique(box, R, cylinder, R, x)  # a face on an edge
    assert not _witness_unique(box, R, box, R, x)  # a face on a face
    assert not _witness_unique(cylinder, R, cylinder, R, x)  # parallel sides
    assert _witness_unique(cylinder, R, cylinder, Rz, np.array([0.0, 1.0, 0.0]))  # crossed
    assert _witness_unique(SHAPE_KINDS.index("point"), R, box, R, x)


def test_the_compiled_supports_decide_as_the_python_code(rng):
    """The compiled supports (:func:`_witness_unique`) decide as the Python code did, on drawn
    rotations and normals and on normals within a few ulp of FLAT_RAD of an axis, each pair of
    shape kinds."""
    def near_axis(R, k):  # a normal meeting axis k at about FLAT_RAD, either side
        other = R[:, (k + 1) % 3]
        angle = FLAT_RAD * (1.0 + rng.choice([-1.0, 1.0]) * rng.integers(0, 4) * 1e-16)
        n = np.sin(angle) * R[:, k] + np.cos(angle) * other
        return n / np.linalg.norm(n)

    for trial in range(3000):
        R_1, R_2 = (np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2))
        if trial % 3 == 0:
            n = rng.normal(size=3)
            n /= np.linalg.norm(n)
        elif trial % 3 == 1:
            n = near_axis(R_1, int(rng.integers(3)))
        else:  # the other's axes nearly parallel to the first's too
            n = near_axis(R_1, 2)
            R_2 = R_1 @ np.linalg.qr(np.eye(3) + 1e-3 * rng.normal(size=(3, 3)))[0]
        for kind_1 in SHAPE_KINDS:
            for kind_2 in SHAPE_KINDS:
                expected = not _witness_not_unique(_support_span(kind_1, R_1, n),
                                                   _support_span(kind_2, R_2, n))
                got = _witness_unique(SHAPE_KINDS.index(kind_1), R_1,
                                      SHAPE_KINDS.index(kind_2), R_2, n)
                assert got == expected, (kind_1, kind_2, R_1, R_2, n)


def test_the_distance_gradient_is_the_finite_difference(model):
    """distance_gradient (coal's witness points and normal, the shapes' point Jacobians) against
    central differences (1e-4 rad) of each pair's distance, over random postures with and
    without the drill: away from the distance's kinks (where differences of 1e-4 and 5e-4 rad
    disagree by more than 1e-4 m/rad, or the pair touches) they agree; it declines (None) where
    the witness points are not unique (a face against a face) and where the shapes overlap."""
    rng = np.random.default_rng(31)
    lower, upper = model.lower_rad, model.upper_rad
    columns = np.arange(len(lower))
    compared = declined = 0
    worst = 0.0
    for drill in (False, True):
        checker = SelfCollisionChecker(model, drill=drill, repeatable=True)

        def distances(q, checker=checker):  # every pair, exact (computed or unmoved)
            checker.check_near(q, np.inf)
            return checker.anchor_m.copy()

        for _ in range(25):
            q = rng.uniform(lower, upper)
            d = distances(q)
            for p in rng.choice(len(d), 6, replace=False):
                gradient = checker.distance_gradient(q, int(p), columns)
                if d[p] <= 0.0:  # overlapping
                    assert gradient is None
                if gradient is None:
                    declined += 1
                    continue
                fd = []
                for h in (1e-4, 5e-4):
                    fd.append(np.array([(distances(q + h * e)[p] - distances(q - h * e)[p])
                                        / (2 * h) for e in np.eye(len(q))]))
                if np.abs(fd[0] - fd[1]).max() > 1e-4:
                    continue  # a kink within 5e-4 rad
                worst = max(worst, float(np.abs(gradient - fd[0]).max()))
                compared += 1
    # measured: the largest difference 3.9e-4 m/rad over 297 compared gradients (gradients of
    # 0.01-1 m/rad), 1 declined (overlapping), 2 near a kink; bounds 2.5x and 2x from those
    assert worst < 1e-3
    assert compared > 150 and declined < 20


def _smooth(a, b, n):
    s = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, n))
    return a + s[:, None] * (b - a)


def _drive(model, drill, inputs, skip):
    dt = model.control_period_s
    detector = CollisionDetector(model, dt, drill=drill)
    detector.skip = skip
    state = RobotState(0.0, inputs[0], np.zeros(len(inputs[0])))
    detector.reset(inputs[0], state, Store())
    outs, modes, ahead = [], [], []
    for k, q in enumerate(inputs):
        cycle = Cycle(k * dt, dt)
        outs.append(detector.update(q, state, cycle))
        modes.append((detector.mode, frozenset(cycle.flags)))
        ahead.append((cycle.info["collision_ahead_m"], cycle.info["collision_distance_m"]))
    return detector, np.array(outs), modes, np.array(ahead)


@pytest.mark.parametrize("drill", [False, True])
def test_skipping_does_not_delay_a_hold(model, drill):
    """Moves from clear postures into the body (the right forearm creeping into the pelvis over
    7.5 s, where the bound follows the distance closest; random fast moves whose way crosses
    the body), held, then back out: the skipping detector holds and recovers
    in the same periods with the same outputs as one that checks every period, skips a fair
    share of the clear periods, and never logs more clearance than the exact check finds."""
    rng = np.random.default_rng(3 + drill)
    checker = SelfCollisionChecker(model, drill=drill)
    home = home_posture(model)
    inward = home.copy()
    inward[1] = 0.3  # the right arm rolled in: its forearm meets the pelvis
    moves = [(home, inward)]
    while len(moves) < 3:
        a, b = home.copy(), home.copy()
        a[:12], b[:12] = (rng.uniform(model.lower_rad[:12], model.upper_rad[:12])
                          for _ in range(2))
        way = [checker.check(q).distance_m for q in _smooth(a, b, 40)]
        if min(way[0], way[-1]) > 0.05 and min(way) < -0.01:
            moves.append((a, b))
    for m, (a, b) in enumerate(moves):
        n = 1500 if m == 0 else int(rng.integers(150, 400))  # a slow creep, then fast moves
        inputs = np.vstack([np.repeat(a[None], 20, axis=0), _smooth(a, b, n),
                            np.repeat(b[None], 40, axis=0), _smooth(b, a, n),
                            np.repeat(a[None], 200, axis=0)])
        always, out_always, modes_always, logged_always = _drive(model, drill, inputs, False)
        skipping, out_skip, modes_skip, logged_skip = _drive(model, drill, inputs, True)
        assert always.events, "the premise: the move is held"
        assert [(e.t_s, e.kind, e.sources) for e in skipping.events] == \
            [(e.t_s, e.kind, e.sources) for e in always.events]
        assert modes_skip == modes_always
        assert np.array_equal(out_skip, out_always)
        assert always.skipped_periods == 0
        safe = sum(mode == "safe" for mode, _ in modes_always)
        assert skipping.skipped_periods > 0.2 * safe  # most clear periods skip
        assert (logged_skip <= logged_always + GJK_M).all()  # a bound: never more clearance


def test_a_checker_without_pairs_skips_nothing(model):
    """No pairs: no rates, and every check is clear (an infinite distance)."""
    checker = SelfCollisionChecker(model, pairs=[])
    assert checker.rate_m_rad.shape == (0, len(model.joint_names))
    assert checker.check(home_posture(model)).distance_m == np.inf


@pytest.fixture
def right_arm_moves(model):
    """The right arm's moves from a drawn posture (the rest at home) by up to 0.3 rad a joint:
    ``right_arm_moves(rng)`` yields 30 pairs (a, b), drawn from ``rng`` as the loop asks for
    them (a test may draw from ``rng`` between them)."""
    lower, upper = model.lower_rad, model.upper_rad
    right = model.limb_slice("right-arm")

    def moves(rng):
        for _ in range(30):
            a = home_posture(model)
            a[right] = rng.uniform(lower[right], upper[right])
            b = a.copy()
            b[right] += rng.uniform(-0.3, 0.3, 6)
            yield a, b
    return moves


def test_a_repeatable_checker_takes_the_posture_before_again(model, right_arm_moves):
    """A repeatable checker keeps each pair's two last distances: going back to the posture
    before (a still goal's, every other check in the teleop's collision room) computes no pair
    and gives the same closest pair to the last bit, and a posture near either one computes
    only the pairs near the band; the checker that keeps one (the pipeline's) computes them
    again."""
    keeps_two = SelfCollisionChecker(model, drill=True, repeatable=True)
    keeps_one = SelfCollisionChecker(model, drill=True)
    again = 0
    for a, b in right_arm_moves(np.random.default_rng(41)):
        first = keeps_two.check_near(a, 0.065)
        keeps_two.check_near(b, 0.065)
        back = keeps_two.check_near(a, 0.065)
        assert not keeps_two._near.any()  # no pair computed
        assert (back.distance_m, back.pair) == (first.distance_m, first.pair)
        for checker in (keeps_two, keeps_one):
            checker.check_near(a, 0.065)
            checker.check_near(b, 0.065)
        keeps_one.check_near(a, 0.065)
        again += int(keeps_one._near.sum())
        near = keeps_two.check_near(a + 1e-6, 0.065)  # bounded by its distances at a
        assert np.count_nonzero(keeps_two._near) <= np.count_nonzero(
            keeps_two.anchor_m <= 0.065 + 2e-5)
        assert abs(near.distance_m - first.distance_m) <= 1e-4 or min(
            near.distance_m, first.distance_m) > 0.065
    assert again > 30  # the one-distance checker did compute pairs again


def test_the_posture_before_is_a_pairs_own_joints(model, right_arm_moves):
    """A pair's posture before is matched on the joints that move its shapes only: the right
    arm back at its joints before after the legs and the left arm moved (the teleop room's
    search starts so from the arm's last target, every period) computes none of the right
    arm's pairs the legs and the left arm do not move, and the check is what a checker that
    computes every pair gives, to the last bit (pinocchio places a shape from its own chain's
    joints only)."""
    rng = np.random.default_rng(47)
    lower, upper = model.lower_rad, model.upper_rad
    right = model.limb_slice("right-arm")
    checker = SelfCollisionChecker(model, drill=True, repeatable=True)
    exact = SelfCollisionChecker(model, drill=True, repeatable=True)
    rate = checker.rate_m_rad
    own = rate[:, right].max(axis=1) > 0.0  # the pairs the right arm moves
    reused = 0
    for a, b in right_arm_moves(rng):
        c = np.clip(a + rng.uniform(-0.05, 0.05, len(a)), lower, upper)
        c[right] = a[right]  # the legs and the left arm moved, the right arm back at a
        checker.check_near(a, 0.065, own)
        near_at_a = checker._near.copy()  # computed at a
        checker.check_near(b, 0.065, own)
        near_at_b = checker._near.copy()  # ... and at b: a's distance is the one before
        got = checker.check_near(c, 0.065, own)
        # (the joints a pair shares with the right arm's shapes stand: its rates tell)
        moved = ((rate > 0.0) & (c != a)).any(axis=1)
        assert not (checker._near & own & ~moved & near_at_a).any()
        reused += int((own & ~moved & near_at_a & near_at_b).sum())
        exact.check(c)
        distances = np.where(own, exact.pair_distances_m(), np.inf)
        if distances.min() <= 0.065:  # (beyond the band: a lower bound, from earlier checks)
            best = int(np.argmin(distances))
            assert (got.distance_m, got.pair) == (distances[best], exact.pair_names[best])
        else:
            assert got.distance_m > 0.065
    assert reused > 200  # the case was met (measured: 410 pairs)


def test_bound_near_is_check_near_where_it_would_compute_no_pair(model):
    """bound_near (the teleop room's finite differences ask it first) gives check_near's
    distance to the last bit wherever check_near would compute no pair, and NaN exactly where
    it would compute one; it changes nothing of the checker. Postures as the room's
    differences make them: one joint moved by 1e-4 rad from a checked posture, in bands from
    the closest pair's distance to 65 mm beyond the room, and postures taken again (the
    distance before reused)."""
    rng = np.random.default_rng(43)
    lower, upper = model.lower_rad, model.upper_rad
    checker = SelfCollisionChecker(model, drill=True, repeatable=True)
    answered = computed = 0
    for _ in range(30):
        q = home_posture(model)
        for arm in ("left-arm", "right-arm"):
            sl = model.limb_slice(arm)
            q[sl] = rng.uniform(lower[sl], upper[sl])
        d = checker.check_near(q, 0.065).distance_m
        q_before = q.copy()
        for i in rng.choice(len(q), 8, replace=False):
            band_m = min(d + rng.choice([1e-5, 1e-3, 0.05]), 0.08)
            q_d = q.copy()
            q_d[i] += 1e-4
            for q_at in (q_d, q_before, q_d):  # the last one: reused from its first check
                anchors = (checker.anchor_q.copy(), checker.anchor_m.copy(),
                           checker.earlier_q.copy(), checker.earlier_m.copy())
                bound = checker.bound_near(q_at, band_m)
                assert all(np.array_equal(a, b) for a, b in zip(
                    anchors, (checker.anchor_q, checker.anchor_m, checker.earlier_q,
                              checker.earlier_m), strict=True))
                got = checker.check_near(q_at, band_m).distance_m
                if np.isnan(bound):
                    computed += 1
                    assert checker._near.any()
                else:
                    answered += 1
                    assert not checker._near.any() and bound == got
    # measured 654 answered, 66 computed (0.36 s)
    assert answered > 300 and computed > 30  # both kinds were met
