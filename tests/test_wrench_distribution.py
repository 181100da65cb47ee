"""The Stabilizer's force-moment distribution (eq. 9-14) as a QP: analytic cases, the
constraints on random feasible and infeasible demands, and bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from robot_file_support import robot_file_with

from hubo_cli.control.wrench_distribution import (
    Contact,
    DistributionParams,
    WrenchDistributor,
    convex_hull,
    project_into_polygon,
)
from hubo_cli.errors import ConfigError
from hubo_cli.model import load_model

WEIGHT_N = 380.0  # about the model's 38.7 kg
TOL_N = 1e-6 * WEIGHT_N  # the solver's equalities hold to rounding (1e-9 relative seen)
TOL_NM = 1e-6 * WEIGHT_N


@pytest.fixture(scope="module")
def distributor(model):
    return WrenchDistributor.from_model(model)


def _stance(width_m=0.24):
    return Contact((0.0, -width_m / 2)), Contact((0.0, width_m / 2))


def _check_constraints(d: WrenchDistributor, split, right, left):
    """Every vertex pushes, each CoP is inside its margined sole, the friction pyramid holds
    and the feet's wrench sums to the (made feasible) demand about the ZMP."""
    assert split.found, split.reason
    assert np.all(split.vertex_force_n >= 0)
    total = split.force_n.sum(axis=0)
    np.testing.assert_allclose(total, split.total_force_n, atol=TOL_N)
    moment = np.zeros(2)
    mu = d.params.friction_coefficient / math.sqrt(2)
    for i, contact in enumerate((right, left)):
        if contact is None:
            assert np.all(split.force_n[i] == 0)
            continue
        moment += split.moment_nm(i, split.zmp_m)
        fz = split.force_n[i, 2]
        assert abs(split.force_n[i, 0]) <= mu * fz + TOL_N
        assert abs(split.force_n[i, 1]) <= mu * fz + TOL_N
        if fz > 1e-3:  # the CoP in the sole frame, inside the margined box
            c, s = math.cos(contact.yaw_rad), math.sin(contact.yaw_rad)
            local = np.array([[c, s], [-s, c]]) @ (split.cop_m[i] - contact.position_m)
            x0, x1, y0, y1 = d.box_local_m
            assert x0 - 1e-9 <= local[0] <= x1 + 1e-9 and y0 - 1e-9 <= local[1] <= y1 + 1e-9
            if contact.edge_x_m is not None:  # rolling: the CoP on the edge
                assert local[0] == pytest.approx(np.clip(contact.edge_x_m, x0, x1), abs=1e-9)
    np.testing.assert_allclose(moment, 0.0, atol=TOL_NM)


def test_single_support_puts_everything_on_the_stance_foot(distributor):
    right, _ = _stance()
    zmp = np.array([0.03, -0.11])
    split = distributor.distribute([5.0, -3.0, WEIGHT_N], zmp, right, None)
    _check_constraints(distributor, split, right, None)
    np.testing.assert_allclose(split.force_n[0], [5.0, -3.0, WEIGHT_N], atol=TOL_N)
    np.testing.assert_allclose(split.force_n[1], 0.0)
    np.testing.assert_allclose(split.cop_m[0], zmp, atol=1e-9)  # one foot: its CoP is the ZMP
    assert not split.zmp_clipped and not split.friction_clipped


def test_double_support_symmetric_split(distributor):
    right, left = _stance()
    split = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.0, 0.0], right, left)
    _check_constraints(distributor, split, right, left)
    np.testing.assert_allclose(split.force_n[:, 2], WEIGHT_N / 2, atol=TOL_N)
    np.testing.assert_allclose(split.cop_m, [right.position_m, left.position_m], atol=1e-9)
    np.testing.assert_allclose(split.vertex_force_n[0], split.vertex_force_n[1], atol=TOL_N)
    assert split.alpha == pytest.approx(0.5)


def test_the_right_share_grows_as_the_zmp_moves_onto_the_right_sole(distributor):
    """From the midpoint (an even split) to the right sole's origin (all on the right) the
    right foot's share rises monotonically, and each loaded CoP stays within 30 mm of its
    reference (W_cop against W_f's alpha weighting: 17 mm at most computed, where the ZMP
    enters the sole and alpha reaches 1)."""
    right, left = _stance()
    shares = []
    for y in np.linspace(0.0, -0.12, 25):
        split = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.0, y], right, left)
        _check_constraints(distributor, split, right, left)
        shares.append(split.force_n[0, 2] / WEIGHT_N)
        assert np.linalg.norm(split.cop_m[0] - right.position_m) < 0.03
        if split.force_n[1, 2] > 0.05 * WEIGHT_N:
            assert np.linalg.norm(split.cop_m[1] - left.position_m) < 0.03
    assert shares[0] == pytest.approx(0.5)
    assert np.all(np.diff(shares) >= -1e-9)
    assert shares[-1] > 0.99


