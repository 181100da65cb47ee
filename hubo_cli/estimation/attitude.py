"""The torso's attitude from the IMU's gyro and accelerometer: a Kalman filter that estimates the
gyro's bias (the multi-layer paper's KalmanFilter component, as hrpsys-base runs it ahead of
its stabilizer).

The filter is a multiplicative (error-state) extended Kalman filter on the quaternion
q_world_torso and the gyro bias b (torso axes). Its error state is the small rotation dtheta
(torso axes: the true attitude is q exp(dtheta)) and the bias error db, with a 6 x 6 covariance.

- Predict, each period dt: the bias-corrected rate omega = gyro - b turns q by omega dt; the
  covariance grows by the gyro's white noise (angle random walk) and the bias's random walk.
- Correct: the accelerometer's direction a / |a| is gravity's direction in the torso axes,
  R^T e_z, while the torso does not accelerate. While it is still (the motion below), its
  noise is ``accel_noise_m_s2`` (the sensor's own) and the vibration measured (the RMS,
  low-passed over ``motion_time_s``, of the reading's departure from its own low-passed
  mean, that mean turned with the gyro), and the correction reaches the bias too: standing
  still is when the bias is learnt.
- Motion: the root mean square, low-passed over ``motion_time_s``, of the departure of |a|
  from g and of the bias-corrected rate; the torso is still while both stay below
  ``still_accel_m_s2`` and ``still_gyro_rad_s``. Beyond, by the factor m (the larger ratio),
  the accelerometer's noise grows by the factor ``1 + motion_noise_gain (m - 1)`` and the
  bias is not corrected: a walk's sway and a push accelerate the torso sideways for a second
  and more, which the accelerometer cannot tell from a tilt (its norm hardly changes, the
  rate does). A reading whose |a| departs from g by more than ``accel_reject_m_s2`` (an
  impact) is not used at all.
- Heading: gravity says nothing about it, nor about the bias about the vertical. While still,
  the torso does not turn about the vertical, so the gyro's vertical component is read as
  that bias (a zero-rate update, its noise the rate's measured vibration, unless it departs
  by more than 3 sigma). The yaw follows the bias-corrected gyro, from the heading the IMU
  reports in the first state.
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
from hubo_cli.estimation.keys import GYRO_BIAS, IMU_REJECTED, OMEGA_TORSO, QUAT_WORLD_TORSO
from hubo_cli.estimation.observer import Observer
from hubo_cli.geometry import JIT
from hubo_cli.state import GRAVITY_M_S2, RobotState


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
 _ACCEL_REJECT, _TILT0, _BIAS0, _GYRO_RANGE, _ACCEL_RANGE) = range(12)
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
def _correct(q, b, P, K, H, res, r):
    """Apply the correction K res to (q, b) and its covariance to P (Joseph form: right for
    any gain, the bias's rows zeroed too, and stays symmetric), in place."""
    dx = K @ res
    IKH = np.eye(6) - K @ H
    P[:, :] = IKH @ P @ IKH.T + r * (K @ K.T)
    q_prior = q.copy()
    _quat_times_rotvec(q_prior, dx[0], dx[1], dx[2], q)
    for i in range(3):
        b[i] += dx[i + 3]


@nb.njit("int64(float64[::1], float64[::1], float64[:, ::1], float64[::1], float64[::1], "
         "float64, float64, float64[::1], float64[::1], float64[::1], float64[:, ::1], "
         "float64[::1], float64[::1])", **JIT)
def _filter_step(q, b, P, gyro, accel, dt, gravity, params, q_out, b_out, P_out, omega_out,
                 motion):
    """One period of the filter from (q, b, P) into (q_out, b_out, P_out), the bias-corrected
    rate into ``omega_out``, the motion's low-passed mean squares (| |a| - g |, the
    bias-corrected rate, the accelerometer's vibration) and the accelerometer's low-passed
    mean (torso axes) updated in ``motion`` (6); returns the rejection bits (GYRO_REJECTED
    ...). With RESULT_REJECTED the outputs are the inputs unchanged."""
    code = 0
    omega_in = omega_out.copy()
    for i in range(4):
        q_out[i] = q[i]
    for i in range(3):
        b_out[i] = b[i]
    for i in range(6):
        for j in range(6):
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
        F = np.eye(6)
        F[0, 1], F[0, 2] = wz * dt, -wy * dt
        F[1, 0], F[1, 2] = -wz * dt, wx * dt
        F[2, 0], F[2, 1] = wy * dt, -wx * dt
        for i in range(3):
            F[i, i + 3] = -dt
        FP = F @ P
        P_new = FP @ F.T
        qa = params[_GYRO_NOISE] ** 2 * dt
        qb = params[_BIAS_WALK] ** 2 * dt
        for i in range(3):
            P_new[i, i] += qa
            P_new[i + 3, i + 3] += qb
        P_out[:, :] = P_new
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
    moving = max(math.sqrt(motion[0]) / params[_STILL_ACCEL],
                 math.sqrt(motion[1]) / params[_STILL_GYRO])
    if accel_ok and dt > 0.0:
        if departure > params[_ACCEL_REJECT]:
            code |= ACCEL_IGNORED
        else:
            factor = 1.0 + params[_MOTION_GAIN] * max(0.0, moving - 1.0)
            sigma2 = (params[_ACCEL_NOISE] ** 2 + motion[2]) * factor * factor
            r = sigma2 / (gravity * gravity)  # of the unit direction
            w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
            zx, zy, zz = 2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z
            res = np.empty(3)
            res[0], res[1], res[2] = accel[0] / norm - zx, accel[1] / norm - zy, \
                accel[2] / norm - zz
            H = np.zeros((3, 6))  # [[z]x, 0]
            H[0, 1], H[0, 2] = -zz, zy
            H[1, 0], H[1, 2] = zz, -zx
            H[2, 0], H[2, 1] = -zy, zx
            PHt = P_out @ H.T
            S = H @ PHt
            for i in range(3):
                S[i, i] += r
            K = PHt @ np.linalg.inv(S)
            if moving > 1.0:  # the bias is learnt only while still
                K[3:, :] = 0.0
            _correct(q_out, b_out, P_out, K, H, res, r)
    if gyro_ok and dt > 0.0 and moving <= 1.0:
        # still: the torso does not turn about the vertical, so the gyro's vertical component
        # is its bias's (a zero-rate update; gravity tells the bias across it), with the rate's
        # measured vibration as its noise, unless it departs by more than 3 sigma
        w, x, y, z = q_out[0], q_out[1], q_out[2], q_out[3]
        H = np.zeros((1, 6))
        H[0, 3], H[0, 4], H[0, 5] = 2 * (x * z - w * y), 2 * (y * z + w * x), \
            w * w - x * x - y * y + z * z
        res = np.empty(1)
        res[0] = (H[0, 3] * (gyro[0] - b_out[0]) + H[0, 4] * (gyro[1] - b_out[1])
                  + H[0, 5] * (gyro[2] - b_out[2]))
        r = max(motion[1] / 3.0, params[_GYRO_NOISE] ** 2 / (2.0 * dt))
        PHt = P_out @ H.T
        s = (H @ PHt)[0, 0] + r
        if res[0] * res[0] <= 9.0 * s:
            _correct(q_out, b_out, P_out, PHt / s, H, res, r)
    if gyro_ok:
        for i in range(3):
            omega_out[i] = gyro[i] - b_out[i]
    finite = True
    for i in range(4):
        finite = finite and math.isfinite(q_out[i])
    for i in range(3):
        finite = finite and math.isfinite(b_out[i]) and math.isfinite(omega_out[i])
    for i in range(6):
        for j in range(6):
            finite = finite and math.isfinite(P_out[i, j])
    if not finite:
        code |= RESULT_REJECTED
        for i in range(3):
            omega_out[i] = omega_in[i]
        for i in range(4):
            q_out[i] = q[i]
        for i in range(3):
            b_out[i] = b[i]
        for i in range(6):
            for j in range(6):
                P_out[i, j] = P[i, j]
    return code


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

    Attributes:
        rejected_periods: how many periods some reading was rejected since the reset.
    """

    name = "attitude"
    writes: tuple[Key, ...] = (QUAT_WORLD_TORSO, GYRO_BIAS, OMEGA_TORSO, IMU_REJECTED)
    MAX_DT_PERIODS = 20  # a longer gap in the state's clock counts as one period

    def __init__(self, params: AttitudeParams, period_s: float) -> None:
        if not (math.isfinite(period_s) and period_s > 0):
            raise ConfigError(f"the control period must be > 0 s, got {period_s!r}")
        self.params = params
        self.period_s = float(period_s)
        self._params = params.as_array()
        self._gravity = GRAVITY_M_S2
        self._q, self._q_next = np.array([1.0, 0.0, 0.0, 0.0]), np.empty(4)
        self._b, self._b_next = np.zeros(3), np.empty(3)
        self._P, self._P_next = np.zeros((6, 6)), np.empty((6, 6))
        self._omega = np.zeros(3)
        self._motion = np.zeros(6)
        self._t_s = 0.0
        self.rejected_periods = 0

    @classmethod
    def for_model(cls, model) -> AttitudeObserver:
        """The observer of ``model``'s robot file (its ``[estimation.attitude]`` table) at its
        control period."""
        return cls(attitude_params(model), model.control_period_s)

    def reset(self, state: RobotState, store: Store) -> None:
        p = self.params
        self._q = initial_attitude(state)
        self._b = np.zeros(3)
        self._P = np.diag([p.initial_tilt_rad ** 2] * 3 + [p.initial_gyro_bias_rad_s ** 2] * 3)
        gyro = _vector(state.imu_gyro_rad_s, 3)
        self._omega = gyro if np.all(np.abs(gyro) <= p.gyro_range_rad_s) else np.zeros(3)
        t_s = _seconds(state.time_s)
        self._t_s = t_s if math.isfinite(t_s) else 0.0
        # the vibration unknown yet: as much as still allows
        self._motion[:3] = 0.0, 0.0, p.still_accel_m_s2 ** 2
        accel = _vector(state.imu_accel_m_s2, 3)
        self._motion[3:] = accel if np.all(np.isfinite(accel)) else (0.0, 0.0, GRAVITY_M_S2)
        self.rejected_periods = 0
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
        code = _filter_step(self._q, self._b, self._P, gyro, accel, dt, self._gravity,
                            self._params, self._q_next, self._b_next, self._P_next, self._omega,
                            self._motion)
        self._q, self._q_next = self._q_next, self._q
        self._b, self._b_next = self._b_next, self._b
        self._P, self._P_next = self._P_next, self._P
        self._write(store, code)

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
        """The error state's covariance (6 x 6: the attitude's rotation in rad, the bias in
        rad/s)."""
        return self._P.copy()


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
