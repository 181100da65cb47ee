"""Rotations, tilt, poses laid flat or inverted and the minimum-jerk profile: the one home
of the geometry hubo-cli shares.

Conventions:
    Quaternions: the function names say the order. ``wxyz`` (scalar first) is the project's
        (IMU, FASTRAK item 11, hubo-ach); ``xyzw`` is PyBullet's. Results are unit quaternions
        in canonical sign: the first non-zero of w, x, y, z is positive (so w >= 0), as
        ``scipy.spatial.transform.Rotation.as_quat(canonical=True)``.
    RPY: roll, pitch, yaw (rad) with ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (rotations about the
        fixed x, then y, then z axes): URDF's ``rpy`` and the fk/ik command's ``--rpy``.
    FASTRAK Euler: azimuth, elevation, roll (deg) with ``R = Rz(az) @ Ry(el) @ Rx(roll)``
        (FASTRAK manual p. C-1): the same rotation as RPY, in another order and unit.
    Gimbal lock: when the pitch (elevation) is +-90 deg, i.e. its cosine is below
        ``GIMBAL_LOCK_COS``, only yaw - roll (pitch +90) or yaw + roll (pitch -90) is defined;
        the roll is then 0 and the whole turn about the vertical is in yaw (azimuth), as scipy
        does. Near the lock (cosine below ``NEAR_LOCK_COS``) the yaw is taken from the matrix
        with the roll already removed, so the angles rebuild the matrix to rounding error
        everywhere.
    Shapes: every conversion broadcasts over leading axes: a (3, 3) matrix or (N, 3, 3)
        matrices, a (4,) quaternion or (N, 4) quaternions, (3,) or (N, 3) angles.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

GIMBAL_LOCK_COS = 1e-14
"""Below this cosine of the pitch (elevation) the roll is set to 0 (see the module docstring)."""
NEAR_LOCK_COS = 1e-3
"""Below this cosine of the pitch the yaw is taken from the matrix with the roll removed; above
it ``atan2(R[1, 0], R[0, 0])`` is as accurate (error below 1e-12 rad)."""

# Peaks of the minimum-jerk progress' derivatives over a unit move of unit duration: a move of
# distance D in time T reaches a peak speed of 1.875 D / T, acceleration 5.7735 D / T^2 (at
# u = 1/2 -+ sqrt(3)/6) and jerk 60 D / T^3 (at its start and end).
MIN_JERK_PEAK_VELOCITY = 1.875
MIN_JERK_PEAK_ACCELERATION = 10.0 / math.sqrt(3.0)
MIN_JERK_PEAK_JERK = 60.0


def min_jerk(s):
    """Minimum-jerk progress ``10 s^3 - 15 s^4 + 6 s^5`` from 0 to 1 (Hoff-Arbib, Flash-Hogan).

    Args:
        s: normalised time (float or array); clipped to [0, 1].

    Returns:
        The progress, a float for a float and an array of the same shape for an array.
    """
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


# ------------------------------------------------------------------------------- kernels
# One compiled kernel per conversion of one rotation; the public functions below run it over
# every leading index (a loop in the compiled batch function), so a single rotation costs a
# few microseconds (the simulator converts its state every period) and a batch runs at C speed.
# The batch functions declare their signatures, so they are compiled (or loaded from numba's
# cache) when this module is imported, never during the first real-time call.
JIT = {"cache": True, "nogil": True, "fastmath": False}  # as hubo_cli.kinematics.dh


@nb.njit(**JIT)
def _canonical(q):
    """Flip a quaternion (4,) in place so that its first non-zero component is positive."""
    for k in range(4):
        if q[k] != 0.0:
            if q[k] < 0.0:
                for j in range(4):
                    q[j] = -q[j]
            return


@nb.njit(**JIT)
def quat_to_matrix_into(q, R):
    """R (3x3, in place) = the rotation of quaternion q (w, x, y, z), normalised first."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    w, x, y, z = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    R[0, 0] = 1 - 2 * (y * y + z * z)
    R[0, 1] = 2 * (x * y - w * z)
    R[0, 2] = 2 * (x * z + w * y)
    R[1, 0] = 2 * (x * y + w * z)
    R[1, 1] = 1 - 2 * (x * x + z * z)
    R[1, 2] = 2 * (y * z - w * x)
    R[2, 0] = 2 * (x * z - w * y)
    R[2, 1] = 2 * (y * z + w * x)
    R[2, 2] = 1 - 2 * (x * x + y * y)


