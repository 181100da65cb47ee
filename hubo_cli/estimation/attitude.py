"""The torso's attitude from the IMU's gyro and accelerometer and the legs' kinematics: a Kalman
filter that estimates the gyro's bias (the multi-layer paper's KalmanFilter component, as
hrpsys-base runs it ahead of its stabilizer) and the floor's tilt.

The filter is a multiplicative (error-state) extended Kalman filter on the quaternion
q_world_torso, the gyro bias b (torso axes) and the floor's normal n (world). Its error state is
the small rotation dtheta (torso axes: the true attitude is q exp(dtheta)), the bias error db
and the floor's small tilt about the world's x and y, with an 8 x 8 covariance.

- Predict, each period dt: the bias-corrected rate omega = gyro - b turns q by omega dt; the
  covariance grows by the gyro's white noise (angle random walk) and the bias's random walk.
- Correct: the accelerometer's direction a / |a| is gravity's direction in the torso axes,
  R^T e_z, while the torso does not accelerate. While it is still (the motion below), its
  noise is ``accel_noise_m_s2`` (the sensor's own) and the vibration measured (the RMS,
  low-passed over ``motion_time_s``, of the reading's departure from its own low-passed
  mean, that mean turned with the gyro); once the torso has been still ``still_learn_s``
  (settled; a robot is set down and settles before a run starts) the correction reaches the
  bias and the floor's tilt too: standing still is when they are learnt.
- Motion: the root mean square, low-passed over ``motion_time_s``, of the departure of |a|
  from g and of the bias-corrected rate, and this reading's |a| - g, rate and departure from
  the gravity expected (sideways too); the torso is still while they stay below
  ``still_accel_m_s2`` and ``still_gyro_rad_s`` (the readings' below 3 and 2 times that).
  Beyond, by the factor m (the larger ratio), the accelerometer's noise grows by the factor
  ``1 + motion_noise_gain (m - 1)``: a walk's sway and a push accelerate the torso sideways
  for a second and more, which the accelerometer cannot tell from a tilt (its norm hardly
  changes, the rate does). Not settled while the legs tell the tilt, the accelerometer is not
  used (they tell it far better). A reading whose |a| departs from g by more than
  ``accel_reject_m_s2`` (an impact) is not used at all.
- Heading: gravity says nothing about it, nor about the bias about the vertical. While still,
  the torso does not turn about the vertical, so the gyro's vertical component is read as
  that bias (a zero-rate update, its noise the rate's measured vibration, unless it departs
  by more than 3 sigma). The yaw follows the bias-corrected gyro, from the heading the IMU
  reports in the first state.
- The legs: a sole that lies flat on the floor (in ``CONTACT``, pressing ``legs_min_fz_n``
  with its centre of pressure ``legs_cop_margin_m`` inside its outline) has the floor's
  normal for its own z axis, so the legs' forward kinematics of the measured joints
  (:class:`~hubo_cli.estimation.base.LegsKinematics`) give the torso's tilt from the floor,
  R^T n, to the encoders' noise and the sole's compliance (``legs_tilt_noise_rad``), walking
  or not; that correction reaches the bias too (the bias across gravity is learnt while
  walking), not the floor's tilt: only gravity tells that, so the floor is learnt from the
  accelerometer once settled. The contact and the wrenches are the last period's (they come
  after the attitude in the period: the wrenches need it).
- Start: the first attitude is the first accelerometer reading's tilt (the simulator's first
  reading is gravity alone: no velocity to difference yet) and the IMU's reported heading,
  no bias; the floor's normal is the soles' (both stand on it at the start, as the floating
  base has them) through the legs and that attitude. A walk moves the torso from its first
  period (0.5-2.5 m/s^2 sideways), so neither could be learnt from the accelerometer after
  it. A residual beyond the filter's expectation (chi-square, :data:`GATE_D2`) counts with
  its noise grown to match it.
- A reading that is not finite or beyond the sensor's range is not used: a bad gyro holds the
  attitude (no prediction), a bad accelerometer skips the correction; :data:`IMU_REJECTED`
  says which this period. A result that would not be finite is never written: the last
  estimate is kept.

The arithmetic is one compiled kernel a period (:func:`_filter_step`). Its parameters are the
robot file's ``[estimation.attitude]`` table (:class:`AttitudeParams`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numba as nb
import numpy as np

from hubo_cli.dataflow import Key, Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.base import LegsKinematics, legs_fk
from hubo_cli.estimation.keys import (
    CONTACT,
    GYRO_BIAS,
    IMU_REJECTED,
    OMEGA_TORSO,
    QUAT_WORLD_TORSO,
    SOLES_FLAT,
    T_TORSO_SOLES,
    WRENCHES,
)
from hubo_cli.estimation.observer import Observer
from hubo_cli.geometry import JIT, quat_wxyz_to_matrix
from hubo_cli.state import ANKLE_SENSORS, GRAVITY_M_S2, RobotState


@dataclass(frozen=True)
class AttitudeParams:
    """The attitude filter's parameters (SI units; every field a positive number).

    Attributes:
        gyro_noise_rad_s_rt_hz: the gyro's white noise density (angle random walk).
        gyro_bias_walk_rad_s2_rt_hz: how fast the gyro's bias may wander (its random walk).
        accel_noise_m_s2: the accelerometer's noise per reading (the vibration measured is
            added to it).
        still_accel_m_s2: the torso counts as still while the RMS of | |a| - g | stays below
            this ...
        still_gyro_rad_s: ... and the RMS of the bias-corrected rate below this.
        motion_time_s: the time constant of those RMS values' low-pass.
        motion_noise_gain: beyond still, the accelerometer's noise grows by this per unit of
            the motion's excess ratio.
        accel_reject_m_s2: beyond this | |a| - g | the accelerometer is not used.
        initial_tilt_rad: the first attitude's uncertainty (taken from the first reading).
        initial_gyro_bias_rad_s: the gyro bias's uncertainty at start (per axis).
        gyro_range_rad_s: the gyro's measuring range; a larger reading is rejected.
        accel_range_m_s2: the accelerometer's measuring range; a larger reading is rejected.
        legs_tilt_noise_rad: the legs' tilt measurement's noise (the encoders' noise through
            the leg and the sole's compliance on the floor).
        legs_min_fz_n: a sole measures the tilt while it presses at least this ...
        legs_cop_margin_m: ... with its centre of pressure at least this inside its outline.
        initial_floor_tilt_rad: the floor's tilt's uncertainty at start.
        still_learn_s: the accelerometer teaches the bias and the floor's tilt once the torso
            has been still this long.
        gyro_bias_max_rad_s: the largest bias a working gyro has (per axis): an estimate
            beyond it reports the gyro rejected (a gyro stuck at a rate is a fault, not a
            bias; the filter still learns it as one, which keeps the attitude: held within
            the bound, a gyro stuck at 0.5 rad/s turned the estimate over).
    """

    gyro_noise_rad_s_rt_hz: float
    gyro_bias_walk_rad_s2_rt_hz: float
    accel_noise_m_s2: float
    still_accel_m_s2: float
    still_gyro_rad_s: float
    motion_time_s: float
    motion_noise_gain: float
    accel_reject_m_s2: float
    initial_tilt_rad: float
    initial_gyro_bias_rad_s: float
    gyro_range_rad_s: float
    accel_range_m_s2: float
    legs_tilt_noise_rad: float
    legs_min_fz_n: float
    legs_cop_margin_m: float
    initial_floor_tilt_rad: float
    still_learn_s: float
    gyro_bias_max_rad_s: float

    def as_array(self) -> np.ndarray:
        """The fields in order, for the kernel."""
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=float)


def attitude_params(model) -> AttitudeParams:
    """The robot file's ``[estimation.attitude]`` table, checked (ConfigError names a missing
    or bad field)."""
    raw = model.raw_estimation.get("attitude", {})
    values = {}
    for f in fields(AttitudeParams):
        where = f"estimation.attitude.{f.name}"
        if f.name not in raw:
            raise ConfigError("missing key", path=str(model.source), field=where)
        value = raw[f.name]
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not (math.isfinite(value) and value > 0):
            raise ConfigError(f"must be a positive number, got {value!r}",
                              path=str(model.source), field=where)
        values[f.name] = float(value)
    return AttitudeParams(**values)


# indices into the kernel's parameter array (AttitudeParams' field order)
(_GYRO_NOISE, _BIAS_WALK, _ACCEL_NOISE, _STILL_ACCEL, _STILL_GYRO, _MOTION_TIME, _MOTION_GAIN,
 _ACCEL_REJECT, _TILT0, _BIAS0, _GYRO_RANGE, _ACCEL_RANGE, _LEGS_NOISE, _LEGS_FZ, _LEGS_MARGIN,
 _FLOOR0, _STILL_LEARN) = range(17)
GATE_D2 = 16.3  # a direction's residual beyond this Mahalanobis square (chi-square, 3 degrees
#                 of freedom, 0.1 %) counts with its noise grown to match it
NX = 8  # the error state: attitude (3), gyro bias (3), the floor's tilt about world x and y (2)
GYRO_REJECTED, ACCEL_REJECTED, ACCEL_IGNORED, RESULT_REJECTED = 1, 2, 4, 8


@nb.njit(**JIT)
def _quat_times_rotvec(q, vx, vy, vz, out):
    """out = q exp(v): q (w, x, y, z) turned by the rotation vector v in its own axes,
    normalised."""
    angle = math.sqrt(vx * vx + vy * vy + vz * vz)
    if angle < 1e-12:
        dw, s = 1.0, 0.5
    else:
        dw, s = math.cos(angle / 2), math.sin(angle / 2) / angle
    dx, dy, dz = vx * s, vy * s, vz * s
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0] = w * dw - x * dx - y * dy - z * dz
    out[1] = w * dx + x * dw + y * dz - z * dy
    out[2] = w * dy - x * dz + y * dw + z * dx
    out[3] = w * dz + x * dy - y * dx + z * dw
    n = math.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    for k in range(4):
        out[k] /= n


@nb.njit(**JIT)
def _mul(A, B, out):
    """out = A B (the sums in index order, as the products written out)."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            acc = 0.0
            for k in range(A.shape[1]):
                acc += A[i, k] * B[k, j]
            out[i, j] = acc


