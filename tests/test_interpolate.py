"""Cartesian pose interpolation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hubo_cli.geometry import rotation_exp, rotation_log, rpy_to_matrix
from hubo_cli.kinematics.interpolate import PosePath, PoseSegment, segment_duration
from hubo_cli.kinematics.poses import make_transform

angles = st.floats(-3.0, 3.0)


@settings(max_examples=200, deadline=None)
@given(angles, st.floats(-1.5, 1.5), angles)
def test_log_exp_round_trip(r, p, y):
    R = rpy_to_matrix(r, p, y)
    assert np.allclose(rotation_exp(rotation_log(R)), R, atol=1e-9)


def test_half_turn_log():
    R = rpy_to_matrix(np.pi, 0, 0)
    assert np.allclose(rotation_exp(rotation_log(R)), R, atol=1e-12)


def test_segment_is_straight_and_ends_exactly():
    A = make_transform(rpy_to_matrix(0.3, -0.2, 1.0), [0.2, -0.3, -0.5])
    B = make_transform(np.eye(3), [0.45, -0.15, 0.1])
    seg = PoseSegment(A, B, 2.0)
    assert np.allclose(seg.at(0.0), A) and np.allclose(seg.at(2.0), B)
    assert np.allclose(seg.at(5.0), B)
    direction = (B[:3, 3] - A[:3, 3]) / np.linalg.norm(B[:3, 3] - A[:3, 3])
    for t in np.linspace(0, 2, 11):
        offset = seg.at(t)[:3, 3] - A[:3, 3]
        assert np.linalg.norm(offset - direction * (offset @ direction)) < 1e-12
        R = seg.at(t)[:3, :3]
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_linear_profile_has_constant_speed():
    A, B = np.eye(4), make_transform(np.eye(3), [0.0, 0.1, 0.0])
    seg = PoseSegment(A, B, 4.0, profile="linear")
    ys = [seg.at(t)[1, 3] for t in np.linspace(0, 4, 9)]
    assert np.allclose(np.diff(ys), 0.1 / 8)


def test_path_plays_segments_in_order():
    A = np.eye(4)
    B = make_transform(np.eye(3), [0.1, 0, 0])
    C = make_transform(np.eye(3), [0.1, 0.2, 0])
    path = PosePath([PoseSegment(A, B, 1.0), PoseSegment(B, C, 2.0)])
    assert path.duration_s == pytest.approx(3.0)
    assert np.allclose(path.at(1.0), B) and np.allclose(path.at(3.5), C)
    assert path.index_at(2.0) == 1
    assert segment_duration(A, B, 0.05) == pytest.approx(2.0)
