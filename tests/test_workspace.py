"""Workspace map: reachability against single-point IK and FK, the searches against brute force,
the paper's section IV points, the stance helper."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hubo_cli.errors import InputError
from hubo_cli.kinematics import get_limb
from hubo_cli.workspace import best_stance, compute_map
from hubo_cli.workspace.cache import cache_dir
from hubo_cli.workspace.search import largest_rectangles, longest_runs, pick_best_x

pytestmark = pytest.mark.xdist_group("workspace")  # module-scoped runs: one worker

COARSE_M = 0.02


@pytest.fixture(scope="module")
def coarse():
    """Right arm, drill, Table IV, 20 mm grid, no refining."""
    return compute_map(resolution_m=COARSE_M, refine=False)


def _goals(wmap, P_m):
    T = np.tile(np.eye(4), (len(P_m), 1, 1))
    T[:, :3, :3] = wmap.R_N_E
    T[:, :3, 3] = P_m
    return T


def _sample(wmap, rng, n, where):
    idx = np.argwhere(where)
    pick = idx[rng.choice(len(idx), size=min(n, len(idx)), replace=False)]
    g = wmap.grid
    P = np.column_stack([g.x_m[pick[:, 0]], g.y_m[pick[:, 2]], g.z_m[pick[:, 1]]])
    return pick, P


def test_map_agrees_with_batched_ik_status(coarse, rng):
    g = coarse.grid
    X, Z, Y = np.meshgrid(g.x_m, g.z_m, g.y_m, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    limb = get_limb("right-arm", "drill")
    status = limb.solve_batch(_goals(coarse, P), allow_cap=False).status
    assert np.array_equal(status.reshape(g.shape) == 0, coarse.reachable)
    assert coarse.reachable.sum() > 500


def test_every_branch_bit_is_an_exact_in_limit_solution(coarse, rng):
    limb = get_limb("right-arm", "drill")
    pick, P = _sample(coarse, rng, 150, coarse.reachable)
    for (i, k, j), p, T in zip(pick, P, _goals(coarse, P), strict=True):
        mask = coarse.masks[i, k, j]
        cands = limb.candidates(T)
        for b in range(8):
            c = cands[b]
            ok = c.exact and c.within_limits
            assert bool(mask & (1 << b)) == ok
            if ok:  # FK of the returned joints lands on the grid point with the orientation
                T_fk = limb.fk(c.q_rad)
                assert np.allclose(T_fk[:3, 3], p, atol=1e-6)
                assert np.allclose(T_fk[:3, :3], coarse.R_N_E, atol=1e-6)


def test_unreachable_points_are_red_and_ik_agrees(coarse, rng):
    limb = get_limb("right-arm", "drill")
    # known out of reach: 650 mm ahead of the shoulder, beyond lA2 + lA3 + the drill
    far = np.array([[0.65, -0.2145, 0.0]])
    assert coarse.query(far)[0] == 0
    assert limb.solve(_goals(coarse, far)[0]).status != "exact"
    # red grid points inside the arm's length: single-point IK finds no exact solution either
    _, P = _sample(coarse, rng, 100, ~coarse.reachable)
    for T in _goals(coarse, P):
        assert limb.solve(T).status != "exact"


def _brute_force_widest(limb, wmap):
    """Per x: the longest run along y of one branch, from Limb.solve / Limb.candidates per point."""
    g = wmap.grid
    best = []
    for x in g.x_m:
        top = (0, None)
        for z in sorted(g.z_m, key=abs):  # same tie rule as the library: rows near z = 0 first
            bits = np.zeros((8, len(g.y_m)), dtype=bool)
            for j, y in enumerate(g.y_m):
                T = np.eye(4)
                T[:3, 3] = (x, y, z)
                if limb.solve(T).status != "exact":
                    continue
                for b, c in enumerate(limb.candidates(T)):
                    bits[b, j] = c.exact and c.within_limits
            for b in range(8):
                run = longest = 0
                for v in bits[b]:
                    run = run + 1 if v else 0
                    longest = max(longest, run)
                if longest > top[0]:
                    top = (longest, (z, b))
        best.append(top)
    return best


def test_best_distance_matches_brute_force_over_single_points():
    wmap = compute_map(resolution_m=0.025, x_range_m=(0.40, 0.55), refine=False)
    brute = _brute_force_widest(get_limb("right-arm", "drill"), wmap)
    lengths = np.array([n for n, _ in brute])
    assert np.array_equal(lengths, wmap.run_length)
    i = pick_best_x(lengths)
    assert i == wmap.best_index
    seg = wmap.widest_grid
    assert seg.wall_distance_m == pytest.approx(wmap.grid.x_m[i])
    assert seg.width_m == pytest.approx((lengths[i] - 1) * 0.025)
    assert (seg.z_m, seg.branch) == pytest.approx(brute[i][1])


@pytest.mark.parametrize("params", ["as-built", "table1"])
@pytest.mark.parametrize("limits", ["table4", "team-code"])
def test_paper_segment_ends_are_reachable(params, limits):
    wmap = compute_map(params=params, limits=limits, resolution_m=0.03, refine=False)
    q, P, masks = wmap.paper_ends()
    assert np.all(masks & (1 << 6)), "both ends on the paper's branch (6)"
    if params == "as-built":  # 484 mm from the neck, 75 mm up, 390 mm apart
        assert P[:, 0] == pytest.approx(0.484, abs=1e-3)
        assert P[:, 2] == pytest.approx(0.0746, abs=1e-3)
        assert P[1, 1] - P[0, 1] == pytest.approx(0.390, abs=1e-3)
        # and the whole segment between them is swept on that one branch
        y = np.linspace(P[0, 1], P[1, 1], 391)
        line = np.column_stack([np.full_like(y, 0.484), y, np.full_like(y, P[0, 2])])
        assert np.all(wmap.query(line) & (1 << 6))


def test_refined_segment_is_exact_at_its_ends():
    wmap = compute_map(resolution_m=0.01, x_range_m=(0.44, 0.50))
    seg, grid_seg = wmap.widest, wmap.widest_grid
    assert seg.width_m >= grid_seg.width_m - 1e-9
    bit = 1 << seg.branch
    y = np.linspace(seg.y_min_m, seg.y_max_m, 500)
    line = np.column_stack([np.full_like(y, seg.wall_distance_m), y, np.full_like(y, seg.z_m)])
    assert np.all(wmap.query(line) & bit)
    beyond = np.array([[seg.wall_distance_m, seg.y_min_m - 1e-5, seg.z_m],
                       [seg.wall_distance_m, seg.y_max_m + 1e-5, seg.z_m]])
    assert not np.any(wmap.query(beyond) & bit)
    limb = get_limb("right-arm", "drill")
    for q, y_end in ((seg.q_min_rad, seg.y_min_m), (seg.q_max_rad, seg.y_max_m)):
        T = limb.fk(q)
        assert T[:3, 3] == pytest.approx([seg.wall_distance_m, y_end, seg.z_m], abs=1e-6)
        assert np.all(q >= limb.lower_rad) and np.all(q <= limb.upper_rad)


def test_left_arm_mirrors_right_with_mirrored_limits():
    # team-code limits are mirror-symmetric between the arms, so the maps must be mirror images
    right = compute_map("right", limits="team-code", resolution_m=COARSE_M, refine=False)
    left = compute_map("left", limits="team-code", resolution_m=COARSE_M, refine=False)
    assert np.allclose(left.grid.y_m, -right.grid.y_m[::-1])
    assert np.array_equal(left.reachable, right.reachable[:, :, ::-1])
    assert left.widest.width_m == pytest.approx(right.widest.width_m)


def _brute_runs(row):
    best = start = run = 0
    for j, v in enumerate(row):
        run = run + 1 if v else 0
        if run > best:
            best, start = run, j - run + 1
    return best, (start if best else -1)


def _brute_rectangle(grid2d):
    nz, ny = grid2d.shape
    best = -1
    for z0 in range(nz):
        for z1 in range(z0, nz):
            for y0 in range(ny):
                for y1 in range(y0, ny):
                    if grid2d[z0:z1 + 1, y0:y1 + 1].all():
                        best = max(best, (z1 - z0) * (y1 - y0))
    return best


@settings(max_examples=60, deadline=None)
@given(arrays(np.uint8, st.tuples(st.integers(1, 2), st.integers(1, 6), st.integers(1, 9)),
              elements=st.sampled_from([0, 1, 2, 3, 64, 80])))
def test_runs_and_rectangles_match_brute_force(masks):
    length, start = longest_runs(masks)
    rects = largest_rectangles(masks)
    for i in range(masks.shape[0]):
        for b in range(8):
            bits = (masks[i] >> b) & 1
            for k in range(masks.shape[1]):
                assert (length[i, k, b], start[i, k, b]) == _brute_runs(bits[k])
            score, z0, z1, y0, y1 = rects[i, b]
            assert score == _brute_rectangle(bits)
            if score >= 0:
                assert bits[z0:z1 + 1, y0:y1 + 1].all()
                assert score == (z1 - z0) * (y1 - y0)


def test_pick_best_x_takes_the_middle_of_the_first_tie():
    assert pick_best_x(np.array([1, 5, 5, 5, 2, 5])) == 2
    assert pick_best_x(np.array([3, 1, 2])) == 0


def test_progress_is_reported_per_chunk():
    calls = []
    compute_map(resolution_m=COARSE_M, refine=True, progress=lambda *a: calls.append(a))
    solving = [c for c in calls if "solving" in c[0]]
    assert solving[-1][1] == solving[-1][2] and len(solving) >= 1
    assert any("refining" in c[0] for c in calls)


def test_bad_inputs_raise_input_errors():
    with pytest.raises(InputError):
        compute_map(arm="middle")
    with pytest.raises(InputError):
        compute_map(orientation="sideways")
    with pytest.raises(InputError):
        compute_map(resolution_m=0.01, x_range_m=(0.9, 1.0))  # nothing reachable that far


def test_best_stance_caches_and_fits_requested_holes(tmp_path, monkeypatch):
    monkeypatch.setenv("HUBO_CACHE_DIR", str(tmp_path))
    first = best_stance(resolution_m=0.01)
    files = list(cache_dir().glob("*.npz"))
    assert len(files) == 1 and cache_dir().is_relative_to(tmp_path)
    again = best_stance(resolution_m=0.01)
    assert again == first  # loaded from the cache, same answer
    r = first.rectangle
    assert first.wall_distance_m == r.wall_distance_m and r.area_m2 > 0.2 * 0.05
    # the returned rectangle is reachable on its branch everywhere on a 5 mm mesh
    limb = get_limb("right-arm", "drill")
    ys = np.linspace(r.y_min_m, r.y_max_m, 21)
    zs = np.linspace(r.z_min_m, r.z_max_m, 9)
    Y, Z = np.meshgrid(ys, zs)
    P = np.column_stack([np.full(Y.size, r.wall_distance_m), Y.ravel(), Z.ravel()])
    T = np.tile(np.eye(4), (len(P), 1, 1))
    T[:, :3, 3] = P
    assert np.all(limb.solve_batch(T, allow_cap=False).status == 0)
    hole = best_stance(size_m=(0.10, 0.05), resolution_m=0.01)
    assert hole.fits and hole.cut.width_m == pytest.approx(0.10)
    assert hole.rectangle.width_m >= 0.10 and hole.rectangle.height_m >= 0.05
    c = hole.cut
    assert hole.rectangle.y_min_m <= c.y_min_m and c.y_max_m <= hole.rectangle.y_max_m
    assert hole.rectangle.z_min_m <= c.z_min_m and c.z_max_m <= hole.rectangle.z_max_m
    too_big = best_stance(size_m=(0.8, 0.5), resolution_m=0.01)
    assert not too_big.fits and too_big.cut is None


def test_pinned_height_and_distance():
    # the paper's height with the team's limits: the best distance is the paper's 484 mm
    at_height = compute_map(limits="team-code", resolution_m=0.002, x_range_m=(0.44, 0.52),
                            z_range_m=(0.0746, 0.0746))
    assert at_height.grid.z_m.tolist() == [0.0746]
    assert at_height.widest.z_m == pytest.approx(0.0746)
    assert at_height.widest.wall_distance_m == pytest.approx(0.483, abs=0.003)
    at_distance = compute_map(limits="team-code", resolution_m=0.002, x_range_m=(0.484, 0.484))
    assert at_distance.widest.wall_distance_m == pytest.approx(0.484)
    assert at_distance.widest.width_m > 0.390


def test_best_stance_with_the_legs_uses_the_widest_segment(tmp_path, monkeypatch):
    monkeypatch.setenv("HUBO_CACHE_DIR", str(tmp_path))
    wmap = compute_map(resolution_m=0.01, refine=False)
    legs = best_stance(resolution_m=0.01, vertical="legs", size_m=(0.30, 0.20))
    seg = wmap.widest_grid
    assert legs.fits and legs.wall_distance_m == pytest.approx(seg.wall_distance_m)
    assert legs.rectangle.height_m == 0 and legs.rectangle.width_m == pytest.approx(seg.width_m)
    assert legs.cut.width_m == pytest.approx(0.30) and legs.cut.height_m == pytest.approx(0.20)
    assert not best_stance(resolution_m=0.01, vertical="legs", size_m=(0.9, 0.1)).fits
    with pytest.raises(InputError):
        best_stance(resolution_m=0.01, vertical="hover")


def test_a_corrupt_cache_file_is_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("HUBO_CACHE_DIR", str(tmp_path))
    fresh = best_stance(resolution_m=0.02)
    (path,) = cache_dir().glob("*.npz")
    path.write_bytes(b"not a zip file")
    assert best_stance(resolution_m=0.02) == fresh
    assert path.stat().st_size > 100  # rewritten


@pytest.mark.parametrize("arm", ["right", "left"])
def test_a_maps_limb_forward_kinematics_ends_where_its_inverse_kinematics_aims(arm, rng):
    # the left arm's drill is mounted as the mirror image (MirroredToolLimb replaces the chain
    # after Limb's own init): fk and the IK must use the same tool. Round 9's review found fk
    # on the unmirrored tool, 251 mm and 180 deg from the IK's exact solution
    from hubo_cli.kinematics.dh import chain_fk
    from hubo_cli.workspace.limbs import arm_limb

    limb = arm_limb(arm, "drill")
    base, _, offset, alpha, a, d, end, _ = limb.chain
    for _ in range(5):
        q = rng.uniform(limb.lower_rad, limb.upper_rad)
        out = np.empty((4, 4))
        chain_fk(q, base, offset, alpha, a, d, end, out)
        assert np.allclose(limb.fk(q), out, atol=1e-12)
        solution = limb.solve(limb.fk(q), q)
        assert np.allclose(limb.fk(solution.q_rad), limb.fk(q), atol=1e-9)
