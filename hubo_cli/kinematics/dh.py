"""Denavit-Hartenberg forward kinematics kernels (standard convention, paper eq. 1).

T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) with theta_i = q_i + offset_i. The kernels are
compiled with numba; all lengths are metres, angles radians, transforms 4x4 homogeneous.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np

JIT = {"cache": True, "nogil": True, "fastmath": False}
# A constant True that one kernel passes to another makes numba compile the callee once more
# for that literal value (seconds per kernel, on every cold cache); TRUE[0] is a plain bool.
TRUE = np.ones(1, dtype=np.bool_)
# The same for a constant int (a joint index, a count): INDEX[3] is a plain int64 of value 3.
INDEX = np.arange(8)
_FLOAT64 = np.dtype(np.float64)  # numpy's one float64 descriptor (``is``: cheaper than ==)


def kernel_array(x) -> np.ndarray:
    """``x`` itself when a compiled kernel takes it as it is (float64, C-ordered, aligned,
    writable: the one signature every kernel compiles), else such a copy (a read-only or
    non-contiguous array would compile the kernel once more; an equal descriptor that is not
    numpy's own is copied too)."""
    if type(x) is np.ndarray and x.dtype is _FLOAT64 and x.flags.carray:
        return x
    return np.array(x, dtype=float, order="C")


PARALLEL_MIN_ROWS = 64  # fewer rows than this per thread run in the calling thread


def in_threads(n: int, run: Callable[[int, int], None]) -> None:
    """``run(start, stop)`` over rows 0 .. n-1 split into contiguous parts, one per numba thread.

    For serial ``nogil`` kernels: the same work as a ``parallel=True`` kernel (every row is
    independent, so the results are the same), without the parallel kernel's compilation
    (seconds per kernel on a cold cache).
    """
    parts = max(1, min(nb.get_num_threads(), n // PARALLEL_MIN_ROWS))
    if parts == 1:
        run(0, n)
        return
    bounds = [n * k // parts for k in range(parts + 1)]
    with ThreadPoolExecutor(parts) as pool:
        for future in [pool.submit(run, bounds[k], bounds[k + 1]) for k in range(parts)]:
            future.result()


@nb.njit(**JIT)
def matmul4(A, B, out):
    """out = A @ B for 4x4 homogeneous transforms (last row assumed [0 0 0 1])."""
    for i in range(3):
        a0, a1, a2, a3 = A[i, 0], A[i, 1], A[i, 2], A[i, 3]
        for j in range(4):
            out[i, j] = a0 * B[0, j] + a1 * B[1, j] + a2 * B[2, j]
        out[i, 3] += a3
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@nb.njit(**JIT)
def mul4(A, B, out):
    """out = A @ B (4x4, general: every entry the sum of its four products, in order)."""
    for i in range(4):
        for j in range(4):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j] \
                + A[i, 3] * B[3, j]


@nb.njit(**JIT)
def invert4(T, out):
    """out = T^-1 for a rigid transform (rotation transposed, translation -R^T p)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = T[j, i]
        out[i, 3] = -(T[0, i] * T[0, 3] + T[1, i] * T[1, 3] + T[2, i] * T[2, 3])
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@nb.njit(**JIT)
def dh_transform(theta, alpha, a, d, out):
    """Write the standard DH transform of one joint into ``out`` (4x4)."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    out[0, 0] = ct
    out[0, 1] = -st * ca
    out[0, 2] = st * sa
    out[0, 3] = a * ct
    out[1, 0] = st
    out[1, 1] = ct * ca
    out[1, 2] = -ct * sa
    out[1, 3] = a * st
    out[2, 0] = 0.0
    out[2, 1] = sa
    out[2, 2] = ca
    out[2, 3] = d
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@nb.njit(inline="always", **JIT)
def dh_step(th, alpha, a, d, x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2):
    """One DH joint applied to a frame kept as its axes (x, y, z) and origin p.

    x' = c x + s y, y' = ca (-s x + c y) + sa z, z' = -sa (-s x + c y) + ca z, p' = p + d z + a x'
    with c, s = cos, sin(th) and ca, sa = cos, sin(alpha). Returns the 12 new components in the
    argument order (x', y', z', p').
    """
    ct, st = math.cos(th), math.sin(th)
    ca, sa = math.cos(alpha), math.sin(alpha)
    nx0, nx1, nx2 = ct * x0 + st * y0, ct * x1 + st * y1, ct * x2 + st * y2
    w0, w1, w2 = -st * x0 + ct * y0, -st * x1 + ct * y1, -st * x2 + ct * y2
    return (nx0, nx1, nx2,
            ca * w0 + sa * z0, ca * w1 + sa * z1, ca * w2 + sa * z2,
            -sa * w0 + ca * z0, -sa * w1 + ca * z1, -sa * w2 + ca * z2,
            p0 + d * z0 + a * nx0, p1 + d * z1 + a * nx1, p2 + d * z2 + a * nx2)


@nb.njit(inline="always", **JIT)
def end_frame(x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2, end, out):
    """out = [x y z p; 0 0 0 1] @ end: the end frame after the last joint (4x4)."""
    for j in range(4):
        e0, e1, e2 = end[0, j], end[1, j], end[2, j]
        out[0, j] = x0 * e0 + y0 * e1 + z0 * e2
        out[1, j] = x1 * e0 + y1 * e1 + z1 * e2
        out[2, j] = x2 * e0 + y2 * e1 + z2 * e2
    out[0, 3] += p0
    out[1, 3] += p1
    out[2, 3] += p2
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@nb.njit(**JIT)
def chain_fk(q, base, offset, alpha, a, d, end, out):
    """out = base @ T_1(q1) ... T_6(q6) @ end: the end frame in the base's parent frame.

    Allocation-free: the running frame is kept as its axes and origin (:func:`dh_step`).
    """
    x0, x1, x2 = base[0, 0], base[1, 0], base[2, 0]
    y0, y1, y2 = base[0, 1], base[1, 1], base[2, 1]
    z0, z1, z2 = base[0, 2], base[1, 2], base[2, 2]
    p0, p1, p2 = base[0, 3], base[1, 3], base[2, 3]
    for i in range(6):
        x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2 = dh_step(
            q[i] + offset[i], alpha[i], a[i], d[i], x0, x1, x2, y0, y1, y2, z0, z1, z2,
            p0, p1, p2)
    end_frame(x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2, end, out)


@nb.njit(parallel=True, **JIT)
def chain_fk_batch(Q, base, offset, alpha, a, d, end):
    """FK of N joint vectors (N x 6) -> N x 4 x 4 transforms."""
    n = Q.shape[0]
    out = np.empty((n, 4, 4))
    for k in nb.prange(n):
        chain_fk(Q[k], base, offset, alpha, a, d, end, out[k])
    return out


@nb.njit(**JIT)
def pose_error(T, T_goal):
    """(position error in m, rotation error in rad) between two transforms.

    The rotation error is the angle of R_goal^T R, computed with atan2 so that it stays accurate
    near zero (acos of the trace loses half the digits there).
    """
    dx = T[0, 3] - T_goal[0, 3]
    dy = T[1, 3] - T_goal[1, 3]
    dz = T[2, 3] - T_goal[2, 3]
    pos = math.sqrt(dx * dx + dy * dy + dz * dz)
    # E = R_goal^T R
    tr = 0.0
    E = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            E[i, j] = T_goal[0, i] * T[0, j] + T_goal[1, i] * T[1, j] + T_goal[2, i] * T[2, j]
        tr += E[i, i]
    vx = E[2, 1] - E[1, 2]
    vy = E[0, 2] - E[2, 0]
    vz = E[1, 0] - E[0, 1]
    sin_angle = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
    cos_angle = 0.5 * (tr - 1.0)
    return pos, math.atan2(sin_angle, cos_angle)