def test_zmp_on_one_sole_in_double_support_loads_that_sole(distributor):
    """alpha = 1 (the ZMP on the right sole): W_f makes the left foot's force 1000 times
    dearer. At the right sole's reference CoP the left carries nothing; 50 mm ahead of it,
    under 5 % (2.8 % computed: it spares the right CoP part of its offset)."""
    right, left = _stance()
    at_ref = distributor.distribute([0.0, 0.0, WEIGHT_N], right.position_m, right, left)
    _check_constraints(distributor, at_ref, right, left)
    assert at_ref.alpha == pytest.approx(1.0, abs=1e-2)
    assert at_ref.force_n[1, 2] < 1e-3 * WEIGHT_N
    ahead = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.05, -0.13], right, left)
    _check_constraints(distributor, ahead, right, left)
    assert ahead.force_n[1, 2] < 0.05 * WEIGHT_N


def test_cop_limit_active_at_the_toe(distributor):
    """A ZMP beyond the toe in single support is moved onto the margined toe edge: the heel
    vertices carry nothing and the CoP is on the edge."""
    right, _ = _stance()
    split = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.4, -0.12], right, None)
    _check_constraints(distributor, split, right, None)
    assert split.zmp_clipped
    toe_x = distributor.box_local_m[1]
    assert split.zmp_m[0] == pytest.approx(toe_x)
    assert split.cop_m[0, 0] == pytest.approx(toe_x)
    heel = distributor.vertices_local_m[:, 0] < toe_x - 1e-9
    np.testing.assert_allclose(split.vertex_force_n[0][heel], 0.0, atol=TOL_N)


def test_a_sole_rolling_on_its_toe_carries_everything_on_the_toe_edge(distributor):
    """Single support on the toe edge (toe-heel phase (ii)): the ZMP is moved onto the edge
    and the CoP is there; in double support the rolling rear sole's CoP stays on its edge."""
    toe_x = distributor.box_local_m[1]
    rolling = Contact((0.0, -0.12), 0.0, (0.13, -0.12), edge_x_m=0.13)  # clamped to toe_x
    split = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.0, -0.1], rolling, None)
    _check_constraints(distributor, split, rolling, None)
    assert split.zmp_clipped
    np.testing.assert_allclose(split.cop_m[0], [toe_x, -0.1], atol=1e-9)
    left = Contact((0.2, 0.12))
    both = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.15, 0.0], rolling, left)
    _check_constraints(distributor, both, rolling, left)
    assert not both.zmp_clipped
    assert both.cop_m[0, 0] == pytest.approx(toe_x)
    assert both.force_n[0, 2] > 0.1 * WEIGHT_N  # the rolling sole still carries its share


def test_friction_limit_clips_the_horizontal_force(distributor):
    right, left = _stance()
    split = distributor.distribute([WEIGHT_N, 0.0, WEIGHT_N], [0.0, 0.0], right, left)
    _check_constraints(distributor, split, right, left)
    assert split.friction_clipped
    mu = distributor.params.friction_coefficient / math.sqrt(2)
    assert split.total_force_n[0] == pytest.approx(mu * WEIGHT_N)


def test_the_reference_cop_pulls_the_cop(distributor):
    """Single support with the ZMP at the origin is exact whatever the reference; double
    support with the references at the toes moves both CoPs forward."""
    right, left = _stance()
    toe_right = Contact(right.position_m, cop_ref_m=(0.1, -0.12))
    toe_left = Contact(left.position_m, cop_ref_m=(0.1, 0.12))
    split = distributor.distribute([0.0, 0.0, WEIGHT_N], [0.1, 0.0], toe_right, toe_left)
    _check_constraints(distributor, split, toe_right, toe_left)
    np.testing.assert_allclose(split.cop_m[:, 0], 0.1, atol=1e-6)