@nb.njit(**JIT)
def matrix_to_quat_into(R, q):
    """The unit quaternion (w, x, y, z) of the rotation matrix ``R`` into ``q`` (compiled, for
    other kernels). Shepperd's method: the largest of |w|, |x|, |y|, |z| comes from the
    diagonal, the others from sums of off-diagonal pairs divided by it (no small divisor, half
    turns too)."""
    m00, m11, m22 = R[0, 0], R[1, 1], R[2, 2]
    d0 = 1.0 + m00 + m11 + m22  # 4 w^2, 4 x^2, 4 y^2, 4 z^2
    d1 = 1.0 + m00 - m11 - m22
    d2 = 1.0 - m00 + m11 - m22
    d3 = 1.0 - m00 - m11 + m22
    if d0 >= d1 and d0 >= d2 and d0 >= d3:  # each row: 4 q_k times (w, x, y, z)
        q[0], q[1], q[2], q[3] = d0, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    elif d1 >= d2 and d1 >= d3:
        q[0], q[1], q[2], q[3] = R[2, 1] - R[1, 2], d1, R[0, 1] + R[1, 0], R[0, 2] + R[2, 0]
    elif d2 >= d3:
        q[0], q[1], q[2], q[3] = R[0, 2] - R[2, 0], R[0, 1] + R[1, 0], d2, R[1, 2] + R[2, 1]
    else:
        q[0], q[1], q[2], q[3] = R[1, 0] - R[0, 1], R[0, 2] + R[2, 0], R[1, 2] + R[2, 1], d3
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for k in range(4):
        q[k] /= n
    _canonical(q)


@nb.njit(**JIT)
def _rpy_to_matrix(rpy, R):
    cr, sr = math.cos(rpy[0]), math.sin(rpy[0])
    cp, sp = math.cos(rpy[1]), math.sin(rpy[1])
    cy, sy = math.cos(rpy[2]), math.sin(rpy[2])
    R[0, 0] = cy * cp
    R[0, 1] = cy * sp * sr - sy * cr
    R[0, 2] = cy * sp * cr + sy * sr
    R[1, 0] = sy * cp
    R[1, 1] = sy * sp * sr + cy * cr
    R[1, 2] = sy * sp * cr - cy * sr
    R[2, 0] = -sp
    R[2, 1] = cp * sr
    R[2, 2] = cp * cr


@nb.njit(**JIT)
def _matrix_to_rpy(R, rpy):
    cos_pitch = math.hypot(R[0, 0], R[1, 0])
    roll = 0.0 if cos_pitch < GIMBAL_LOCK_COS else math.atan2(R[2, 1], R[2, 2])
    rpy[0] = roll
    rpy[1] = math.atan2(-R[2, 0], cos_pitch)
    if cos_pitch >= NEAR_LOCK_COS:
        rpy[2] = math.atan2(R[1, 0], R[0, 0])
    else:
        # R Rx(roll)^T = Rz(yaw) Ry(pitch), whose second column is (-sin yaw, cos yaw, 0)
        cr, sr = math.cos(roll), math.sin(roll)
        rpy[2] = math.atan2(R[0, 2] * sr - R[0, 1] * cr, R[1, 1] * cr - R[1, 2] * sr)


@nb.njit(**JIT)
def _rpy_to_quat(rpy, q):
    cr, sr = math.cos(0.5 * rpy[0]), math.sin(0.5 * rpy[0])
    cp, sp = math.cos(0.5 * rpy[1]), math.sin(0.5 * rpy[1])
    cy, sy = math.cos(0.5 * rpy[2]), math.sin(0.5 * rpy[2])
    q[0] = cy * cp * cr + sy * sp * sr
    q[1] = cy * cp * sr - sy * sp * cr
    q[2] = cy * sp * cr + sy * cp * sr
    q[3] = sy * cp * cr - cy * sp * sr
    _canonical(q)


