"""The robot standing still on both soles, as the running IMU check (:mod:`.imu_tilt`) judges
it: windows of :data:`STILL_STATES` fresh states, each state's gyro under
:data:`STILL_GYRO_RAD_S`, both soles loaded (:data:`~.legs.SOLE_LOADED_WEIGHTS` of the robot's
weight on the raw F_z) and lying flat (``SOLES_FLAT``: the attitude's legs measurement, its own
load ``legs_min_fz_n`` on the compensated F_z and the centre of pressure inside the outline),
the torso on the legs moved less than :data:`STILL_TORSO_M` and turned less than
:data:`STILL_TURN_RAD` over the window: its mean acceleration is then gravity's to 0.02 m/s^2."""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import SOLES_FLAT, T_TORSO_SOLES
from hubo_cli.estimation.sensor_checks.legs import angle_rad, both_soles_loaded
from hubo_cli.state import RobotState

STILL_STATES = 50  # 0.25 s
STILL_GYRO_RAD_S = 0.05
STILL_TORSO_M = 0.002
STILL_TURN_RAD = math.radians(0.2)


class StillWindow:
    """Fresh states standing still on both loaded flat soles, summed until STILL_STATES: the
    IMU's vertical (its accelerometer's direction) and the legs' (the soles' normals through the
    joints' kinematics), both in the torso's axes, and where the torso stood on the legs.

    Attributes:
        verticals: the window's mean verticals (unit; the IMU's, the legs'), set at the end of
            a still window.
    """

    def __init__(self) -> None:
        self._restart()

    def _restart(self) -> None:
        self.n = 0
        self.sums = [0.0] * 6  # the IMU's vertical (3), the legs' (3)
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
                 and both_soles_loaded(state, weight_n)
                 and all(store.get(SOLES_FLAT, (False, False))))
        if not still:
            if self.n:
                self._restart()
            return None
        return self._add((ax / accel_n, ay / accel_n, az / accel_n), T_torso_soles)

    def _add(self, imu_up, T_torso_soles: np.ndarray) -> float | None:
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
        if self.n < STILL_STATES:
            return None
        first, last = self._first, np.asarray(T_torso_soles, dtype=float)
        moved_m = float(np.linalg.norm(last[:, :3, 3].mean(axis=0) - first[:, :3, 3].mean(axis=0)))
        turned_rad = max(angle_rad(first[k, :3, :3].T @ last[k, :3, :3]) for k in (0, 1))
        imu, legs = np.array(sums[:3]), np.array(sums[3:])
        imu, legs = imu / np.linalg.norm(imu), legs / np.linalg.norm(legs)
        self._restart()
        if moved_m >= STILL_TORSO_M or turned_rad >= STILL_TURN_RAD:
            return None
        self.verticals = (imu, legs)
        return math.degrees(math.acos(min(1.0, float(imu @ legs))))