def _random_contacts(data_rng, single: bool):
    """Two soles at random places and headings, random reference CoPs, each rolling on an
    edge (anywhere along it, even beyond the sole: clamped) one time in three."""
    width = data_rng.uniform(0.16, 0.4)
    x_offset = data_rng.uniform(-0.3, 0.3)

    def edge():
        return data_rng.uniform(-0.15, 0.2) if data_rng.random() < 1 / 3 else None

    right = Contact((data_rng.uniform(-0.1, 0.1), -width / 2), data_rng.uniform(-0.5, 0.5),
                    tuple(data_rng.uniform(-0.1, 0.1, 2) + (0, -width / 2)), edge())
    left = Contact((x_offset, width / 2), data_rng.uniform(-0.5, 0.5),
                   tuple(data_rng.uniform(-0.1, 0.1, 2) + (x_offset, width / 2)), edge())
    if single:
        return (right, None) if data_rng.random() < 0.5 else (None, left)
    return right, left


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), single=st.booleans())
def test_random_feasible_demands_are_met_exactly(distributor, seed, single):
    rng = np.random.default_rng(seed)
    right, left = _random_contacts(rng, single)
    verts = np.vstack([distributor_vertices(distributor, c) for c in (right, left) if c])
    weights = rng.dirichlet(np.ones(len(verts)) * 0.3)
    zmp = weights @ verts  # inside the support polygon
    fz = rng.uniform(20.0, 3 * WEIGHT_N)
    mu = distributor.params.friction_coefficient / math.sqrt(2)
    horizontal = rng.uniform(-1, 1, 2) * mu * fz * 0.999
    split = distributor.distribute([*horizontal, fz], zmp, right, left)
    _check_constraints(distributor, split, right, left)
    assert not split.zmp_clipped and not split.friction_clipped
    np.testing.assert_allclose(split.zmp_m, zmp)
    np.testing.assert_allclose(split.total_force_n, [*horizontal, fz])


def distributor_vertices(d: WrenchDistributor, contact: Contact) -> np.ndarray:
    """The contact's four points in the world: the margined sole's corners, or on a rolling
    edge the two ends of that edge (each twice)."""
    local = d.vertices_local_m.copy()
    if contact.edge_x_m is not None:
        local[:, 0] = np.clip(contact.edge_x_m, d.box_local_m[0], d.box_local_m[1])
    c, s = math.cos(contact.yaw_rad), math.sin(contact.yaw_rad)
    return local @ np.array([[c, -s], [s, c]]).T + contact.position_m


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), single=st.booleans())
def test_random_infeasible_demands_are_made_feasible(distributor, seed, single):
    """A ZMP anywhere within 2 m and a horizontal force up to twice the weight: moved into the
    polygon and the pyramid (flagged), then met exactly."""
    rng = np.random.default_rng(seed)
    right, left = _random_contacts(rng, single)
    fz = rng.uniform(20.0, 3 * WEIGHT_N)
    zmp = rng.uniform(-2, 2, 2)
    force = [*rng.uniform(-2, 2, 2) * fz, fz]
    split = distributor.distribute(force, zmp, right, left)
    _check_constraints(distributor, split, right, left)
    verts = np.vstack([distributor_vertices(distributor, c) for c in (right, left) if c])
    hull = convex_hull(verts)
    nearest, _ = project_into_polygon(split.zmp_m, hull)
    assert np.linalg.norm(nearest - split.zmp_m) < 1e-9  # inside or on the edge


@pytest.mark.parametrize("bad", [
    dict(force=[0, 0, float("nan")]), dict(zmp=[float("inf"), 0]),
    dict(right=Contact((float("nan"), 0.0))), dict(force=[0, 0, -50.0]),
    dict(left=Contact((0.0, 0.12), edge_x_m=float("inf"))),
    dict(force=[0, 0, 0.5]), dict(right=None, left=None)])
def test_bad_demands_give_no_distribution_and_no_nan(distributor, bad):
    right, left = _stance()
    args = dict(force=[0, 0, WEIGHT_N], zmp=[0, 0], right=right, left=left) | bad
    split = distributor.distribute(args["force"], args["zmp"], args["right"], args["left"])
    assert not split.found and split.reason
    for array in (split.force_n, split.cop_m, split.vertex_force_n, split.zmp_m,
                  split.total_force_n):
        assert np.all(np.isfinite(array))
    assert np.all(split.force_n == 0)


def test_the_hull_of_two_soles(distributor):
    right, left = _stance()
    verts = np.vstack([distributor_vertices(distributor, c) for c in (right, left)])
    hull = convex_hull(verts)
    assert len(hull) == 4  # the two rectangles side by side: the outer four corners
    area = 0.5 * np.sum(hull[:, 0] * np.roll(hull[:, 1], -1) - np.roll(hull[:, 0], -1) * hull[:, 1])
    x0, x1, y0, y1 = distributor.box_local_m
    assert area == pytest.approx((x1 - x0) * (0.24 + y1 - y0))  # counter-clockwise: positive


@pytest.mark.parametrize("key,value", [("cop_weight", "0"), ("friction_coefficient", "-0.5"),
                                       ("cop_margin_m", '"a"'), ("force_weight", "true"),
                                       ("cop_weight", "nan")])
def test_bad_parameters_are_refused(model, tmp_path, key, value):
    bad = load_model(path=robot_file_with(model, tmp_path, "wrench_distribution", key, value))
    with pytest.raises(ConfigError, match=key):
        WrenchDistributor.from_model(bad)


def test_a_margin_wider_than_the_sole_is_refused(model):
    params = DistributionParams(1.0, 1e-3, 0.5, model.feet.width_m / 2)
    with pytest.raises(ConfigError, match="leaves no sole"):
        WrenchDistributor(model.feet, params)
