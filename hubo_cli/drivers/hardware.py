"""The hardware driver (name ``hardware``): the real Hubo through hubo-ach's channels.

Every 5 ms control period (200 Hz) the driver puts one ``struct hubo_ref`` (462 bytes, see
:mod:`hubo_cli.drivers.hubo_ach`) on hubo-ach's ``hubo-ref`` channel through libach and reads
hubo-daemon's ``struct hubo_state`` from ``hubo-state``: the body IMU's tilt angles and rates
become the torso quaternion (its tilt: a_z is no heading,
:func:`~hubo_cli.drivers.hubo_ach.body_imu_quat`), the gyro and the accelerometer's specific force
(:func:`~hubo_cli.drivers.hubo_ach.accel_from_tilt`: the gravity the tilts imply), ``ft`` the
four wrenches, ``joint[].pos/vel`` the joints and ``time`` the driver's clock. It waits (up to
``state_wait_s``) for the daemon's next state each period, so the robot's own 200 Hz loop paces
the run. References are in hubo-ach joint order (``model.hubo_ach["index"]``); joints the
model does not drive (neck, waist, wrist roll, fingers) keep the position measured at start, so
nothing moves that the pipeline does not command.

Without a robot, ``sink="file"`` (``--dry-run``) writes the same 462-byte frames to
``sink_path`` (``"fifo"``: a named pipe, opened without waiting for a reader; a full pipe drops
the frame and flags ``sink-full``) and the state echoes the references through hubo-daemon's
reference filter. :func:`read_ref_frames` decodes such a file.

Start-up and safety, enforced here whatever the layers above do:

- refuses to start unless ``armed=True`` (``--arm``): :class:`~hubo_cli.errors.SafetyError`;
- :meth:`start` reads the measured posture, waits 0.8 s without sending a reference
  (hubo-ach's ``HUBO_STARTUP_SEND_REF_DELAY``; the state must keep coming meanwhile), then makes
  the posture measured at that instant the reference; a limb joint measured more than
  ``start_tolerance_rad`` outside its limits refuses the start;
- a NaN or infinite reference freezes that joint at its last good reference until
  :meth:`release_joints` (flag ``nan-ref``, joints in :attr:`frozen_joints`);
- a reference that would move a joint faster than its velocity limit (times
  ``velocity_margin``) is refused whole: servo-off latches (the last reference is held, flag
  ``servo-off``) until :meth:`reset_servo`;
- references go out in hubo-ach's mode 1 (direct) by default, or mode 0 (hubo-daemon's reference
  filter) with ``ref_mode``;
- every fresh state is checked (:mod:`hubo_cli.drivers.servo_guard`): a servo error, an
  impossible sole force or a standing robot off the ground, a motor at its maximum temperature
  latch servo-off and :meth:`step` raises the trip (exit 3); a warm motor slows its joint;
- no fresh state (a new ``hubo-state`` frame whose ``time`` advances) for ``stale_after_s``
  (:data:`STALE_AFTER_S`, 0.1 s, wall clock; a dry run's echo judges it in its own time,
  :meth:`~hubo_cli.drivers.hubo_ach_io.StateSource.clock_s`): the pipeline's commands are
  ignored from then on, the reference brakes to rest within the joints' limits and holds
  (flag ``stale-state``; ``stale-hold`` once the state comes again, which never resumes the
  motion), and
  ``stale_grace_s`` (:data:`STALE_GRACE_S`, 0.8 s) later, or at the brake's rest if later,
  :meth:`step` raises
  :class:`~hubo_cli.drivers.stale_state.StateLost` (exit 3), which ends the run (see
  :mod:`hubo_cli.drivers.stale_state`);
- fresh states that keep coming late (each one's ``time`` against this computer's clock older
  than 0.1 s for 0.1 s, :mod:`hubo_cli.drivers.state_age`) latch servo-off like the checks
  above and end the run (exit 3, :class:`~hubo_cli.drivers.state_age.StateTooOld`);
- any exception inside ends in a hold (the last reference keeps being sent, flag ``fault``,
  :attr:`fault_message`), never a crash. Malformed commands (wrong shape, unknown joint name)
  are the caller's error: refused with :class:`~hubo_cli.errors.ConfigError`, nothing sent.

``hubo_ref`` has no header, so what this driver's own frames used to carry (sequence, time,
hold/servo-off/fault bits) is reported beside it: words in ``RobotState.flags``, which the run
log records (``servo-off``, ``stopped`` for the final hold, ``fault``, ``stale-state``,
``ref-wait`` while hubo-daemon does not apply references yet), and per-period numbers declared
in :attr:`HardwareDriver.log_columns` with :meth:`HardwareDriver.log_values` (frames put, the
daemon's clock, the state's age, the round trip, the servo error, the thermal scale), summarised
by :meth:`HardwareDriver.summary_values`.
"""

