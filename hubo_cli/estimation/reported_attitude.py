"""The torso attitude as the driver reports it (``state.imu_quat_wxyz``), passed on unfiltered.

This stands in the estimator's place for the attitude until the Kalman filter of gyro and
accelerometer (:mod:`hubo_cli.estimation.attitude`, with its gyro bias) replaces it: the
simulator reports its ideal orientation (with the perturbation's noise and bias), the hardware
driver the quaternion of hubo-ach's IMU tilt angles. A reading that is not a finite non-zero
quaternion keeps the last attitude (upright before the first good one).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import QUAT_WORLD_TORSO
from hubo_cli.estimation.observer import Observer
from hubo_cli.state import RobotState


class ReportedAttitude(Observer):
    """Writes ``QUAT_WORLD_TORSO``: the driver's IMU quaternion, normalised (see the module
    docstring)."""

    name = "reported-attitude"
    writes = (QUAT_WORLD_TORSO,)

    def __init__(self) -> None:
        self._last = np.array([1.0, 0.0, 0.0, 0.0])

    def reset(self, state: RobotState, store: Store) -> None:
        self._last = np.array([1.0, 0.0, 0.0, 0.0])
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        try:
            q = np.array(state.imu_quat_wxyz, dtype=float).reshape(4)
        except (TypeError, ValueError):
            q = None
        if q is not None:
            norm = float(np.sqrt(q @ q))
            if np.isfinite(norm) and norm > 1e-6:
                self._last = q / norm
        store[QUAT_WORLD_TORSO] = self._last
