"""The per-period arithmetic of :mod:`hubo_cli.kinematics.torso`, compiled with numba.

:func:`hubo_cli.kinematics.torso.torso_in_stance` runs whenever the legs' command changes (the
commanded torso pose), and the correction's filter step every control period. Done with numpy
each was about twenty small-array calls; here each is one compiled call: :func:`stance_pose` on
the legs' DH chains packed once per
:class:`~hubo_cli.kinematics.wholebody.WholeBody` (:class:`StanceLegs`), and
:func:`follow_deviation`. The arithmetic is that of the numpy versions (tests/test_torso.py
compares them to 1e-12).
"""

from __future__ import annotations

import math
import weakref

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, chain_fk, invert4, mul4
from hubo_cli.model import LEGS

ENCODERS = 0      # the mean of the two legs' orientations
IMU_TILT = 1      # the IMU's tilt under the legs' mean heading


@nb.njit(**JIT)
def _mul3(A, B, out):
    """out = A @ B (3x3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@nb.njit(**JIT)
def _log3(R, w):
    """w = the rotation vector of R (as :func:`hubo_cli.geometry.rotation_log`); R is 3x3 or a
    4x4 transform (only its rotation block is read)."""
    cos_angle = min(1.0, max(-1.0, (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0))
    w0 = (R[2, 1] - R[1, 2]) / 2.0
    w1 = (R[0, 2] - R[2, 0]) / 2.0
    w2 = (R[1, 0] - R[0, 1]) / 2.0
    sin_angle = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    angle = math.atan2(sin_angle, cos_angle)
    if cos_angle < 0.0:
        best, best_d = 0, -np.inf
        for k in range(3):
            d = R[k, k] - cos_angle
            if d > best_d:
                best, best_d = k, d
        c = np.empty(3)
        for i in range(3):
            c[i] = (R[i, best] + R[best, i]) / 2.0 - (cos_angle if i == best else 0.0)
        n = math.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        s = angle if c[0] * w0 + c[1] * w1 + c[2] * w2 >= 0.0 else -angle
        for i in range(3):
            w[i] = s * (c[i] / n)
        return
    if sin_angle < 1e-12:
        w[0], w[1], w[2] = w0, w1, w2
        return
    w[0], w[1], w[2] = w0 / sin_angle * angle, w1 / sin_angle * angle, w2 / sin_angle * angle


@nb.njit(**JIT)
def exp3(v, R):
    """R = the rotation of the rotation vector v (Rodrigues, as
    :func:`hubo_cli.geometry.rotation_exp`)."""
    angle = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    for i in range(3):
        for j in range(3):
            R[i, j] = 1.0 if i == j else 0.0
    if angle < 1e-12:
        return
    kx, ky, kz = v[0] / angle, v[1] / angle, v[2] / angle
    K = np.array([[0.0, -kz, ky], [kz, 0.0, -kx], [-ky, kx, 0.0]])
    s, c1 = math.sin(angle), 1.0 - math.cos(angle)
    for i in range(3):
        for j in range(3):
            KK = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
            R[i, j] += s * K[i, j] + c1 * KK


@nb.njit(**JIT)
def _turn(yaw, R_in, R):
    """R = Rz(yaw) @ R_in."""
    c, s = math.cos(yaw), math.sin(yaw)
    for j in range(3):
        R[0, j] = c * R_in[0, j] - s * R_in[1, j]
        R[1, j] = s * R_in[0, j] + c * R_in[1, j]
        R[2, j] = R_in[2, j]


@nb.njit(**JIT)
def _legs_fk(q, first, bases, dh, ends, soles, R_legs, p):
    """Per leg the neck's orientation in S seen through that leg, R_S_N = R_S_sole R_N_sole^T,
    into ``R_legs`` (2, 3, 3); the sum of the two soles' positions in the neck frame into ``p``
    (3,, zeroed by the caller)."""
    T = np.empty((4, 4))
    for leg in range(2):
        i0 = first[leg]
        chain_fk(q[i0:i0 + 6], bases[leg], dh[leg, 0], dh[leg, 1], dh[leg, 2], dh[leg, 3],
                 ends[leg], T)
        S = soles[leg]
        for i in range(3):
            for j in range(3):
                R_legs[leg, i, j] = S[i, 0] * T[j, 0] + S[i, 1] * T[j, 1] + S[i, 2] * T[j, 2]
            p[i] += T[i, 3]


@nb.njit(**JIT)
def _legs_mean(R_legs, R):
    """The geodesic mean of the two legs' orientations: R = R_0 exp(log(R_0^T R_1) / 2)."""
    D = np.empty((3, 3))
    A = R_legs[0]
    for i in range(3):
        for j in range(3):
            D[i, j] = A[0, i] * R_legs[1, 0, j] + A[1, i] * R_legs[1, 1, j] \
                + A[2, i] * R_legs[1, 2, j]
    w = np.empty(3)
    _log3(D, w)
    for i in range(3):
        w[i] /= 2
    E = np.empty((3, 3))
    exp3(w, E)
    _mul3(A, E, R)