@nb.njit(**JIT)
def _mul_bt(A, B, out):
    """out = A B^T."""
    for i in range(A.shape[0]):
        for j in range(B.shape[0]):
            acc = 0.0
            for k in range(A.shape[1]):
                acc += A[i, k] * B[j, k]
            out[i, j] = acc


@nb.njit(**JIT)
def _correct(q, b, n, P, K, H, res, r):
    """Apply the correction K res to (q, b, n) and its covariance to P (Joseph form: right for
    any gain, the bias's rows zeroed too, and stays symmetric), in place."""
    m = H.shape[0]
    dx = np.empty(NX)  # K res
    IKH = np.empty((NX, NX))  # I - K H
    for i in range(NX):
        acc = 0.0
        for k in range(m):
            acc += K[i, k] * res[k]
        dx[i] = acc
        for j in range(NX):
            acc = 0.0
            for k in range(m):
                acc += K[i, k] * H[k, j]
            IKH[i, j] = (1.0 if i == j else 0.0) - acc
    A = np.empty((NX, NX))  # (I - K H) P
    _mul(IKH, P, A)
    for i in range(NX):  # P = A (I - K H)^T + r K K^T
        for j in range(NX):
            acc = kk = 0.0
            for k in range(NX):
                acc += A[i, k] * IKH[j, k]
            for k in range(m):
                kk += K[i, k] * K[j, k]
            P[i, j] = acc + r * kk
    q_prior = q.copy()
    _quat_times_rotvec(q_prior, dx[0], dx[1], dx[2], q)
    for i in range(3):
        b[i] += dx[i + 3]
    # the floor's normal turned by (dx6, dx7, 0) about the world's axes
    nx, ny, nz = n[0], n[1], n[2]
    n[0], n[1], n[2] = nx + dx[7] * nz, ny - dx[6] * nz, nz + dx[6] * ny - dx[7] * nx
    norm = math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
    for i in range(3):
        n[i] /= norm


