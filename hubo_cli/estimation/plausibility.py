"""Sensors that lie without being NaN: the one home of the plausibility checks on the readings.

A sensor can fail and keep reporting finite numbers: an IMU whose values stop changing, force
sensors that read far more than the robot weighs, a wrist sensor that reads flat (a dead
channel reads 0 to the last bit) while its arm moves. The controllers
act on these readings, so each is a device fault (:class:`SensorFault`, exit 3): the control
loop stops as it does after Ctrl-C (a walk finishes its step into a double-support stance, any
other run brakes to rest), and a sensor already dead at the start refuses the run before
anything moves (:class:`SensorRefusal`, exit 4, as the other refusals with nothing moved).

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
- a wrist sensor whose reading, the weight of the hand and its tool removed (as the run
  declares the tool: :mod:`hubo_cli.estimation.wrenches`), averages more than
  :data:`WRIST_START_MAX_N` along its z over the run's first :data:`WRIST_START_PERIODS`
  periods, while the hands touch nothing yet: an offset, a wrong tool in the task file (the
  drill declared and not held weighs 5.2 N), or the other wrist's sensor (round 18; averaged,
  because one reading's noise alone is 1 N);
- at the start, with both soles loaded (each carrying :data:`SOLE_LOADED_WEIGHTS` of the
  robot's weight at least), the IMU's vertical (its accelerometer's gravity, as the attitude
  starts from it) more than :data:`IMU_LEGS_MAX_ROLL_DEG` in roll or
  :data:`IMU_LEGS_MAX_PITCH_DEG` in pitch from the legs' (the soles' normal through
  the measured joints' kinematics): a floor tilted that much or an IMU mounted crooked or
  miscalibrated, which one state cannot tell apart (round 18; the estimate would start tilted
  by the difference and the capture point stop the run at once, without naming the IMU; round
  19: the message names both, the bound is the tilt a walk is run on);
- after the start, the same comparison whenever the robot stands still on both loaded soles
  lying flat for :data:`STILL_STATES` fresh states, the two verticals averaged over them,
  their difference more than :data:`IMU_LEGS_RUNNING_MAX_DEG` from the start's: an IMU that
  drifts or is knocked since the start (round 19; while the robot moves, its accelerometer
  reads its motion as well as gravity). Flat as the attitude's legs measurement judges it
  (``SOLES_FLAT``: each sole's centre of pressure inside its outline by a margin): a robot
  leaning on its soles' edges tilts where the legs' kinematics, which take each sole flat on
  the floor, do not see it (round 20: round 19's check, judging every loaded sole, stopped
  the push-wall's emergency revert on a true IMU 2.9 deg from the legs);
- an ankle sensor wired wrong (round 20): its F_z, the foot's weight removed, below
  -:data:`SOLE_PULL_MAX_WEIGHTS` of the robot's weight (the floor pushes a sole, it cannot pull
  it: the sign of F_z flipped), or the centre of pressure it gives its sole more than
  :data:`COP_OFF_SOLE_M` outside the sole's outline while it carries
  :data:`SOLE_LOADED_WEIGHTS` of the robot's weight (no force on a sole acts outside it: the
  sensor turned about its z, a moment's sign flipped), or a sole read carrying
  :data:`SOLE_CARRIES_WEIGHTS` of the weight more than :data:`SOLE_UNDER_M` above one read in
  the air (the estimate stands the robot on the sole its sensor loads; on a flat floor the
  other cannot lie under it: the sensors swapped between the feet, seen once a foot lifts), at
  the start (refused) or for longer than :data:`SOLE_WIRING_OVER_S` later
  (:data:`SOLE_SWAPPED_OVER_S` for a sole under the other: a healthy robot rocking on a sole's
  edge reads so for a moment, as the estimate takes that sole flat); or, before a step or a
  bounce, both soles more than :data:`SOLES_SUNK_M` under the floor the robot started on for
  longer than :data:`SOLE_WIRING_OVER_S` (the sensors swapped before a foot lifts: a walk's
  first weight shift rocks the robot from sole to sole, and standing it on the sole its sensor
  loads, the rising one, each rock carries the estimate down; round 21). A moment flipped or a
  sensor turned while the centre of pressure stays near the ankle, and swapped sensors on a
  robot that stands without rocking, read as a working pair does (docs/history/safety.md,
  rounds 20 and 21).
- an ankle sensor reading exactly 0 in every component (a dead channel, as the wrists' check
  above; round 21): at the start (refused) or for longer than :data:`SOLE_WIRING_OVER_S` of
  fresh states later. A working sensor never does: its noise, and the foot beyond it weighs
  something even in the air (the simulated sensors' smallest largest component on healthy
  walks is in docs/history/safety.md, round 21). The estimate read such a foot as off the
  floor: a stand on a dead right ankle ran its 4 s and exited 0 (review 21).
- the accelerometer reading exactly 0 in every component (a dead channel: a working one reads
  gravity, and a robot on its feet is never in free fall) at the start (refused) or for
  :data:`IMU_FROZEN_STATES` fresh states later: the attitude ran on the gyro alone and the
  running IMU check, which skips a zero vector, never judged it (review 21: a stand and a walk
  on it exited 0). The hardware driver's accelerometer is hubo-ach's tilt made a vector, never
  0; a dead tilt is the frozen IMU above.

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
walk finishes its step into a stance: the faults below leave the joints, and so the step's
placement, sound; and a driver whose sensors are made up is not judged.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.errors import DeviceError
from hubo_cli.estimation.keys import (
    CONTACT,
    SOLES_FLAT,
    T_TORSO_SOLES,
    T_WORLD_SOLES,
    WRENCHES,
)
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
# The IMU's vertical and the legs' at the start, both soles loaded, at most this far apart
# (deg). The legs give the torso's tilt against the soles, the IMU against gravity: on a floor
# tilted by X deg they differ by X, as they do with the IMU mounted X deg crooked; at the start
# (one state, nothing moved yet) the two cannot be told apart (the soles' forces and CoP say
# nothing of the floor's tilt), so the bound is the tilt either way the robot can be run on.
# Healthy starts (round 18; walk, sim, the six tasks and both sample replays, nominal and
# perturbed seeds, both code paths; docs/history/safety.md) read 0.006 deg nominal and up to
# 0.54 deg perturbed (a perturbed floor's tilt, up to 0.5 deg, and the sensor's calibration and
# noise). Floors (round 19, the check moved away, walk --to 0.6 0 0 on the sim driver, nominal
# robot): tilted about the torso's y (pitch), 1.3 deg either way completes (8 and 6 steps, 11
# and 10 mm off), +1.5, +1.6 and +1.8 deg stop on the capture point at 0.14-0.18 s, no step;
# about x (roll, the review's cross-slope), 1.6 deg either way completes (4.6 and 0.4 mm off),
# 1.7 deg stops at 5.9 s (5 steps), 1.8 at 3.6 s, 2.0 stops. An IMU pitched 1 deg walked as a
# healthy one, 1.5 deg slowed (8 steps, 20 mm off), 2 deg stopped at 0.15 s. So the bound is per
# axis, midway between the largest tilt walked and the smallest that stopped (a start reads
# the floor's tilt to 0.01 deg), the difference's roll and pitch inside the ellipse of these
# half-axes; healthy starts stay 0.86 deg under the smaller
IMU_LEGS_MAX_PITCH_DEG = 1.4
IMU_LEGS_MAX_ROLL_DEG = 1.65
IMU_LEGS_MAX_DEG = IMU_LEGS_MAX_PITCH_DEG  # (the smaller: within it any tilt passes)
SOLE_LOADED_WEIGHTS = 0.25  # a sole loaded: its F_z at least this many robot weights
# After the start, the same comparison over windows of STILL_STATES fresh states standing still
# on both loaded soles lying flat (SOLES_FLAT; each state's gyro under STILL_GYRO_RAD_S, the
# torso on the legs moved less than STILL_TORSO_M and turned less than STILL_TURN_RAD over the
# window: its mean acceleration is then gravity's to 0.02 m/s^2), the two verticals averaged
# over the window (the IMU's noise and quantisation averaged out), their difference against
# the start's: an IMU that drifts or is knocked since the start. Healthy runs (round 20,
# docs/history/safety.md; both code paths: the push-wall with and without the e-stop, the
# valve and door experiments, standing pushes, walks, cut-rectangle, nominal and seeds 3,
# 31-44) read at most 0.72 deg (sim --perturb 31 settling at 0.37 s); the leans round 19's
# rule stopped (soles on their edges: 2.8-7.5 deg) are not judged. 1.5 deg keeps 0.78 deg
# over it (an IMU knocked 1.4 deg reads no fault, 2 deg stops 0.25 s later; drifting 0.1
# deg/s stops after 15 s)
STILL_STATES = 50  # 0.25 s
STILL_GYRO_RAD_S = 0.05
STILL_TORSO_M = 0.002
STILL_TURN_RAD = math.radians(0.2)
IMU_LEGS_RUNNING_MAX_DEG = 1.5
# A wrist's compensated F_z, averaged over the run's first WRIST_START_PERIODS periods (0.1 s),
# at most this far from 0 (N). Healthy starts (round 18; the same runs as IMU_LEGS_MAX_DEG)
# averaged 0.02 N nominal and up to 0.92 N perturbed (single readings 3.7 N): the masses of the
# hand and the drill drawn 10 % off (0.8 N with the drill), the noise (1 N a reading, 0.22 N
# averaged). The drill declared and not held reads 5.2 N
WRIST_START_MAX_N = 2.5
WRIST_START_PERIODS = 20
# An ankle sensor wired wrong (round 20, docs/history/safety.md; healthy walks, stands, pushes,
# the push-wall and the tasks, nominal and perturbed, both code paths). The floor's push on a
# sole, its foot's weight removed, read at least -29 N (a foot landing after a side push); F_z's
# sign flipped reads minus the sole's load, -140 N or less on a standing robot:
SOLE_PULL_MAX_WEIGHTS = 0.25
# A sole's centre of pressure from its sensor read at most 15.4 mm outside the sole for a
# period while it carried SOLE_LOADED_WEIGHTS (a 100 N push mid-walk), 0.6 mm held over 0.055
# s (20.5 mm for a period with 50 N: a lighter sole is not judged); a sensor turned 180 deg
# about its z puts a toe-loaded sole's 40 mm beyond its heel, turned 90 deg 65 mm beside it
COP_OFF_SOLE_M = 0.02
# A sole read carrying SOLE_CARRIES_WEIGHTS of the weight lay at most 5.0 mm above one read as
# in the air (below SOLE_IN_AIR_WEIGHTS) in the estimate (the floor flat; its tilt on a
# perturbed robot, 0.5 deg at most, is 2 mm over the 0.24 m between the soles); swapped
# sensors, the estimate stands the robot on its lifted foot: up to 50-90 mm
SOLE_UNDER_M = 0.02
SOLE_CARRIES_WEIGHTS = 0.5
SOLE_IN_AIR_WEIGHTS = 0.1
SOLE_WIRING_OVER_S = 0.05  # either for longer than this (s) after the start
# ... and a sole under the other for longer than this (s): rocking from sole to sole after a
# backward capture step (sim --step pushed 90 or 105 N backward, round 20's audit), healthy
# robots read the loaded sole, rolled on its edge and taken flat by the estimate, 21-43 mm
# above the other for up to 0.105 s in a row (11 of 22 runs stopped on SOLE_WIRING_OVER_S);
# swapped sensors on walks read so for 0.245 s (seed 1) to 0.76-0.83 s (nominal) in a row
SOLE_SWAPPED_OVER_S = 0.15
# Before a step (each sole within SOLE_STEPPED_M of where the estimate put it at the start: the
# floor under both is the one the robot started on) and before a bounce (the soles together
# carrying less than SOLE_IN_AIR_WEIGHTS of the weight: the estimate then holds no sole to the
# floor, and takes the anchor up where its sole comes down), both soles estimated more than
# SOLES_SUNK_M under that floor (round 21, docs/history/safety.md). Healthy walks, pushes and
# tasks, both code paths, read 0.61 mm at most (a door pushed on seed 55, the wrist
# overloaded, bounced and sank 2.9 mm after its first bounce, which is not judged); swapped
# sensors, the estimate stands the robot on the foot that rises as the walk's first weight
# shift rocks it from sole to sole, and each rock carries the estimate down: past 2 mm by
# 0.47-0.68 s (the first lift-off at 0.9 s; the fast gait's at 0.55 s, seen at 0.51 s), 5-40 mm
# later
SOLES_SUNK_M = 0.002
SOLE_STEPPED_M = 0.03


class SensorFault(DeviceError):
    """A sensor reads finite values no working sensor reads (see the module docstring)."""

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message, hint=hint or "check the sensor (cable, power, hubo-daemon's "
                                                "reading of it), then start the run again")


class SensorRefusal(SensorFault):
    """A sensor reads what no working one does before anything moved: the run is refused
    (exit 4, as every refusal with nothing moved), not stopped."""

    exit_code = 4


class SensorPlausibility(Observer):
    """Raises :class:`SensorFault` once, the first period a reading is implausible (see the
    module docstring); it writes no key and runs last, after the estimate it checks.

    Args:
        model: the robot model (joint names).
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
        self.weight_n = float(weight_n)
        self.drill_kg = drill_kg
        self.period_s = float(period_s)
        self.measured = measured
        self._arms = {wrist: model.limb_slice(arm) for wrist, arm in zip(WRISTS, ARMS,
                                                                          strict=True)}
        corners = model.feet.sole_corners_m()
        self._sole_lo, self._sole_hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
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
        self._wiring_over = 0  # periods in a row an ankle sensor read as wired wrong
        self._ankle_dead = dict.fromkeys(ANKLE_SENSORS, 0)  # fresh states in a row all 0
        self._accel_dead = 0  # fresh states in a row with the accelerometer all 0
        self._swapped_over = 0  # ... the two read as swapped
        self._sunk_over = 0  # ... both soles under the floor before a step
        self._soles_start_xy = None  # where the estimate put the soles at the start (m) ...
        self._judge_sunk = True  # ... until one leaves it (a step) or both bounce
        self._periods = 0  # periods judged since the reset
        self._wrist_sums = np.zeros((2, len(WRISTS)))  # per wrist: compensated F_z, raw F_z
        self._still = _StillWindow()
        self._tilt_start_deg = (0.0, 0.0)  # the IMU's roll, pitch less the legs' at the start
        self.imu_legs_max_deg = 0.0  # the largest angle a still window read (a measurement)
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
                                 "then start the run again", refuse=True)
        self._dead_ankles(state, start=True)
        self._dead_accelerometer(state, start=True)
        self._imu_against_legs(state, store)
        self._ankle_wiring(state, store, start=True)
        self.update(state, store)

    def _imu_against_legs(self, state: RobotState, store: Store) -> None:
        """Refuse a start whose IMU's vertical is beyond IMU_LEGS_MAX_ROLL_DEG in roll or
        IMU_LEGS_MAX_PITCH_DEG in pitch from the legs' with both soles loaded (module
        docstring); nothing is judged otherwise (a robot hanging in its gantry, joints or
        readings not finite)."""
        T_torso_soles = store.get(T_TORSO_SOLES)
        accel = np.asarray(state.imu_accel_m_s2, dtype=float)
        soles_n = [float(np.asarray(state.ft.get(s, np.zeros(6)), dtype=float)[2])
                   for s in ANKLE_SENSORS]
        if T_torso_soles is None or not (np.all(np.isfinite(accel))
                                         and np.linalg.norm(accel) > 0.0) \
                or not min(soles_n) >= SOLE_LOADED_WEIGHTS * self.weight_n:
            return
        legs = np.asarray(T_torso_soles)[:, :3, 2].sum(axis=0)
        legs /= np.linalg.norm(legs)
        imu = accel / np.linalg.norm(accel)
        apart_deg = math.degrees(math.acos(min(1.0, float(legs @ imu))))
        (imu_roll, imu_pitch), (legs_roll, legs_pitch) = _roll_pitch_deg(imu, digits=None), \
            _roll_pitch_deg(legs, digits=None)
        self._tilt_start_deg = (imu_roll - legs_roll, imu_pitch - legs_pitch)  # floor or mount
        if math.hypot((imu_roll - legs_roll) / IMU_LEGS_MAX_ROLL_DEG,
                      (imu_pitch - legs_pitch) / IMU_LEGS_MAX_PITCH_DEG) > 1.0:
            (imu_roll, imu_pitch), (legs_roll, legs_pitch) = _roll_pitch_deg(imu), \
                _roll_pitch_deg(legs)  # (as said: rounded, never "-0.0")
            self._raise(f"the IMU reads the torso at roll {imu_roll:.1f} deg, pitch "
                        f"{imu_pitch:.1f} deg, the legs' kinematics with both soles loaded at "
                        f"roll {legs_roll:.1f}, pitch {legs_pitch:.1f}: {apart_deg:.1f} deg "
                        f"apart (at most {IMU_LEGS_MAX_ROLL_DEG:g} deg in roll, "
                        f"{IMU_LEGS_MAX_PITCH_DEG:g} in pitch): the floor is tilted by "
                        f"{apart_deg:.1f} deg or the IMU is mis-mounted; refused before "
                        "anything moved",
                        hint=f"stand the robot on a floor level to {IMU_LEGS_MAX_PITCH_DEG:g} deg "
                             "(a walk on a floor pitched 1.5 deg stopped at once); on a level "
                             "floor, check the IMU's mounting and calibration, then start the "
                             "run again", refuse=True)

    def update(self, state: RobotState, store: Store) -> None:
        if not self.measured or self.fault is not None:
            return
        self._soles(state)
        self._ankle_wiring(state, store)
        self._periods += 1
        if self._periods <= WRIST_START_PERIODS:  # (every period: a repeat weighs the same)
            self._wrist_start(state, store)
        fresh = self._t_s is None or state.time_s > self._t_s
        if not fresh:  # the same state again: a gap is the stale-state check's
            return
        q = np.asarray(state.q_rad, dtype=float)
        dt_s = None if self._t_s is None else state.time_s - self._t_s
        self._dead_ankles(state)
        self._dead_accelerometer(state)
        self._frozen_imu(state, store)
        self._imu_tilt_while_still(state, store)
        if dt_s is not None:
            self._dead_wrists(state, np.abs(q - self._q) / dt_s)
        self._t_s, self._q = state.time_s, q.copy()

    def _imu_tilt_while_still(self, state: RobotState, store: Store) -> None:
        """Each window of STILL_STATES fresh states standing still on both loaded flat soles:
        the IMU's mean vertical against the legs', their difference more than
        IMU_LEGS_RUNNING_MAX_DEG from the start's, is a fault (module docstring); a state not
        still starts the window again. (Scalar arithmetic: it runs every fresh state.)"""
        T_torso_soles = store.get(T_TORSO_SOLES)
        ax, ay, az = state.imu_accel_m_s2.tolist()
        gx, gy, gz = state.imu_gyro_rad_s.tolist()
        accel_n = math.sqrt(ax * ax + ay * ay + az * az)
        loaded_n = SOLE_LOADED_WEIGHTS * self.weight_n
        still = (T_torso_soles is not None and accel_n > 0.0 and math.isfinite(accel_n)
                 and gx * gx + gy * gy + gz * gz < STILL_GYRO_RAD_S**2
                 and all(float(state.ft[s][2]) >= loaded_n if s in state.ft else False
                         for s in ANKLE_SENSORS)
                 and all(store.get(SOLES_FLAT, (False, False))))
        if not still:
            if self._still.n:
                self._still = _StillWindow()
            return
        apart_deg = self._still.add((ax / accel_n, ay / accel_n, az / accel_n), T_torso_soles)
        if apart_deg is None:
            return
        # against the start's difference (a floor's tilt or the IMU's mounting stays; round 19:
        # a 1.6 deg floor, which the start check lets walk, stopped here at 0.25 s)
        (imu_roll, imu_pitch), (legs_roll, legs_pitch) = (
            _roll_pitch_deg(v, digits=None) for v in self._still.verticals)
        start_roll, start_pitch = self._tilt_start_deg
        moved_deg = math.hypot(imu_roll - legs_roll - start_roll,
                               imu_pitch - legs_pitch - start_pitch)
        self.imu_legs_max_deg = max(self.imu_legs_max_deg, moved_deg)
        if moved_deg > IMU_LEGS_RUNNING_MAX_DEG:
            imu, legs = self._still.verticals
            (imu_roll, imu_pitch), (legs_roll, legs_pitch) = _roll_pitch_deg(imu), \
                _roll_pitch_deg(legs)
            self._raise("standing still on both soles flat for "
                        f"{STILL_STATES * self.period_s:.2f} s at t = {state.time_s:.2f} s, "
                        "the IMU read the torso at roll "
                        f"{imu_roll:.1f} deg, pitch {imu_pitch:.1f} deg, the legs' kinematics "
                        f"at roll {legs_roll:.1f}, pitch {legs_pitch:.1f}: {apart_deg:.1f} deg "
                        f"apart ({moved_deg:.1f} deg from the start's "
                        f"{math.hypot(start_roll, start_pitch):.1f}; at most "
                        f"{IMU_LEGS_RUNNING_MAX_DEG:g} deg): the IMU drifted or tilted since "
                        "the start",
                        hint="check the IMU's mounting and calibration, then start the run "
                             "again")

    def _soles(self, state: RobotState) -> None:
        soles_n = sum(float(state.ft[s][2]) for s in ANKLE_SENSORS if s in state.ft)
        over = soles_n > SOLES_MAX_WEIGHTS * self.weight_n
        self._soles_over = self._soles_over + 1 if over else 0
        if self._soles_over * self.period_s > SOLES_OVER_S + 1e-9:
            self._raise(f"the ankle force sensors read {soles_n:.0f} N together "
                        f"({soles_n / self.weight_n:.1f} times the robot's "
                        f"{self.weight_n:.0f} N) for {self._soles_over * self.period_s:.3f} s "
                        f"at t = {state.time_s:.2f} s")

    def _ankle_wiring(self, state: RobotState, store: Store, start: bool = False) -> None:
        """An ankle sensor whose F_z pulls its sole or whose centre of pressure lies off its
        sole, or the two swapped (module docstring): refused at the start, a fault once it
        lasts longer than SOLE_WIRING_OVER_S (swapped: SOLE_SWAPPED_OVER_S)."""
        wrenches = store.get(WRENCHES)
        if wrenches is None:
            return
        wrong = None
        for sensor in ANKLE_SENSORS:
            w = np.asarray(wrenches[sensor], dtype=float)
            fz_n = float(w[2])
            if fz_n < -SOLE_PULL_MAX_WEIGHTS * self.weight_n:
                wrong = (sensor, f"F_z {fz_n:.0f} N, its foot's weight removed (the floor "
                                 "pushes a sole, it cannot pull it: at least "
                                 f"{-SOLE_PULL_MAX_WEIGHTS * self.weight_n:.0f} N)",
                         "its F_z's sign is flipped")
                break
            if not fz_n >= SOLE_LOADED_WEIGHTS * self.weight_n:
                continue
            cop_m = np.array([-w[4], w[3]]) / fz_n
            off_m = float(np.max(np.maximum(self._sole_lo - cop_m, cop_m - self._sole_hi)))
            if off_m > COP_OFF_SOLE_M:
                (x0, y0), (x1, y1) = self._sole_lo * 1000, self._sole_hi * 1000
                wrong = (sensor, f"its sole's centre of pressure at x {round(cop_m[0] * 1000)}, y "
                                 f"{round(cop_m[1] * 1000)} mm while the sole carries {fz_n:.0f} "
                                 f"N: {off_m * 1000:.0f} mm outside the sole (x {x0:.0f} to "
                                 f"{x1:.0f}, y {y0:.0f} to {y1:.0f} mm; at most "
                                 f"{COP_OFF_SOLE_M * 1000:.0f} mm: no force on a sole acts "
                                 "outside it)",
                         "it is turned about its z (mounted 90 or 180 deg off) or the sign of "
                         "its m_x or m_y is flipped")
                break
        swapped = self._ankles_swapped(store, wrenches)
        sunk = self._soles_sunk(store, wrenches)
        self._wiring_over = self._wiring_over + 1 if wrong else 0
        self._swapped_over = self._swapped_over + 1 if swapped else 0
        self._sunk_over = self._sunk_over + 1 if sunk else 0
        for found, over, over_s in ((wrong, self._wiring_over, SOLE_WIRING_OVER_S),
                                    (swapped, self._swapped_over, SOLE_SWAPPED_OVER_S),
                                    (sunk, self._sunk_over, SOLE_WIRING_OVER_S)):
            if found is not None and (start or over * self.period_s > over_s + 1e-9):
                break
        else:
            return
        sensor, reading, cause = found
        when = ", at the start: refused before anything moved" if start else (
            f" for {over * self.period_s:.3f} s at t = {state.time_s:.2f} s")
        self._raise(f"the {sensor} force-torque sensor reads {reading}{when}",
                    hint=f"{cause}, or the ankle sensors are wired to the wrong channels: check "
                         f"the {sensor} sensor's mounting, its cable and hubo-daemon's channel "
                         "and sign settings for it, then start the run again", refuse=start)

    def _dead_ankles(self, state: RobotState, start: bool = False) -> None:
        """An ankle sensor reading exactly 0 in every component: refused at the start, a fault
        once it lasts longer than SOLE_WIRING_OVER_S of fresh states (module docstring)."""
        for sensor in ANKLE_SENSORS:
            reading = state.ft.get(sensor)
            dead = reading is not None and not np.any(np.asarray(reading, dtype=float))
            self._ankle_dead[sensor] = self._ankle_dead[sensor] + 1 if dead else 0
            held_s = self._ankle_dead[sensor] * self.period_s
            if dead and (start or held_s > SOLE_WIRING_OVER_S + 1e-9):
                when = (", at the start: refused before anything moved" if start else
                        f" for {held_s:.3f} s at t = {state.time_s:.2f} s")
                self._raise(f"the {sensor} force-torque sensor reads exactly 0 in every "
                            f"component{when}: a dead channel (a working sensor's noise and "
                            "the foot beyond it never read so; the estimate takes that foot "
                            "off the floor)",
                            hint=f"check the {sensor} sensor's cable and power and "
                                 "hubo-daemon's channel for it, then start the run again",
                            refuse=start)

    def _dead_accelerometer(self, state: RobotState, start: bool = False) -> None:
        """The accelerometer reading exactly 0 in every component: refused at the start, a
        fault after IMU_FROZEN_STATES fresh states (module docstring)."""
        dead = not np.any(np.asarray(state.imu_accel_m_s2, dtype=float))
        self._accel_dead = self._accel_dead + 1 if dead else 0
        if dead and (start or self._accel_dead >= IMU_FROZEN_STATES):
            when = (" at the start: refused before anything moved" if start else
                    f" for {self._accel_dead} states at t = {state.time_s:.2f} s")
            self._raise(f"the IMU's accelerometer reads exactly 0 in every component{when}: a "
                        "dead channel (a working one reads gravity on a robot that stands or "
                        "walks)", refuse=start)

    def _ankles_swapped(self, store: Store, wrenches: dict) -> tuple[str, str, str] | None:
        """A sole read carrying SOLE_CARRIES_WEIGHTS of the robot more than SOLE_UNDER_M above
        one read as in the air (below SOLE_IN_AIR_WEIGHTS): the estimate stands the robot on the
        sole its sensor loads, so the other one is under the floor (module docstring)."""
        T_world_soles = store.get(T_WORLD_SOLES)
        if T_world_soles is None:
            return None
        z_m = np.asarray(T_world_soles, dtype=float)[:, 2, 3]
        fz_n = [float(wrenches[sensor][2]) for sensor in ANKLE_SENSORS]
        for k, other in ((0, 1), (1, 0)):
            below_m = z_m[k] - z_m[other]
            if fz_n[k] > SOLE_CARRIES_WEIGHTS * self.weight_n and \
                    fz_n[other] < SOLE_IN_AIR_WEIGHTS * self.weight_n and below_m > SOLE_UNDER_M:
                return (ANKLE_SENSORS[k], f"F_z {fz_n[k]:.0f} N while the {ANKLE_SENSORS[other]} "
                                          f"sensor reads {fz_n[other]:.0f} N, its sole "
                                          f"{below_m * 1000:.0f} mm lower (at most "
                                          f"{SOLE_UNDER_M * 1000:.0f} mm: the sole carrying the "
                                          "robot is on the floor, the other cannot be under it)",
                        "the two ankle sensors are swapped between the feet")
        return None

    def _soles_sunk(self, store: Store, wrenches: dict) -> tuple[str, str, str] | None:
        """Before a step (each sole within SOLE_STEPPED_M of its place at the start) or a bounce
        (the soles together under SOLE_IN_AIR_WEIGHTS), both soles more than SOLES_SUNK_M under
        the floor: the estimate stood the robot on a rising foot (module docstring). After
        either, never again judged (the floor there may lie elsewhere; a bounce lets the
        estimate's height float). (Scalar arithmetic: it runs every period while the robot
        stands.)"""
        T_world_soles = store.get(T_WORLD_SOLES)
        if T_world_soles is None or not self._judge_sunk:
            return None
        fz_n = [float(wrenches[sensor][2]) for sensor in ANKLE_SENSORS]
        if not fz_n[0] + fz_n[1] >= SOLE_IN_AIR_WEIGHTS * self.weight_n:
            self._judge_sunk = False
            return None
        (rx, ry, rz), (lx, ly, lz) = np.asarray(T_world_soles)[:, :3, 3].tolist()
        if self._soles_start_xy is None:
            self._soles_start_xy = (rx, ry, lx, ly)
        rx0, ry0, lx0, ly0 = self._soles_start_xy
        if not (math.hypot(rx - rx0, ry - ry0) <= SOLE_STEPPED_M
                and math.hypot(lx - lx0, ly - ly0) <= SOLE_STEPPED_M):
            self._judge_sunk = False  # (or not finite)
            return None
        if not (rz < -SOLES_SUNK_M and lz < -SOLES_SUNK_M):
            return None
        return ("right-ankle", f"F_z {fz_n[0]:.0f} N and the left-ankle sensor {fz_n[1]:.0f} N, "
                               "which stand the robot on soles "
                               f"{-rz * 1000:.1f} mm (right) and {-lz * 1000:.1f} mm (left) "
                               "under the floor it started on, before a step (at most "
                               f"{SOLES_SUNK_M * 1000:.0f} mm: the estimate stands the robot on "
                               "the sole its sensor loads, and a foot that rises as the robot "
                               "rocks carries it down)",
                "the two ankle sensors are swapped between the feet")

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

    def _wrist_start(self, state: RobotState, store: Store) -> None:
        """Sum each wrist's compensated and raw F_z over the first WRIST_START_PERIODS
        periods; at the last, fault a wrist whose compensated mean is beyond
        WRIST_START_MAX_N (module docstring)."""
        wrenches = store.get(WRENCHES)
        for k, wrist in enumerate(WRISTS):
            reading = state.ft.get(wrist)
            if wrenches is None or reading is None:
                self._wrist_sums[:, k] = np.nan  # not judged
                continue
            self._wrist_sums[0, k] += float(wrenches[wrist][2])
            self._wrist_sums[1, k] += float(np.asarray(reading, dtype=float)[2])
        if self._periods < WRIST_START_PERIODS:
            return
        compensated, raw = self._wrist_sums / WRIST_START_PERIODS
        for k, wrist in enumerate(WRISTS):
            if abs(compensated[k]) > WRIST_START_MAX_N:  # (NaN: not judged)
                tool = "the drill" if self.drill_kg is not None and wrist == "right-wrist" \
                    else "its tool"
                self._raise(f"the {wrist} force-torque sensor read {raw[k]:.1f} N along its z "
                            f"over the first {WRIST_START_PERIODS * self.period_s:.2f} s, where "
                            f"the hand and {tool} as the run declares it weigh "
                            f"{raw[k] - compensated[k]:.1f} N: {abs(compensated[k]):.1f} N apart "
                            f"(at most {WRIST_START_MAX_N:g} N) at t = {state.time_s:.2f} s",
                            hint=self._wrist_hint(wrist, compensated[k]))

    def _wrist_hint(self, wrist: str, apart_n: float) -> str:
        """What to check for a wrist reading ``apart_n`` more than its declared load (N)."""
        check = "the sensor's zero, which wrist it is wired to and the task file's [stance] tool"
        if self.drill_kg is None or wrist != "right-wrist":
            return f"check {check}, then start the run again"
        heavier = "heavier" if apart_n > 0 else "lighter"
        return (f"a drill about {abs(apart_n) / 9.80665:.2f} kg {heavier} (along the sensor's "
                f"z) than the {self.drill_kg:g} kg the run declares reads so: weigh it and give "
                "its mass in the task file's [stance] tool_mass_kg or with --set "
                f"stance.tool_mass_kg=KG; else check {check}, then start the run again")

    def _raise(self, message: str, hint: str = "", refuse: bool = False) -> None:
        self.fault = (SensorRefusal if refuse else SensorFault)(message, hint)
        raise self.fault


