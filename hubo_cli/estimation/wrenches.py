"""RemoveForceOffset (hrpsys RemoveForceSensorLinkOffset): the force-torque sensors' readings
with the weight of what hangs beyond each sensor removed, and at the wrists its inertia too.

A sensor reads what the body beyond it and the environment load onto it
(:class:`~hubo_cli.state.RobotState` ``ft``): beyond a wrist sensor the hand and, when held,
the tool; beyond an ankle sensor the foot. Each body is taken whole as the robot's URDF has it
on the limb's last joint (the drill URDF when the right hand holds the drill): its mass m and
centre of mass c in the sensor's frame, from pinocchio's model once. Each period the gravity
direction in the sensor's frame comes from the estimated attitude (``QUAT_WORLD_TORSO``) and the
limb's forward kinematics of the measured joints,

    g_S = R_torso_S^T R_world_torso^T (0, 0, -g),   f_off = m g_S,   m_off = c x f_off,

and the compensated wrench is the reading minus (f_off, m_off), with the components the sensor
does not measure (``FT_MEASURED``: Hubo's read f_z, m_x, m_y) set to 0. A still hand or a
foot in the air then reads zero, a standing foot the floor's reaction.

At the wrists the hand's (and the held tool's) inertia is removed as well: the sensor carries
m (g - a) at the body's centre of mass, and a hard landing shakes the whole upper body (a
150 N backward capture step's touchdown: a one-period 2.2 N m on a free hand, over the wrist
stop's 1.21 N m). The body's specific force there, in the torso axes, is the torso IMU's
(the accelerometer's specific force s_imu at the torso frame's origin) carried to the centre
of mass p (torso frame, from the arm's measured joints) as a rigid body,

    s_c = s_imu + alpha x p + omega x (omega x p),   f_off = -m R_torso_S^T s_c,

omega the estimate's bias-free rate (``OMEGA_TORSO``) and alpha its difference over the
period, clipped to ANGULAR_ACCEL_MAX_RAD_S2 (the lunge's landing: up to 200 rad/s^2; without
alpha its landing still trips the stop, with 1.76 N m). The arm's own motion relative to the
torso is left out (the encoders' noise, differenced twice, would swamp it; the arms'
trajectories move a hand at most 0.4 m/s^2: about 0.4 N with the drill), so a shove of a few
milliseconds that makes the arm yield on its joints and whip after the torso is not removed
and can read worse than the raw sensor; so is the bodies' rotational inertia (I alpha; the
simulator's sensors leave it out too). alpha is 0 unless this period's and the last
period's gyro were both used.

The inertia is removed only where it is plausible, so that a bad IMU can neither stop a
still hand nor hide a real load for long:

- Near rest, the weight alone (exactly the weight path): while the accelerometer reads
  within ``accel_reject_m_s2`` (the attitude's impact threshold, 2 m/s^2) of the attitude's
  gravity; a gyro glitch on a still robot then changes nothing. So does a rejected or
  non-finite accelerometer.
- Bounded: the inertial moment removed (beyond the weight's) is at most INERTIA_LARGE_NM
  (2.0 N m) for at most INERTIA_BURST_PERIODS (12) periods in a row, then at most
  INERTIA_SMALL_NM (0.2 N m) until it falls under that again; the force removed is at
  most INERTIA_FORCE_N (15 N). Measured in the 150 N backward lunge (push, step, landing,
  catch; the torso departs from rest for 2 s; AVX-512 / portable paths): at most 1.79 /
  1.92 N m and 8.6 / 8.8 N removed, over 0.2 N m for at most 8 / 6 periods in a row (a
  landing that needed more than the cap would read the excess, not the whole).
- Worst case, whatever a finite IMU reads: a real wrist moment is misread (hidden or
  added) by at most 2.0 N m for at most 12 periods (60 ms) in a row, and by at most 0.2 N m
  otherwise (a period whose inertial moment is 0.2 N m or less ends the run). An overload
  above the 1.21 N m stop's limit plus 0.2 N m (1.41 N m) is therefore stopped within 13
  periods (65 ms). The other way, a glitch while the accelerometer departs from rest (the
  torso really moving, or the accelerometer itself bad) can add up to 2.0 N m and stop a
  free hand; a gyro glitch alone on a still robot cannot.
- No inertia on a driver whose accelerometer is not measured (``Driver.accel_measured``):
  hubo-ach's body IMU reports tilt, and the hardware driver rebuilds the accelerometer
  from it (it reads rest), so the wrists there have their weight alone.

The ankles keep the weight alone: their readings feed the contact, the ZMP and the
attitude's legs, and a foot's inertia is not what those are tuned on.

A sensor whose reading, joints or the attitude are not finite (or not six numbers) keeps its
last compensated wrench (zero before the first good one).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import IMU_REJECTED, OMEGA_TORSO, QUAT_WORLD_TORSO, WRENCHES
from hubo_cli.estimation.observer import Observer
from hubo_cli.geometry import quat_to_matrix_into
from hubo_cli.kinematics.dh import chain_fk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import all_finite
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import FT_MEASURED, FT_SENSORS, GRAVITY_M_S2, RobotState, T_frame_sensor

# the inertia removed at a wrist, bounded (module docstring; measured in the 150 N backward lunge)
INERTIA_SMALL_NM = 0.2  # at most this moment (N m) for as long as the torso accelerates
INERTIA_LARGE_NM = 2.0  # ... and at most this for INERTIA_BURST_PERIODS in a row (an impact)
INERTIA_BURST_PERIODS = 12  # 60 ms at 200 Hz
INERTIA_FORCE_N = 15.0  # the force removed, at most (N)
ANGULAR_ACCEL_MAX_RAD_S2 = 300.0  # the torso's angular acceleration, clipped to this

# per sensor in FT_SENSORS: its limb and the URDF frame whose origin is the sensor's
SENSOR_LIMBS = {"right-wrist": ("right-arm", "right_hand"), "left-wrist": ("left-arm", "left_hand"),
                "right-ankle": ("right-leg", "right_sole"), "left-ankle": ("left-leg", "left_sole")}


def sensor_loads(model: RobotModel, drill: bool) -> tuple[np.ndarray, np.ndarray]:
    """Mass (kg, per sensor in FT_SENSORS) and centre of mass (m, in the sensor's frame) of
    the body beyond each sensor: the URDF's bodies on the limb's last joint (pinocchio merges
    the fixed links, the drill's too, into it)."""
    robot = load_pin_robot(model, urdf_path=model.urdf_path(drill))
    pmodel = robot.model
    masses, coms = np.zeros(len(FT_SENSORS)), np.zeros((len(FT_SENSORS), 3))
    for k, sensor in enumerate(FT_SENSORS):
        limb, frame = SENSOR_LIMBS[sensor]
        joint_id = pmodel.getJointId(model.limbs[limb].joints[-1])
        placement = pmodel.frames[robot.frame_id(frame)]
        if placement.parentJoint != joint_id:
            raise ConfigError(f"the URDF's {frame} frame is not on {limb}'s last joint",
                              path=str(robot.urdf_path),
                              hint="regenerate it with tools/make_urdf.py")
        T_joint_sensor = placement.placement.homogeneous @ T_frame_sensor(sensor)
        inertia = pmodel.inertias[joint_id]
        masses[k] = inertia.mass
        lever = np.append(inertia.lever, 1.0)
        coms[k] = (np.linalg.inv(T_joint_sensor) @ lever)[:3]
    return masses, coms


def sensor_chains(model: RobotModel) -> tuple[np.ndarray, ...]:
    """The four sensors' limb chains stacked for :func:`compensate`: joint index (4 x 6) into
    the joint vector, then base, offset, alpha, a, d and end (the DH frame 6 to the sensor)."""
    rows = []
    for sensor in FT_SENSORS:
        limb_name, _ = SENSOR_LIMBS[sensor]
        limb = Limb(model, limb_name, "hand")
        base, offset, alpha, a, d, end = limb.fk_chain
        sl = model.limb_slice(limb_name)
        rows.append((np.arange(sl.start, sl.stop), base, offset, alpha, a, d,
                     end @ T_frame_sensor(sensor)))
    index = np.array([r[0] for r in rows], dtype=np.int64)
    return (index, *(np.ascontiguousarray([r[k] for r in rows], dtype=float)
                     for k in range(1, 7)))


def joint_vector(q_rad, joints: int) -> np.ndarray:
    """The measured joints as ``joints`` floats; NaN (hold the estimate) when the driver's
    vector is not that."""
    try:
        q = np.asarray(q_rad, dtype=float)
    except (TypeError, ValueError):
        q = None
    if q is None or q.shape != (joints,):
        return np.full(joints, np.nan)
    return q


@nb.njit(cache=True, nogil=True)
def _com_point(qk, k, base, offset, alpha, a, d, end, com, T):
    """The centre of mass of the body beyond sensor ``k`` in the torso frame (m), for its
    limb's joints ``qk``; ``T`` gets the sensor's pose (T_torso_S)."""
    chain_fk(qk, base[k], offset[k], alpha[k], a[k], d[k], end[k], T)
    c = com[k]
    return (T[0, 0] * c[0] + T[0, 1] * c[1] + T[0, 2] * c[2] + T[0, 3],
            T[1, 0] * c[0] + T[1, 1] * c[1] + T[1, 2] * c[2] + T[1, 3],
            T[2, 0] * c[0] + T[2, 1] * c[1] + T[2, 2] * c[2] + T[2, 3])


@nb.njit(cache=True, nogil=True)
def _offset_at(T, p, k, mass, com, s_torso, scale, omega, domega, out):
    """The load on sensor ``k`` (``out``, 6) of the body beyond it, its pose ``T`` and centre
    of mass ``p`` given (:func:`_com_point`): -m times the centre of mass's specific force,
    that of the torso frame's origin (torso axes; ``scale`` times ``s_torso``: at rest -g
    times world z in the torso axes) carried to it with the torso's rate ``omega`` and angular
    acceleration ``domega`` (torso axes; 0 and 0: the weight alone, -g in ``scale``)."""
    c = com[k]
    p0, p1, p2 = p
    # the centre of mass p (torso frame) turning with the torso: + domega x p + w x (w x p)
    wp0 = omega[1] * p2 - omega[2] * p1
    wp1 = omega[2] * p0 - omega[0] * p2
    wp2 = omega[0] * p1 - omega[1] * p0
    s0 = s_torso[0] + (domega[1] * p2 - domega[2] * p1 + omega[1] * wp2 - omega[2] * wp1)
    s1 = s_torso[1] + (domega[2] * p0 - domega[0] * p2 + omega[2] * wp0 - omega[0] * wp2)
    s2 = s_torso[2] + (domega[0] * p1 - domega[1] * p0 + omega[0] * wp1 - omega[1] * wp0)
    for i in range(3):  # in the sensor's axes: R_torso_S^T s
        z = s0 * T[0, i] + s1 * T[1, i] + s2 * T[2, i]
        out[i] = scale * z * mass[k]
    out[3] = c[1] * out[2] - c[2] * out[1]
    out[4] = c[2] * out[0] - c[0] * out[2]
    out[5] = c[0] * out[1] - c[1] * out[0]


@nb.njit(cache=True, nogil=True)
def compensate(q, quat_wxyz, accel, omega, domega, inertial, raw, index, base, offset, alpha,
               a, d, end, mass, com, gravity, measured, gate, last, out):
    """The compensated wrenches (``out``, n x 6) of the readings ``raw`` (n x 6) for the joints
    ``q`` (rad) and the torso attitude ``quat_wxyz``; a sensor with a non-finite input keeps
    its row of ``last``. ``measured``: 1 for the components the sensors read, 0 elsewhere.
    The sensors with ``inertial`` 1 have the body's inertia removed too, from the
    accelerometer's specific force ``accel`` and the torso's rate ``omega`` and angular
    acceleration ``domega`` (torso axes), bounded by ``gate`` (2 x 6): row 0 the bounds
    (the accelerometer's rest band, m/s^2; INERTIA_SMALL_NM, INERTIA_LARGE_NM,
    INERTIA_FORCE_N, INERTIA_BURST_PERIODS, ANGULAR_ACCEL_MAX_RAD_S2), row 1 per sensor the
    periods in a row its unbounded inertial moment exceeded the small bound (updated here).
    A non-finite ``accel``, or one within the rest band of the attitude's gravity: their
    weight alone."""
    R = np.empty((3, 3))
    attitude_ok = all_finite(quat_wxyz) and (quat_wxyz[0] ** 2 + quat_wxyz[1] ** 2
                                          + quat_wxyz[2] ** 2 + quat_wxyz[3] ** 2) > 1e-12
    up = np.zeros(3)
    if attitude_ok:
        quat_to_matrix_into(quat_wxyz, R)
        for i in range(3):  # world z in the torso axes: R^T (0, 0, 1)
            up[i] = R[2, i]
    moving = all_finite(accel) and all_finite(omega) and all_finite(domega) and math.sqrt(
        (accel[0] - gravity * up[0]) ** 2 + (accel[1] - gravity * up[1]) ** 2
        + (accel[2] - gravity * up[2]) ** 2) > gate[0, 0]
    small_nm, large_nm, force_n, burst_max = gate[0, 1], gate[0, 2], gate[0, 3], gate[0, 4]
    clipped = np.empty(3)
    for i in range(3):  # the angular acceleration within its plausible bound
        clipped[i] = min(max(domega[i], -gate[0, 5]), gate[0, 5])
    still = np.zeros(3)
    T = np.empty((4, 4))
    qk = np.empty(6)
    load = np.empty(6)
    extra = np.empty(6)
    for k in range(raw.shape[0]):
        for j in range(6):
            qk[j] = q[index[k, j]]
        if not (attitude_ok and all_finite(qk) and all_finite(raw[k])):
            for j in range(6):
                out[k, j] = last[k, j]
            continue
        p = _com_point(qk, k, base, offset, alpha, a, d, end, com, T)
        _offset_at(T, p, k, mass, com, up, -gravity, still, still, load)
        if not (moving and inertial[k]):
            gate[1, k] = 0.0
        else:  # the inertia: what the motion adds to the weight, bounded
            _offset_at(T, p, k, mass, com, accel, -1.0, omega, clipped, extra)
            for j in range(6):
                extra[j] -= load[j]
            moment = math.sqrt(extra[3] ** 2 + extra[4] ** 2 + extra[5] ** 2)
            force = math.sqrt(extra[0] ** 2 + extra[1] ** 2 + extra[2] ** 2)
            gate[1, k] = gate[1, k] + 1.0 if moment > small_nm else 0.0
            cap_nm = large_nm if gate[1, k] <= burst_max else small_nm
            scale_f = min(1.0, force_n / max(force, 1e-300))
            scale_m = min(1.0, cap_nm / max(moment, 1e-300))
            for j in range(3):
                load[j] += scale_f * extra[j]
                load[j + 3] += scale_m * extra[j + 3]
        for j in range(6):
            out[k, j] = (raw[k, j] - load[j]) * measured[j]


@nb.njit(cache=True, nogil=True)
def hanging_readings(q, quat_wxyz, index, base, offset, alpha, a, d, end, mass, com, gravity,
                     measured, out):
    """What the sensors read with nothing but the weight beyond them (``out``, n x 6): a
    perfectly modelled robot touching nothing (the ideal driver's wrists and its feet in the
    air; :mod:`hubo_cli.drivers.floor` adds the floor's push under the soles down)."""
    R = np.empty((3, 3))
    quat_to_matrix_into(quat_wxyz, R)
    up = np.empty(3)
    for i in range(3):
        up[i] = R[2, i]
    still = np.zeros(3)
    T = np.empty((4, 4))
    qk = np.empty(6)
    load = np.empty(6)
    for k in range(out.shape[0]):
        for j in range(6):
            qk[j] = q[index[k, j]]
        p = _com_point(qk, k, base, offset, alpha, a, d, end, com, T)
        _offset_at(T, p, k, mass, com, up, -gravity, still, still, load)
        for j in range(6):
            out[k, j] = load[j] * measured[j]


def measured_mask() -> np.ndarray:
    """1 for the wrench components the sensors measure (``FT_MEASURED``), 0 elsewhere."""
    mask = np.zeros(6)
    mask[list(FT_MEASURED)] = 1.0
    return mask


class RemoveForceOffset(Observer):
    """Writes ``WRENCHES``: the sensors' readings with the weight beyond them removed, at the
    wrists the inertia too (see the module docstring).

    Args:
        model: the robot model (URDF, limbs).
        accel_rest_m_s2: the accelerometer within this of gravity (as the attitude has it)
            reads a robot at rest: the hands' weight alone is removed (the attitude filter's
            ``accel_reject_m_s2``).
        drill: the right hand holds the drill (its mass is beyond the right wrist sensor).
        period_s: the control period (s; default the model's), over which the rate is
            differenced.
        drill_kg: the drill's mass (kg) when it differs from the robot file's (a task's
            ``tool_mass_kg``); the right wrist's load is the hand and a drill of this mass.
    """

    name = "remove-force-offset"
    reads = (QUAT_WORLD_TORSO, OMEGA_TORSO, IMU_REJECTED)
    writes = (WRENCHES,)

    def __init__(self, model: RobotModel, accel_rest_m_s2: float, drill: bool = False,
                 period_s: float | None = None, accel_measured: bool = True,
                 drill_kg: float | None = None) -> None:
        self.mass_kg, self.com_sensor_m = sensor_loads(model, drill)
        if drill and drill_kg is not None and drill_kg != model.drill.mass_kg:
            self._weigh_drill(model, float(drill_kg))
        self._chains = sensor_chains(model)
        self._measured = measured_mask()
        # the wrists: the hand's (and the tool's) inertia removed too, where the driver
        # measures the accelerometer (hubo-ach's is rebuilt from the tilt: weight alone)
        self._inertial = np.array([accel_measured and SENSOR_LIMBS[s][0].endswith("-arm")
                                   for s in FT_SENSORS])
        self._gate = np.zeros((2, 6))
        self._gate[0] = (accel_rest_m_s2, INERTIA_SMALL_NM,
                         INERTIA_LARGE_NM, INERTIA_FORCE_N, INERTIA_BURST_PERIODS,
                         ANGULAR_ACCEL_MAX_RAD_S2)
        self._dt_s = model.control_period_s if period_s is None else float(period_s)
        self._nan = np.full(6, np.nan)
        self._nan3 = np.full(3, np.nan)
        self._zero3 = np.zeros(3)
        self._omega_last: np.ndarray | None = None  # the last period's rate, if it was read
        self._last = np.zeros((len(FT_SENSORS), 6))
        self._raw = np.zeros((len(FT_SENSORS), 6))
        self._joints = len(model.joint_names)
        self._update(np.zeros(self._joints), np.array([1.0, 0.0, 0.0, 0.0]), self._nan3,
                     self._zero3, self._zero3)

    def _weigh_drill(self, model: RobotModel, drill_kg: float) -> None:
        """The right wrist's load with the drill weighing ``drill_kg``: the drill's share of
        the drill URDF's load (the load less the hand's) scaled to that mass, its centre where
        it was."""
        k = FT_SENSORS.index("right-wrist")
        hand_kg, hand_com = sensor_loads(model, False)
        drill_com = ((self.mass_kg[k] * self.com_sensor_m[k] - hand_kg[k] * hand_com[k])
                     / (self.mass_kg[k] - hand_kg[k]))
        self.mass_kg[k] = hand_kg[k] + drill_kg
        self.com_sensor_m[k] = (hand_kg[k] * hand_com[k] + drill_kg * drill_com) / self.mass_kg[k]

    def reset(self, state: RobotState, store: Store) -> None:
        self._last = np.zeros((len(FT_SENSORS), 6))
        self._omega_last = None
        self._gate[1] = 0.0
        self.update(state, store)

    def _update(self, q_rad: np.ndarray, quat_wxyz: np.ndarray, accel: np.ndarray,
                omega: np.ndarray, domega: np.ndarray) -> np.ndarray:
        out = np.empty((len(FT_SENSORS), 6))
        compensate(q_rad, quat_wxyz, accel, omega, domega, self._inertial, self._raw,
                   *self._chains, self.mass_kg, self.com_sensor_m, GRAVITY_M_S2,
                   self._measured, self._gate, self._last, out)
        self._last = out
        return out

    def _motion(self, state: RobotState, store: Store) -> tuple[np.ndarray, ...]:
        """The torso's motion as sensed: the accelerometer's specific force (NaN when
        rejected), the rate and its difference over the period (0 unless this and the last
        period's gyro were read), torso axes."""
        gyro_rejected, accel_rejected = store[IMU_REJECTED]
        accel = self._nan3
        if not accel_rejected:
            try:
                accel = np.asarray(state.imu_accel_m_s2, dtype=float).reshape(3)
            except (TypeError, ValueError, AttributeError):
                accel = self._nan3
        omega = np.asarray(store[OMEGA_TORSO], dtype=float)
        last, self._omega_last = self._omega_last, None if gyro_rejected else omega
        domega = self._zero3 if last is None or gyro_rejected else (omega - last) / self._dt_s
        return accel, omega, domega

    def update(self, state: RobotState, store: Store) -> None:
        raw = self._raw
        for k, sensor in enumerate(FT_SENSORS):
            try:
                reading = state.ft.get(sensor, self._nan)
                if type(reading) is np.ndarray and reading.dtype == np.float64 \
                        and reading.shape == (6,):
                    raw[k] = reading  # the drivers' own: taken as it is
                else:
                    raw[k] = np.asarray(reading, dtype=float).reshape(6)
            except (TypeError, ValueError, AttributeError):  # not six numbers: it holds
                raw[k] = self._nan
        out = self._update(joint_vector(state.q_rad, self._joints),
                           np.asarray(store[QUAT_WORLD_TORSO], dtype=float),
                           *self._motion(state, store))
        store[WRENCHES] = dict(zip(FT_SENSORS, out, strict=True))
