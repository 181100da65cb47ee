"""A FASTRAK device emulator on a serial line or a pseudo-terminal.

:class:`EmulatedFastrak` is the device itself (no I/O): it answers the commands the reader uses
(``c C P S F f u U O l`` and a few that only need acknowledging), keeps the format, units,
output list per station and station map, and produces data records with the same encoder the
sample writers use. :class:`FastrakEmulator` serves it on an endpoint (a pty from
``os.openpty``, or a real serial port through pyserial), streaming records at 120 Hz shared
across the enabled stations while continuous mode is on.

Power-up state is the manual's default (polled, ASCII, inches, list 2,4,1); ``streaming=True``
starts like a unit whose EEPROM was saved in the Hubo lab's configuration (continuous, binary,
cm, list 52,61,50), which is what a reader that "never trusts the power-up state" must handle.
"""

from __future__ import annotations

import math
import os
import select
import threading
import time
import tty
from collections import deque

import numpy as np

from hubo_cli.errors import DeviceError, InputError
from hubo_cli.fastrak.capture import RECORD_RATE_HZ, load_recording
from hubo_cli.fastrak.records import encode_record, make_layout
from hubo_cli.fastrak.track import PoseTrack
from hubo_cli.geometry import fastrak_euler_deg_to_quat_wxyz

SINGLE_CHAR_COMMANDS = b"cCPSFfuUDdW"
TERMINATED_COMMANDS = b"OlHRABbGxvVQerINXoT"
FIRMWARE = "  3.00"
SYSTEM_ID = "hubo-cli FASTRAK emulator"


