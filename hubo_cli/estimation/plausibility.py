"""Sensors that lie without being NaN: the one home of the plausibility checks on the readings.

A sensor can fail and keep reporting finite numbers: an IMU whose values stop changing, force
sensors that read far more than the robot weighs, a wrist sensor that reads flat (a dead
channel reads 0 to the last bit) while its arm moves. The controllers
act on these readings, so each is a device fault (:class:`SensorFault`, exit 3): the control
loop stops as it does after Ctrl-C (a walk finishes its step into a double-support stance, any
other run brakes to rest), and a sensor already dead at the start refuses the run before
anything moves.

Checks (each bound measured on healthy runs, docs/history/safety.md, rounds 17 and 18), over
fresh states only (a state whose time advances: the hardware driver repeats the last one when
the daemon publishes nothing new, and such a gap is the stale-state check's,
:mod:`hubo_cli.drivers.stale_state`):

- the IMU (orientation, gyro and accelerometer together) bit-identical over the last
  :data:`IMU_FROZEN_STATES` fresh states while the legs' kinematics turned the torso at least
  :data:`TORSO_TURNED_RAD` over them (on a sole loaded in both states, taken as still on the
  floor). A still torso may read the same to the last bit (a quantised IMU without noise), a
  moving one cannot; a walk's torso turns 0.4 deg in 10 states (median), a standing echo
  robot's at most 0.013 deg;
- the soles' F_z together over :data:`SOLES_MAX_WEIGHTS` times the robot's weight for longer
  than :data:`SOLES_OVER_S` (a landing's impact is shorter);
- a wrist sensor bit-identical for :data:`WRIST_FLAT_STATES` fresh states while its arm moves
  (one of its joints at least :data:`ARM_MOVING_RAD_S` fast between fresh states, from their
  positions: a daemon may leave the velocities 0), or reading exactly 0 in every component
  at the start (a dead channel, or a sensor nulled with the hand on: the estimate removes
  the hand's weight from the reading, :mod:`hubo_cli.estimation.wrenches`, so it needs the
  sensor as it reads with nothing removed).

Not a check: an estimated fall while the soles still carry the robot. A real fall does that (the
push-wall robot tipping over its toes read 291 N of 380 N at 30 deg); a joint encoder that lies
is :mod:`hubo_cli.control.following`'s (a measured jump, a joint that does not follow).

Only a driver whose sensors are measured (``Driver.sensors_measured``) is checked: the ideal
driver's and a hardware dry run's echo (zero force and a level, still IMU) are not sensors.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.errors import DeviceError
from hubo_cli.estimation.keys import CONTACT, T_TORSO_SOLES
from hubo_cli.estimation.observer import Observer
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.state import ANKLE_SENSORS, RobotState

IMU_FROZEN_STATES = 10  # fresh states in a row bit-identical (50 ms at the state's rate) ...
TORSO_TURNED_RAD = 1e-3  # ... over which the legs turned the torso this much (0.06 deg)
SOLES_MAX_WEIGHTS = 2.5  # the soles' F_z together, in robot weights ...
SOLES_OVER_S = 0.1       # ... for longer than this (s)
WRIST_FLAT_STATES = 40   # fresh states (0.2 s) of its arm moving
ARM_MOVING_RAD_S = 0.02  # an arm moves: one of its joints this fast between fresh states
WRISTS = ("right-wrist", "left-wrist")


class SensorFault(DeviceError):
    """A sensor reads finite values no working sensor reads (see the module docstring)."""

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message, hint=hint or "check the sensor (cable, power, hubo-daemon's "
                                                "reading of it), then start the run again")


class SensorPlausibility(Observer):
    """Raises :class:`SensorFault` once, the first period a reading is implausible (see the
    module docstring); it writes no key and runs last, after the estimate it checks.

    Args:
        model: the robot model (joint names).
        weight_n: the robot's weight (N), its tools included.
        period_s: the control period (s).
        measured: the driver's sensors are measured (``Driver.sensors_measured``); False:
            nothing is checked.
    """

    name = "sensor-plausibility"
    reads = (CONTACT,)
    follows = (T_TORSO_SOLES,)  # the legs' kinematics (without them no turn is seen)

    def __init__(self, model: RobotModel, weight_n: float, period_s: float,
                 measured: bool = True) -> None:
        self.weight_n = float(weight_n)
        self.period_s = float(period_s)
        self.measured = measured
        self._arms = {wrist: model.limb_slice(arm) for wrist, arm in zip(WRISTS, ARMS,
                                                                          strict=True)}
        self.fault: SensorFault | None = None

    def reset(self, state: RobotState, store: Store) -> None:
        self.fault = None
        self._t_s = None  # the last fresh state's time (s)
        self._q = None  # its joints (rad)
        self._imu = None
        self._imu_same = 0  # fresh states in a row with the IMU bit-identical
        self._legs = None  # the last fresh state's R_torso_sole (2, 3, 3) and contact
        self._contact = (False, False)
        self._R_turned = np.eye(3)  # the torso's turn on the legs since the first fresh state
        self._turns = deque(maxlen=IMU_FROZEN_STATES + 1)  # ... at the last fresh states
        self._wrist = dict.fromkeys(WRISTS)
        self._wrist_flat = dict.fromkeys(WRISTS, 0)
        self._soles_over = 0  # periods in a row over the limit
        if not self.measured:
            return
        for wrist in WRISTS:
            reading = state.ft.get(wrist)
            if reading is not None and not np.any(np.asarray(reading, dtype=float)):
                self._raise(f"the {wrist} force-torque sensor reads exactly 0 in every "
                            "component at the start: refused before anything moved (a dead "
                            "channel reads so, and so does a sensor nulled with the hand on: "
                            "the estimate removes the hand's weight itself, so null the wrist "
                            "sensors with nothing beyond them or not at all; against hubo "
                            "hardware fake-daemon pass --echo-sensors)",
                            hint="check the sensor's cable and power, or how it was nulled, "
                                 "then start the run again")
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        if not self.measured or self.fault is not None:
            return
        self._soles(state)
        fresh = self._t_s is None or state.time_s > self._t_s
        if not fresh:  # the same state again: a gap is the stale-state check's
            return
        q = np.asarray(state.q_rad, dtype=float)
        dt_s = None if self._t_s is None else state.time_s - self._t_s
        self._frozen_imu(state, store)
        if dt_s is not None:
            self._dead_wrists(state, np.abs(q - self._q) / dt_s)
        self._t_s, self._q = state.time_s, q.copy()

    def _soles(self, state: RobotState) -> None:
        soles_n = sum(float(state.ft[s][2]) for s in ANKLE_SENSORS if s in state.ft)
        over = soles_n > SOLES_MAX_WEIGHTS * self.weight_n
        self._soles_over = self._soles_over + 1 if over else 0
        if self._soles_over * self.period_s > SOLES_OVER_S + 1e-9:
            self._raise(f"the ankle force sensors read {soles_n:.0f} N together "
                        f"({soles_n / self.weight_n:.1f} times the robot's "
                        f"{self.weight_n:.0f} N) for {self._soles_over * self.period_s:.3f} s "
                        f"at t = {state.time_s:.2f} s")

    def _frozen_imu(self, state: RobotState, store: Store) -> None:
        """The IMU bit-identical over the last IMU_FROZEN_STATES fresh states while the legs
        turned the torso TORSO_TURNED_RAD over them (a still or slowly leaning torso may read
        the same: a quantised IMU without noise)."""
        self._turn_on_legs(store)
        self._turns.append(self._R_turned.copy())
        imu = np.concatenate([state.imu_quat_wxyz, state.imu_gyro_rad_s, state.imu_accel_m_s2])
        same = self._imu is not None and np.array_equal(imu, self._imu)
        self._imu, self._imu_same = imu, self._imu_same + 1 if same else 0
        if self._imu_same < IMU_FROZEN_STATES:
            return
        turned_rad = _angle_rad(self._turns[0].T @ self._turns[-1])
        if turned_rad >= TORSO_TURNED_RAD:
            self._raise(f"the IMU read the same values to the last bit for {self._imu_same} "
                        f"states, the last {IMU_FROZEN_STATES} while the legs turned the torso "
                        f"{np.degrees(turned_rad):.2f} deg, at t = {state.time_s:.2f} s: frozen")

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

    def _dead_wrists(self, state: RobotState, speed_rad_s: np.ndarray) -> None:
        """A wrist sensor bit-identical for WRIST_FLAT_STATES fresh states while its arm moved
        (from the joints' positions: a daemon's velocities may read 0)."""
        for wrist, arm in self._arms.items():
            reading = state.ft.get(wrist)
            if reading is None:
                continue
            reading = np.asarray(reading, dtype=float)
            flat = self._wrist[wrist] is not None and np.array_equal(reading, self._wrist[wrist])
            self._wrist[wrist] = reading.copy()
            if not flat:
                self._wrist_flat[wrist] = 0
            elif np.max(speed_rad_s[arm]) >= ARM_MOVING_RAD_S:
                self._wrist_flat[wrist] += 1
                if self._wrist_flat[wrist] >= WRIST_FLAT_STATES:
                    self._raise(f"the {wrist} force-torque sensor read the same values to "
                                f"the last bit for {self._wrist_flat[wrist]} states while "
                                f"its arm moved, at t = {state.time_s:.2f} s: dead")

    def _raise(self, message: str, hint: str = "") -> None:
        self.fault = SensorFault(message, hint)
        raise self.fault


def _angle_rad(R: np.ndarray) -> float:
    """The angle of the rotation ``R`` (rad)."""
    return float(np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)))
