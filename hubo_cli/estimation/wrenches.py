"""RemoveForceOffset (hrpsys RemoveForceSensorLinkOffset): the force-torque sensors' readings
with the weight of what hangs beyond each sensor removed.

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
foot in the air then reads zero, a standing foot the floor's reaction. The bodies' own
accelerations are not removed (hrpsys does not either): a hand moving at the arms' limits
(0.4 m/s^2) with the drill reads up to about 0.4 N of it.

A sensor whose reading, joints or the attitude are not finite (or not six numbers) keeps its
last compensated wrench (zero before the first good one).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import QUAT_WORLD_TORSO, WRENCHES
from hubo_cli.estimation.observer import Observer
from hubo_cli.geometry import quat_to_matrix_into
from hubo_cli.kinematics.dh import chain_fk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import FT_MEASURED, FT_SENSORS, GRAVITY_M_S2, RobotState, T_frame_sensor

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
        base, _, offset, alpha, a, d, end, _ = limb.chain
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
def all_finite(x) -> bool:
    for v in x.flat:
        if not math.isfinite(v):
            return False
    return True


@nb.njit(cache=True, nogil=True)
def _offset(qk, R, k, base, offset, alpha, a, d, end, mass, com, gravity, T, out):
    """The weight's wrench on sensor ``k`` (``out``, 6) for its limb's joints ``qk`` and the
    torso rotation ``R``."""
    chain_fk(qk, base[k], offset[k], alpha[k], a[k], d[k], end[k], T)
    # gravity in the sensor's axes: -g times world z seen in them (R_world_sensor's row 2)
    for i in range(3):
        z = R[2, 0] * T[0, i] + R[2, 1] * T[1, i] + R[2, 2] * T[2, i]
        out[i] = -gravity * z * mass[k]
    c = com[k]
    out[3] = c[1] * out[2] - c[2] * out[1]
    out[4] = c[2] * out[0] - c[0] * out[2]
    out[5] = c[0] * out[1] - c[1] * out[0]


@nb.njit(cache=True, nogil=True)
def compensate(q, quat_wxyz, raw, index, base, offset, alpha, a, d, end, mass, com, gravity,
               measured, last, out):
    """The compensated wrenches (``out``, n x 6) of the readings ``raw`` (n x 6) for the joints
    ``q`` (rad) and the torso attitude ``quat_wxyz``; a sensor with a non-finite input keeps
    its row of ``last``. ``measured``: 1 for the components the sensors read, 0 elsewhere."""
    R = np.empty((3, 3))
    attitude_ok = all_finite(quat_wxyz) and (quat_wxyz[0] ** 2 + quat_wxyz[1] ** 2
                                          + quat_wxyz[2] ** 2 + quat_wxyz[3] ** 2) > 1e-12
    if attitude_ok:
        quat_to_matrix_into(quat_wxyz, R)
    T = np.empty((4, 4))
    qk = np.empty(6)
    weight = np.empty(6)
    for k in range(raw.shape[0]):
        for j in range(6):
            qk[j] = q[index[k, j]]
        if not (attitude_ok and all_finite(qk) and all_finite(raw[k])):
            for j in range(6):
                out[k, j] = last[k, j]
            continue
        _offset(qk, R, k, base, offset, alpha, a, d, end, mass, com, gravity, T, weight)
        for j in range(6):
            out[k, j] = (raw[k, j] - weight[j]) * measured[j]


@nb.njit(cache=True, nogil=True)
def hanging_readings(q, quat_wxyz, index, base, offset, alpha, a, d, end, mass, com, gravity,
                     measured, out):
    """What the sensors read with nothing but the weight beyond them (``out``, n x 6): a
    perfectly modelled robot touching nothing (the ideal driver's sensors)."""
    R = np.empty((3, 3))
    quat_to_matrix_into(quat_wxyz, R)
    T = np.empty((4, 4))
    qk = np.empty(6)
    weight = np.empty(6)
    for k in range(out.shape[0]):
        for j in range(6):
            qk[j] = q[index[k, j]]
        _offset(qk, R, k, base, offset, alpha, a, d, end, mass, com, gravity, T, weight)
        for j in range(6):
            out[k, j] = weight[j] * measured[j]


def measured_mask() -> np.ndarray:
    """1 for the wrench components the sensors measure (``FT_MEASURED``), 0 elsewhere."""
    mask = np.zeros(6)
    mask[list(FT_MEASURED)] = 1.0
    return mask


class RemoveForceOffset(Observer):
    """Writes ``WRENCHES``: the sensors' readings with the weight beyond them removed (see the
    module docstring).

    Args:
        model: the robot model (URDF, limbs).
        drill: the right hand holds the drill (its mass is beyond the right wrist sensor).
    """

    name = "remove-force-offset"
    reads = (QUAT_WORLD_TORSO,)
    writes = (WRENCHES,)

    def __init__(self, model: RobotModel, drill: bool = False) -> None:
        self.mass_kg, self.com_sensor_m = sensor_loads(model, drill)
        self._chains = sensor_chains(model)
        self._measured = measured_mask()
        self._nan = np.full(6, np.nan)
        self._last = np.zeros((len(FT_SENSORS), 6))
        self._raw = np.zeros((len(FT_SENSORS), 6))
        self._joints = len(model.joint_names)
        self._update(np.zeros(self._joints), np.array([1.0, 0.0, 0.0, 0.0]))

    def reset(self, state: RobotState, store: Store) -> None:
        self._last = np.zeros((len(FT_SENSORS), 6))
        self.update(state, store)

    def _update(self, q_rad: np.ndarray, quat_wxyz: np.ndarray) -> np.ndarray:
        out = np.empty((len(FT_SENSORS), 6))
        compensate(q_rad, quat_wxyz, self._raw, *self._chains, self.mass_kg, self.com_sensor_m,
                   GRAVITY_M_S2, self._measured, self._last, out)
        self._last = out
        return out

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
                           np.asarray(store[QUAT_WORLD_TORSO], dtype=float))
        store[WRENCHES] = dict(zip(FT_SENSORS, out, strict=True))
