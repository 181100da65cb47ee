"""hubo-ach's channel structures, exactly as ``include/hubo.h`` declares them (packed).

The layout is that of hubo/hubo-ach's develop branch of late 2013 (``hubo-ach`` 0.1.20131101):
``struct hubo_ref`` is 462 bytes and ``struct hubo_state`` 3,898 bytes. hubo-daemon checks every
``hubo-ref`` frame against ``sizeof(hubo_ref_t)`` and exits on a mismatch, so these structures
are the contract with the robot; a test checks every size and offset against the header.

Conversions to this project's units and frames live here too: the reference in hubo-ach joint
order (:func:`encode_ref`, :func:`decode_ref`), hubo-daemon's reference filter
(:func:`reference_filter`) and the state's IMU tilt angles to a quaternion
(:func:`quat_from_tilt`) and to the specific force they imply (:func:`accel_from_tilt`).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

from hubo_cli.state import GRAVITY_M_S2

JOINT_COUNT = 42          # HUBO_JOINT_COUNT
JMC_COUNT = 0x36          # HUBO_JMC_COUNT (motor controller boards)
IMU_COUNT = 3             # HUBO_IMU_COUNT
FT_COUNT = 4
IMU_TILT_R, IMU_TILT_L, IMU_BODY = 0, 1, 2   # hubo_imu_index_t: foot tilt sensors, the IMU
FT_R_HAND, FT_L_HAND, FT_R_FOOT, FT_L_FOOT = 0, 1, 2, 3  # hubo_sensor_index_t
MODE_REF_FILTER, MODE_REF, MODE_COMPLIANT, MODE_ENC_FILTER = 0, 1, 2, 3  # hubo_mode_type_t
CHAN_REF = "hubo-ref"     # HUBO_CHAN_REF_NAME
CHAN_STATE = "hubo-state"  # HUBO_CHAN_STATE_NAME
LOOP_PERIOD_S = 0.005     # HUBO_LOOP_PERIOD
REF_FILTER_LENGTH = 40    # HUBO_REF_FILTER_LENGTH
STARTUP_SEND_REF_DELAY_S = 0.8  # HUBO_STARTUP_SEND_REF_DELAY


class HuboImu(ctypes.Structure):
    """``hubo_imu_t``: tilt angles a_x, a_y, a_z (rad) and rates w_x, w_y, w_z (rad/s)."""

    _pack_ = 1
    _fields_ = [(n, ctypes.c_double) for n in ("a_x", "a_y", "a_z", "w_x", "w_y", "w_z")]


class HuboFt(ctypes.Structure):
    """``hubo_ft_t``: moments m_x, m_y (N m) and force f_z (N)."""

    _pack_ = 1
    _fields_ = [(n, ctypes.c_double) for n in ("m_x", "m_y", "f_z")]


class HuboJointState(ctypes.Structure):
    """``hubo_joint_state_t``: ref, comply, pos (rad), cur (A), vel (rad/s), duty, heat, tmp,
    active, zeroed."""

    _pack_ = 1
    _fields_ = ([("ref", ctypes.c_double), ("comply", ctypes.c_uint8)]
                + [(n, ctypes.c_double) for n in ("pos", "cur", "vel", "duty", "heat", "tmp")]
                + [("active", ctypes.c_uint8), ("zeroed", ctypes.c_uint8)])


class HuboJointStatus(ctypes.Structure):
    """``hubo_joint_status_t``: 17 one-byte flags (STATx0, STATx1, STATx2)."""

    _pack_ = 1
    _fields_ = [(n, ctypes.c_uint8) for n in (
        "driverOn", "ctrlOn", "mode", "limitSwitch", "homeFlag",
        "jam", "pwmSaturated", "bigError", "encError", "driverFault", "motorFail0", "motorFail1",
        "posMinError", "posMaxError", "velError", "accError", "tempError")]


class HuboJmcState(ctypes.Structure):
    """``hubo_jmc_state_t``: board temperature (deg C)."""

    _pack_ = 1
    _fields_ = [("temp", ctypes.c_double)]


class HuboPower(ctypes.Structure):
    """``hubo_power_t``: the back power board's voltage, current and power."""

    _pack_ = 1
    _fields_ = [(n, ctypes.c_double) for n in ("voltage", "current", "power")]


