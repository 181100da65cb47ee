"""The centre of mass, its velocity, the capture point and the ZMP of the soles in contact.

* CoM: one pass down the tree a period (pinocchio's model of the URDF's masses, the drill URDF
  when the right hand holds the drill; the floating base at ``T_WORLD_TORSO``, the measured
  joints), pinocchio's ``centerOfMass`` arithmetic compiled (:func:`centre_of_mass`).
* Its velocity: finite-differenced and low-passed (first order at ``com_velocity_cutoff_hz``,
  4 Hz as hrpsys' Stabilizer); zero in the first period.
* Capture point: CP = x_G + v_G / omega, omega = sqrt(g / (z_G - z_ground)), z_ground the
  lowest corner of the soles in contact (``T_WORLD_SOLES``, ``CONTACT``); without contact the
  CoM's x, y. The arithmetic the capture-point monitor (:mod:`hubo_cli.control.capture_point`)
  ran on the simulator's truth before the estimate existed; it now judges these keys.
* ZMP: each sole in contact with a positive F_z gives its centre of pressure from its ankle
  sensor's compensated wrench in the sole frame (``WRENCHES``: p = (-m_y / f_z, m_x / f_z) on
  the sole, exact for a sensor at the sole whatever the shear), put in the world through its
  pose; the ZMP is their mean weighted by F_z. NaN without a loaded sole in contact.

Non-finite inputs keep the last estimate.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
    ZMP_WORLD,
)
from hubo_cli.estimation.observer import Observer
from hubo_cli.estimation.wrenches import joint_vector
from hubo_cli.geometry import matrix_to_quat_into
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import ANKLE_SENSORS, GRAVITY_M_S2, RobotState


@nb.njit(cache=True, nogil=True)
def configure(q, index, q_rad, T_world_torso) -> bool:
    """Pinocchio's floating-base ``q`` (in place): the joints ``q_rad`` at ``index``, the torso
    pose (x y z, then the quaternion x y z w). False (``q`` untouched) when not finite."""
    for i in range(q_rad.shape[0]):
        if not math.isfinite(q_rad[i]):
            return False
    for r in range(3):
        for c in range(4):
            if not math.isfinite(T_world_torso[r, c]):
                return False
    for i in range(q_rad.shape[0]):
        q[index[i]] = q_rad[i]
    quat = np.empty(4)
    matrix_to_quat_into(T_world_torso[:3, :3], quat)  # w x y z
    q[0], q[1], q[2] = T_world_torso[0, 3], T_world_torso[1, 3], T_world_torso[2, 3]
    q[3], q[4], q[5], q[6] = quat[1], quat[2], quat[3], quat[0]
    return True


# pinocchio's joint models the kernel knows: the free flyer (the root), revolute about x, y, z
_AXES = {"JointModelRX": 0, "JointModelRY": 1, "JointModelRZ": 2}


def tree_arrays(pmodel: pin.Model) -> tuple[np.ndarray, ...]:
    """A floating pinocchio model as :func:`centre_of_mass` takes it: per joint its parent,
    axis (-1 the free flyer), index in q, placement in its parent (rotation, translation),
    mass and centre of mass in its own frame."""
    axis = []
    for j, joint in enumerate(pmodel.joints[1:], start=1):
        name = joint.shortname()
        if j == 1 and name == "JointModelFreeFlyer":
            axis.append(-1)
        elif name in _AXES:
            axis.append(_AXES[name])
        else:
            raise ConfigError(f"the centre of mass kernel has no {name} (joint "
                              f"{pmodel.names[j]})", hint="the robot's joints are revolute "
                              "about x, y or z below a free flyer")
    joints = range(1, pmodel.njoints)
    return (np.array([0, *(pmodel.parents[j] for j in joints)], dtype=np.int64),
            np.array([0, *axis], dtype=np.int64),
            np.array([0, *(pmodel.joints[j].idx_q for j in joints)], dtype=np.int64),
            np.array([np.eye(3), *(pmodel.jointPlacements[j].rotation for j in joints)]),
            np.array([np.zeros(3), *(pmodel.jointPlacements[j].translation for j in joints)]),
            np.array([0.0, *(pmodel.inertias[j].mass for j in joints)]),
            np.array([np.zeros(3), *(pmodel.inertias[j].lever for j in joints)]))


@nb.njit(cache=True, nogil=True)
def centre_of_mass(q, parent, axis, q_at, R_place, p_place, mass, lever, out):
    """The centre of mass (``out``, 3) of pinocchio's configuration ``q`` (free flyer first:
    x y z, quaternion x y z w) for the model of :func:`tree_arrays`: pinocchio's
    ``centerOfMass`` (each body's mass moment carried down the tree, child to parent, through
    its joint's placement), compiled in one call."""
    n = parent.shape[0]
    moment = np.empty((n, 3))
    total = np.empty(n)
    total[0] = 0.0
    moment[0, :] = 0.0
    for i in range(1, n):
        total[i] = mass[i]
        for k in range(3):
            moment[i, k] = mass[i] * lever[i, k]
    R = np.empty((3, 3))  # the joint's rotation, then its placement's times it
    M = np.empty((3, 3))
    for i in range(n - 1, 0, -1):
        P, t = R_place[i], p_place[i]
        px, py, pz = t[0], t[1], t[2]
        if axis[i] < 0:  # the free flyer: Eigen's quaternion to rotation
            x, y, z, w = q[3], q[4], q[5], q[6]
            tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
            twx, twy, twz = tx * w, ty * w, tz * w
            txx, txy, txz = tx * x, ty * x, tz * x
            tyy, tyz, tzz = ty * y, tz * y, tz * z
            R[0, 0], R[0, 1], R[0, 2] = 1.0 - (tyy + tzz), txy - twz, txz + twy
            R[1, 0], R[1, 1], R[1, 2] = txy + twz, 1.0 - (txx + tzz), tyz - twx
            R[2, 0], R[2, 1], R[2, 2] = txz - twy, tyz + twx, 1.0 - (txx + tyy)
            px += P[0, 0] * q[0] + P[0, 1] * q[1] + P[0, 2] * q[2]
            py += P[1, 0] * q[0] + P[1, 1] * q[1] + P[1, 2] * q[2]
            pz += P[2, 0] * q[0] + P[2, 1] * q[1] + P[2, 2] * q[2]
        else:
            c, s = math.cos(q[q_at[i]]), math.sin(q[q_at[i]])
            a = axis[i]
            b, d = (a + 1) % 3, (a + 2) % 3  # the plane it turns
            R[:, :] = 0.0
            R[a, a] = 1.0
            R[b, b], R[b, d], R[d, b], R[d, d] = c, -s, s, c
        for r in range(3):
            for k in range(3):
                M[r, k] = P[r, 0] * R[0, k] + P[r, 1] * R[1, k] + P[r, 2] * R[2, k]
        j = parent[i]
        total[j] += total[i]
        mi = total[i]
        cx, cy, cz = moment[i, 0], moment[i, 1], moment[i, 2]
        moment[j, 0] += M[0, 0] * cx + M[0, 1] * cy + M[0, 2] * cz + mi * px
        moment[j, 1] += M[1, 0] * cx + M[1, 1] * cy + M[1, 2] * cz + mi * py
        moment[j, 2] += M[2, 0] * cx + M[2, 1] * cy + M[2, 2] * cz + mi * pz
    for k in range(3):
        out[k] = moment[0, k] / total[0]


@nb.njit(cache=True, nogil=True)
def support(com, prev_com, velocity, alpha, dt, first, soles, right_down, left_down, corners,
            wrench_right, wrench_left, gravity, min_fz, cp_out, zmp_out):
    """The CoM velocity low-passed in place (zero when ``first``; ``prev_com`` becomes
    ``com``), the capture point into ``cp_out`` (2,) and the ZMP into ``zmp_out`` (2,)."""
    for i in range(3):
        if first:
            velocity[i] = 0.0
        else:
            velocity[i] = velocity[i] + alpha * ((com[i] - prev_com[i]) / dt - velocity[i])
        prev_com[i] = com[i]
    down = (right_down, left_down)
    ground_z = np.inf
    for k in range(2):
        if down[k]:
            T = soles[k]
            for c in range(4):
                z = T[2, 0] * corners[c, 0] + T[2, 1] * corners[c, 1] + T[2, 3]
                ground_z = min(ground_z, z)
    if ground_z == np.inf:
        cp_out[0], cp_out[1] = com[0], com[1]
    else:
        omega = math.sqrt(gravity / max(com[2] - ground_z, 1e-3))
        cp_out[0] = com[0] + velocity[0] / omega
        cp_out[1] = com[1] + velocity[1] / omega
    total = 0.0
    zx = zy = 0.0
    for k in range(2):
        w = wrench_right if k == 0 else wrench_left
        fz = w[2]
        if not (down[k] and fz > min_fz):
            continue
        px, py = -w[4] / fz, w[3] / fz
        T = soles[k]
        zx += fz * (T[0, 0] * px + T[0, 1] * py + T[0, 3])
        zy += fz * (T[1, 0] * px + T[1, 1] * py + T[1, 3])
        total += fz
    if total > 0.0 and math.isfinite(zx) and math.isfinite(zy):
        zmp_out[0], zmp_out[1] = zx / total, zy / total
    else:
        zmp_out[0] = zmp_out[1] = np.nan


@nb.njit(cache=True, nogil=True)
def _period(q, q_index, q_rad, T_world_torso, parent, axis, q_at, R_place, p_place, mass, lever,
            com, prev_com, velocity, alpha, dt, first, soles, right_down, left_down, corners,
            wrench_right, wrench_left, gravity, min_fz, cp_out, zmp_out) -> bool:
    """:func:`configure`, :func:`centre_of_mass` into ``com`` and :func:`support` in one
    call; False (nothing written) when the joints or the torso pose are not finite."""
    if not configure(q, q_index, q_rad, T_world_torso):
        return False
    centre_of_mass(q, parent, axis, q_at, R_place, p_place, mass, lever, com)
    support(com, prev_com, velocity, alpha, dt, first, soles, right_down, left_down, corners,
            wrench_right, wrench_left, gravity, min_fz, cp_out, zmp_out)
    return True


class CentreOfMass(Observer):
    """Writes ``COM_WORLD``, ``COM_VELOCITY_WORLD``, ``CAPTURE_POINT_WORLD`` and ``ZMP_WORLD``
    (see the module docstring).

    Args:
        model: the robot model (URDF, feet, ``[estimation]``).
        period_s: the control period (s).
        drill: the right hand holds the drill (its mass counts).
    """

    name = "centre-of-mass"
    reads = (T_WORLD_TORSO, T_WORLD_SOLES, CONTACT, WRENCHES)
    writes = (COM_WORLD, COM_VELOCITY_WORLD, CAPTURE_POINT_WORLD, ZMP_WORLD)

    def __init__(self, model: RobotModel, period_s: float, drill: bool = False) -> None:
        self.robot = load_pin_robot(model, floating=True, urdf_path=model.urdf_path(drill))
        self._q_index = self.robot.q_index
        self._tree = tree_arrays(self.robot.model)
        self.dt_s = float(period_s)
        tau_s = 1.0 / (2.0 * math.pi * model.estimation.com_velocity_cutoff_hz)
        self.alpha = self.dt_s / (self.dt_s + tau_s)
        self._min_fz_n = model.estimation.zmp_sole_min_fz_n
        self._corners = np.ascontiguousarray(model.feet.sole_corners_m())
        self._joints = len(model.joint_names)
        self._q = self.robot.configuration(np.zeros(self._joints))
        self._first = True
        self._prev_com = np.zeros(3)
        self._com = np.zeros(3)
        self._velocity = np.zeros(3)
        self._cp = np.zeros(2)
        self._zmp = np.full(2, np.nan)
        _period(self._q.copy(), self._q_index, np.zeros(self._joints), np.eye(4),
                *self._tree, np.empty(3), np.zeros(3), np.zeros(3), self.alpha, self.dt_s, True,
                np.tile(np.eye(4), (2, 1, 1)), True, True, self._corners, np.zeros(6),
                np.zeros(6), GRAVITY_M_S2, self._min_fz_n, np.zeros(2), np.zeros(2))  # compiled

    def reset(self, state: RobotState, store: Store) -> None:
        self._first = True
        self._velocity = np.zeros(3)
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        T = np.asarray(store[T_WORLD_TORSO], dtype=float)
        com, velocity, cp, zmp = np.empty(3), self._velocity.copy(), np.empty(2), np.empty(2)
        contact = store[CONTACT]
        wrenches = store[WRENCHES]
        if _period(self._q, self._q_index, joint_vector(state.q_rad, self._joints), T,
                   *self._tree, com, self._prev_com, velocity, self.alpha, self.dt_s,
                   self._first, np.ascontiguousarray(store[T_WORLD_SOLES], dtype=float),
                   bool(contact[0]), bool(contact[1]), self._corners,
                   wrenches[ANKLE_SENSORS[0]], wrenches[ANKLE_SENSORS[1]], GRAVITY_M_S2,
                   self._min_fz_n, cp, zmp):
            self._first = False
            self._com, self._velocity, self._cp, self._zmp = com, velocity, cp, zmp
        store[COM_WORLD] = self._com
        store[COM_VELOCITY_WORLD] = self._velocity
        store[CAPTURE_POINT_WORLD] = self._cp
        store[ZMP_WORLD] = self._zmp
