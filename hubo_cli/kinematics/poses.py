"""Small pose helpers: roll-pitch-yaw <-> rotation, building transforms (m, rad)."""

from __future__ import annotations

import numpy as np


def rpy_to_matrix(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (fixed-axis x, then y, then z)."""
    cr, sr = np.cos(roll_rad), np.sin(roll_rad)
    cp, sp = np.cos(pitch_rad), np.sin(pitch_rad)
    cy, sy = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def matrix_to_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in rad with R = Rz(yaw) Ry(pitch) Rx(roll); yaw = 0 at gimbal lock."""
    pitch = float(np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])))
    if np.hypot(R[0, 0], R[1, 0]) < 1e-12:
        return float(np.arctan2(-R[1, 2], R[1, 1])), pitch, 0.0
    return float(np.arctan2(R[2, 1], R[2, 2])), pitch, float(np.arctan2(R[1, 0], R[0, 0]))


def make_transform(R: np.ndarray, p_m) -> np.ndarray:
    """4x4 homogeneous transform from a rotation matrix and a position (m)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p_m
    return T


def is_rigid_transform(T: np.ndarray, tol: float = 1e-6) -> bool:
    """True if T is a finite 4x4 rigid transform (orthonormal rotation, det +1, last row 0001)."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        return False
    R = T[:3, :3]
    return bool(np.allclose(R.T @ R, np.eye(3), atol=tol) and abs(np.linalg.det(R) - 1) < tol
                and np.allclose(T[3], [0, 0, 0, 1], atol=tol))