class HuboState(ctypes.Structure):
    """``hubo_state_t`` (3,898 bytes): what hubo-daemon publishes on ``hubo-state``."""

    _pack_ = 1
    _fields_ = [("imu", HuboImu * IMU_COUNT), ("ft", HuboFt * FT_COUNT),
                ("joint", HuboJointState * JOINT_COUNT),
                ("status", HuboJointStatus * JOINT_COUNT), ("driver", HuboJmcState * JMC_COUNT),
                ("power", HuboPower), ("time", ctypes.c_double), ("refWait", ctypes.c_int16)]


class HuboRef(ctypes.Structure):
    """``hubo_ref_t`` (462 bytes): what a client writes on ``hubo-ref``."""

    _pack_ = 1
    _fields_ = [("ref", ctypes.c_double * JOINT_COUNT), ("mode", ctypes.c_int16 * JOINT_COUNT),
                ("comply", ctypes.c_int8 * JOINT_COUNT)]


REF_SIZE = ctypes.sizeof(HuboRef)
STATE_SIZE = ctypes.sizeof(HuboState)
# numpy's views of the same packed layouts (derived from the ctypes structures, one source)
REF_DTYPE = np.dtype(HuboRef)
STATE_DTYPE = np.dtype(HuboState)
IMU_FIELDS = ("a_x", "a_y", "a_z", "w_x", "w_y", "w_z")
FT_FIELDS = ("m_x", "m_y", "f_z")


@dataclass
class RefFrame:
    """One ``hubo_ref`` frame in numpy form (hubo-ach joint order, rad)."""

    ref_rad: np.ndarray
    mode: np.ndarray
    comply: np.ndarray


def encode_ref(ref_rad, mode, comply) -> bytes:
    """Pack one ``hubo_ref`` frame (462 bytes) from 42 references (rad), modes and comply."""
    frame = np.zeros((), dtype=REF_DTYPE)
    frame["ref"] = ref_rad
    frame["mode"] = mode
    frame["comply"] = comply
    return frame.tobytes()


def decode_ref(data: bytes) -> RefFrame:
    """Unpack one ``hubo_ref`` frame; refuses any size but ``sizeof(hubo_ref_t)``."""
    if len(data) != REF_SIZE:
        raise ValueError(f"a hubo_ref frame is {REF_SIZE} bytes, got {len(data)}")
    frame = np.frombuffer(data, dtype=REF_DTYPE)[0]
    return RefFrame(frame["ref"].copy(), frame["mode"].copy(), frame["comply"].copy())