@nb.njit(**JIT)
def _inverse3(S, out):
    """out = S^-1 of a 3 x 3 matrix (the adjugate over the determinant); NaN when singular
    (the period's result is then rejected)."""
    a, b, c = S[0, 0], S[0, 1], S[0, 2]
    d, e, f = S[1, 0], S[1, 1], S[1, 2]
    g, h, k = S[2, 0], S[2, 1], S[2, 2]
    c00, c01, c02 = e * k - f * h, f * g - d * k, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    if det == 0.0:
        for i in range(3):
            for j in range(3):
                out[i, j] = np.nan
        return
    out[0, 0], out[1, 0], out[2, 0] = c00 / det, c01 / det, c02 / det
    out[0, 1], out[1, 1], out[2, 1] = (c * h - b * k) / det, (a * k - c * g) / det, \
        (b * g - a * h) / det
    out[0, 2], out[1, 2], out[2, 2] = (b * f - c * e) / det, (c * d - a * f) / det, \
        (a * e - b * d) / det


@nb.njit(**JIT)
def _vertical_update(q, b, n, P, measured, predicted, r, floor, learn_bias, learn_floor):
    """Correct (q, b, n, P) in place by a measured direction in the torso axes: gravity's
    (``floor`` False: predicted R^T e_z) or the floor's normal (``floor``: predicted R^T n),
    each component's noise variance ``r``; the bias and the floor's tilt are corrected only
    with ``learn_bias`` and ``learn_floor``."""
    ux, uy, uz = predicted[0], predicted[1], predicted[2]
    H = np.zeros((3, NX))  # [[u]x, 0, -R^T [n]x (x, y columns)]
    H[0, 1], H[0, 2] = -uz, uy
    H[1, 0], H[1, 2] = uz, -ux
    H[2, 0], H[2, 1] = -uy, ux
    if floor:
        w, x, y, z = q[0], q[1], q[2], q[3]
        R = np.empty((3, 3))
        R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), \
            2 * (x * z + w * y)
        R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), \
            2 * (y * z - w * x)
        R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), \
            1 - 2 * (x * x + y * y)
        for i in range(3):  # columns x, y of [n]x: (0, nz, -ny), (-nz, 0, nx)
            H[i, 6] = -(R[1, i] * n[2] - R[2, i] * n[1])
            H[i, 7] = -(-R[0, i] * n[2] + R[2, i] * n[0])
    res = np.empty(3)
    for i in range(3):
        res[i] = measured[i] - predicted[i]
    PHt = np.empty((NX, 3))  # P H^T
    _mul_bt(P, H, PHt)
    S = np.empty((3, 3))  # H P H^T + r I
    _mul(H, PHt, S)
    for i in range(3):
        S[i, i] += r
    S_inv = np.empty((3, 3))
    _inverse3(S, S_inv)
    d2 = 0.0  # res^T S^-1 res
    for j in range(3):
        d2 += (res[0] * S_inv[0, j] + res[1] * S_inv[1, j] + res[2] * S_inv[2, j]) * res[j]
    if d2 > GATE_D2:  # more than the filter expects: weighed as if that noisy (a jolt's
        #               sideways acceleration hardly changes |a|; a sole that tips)
        extra = r * (d2 / GATE_D2 - 1.0)
        r += extra
        for i in range(3):
            S[i, i] += extra
        _inverse3(S, S_inv)
    K = np.empty((NX, 3))  # P H^T S^-1
    for i in range(NX):
        for j in range(3):
            K[i, j] = PHt[i, 0] * S_inv[0, j] + PHt[i, 1] * S_inv[1, j] + PHt[i, 2] * S_inv[2, j]
    if not learn_bias:
        K[3:6, :] = 0.0
    if not learn_floor:
        K[6:, :] = 0.0
    _correct(q, b, n, P, K, H, res, r)


