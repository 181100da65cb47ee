"""The robot standing still on both soles, as the running IMU check (:mod:`.imu_tilt`) judges
it: windows of :data:`STILL_STATES` fresh states, each state's gyro under
:data:`STILL_GYRO_RAD_S`, both soles loaded (:data:`~.legs.SOLE_LOADED_WEIGHTS` of the robot's
weight on the raw F_z) and lying flat (``SOLES_FLAT``: the attitude's legs measurement, its own
load ``legs_min_fz_n`` on the compensated F_z and the centre of pressure inside the outline),
the torso on the legs moved less than :data:`STILL_TORSO_M` and turned less than
:data:`STILL_TURN_RAD` over the window: its mean acceleration is then gravity's to 0.02 m/s^2.
The soles' weight check (:mod:`.soles_weight`) judges a window of the whole robot still
(``whole_body``: every joint slower than :data:`STILL_JOINT_RAD_S` too, arms moving shift the
soles' load by up to 0.17 of the weight) however its soles are loaded (an ankle sensor
reading low unloads its sole)."""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import SOLES_FLAT, T_TORSO_SOLES
from hubo_cli.estimation.sensor_checks.legs import angle_rad, both_soles_loaded
from hubo_cli.state import ANKLE_SENSORS, RobotState

STILL_STATES = 50  # 0.25 s
STILL_GYRO_RAD_S = 0.05
STILL_TORSO_M = 0.002
STILL_TURN_RAD = math.radians(0.2)
STILL_JOINT_RAD_S = 0.05  # the whole body still: every joint slower than this


class StillWindow:
    """Fresh states standing still on both loaded flat soles, summed until STILL_STATES: the
    IMU's vertical (its accelerometer's direction) and the legs' (the soles' normals through the
    joints' kinematics), both in the torso's axes, and where the torso stood on the legs.

    Args:
        whole_body: a still state needs every joint slower than STILL_JOINT_RAD_S, the soles
            however loaded (False: both soles loaded and flat, the joints as they may).

    Attributes:
        verticals: the window's mean verticals (unit; the IMU's, the legs'), set at the end of
            a still window.
        soles_fz_n: the window's mean F_z of the ankle sensors (raw, N; right, left), set with
            ``verticals``.
    """

    def __init__(self, whole_body: bool = False) -> None:
        self.whole_body = whole_body
        self.soles_fz_n = (0.0, 0.0)
        self._restart()

    def _restart(self) -> None:
        self.n = 0
        self.sums = [0.0] * 8  # the IMU's vertical (3), the legs' (3), the soles' F_z (2)
        self.verticals = (np.zeros(3), np.zeros(3))
        self._first = None  # the first state's T_torso_soles

    def update(self, state: RobotState, store: Store, weight_n: float) -> float | None:
        """Add a fresh state if still (else the window starts again); at the window's end, the
        angle between the mean verticals (deg), or None (not yet, not still, or the torso moved
        on the legs over the window: it starts again). (Scalar arithmetic: it runs every fresh
        state.)"""
        T_torso_soles = store.get(T_TORSO_SOLES)
        ax, ay, az = state.imu_accel_m_s2.tolist()
        gx, gy, gz = state.imu_gyro_rad_s.tolist()
        accel_n = math.sqrt(ax * ax + ay * ay + az * az)
        still = (T_torso_soles is not None and accel_n > 0.0 and math.isfinite(accel_n)
                 and gx * gx + gy * gy + gz * gz < STILL_GYRO_RAD_S**2
                 and (all(s in state.ft for s in ANKLE_SENSORS)
                      and float(np.max(np.abs(state.dq_rad_s))) < STILL_JOINT_RAD_S
                      if self.whole_body else
                      both_soles_loaded(state, weight_n)
                      and all(store.get(SOLES_FLAT, (False, False)))))
        if not still:
            if self.n:
                self._restart()
            return None
        right, left = (state.ft[s] for s in ANKLE_SENSORS)
        return self._add((ax / accel_n, ay / accel_n, az / accel_n), T_torso_soles,
                         (float(right[2]), float(left[2])))

    def _add(self, imu_up, T_torso_soles: np.ndarray, fz_n) -> float | None:
        """Add a still state (the IMU's unit vertical); at the window's end, the angle between
        the mean verticals (deg), or None."""
        if self._first is None:
            self._first = np.array(T_torso_soles, dtype=float)
        self.n += 1
        legs = T_torso_soles[0][:3, 2] + T_torso_soles[1][:3, 2]
        sums = self.sums
        sums[0] += imu_up[0]
        sums[1] += imu_up[1]
        sums[2] += imu_up[2]
        sums[3] += float(legs[0])
        sums[4] += float(legs[1])
        sums[5] += float(legs[2])
        sums[6] += fz_n[0]
        sums[7] += fz_n[1]
        if self.n < STILL_STATES:
            return None
        first, last = self._first, np.asarray(T_torso_soles, dtype=float)
        moved_m = float(np.linalg.norm(last[:, :3, 3].mean(axis=0) - first[:, :3, 3].mean(axis=0)))
        turned_rad = max(angle_rad(first[k, :3, :3].T @ last[k, :3, :3]) for k in (0, 1))
        imu, legs = np.array(sums[:3]), np.array(sums[3:6])
        fz_n = (sums[6] / self.n, sums[7] / self.n)
        imu, legs = imu / np.linalg.norm(imu), legs / np.linalg.norm(legs)
        self._restart()
        if moved_m >= STILL_TORSO_M or turned_rad >= STILL_TURN_RAD:
            return None
        self.verticals, self.soles_fz_n = (imu, legs), fz_n
        return math.degrees(math.acos(min(1.0, float(imu @ legs))))