class BuiltinMotion:
    """Slow hand-like motion for each station (metres, transmitter frame X fwd, Y right, Z down).

    Station 1 circles in front-right, station 2 front-left (5 cm radius, 6 s period), stations
    3 and 4 closer in; orientations sway by up to 15 degrees.
    """

    BASES_M = {1: (0.40, 0.20, 0.10), 2: (0.40, -0.20, 0.10), 3: (0.30, 0.10, -0.10),
               4: (0.30, -0.10, -0.10)}

    @property
    def stations(self) -> tuple[int, ...]:
        """Stations this motion can drive."""
        return (1, 2, 3, 4)

    def pose(self, station: int, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and quaternion (w, x, y, z) of ``station`` at ``t_s`` seconds."""
        phase = 2 * math.pi * (t_s / 6.0 + 0.25 * (station - 1))
        base = self.BASES_M[station]
        p = np.array([base[0] + 0.02 * math.sin(phase / 2), base[1] + 0.05 * math.cos(phase),
                      base[2] + 0.05 * math.sin(phase)])
        az_el_rl_deg = (15.0 * math.sin(phase / 3), 8.0 * math.sin(phase / 2),
                        10.0 * math.cos(phase / 4))
        q = fastrak_euler_deg_to_quat_wxyz(az_el_rl_deg)
        return p, q


class RecordedMotion:
    """Poses played from a recording, looping; stations are those in the recording."""

    def __init__(self, tracks: dict[int, PoseTrack]) -> None:
        self.tracks = tracks
        self.start_s = min(t.start_s for t in tracks.values())
        self.period_s = max(t.end_s for t in tracks.values()) - self.start_s

    @staticmethod
    def from_file(path) -> RecordedMotion:
        """Load a raw capture or pose log (see :func:`load_recording`).

        Raises:
            InputError: a position a tracker could not send (beyond its range, which a
                binary record would carry as infinity): refused by the loader
                (:func:`~hubo_cli.fastrak.capture.parse_pose_log`).
        """
        batch = load_recording(path).batch
        tracks = {}
        for s in sorted(set(batch.station.tolist())):
            sel = batch.station == s
            tracks[s] = PoseTrack(batch.t_s[sel], batch.position_m[sel], batch.quat_wxyz[sel])
        return RecordedMotion(tracks)

    @property
    def stations(self) -> tuple[int, ...]:
        """Stations in the recording."""
        return tuple(sorted(self.tracks))

    def pose(self, station: int, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Recorded pose of ``station`` at ``t_s`` seconds into the (looped) recording."""
        t = self.start_s + (t_s % self.period_s if self.period_s > 0 else 0.0)
        p, q = self.tracks[station].at(t)
        return p[0], q[0]


class EmulatedFastrak:
    """The device: command handling, configuration state and record generation.

    Args:
        stations: stations with a receiver plugged in (enabled at power-up).
        motion: pose provider with ``pose(station, t_s)`` (default :class:`BuiltinMotion`).
        streaming: start as a unit saved in continuous binary cm mode (list 52,61,50).
        keep_played: how many played records to remember (for tests); 0 keeps none.

    Attributes:
        status: status character put in every record (``" "``; set a letter to test).
        played: (t_s, station, position_m, quat_wxyz) of each record sent since continuous
            mode last started.
    """

    def __init__(self, stations=(1,), motion=None, streaming: bool = False,
                 keep_played: int = 0) -> None:
        stations = tuple(sorted({int(s) for s in stations}))
        if not stations or any(not 1 <= s <= 4 for s in stations):
            raise InputError(f"emulated stations {list(stations)} must be within 1..4",
                             hint="use --stations 1 to 4")
        self.motion = motion or BuiltinMotion()
        missing = [s for s in stations if s not in self.motion.stations]
        if missing:
            raise InputError(f"the recording has no poses for station(s) {missing}",
                             hint=f"it has stations {list(self.motion.stations)}; "
                                  "use fewer --stations")
        self.plugged = stations
        self.status = " "
        self.played: deque = deque(maxlen=keep_played or None)
        self._keep = keep_played > 0
        self._lock = threading.Lock()
        self._cmd = b""
        self._next_index = 0
        self.commands_seen: list[str] = []
        self.power_up(streaming)

    def power_up(self, streaming: bool = False) -> None:
        """Reset to the power-up state (manual defaults, or a saved streaming configuration)."""
        self.enabled = {s: s in self.plugged for s in range(1, 5)}
        if streaming:
            self.binary, self.units, self.continuous = True, "cm", True
            self.lists = {s: (52, 61, 50) for s in range(1, 5)}
        else:
            self.binary, self.units, self.continuous = False, "in", False
            self.lists = {s: (2, 4, 1) for s in range(1, 5)}
        self.suspended = False

    # -- state ---------------------------------------------------------------------------------

    @property
    def active_stations(self) -> list[int]:
        """Stations that produce records: plugged in and enabled."""
        return [s for s in self.plugged if self.enabled[s]]

    def played_snapshot(self) -> list[tuple[float, int, np.ndarray, np.ndarray]]:
        """A copy of the played-record log."""
        with self._lock:
            return list(self.played)

    def _flags(self) -> str:
        bits = (1 if self.binary else 0) | (2 if self.units == "cm" else 0) \
            | (8 if self.continuous else 0)
        return f"3F{bits:X}"

    def record(self, station: int, t_s: float) -> bytes:
        """The data record ``station`` would send at ``t_s`` (also logged as played)."""
        p, q = self.motion.pose(station, t_s)
        layout = make_layout("binary" if self.binary else "ascii", self.lists[station])
        rec = encode_record(layout, station, p, q, self.units, self.status)
        if self._keep:
            with self._lock:
                self.played.append((t_s, station, p, q))
        return rec

    def next_record(self, t_s: float) -> bytes:
        """The record of the next station in turn if streaming, else nothing."""
        stations = self.active_stations
        if not self.continuous or self.suspended or not stations:
            return b""
        station = stations[self._next_index % len(stations)]
        self._next_index += 1
        return self.record(station, t_s)

    # -- commands ------------------------------------------------------------------------------

    def receive(self, data: bytes, t_s: float) -> bytes:
        """Handle command bytes from the host; return the reply bytes."""
        self._cmd += data
        out: list[bytes] = []
        while self._cmd:
            ch = self._cmd[:1]
            if ch in (b"\r", b"\n"):
                self._cmd = self._cmd[1:]
            elif ch[0] in SINGLE_CHAR_COMMANDS:
                self._cmd = self._cmd[1:]
                out.append(self._single(ch.decode(), t_s))
            elif ch == b"\x19":  # ^Y reinitialise
                self._cmd = self._cmd[1:]
                self.power_up(False)
            elif ch in (b"\x0b", b"\x11", b"\x13"):  # ^K save, ^Q resume, ^S suspend
                self._cmd = self._cmd[1:]
                if ch == b"\x13":
                    self.suspended = True
                elif ch == b"\x11":
                    self.suspended = False
            elif ch[0] in TERMINATED_COMMANDS:
                ends = [i for i in (self._cmd.find(b"\r"), self._cmd.find(b"\n")) if i >= 0]
                if not ends:
                    if len(self._cmd) > 256:
                        out.append(self._error(self._cmd[:16], -5))
                        self._cmd = b""
                    break
                end = min(ends)
                command, self._cmd = self._cmd[:end], self._cmd[end + 1:]
                out.append(self._terminated(command))
            else:
                out.append(self._error(ch, -99))
                self._cmd = self._cmd[1:]
        return b"".join(out)

    def _error(self, command: bytes, code: int) -> bytes:
        return b"2 E*ERROR* " + command.replace(b"\r", b"") + f" {code}\r\n".encode()

    def _single(self, c: str, t_s: float) -> bytes:
        self.commands_seen.append(c)
        if c == "c":
            self.continuous = False
        elif c == "C":
            if not self.continuous:
                with self._lock:
                    self.played.clear()
            self.continuous = True
        elif c in "Ff":
            self.binary = c == "f"
        elif c in "uU":
            self.units = "cm" if c == "u" else "in"
        elif c == "W":
            self.power_up(False)
        elif c == "P":
            return b"".join(self.record(s, t_s) for s in self.active_stations)
        elif c == "S":
            station = self.active_stations[0] if self.active_stations else 1
            sensor_map = sum(1 << (s - 1) for s in self.active_stations)
            text = (f"2{station}S{self._flags()}    F3{sensor_map:X}  {FIRMWARE}"
                    f"{SYSTEM_ID:<32.32}\r\n")
            return text.encode()
        return b""

    def _station_arg(self, command: bytes) -> tuple[int | None, list[str]]:
        text = command[1:].decode("latin-1")
        parts = text.split(",")
        try:
            station = int(parts[0])
        except ValueError:
            return None, parts[1:]
        return (station if 1 <= station <= 4 else None), parts[1:]

    def _terminated(self, command: bytes) -> bytes:
        name = command[:1].decode()
        self.commands_seen.append(command.decode("latin-1"))
        if name not in "Ol":
            return b""  # accepted without effect (alignment, hemisphere, filters, ...)
        station, args = self._station_arg(command)
        if station is None:
            return self._error(command, -3)
        if name == "l":
            if not args:
                bits = "".join("1" if self.enabled[s] else "0" for s in range(1, 5))
                return f"2{station}l{bits}\r\n".encode()
            if args[0].strip() not in ("0", "1"):
                return self._error(command, -3)
            self.enabled[station] = args[0].strip() == "1"
            return b""
        if not args:
            listed = ",".join(map(str, self.lists[station]))
            return f"2{station}O{listed}\r\n".encode()
        try:
            items = tuple(int(a) for a in args if a.strip() != "")
            make_layout("binary", items)
        except (ValueError, InputError):
            return self._error(command, -3)
        self.lists[station] = items
        return b""


# ---------------------------------------------------------------------------------------------
# Endpoints


class PtyEndpoint:
    """A pseudo-terminal: the emulator holds the master; ``path`` is the slave a reader opens."""

    def __init__(self) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self._slave)
        self.dropped_bytes = 0

    def read(self, timeout_s: float) -> bytes:
        """Bytes the host wrote (empty after ``timeout_s`` seconds without any)."""
        ready, _, _ = select.select([self.master], [], [], max(0.0, timeout_s))
        if not ready:
            return b""
        try:
            return os.read(self.master, 4096)
        except (BlockingIOError, OSError):
            return b""

    def write(self, data: bytes) -> None:
        """Send bytes to the host; what does not fit the line's buffer is lost (like a wire)."""
        try:
            n = os.write(self.master, data)
        except BlockingIOError:
            n = 0
        except OSError:
            n = 0
        self.dropped_bytes += len(data) - n

    def close(self) -> None:
        """Close both ends (a reader then sees the port disappear)."""
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass


