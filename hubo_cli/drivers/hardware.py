"""The hardware driver (name ``hardware``): the real robot's hubo-ach interface, dry-runnable.

Every 5 ms control period (200 Hz) the driver writes one *reference frame* to a sink that a
bridge process forwards to hubo-ach's ``hubo-ref`` channel, and reads the robot's state from a
source. No robot is attached here, so the default source is an internal echo of the references
through hubo-ach's reference filter (mode 0: f <- (f (L - 1) + r) / L, L = 40), which lets the
whole stack be dry-run.

Sink (``run_dir/hubo-ref.bin``; ``sink="fifo"`` makes it a named pipe, opened without waiting
for a reader; a full pipe drops the frame and flags ``sink-full``). Fixed-size little-endian
binary frames, struct ``<4sIQdI42d42h42b`` (490 bytes, see :data:`REF_FRAME`):

    magic b"HREF" | version u32 (1) | seq u64 | time_s f64 | flags u32 |
    ref[42] f64 (rad) | mode[42] i16 | comply[42] i8

in hubo-ach joint order (``model.hubo_ach["index"]``; joints the model does not drive keep their
start position). mode: 0 filtered (default), 1 direct. flags: bit 0 servo-off requested, bit 1
hold (driver stopped), bit 2 driver fault. :func:`read_ref_frames` decodes a sink file.

State source (``state_source="echo"`` or the path of a file/FIFO a bridge writes): frames
``<4sIQd4d3d12d42d`` (512 bytes, see :data:`STATE_FRAME`):

    magic b"HSTA" | version u32 (1) | seq u64 | time_s f64 | imu quaternion w x y z |
    gyro x y z (rad/s, torso frame) | ft[4] (mx, my, fz) for R hand, L hand, R foot, L foot |
    pos[42] (rad)

The latest complete frame wins; no new frame for ``stale_periods`` periods flags
``stale-state`` (the last state is kept).

Start-up and safety, enforced here whatever the layers above do:
- refuses to start unless ``armed=True`` (``--arm``): :class:`~hubo_cli.errors.SafetyError`;
- :meth:`start` reads the measured posture, makes it the reference and sends no reference for
  the first 0.8 s (hubo-ach's ``HUBO_STARTUP_SEND_REF_DELAY``); it returns at t = 0.8 s;
- a NaN or infinite reference freezes that joint at its last good reference until
  :meth:`release_joints` (flag ``nan-ref``, joints in :attr:`frozen_joints`);
- a reference that would move a joint faster than its velocity limit (times
  ``velocity_margin``, 1.02 by default, room for rounding in the trajectory generator) is refused
  whole: the driver latches servo-off (frames keep the last reference with flags bit 0 set,
  state flag ``servo-off``) until :meth:`reset_servo`;
- any exception inside ends in a hold (last reference kept, flag ``fault``,
  :attr:`fault_message`), never a crash. Malformed commands (wrong shape, unknown joint name)
  are the caller's error: refused with :class:`~hubo_cli.errors.ConfigError`, nothing sent.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.drivers import checks
from hubo_cli.drivers.base import Driver, RunContext
from hubo_cli.errors import ConfigError, DeviceError, SafetyError
from hubo_cli.model import RobotModel
from hubo_cli.posture import home_posture
from hubo_cli.state import FT_SENSORS, RobotState

JOINT_COUNT = 42
REF_FRAME = struct.Struct("<4sIQdI42d42h42b")
STATE_FRAME = struct.Struct("<4sIQd4d3d12d42d")
REF_MAGIC, STATE_MAGIC, VERSION = b"HREF", b"HSTA", 1
FLAG_SERVO_OFF, FLAG_HOLD, FLAG_FAULT = 1, 2, 4
MODE_FILTERED, MODE_DIRECT = 0, 1


@dataclass
class RefFrame:
    """One decoded reference frame (see the module docstring)."""

    seq: int
    time_s: float
    flags: int
    ref_rad: np.ndarray
    mode: np.ndarray
    comply: np.ndarray


def encode_ref_frame(seq: int, time_s: float, flags: int, ref_rad, mode, comply) -> bytes:
    """Pack one reference frame."""
    return REF_FRAME.pack(REF_MAGIC, VERSION, seq, time_s, flags, *ref_rad, *mode, *comply)


def read_ref_frames(path: str | Path) -> list[RefFrame]:
    """Decode every complete reference frame of a sink file."""
    data = Path(path).read_bytes()
    frames = []
    for k in range(len(data) // REF_FRAME.size):
        fields = REF_FRAME.unpack_from(data, k * REF_FRAME.size)
        if fields[0] != REF_MAGIC or fields[1] != VERSION:
            raise DeviceError(f"{path}: frame {k} is not a version-{VERSION} reference frame")
        n = JOINT_COUNT
        frames.append(RefFrame(fields[2], fields[3], fields[4], np.array(fields[5:5 + n]),
                               np.array(fields[5 + n:5 + 2 * n]), np.array(fields[5 + 2 * n:])))
    return frames


def encode_state_frame(seq: int, time_s: float, quat_wxyz, gyro_rad_s, ft_mx_my_fz,
                       pos_rad) -> bytes:
    """Pack one state frame (what a bridge writes; used by tests and simulators)."""
    return STATE_FRAME.pack(STATE_MAGIC, VERSION, seq, time_s, *quat_wxyz, *gyro_rad_s,
                            *np.ravel(ft_mx_my_fz), *pos_rad)


@dataclass
class StateFrame:
    """The part of hubo-ach's state this driver uses (SI units, hubo-ach joint order)."""

    time_s: float
    quat_wxyz: np.ndarray
    gyro_rad_s: np.ndarray
    ft_mx_my_fz: np.ndarray  # 4 x 3: R hand, L hand, R foot, L foot
    pos_rad: np.ndarray


