"""The IMU frozen: orientation, gyro and accelerometer together bit-identical over the last
:data:`IMU_FROZEN_STATES` fresh states while the legs' kinematics turned the torso at least
:data:`TORSO_TURNED_RAD` over them (on a sole loaded in both states, taken as still on the
floor). A still torso may read the same to the last bit (a quantised IMU without noise), a
moving one cannot; a walk's torso turns 0.4 deg in 10 states (median), a standing echo robot's
at most 0.013 deg (rounds 17 and 18, docs/history/safety.md)."""

from __future__ import annotations

from collections import deque

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import CONTACT, T_TORSO_SOLES
from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.estimation.sensor_checks.legs import angle_rad
from hubo_cli.state import RobotState

IMU_FROZEN_STATES = 10  # fresh states in a row bit-identical (50 ms at the state's rate) ...
TORSO_TURNED_RAD = 1e-3  # ... over which the legs turned the torso this much (0.06 deg)


class FrozenImu:
    """Judges each fresh state (module docstring)."""

    def __init__(self) -> None:
        self._imu = None
        self._same = 0  # fresh states in a row with the IMU bit-identical
        self._legs = None  # the last fresh state's R_torso_sole (2, 3, 3) and contact
        self._contact = (False, False)
        self._R_turned = np.eye(3)  # the torso's turn on the legs since the first fresh state
        self._turns = deque(maxlen=IMU_FROZEN_STATES + 1)  # ... at the last fresh states

    def update(self, state: RobotState, store: Store) -> None:
        """The IMU bit-identical over the last IMU_FROZEN_STATES fresh states while the legs
        turned the torso TORSO_TURNED_RAD over them (a still or slowly leaning torso may read
        the same: a quantised IMU without noise)."""
        self._turn_on_legs(store)
        self._turns.append(self._R_turned.copy())
        imu = np.concatenate([state.imu_quat_wxyz, state.imu_gyro_rad_s, state.imu_accel_m_s2])
        same = self._imu is not None and np.array_equal(imu, self._imu)
        self._imu, self._same = imu, self._same + 1 if same else 0
        if self._same < IMU_FROZEN_STATES:
            return
        turned_rad = angle_rad(self._turns[0].T @ self._turns[-1])
        if turned_rad >= TORSO_TURNED_RAD:
            raise sensor_fault(f"the IMU read the same values to the last bit for {self._same} "
                               f"states, the last {IMU_FROZEN_STATES} while the legs turned the "
                               f"torso {np.degrees(turned_rad):.2f} deg, at t = "
                               f"{state.time_s:.2f} s: frozen")

    def _turn_on_legs(self, store: Store) -> None:
        """Add the torso's turn since the last fresh state on a sole loaded in both (the sole
        taken as still on the floor; none loaded in both, or no legs: no turn seen)."""
        T_torso_soles = store.get(T_TORSO_SOLES)
        contact = tuple(store.get(CONTACT, (False, False)))
        legs = None if T_torso_soles is None else np.array(T_torso_soles)[:, :3, :3]
        if legs is not None and self._legs is not None:
            for k in (0, 1):
                if contact[k] and self._contact[k]:
                    # R_world_torso' = R_world_torso R_torso_sole R_torso_sole'^T (sole still)
                    self._R_turned = self._R_turned @ self._legs[k] @ legs[k].T
                    break
        self._legs, self._contact = legs, contact