@nb.njit("int64(float64[::1], float64[::1], float64[::1], float64[:, ::1], float64[::1], "
         "float64[::1], float64[:, ::1], float64, float64, float64[::1], float64[::1], "
         "float64[::1], float64[::1], float64[:, ::1], float64[::1], float64[::1])", **JIT)
def _filter_step(q, b, n, P, gyro, accel, legs, dt, gravity, params, q_out, b_out, n_out,
                 P_out, omega_out, motion):
    """One period of the filter from (q, b, n, P) into (q_out, b_out, n_out, P_out), the
    bias-corrected rate into ``omega_out``, the motion's low-passed mean squares (| |a| - g |,
    the bias-corrected rate, the accelerometer's vibration) and the accelerometer's low-passed
    mean (torso axes) and the time still updated in ``motion`` (7); ``legs`` (2 x 4): per
    sole, 1 and the floor's normal in the torso axes from the leg when it measures the tilt
    this period, else 0;
    returns the rejection bits (GYRO_REJECTED ...). With RESULT_REJECTED the outputs are the
    inputs unchanged."""
    code = 0
    omega_in = omega_out.copy()
    for i in range(4):
        q_out[i] = q[i]
    for i in range(3):
        b_out[i] = b[i]
        n_out[i] = n[i]
    for i in range(NX):
        for j in range(NX):
            P_out[i, j] = P[i, j]
    gyro_ok = True
    for i in range(3):
        if not (math.isfinite(gyro[i]) and abs(gyro[i]) <= params[_GYRO_RANGE]):
            gyro_ok = False
    alpha = min(1.0, dt / params[_MOTION_TIME])
    if gyro_ok and dt > 0.0:
        wx, wy, wz = gyro[0] - b[0], gyro[1] - b[1], gyro[2] - b[2]
        omega_out[0], omega_out[1], omega_out[2] = wx, wy, wz
        motion[1] += alpha * (wx * wx + wy * wy + wz * wz - motion[1])
        # the mean reading turned into this period's torso axes: m - (w dt) x m
        mx, my, mz = motion[3], motion[4], motion[5]
        motion[3] -= (wy * mz - wz * my) * dt
        motion[4] -= (wz * mx - wx * mz) * dt
        motion[5] -= (wx * my - wy * mx) * dt
        _quat_times_rotvec(q, wx * dt, wy * dt, wz * dt, q_out)
        # F = [[I - [w dt]x, -I dt], [0, I]]; P = F P F^T + Q
        F = np.eye(NX)
        F[0, 1], F[0, 2] = wz * dt, -wy * dt
        F[1, 0], F[1, 2] = -wz * dt, wx * dt
        F[2, 0], F[2, 1] = wy * dt, -wx * dt
        for i in range(3):
            F[i, i + 3] = -dt
        FP = np.empty((NX, NX))
        _mul(F, P, FP)
        _mul_bt(FP, F, P_out)  # F P F^T
        qa = params[_GYRO_NOISE] ** 2 * dt
        qb = params[_BIAS_WALK] ** 2 * dt
        for i in range(3):
            P_out[i, i] += qa
            P_out[i + 3, i + 3] += qb
    elif not gyro_ok:
        code |= GYRO_REJECTED
    accel_ok = True
    norm = departure = 0.0
    for i in range(3):
        if not (math.isfinite(accel[i]) and abs(accel[i]) <= params[_ACCEL_RANGE]):
            accel_ok = False
    if not accel_ok:
        code |= ACCEL_REJECTED
    elif dt > 0.0:
        norm = math.sqrt(accel[0] ** 2 + accel[1] ** 2 + accel[2] ** 2)
        departure = abs(norm - gravity)
        motion[0] += alpha * (departure * departure - motion[0])
        vibration2 = 0.0
        for i in range(3):
            d = accel[i] - motion[3 + i]
            vibration2 += d * d
            motion[3 + i] += alpha * d
        motion[2] += alpha * (vibration2 - motion[2])
    # a single reading (|a| - g, the rate, the reading's departure from the gravity expected)
    # several times still's is motion already (a walk sways the torso sideways from its first
    # period, |a| hardly changing: the low-passed RMS saw it only after the floor's tilt had
    # learnt 0.65 deg of it)
    rate = math.sqrt(omega_out[0] ** 2 + omega_out[1] ** 2 + omega_out[2] ** 2) if gyro_ok \
        else 0.0
    sway = 0.0  # the reading's departure from the gravity expected, m/s^2 (sideways too)
    if accel_ok:
        w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
        sway = math.sqrt((accel[0] - gravity * 2 * (x * z - w * y)) ** 2
                         + (accel[1] - gravity * 2 * (y * z + w * x)) ** 2
                         + (accel[2] - gravity * (w * w - x * x - y * y + z * z)) ** 2)
    moving = max(math.sqrt(motion[0]) / params[_STILL_ACCEL],
                 math.sqrt(motion[1]) / params[_STILL_GYRO],
                 departure / (3.0 * params[_STILL_ACCEL]), rate / (3.0 * params[_STILL_GYRO]),
                 sway / (2.0 * params[_STILL_ACCEL]))
    if dt > 0.0:
        motion[6] = motion[6] + dt if moving <= 1.0 else 0.0
    # a walk comes to rest swaying for a few tenths of a second after the RMS says still: the
    # floor's tilt learnt then was 0.7 deg off on a level floor
    settled = motion[6] >= params[_STILL_LEARN]
    legs_measure = legs[0, 0] == 1.0 or legs[1, 0] == 1.0
    if accel_ok and dt > 0.0 and (settled or not legs_measure):
        # not settled, the legs tell the tilt far better than an accelerometer that feels the
        # sway (the legs pulling back a tilt the sway pushed turned the bias by 0.7 deg/s)
        if departure > params[_ACCEL_REJECT]:
            code |= ACCEL_IGNORED
        else:
            factor = 1.0 + params[_MOTION_GAIN] * max(0.0, moving - 1.0)
            sigma2 = (params[_ACCEL_NOISE] ** 2 + motion[2] + departure * departure) \
                * factor * factor
            w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
            predicted, measured = np.empty(3), np.empty(3)
            predicted[0], predicted[1] = 2 * (x * z - w * y), 2 * (y * z + w * x)
            predicted[2] = w * w - x * x - y * y + z * z
            for i in range(3):
                measured[i] = accel[i] / norm
            # of the unit direction; the bias and the floor's tilt are learnt from it only once
            # settled (a walk's sway is 0.5-2.5 m/s^2 sideways for a fifth of a second and
            # more, 3-15 deg of gravity's direction: it moved the floor by tenths of a degree)
            _vertical_update(q_out, b_out, n_out, P_out, measured, predicted,
                             sigma2 / (gravity * gravity), False, settled, settled)
    # the legs: a loaded flat sole lies on the floor, its normal the floor's
    for k in range(2):
        if legs[k, 0] == 1.0:
            w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
            predicted = np.empty(3)  # R^T n
            predicted[0] = ((1 - 2 * (y * y + z * z)) * n_out[0] + 2 * (x * y + w * z) * n_out[1]
                            + 2 * (x * z - w * y) * n_out[2])
            predicted[1] = (2 * (x * y - w * z) * n_out[0] + (1 - 2 * (x * x + z * z)) * n_out[1]
                            + 2 * (y * z + w * x) * n_out[2])
            predicted[2] = (2 * (x * z + w * y) * n_out[0] + 2 * (y * z - w * x) * n_out[1]
                            + (1 - 2 * (x * x + y * y)) * n_out[2])
            # the floor's tilt is not corrected by it: the legs tell the torso's tilt from the
            # floor, only gravity the floor's
            _vertical_update(q_out, b_out, n_out, P_out, legs[k, 1:], predicted,
                             params[_LEGS_NOISE] ** 2, True, True, False)
    if gyro_ok and dt > 0.0 and moving <= 1.0:
        # still: the torso does not turn about the vertical, so the gyro's vertical component
        # is its bias's (a zero-rate update; gravity tells the bias across it), with the rate's
        # measured vibration as its noise, unless it departs by more than 3 sigma
        w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
        H = np.zeros((1, NX))
        H[0, 3], H[0, 4], H[0, 5] = 2 * (x * z - w * y), 2 * (y * z + w * x), \
            w * w - x * x - y * y + z * z
        res = np.empty(1)
        res[0] = (H[0, 3] * (gyro[0] - b_out[0]) + H[0, 4] * (gyro[1] - b_out[1])
                  + H[0, 5] * (gyro[2] - b_out[2]))
        r = max(motion[1] / 3.0, params[_GYRO_NOISE] ** 2 / (2.0 * dt))
        PHt = np.empty((NX, 1))  # P H^T
        _mul_bt(P_out, H, PHt)
        s = 0.0
        for k in range(NX):
            s += H[0, k] * PHt[k, 0]
        s += r
        if res[0] * res[0] <= 9.0 * s:
            for i in range(NX):
                PHt[i, 0] /= s
            _correct(q_out, b_out, n_out, P_out, PHt, H, res, r)
    if gyro_ok:
        for i in range(3):
            omega_out[i] = gyro[i] - b_out[i]
    finite = True
    for i in range(4):
        finite = finite and math.isfinite(q_out[i])
    for i in range(3):
        finite = finite and math.isfinite(b_out[i]) and math.isfinite(omega_out[i]) \
            and math.isfinite(n_out[i])
    for i in range(NX):
        for j in range(NX):
            finite = finite and math.isfinite(P_out[i, j])
    if not finite:
        code |= RESULT_REJECTED
        for i in range(3):
            omega_out[i] = omega_in[i]
        for i in range(4):
            q_out[i] = q[i]
        for i in range(3):
            b_out[i] = b[i]
            n_out[i] = n[i]
        for i in range(NX):
            for j in range(NX):
                P_out[i, j] = P[i, j]
    return code