class EchoSource:
    """The default state source: hubo-ach's reference filter applied to the references."""

    def __init__(self, filter_length: int) -> None:
        self.filter_length = filter_length
        self._pos = np.zeros(JOINT_COUNT)
        self._t = 0.0

    def start(self, pos0_rad: np.ndarray) -> None:
        self._pos = np.array(pos0_rad, dtype=float)
        self._t = 0.0

    def feed(self, ref_rad: np.ndarray, mode: np.ndarray, dt_s: float) -> None:
        """One period of the daemon: filtered joints lag, direct joints follow."""
        L = self.filter_length
        filtered = (self._pos * (L - 1) + ref_rad) / L
        self._pos = np.where(mode == MODE_DIRECT, ref_rad, filtered)
        self._t += dt_s

    def poll(self) -> StateFrame | None:
        return StateFrame(self._t, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3),
                          np.zeros((4, 3)), self._pos.copy())

    def close(self) -> None:
        """Nothing to release."""


class StreamSource:
    """State frames read without blocking from a file or named pipe a bridge writes."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._fd = -1
        self._buffer = b""

    def start(self, pos0_rad: np.ndarray) -> None:
        try:
            self._fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError as exc:
            raise DeviceError(f"cannot open the state source {self.path}: {exc.strerror}",
                              hint="start the bridge first or use state_source='echo'") from None

    def feed(self, ref_rad: np.ndarray, mode: np.ndarray, dt_s: float) -> None:
        """The real robot moves by itself; nothing to simulate."""

    def poll(self) -> StateFrame | None:
        """The newest complete frame since the last poll, or None."""
        while True:
            try:
                chunk = os.read(self._fd, 65536)
            except BlockingIOError:
                break
            if not chunk:
                break
            self._buffer += chunk
        n = len(self._buffer) // STATE_FRAME.size
        if n == 0:
            return None
        start = (n - 1) * STATE_FRAME.size
        fields = STATE_FRAME.unpack_from(self._buffer, start)
        self._buffer = self._buffer[n * STATE_FRAME.size:]
        if fields[0] != STATE_MAGIC or fields[1] != VERSION:
            raise DeviceError(f"{self.path}: not a version-{VERSION} state frame")
        return StateFrame(fields[3], np.array(fields[4:8]), np.array(fields[8:11]),
                          np.array(fields[11:23]).reshape(4, 3), np.array(fields[23:65]))

    def close(self) -> None:
        if self._fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = -1


class HardwareDriver(Driver):
    """hubo-ach style driver. Options:

    Args:
        armed: must be True to start (the ``--arm`` flag).
        run_dir: folder for the sink (default: a new run folder ``runs/<time>-hardware``).
        sink: ``"file"`` (default) or ``"fifo"`` (named pipe).
        state_source: ``"echo"`` (default) or the path of a state-frame file/FIFO.
        ref_mode: hubo-ach mode written for every joint (0 filtered, 1 direct).
        velocity_margin: references faster than margin x the velocity limit trip servo-off.
        stale_periods: periods without a new state frame before ``stale-state`` is flagged.
    """

    name = "hardware"
    real_time = True

    @classmethod
    def run_options(cls, run: RunContext) -> dict:
        """The reference sink (and its files) live in the run folder."""
        return {"run_dir": Path(run.run_dir)}

    def __init__(self, model: RobotModel, armed: bool = False, run_dir: str | Path | None = None,
                 sink: str = "file", state_source: str | Path = "echo",
                 ref_mode: int = MODE_FILTERED, velocity_margin: float = 1.02,
                 stale_periods: int = 20) -> None:
        super().__init__(model)
        if sink not in ("file", "fifo"):
            raise ConfigError(f"unknown sink {sink!r}", hint="use 'file' or 'fifo'")
        if ref_mode not in (MODE_FILTERED, MODE_DIRECT):
            raise ConfigError(f"unsupported hubo-ach mode {ref_mode}", hint="use 0 or 1")
        self.armed = bool(armed)
        self.run_dir = Path(run_dir) if run_dir is not None else None
        self.sink_kind = sink
        self.ref_mode = int(ref_mode)
        self.velocity_margin = float(velocity_margin)
        self.stale_periods = int(stale_periods)
        ach = model.hubo_ach
        self.ach_index = np.array([ach["index"][n] for n in self.joint_names])
        self.startup_delay_s = float(ach["startup_ref_delay_s"])
        L = int(ach["ref_filter_length"])
        self.source = EchoSource(L) if str(state_source) == "echo" else StreamSource(
            Path(state_source))
        self.sink_path: Path | None = None
        self.frozen_joints: set[str] = set()
        self.servo_off = False
        self.fault_message = ""
        self._fd = -1
        self._seq = 0
        self._t = 0.0
        self._ref42 = np.zeros(JOINT_COUNT)
        self._cmd = np.zeros(len(self.joint_names))
        self._state: RobotState | None = None
        self._frame: StateFrame | None = None
        self._q_prev = np.zeros(len(self.joint_names))
        self._flags: list[str] = []
        self._stale = 0
        self._stopped = False
        self._closed = False

    # ------------------------------------------------------------------ life cycle
    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Arm check, open the sink and source, wait out the 0.8 s without references.

        ``q0_rad`` is the posture the echo source starts in (home by default); with a real
        source the measured posture is used. Returns the state at t = 0.8 s.
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
        self._open_sink()
        self.source.start(pos0)
        self._t = 0.0
        self._seq = 0
        self._stopped = False
        self.servo_off = False
        self.frozen_joints = set()
        self._frame = None
        self._read_source()
        if self._frame is None:  # a real source that has not written yet: wait in the loop
            self._frame = StateFrame(0.0, np.array([1.0, 0, 0, 0]), np.zeros(3),
                                     np.zeros((4, 3)), pos0)
        self._ref42 = self._frame.pos_rad.copy()
        self._cmd = self._ref42[self.ach_index].copy()
        self._q_prev = self._cmd.copy()
        for _ in range(int(round(self.startup_delay_s / self.period_s))):
            self._t += self.period_s
            self.source.feed(self._ref42, self._modes(), self.period_s)
            self._read_source()
        self._flags = []
        self._state = self._make_state()
        return self._state

    def _open_sink(self) -> None:
        if self._fd >= 0:
            return
        if self.run_dir is None:
            from hubo_cli.runs import make_run_dir

            self.run_dir = make_run_dir("hardware")
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.sink_path = self.run_dir / "hubo-ref.bin"
        try:
            if self.sink_kind == "fifo":
                if self.sink_path.exists() and not stat.S_ISFIFO(self.sink_path.stat().st_mode):
                    self.sink_path.unlink()
                if not self.sink_path.exists():
                    os.mkfifo(self.sink_path)
                # read-write so that opening never waits for a reader
                self._fd = os.open(self.sink_path, os.O_RDWR | os.O_NONBLOCK)
            else:
                self._fd = os.open(self.sink_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        except OSError as exc:
            raise DeviceError(f"cannot open the reference sink {self.sink_path}: {exc.strerror}",
                              hint="check the run folder is writable") from None

    def read(self) -> RobotState:
        """The state at the end of the last period."""
        self._require_started()
        return self._state

    def send(self, q_cmd_rad) -> np.ndarray:
        """Check and accept a reference (written to the sink at the next :meth:`step`).

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
        speed = np.abs(q - self._cmd) / self.period_s
        limit = self.model.velocity_rad_s * self.velocity_margin
        if np.any(speed > limit):
            self.servo_off = True
            self._flags.append("servo-off")
            return
        self._cmd = q
        self._ref42[self.ach_index] = q

    def step(self) -> RobotState:
        """Write this period's reference frame, advance the source, read the state."""
        self._require_started()
        try:
            self._t += self.period_s
            self._write_frame()
            self.source.feed(self._ref42, self._modes(), self.period_s)
            self._read_source()
        except Exception as exc:  # any internal failure ends in a hold
            self._enter_fault(exc)
        self._state = self._make_state()
        return self._state

    def stop(self) -> None:
        """Hold the last reference (one frame with the hold bit); never raises."""
        if self._closed or self._stopped:
            self._stopped = True
            return
        self._stopped = True
        with contextlib.suppress(Exception):
            if self._state is not None:
                self._write_frame()

    def close(self) -> None:
        """Close the sink and the source. Safe to call twice."""
        self._stopped = True
        if self._fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = -1
        with contextlib.suppress(Exception):
            self.source.close()
        self._closed = True

    # ------------------------------------------------------------------ operator actions
    def release_joints(self) -> None:
        """Unfreeze the joints frozen by NaN references (their reference stays where it was)."""
        self.frozen_joints = set()

    def reset_servo(self) -> None:
        """Clear a latched servo-off (after the operator has checked the robot)."""
        self.servo_off = False

    # ------------------------------------------------------------------ internals
    def _require_started(self) -> None:
        if self._closed:
            raise DeviceError("the hardware driver is closed", hint="create a new driver")
        if self._state is None:
            raise DeviceError("the hardware driver has not been started",
                              hint=checks.NOT_STARTED_HINT)

    def _modes(self) -> np.ndarray:
        return np.full(JOINT_COUNT, self.ref_mode, dtype=np.int16)

    def _write_frame(self) -> None:
        flags = ((FLAG_SERVO_OFF if self.servo_off else 0) | (FLAG_HOLD if self._stopped else 0)
                 | (FLAG_FAULT if self.fault_message else 0))
        frame = encode_ref_frame(self._seq, self._t, flags, self._ref42, self._modes(),
                                 np.zeros(JOINT_COUNT, dtype=np.int8))
        self._seq += 1
        try:
            os.write(self._fd, frame)
        except BlockingIOError:
            self._flags.append("sink-full")
        except OSError as exc:
            if exc.errno == errno.EAGAIN:
                self._flags.append("sink-full")
            else:
                raise

    def _read_source(self) -> None:
        frame = self.source.poll()
        if frame is None:
            self._stale += 1
            if self._stale >= self.stale_periods:
                self._flags.append("stale-state")
            return
        if not (np.all(np.isfinite(frame.pos_rad)) and np.all(np.isfinite(frame.quat_wxyz))):
            raise DeviceError("the state source sent a non-finite value")
        self._stale = 0
        self._frame = frame

    def _enter_fault(self, exc: Exception) -> None:
        self.fault_message = f"{type(exc).__name__}: {exc}"
        self._flags.append("fault")
        with contextlib.suppress(Exception):
            self._write_frame()

    def _make_state(self) -> RobotState:
        frame = self._frame
        q = frame.pos_rad[self.ach_index].copy()
        dq = (q - self._q_prev) / self.period_s
        self._q_prev = q
        ft = {}
        for k, sensor in enumerate(FT_SENSORS):
            mx, my, fz = frame.ft_mx_my_fz[k]  # hubo-ach order: R hand, L hand, R foot, L foot
            ft[sensor] = np.array([0.0, 0.0, fz, mx, my, 0.0])
        flags = list(dict.fromkeys(self._flags))
        self._flags = []
        for latched, name in ((self.servo_off, "servo-off"), (bool(self.frozen_joints), "nan-ref"),
                              (bool(self.fault_message), "fault"), (self._stopped, "stopped")):
            if latched and name not in flags:
                flags.append(name)
        return RobotState(time_s=self._t, q_rad=q, dq_rad_s=dq, imu_quat_wxyz=frame.quat_wxyz,
                          imu_gyro_rad_s=frame.gyro_rad_s, ft=ft, flags=tuple(flags))