@nb.njit("float64[:, :, ::1](float64[:, ::1])", **JIT)
def _quats_to_matrices(q):
    out = np.empty((q.shape[0], 3, 3))
    for i in range(q.shape[0]):
        quat_to_matrix_into(q[i], out[i])
    return out


@nb.njit("float64[:, ::1](float64[:, :, ::1])", **JIT)
def _matrices_to_quats(R):
    out = np.empty((R.shape[0], 4))
    for i in range(R.shape[0]):
        matrix_to_quat_into(R[i], out[i])
    return out


@nb.njit("float64[:, :, ::1](float64[:, ::1])", **JIT)
def _rpys_to_matrices(rpy):
    out = np.empty((rpy.shape[0], 3, 3))
    for i in range(rpy.shape[0]):
        _rpy_to_matrix(rpy[i], out[i])
    return out


@nb.njit("float64[:, ::1](float64[:, :, ::1])", **JIT)
def _matrices_to_rpys(R):
    out = np.empty((R.shape[0], 3))
    for i in range(R.shape[0]):
        _matrix_to_rpy(R[i], out[i])
    return out


@nb.njit("float64[:, ::1](float64[:, ::1])", **JIT)
def _rpys_to_quats(rpy):
    out = np.empty((rpy.shape[0], 4))
    for i in range(rpy.shape[0]):
        _rpy_to_quat(rpy[i], out[i])
    return out


def _each(batch_kernel, values, item_shape: tuple[int, ...], out_item_shape: tuple[int, ...]
          ) -> np.ndarray:
    """Run a batch kernel over the leading axes of ``values`` (items of ``item_shape``)."""
    a = np.asarray(values, dtype=np.float64)
    if a.shape[a.ndim - len(item_shape):] != item_shape:
        raise ValueError(f"expected items of shape {item_shape}, got an array of {a.shape}")
    lead = a.shape[:a.ndim - len(item_shape)]
    flat = np.ascontiguousarray(a.reshape((-1,) + item_shape))
    return batch_kernel(flat).reshape(lead + out_item_shape)


# ------------------------------------------------------------------------------- one rotation
# The same arithmetic as the kernels, in Python floats, for a single quaternion or matrix: the
# simulator and the modules convert a few rotations every period, where the batch machinery
# (array checks, the compiled call) costs more than the conversion. The results are identical
# to the kernels' (tests/test_geometry.py compares them bit for bit).
def _one_quat(values) -> tuple | list | None:
    """The four numbers of a single quaternion (a (4,) array, tuple or list), else None."""
    if isinstance(values, np.ndarray):
        return values.tolist() if values.shape == (4,) else None
    if (isinstance(values, (tuple, list)) and len(values) == 4
            and all(isinstance(v, (float, int)) for v in values)):
        return values
    return None


def _one_matrix(values) -> list[list[float]] | None:
    """The rows of a single (3, 3) matrix given as an array, else None."""
    if isinstance(values, np.ndarray) and values.shape == (3, 3):
        return values.tolist()
    return None


def _quat_to_matrix_rows(w: float, x: float, y: float, z: float) -> np.ndarray:
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                     2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                     2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
                    ).reshape(3, 3)


