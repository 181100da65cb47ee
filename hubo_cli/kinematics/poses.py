"""Small pose helpers: building and checking 4x4 transforms (m); rotations are in
:mod:`hubo_cli.geometry`."""

from __future__ import annotations

import numpy as np

# the largest magnitude fk and ik take in a number (joints in rad, positions in m or mm, one
# pose or a batch's row): a Hubo limb reaches within a metre of the neck, so a number beyond it
# is a typo or garbage, refused rather than solved to an infinite error
MAX_INPUT_MAGNITUDE = 1e6


def make_transform(R: np.ndarray, p_m) -> np.ndarray:
    """4x4 homogeneous transform from a rotation matrix and a position (m)."""
    T = np.zeros((4, 4))  # np.eye costs as much again (it is Python over np.zeros)
    T[:3, :3] = R
    T[:3, 3] = p_m
    T[3, 3] = 1.0
    return T


def is_rigid_transform(T: np.ndarray, tol: float = 1e-6) -> bool:
    """True if T is a finite 4x4 rigid transform (orthonormal rotation, det +1, last row 0001)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1) < tol
                and np.allclose(T[3], [0, 0, 0, 1], atol=tol))
