"""Rotation conversions used by FASTRAK records, vectorised over N poses.

Conventions of the device (manual p.C-1): Euler angles are azimuth about Z, then elevation about
the new Y, then roll about the new X, in degrees, so ``R = Rz(az) @ Ry(el) @ Rx(roll)``;
quaternions are scalar first (w, x, y, z).
"""

from __future__ import annotations

import numpy as np


def rotation_from_euler_deg(az_el_rl_deg: np.ndarray) -> np.ndarray:
    """(N,3) azimuth, elevation, roll in degrees -> (N,3,3) ``Rz(az) @ Ry(el) @ Rx(roll)``."""
    a = np.radians(np.asarray(az_el_rl_deg, dtype=np.float64))
    ca, sa = np.cos(a[:, 0]), np.sin(a[:, 0])
    ce, se = np.cos(a[:, 1]), np.sin(a[:, 1])
    cr, sr = np.cos(a[:, 2]), np.sin(a[:, 2])
    R = np.empty((a.shape[0], 3, 3))
    R[:, 0, 0] = ca * ce
    R[:, 0, 1] = ca * se * sr - sa * cr
    R[:, 0, 2] = ca * se * cr + sa * sr
    R[:, 1, 0] = sa * ce
    R[:, 1, 1] = sa * se * sr + ca * cr
    R[:, 1, 2] = sa * se * cr - ca * sr
    R[:, 2, 0] = -se
    R[:, 2, 1] = ce * sr
    R[:, 2, 2] = ce * cr
    return R


def quat_from_euler_deg(az_el_rl_deg: np.ndarray) -> np.ndarray:
    """(N,3) azimuth, elevation, roll in degrees -> (N,4) quaternions of ``Rz Ry Rx``, w >= 0."""
    h = np.radians(np.asarray(az_el_rl_deg, dtype=np.float64)) * 0.5
    c, s = np.cos(h), np.sin(h)
    ca, ce, cr = c[:, 0], c[:, 1], c[:, 2]
    sa, se, sr = s[:, 0], s[:, 1], s[:, 2]
    q = np.stack([ca * ce * cr + sa * se * sr, ca * ce * sr - sa * se * cr,
                  ca * se * cr + sa * ce * sr, sa * ce * cr - ca * se * sr], axis=1)
    q[q[:, 0] < 0] *= -1.0
    return q


def euler_deg_from_rotation(R: np.ndarray) -> np.ndarray:
    """(N,3,3) rotations -> (N,3) azimuth, elevation, roll in degrees (inverse of the above)."""
    R = np.asarray(R, dtype=np.float64)
    az = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    el = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
    rl = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    return np.degrees(np.stack([az, el, rl], axis=1))


def rotation_from_quat(q_wxyz: np.ndarray) -> np.ndarray:
    """(N,4) scalar-first quaternions (normalised here) -> (N,3,3) rotation matrices."""
    q = np.asarray(q_wxyz, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    R = np.empty((q.shape[0], 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def quat_from_rotation(R: np.ndarray) -> np.ndarray:
    """(N,3,3) rotations -> (N,4) unit quaternions (w, x, y, z) with w >= 0 (Shepperd's method)."""
    R = np.asarray(R, dtype=np.float64)
    n = R.shape[0]
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    diag = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    pick = np.argmax(diag, axis=1)
    q = np.empty((n, 4))
    # largest of w, x, y, z computed from the diagonal, the others from off-diagonal sums
    for k in range(4):
        sel = pick == k
        if not sel.any():
            continue
        r = R[sel]
        if k == 0:
            s = np.sqrt(1.0 + tr[sel]) * 2
            q[sel] = np.stack([0.25 * s, (r[:, 2, 1] - r[:, 1, 2]) / s,
                               (r[:, 0, 2] - r[:, 2, 0]) / s, (r[:, 1, 0] - r[:, 0, 1]) / s], 1)
        elif k == 1:
            s = np.sqrt(np.maximum(1.0 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2], 1e-300)) * 2
            q[sel] = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / s, 0.25 * s,
                               (r[:, 0, 1] + r[:, 1, 0]) / s, (r[:, 0, 2] + r[:, 2, 0]) / s], 1)
        elif k == 2:
            s = np.sqrt(np.maximum(1.0 + r[:, 1, 1] - r[:, 0, 0] - r[:, 2, 2], 1e-300)) * 2
            q[sel] = np.stack([(r[:, 0, 2] - r[:, 2, 0]) / s, (r[:, 0, 1] + r[:, 1, 0]) / s,
                               0.25 * s, (r[:, 1, 2] + r[:, 2, 1]) / s], 1)
        else:
            s = np.sqrt(np.maximum(1.0 + r[:, 2, 2] - r[:, 0, 0] - r[:, 1, 1], 1e-300)) * 2
            q[sel] = np.stack([(r[:, 1, 0] - r[:, 0, 1]) / s, (r[:, 0, 2] + r[:, 2, 0]) / s,
                               (r[:, 1, 2] + r[:, 2, 1]) / s, 0.25 * s], 1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1.0
    return q
