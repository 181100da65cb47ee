"""Sensors whose channels read exactly 0 in every component (round 21, review 21):

- an ankle force-torque sensor, at the start (refused) or for longer than
  :data:`~.ankle_wiring.SOLE_WIRING_OVER_S` of fresh states later. A working sensor never does:
  its noise, and the foot beyond it weighs something even in the air (the simulated sensors'
  smallest largest component on healthy walks is in docs/history/safety.md, round 21). The
  estimate read such a foot as off the floor: a stand on a dead right ankle ran its 4 s and
  exited 0 (review 21);
- the accelerometer (a working one reads gravity, and a robot on its feet is never in free
  fall), at the start (refused) or for :data:`~.imu_frozen.IMU_FROZEN_STATES` fresh states
  later: the attitude ran on the gyro alone and the running IMU check, which skips a zero
  vector, never judged it (review 21: a stand and a walk on it exited 0). The hardware
  driver's accelerometer is hubo-ach's tilt made a vector, never 0; a dead tilt is the frozen
  IMU's (:mod:`.imu_frozen`).

A wrist sensor reading 0 is :mod:`.wrists`' (refused at the start; later, flat while its arm
moves).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.estimation.sensor_checks.ankle_wiring import SOLE_WIRING_OVER_S
from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.estimation.sensor_checks.imu_frozen import IMU_FROZEN_STATES
from hubo_cli.state import ANKLE_SENSORS, RobotState


class DeadChannels:
    """Judges the start and each fresh state (module docstring)."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._ankle_dead = dict.fromkeys(ANKLE_SENSORS, 0)  # fresh states in a row all 0
        self._accel_dead = 0  # fresh states in a row with the accelerometer all 0

    def update(self, state: RobotState, start: bool = False) -> None:
        self._ankles(state, start)
        self._accelerometer(state, start)

    def _ankles(self, state: RobotState, start: bool) -> None:
        """An ankle sensor reading exactly 0 in every component: refused at the start, a fault
        once it lasts longer than SOLE_WIRING_OVER_S of fresh states."""
        for sensor in ANKLE_SENSORS:
            reading = state.ft.get(sensor)
            dead = reading is not None and not np.any(np.asarray(reading, dtype=float))
            self._ankle_dead[sensor] = self._ankle_dead[sensor] + 1 if dead else 0
            held_s = self._ankle_dead[sensor] * self.period_s
            if dead and (start or held_s > SOLE_WIRING_OVER_S + 1e-9):
                when = (", at the start: refused before anything moved" if start else
                        f" for {held_s:.3f} s at t = {state.time_s:.2f} s")
                raise sensor_fault(f"the {sensor} force-torque sensor reads exactly 0 in every "
                                   f"component{when}: a dead channel (a working sensor's noise "
                                   "and the foot beyond it never read so; the estimate takes "
                                   "that foot off the floor)",
                                   hint=f"check the {sensor} sensor's cable and power and "
                                        "hubo-daemon's channel for it, then start the run again",
                                   refuse=start)

    def _accelerometer(self, state: RobotState, start: bool) -> None:
        """The accelerometer reading exactly 0 in every component: refused at the start, a
        fault after IMU_FROZEN_STATES fresh states."""
        dead = not np.any(np.asarray(state.imu_accel_m_s2, dtype=float))
        self._accel_dead = self._accel_dead + 1 if dead else 0
        if dead and (start or self._accel_dead >= IMU_FROZEN_STATES):
            when = (" at the start: refused before anything moved" if start else
                    f" for {self._accel_dead} states at t = {state.time_s:.2f} s")
            raise sensor_fault(f"the IMU's accelerometer reads exactly 0 in every component"
                               f"{when}: a dead channel (a working one reads gravity on a robot "
                               "that stands or walks)", refuse=start)
