"""Live FASTRAK reader on a serial port (pyserial), as a :class:`PoseSource`.

Start-up never trusts the unit's power-up state (it may have been saved in binary, cm or
continuous mode): the reader stops continuous output (``c``), waits, flushes, probes with ``S``,
then sets the station map (``l``), the output list of every enabled station (``O``), the format
(``F``/``f``), the units (``u``/``U``) and finally continuous mode (``C``). It then waits for the
first valid record, so a silent or misconfigured unit fails at once with a clear message.

A background thread reads the port, stamps each read with its receive time, feeds the
resynchronising parser, writes the raw capture if one was asked for, and queues the samples.
A read error (unplugged adapter, closed pty), or no valid record for ``silence_timeout_s``
(silence or garbage alike), closes the port and reconnects with exponential backoff, a
reconnection counting once a record came; after ``reconnect_timeout_s`` without success (or at
once when ``reconnect=False``) the next ``read_until`` raises :class:`DeviceError`.
"""

from __future__ import annotations

import math
import re
import threading
import time

from hubo_cli.errors import DeviceError, InputError
from hubo_cli.fastrak.capture import CaptureHeader, CaptureWriter, utc_stamp
from hubo_cli.fastrak.parser import StreamParser
from hubo_cli.fastrak.records import (
    DEFAULT_PLAUSIBILITY,
    UNIT_SCALE_M,
    Plausibility,
    make_layout,
)
from hubo_cli.fastrak.source import PoseSample, PoseSource, SourceStats, batch_samples

STATUS_REPLY = re.compile(rb"2([1-4])S([0-9A-Fa-f]{3})([^\r\n]*)\r\n")
STATION_REPLY = re.compile(rb"2[1-4]l([01]{4})\r\n")
EMULATE_HINT = "run `hubo fastrak emulate --pty` for a test tracker without hardware"


def decode_status_flags(hex3: str) -> dict:
    """Meaning of the 3 hex flag characters of the ``S`` reply (manual p.68-69)."""
    bits = int(hex3, 16)
    return {"binary": bool(bits & 1), "units": "cm" if bits & 2 else "in",
            "metal_compensation": bool(bits & 4), "continuous": bool(bits & 8)}


def _open_error(port: str, exc: Exception) -> DeviceError:
    text = str(exc)
    errno = getattr(exc, "errno", None)
    if errno == 2 or "No such file" in text:
        return DeviceError(f"no serial port {port}",
                           hint="check the adapter is plugged in (list ports with `python -m "
                                f"serial.tools.list_ports`), or {EMULATE_HINT}")
    if errno == 13 or "Permission denied" in text:
        return DeviceError(f"permission denied opening {port}",
                           hint="add your user to the dialout group "
                                "(sudo usermod -aG dialout $USER) and log in again")
    if "exclusive" in text.lower() or "lock" in text.lower():
        return DeviceError(f"{port} is in use by another program",
                           hint="close the other program that holds the port")
    return DeviceError(f"cannot open {port}: {text}", hint="check the port name and the cable")