@dataclass
class StateFrame:
    """The part of ``hubo_state`` a controller uses, in SI units and hubo-ach joint order.

    Attributes:
        time_s: the daemon's clock (``CLOCK_MONOTONIC`` seconds on the robot's computer).
        imu_tilt_rad: the body IMU's tilt angles a_x, a_y, a_z (rad).
        imu_rate_rad_s: its rates w_x, w_y, w_z (rad/s).
        ft_mx_my_fz: 4 x 3: m_x, m_y (N m), f_z (N) for R hand, L hand, R foot, L foot.
        pos_rad, vel_rad_s: the 42 joints' measured positions and velocities.
        ref_wait: the daemon is not applying references yet (``refWait``).
        ref_rad: the 42 references the motors are given (``joint[].ref``: after the reference
            filter); None: the positions (a daemon publishing them; not decoded).
        tmp_c: the 42 motors' temperatures (``joint[].tmp``, degrees C); None: zero (a daemon
            publishing them).
        cur_a: the 42 motors' currents (``joint[].cur``, A); None: zero.
        heat_j: the heat each motor has generated (``joint[].heat``, J: hubo.h's "NOT
            TEMPERATURE"); None: zero (not decoded).
        status: ``status[]`` flags by name (each 42 values, 0 or 1), e.g. ``jam``,
            ``tempError``; None or a flag not named: zero (not decoded).
    """

    time_s: float
    imu_tilt_rad: np.ndarray
    imu_rate_rad_s: np.ndarray
    ft_mx_my_fz: np.ndarray
    pos_rad: np.ndarray
    vel_rad_s: np.ndarray
    ref_wait: bool = False
    ref_rad: np.ndarray | None = None
    tmp_c: np.ndarray | None = None
    cur_a: np.ndarray | None = None
    heat_j: np.ndarray | None = None
    status: dict[str, np.ndarray] | None = None


def _doubles(data: bytes, offset: int, count: int, stride: int = 8) -> np.ndarray:
    """``count`` little-endian doubles from ``offset``, ``stride`` bytes apart (a copy)."""
    return np.ndarray((count,), "<f8", data, offset, (stride,)).copy()


_IMU_OFFSET = HuboState.imu.offset + IMU_BODY * ctypes.sizeof(HuboImu)
_JOINT_STRIDE = ctypes.sizeof(HuboJointState)


def decode_state(data: bytes) -> StateFrame:
    """Unpack one ``hubo_state`` frame; refuses any size but ``sizeof(hubo_state_t)``."""
    if len(data) != STATE_SIZE:
        raise ValueError(f"a hubo_state frame is {STATE_SIZE} bytes, got {len(data)}")
    imu = _doubles(data, _IMU_OFFSET, 6)
    joint = HuboState.joint.offset
    ref_wait = int.from_bytes(data[HuboState.refWait.offset:][:2], "little", signed=True)
    return StateFrame(float(_doubles(data, HuboState.time.offset, 1)[0]), imu[:3], imu[3:],
                      _doubles(data, HuboState.ft.offset, 3 * FT_COUNT).reshape(FT_COUNT, 3),
                      _doubles(data, joint + HuboJointState.pos.offset, JOINT_COUNT,
                               _JOINT_STRIDE),
                      _doubles(data, joint + HuboJointState.vel.offset, JOINT_COUNT,
                               _JOINT_STRIDE),
                      bool(ref_wait),
                      tmp_c=_doubles(data, joint + HuboJointState.tmp.offset, JOINT_COUNT,
                                     _JOINT_STRIDE),
                      cur_a=_doubles(data, joint + HuboJointState.cur.offset, JOINT_COUNT,
                                     _JOINT_STRIDE))


def encode_state(frame: StateFrame) -> bytes:
    """Pack a ``hubo_state`` frame (3,898 bytes) from a :class:`StateFrame`; every field this
    project does not model is zero, except ``active`` and ``zeroed`` (1 for every joint)."""
    s = np.zeros((), dtype=STATE_DTYPE)
    imu = np.concatenate([frame.imu_tilt_rad, frame.imu_rate_rad_s])
    for f, value in zip(IMU_FIELDS, imu, strict=True):
        s["imu"][f][IMU_BODY] = value
    for k, f in enumerate(FT_FIELDS):
        s["ft"][f] = np.asarray(frame.ft_mx_my_fz)[:, k]
    s["joint"]["pos"] = frame.pos_rad
    s["joint"]["ref"] = frame.pos_rad if frame.ref_rad is None else frame.ref_rad
    s["joint"]["vel"] = frame.vel_rad_s
    for name, values in (("tmp", frame.tmp_c), ("cur", frame.cur_a), ("heat", frame.heat_j)):
        if values is not None:
            s["joint"][name] = values
    for name, values in (frame.status or {}).items():
        s["status"][name] = values
    s["joint"]["active"] = 1
    s["joint"]["zeroed"] = 1
    s["time"] = frame.time_s
    s["refWait"] = int(frame.ref_wait)
    return s.tobytes()