from __future__ import annotations

import contextlib
import math
import time
from array import array
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hubo_cli.drivers import checks, hubo_ach
from hubo_cli.drivers.ach import DRY_RUN_HINT, load_libach
from hubo_cli.drivers.base import Driver, RunContext
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, RefFrame, StateFrame
from hubo_cli.drivers.hubo_ach_io import (
    AchRefSink,
    AchStateSource,
    EchoSource,
    FileRefSink,
    RefSink,
    StateSource,
)
from hubo_cli.drivers.servo_guard import (
    GUARD_MAX,
    ServoErrorGuard,
    SoleForceGuard,
    ThermalLimiter,
    guard_parameters,
)
from hubo_cli.drivers.stale_state import StaleStateBrake
from hubo_cli.drivers.state_age import StateAgeGuard
from hubo_cli.errors import ConfigError, DeviceError, SafetyError, quoted
from hubo_cli.model import RobotModel
from hubo_cli.posture import home_posture
from hubo_cli.state import FT_SENSORS, RobotState

SINKS = ("ach", "file", "fifo")
STALE_AFTER_S = 0.1  # no fresh state this long (the source's clock): brake and hold
# ... and this long after the brake began the run ends (exit 3): the robot is braked and never
# resumes by itself, so the grace is only how long a glitch may last before the run is given
# up; 0.8 s leaves the run's own end (log, summary, plots) room within the 1.5 s that a dead
# robot's run may take to exit after the state stopped
STALE_GRACE_S = 0.8
MODE_FILTERED, MODE_DIRECT = hubo_ach.MODE_REF_FILTER, hubo_ach.MODE_REF
REF_MODES = {"direct": MODE_DIRECT, "filtered": MODE_FILTERED}  # --ref-mode's words
REF_NAMES = {v: k for k, v in REF_MODES.items()}
SINK_FILE_NAME = "hubo-ref.bin"
# hubo-daemon's refWait set this long while references are put: the robot is not driven (the
# servo-error check cannot run meanwhile). The daemon applies references from its first
# period; the 0.8 s start-up delay without references is waited before the first is put
REF_WAIT_MAX_S = 0.5


class RefWaitError(DeviceError):
    """hubo-daemon kept refWait set: the references are not applied."""

    def __init__(self, channel: str, for_s: float, t_s: float) -> None:
        super().__init__(f"{channel} says refWait (references not applied) for {for_s:.2f} s "
                         f"at t = {t_s:.2f} s: the robot is not following; it holds its last "
                         "reference",
                         hint="check hubo-daemon (hubo-console: is it in control of the "
                              "joints?), then start the run again")


def hubo_ach_vector(model: RobotModel, q_rad, rest_rad: float = 0.0) -> np.ndarray:
    """The 42-joint hubo-ach vector of a limb posture (rad); other joints at ``rest_rad``."""
    out = np.full(JOINT_COUNT, rest_rad)
    out[[model.hubo_ach["index"][n] for n in model.joint_names]] = q_rad
    return out


def read_ref_frames(path: str | Path) -> list[RefFrame]:
    """Decode every frame of a file sink (462 bytes each).

    Raises:
        DeviceError: the file does not hold whole ``hubo_ref`` frames.
    """
    data = Path(path).read_bytes()
    if len(data) % hubo_ach.REF_SIZE:
        raise DeviceError(f"{path}: {len(data)} bytes is not a whole number of "
                          f"{hubo_ach.REF_SIZE}-byte hubo_ref frames")
    size = hubo_ach.REF_SIZE
    return [hubo_ach.decode_ref(data[k:k + size]) for k in range(0, len(data), size)]