def matrix_rows_to_quat_wxyz(R) -> np.ndarray:
    """:func:`matrix_to_quat_wxyz` of one rotation given as its three rows of floats."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = R
    d0 = 1.0 + m00 + m11 + m22
    d1 = 1.0 + m00 - m11 - m22
    d2 = 1.0 - m00 + m11 - m22
    d3 = 1.0 - m00 - m11 + m22
    if d0 >= d1 and d0 >= d2 and d0 >= d3:
        q = [d0, m21 - m12, m02 - m20, m10 - m01]
    elif d1 >= d2 and d1 >= d3:
        q = [m21 - m12, d1, m01 + m10, m02 + m20]
    elif d2 >= d3:
        q = [m02 - m20, m01 + m10, d2, m12 + m21]
    else:
        q = [m10 - m01, m02 + m20, m12 + m21, d3]
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    q = [v / n for v in q]
    for v in q:  # canonical sign: the first non-zero component positive
        if v != 0.0:
            if v < 0.0:
                q = [-c for c in q]
            break
    return np.array(q)


def _matrix_rows_to_rpy(R: list[list[float]]) -> np.ndarray:
    cos_pitch = float(np.hypot(R[0][0], R[1][0]))  # the C library's, as the kernel
    roll = 0.0 if cos_pitch < GIMBAL_LOCK_COS else math.atan2(R[2][1], R[2][2])
    pitch = math.atan2(-R[2][0], cos_pitch)
    if cos_pitch >= NEAR_LOCK_COS:
        yaw = math.atan2(R[1][0], R[0][0])
    else:
        cr, sr = math.cos(roll), math.sin(roll)
        yaw = math.atan2(R[0][2] * sr - R[0][1] * cr, R[1][1] * cr - R[1][2] * sr)
    return np.array((roll, pitch, yaw))


def _rpy_array(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    return np.stack(np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                          for a in (roll_rad, pitch_rad, yaw_rad))), axis=-1)


# ------------------------------------------------------------------------------- quaternions
def quat_wxyz_to_matrix(q_wxyz) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) w, x, y, z (normalised here)."""
    one = _one_quat(q_wxyz)
    if one is not None:
        return _quat_to_matrix_rows(*one)
    return _each(_quats_to_matrices, q_wxyz, (4,), (3, 3))


