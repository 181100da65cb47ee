"""hubo_cli.geometry against scipy.spatial.transform, on random and degenerate rotations."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from hubo_cli import geometry as g

TOL = 1e-12
HALF_PI = np.pi / 2


def _wrap(a):
    """Angles to [-pi, pi) (so that pi and -pi compare equal)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _exact_lock_matrices() -> np.ndarray:
    """Rotations at exactly +-90 deg pitch, built without rounding: Rz(t) Ry(+-90) (and one
    Ry(+-90) Rx(t) that is the same rotation family)."""
    out = []
    for c, s in [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.6, 0.8), (-0.28, 0.96)]:
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        for sp in (1.0, -1.0):
            Ry = np.array([[0.0, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, 0.0]])
            out.append(Rz @ Ry)
    return np.array(out)


def _degenerate() -> np.ndarray:
    """Identity, half turns (about the axes and random axes), exact and rounded +-90 deg pitch,
    and pitches just short of the lock."""
    rng = np.random.default_rng(5)
    axes = np.vstack([np.eye(3), rng.normal(size=(5, 3))])
    half_turns = Rotation.from_rotvec(np.pi * axes / np.linalg.norm(axes, axis=1)[:, None])
    rounded_lock = [g.rpy_to_matrix(r, p, y) for r, y in rng.uniform(-3, 3, (6, 2))
                    for p in (HALF_PI, -HALF_PI)]
    near_lock = [g.rpy_to_matrix(0.7, sign * (HALF_PI - d), -2.1) for d in (1e-13, 1e-9, 1e-6)
                 for sign in (1, -1)]
    # scipy's matrices near the lock carry rounding noise in the small entries
    pitches = np.outer([1, -1], HALF_PI - np.logspace(-16, -4, 25)).ravel()
    yaw_roll = rng.uniform(-3, 3, (len(pitches), 2))
    noisy = Rotation.from_euler("ZYX", np.column_stack([yaw_roll[:, 0], pitches, yaw_roll[:, 1]]))
    return np.concatenate([np.eye(3)[None], half_turns.as_matrix(), _exact_lock_matrices(),
                           rounded_lock, near_lock, noisy.as_matrix()])


@pytest.fixture(scope="module")
def rotations() -> np.ndarray:
    """(N, 3, 3): 2000 random rotations and the degenerate ones."""
    random = Rotation.random(2000, rng=np.random.default_rng(11)).as_matrix()
    return np.concatenate([random, _degenerate()])