class _StillWindow:
    """Fresh states standing still on both loaded flat soles, summed until STILL_STATES: the IMU's
    vertical (its accelerometer's direction) and the legs' (the soles' normals through the
    joints' kinematics), both in the torso's axes, and where the torso stood on the legs."""

    def __init__(self) -> None:
        self.n = 0
        self.sums = [0.0] * 6  # the IMU's vertical (3), the legs' (3)
        self.verticals = (np.zeros(3), np.zeros(3))
        self._first = None  # the first state's T_torso_soles

    def add(self, imu_up, T_torso_soles: np.ndarray) -> float | None:
        """Add a state (the IMU's unit vertical); at the window's end, the angle between the
        mean verticals (deg), or None (not yet, or the torso moved on the legs: the window
        starts again)."""
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
        turned_rad = max(_angle_rad(first[k, :3, :3].T @ last[k, :3, :3]) for k in (0, 1))
        imu, legs = np.array(sums[:3]), np.array(sums[3:])
        imu, legs = imu / np.linalg.norm(imu), legs / np.linalg.norm(legs)
        self.__init__()
        if moved_m >= STILL_TORSO_M or turned_rad >= STILL_TURN_RAD:
            return None
        self.verticals = (imu, legs)
        return math.degrees(math.acos(min(1.0, float(imu @ legs))))


def _angle_rad(R: np.ndarray) -> float:
    """The angle of the rotation ``R`` (rad)."""
    return float(np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)))


def _roll_pitch_deg(up, digits: int | None = 1) -> tuple[float, float]:
    """The torso's roll and pitch (deg) for the world's vertical ``up`` in its axes (rounded to
    ``digits``; None: not rounded)."""
    roll = math.degrees(math.atan2(up[1], up[2]))
    pitch = math.degrees(math.atan2(-up[0], math.hypot(up[1], up[2])))
    if digits is None:
        return roll, pitch
    return round(roll, digits) + 0.0, round(pitch, digits) + 0.0  # (never "-0.0")
