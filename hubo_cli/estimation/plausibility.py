"""Sensors that lie (NaN included): the one observer of the plausibility checks on the
readings (each check its own module in :mod:`hubo_cli.estimation.sensor_checks`, with its
bounds and the healthy runs they were measured on, docs/history/safety.md rounds 17-20).

A sensor can fail and keep reporting finite numbers: an IMU whose values stop changing, force
sensors that read far more than the robot weighs, a wrist sensor that reads flat (a dead
channel reads 0 to the last bit) while its arm moves; or report NaN, which every bound lets
through (a comparison with NaN is false). The controllers act on these readings, so each is a
device fault (:class:`SensorFault`, exit 3): the control loop stops as it does after Ctrl-C (a
walk finishes its step into a double-support stance, any other run brakes to rest), and a
sensor already dead at the start refuses the run before
anything moves (:class:`SensorRefusal`, exit 4, as the other refusals with nothing moved).

Checks, in the order they judge a period:

- every period (a repeated state weighs the same): a reading that is not a finite number
  (:mod:`~hubo_cli.estimation.sensor_checks.non_finite`), the soles' load over the robot's
  weight (:mod:`~hubo_cli.estimation.sensor_checks.soles_overload`), the ankle sensors wired wrong
  (:mod:`~hubo_cli.estimation.sensor_checks.ankle_wiring`), the wrists' mean load over the
  first periods (:mod:`~hubo_cli.estimation.sensor_checks.wrists`);
- over fresh states only (a state whose time advances: the hardware driver repeats the last
  one when the daemon publishes nothing new, and such a gap is the stale-state check's,
  :mod:`hubo_cli.drivers.stale_state`): an ankle sensor or the accelerometer reading
  exactly 0 (:mod:`~hubo_cli.estimation.sensor_checks.dead_channels`), the IMU frozen while
  the legs turn the torso (:mod:`~hubo_cli.estimation.sensor_checks.imu_frozen`), the IMU's
  vertical against the legs' while standing still
  (:mod:`~hubo_cli.estimation.sensor_checks.imu_tilt`), a wrist sensor flat while its arm
  moves;
- at the start, before the first period (refused): a reading that is not a finite number, a
  wrist sensor reading exactly 0, an ankle sensor or the accelerometer reading exactly 0, the
  IMU's vertical against the legs', the ankle sensors wired wrong.

Not a check: an estimated fall while the soles still carry the robot. A real fall does that (the
push-wall robot tipping over its toes read 291 N of 380 N at 30 deg); a joint encoder that lies
is :mod:`hubo_cli.control.following`'s (a measured jump, a joint that does not follow).

Only a driver whose sensors are measured (``Driver.sensors_measured``) is checked: the ideal
driver's and a hardware dry run's echo (zero force and a level, still IMU) are not sensors.

The estimate's other check, the torso's height over the floor, lives in
:mod:`hubo_cli.control.following`, not here, because it differs in both respects that matter:
it holds for every driver (it judges the estimate built on the joints, which every driver
reports, made-up sensors or not; noisy encoders carried it to 9.16 m), and it brakes the run at
once, a walk too (a walk's stance stop steps on the estimate that check found wrong). Here a
walk finishes its step into a stance: these faults leave the joints, and so the step's
placement, sound; and a driver whose sensors are made up is not judged.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import (
    CONTACT,
    SOLES_FLAT,
    T_TORSO_SOLES,
    T_WORLD_SOLES,
    WRENCHES,
)
from hubo_cli.estimation.observer import Observer
from hubo_cli.estimation.sensor_checks.ankle_wiring import AnkleWiring
from hubo_cli.estimation.sensor_checks.dead_channels import DeadChannels
from hubo_cli.estimation.sensor_checks.faults import SensorFault, SensorRefusal
from hubo_cli.estimation.sensor_checks.imu_frozen import FrozenImu
from hubo_cli.estimation.sensor_checks.imu_tilt import ImuTilt
from hubo_cli.estimation.sensor_checks.non_finite import check_finite
from hubo_cli.estimation.sensor_checks.soles_overload import SolesOverload
from hubo_cli.estimation.sensor_checks.wrists import WristChecks
from hubo_cli.model import RobotModel
from hubo_cli.state import RobotState

__all__ = ["SensorFault", "SensorPlausibility", "SensorRefusal"]


class SensorPlausibility(Observer):
    """Raises :class:`SensorFault` once, the first period a reading is implausible (see the
    module docstring); it writes no key and runs last, after the estimate it checks.

    Args:
        model: the robot model (joint names, the soles' outline).
        weight_n: the robot's weight (N), its tools included.
        period_s: the control period (s).
        measured: the driver's sensors are measured (``Driver.sensors_measured``); False:
            nothing is checked.
        drill_kg: the drill's declared mass (kg) when the right hand holds it (the hint of
            the wrist start check names it), else None.
    """

    name = "sensor-plausibility"
    reads = (T_TORSO_SOLES, T_WORLD_SOLES, WRENCHES, CONTACT, SOLES_FLAT)

    def __init__(self, model: RobotModel, weight_n: float, period_s: float,
                 measured: bool = True, drill_kg: float | None = None) -> None:
        self.model = model
        self.weight_n = float(weight_n)
        self.drill_kg = drill_kg
        self.period_s = float(period_s)
        self.measured = measured
        self.fault: SensorFault | None = None

    @property
    def imu_legs_max_deg(self) -> float:
        """The largest angle a still window read against the start's (deg; a measurement)."""
        return self._tilt.max_deg

    def reset(self, state: RobotState, store: Store) -> None:
        self.fault = None
        self._t_s = None  # the last fresh state's time (s)
        self._q = None  # its joints (rad)
        self._soles = SolesOverload(self.weight_n, self.period_s)
        self._wiring = AnkleWiring(self.weight_n, self.period_s, self.model.feet)
        self._wrists = WristChecks(self.model, self.period_s, self.drill_kg)
        self._frozen = FrozenImu()
        self._tilt = ImuTilt(self.weight_n, self.period_s)
        self._dead = DeadChannels(self.period_s)
        if not self.measured:
            return
        try:
            check_finite(state, self.model.joint_names, start=True)
            self._wrists.start(state)
            self._dead.update(state, start=True)
            self._tilt.start(state, store)
            self._wiring.update(state, store, start=True)
        except SensorFault as fault:
            self.fault = fault
            raise
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        if not self.measured or self.fault is not None:
            return
        try:
            self._judge(state, store)
        except SensorFault as fault:
            self.fault = fault
            raise

    def _judge(self, state: RobotState, store: Store) -> None:
        check_finite(state, self.model.joint_names)
        self._soles.update(state)
        self._wiring.update(state, store)
        self._wrists.update_start(state, store)
        fresh = self._t_s is None or state.time_s > self._t_s
        if not fresh:  # the same state again: a gap is the stale-state check's
            return
        q = np.asarray(state.q_rad, dtype=float)
        dt_s = None if self._t_s is None else state.time_s - self._t_s
        self._dead.update(state)
        self._frozen.update(state, store)
        self._tilt.update(state, store)
        if dt_s is not None:
            self._wrists.update_dead(state, np.abs(q - self._q) / dt_s)
        self._t_s, self._q = state.time_s, q.copy()