def _scipy_euler_zyx(R: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy warns at the gimbal lock
        return Rotation.from_matrix(R).as_euler("ZYX")  # yaw, pitch, roll


# ------------------------------------------------------------------------------- quaternions
def test_quaternion_to_matrix_matches_scipy(rotations):
    q_xyzw = Rotation.from_matrix(rotations).as_quat()
    q_wxyz = q_xyzw[:, [3, 0, 1, 2]]
    expected = Rotation.from_quat(q_xyzw).as_matrix()
    assert np.abs(g.quat_wxyz_to_matrix(q_wxyz) - expected).max() < TOL
    assert np.abs(g.quat_xyzw_to_matrix(q_xyzw) - expected).max() < TOL
    # scalars work the same, and the norm does not matter
    assert np.abs(g.quat_wxyz_to_matrix(3.0 * q_wxyz[7]) - expected[7]).max() < TOL


def test_matrix_to_quaternion_matches_scipy_and_is_canonical(rotations):
    q = g.matrix_to_quat_wxyz(rotations)
    expected = Rotation.from_matrix(rotations).as_quat(canonical=True)[:, [3, 0, 1, 2]]
    # the sign of a half turn's quaternion (w = 0) rests on the rounding of w: compare +-q
    sign = np.where(np.sum(q * expected, axis=1) < 0, -1.0, 1.0)
    assert np.abs(q * sign[:, None] - expected).max() < TOL
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() < TOL
    first = q[np.arange(len(q)), np.argmax(q != 0.0, axis=1)]
    assert (first > 0).all()
    assert np.abs(g.quat_wxyz_to_matrix(q) - rotations).max() < TOL


def test_one_rotation_converts_exactly_as_the_batch(rotations):
    """A single quaternion or matrix takes a Python path (the simulator converts a few every
    period); it gives the batch kernels' numbers to the last bit, degenerate ones included."""
    q_wxyz = g.matrix_to_quat_wxyz(rotations)
    q_wxyz[::3] *= 2.5  # any norm
    R_batch = g.quat_wxyz_to_matrix(q_wxyz)
    for q, R in zip(q_wxyz, R_batch, strict=True):
        assert np.array_equal(g.quat_wxyz_to_matrix(q), R)
        assert np.array_equal(g.quat_xyzw_to_matrix(tuple(q[[1, 2, 3, 0]].tolist())), R)
    for batch, one in ((g.matrix_to_quat_wxyz(rotations), g.matrix_to_quat_wxyz),
                       (g.matrix_to_rpy(rotations), g.matrix_to_rpy)):
        assert all(np.array_equal(one(R), expected) for R, expected in zip(rotations, batch,
                                                                            strict=True))
    assert g.quat_wxyz_to_matrix([1, 0, 0, 0]).shape == (3, 3)  # integers too
    assert g.quat_wxyz_to_matrix([[1.0, 0, 0, 0]]).shape == (1, 3, 3)  # a batch of one stays one


def test_half_turn_quaternions_are_exact():
    assert np.array_equal(g.matrix_to_quat_wxyz(np.diag([1.0, -1.0, -1.0])), [0, 1, 0, 0])
    assert np.array_equal(g.matrix_to_quat_wxyz(np.diag([-1.0, 1.0, -1.0])), [0, 0, 1, 0])
    assert np.array_equal(g.matrix_to_quat_wxyz(np.diag([-1.0, -1.0, 1.0])), [0, 0, 0, 1])
    assert np.array_equal(g.matrix_to_quat_wxyz(np.eye(3)), [1, 0, 0, 0])


def test_slerp_matches_scipy():
    rng = np.random.default_rng(2)
    pairs = Rotation.random(400, rng=rng)
    ends = Rotation.random(400, rng=rng)
    u = rng.uniform(0, 1, 400)
    ours = g.slerp_quat_wxyz(pairs.as_quat()[:, [3, 0, 1, 2]], ends.as_quat()[:, [3, 0, 1, 2]], u)
    for k in range(0, 400, 7):
        both = Rotation.concatenate([pairs[k], ends[k]])
        expected = Slerp([0.0, 1.0], both)([u[k]]).as_matrix()[0]
        assert np.abs(g.quat_wxyz_to_matrix(ours[k]) - expected).max() < 1e-10


# ------------------------------------------------------------------------------- RPY
def test_rpy_to_matrix_matches_scipy():
    rng = np.random.default_rng(3)
    rpy = np.vstack([rng.uniform(-np.pi, np.pi, (500, 3)),
                     [[0.3, HALF_PI, -1.0], [0.0, -HALF_PI, 2.0], [np.pi, 0.0, np.pi]]])
    expected = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    assert np.abs(g.rpy_to_matrix(rpy[:, 0], rpy[:, 1], rpy[:, 2]) - expected).max() < TOL
    assert np.abs(g.rpy_to_matrix(*rpy[4]) - expected[4]).max() < TOL
    q = g.rpy_to_quat_wxyz(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    expected_q = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_quat(canonical=True)
    assert np.abs(q - expected_q[:, [3, 0, 1, 2]]).max() < TOL


def test_matrix_to_rpy_round_trips_everywhere(rotations):
    rpy = g.matrix_to_rpy(rotations)
    assert np.abs(g.rpy_to_matrix(rpy[:, 0], rpy[:, 1], rpy[:, 2]) - rotations).max() < TOL
    assert (np.abs(rpy[:, 1]) <= HALF_PI).all() and (np.abs(rpy) <= np.pi).all()


def test_matrix_to_rpy_matches_scipy_away_from_the_lock(rotations):
    rpy = g.matrix_to_rpy(rotations)
    expected = _scipy_euler_zyx(rotations)[:, ::-1]
    clear = np.cos(expected[:, 1]) > 1e-3  # there the angles are well conditioned
    assert clear.sum() > 2000
    assert np.abs(_wrap(rpy[clear] - expected[clear])).max() < TOL


def test_gimbal_lock_puts_the_turn_in_yaw_as_scipy():
    R = _exact_lock_matrices()
    rpy = g.matrix_to_rpy(R)
    expected = _scipy_euler_zyx(R)[:, ::-1]
    assert np.array_equal(rpy[:, 0], np.zeros(len(R)))
    assert np.abs(_wrap(rpy - expected)).max() < TOL
    # Rz(yaw) Ry(90) Rx(roll) = Rz(yaw - roll) Ry(90): the result is (0, 90 deg, yaw - roll)
    roll, yaw = 0.4, 1.1
    assert np.abs(g.matrix_to_rpy(g.rpy_to_matrix(roll, HALF_PI, yaw))
                  - [0.0, HALF_PI, yaw - roll]).max() < TOL
    assert np.abs(g.matrix_to_rpy(g.rpy_to_matrix(roll, -HALF_PI, yaw))
                  - [0.0, -HALF_PI, yaw + roll]).max() < TOL


def test_quaternion_to_rpy(rotations):
    q = g.matrix_to_quat_wxyz(rotations)
    rpy = g.quat_wxyz_to_rpy(q)
    assert np.abs(g.rpy_to_matrix(rpy[:, 0], rpy[:, 1], rpy[:, 2]) - rotations).max() < TOL
    roll, pitch = g.roll_pitch_of_quat_wxyz(q[3])
    assert isinstance(roll, float) and (roll, pitch) == (rpy[3, 0], rpy[3, 1])


@settings(max_examples=300, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-HALF_PI, HALF_PI), st.floats(-np.pi, np.pi))
def test_rpy_round_trip_property(roll, pitch, yaw):
    R = g.rpy_to_matrix(roll, pitch, yaw)
    assert np.abs(g.rpy_to_matrix(*g.matrix_to_rpy(R)) - R).max() < TOL
    q = g.rpy_to_quat_wxyz(roll, pitch, yaw)
    assert np.abs(g.quat_wxyz_to_matrix(q) - R).max() < TOL


# ------------------------------------------------------------------------------- FASTRAK Euler
def test_fastrak_euler_matches_scipy(rotations):
    rng = np.random.default_rng(4)
    angles = np.column_stack([rng.uniform(-180, 180, 500), rng.uniform(-90, 90, 500),
                              rng.uniform(-180, 180, 500)])
    angles = np.vstack([angles, [[30.0, 90.0, 40.0], [-120.0, -90.0, 15.0], [0, 0, 0]]])
    expected = Rotation.from_euler("ZYX", angles, degrees=True)
    assert np.abs(g.fastrak_euler_deg_to_matrix(angles) - expected.as_matrix()).max() < TOL
    assert np.abs(g.fastrak_euler_deg_to_quat_wxyz(angles)
                  - expected.as_quat(canonical=True)[:, [3, 0, 1, 2]]).max() < TOL
    euler = g.matrix_to_fastrak_euler_deg(rotations)
    assert np.abs(g.fastrak_euler_deg_to_matrix(euler) - rotations).max() < TOL
    reference = np.degrees(_scipy_euler_zyx(rotations))
    clear = np.cos(np.radians(reference[:, 1])) > 1e-3
    assert np.abs(_wrap(np.radians(euler[clear] - reference[clear]))).max() < TOL


def test_fastrak_euler_round_trips_at_plus_minus_90_deg_elevation():
    """The device's encoder used to lose up to 1.34 rad here (no gimbal-lock branch)."""
    angles = np.array([[30.0, 90.0, 40.0], [-120.0, -90.0, 15.0], [170.0, 90.0, -170.0],
                       [0.0, -90.0, 0.0]])
    R = g.fastrak_euler_deg_to_matrix(angles)
    euler = g.matrix_to_fastrak_euler_deg(R)
    assert np.abs(g.fastrak_euler_deg_to_matrix(euler) - R).max() < TOL
    assert np.array_equal(euler[:, 2], np.zeros(4))  # roll 0, the turn is in the azimuth
    expected_az = [30.0 - 40.0, -120.0 + 15.0, 170.0 + 170.0 - 360.0, 0.0]
    assert np.abs(euler[:, 0] - expected_az).max() < 1e-10
    assert np.abs(np.abs(euler[:, 1]) - 90.0).max() < 1e-10


# ------------------------------------------------------------------------------- rotation vectors
def test_rotation_log_and_exp_match_scipy(rotations):
    for R in rotations:
        v = g.rotation_log(R)
        expected = Rotation.from_matrix(R).as_rotvec()
        angle = np.linalg.norm(expected)
        if abs(angle - np.pi) < 1e-6:  # a half turn: v and -v are the same rotation
            assert abs(np.linalg.norm(v) - angle) < TOL
            assert min(np.abs(v - expected).max(), np.abs(v + expected).max()) < 1e-9
        else:
            assert np.abs(v - expected).max() < TOL
        assert np.abs(g.rotation_exp(v) - Rotation.from_rotvec(v).as_matrix()).max() < TOL
        assert np.abs(g.rotation_exp(v) - R).max() < TOL


def test_rotation_log_and_exp_of_small_rotations_match_scipy():
    """The control loop's case (a body swaying by milliradians), taken in Python floats."""
    rng = np.random.default_rng(7)
    for scale in (1e-14, 1e-9, 1e-4, 0.1, 0.5):  # angles below pi
        for v in rng.normal(size=(50, 3)) * scale:
            R = Rotation.from_rotvec(v).as_matrix()
            assert np.abs(g.rotation_exp(v) - R).max() < TOL
            assert np.abs(g.rotation_log(R) - v).max() < TOL


# ------------------------------------------------------------------------------- tilt
def test_tilt_is_the_angle_of_the_body_z_axis(rotations):
    z_body = Rotation.from_matrix(rotations).apply([0.0, 0.0, 1.0])
    expected = np.arctan2(np.linalg.norm(np.cross(z_body, [0.0, 0.0, 1.0]), axis=1),
                          z_body[:, 2])
    assert np.abs(g.tilt_rad_of_matrix(rotations) - expected).max() < TOL
    assert np.abs([g.tilt_rad_of_z_axis(*R[:, 2].tolist()) for R in rotations]
                  - expected).max() < TOL
    q = g.matrix_to_quat_wxyz(rotations)
    assert np.abs(g.tilt_rad_of_quat_wxyz(q) - expected).max() < TOL
    assert np.abs(g.tilt_rad_of_quat_wxyz(2.5 * q) - expected).max() < TOL


def test_tilt_of_known_rotations():
    assert g.tilt_rad_of_matrix(np.eye(3)) == 0.0
    assert g.tilt_rad_of_matrix(np.diag([1.0, -1.0, -1.0])) == np.pi
    assert abs(g.tilt_rad_of_matrix(g.rpy_to_matrix(0.0, 1e-9, 2.0)) - 1e-9) < 1e-20
    assert abs(g.tilt_rad_of_quat_wxyz(g.rpy_to_quat_wxyz(0.3, 0.0, -1.2)) - 0.3) < TOL
    # yaw does not tilt
    assert g.tilt_rad_of_quat_wxyz([np.cos(0.4), 0.0, 0.0, np.sin(0.4)]) == 0.0


# ------------------------------------------------------------------------------- poses
def test_a_pose_laid_flat_keeps_its_place_and_heading(rotations):
    """Laid flat at a height, a pose keeps its x, y and heading (the turn of its x axis about
    the vertical) and stands upright: to the bit, the walking pattern's flat sole of that
    (x, y, z, yaw) row. A frame whose x axis is exactly vertical has no heading: it is laid
    heading along the world's x (or against it)."""
    from hubo_cli.walking.body import pose_of_row

    rng = np.random.default_rng(7)
    for R, xyz, z_m in zip(rotations, rng.uniform(-5.0, 5.0, (len(rotations), 3)),
                           rng.uniform(-0.1, 1.0, len(rotations)), strict=True):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, xyz
        flat = g.pose_laid_flat(T, z_m)
        heading = math.atan2(R[1, 0], R[0, 0])  # (numpy's arctan2 may differ in the last bit)
        assert np.array_equal(flat, pose_of_row(np.array([xyz[0], xyz[1], z_m, heading])))
        assert np.array_equal(flat[:, 2:], [[0.0, xyz[0]], [0.0, xyz[1]], [1.0, z_m], [0.0, 1.0]])
        assert np.abs(flat[:3, :3].T @ flat[:3, :3] - np.eye(3)).max() < TOL
        if np.hypot(R[0, 0], R[1, 0]) > 1e-6:  # the x axis turned as the frame's
            assert flat[0, 0] * R[1, 0] - flat[1, 0] * R[0, 0] == pytest.approx(0.0, abs=TOL)
            assert flat[:2, 0] @ R[:2, 0] > 0.0
        elif R[0, 0] == R[1, 0] == 0.0:
            assert abs(flat[1, 0]) < 1e-15  # (sin(pi) after a -0.0 in x)
    assert np.array_equal(g.pose_laid_flat(np.eye(4)), np.eye(4))  # z_m defaults to the floor


# ------------------------------------------------------------------------------- minimum jerk
PROFILE = np.polynomial.Polynomial([0, 0, 0, 10, -15, 6])


def test_min_jerk_is_the_quintic_clipped_to_its_ends():
    s = np.linspace(-0.5, 1.5, 2001)
    inside = (s >= 0) & (s <= 1)
    values = g.min_jerk(s)
    assert np.abs(values[inside] - PROFILE(s[inside])).max() < 1e-14
    assert (values[s < 0] == 0.0).all() and (values[s > 1] == 1.0).all()
    assert np.abs(g.min_jerk(1.0 - s[inside]) - (1.0 - values[inside])).max() < 1e-14
    scalar = g.min_jerk(float(s[900]))
    assert isinstance(scalar, float) and scalar == values[900]


def test_min_jerk_peaks_are_its_derivatives_maxima():
    s = np.linspace(0.0, 1.0, 200_001)
    for k, peak in [(1, g.MIN_JERK_PEAK_VELOCITY), (2, g.MIN_JERK_PEAK_ACCELERATION),
                    (3, g.MIN_JERK_PEAK_JERK)]:
        assert np.abs(PROFILE.deriv(k)(s)).max() == pytest.approx(peak, rel=1e-9)