def reference_filter(filtered_rad: np.ndarray, ref_rad: np.ndarray, mode: np.ndarray,
                     length: int = REF_FILTER_LENGTH) -> np.ndarray:
    """One period of hubo-daemon's ``refFilterMode`` for modes 0 and 1 (rad).

    Mode 0: f <- (f (L - 1) + r) / L; mode 1: f <- r. Other modes (compliant, encoder filter)
    need the motors and keep f.
    """
    smoothed = (filtered_rad * (length - 1.0) + ref_rad) / length
    out = np.where(mode == MODE_REF_FILTER, smoothed, filtered_rad)
    return np.where(mode == MODE_REF, ref_rad, out)


def tilt_from_quat(q_wxyz) -> np.ndarray:
    """The IMU's tilt angles a_x, a_y, a_z (rad) of a torso orientation (unit quaternion w, x,
    y, z): the inverse of :func:`quat_from_tilt` (R = Rz(a_z) Ry(a_y) Rx(a_x))."""
    w, x, y, z = (float(v) for v in q_wxyz)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - x * z), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.array([roll, pitch, yaw])


def quat_from_tilt(tilt_rad) -> np.ndarray:
    """Unit quaternion w, x, y, z of the torso from the IMU's tilt angles (rad).

    The rotation is Rz(a_z) Ry(a_y) Rx(a_x), whose roll and pitch are a_x and a_y again.
    hubo-ach's IMU reports a_x (roll about x) and a_y (pitch about y) from its inclinometers; its
    a_z is no heading (gravity does not show one, and the body IMU has no other reference): the
    hardware driver passes a_z = 0 (:func:`body_imu_quat`).
    """
    roll, pitch, yaw = (0.5 * float(v) for v in tilt_rad)
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def body_imu_tilt(q_wxyz) -> np.ndarray:
    """The body IMU's a_x, a_y, a_z (rad) as the simulated daemon publishes them for a torso
    orientation: its roll and pitch (:func:`tilt_from_quat`), a_z 0 (no heading)."""
    tilt = tilt_from_quat(q_wxyz)
    tilt[2] = 0.0
    return tilt


def body_imu_quat(tilt_rad) -> np.ndarray:
    """The torso attitude the hardware driver reports from the body IMU's a_x, a_y (rad): its
    tilt, yaw 0; a_z is not read (it is no heading, see :func:`quat_from_tilt`)."""
    return quat_from_tilt((float(tilt_rad[0]), float(tilt_rad[1]), 0.0))


def accel_from_tilt(tilt_rad) -> np.ndarray:
    """The accelerometer's specific force (m/s^2, IMU axes) that the IMU's tilt angles a_x
    (roll), a_y (pitch) imply at rest: gravity, [0, 0, g] in the world, carried into the IMU
    frame of :func:`quat_from_tilt` (R = Rz(a_z) Ry(a_y) Rx(a_x)), R^T [0, 0, g] =
    g [-sin a_y, sin a_x cos a_y, cos a_x cos a_y]; a_z does not enter it.

    Assumed: hubo-ach's a_x, a_y are the roll and pitch of that rotation (a positive a_x tips
    the torso's y axis up, i.e. the robot leans to its right; a positive a_y tips the x axis
    down, forward), as hubo-daemon's inclinometer reading is converted to radians; the body
    IMU reports no raw accelerations, so the dynamic part is lost (it reads as rest).
    """
    roll, pitch = float(tilt_rad[0]), float(tilt_rad[1])
    cp = np.cos(pitch)
    return GRAVITY_M_S2 * np.array([-np.sin(pitch), np.sin(roll) * cp, np.cos(roll) * cp])