class SerialEndpoint:
    """A real serial port (for a null-modem cable to the machine under test)."""

    def __init__(self, port: str, baud: int = 115200) -> None:
        import serial

        from hubo_cli.fastrak.reader import _open_error

        try:
            self._ser = serial.Serial(port, baud, timeout=0, write_timeout=0.5,
                                      xonxoff=False, rtscts=False, dsrdtr=False)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise _open_error(port, exc) from None
        self.path = port
        self.dropped_bytes = 0

    def read(self, timeout_s: float) -> bytes:
        """Bytes the host wrote (empty after ``timeout_s`` seconds without any)."""
        ready, _, _ = select.select([self._ser.fileno()], [], [], max(0.0, timeout_s))
        if not ready:
            return b""
        return self._ser.read(max(1, self._ser.in_waiting))

    def write(self, data: bytes) -> None:
        """Send bytes to the host."""
        import serial

        try:
            self._ser.write(data)
        except serial.SerialTimeoutException:
            self.dropped_bytes += len(data)

    def close(self) -> None:
        """Close the port."""
        self._ser.close()


class FastrakEmulator:
    """Serve an :class:`EmulatedFastrak` on an endpoint, in the foreground or on a thread.

    Args:
        device: the emulated device.
        endpoint: :class:`PtyEndpoint` or :class:`SerialEndpoint`.
        rate_hz: records per second in continuous mode, shared by the stations.
    """

    def __init__(self, device: EmulatedFastrak, endpoint, rate_hz: float = RECORD_RATE_HZ):
        self.device = device
        self.endpoint = endpoint
        self.period_s = 1.0 / rate_hz
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.records_sent = 0
        self.error: Exception | None = None

    @property
    def port_name(self) -> str:
        """The path a reader opens (the pty slave or the serial port)."""
        return self.endpoint.path

    def serve(self, duration_s: float | None = None) -> None:
        """Answer commands and stream records until stopped or ``duration_s`` elapsed."""
        start = time.monotonic()
        next_slot = start
        device, endpoint = self.device, self.endpoint
        while not self._stop.is_set():
            now = time.monotonic()
            if duration_s is not None and now - start >= duration_s:
                break
            data = endpoint.read(min(max(next_slot - now, 0.0), 0.05))
            now = time.monotonic()
            if data:
                reply = device.receive(data, now - start)
                if reply:
                    endpoint.write(reply)
            if now >= next_slot:
                record = device.next_record(next_slot - start)
                if record:
                    endpoint.write(record)
                    self.records_sent += 1
                next_slot += self.period_s
                if now - next_slot > 0.25:  # after a stall, do not burst the missed slots
                    next_slot = now

    def _run(self) -> None:
        try:
            self.serve()
        except Exception as exc:  # noqa: BLE001 (kept for the owner thread to inspect)
            self.error = exc

    def start(self) -> FastrakEmulator:
        """Serve on a background thread; return self."""
        self._thread = threading.Thread(target=self._run, name="fastrak-emulator", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and close the endpoint."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.endpoint.close()

    def __enter__(self) -> FastrakEmulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def make_emulator(pty: bool = True, port: str | None = None, baud: int = 115200,
                  stations: int | None = None, from_file=None, streaming: bool = False,
                  keep_played: int = 0) -> FastrakEmulator:
    """Build an emulator on a new pty (``pty=True``) or on ``port``.

    Args:
        pty: create a pseudo-terminal (its slave path is ``port_name``).
        port: serial device to serve on instead of a pty.
        baud: line rate for ``port``.
        stations: emulate stations 1..N (default 1, or the recording's stations).
        from_file: raw capture or pose log to play (looped) instead of the built-in motion.
        streaming: start in a saved continuous binary configuration.
        keep_played: remember this many played records (tests).

    Raises:
        InputError: bad station count or recording. DeviceError: the port cannot be opened.
    """
    motion = RecordedMotion.from_file(from_file) if from_file is not None else BuiltinMotion()
    if stations is None:
        chosen = motion.stations if from_file is not None else (1,)
    else:
        if not 1 <= int(stations) <= 4:
            raise InputError(f"--stations {stations} must be 1 to 4",
                             hint="a FASTRAK has up to four receivers")
        chosen = tuple(range(1, int(stations) + 1))
    device = EmulatedFastrak(chosen, motion, streaming=streaming, keep_played=keep_played)
    if port is not None:
        endpoint = SerialEndpoint(port, baud)
    elif pty:
        try:
            endpoint = PtyEndpoint()
        except OSError as exc:
            raise DeviceError(f"cannot create a pseudo-terminal: {exc}",
                              hint="this needs a POSIX system with /dev/ptmx") from None
    else:
        raise InputError("choose where to emulate", hint="use --pty or --port DEV")
    return FastrakEmulator(device, endpoint)