class FastrakReader(PoseSource):
    """A live FASTRAK on a serial port.

    Args:
        port: serial device (``/dev/ttyUSB0``, an emulator's ``/dev/pts/N``).
        baud: line rate; the unit's rate is set by its I/O select switches (default 115200).
        fmt: ``binary`` (default) or ``ascii`` record format to configure.
        output_list: the ``O`` list for every enabled station (default 2,11,1: position,
            quaternion, CR LF).
        units: ``cm`` (default) or ``in`` (positions are delivered in metres either way).
        stations: stations to enable (default: those the unit reports active).
        capture: path of a raw capture to write while reading (None: no capture).
        reconnect: reopen the port with backoff after an error or silence.
        settle_s: wait after ``c`` before flushing (a record in flight must finish).
        probe_timeout_s: how long to wait for each reply (``S``, ``l``).
        first_record_timeout_s: how long to wait for the first record after ``C``.
        silence_timeout_s: no valid record for this long (silence, or bytes that are none)
            counts as a lost connection; a reconnection counts once a record came.
        reconnect_timeout_s: give up reconnecting after this long.
        read_timeout_s: serial read timeout (bounds how long the reader thread blocks).
        command_gap_s: pause between configuration commands.
        plausibility: record plausibility limits.
    """

    live = True

    def __init__(self, port: str, baud: int = 115200, fmt: str = "binary",
                 output_list=(2, 11, 1), units: str = "cm", stations=None, capture=None,
                 reconnect: bool = True, settle_s: float = 0.2, probe_timeout_s: float = 1.0,
                 first_record_timeout_s: float = 1.0, silence_timeout_s: float = 1.0,
                 reconnect_timeout_s: float = 10.0, read_timeout_s: float = 0.05,
                 command_gap_s: float = 0.02,
                 plausibility: Plausibility = DEFAULT_PLAUSIBILITY) -> None:
        super().__init__()
        if not str(port).strip():  # (pyserial opens no port and says "no such file")
            raise InputError("no serial port given (an empty name)",
                             hint="give the FASTRAK's device, e.g. /dev/ttyUSB0, or "
                                  f"{EMULATE_HINT}")
        self.layout = make_layout(fmt, output_list)
        if units not in UNIT_SCALE_M:
            raise InputError(f"unknown units {units!r}", hint="use cm or in")
        self.port = port
        self.baud = int(baud)
        self.units = units
        self.requested_stations = (None if stations is None
                                   else tuple(sorted({int(s) for s in stations})))
        if self.requested_stations is not None and (
                not self.requested_stations
                or any(not 1 <= s <= 4 for s in self.requested_stations)):
            raise InputError(f"stations {stations} are not within 1..4",
                             hint="FASTRAK stations are numbered 1 to 4")
        self.reconnect = reconnect
        self.settle_s = settle_s
        self.probe_timeout_s = probe_timeout_s
        self.first_record_timeout_s = first_record_timeout_s
        self.silence_timeout_s = silence_timeout_s
        self.reconnect_timeout_s = reconnect_timeout_s
        self.read_timeout_s = read_timeout_s
        self.command_gap_s = command_gap_s
        self.plausibility = plausibility
        self.stats = SourceStats()
        self.unit_status: dict = {}
        self.stations: tuple[int, ...] = ()
        self._lock = threading.Lock()
        self._queue: list[PoseSample] = []
        self._error: DeviceError | InputError | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._writer: CaptureWriter | None = None
        self._t0 = time.monotonic()
        self._started = False
        self._ser = self._connect()
        self._parser = StreamParser(self.layout, units, self.stations, plausibility)
        self.info = {"kind": "fastrak", "port": port, "baud": self.baud, "format": fmt,
                     "output_list": list(self.layout.output_list), "units": units,
                     "stations": list(self.stations), "unit_status": self.unit_status}
        try:
            if capture is not None:
                header = CaptureHeader(fmt, self.layout.output_list, units, self.baud,
                                       self.stations, {"port": port, "created_utc": utc_stamp(),
                                                       "unit_status": self.unit_status})
                self._writer = CaptureWriter(capture, header)
            self._wait_first_record()
        except BaseException:
            self._close_port()
            if self._writer is not None:
                self._writer.close()
            raise
        self._last_record_s = self._looked_at_s = self.now_s()
        self._thread = threading.Thread(target=self._run, name=f"fastrak:{port}", daemon=True)
        self._thread.start()

    # -- clock and queue ------------------------------------------------------------------

    def now_s(self) -> float:
        """Seconds since the reader started streaming (monotonic clock)."""
        return time.monotonic() - self._t0

    def looked_s(self) -> float:
        """When the reader thread last completed a read of the port (data or its timeout);
        ``inf`` (judge by the caller's clock) while it reconnects, or when it has not looked
        for ``silence_timeout_s``: a reader that does not read counts as a silent unit."""
        looked = self._looked_at_s
        return looked if self.now_s() - looked <= self.silence_timeout_s else math.inf

    def read_until(self, t_s: float = 0.0) -> list[PoseSample]:
        """Every sample received since the last call (``t_s`` is ignored; never blocks).

        Raises:
            DeviceError: the connection is lost and could not be re-established (raised once
                the samples received before the loss have been delivered).
            InputError: the capture file could not be written.
        """
        with self._lock:
            out, self._queue = self._queue, []
            error = self._error
        if not out and error is not None:
            raise error
        self._seen(out)
        return out

    @property
    def alive(self) -> bool:
        """True while the reader thread runs (connected or reconnecting)."""
        return self._thread is not None and self._thread.is_alive()

    # -- port set-up ------------------------------------------------------------------------

    def _open_port(self):
        import serial

        try:
            return serial.Serial(port=self.port, baudrate=self.baud, bytesize=serial.EIGHTBITS,
                                 parity=serial.PARITY_NONE, stopbits=serial.STOPBITS_ONE,
                                 timeout=self.read_timeout_s, write_timeout=1.0,
                                 xonxoff=False, rtscts=False, dsrdtr=False, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise _open_error(self.port, exc) from None

    def _send(self, ser, command: bytes) -> None:
        ser.write(command)
        ser.flush()
        if self.command_gap_s:
            time.sleep(self.command_gap_s)

    def _await_reply(self, ser, pattern: re.Pattern) -> re.Match | None:
        """Read until ``pattern`` matches the bytes received or the probe timeout passes."""
        deadline = time.monotonic() + self.probe_timeout_s
        got = b""
        while time.monotonic() < deadline:
            got += ser.read(max(1, ser.in_waiting))
            match = pattern.search(got)
            if match:
                return match
        return None

    def _connect(self):
        """Open, probe and configure the unit; return the open serial port."""
        import termios  # pyserial's buffer resets raise its error, which is no OSError

        import serial

        ser = self._open_port()
        try:
            self._probe(ser)
            self._configure(ser)
        except (serial.SerialException, OSError, termios.error) as exc:
            ser.close()
            raise DeviceError(f"lost {self.port} while configuring the FASTRAK: {exc}",
                              hint="check the cable and the adapter") from None
        except BaseException:
            ser.close()
            raise
        return ser

    def _probe(self, ser) -> None:
        """Stop continuous output and ask for the status record (twice before giving up)."""
        for attempt in range(2):
            self._send(ser, b"c" if attempt == 0 else b"\rc")
            time.sleep(self.settle_s)
            ser.reset_input_buffer()
            self._send(ser, b"S")
            match = self._await_reply(ser, STATUS_REPLY)
            if match:
                flags = match.group(2).decode()
                self.unit_status = {"flags": flags, **decode_status_flags(flags),
                                    "reply": match.group(0)[:-2].decode("latin-1")}
                return
        raise DeviceError(f"no reply from a FASTRAK on {self.port} at {self.baud} baud",
                          hint="check power, cable and the baud rate set by the unit's I/O "
                               "switches (try --baud 9600, 19200, 38400 or 57600); "
                               + EMULATE_HINT)

    def _configure(self, ser) -> None:
        """Set stations, output lists, format and units explicitly, then start streaming."""
        ser.reset_input_buffer()
        self._send(ser, b"l1\r")
        match = self._await_reply(ser, STATION_REPLY)
        active = None if match is None else {
            i + 1 for i, c in enumerate(match.group(1).decode()) if c == "1"}
        if self.requested_stations is not None:
            stations = self.requested_stations
            for s in range(1, 5):
                if s in stations and (active is None or s not in active):
                    self._send(ser, f"l{s},1\r".encode())
                elif s not in stations and (active is None or s in active):
                    self._send(ser, f"l{s},0\r".encode())
        elif active is None:
            stations = (1,)
        else:
            stations = tuple(sorted(active))
        if not stations:
            raise DeviceError(f"the FASTRAK on {self.port} reports no active station",
                              hint="plug a receiver into station 1 (a unit saved with its "
                                   "stations switched off: `hubo record --stations 1` enables "
                                   "one; teleop takes the active ones)")
        if self.stations and stations != self.stations:
            raise DeviceError(f"after reconnecting, {self.port} reports stations "
                              f"{list(stations)} instead of {list(self.stations)}",
                              hint="check the receivers and restart")
        self.stations = stations
        items = ",".join(map(str, self.layout.output_list))
        for s in stations:
            self._send(ser, f"O{s},{items}\r".encode())
        self._send(ser, b"f" if self.layout.fmt == "binary" else b"F")
        self._send(ser, b"u" if self.units == "cm" else b"U")
        time.sleep(max(self.command_gap_s, 0.02))
        leftover = ser.read(ser.in_waiting) if ser.in_waiting else b""
        if b"*ERROR*" in leftover:
            start = leftover.find(b"*ERROR*")
            text = leftover[max(0, start - 2):start + 40].split(b"\r")[0].decode("latin-1")
            raise DeviceError(f"the FASTRAK on {self.port} refused the configuration: {text}",
                              hint=f"check the output list {items} is supported by the unit")
        ser.reset_input_buffer()
        if not self._started:
            self._t0 = time.monotonic()
            self._started = True
        self._send(ser, b"C")

    def _wait_first_record(self) -> None:
        """Wait for a valid record on the port just configured (at the start, and after each
        reconnection: a unit that answers its commands but sends no record is not back).

        Raises:
            DeviceError: no valid record within ``first_record_timeout_s``.
        """
        before = self.stats.good_records
        deadline = time.monotonic() + self.first_record_timeout_s
        while time.monotonic() < deadline:
            data = self._ser.read(max(1, self._ser.in_waiting))
            if data:
                self._ingest(data, self.now_s())
                if self.stats.good_records > before:
                    return
        raise DeviceError(f"the FASTRAK on {self.port} answered but sent no valid record in "
                          f"{self.first_record_timeout_s:g} s",
                          hint=f"check receivers are plugged into stations {list(self.stations)} "
                               "and the baud rate is high enough for the output list")

    # -- streaming --------------------------------------------------------------------------

    def _ingest(self, data: bytes, t_s: float) -> int:
        """Parse, queue and capture the bytes of one read; returns the valid records in them."""
        batch, bad = self._parser.feed(data, t_s)
        samples = batch_samples(batch)
        with self._lock:
            self._queue.extend(samples)
            self.stats.add(batch, bad, len(data))
        if self._writer is not None:
            self._writer.write(t_s, data)
        return len(samples)

    def _run(self) -> None:
        try:
            self._stream()
        except OSError as exc:  # the capture file could not be written
            self._fail(InputError(f"cannot write the capture: {exc.strerror or exc}",
                                  hint="free disk space or choose another --out path"))
        except Exception as exc:  # noqa: BLE001 (reported by read_until, never silent)
            self._fail(DeviceError(f"the FASTRAK reader on {self.port} stopped: {exc!r}",
                                   hint="restart; if it happens again, record with "
                                        "`hubo record` and report the capture"))

    def _stream(self) -> None:
        import serial

        while not self._stop.is_set():
            try:
                data = self._ser.read(max(1, self._ser.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                if not self._recover(f"read failed ({exc})"):
                    return
                continue
            now = self.now_s()
            if data and self._ingest(data, now):
                self._last_record_s = now
            self._looked_at_s = now  # after the samples are queued: they count as seen
            if now - self._last_record_s > self.silence_timeout_s:
                # silent, or only garbage (a unit at another baud rate, a broken line): the
                # connection is set up again, as at the start (review 23: a unit sending
                # only noise held the hands for good, the run never ending)
                if not self._recover(f"no valid record for {self.silence_timeout_s:g} s"):
                    return

    def _fail(self, error: DeviceError | InputError) -> None:
        with self._lock:
            self._error = error

    def _recover(self, reason: str) -> bool:
        """Reconnect with backoff; False (and an error for read_until) if that is not possible."""
        import termios

        import serial

        self._looked_at_s = -math.inf  # not looking: judged by the caller's clock
        self._close_port()
        if not self.reconnect:
            self._fail(DeviceError(f"FASTRAK on {self.port} stopped: {reason}",
                                   hint="check the cable and the unit's power, then restart"))
            return False
        start = time.monotonic()
        delay = 0.25
        last = reason
        while not self._stop.is_set():
            if time.monotonic() - start > self.reconnect_timeout_s:
                self._fail(DeviceError(
                    f"FASTRAK on {self.port} lost ({reason}); reconnecting failed for "
                    f"{self.reconnect_timeout_s:g} s ({last})",
                    hint="check the cable, the adapter and the unit's power, then restart"))
                return False
            if self._stop.wait(delay):
                return False
            delay = min(delay * 2.0, 4.0)
            try:
                ser = self._connect()
            except DeviceError as exc:
                last = str(exc)
                continue
            if self._stop.is_set():  # closed while reconnecting
                ser.close()
                return False
            self._ser = ser
            lost = self._parser.reset()
            with self._lock:
                self.stats.bad_bytes += lost
            try:  # back once a record comes (review 23: a unit answering its commands and
                # sending no record was "reconnected" each second, the run never ending)
                self._wait_first_record()
            except (DeviceError, serial.SerialException, OSError, termios.error) as exc:
                last = str(exc)
                self._close_port()
                continue
            with self._lock:
                self.stats.reconnects += 1
            self._last_record_s = self.now_s()
            return True
        return False

    def _close_port(self) -> None:
        ser, self._ser = getattr(self, "_ser", None), None
        if ser is None:
            return
        try:
            if ser.is_open:
                ser.write(b"c")
                ser.flush()
        except Exception:  # noqa: BLE001 (the port is going away; stopping it is best effort)
            pass
        try:
            ser.close()
        except Exception:  # noqa: BLE001
            pass

    def close(self) -> None:
        """Stop the reader thread, stop continuous output and close the port and capture."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=self.settle_s + 2 * self.probe_timeout_s
                              + self.first_record_timeout_s + 1.0)
        self._close_port()
        if self._thread is not None and not self._thread.is_alive():
            batch, lost = self._parser.finish()
            with self._lock:
                self._queue.extend(batch_samples(batch))
                self.stats.add(batch, lost)
        if self._writer is not None:
            self._writer.close()