@nb.njit(**JIT)
def _neck_on_soles(R, p, soles, out):
    """out = T_S_N with orientation R, placed so that each foot pivots about its sole origin
    (the mean of the two legs' neck positions)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = R[i, j]
        out[i, 3] = (soles[0, i, 3] + soles[1, i, 3]
                     - (R[i, 0] * p[0] + R[i, 1] * p[1] + R[i, 2] * p[2])) / 2
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@nb.njit(**JIT)
def stance_pose(q, first, bases, dh, ends, soles, R_imu, mode, out):
    """out = T_S_N (4x4) from the legs' joints.

    Args:
        q: the full joint vector (rad).
        first: index in ``q`` of each leg's first joint (2,), right leg first.
        bases: per leg the base transform of its DH chain (2, 4, 4).
        dh: per leg the DH offset, alpha, a and d (2, 4, 6).
        ends: per leg the end transform of its DH chain (2, 4, 4).
        soles: T_S_sole per leg (2, 4, 4).
        R_imu: the IMU's rotation matrix (3, 3); unused for ``ENCODERS``.
        mode: ``ENCODERS`` or ``IMU_TILT``.
        out: T_S_N (4x4).
    """
    R_legs = np.empty((2, 3, 3))
    p = np.zeros(3)
    _legs_fk(q, first, bases, dh, ends, soles, R_legs, p)
    R = np.empty((3, 3))
    if mode == ENCODERS:
        _legs_mean(R_legs, R)
    else:
        h = (math.atan2(R_legs[0, 1, 0], R_legs[0, 0, 0])
             + math.atan2(R_legs[1, 1, 0], R_legs[1, 0, 0])) / 2
        _turn(h - math.atan2(R_imu[1, 0], R_imu[0, 0]), R_imu, R)
    _neck_on_soles(R, p, soles, out)


@nb.njit(**JIT)
def _follow(now, raw, alpha, limit, max_step):
    """One low-pass step of ``now`` (3,) toward ``raw`` in place, kept within ``limit`` (norm)
    and moving at most ``max_step`` (norm)."""
    w0 = now[0] + alpha * (raw[0] - now[0])
    w1 = now[1] + alpha * (raw[1] - now[1])
    w2 = now[2] + alpha * (raw[2] - now[2])
    norm = math.hypot(math.hypot(w0, w1), w2)
    if norm > limit:
        f = limit / norm
        w0, w1, w2 = w0 * f, w1 * f, w2 * f
    s0, s1, s2 = w0 - now[0], w1 - now[1], w2 - now[2]
    size = math.hypot(math.hypot(s0, s1), s2)
    if size > max_step:
        f = max_step / size
        s0, s1, s2 = s0 * f, s1 * f, s2 * f
    now[0] += s0
    now[1] += s1
    now[2] += s2


@nb.njit(**JIT)
def follow_deviation(T_cmd_inv, T_meas, offset, rotation, alpha, bounds, T_dev, T_dev_inv):
    """One step of the torso correction's filter (:class:`~hubo_cli.kinematics.torso.
    TorsoCorrection`): the deviation T_cmd^-1 T_meas low-passed into ``offset`` and
    ``rotation`` (3,) in place, bounded by ``bounds`` (max offset, max offset step, max tilt,
    max tilt step); writes the filtered T_dev and its inverse (4x4)."""
    raw = np.empty((4, 4))
    mul4(T_cmd_inv, T_meas, raw)
    p = np.empty(3)
    for i in range(3):
        p[i] = raw[i, 3]
    _follow(offset, p, alpha, bounds[0], bounds[1])
    w = np.empty(3)
    _log3(raw, w)  # the whole 4x4: a block view would compile _log3 once more
    _follow(rotation, w, alpha, bounds[2], bounds[3])
    R = np.empty((3, 3))
    exp3(rotation, R)
    for i in range(3):
        for j in range(3):
            T_dev[i, j] = R[i, j]
        T_dev[i, 3] = offset[i]
    T_dev[3, 0] = 0.0
    T_dev[3, 1] = 0.0
    T_dev[3, 2] = 0.0
    T_dev[3, 3] = 1.0
    invert4(T_dev, T_dev_inv)


class StanceLegs:
    """The legs' chains and soles of a whole-body solver, packed for :func:`stance_pose`
    (built once; building it compiles the kernel or loads it from numba's cache).

    Args:
        body: the whole-body solver (its legs and ``T_S_sole``).
    """

    def __init__(self, body) -> None:
        model = body.model
        self.first = np.array([model.limb_slice(leg).start for leg in LEGS], dtype=np.int64)
        self.bases = np.empty((2, 4, 4))
        self.dh = np.empty((2, 4, 6))
        self.ends = np.empty((2, 4, 4))
        self.soles = np.empty((2, 4, 4))
        for k, leg in enumerate(LEGS):
            base, offset, alpha, a, d, end = body.legs[leg].fk_chain
            self.bases[k], self.dh[k], self.ends[k] = base, (offset, alpha, a, d), end
            self.soles[k] = body.T_S_sole[leg]
        self._none = np.zeros((3, 3))
        self.pose(body.q_home)  # compile (or load) the kernels now, not in a control period

    def pose(self, q_rad: np.ndarray, R_imu: np.ndarray | None = None) -> np.ndarray:
        """T_S_N (4x4, m); see :func:`hubo_cli.kinematics.torso.torso_in_stance`."""
        out = np.empty((4, 4))
        if R_imu is None:
            mode, R = ENCODERS, self._none
        else:
            mode, R = IMU_TILT, R_imu
        stance_pose(np.ascontiguousarray(q_rad, dtype=np.float64), self.first, self.bases,
                    self.dh, self.ends, self.soles, np.ascontiguousarray(R, dtype=np.float64),
                    mode, out)
        return out


_PACKED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def stance_legs(body) -> StanceLegs:
    """The :class:`StanceLegs` of ``body``, packed on first use and kept while it lives."""
    legs = _PACKED.get(body)
    if legs is None:
        legs = _PACKED[body] = StanceLegs(body)
    return legs
