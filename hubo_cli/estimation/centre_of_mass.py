"""The centre of mass, its velocity, the capture point and the ZMP of the soles in contact.

* CoM: one pinocchio pass a period (the URDF's masses, the drill URDF when the right hand
  holds the drill; the floating base at ``T_WORLD_TORSO``, the measured joints).
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
        self.data = self.robot.model.createData()
        self._pin_model, self._q_index = self.robot.model, self.robot.q_index
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
        configure(self._q.copy(), self.robot.q_index, np.zeros(self._joints), np.eye(4))
        support(np.zeros(3), np.zeros(3), np.zeros(3), self.alpha, self.dt_s, True,
                np.tile(np.eye(4), (2, 1, 1)), True, True, self._corners, np.zeros(6),
                np.zeros(6), GRAVITY_M_S2, self._min_fz_n, np.zeros(2), np.zeros(2))

    def reset(self, state: RobotState, store: Store) -> None:
        self._first = True
        self._velocity = np.zeros(3)
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        T = np.asarray(store[T_WORLD_TORSO], dtype=float)
        if configure(self._q, self._q_index, joint_vector(state.q_rad, self._joints), T):
            com = pin.centerOfMass(self._pin_model, self.data, self._q, False)
            velocity, cp, zmp = self._velocity.copy(), np.empty(2), np.empty(2)
            contact = store[CONTACT]
            wrenches = store[WRENCHES]
            right, left = wrenches[ANKLE_SENSORS[0]], wrenches[ANKLE_SENSORS[1]]
            support(com, self._prev_com, velocity, self.alpha, self.dt_s, self._first,
                    np.ascontiguousarray(store[T_WORLD_SOLES], dtype=float), bool(contact[0]),
                    bool(contact[1]), self._corners, right, left, GRAVITY_M_S2, self._min_fz_n,
                    cp, zmp)
            self._first = False
            self._com, self._velocity, self._cp, self._zmp = com.copy(), velocity, cp, zmp
        store[COM_WORLD] = self._com
        store[COM_VELOCITY_WORLD] = self._velocity
        store[CAPTURE_POINT_WORLD] = self._cp
        store[ZMP_WORLD] = self._zmp