def quat_xyzw_to_matrix(q_xyzw) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) x, y, z, w (PyBullet's order)."""
    one = _one_quat(q_xyzw)
    if one is not None:
        x, y, z, w = one
        return _quat_to_matrix_rows(w, x, y, z)
    return quat_wxyz_to_matrix(np.asarray(q_xyzw, dtype=np.float64)[..., [3, 0, 1, 2]])


def matrix_to_quat_wxyz(R) -> np.ndarray:
    """Canonical unit quaternions (..., 4) w, x, y, z of rotation matrices (..., 3, 3)
    (Shepperd's method: accurate for every rotation, half turns included)."""
    one = _one_matrix(R)
    if one is not None:
        return matrix_rows_to_quat_wxyz(one)
    return _each(_matrices_to_quats, R, (3, 3), (4,))


def unit_quats(q) -> tuple[np.ndarray, np.ndarray]:
    """Quaternions (N, 4) made unit, and their norms (N,), without overflow: a quaternion whose
    squares overflow ([1e300, 0, 0, 0]; q / inf would be a zero quaternion) is scaled by its
    largest component first (its norm is then inf). A zero quaternion stays zero, its norm 0:
    the caller refuses it. Components must be finite."""
    q = np.asarray(q, dtype=np.float64).reshape(-1, 4)
    with np.errstate(over="ignore"):
        norm = np.linalg.norm(q, axis=1)
    unit = q / np.where(norm > 0.0, norm, 1.0)[:, None]
    over = ~np.isfinite(norm)
    if over.any():
        scaled = q[over] / np.abs(q[over]).max(axis=1)[:, None]
        unit[over] = scaled / np.linalg.norm(scaled, axis=1)[:, None]
    return unit, norm


def slerp_quat_wxyz(q0_wxyz, q1_wxyz, u) -> np.ndarray:
    """Spherical interpolation between unit quaternions (..., 4) at fractions ``u`` (...,),
    along the shorter arc (``u`` = 0 gives q0, 1 gives q1 or -q1)."""
    q0 = np.asarray(q0_wxyz, dtype=np.float64)
    q1 = np.asarray(q1_wxyz, dtype=np.float64)
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    u = np.asarray(u, dtype=np.float64)[..., None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    small = theta < 1e-6
    sin_t = np.where(small, 1.0, np.sin(theta))
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / sin_t)
    w1 = np.where(small, u, np.sin(u * theta) / sin_t)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ------------------------------------------------------------------------------- roll, pitch, yaw
def rpy_to_matrix(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``: (3, 3) for floats, (..., 3, 3) for arrays."""
    return _each(_rpys_to_matrices, _rpy_array(roll_rad, pitch_rad, yaw_rad), (3,), (3, 3))


def matrix_to_rpy(R) -> np.ndarray:
    """(..., 3) roll, pitch, yaw (rad) of rotation matrices (..., 3, 3), inverse of
    :func:`rpy_to_matrix`: roll and yaw in [-pi, pi], pitch in [-pi/2, pi/2]; roll = 0 at the
    gimbal lock (see the module docstring)."""
    one = _one_matrix(R)
    if one is not None:
        return _matrix_rows_to_rpy(one)
    return _each(_matrices_to_rpys, R, (3, 3), (3,))


def rpy_to_quat_wxyz(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """Canonical quaternion(s) (..., 4) w, x, y, z of ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``."""
    return _each(_rpys_to_quats, _rpy_array(roll_rad, pitch_rad, yaw_rad), (3,), (4,))


def quat_wxyz_to_rpy(q_wxyz) -> np.ndarray:
    """(..., 3) roll, pitch, yaw (rad) of quaternions (..., 4) w, x, y, z."""
    return matrix_to_rpy(quat_wxyz_to_matrix(q_wxyz))


# ------------------------------------------------------------------------------- FASTRAK Euler
def fastrak_euler_deg_to_matrix(az_el_rl_deg) -> np.ndarray:
    """(..., 3, 3) ``Rz(az) @ Ry(el) @ Rx(roll)`` of (..., 3) azimuth, elevation, roll (deg)."""
    a = np.radians(np.asarray(az_el_rl_deg, dtype=np.float64))
    return rpy_to_matrix(a[..., 2], a[..., 1], a[..., 0])


def matrix_to_fastrak_euler_deg(R) -> np.ndarray:
    """(..., 3) azimuth, elevation, roll (deg) of rotation matrices (..., 3, 3); roll = 0 at the
    gimbal lock (elevation +-90 deg)."""
    return np.degrees(matrix_to_rpy(R)[..., ::-1])


def fastrak_euler_deg_to_quat_wxyz(az_el_rl_deg) -> np.ndarray:
    """Canonical quaternion(s) (..., 4) w, x, y, z of (..., 3) azimuth, elevation, roll (deg)."""
    a = np.radians(np.asarray(az_el_rl_deg, dtype=np.float64))
    return rpy_to_quat_wxyz(a[..., 2], a[..., 1], a[..., 0])


# ------------------------------------------------------------------------------- rotation vectors
def rotation_log_floats(r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
                        r20: float, r21: float, r22: float) -> tuple[float, float, float] | None:
    """:func:`rotation_log` of a rotation of up to a quarter turn given as its nine entries
    (row by row), in Python floats; None beyond a quarter turn (use :func:`rotation_log`)."""
    cos_angle = min(1.0, max(-1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    if cos_angle < 0.0:
        return None
    w0, w1, w2 = (r21 - r12) / 2.0, (r02 - r20) / 2.0, (r10 - r01) / 2.0
    sin_angle = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if sin_angle < 1e-12:
        return w0, w1, w2  # small angle: the vector part is the rotation vector
    scale = math.atan2(sin_angle, cos_angle) / sin_angle
    return w0 * scale, w1 * scale, w2 * scale


def rotation_log(R) -> np.ndarray:
    """Rotation vector (axis * angle, rad, angle in [0, pi]) of a (3, 3) rotation matrix."""
    R = np.asarray(R, dtype=np.float64)
    # up to a quarter turn (the control loop's case, several times a period) in Python floats:
    # the same operations as the array formula below, without its dispatch
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
    small = rotation_log_floats(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    if small is not None:
        return np.array(small)
    # beyond a quarter turn (up to a half turn, where w vanishes) the axis k is read from the
    # symmetric part, (R + R^T) / 2 - cos I = (1 - cos) k k^T, and its sign from w
    cos_angle = min(1.0, max(-1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    angle = np.arctan2(np.linalg.norm(w), cos_angle)
    B = (R + R.T) / 2.0 - cos_angle * np.eye(3)
    column = B[:, np.argmax(np.diagonal(B))]
    axis = column / np.linalg.norm(column)
    return (angle if axis @ w >= 0.0 else -angle) * axis


def rotation_exp(v) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector (axis * angle, rad) (Rodrigues)."""
    v0, v1, v2 = np.asarray(v, dtype=np.float64).tolist()
    angle = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if angle < 1e-12:
        return np.eye(3)
    # I + sin K + (1 - cos) K^2 for the unit axis k, in Python floats (K^2 = k k^T - I)
    k0, k1, k2 = v0 / angle, v1 / angle, v2 / angle
    s, c = math.sin(angle), 1.0 - math.cos(angle)
    return np.array([[1.0 - c * (k1 * k1 + k2 * k2), c * k0 * k1 - s * k2, c * k0 * k2 + s * k1],
                     [c * k0 * k1 + s * k2, 1.0 - c * (k0 * k0 + k2 * k2), c * k1 * k2 - s * k0],
                     [c * k0 * k2 - s * k1, c * k1 * k2 + s * k0, 1.0 - c * (k0 * k0 + k1 * k1)]])


# ------------------------------------------------------------------------------- poses
def pose_laid_flat(T_world_frame: np.ndarray, z_m: float = 0.0) -> np.ndarray:
    """A frame's pose (4x4, in the world) laid flat on a floor at height ``z_m`` (world):
    the same x, y and heading (the turn of its x axis about the world's vertical,
    ``atan2(T[1, 0], T[0, 0])``), its z axis the world's (a sole or the torso over the floor)."""
    T = T_world_frame
    heading = math.atan2(T[1, 0], T[0, 0])
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s, 0.0, T[0, 3]], [s, c, 0.0, T[1, 3]], [0.0, 0.0, 1.0, z_m],
                     [0.0, 0.0, 0.0, 1.0]])


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """The inverse of rigid transforms (4x4, or a stack of them: ... x 4 x 4): [R^T, -R^T p]."""
    T = np.asarray(T, dtype=float)
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros(T.shape)
    out[..., :3, :3] = R_t
    out[..., :3, 3] = -(R_t @ T[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


# ------------------------------------------------------------------------------- tilt
def tilt_rad_of_z_axis(x: float, y: float, z: float) -> float:
    """Angle (rad, [0, pi]) between a frame's z axis, given by its world components (the third
    column of the frame's rotation in the world), and the world's z axis."""
    return math.atan2(math.hypot(x, y), z)


def tilt_rad_of_matrix(R):
    """Angle (rad, [0, pi]) between a frame's z axis and the world's z axis, for rotation
    matrices (..., 3, 3) of the frame in the world (torso, sole)."""
    one = _one_matrix(R)
    if one is not None:  # one matrix (several a period): the same in Python floats
        (_, _, r02), (_, _, r12), (_, _, r22) = one
        return tilt_rad_of_z_axis(r02, r12, r22)
    R = np.asarray(R, dtype=np.float64)
    return np.arctan2(np.hypot(R[..., 0, 2], R[..., 1, 2]), R[..., 2, 2])


def tilt_rad_of_quat_wxyz(q_wxyz):
    """:func:`tilt_rad_of_matrix` of quaternions (..., 4) w, x, y, z (any norm): the body z
    axis makes the angle ``2 atan2(|(x, y)|, |(w, z)|)`` with the world's z axis."""
    if isinstance(q_wxyz, np.ndarray) and q_wxyz.shape == (4,):  # one (each period): in floats
        w, x, y, z = q_wxyz.tolist()
        return 2.0 * math.atan2(math.hypot(x, y), math.hypot(w, z))
    q = np.asarray(q_wxyz, dtype=np.float64)
    return 2.0 * np.arctan2(np.hypot(q[..., 1], q[..., 2]), np.hypot(q[..., 0], q[..., 3]))


def roll_pitch_of_quat_wxyz(q_wxyz) -> tuple[float, float]:
    """Roll and pitch (rad) of one quaternion w, x, y, z: the tilt about world x and y of the
    :func:`quat_wxyz_to_rpy` decomposition (the yaw does not change them)."""
    rpy = quat_wxyz_to_rpy(q_wxyz)
    return float(rpy[0]), float(rpy[1])