@nb.njit(**JIT)
def _flat_soles(T_torso_soles, right_down, left_down, wrench_right, wrench_left, min_fz_n,
                inside, legs) -> bool:
    """Per sole, 1 and its normal in the torso axes into ``legs`` (2 x 4) when it lies flat:
    in contact, pressing more than ``min_fz_n`` with its centre of pressure
    (:func:`~hubo_cli.estimation.base.centre_of_pressure` of its ankle wrench) within
    ``inside`` (x_lo, x_hi, y_lo, y_hi); whether one does."""
    x_lo, x_hi, y_lo, y_hi = inside
    flat = False
    for k in range(2):
        down = right_down if k == 0 else left_down
        w = wrench_right if k == 0 else wrench_left
        if not down or w.shape[0] < 5:  # (never read beyond a short row)
            continue
        fz, mx, my = w[2], w[3], w[4]
        if not (fz > min_fz_n and math.isfinite(mx) and math.isfinite(my)):
            continue
        px, py = -my / fz, mx / fz
        if x_lo < px < x_hi and y_lo < py < y_hi:
            legs[k, 0] = 1.0
            for i in range(3):
                legs[k, 1 + i] = T_torso_soles[k, i, 2]
            flat = True
    return flat


@nb.njit(**JIT)
def _legs_tilt(q, index, base, offset, alpha, a, d, end, right_down, left_down, wrench_right,
               wrench_left, min_fz_n, inside, T_torso_soles, legs) -> int:
    """The legs' kinematics (:class:`~hubo_cli.estimation.base.LegsKinematics`' kernel) into
    ``T_torso_soles``, then :func:`_flat_soles` into ``legs``, in one call: 0 when a joint is
    not finite (nothing written), 2 when a sole lies flat, else 1."""
    if not legs_fk(q, index, base, offset, alpha, a, d, end, T_torso_soles):
        return 0
    return 2 if _flat_soles(T_torso_soles, right_down, left_down, wrench_right, wrench_left,
                            min_fz_n, inside, legs) else 1