class HardwareDriver(Driver):
    """hubo-ach driver. Options:

    Args:
        armed: must be True to start (the ``--arm`` flag).
        sink: ``"ach"`` (default: hubo-ach's channels through libach), ``"file"`` or ``"fifo"``
            (dry runs: frames to ``sink_path``, state echoed through the reference filter).
        sink_path: the file or pipe of the ``file``/``fifo`` sinks (the run scaffold puts it in
            the run folder; see :meth:`run_options`).
        ach_ref, ach_state: the channel names (hubo-ach's ``hubo-ref``, ``hubo-state``).
        ref_mode: hubo-ach mode written for every joint (or its word, ``direct`` or
            ``filtered``): 1 direct (the default, as
            hubo-motion-rt's control-daemon, which avoids the filter's 0.2 s lag) or 0
            through hubo-daemon's reference filter.
        servo_error_limit_rad: the servo-error trip (default: the robot file's
            ``[hardware_guards]``; see :mod:`hubo_cli.drivers.servo_guard`).
        velocity_margin: references faster than margin x the velocity limit trip servo-off.
        echo_sensors: the daemon's sensors are made up (``hubo hardware fake-daemon``: zero
            force, a level and still IMU), as a dry run's are: not checked
            (:attr:`sensors_measured`), and the force stops cannot act.
        stale_after_s: wall time without a fresh state before the driver brakes and holds.
        stale_grace_s: how long after the brake began the run ends (:class:`StateLost`).
        state_wait_s: how long each period waits for the daemon's next state (default 1.5
            periods).
        start_timeout_s: how long :meth:`start` waits for the first state.
        start_tolerance_rad: how far outside its limits a joint may be measured at start.
        clock: wall-clock time source (s) for the state's age and the round trip, and for the
            stale-state brake; injectable for tests. Default: ``time.monotonic``, the brake
            on the source's own clock (a dry run's echo: its own time).
    """

    name = "hardware"
    real_time = True
    log_columns = ("hw_ref_seq", "hw_state_time_s", "hw_state_age_periods", "hw_ref_mode",
                   "hw_state_age_ms", "hw_round_trip_ms", "hw_servo_error_rad",
                   "hw_thermal_scale", "hw_max_motor_temp_c")
    # what its sensors are (the driver contract's facts: Driver's Attributes), together
    accel_measured = False  # hubo-ach's body IMU reports tilt: accel_from_tilt reads rest

    @property
    def sensors_measured(self) -> bool:
        """The robot's sensors through hubo-ach; a dry run's echo reads no force and a level,
        still IMU (:mod:`hubo_cli.estimation.plausibility` cannot check it, and the force
        stops never see a force there): a property, its answer depends on how the driver was
        opened."""
        return self.sink_kind == "ach" and not self.echo_sensors

    def __init__(self, model: RobotModel, armed: bool = False, sink: str = "ach",
                 sink_path: str | Path | None = None, ach_ref: str = hubo_ach.CHAN_REF,
                 ach_state: str = hubo_ach.CHAN_STATE, ref_mode: int = MODE_DIRECT,
                 servo_error_limit_rad: float | None = None,
                 velocity_margin: float = 1.02, stale_after_s: float = STALE_AFTER_S,
                 stale_grace_s: float = STALE_GRACE_S, state_wait_s: float | None = None,
                 start_timeout_s: float = 1.0, start_tolerance_rad: float = 0.02,
                 echo_sensors: bool = False,
                 clock: Callable[[], float] | None = None) -> None:
        super().__init__(model)
        self.echo_sensors = bool(echo_sensors)
        if sink not in SINKS:
            raise ConfigError(f"unknown sink {quoted(sink)}", hint=f"use one of {', '.join(SINKS)}")
        if sink != "ach" and sink_path is None:
            raise ConfigError(f"the {sink} sink needs sink_path",
                              hint="give the file's path (the run folder's hubo-ref.bin)")
        ref_mode = REF_MODES.get(ref_mode, ref_mode)
        if ref_mode not in (MODE_FILTERED, MODE_DIRECT):
            raise ConfigError(f"unsupported hubo-ach mode {ref_mode}",
                              hint="use 1 (direct) or 0 (filtered)")
        if not (stale_after_s > 0 and stale_grace_s >= 0 and start_timeout_s > 0
                and velocity_margin >= 1.0):
            raise ConfigError("stale_after_s and start_timeout_s must be > 0, stale_grace_s "
                              ">= 0 and velocity_margin >= 1")
        for channel in (ach_ref, ach_state):
            if not channel or "/" in channel or len(channel) > 63:
                raise ConfigError(f"bad ach channel name {quoted(channel)}",
                                  hint="1 to 63 characters, no '/'")
        self.armed = bool(armed)
        self.sink_kind = sink
        self.sink_path = Path(sink_path) if sink_path is not None else None
        self.ach_ref, self.ach_state = ach_ref, ach_state
        self.ref_mode = int(ref_mode)
        self.velocity_margin = float(velocity_margin)
        self.state_wait_s = 1.5 * self.period_s if state_wait_s is None else float(state_wait_s)
        self.start_timeout_s = float(start_timeout_s)
        self.start_tolerance_rad = float(start_tolerance_rad)
        ach = model.hubo_ach
        self.ach_index = np.array([ach["index"][n] for n in self.joint_names])
        self.startup_delay_s = float(ach["startup_ref_delay_s"])
        self.filter_length = int(ach["ref_filter_length"])
        self.sink: RefSink | None = None
        self.frozen_joints: set[str] = set()
        self.servo_off = False
        self.fault_message = ""
        self._seq = 0
        self._ref42 = np.zeros(JOINT_COUNT)
        self._cmd = np.zeros(len(self.joint_names))
        self._state: RobotState | None = None
        self._frame: StateFrame | None = None
        self._t0 = 0.0
        self._flags: list[str] = []
        self._stale = 0  # periods since the last fresh state (logged)
        self.source: StateSource | None = None
        self.stale = StaleStateBrake(model, self.period_s, float(stale_after_s),
                                     float(stale_grace_s), clock or self._source_clock_s)
        guards = guard_parameters(model)
        if servo_error_limit_rad is not None:
            most = GUARD_MAX["servo_error_limit_rad"]
            if not 0 < servo_error_limit_rad <= most:
                raise ConfigError(f"servo_error_limit_rad {servo_error_limit_rad} must be > 0 "
                                  f"and at most {most:g}")
            guards["servo_error_limit_rad"] = float(servo_error_limit_rad)
        self.servo_guard = ServoErrorGuard(self.joint_names, self.ach_index,
                                           guards["servo_error_limit_rad"],
                                           int(guards["servo_error_window_periods"]),
                                           self.filter_length)
        self.sole_guard = SoleForceGuard(guards["sole_force_max_n"],
                                         guards["sole_standing_min_n"],
                                         guards["sole_unloaded_n"],
                                         guards["sole_unloaded_grace_s"],
                                         int(guards["sole_force_window_periods"]))
        self.state_age = StateAgeGuard(ach_state)
        self.thermal = ThermalLimiter(self.joint_names, self.ach_index,
                                      guards["motor_warning_temperature_c"],
                                      guards["motor_max_temperature_c"])
        self.clock = clock or time.monotonic
        self.trip: Exception | None = None  # a guard's DeviceError: the run ends with it
        self._put_s: float | None = None  # wall time of the last put not yet answered
        self._round_trip_s = float("nan")
        self._ages_s = array("d")  # per period (8 bytes each: an hour is 5.8 MB)
        self._round_trips_s = array("d")
        self._max_servo_error_rad = 0.0
        self._thermal_periods = 0
        self._sent = (self._cmd,) * 3  # the last three references put, oldest first
        self._stopped = False
        self._closed = False

    @classmethod
    def run_options(cls, run: RunContext) -> dict:
        """The file sink's path in the run folder (used only by the ``file``/``fifo`` sinks)."""
        return {"sink_path": Path(run.run_dir) / SINK_FILE_NAME}

    # ------------------------------------------------------------------ life cycle
    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Arm check, open the channels, wait out the 0.8 s without references.

        ``q0_rad`` is the posture a dry run starts in (home by default); on the robot the
        measured posture is used. Returns the state at t = 0.8 s.

        Raises:
            SafetyError: not armed, or a joint measured outside its limits.
            DeviceError: libach missing, a channel missing, no state from the daemon.
        """
        if not self.armed:
            raise SafetyError(
                "the hardware driver is not armed: it would send references to the real robot",
                hint="check the robot is hanging or standing safely, then pass --arm")
        if self._closed:
            raise DeviceError("the hardware driver is closed", hint="create a new driver")
        q0 = home_posture(self.model) if q0_rad is None else np.asarray(q0_rad, dtype=float)
        if q0.shape != (len(self.joint_names),) or not np.all(np.isfinite(q0)):
            raise ConfigError(f"start posture must be {len(self.joint_names)} finite angles")
        pos0 = np.zeros(JOINT_COUNT)
        pos0[self.ach_index] = np.clip(q0, self.model.lower_rad, self.model.upper_rad)
        self._open_io()
        self._reset()
        frame = self.source.open(pos0)
        if frame is None:
            raise DeviceError(f"no {self.ach_state} frame within {self.start_timeout_s:g} s",
                              hint="is hubo-daemon (hubo-ach) running and publishing?")
        self._take(frame)
        if self.trip is not None:  # a sole or a motor out of bounds: nothing moved
            raise self.trip
        self._t0 = frame.time_s
        self._ref42 = frame.pos_rad.copy()
        for _ in range(int(round(self.startup_delay_s / self.period_s))):
            self._read(self.source.advance(self._ref42, self._modes()))
            if self.trip is not None:  # a sole or a motor out of bounds: nothing moved
                raise self.trip
        if self.stale.age_s >= self.stale.after_s:
            raise DeviceError(f"{self.ach_state} stopped updating during the start-up delay",
                              hint="is hubo-daemon (hubo-ach) running?")
        self._ref42 = self._frame.pos_rad.copy()  # the posture measured now is the reference
        self._check_start_posture()
        self.servo_guard.reset(self._ref42)
        self._cmd = np.clip(self._ref42[self.ach_index], self.model.lower_rad,
                            self.model.upper_rad)
        self._ref42[self.ach_index] = self._cmd
        self._sent = (self._cmd,) * 3
        self._flags = []
        self._state = self._make_state()
        return self._state

    def _open_io(self) -> None:
        if self.sink is not None:
            return
        if self.sink_kind == "ach":
            lib = load_libach(DRY_RUN_HINT)
            self.sink = AchRefSink(lib, self.ach_ref)
            try:
                self.source = AchStateSource(lib, self.ach_state, self.state_wait_s,
                                             self.start_timeout_s)
            except Exception:
                self.sink.close()
                self.sink = None
                raise
        else:
            self.sink = FileRefSink(self.sink_path, fifo=self.sink_kind == "fifo")
            self.source = EchoSource(self.period_s, self.filter_length)

    def _reset(self) -> None:
        self._seq = 0
        self._stale = 0
        self.stale.reset()
        self._stopped = False
        self.servo_off = False
        self.fault_message = ""
        self.frozen_joints = set()
        self.trip = None
        self.sole_guard.reset()
        self.thermal.reset()
        self._put_s = None
        self._ages_s, self._round_trips_s = array("d"), array("d")
        self._max_servo_error_rad = 0.0
        self._thermal_periods = 0
        self._ref_wait_since_s: float | None = None

    def _check_start_posture(self) -> None:
        q = self._ref42[self.ach_index]
        below = self.model.lower_rad - q
        above = q - self.model.upper_rad
        outside = np.flatnonzero(np.maximum(below, above) > self.start_tolerance_rad)
        if outside.size:
            i = int(outside[0])
            raise SafetyError(
                f"{self.joint_names[i]} is measured at {q[i]:+.3f} rad, outside its limits "
                f"[{self.model.lower_rad[i]:+.3f}, {self.model.upper_rad[i]:+.3f}]",
                hint="bring the joint into range (hubo-console) before starting")

    def read(self) -> RobotState:
        """The state at the end of the last period."""
        self._require_started()
        return self._state

    def send(self, q_cmd_rad) -> np.ndarray:
        """Check and accept a reference (put on ``hubo-ref`` at the next :meth:`step`).

        Returns the reference actually held for the 24 limb joints (rad)."""
        self._require_started()
        q = self.full_command(self._cmd, q_cmd_rad)
        try:
            self._accept(q)
        except Exception as exc:  # any internal failure ends in a hold
            self._enter_fault(exc)
        return self._cmd.copy()

    def _accept(self, q: np.ndarray) -> None:
        if self._stopped or self.fault_message:
            self._flags.append("stopped" if self._stopped else "fault")
            return
        if self.stale.holding:  # braking or held after stale state: commands ignored
            if self._braking():
                self._hold(self.stale.advance())
            return
        if self.servo_off:
            self._flags.append("servo-off")
            return
        q, flags, frozen = checks.sanitize_command(self.model, self._cmd, q)
        self._flags += flags
        for i in np.flatnonzero(frozen):
            self.frozen_joints.add(self.joint_names[i])
        if self.frozen_joints:
            held = [self.joint_names.index(n) for n in self.frozen_joints]
            q[held] = self._cmd[held]
            self._flags.append(checks.NAN_REF)
        if self.thermal.limiting:  # hot motors: their joints slowed (to a stop at the maximum)
            step = self.thermal.scale * self.model.velocity_rad_s * self.period_s
            q = self._cmd + np.clip(q - self._cmd, -step, step)
            self._flags.append("thermal")
        speed = np.abs(q - self._cmd) / self.period_s
        limit = self.model.velocity_rad_s * self.velocity_margin
        if np.any(speed > limit):
            self.servo_off = True
            self._flags.append("servo-off")
            return
        self._cmd = q
        self._ref42[self.ach_index] = q

    def step(self) -> RobotState:
        """Put this period's reference, then read the daemon's next state.

        Raises:
            StateLost: ``stale_grace_s`` after a stale state began the brake (the brake's
                hold reference has been put; :meth:`stop` puts it once more).
            ServoError, SoleForceError, MotorTooHot: a check of the measured state tripped
                (:mod:`hubo_cli.drivers.servo_guard`); servo-off holds the last reference.
        """
        self._require_started()
        try:
            if self._braking() and not self.stale.advanced:  # no send() this period
                self._hold(self.stale.advance())
            self.stale.advanced = False
            self._put()
            self._sent = (*self._sent[1:], self._cmd)
            self._read(self.source.advance(self._ref42, self._modes()))
            self.stale.watch(self._frame.time_s - self._t0, self._sent)
            self._time_state()
        except Exception as exc:  # any internal failure ends in a hold
            self._enter_fault(exc)
        self._state = self._make_state()
        if self.trip is not None:
            raise self.trip
        lost = self.stale.lost(self.ach_state, self._braking())
        if lost is not None:
            raise lost
        return self._state

    def stop(self) -> None:
        """Hold the last reference (put it once more; the daemon keeps it); never raises."""
        if self._closed or self._stopped:
            self._stopped = True
            return
        self._stopped = True
        with contextlib.suppress(Exception):
            if self._state is not None:
                self._put()

    def close(self) -> None:
        """Close the channels or file. Safe to call twice."""
        self._stopped = True
        for part in (self.sink, self.source):
            if part is not None:
                with contextlib.suppress(Exception):
                    part.close()
        self._closed = True

    # ------------------------------------------------------------------ operator actions
    def release_joints(self) -> None:
        """Unfreeze the joints frozen by NaN references (their reference stays where it was)."""
        self.frozen_joints = set()

    def reset_servo(self) -> None:
        """Clear a latched servo-off (after the operator has checked the robot)."""
        self.servo_off = False

    # ------------------------------------------------------------------ log
    def log_values(self) -> dict[str, float]:
        """This period's values of :attr:`log_columns`: frames put so far, the daemon's time of
        the newest state (s), how many periods ago it arrived, the hubo-ach mode, the state's
        age (now minus its ``time``, ms; NaN for a simulated clock), the time from putting
        this period's reference to reading the next fresh state (ms; NaN without one), the
        largest servo error (rad), the smallest thermal velocity scale and the hottest limb
        motor's temperature (degrees C; NaN before a state; the soles' forces are the log's
        ``*_foot_fz_n``)."""
        frame = self._frame
        time_s = frame.time_s if frame is not None else float("nan")
        ages = self._ages_s[-1:] if self._ages_s else [float("nan")]
        return {"hw_ref_seq": float(self._seq), "hw_state_time_s": time_s,
                "hw_state_age_periods": float(self._stale), "hw_ref_mode": float(self.ref_mode),
                "hw_state_age_ms": 1e3 * ages[0], "hw_round_trip_ms": 1e3 * self._round_trip_s,
                "hw_servo_error_rad": float(np.max(self.servo_guard.error_rad)),
                "hw_thermal_scale": float(np.min(self.thermal.scale)),
                "hw_max_motor_temp_c": float(np.max(self.thermal.temperature_c))}

    def summary_values(self) -> dict[str, object]:
        """The run's hubo-ach mode, the state's age and the reference-to-state round trip
        (median, p99, max in ms; None without a measure), whether the state's age was judged
        (``hw_state_age_checked``: False on a simulated clock; ``hw_state_age_baseline_ms``: the
        smallest recent age it is judged against, :mod:`hubo_cli.drivers.state_age`), the
        largest servo error (rad), the periods slowed by hot motors, the hottest motor (joint
        and degrees C; None without a temperature), the trip that ended the run (if any) and
        whether the daemon's sensors were judged (``hw_sensors_checked``: False on a dry run
        or with ``--echo-sensors``, whose warning ``--json`` leaves out: the sensor checks
        were off and the force stops read no force)."""
        def stats(values_s: array) -> dict[str, float | None]:
            x = np.frombuffer(values_s, dtype=float) * 1e3
            x = x[np.isfinite(x)]
            if not x.size:
                return {"median": None, "p99": None, "max": None}
            return {"median": round(float(np.median(x)), 3),
                    "p99": round(float(np.percentile(x, 99)), 3), "max": round(float(x.max()), 3)}

        return {"hw_ref_mode": REF_NAMES[self.ref_mode],
                "hw_state_age_ms": stats(self._ages_s),
                "hw_state_age_checked": bool(self.state_age.judged),
                "hw_state_age_baseline_ms": (round(1e3 * self.state_age.baseline_s, 3)
                                             if math.isfinite(self.state_age.baseline_s)
                                             else None),
                "hw_round_trip_ms": stats(self._round_trips_s),
                "hw_max_servo_error_rad": round(self._max_servo_error_rad, 4),
                "hw_thermal_limited_periods": self._thermal_periods,
                "hw_hottest_motor": self._hottest_motor(),
                "hw_trip": None if self.trip is None else type(self.trip).__name__,
                "hw_sensors_checked": bool(self.sensors_measured)}

    def _hottest_motor(self) -> dict | None:
        """The run's hottest motor: joint and degrees C (None: unreadable, NaN in the state)."""
        joint, temperature_c = self.thermal.hottest
        if joint is None:
            return None
        return {"joint": joint, "temperature_c": (round(temperature_c, 2)
                                                  if np.isfinite(temperature_c) else None)}

    # ------------------------------------------------------------------ internals
    def _require_started(self) -> None:
        if self._closed:
            raise DeviceError("the hardware driver is closed", hint="create a new driver")
        if self._state is None:
            raise DeviceError("the hardware driver has not been started",
                              hint=checks.NOT_STARTED_HINT)

    def _modes(self) -> np.ndarray:
        return np.full(JOINT_COUNT, self.ref_mode, dtype=np.int16)

    def _put(self) -> None:
        frame = hubo_ach.encode_ref(self._ref42, self._modes(), np.zeros(JOINT_COUNT, np.int8))
        if self.sink.put(frame):
            self._seq += 1
            self.servo_guard.sent(self._ref42, self._modes())
            if self._put_s is None:
                self._put_s = self.clock()
        else:
            self._flags.append("sink-full")

    def _read(self, frame: StateFrame | None) -> None:
        if frame is None or (self._frame is not None and frame.time_s <= self._frame.time_s):
            self._stale += 1  # nothing new, or a frame whose clock did not advance
            return
        self._take(frame)

    def _source_clock_s(self) -> float:
        """The clock a state's freshness is judged by: the source's (wall time before one)."""
        return time.monotonic() if self.source is None else self.source.clock_s()

    def _braking(self) -> bool:
        """The stale-state brake still moves the reference (not after a stop or a fault)."""
        return self.stale.braking and not self._stopped and not self.fault_message

    def _hold(self, q: np.ndarray) -> None:
        """Make ``q`` (the brake's) the reference."""
        if np.all(np.isfinite(q)):
            self._cmd = q
            self._ref42[self.ach_index] = q

    def _take(self, frame: StateFrame) -> None:
        t_s = frame.time_s - self._t0 if self._frame is not None else 0.0
        self._guard(self.sole_guard.check(frame.ft_mx_my_fz, t_s), "sole-force")
        if self.trip is not None:
            return  # the run ends with the sole's trip: the frame is not taken
        values = np.concatenate([frame.pos_rad, frame.vel_rad_s, frame.imu_tilt_rad,
                                 frame.imu_rate_rad_s, frame.ft_mx_my_fz.ravel(), [frame.time_s]])
        if not np.isfinite(values).all():
            raise DeviceError(f"{self.ach_state} sent a non-finite value")
        self._stale = 0
        self.stale.fresh()
        self._frame = frame
        if self._put_s is not None:  # the first fresh state after a reference was put
            self._round_trip_s = self.clock() - self._put_s
            self._round_trips_s.append(self._round_trip_s)
            self._put_s = None
        self._guard(self.thermal.check(frame.tmp_c, t_s), "motor-hot")
        if self._seq and not frame.ref_wait:  # references are being applied: they must hold
            self._ref_wait_since_s = None
            self._guard(self.servo_guard.check(frame.pos_rad, t_s), "servo-error")
            self._max_servo_error_rad = max(self._max_servo_error_rad,
                                            float(np.max(self.servo_guard.error_rad)))
        elif self._seq:  # the daemon does not apply them: for REF_WAIT_MAX_S at most
            if self._ref_wait_since_s is None:
                self._ref_wait_since_s = t_s
            elif t_s - self._ref_wait_since_s > REF_WAIT_MAX_S:
                self._guard(RefWaitError(self.ach_state, t_s - self._ref_wait_since_s, t_s),
                            "ref-wait")

    def _guard(self, trip: Exception | None, flag: str) -> None:
        """A check's trip latches servo-off (the last reference held) and ends the run."""
        if trip is not None and self.trip is None:
            self.trip = trip
            self.servo_off = True
            self._flags.append(flag)

    def _time_state(self) -> None:
        """This period's state age (wall clock minus the state's time, s) and round trip."""
        if self._put_s is not None:  # no fresh state answered this period's reference
            self._round_trip_s = float("nan")
        if self.source.wall_clock:
            age_s = self.clock() - self._frame.time_s
            self._ages_s.append(age_s)
            if self._stale == 0:  # a fresh state this period: is it late? (exit 3)
                self._guard(self.state_age.check(age_s, self._frame.time_s - self._t0),
                            "state-late")
        if self.thermal.limiting:
            self._thermal_periods += 1

    def _enter_fault(self, exc: Exception) -> None:
        self.fault_message = f"{type(exc).__name__}: {exc}"
        self._flags.append("fault")
        with contextlib.suppress(Exception):
            self._put()

    def _make_state(self) -> RobotState:
        frame = self._frame
        ft = {}
        for k, sensor in enumerate(FT_SENSORS):
            # hubo-ach's hubo_ft_t (order R hand, L hand, R foot, L foot) is the three axes a
            # Hubo sensor measures in its own frame: f_z along its axis (a wrist's along the
            # forearm), m_x and m_y across it. RobotState.ft is in the sensors' own frames
            # (state.T_frame_sensor), so they go where they are: both of a wrist's bending
            # moments reach the wrist stop (|m_x, m_y| of the estimate's compensated wrench;
            # read as the hand's axes before, the stop took |m_y, m_z| = |m_y| and missed m_x)
            mx, my, fz = frame.ft_mx_my_fz[k]
            ft[sensor] = np.array([0.0, 0.0, fz, mx, my, 0.0])
        flags = list(dict.fromkeys(self._flags))
        self._flags = []
        for latched, name in ((self.servo_off, "servo-off"), (bool(self.frozen_joints), "nan-ref"),
                              (bool(self.fault_message), "fault"), (self._stopped, "stopped"),
                              (frame.ref_wait, "ref-wait")):
            if latched and name not in flags:
                flags.append(name)
        flags += self.stale.flags()
        return RobotState(time_s=frame.time_s - self._t0, q_rad=frame.pos_rad[self.ach_index],
                          dq_rad_s=frame.vel_rad_s[self.ach_index],
                          imu_quat_wxyz=hubo_ach.body_imu_quat(frame.imu_tilt_rad),
                          imu_gyro_rad_s=frame.imu_rate_rad_s.copy(),
                          imu_accel_m_s2=hubo_ach.accel_from_tilt(frame.imu_tilt_rad), ft=ft,
                          flags=tuple(flags))