def initial_attitude(state: RobotState) -> np.ndarray:
    """The first attitude (quaternion w, x, y, z): the tilt of the accelerometer's reading
    (the gravity it sees), the heading of the IMU's reported orientation (ZYX yaw); either
    from the reported orientation alone when the accelerometer's reading is not usable, and
    upright when neither is."""
    quat = _vector(state.imu_quat_wxyz, 4)
    yaw = 0.0
    if np.all(np.isfinite(quat)) and np.linalg.norm(quat) > 0.5:
        w, x, y, z = quat / np.linalg.norm(quat)
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        tilt_source = quat
    else:
        tilt_source = None
    accel = _vector(state.imu_accel_m_s2, 3)
    if np.all(np.isfinite(accel)) \
            and 0.5 * GRAVITY_M_S2 < np.linalg.norm(accel) < 1.5 * GRAVITY_M_S2:
        fx, fy, fz = accel
        roll, pitch = math.atan2(fy, fz), math.atan2(-fx, math.hypot(fy, fz))
    elif tilt_source is not None:
        w, x, y, z = tilt_source / np.linalg.norm(tilt_source)
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - x * z))))
    else:
        roll = pitch = 0.0
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


class AttitudeObserver(Observer):
    """The torso's attitude, the gyro's bias and the bias-corrected rate from the IMU.

    Args:
        params: the filter's parameters (:func:`attitude_params` of the robot file).
        period_s: the control period, used when the state's clock does not advance sensibly.
        model: the robot model, for the legs' tilt measurement (None: gyro and accelerometer
            alone).

    Attributes:
        rejected_periods: how many periods some reading was rejected since the reset.
        legs_periods: how many periods a sole measured the tilt since the reset.
    """

    name = "attitude"
    writes: tuple[Key, ...] = (QUAT_WORLD_TORSO, GYRO_BIAS, OMEGA_TORSO, IMU_REJECTED)
    MAX_DT_PERIODS = 20  # a longer gap in the state's clock counts as one period

    def __init__(self, params: AttitudeParams, period_s: float, model=None) -> None:
        if not (math.isfinite(period_s) and period_s > 0):
            raise ConfigError(f"the control period must be > 0 s, got {period_s!r}")
        self.params = params
        self.period_s = float(period_s)
        self._params = params.as_array()
        self._gravity = GRAVITY_M_S2
        self._q, self._q_next = np.array([1.0, 0.0, 0.0, 0.0]), np.empty(4)
        self._b, self._b_next = np.zeros(3), np.empty(3)
        self._n, self._n_next = np.array([0.0, 0.0, 1.0]), np.empty(3)
        self._P, self._P_next = np.zeros((NX, NX)), np.empty((NX, NX))
        self._omega = np.zeros(3)
        self._motion = np.zeros(7)
        self._t_s = 0.0
        self._legs = None if model is None else LegsKinematics(model)
        self.previous = () if model is None else (CONTACT, WRENCHES)
        self._T_torso_soles = np.tile(np.eye(4), (2, 1, 1))
        self._legs_tilt = np.zeros((2, 4))
        if model is not None:  # the outline less the margin, where the sole is flat
            # the legs, for the base too; which soles lie flat, for the IMU's running check
            self.writes = (*AttitudeObserver.writes, T_TORSO_SOLES, SOLES_FLAT)
            corners, margin = model.feet.sole_corners_m(), params.legs_cop_margin_m
            self._inside = (float(corners[:, 0].min()) + margin,
                            float(corners[:, 0].max()) - margin,
                            float(corners[:, 1].min()) + margin,
                            float(corners[:, 1].max()) - margin)
            self._no_wrench = np.zeros(6)
            _legs_tilt(*self._legs.kernel_arguments(np.zeros(len(model.joint_names))), False,
                       False, self._no_wrench, self._no_wrench, 1.0, self._inside,
                       np.empty((2, 4, 4)), np.zeros((2, 4)))  # compiled now
        self.rejected_periods = self.legs_periods = 0

    @classmethod
    def for_model(cls, model) -> AttitudeObserver:
        """The observer of ``model``'s robot file (its ``[estimation.attitude]`` table) at its
        control period, with the legs' tilt measurement."""
        return cls(attitude_params(model), model.control_period_s, model)

    def reset(self, state: RobotState, store: Store) -> None:
        p = self.params
        self._q = initial_attitude(state)
        self._b = np.zeros(3)
        self._n = self._initial_floor(self._legs_measurement(state, store, measure=False)[0])
        self._P = np.diag([p.initial_tilt_rad ** 2] * 3 + [p.initial_gyro_bias_rad_s ** 2] * 3
                          + [p.initial_floor_tilt_rad ** 2] * 2)
        gyro = _vector(state.imu_gyro_rad_s, 3)
        self._omega = gyro if np.all(np.abs(gyro) <= p.gyro_range_rad_s) else np.zeros(3)
        t_s = _seconds(state.time_s)
        self._t_s = t_s if math.isfinite(t_s) else 0.0
        # the vibration unknown yet: as much as still allows
        self._motion[:3] = 0.0, 0.0, p.still_accel_m_s2 ** 2
        accel = _vector(state.imu_accel_m_s2, 3)
        self._motion[3:6] = accel if np.all(np.isfinite(accel)) else (0.0, 0.0, GRAVITY_M_S2)
        self._motion[6] = p.still_learn_s  # settled: a robot is set down and settles first
        self.rejected_periods = self.legs_periods = 0
        self._write(store, 0)

    def update(self, state: RobotState, store: Store) -> None:
        t_s = _seconds(state.time_s)
        dt = t_s - self._t_s
        if not math.isfinite(dt) or dt < 0.0 or dt > self.MAX_DT_PERIODS * self.period_s:
            dt = self.period_s  # a clock that jumps: one period
        if math.isfinite(t_s):
            self._t_s = t_s
        gyro, accel = state.imu_gyro_rad_s, state.imu_accel_m_s2
        if type(gyro) is not np.ndarray or gyro.dtype != np.float64 or gyro.shape != (3,):
            gyro = _vector(gyro, 3)
        if type(accel) is not np.ndarray or accel.dtype != np.float64 or accel.shape != (3,):
            accel = _vector(accel, 3)
        _, legs = self._legs_measurement(state, store)
        code = _filter_step(self._q, self._b, self._n, self._P, gyro, accel, legs, dt,
                            self._gravity, self._params, self._q_next, self._b_next,
                            self._n_next, self._P_next, self._omega, self._motion)
        self._q, self._q_next = self._q_next, self._q
        self._b, self._b_next = self._b_next, self._b
        self._n, self._n_next = self._n_next, self._n
        self._P, self._P_next = self._P_next, self._P
        bound = self.params.gyro_bias_max_rad_s
        if not (abs(self._b[0]) <= bound and abs(self._b[1]) <= bound and abs(self._b[2]) <= bound):
            code |= GYRO_REJECTED  # a bias no working gyro has: flagged
        self._write(store, code)

    def _initial_floor(self, legs_solved: bool) -> np.ndarray:
        """The floor's normal in the world at start: both soles stand flat on it (as the
        floating base has them), so it is their mean normal through the legs, turned into the
        world by the first attitude (the accelerometer's tilt); level without the legs."""
        if not legs_solved:
            return np.array([0.0, 0.0, 1.0])
        normal = quat_wxyz_to_matrix(self._q) @ self._T_torso_soles[:, :3, 2].sum(axis=0)
        return normal / np.linalg.norm(normal)

    def _legs_measurement(self, state: RobotState, store: Store,
                          measure: bool = True) -> tuple[bool, np.ndarray]:
        """The legs' kinematics of this period's joints into ``T_TORSO_SOLES`` (a new array;
        None when they are not finite) and, with ``measure``, per sole (right, left): 1 and its
        normal in the torso axes when it lies flat on the floor, else 0 (which ones into
        ``SOLES_FLAT``). Flat: in contact and pressing ``legs_min_fz_n`` with its centre of
        pressure ``legs_cop_margin_m`` inside its outline, as the last period's estimate has
        them (the contact and the wrenches come after the attitude in the period: a sole on
        its edge would say the floor tilts).
        Returns whether the legs were solved (never without them) and the measurement."""
        legs = self._legs_tilt
        legs[0, 0] = legs[1, 0] = 0.0
        if self._legs is None:
            return False, legs
        contact, wrenches = (store.get(CONTACT), store.get(WRENCHES)) if measure else (None, None)
        if contact is None or wrenches is None:
            right = left = False
            wrench_right = wrench_left = self._no_wrench
        else:
            right, left = bool(contact[0]), bool(contact[1])
            wrench_right = np.asarray(wrenches[ANKLE_SENSORS[0]], dtype=float)
            wrench_left = np.asarray(wrenches[ANKLE_SENSORS[1]], dtype=float)
        T_torso_soles = np.empty((2, 4, 4))
        solved = _legs_tilt(*self._legs.kernel_arguments(state.q_rad), right, left, wrench_right,
                            wrench_left, self.params.legs_min_fz_n, self._inside,
                            T_torso_soles, legs)
        if solved:
            self._T_torso_soles = T_torso_soles
            if solved == 2:
                self.legs_periods += 1
        store[T_TORSO_SOLES] = T_torso_soles if solved else None
        store[SOLES_FLAT] = (bool(legs[0, 0]), bool(legs[1, 0]))
        return bool(solved), legs

    def _write(self, store: Store, code: int) -> None:
        if code & (GYRO_REJECTED | ACCEL_REJECTED | RESULT_REJECTED):
            self.rejected_periods += 1
        store[QUAT_WORLD_TORSO] = self._q.copy()
        store[GYRO_BIAS] = self._b.copy()
        store[OMEGA_TORSO] = self._omega.copy()
        store[IMU_REJECTED] = (bool(code & (GYRO_REJECTED | RESULT_REJECTED)),
                               bool(code & (ACCEL_REJECTED | RESULT_REJECTED)))

    @property
    def covariance(self) -> np.ndarray:
        """The error state's covariance (8 x 8: the attitude's rotation in rad, the bias in
        rad/s, the floor's tilt about the world's x and y in rad)."""
        return self._P.copy()

    @property
    def floor_normal(self) -> np.ndarray:
        """The floor's estimated normal in the world (unit vector): its tilt from level."""
        return self._n.copy()


def _vector(values, n: int) -> np.ndarray:
    """``n`` float64s from a reading of any shape or type: NaN where there are not ``n``
    numbers (the kernel then rejects it)."""
    try:
        out = np.array(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return np.full(n, np.nan)
    return out if out.shape == (n,) else np.full(n, np.nan)


def _seconds(value) -> float:
    """A state's time as a float; NaN when it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
