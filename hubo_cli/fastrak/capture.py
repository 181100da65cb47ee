"""Recording formats: the raw capture and the pose log (CSV), their readers and writers.

Raw capture (``trajectories/README.md`` has the full description)::

    FASTRAK-CAPTURE 1\\n
    {"format": "binary", "output_list": [2, 11, 1], "units": "cm", "baud": 115200,
     "stations": [1, 2], ...}\\n                      <- one line of JSON
    then chunks, each: float64 t_s, uint32 n (little-endian), n raw bytes

Each chunk is one read from the serial port as received, with its receive time in seconds since
the recording started. A replay feeds the chunks through the same parser as the live reader.

Pose log: CSV with the header ``t_s,station,x_m,y_m,z_m,qw,qx,qy,qz,status``; positions in metres
in the transmitter frame, scalar-first unit quaternions, status empty when healthy.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError, quoted
from hubo_cli.fastrak.parser import decode_stream
from hubo_cli.fastrak.records import (
    DEFAULT_PLAUSIBILITY,
    STATUS_OK_CHARS,
    UNIT_SCALE_M,
    Plausibility,
    RecordBatch,
    encode_records,
    make_layout,
)
from hubo_cli.fastrak.source import PoseSample, ReplaySource, SourceStats, batch_samples
from hubo_cli.fastrak.track import PoseTrack
from hubo_cli.geometry import matrix_to_quat_wxyz, unit_quats
from hubo_cli.outputs import write_error
from hubo_cli.streams import open_nonblocking, reader_of

MAGIC = b"FASTRAK-CAPTURE 1\n"
CHUNK_HEAD = struct.Struct("<dI")
MAX_CHUNK_BYTES = 65536  # one serial read: 5 s of a 115200-baud line; a longer one is garbled
# the largest recording read (a binary capture of two stations takes about 6 kB/s, a pose log
# about 9 kB/s: 256 MiB is some 8 hours); a bigger file is not read at all
MAX_RECORDING_BYTES = 256 << 20
# the first bytes of a recording are parsed before the rest is read: a file that is not a
# recording (/dev/zero, random bytes, a binary blob) is refused from them
FIRST_BYTES = 1 << 20
MAX_LINE_BYTES = 65536  # no line of a pose log comes near this
MAX_CHUNK_GAP_S = 3600.0  # chunks an hour apart are a garbled time, not a recording
# A pose log's quaternion whose norm departs from 1 by more than this is not a quaternion (the
# columns hold something else, or the file is garbled): refused, naming its line. The shipped
# samples' norms depart by at most 6e-8 (written with 7 decimals); a tracker's ASCII output
# keeps four decimals (the wire parser allows 0.02, records.Plausibility.unit_norm_tol); 0.1
# leaves room for a hand-written file at two decimals (0.71, 0.71: 1.004).
QUAT_NORM_TOL = 0.1
# a recording whose first time is before 0 or after this (a clock's epoch, a time of day, rows
# cut from the middle of a recording) is counted from its first sample, so it replays from its
# start; one that starts within it keeps its times (a live capture's first chunk comes a few
# milliseconds after its start: the shipped ones at 2.9 and 4.7 ms)
MAX_START_S = 1.0
# the coarsest step a recording's times may have: float64 resolves 1e12 s to 0.12 ms, 1e16 s to
# 2 s (every record of a minute at one instant)
TIME_RESOLUTION_S = 1e-3
# more records a second than any tracker sends (a FASTRAK 120, a generated stream 240 a hand):
# times squeezed together (6 s of motion in 1.4 us) are garbled
MAX_RECORDS_PER_S = 10_000.0
# a pose log's station may repeat its time in this many rows in a row (a serial read that
# delivered several of its records at once: a decoded capture stamps each with the read's time);
# more are refused: 0.25 s of a 120 Hz tracker's records (the teleop's stale-input timeout)
# delivered as one instant, their motion lost (the review's log: 3 s of rows at t = 1.0 s)
MAX_SAME_TIME_ROWS = 30
# a pose log's rows of different stations may be out of time order by this much: each station
# stamped by itself (two stations of a 120 Hz tracker come 8 ms apart); its rows are merged by
# time. Further back is a time going backwards (two recordings in one file), refused.
MAX_STATION_SKEW_S = 0.05
_STATUS_TEXT = STATUS_OK_CHARS.decode("ascii")  # a pose log's status: a record's own
LINE_ENDS = re.compile(r"\r\n|\r|\n")  # a pose log's line ends (a CSV file's)
POSE_LOG_COLUMNS = ("t_s", "station", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz", "status")
RECORD_RATE_HZ = 120.0
"""Records per second the device emits in continuous mode, shared by the enabled stations."""


@dataclass
class CaptureHeader:
    """What a raw capture needs to be decoded.

    Attributes:
        fmt: ``ascii`` or ``binary``.
        output_list: the ``O`` list every station was configured with.
        units: ``cm`` or ``in``.
        baud: serial rate the bytes were received at.
        stations: enabled stations.
        extra: anything else recorded (port, time, the unit's status reply, ...).
    """

    fmt: str
    output_list: tuple[int, ...]
    units: str
    baud: int
    stations: tuple[int, ...]
    extra: dict = field(default_factory=dict)

    def to_json(self) -> str:
        """The header line (without newline)."""
        data = {"format": self.fmt, "output_list": list(self.output_list), "units": self.units,
                "baud": self.baud, "stations": list(self.stations), **self.extra}
        return json.dumps(data, separators=(", ", ": "))

    @staticmethod
    def from_dict(data: dict, where: str) -> CaptureHeader:
        """Validate a decoded header; raise InputError naming ``where`` if it is malformed."""
        def value(name: str):
            if name not in data:
                raise InputError(f"{where}: the capture header lacks {name}", hint=HEADER_HINT)
            return data[name]

        def whole_numbers(name: str) -> tuple[int, ...]:
            items = value(name)
            if not (isinstance(items, list) and all(map(_whole, items))):
                raise InputError(f"{where}: the capture header's {name} is {quoted(items)}, "
                                 "not a list of whole numbers", hint=HEADER_HINT)
            return tuple(int(v) for v in items)

        fmt, units = value("format"), value("units")
        output_list, stations = whole_numbers("output_list"), whole_numbers("stations")
        baud = data.get("baud", 115200)
        if not (_whole(baud) and baud > 0):
            raise InputError(f"{where}: the capture header's baud is {quoted(baud)}, not a "
                             "baud rate", hint="baud is the serial line's bits per second, "
                                               "e.g. 115200")
        if not isinstance(units, str) or units not in UNIT_SCALE_M:
            raise InputError(f"{where}: capture header has units {quoted(units)}",
                             hint="units must be cm or in")
        if not stations or any(not 1 <= s <= 4 for s in stations):
            raise InputError(f"{where}: capture header has stations {quoted(list(stations))}",
                             hint="stations are numbered 1 to 4")
        if not isinstance(fmt, str):
            raise InputError(f"{where}: capture header has format {quoted(fmt)}",
                             hint="format is ascii or binary")
        try:
            make_layout(fmt, output_list)
        except InputError as exc:
            raise InputError(f"{where}: the capture header's {exc.message}", hint=exc.hint
                             ) from None
        known = {"format", "output_list", "units", "baud", "stations"}
        return CaptureHeader(fmt, output_list, units, int(baud), stations,
                             {k: v for k, v in data.items() if k not in known})


HEADER_HINT = "the header needs format, output_list, units and stations"


def _whole(v) -> bool:
    """A JSON whole number (not a boolean, NaN or infinity; 2.0 counts)."""
    return (isinstance(v, int) and not isinstance(v, bool)) or (
        isinstance(v, float) and math.isfinite(v) and v.is_integer())


@dataclass
class Capture:
    """A raw capture in memory: the header, the bytes, and where each chunk ends and when."""

    header: CaptureHeader
    data: bytes
    chunk_ends: np.ndarray
    chunk_times: np.ndarray
    truncated: bool = False

    def decode(self, plausibility: Plausibility = DEFAULT_PLAUSIBILITY
               ) -> tuple[RecordBatch, int]:
        """Decode every record (same parser as live); return (records, bytes skipped)."""
        h = self.header
        layout = make_layout(h.fmt, h.output_list)
        return decode_stream(self.data, self.chunk_ends, self.chunk_times, layout, h.units,
                             h.stations, plausibility)


def read_recording_bytes(path: str | Path) -> bytes:
    """The bytes of a recording file, read a block at a time (Ctrl-C and SIGTERM are seen
    between blocks): its first :data:`FIRST_BYTES` must parse as a raw capture or a pose log,
    and the file must not exceed :data:`MAX_RECORDING_BYTES`, so that a file that is no
    recording (``/dev/zero``, random bytes) is refused from its first bytes, never read whole.
    A FIFO or device is opened without waiting for a writer and refused when no byte comes
    for :data:`hubo_cli.streams.STREAM_WAIT_S`.

    Raises:
        InputError: the file is missing, unreadable, too large, silent or not a recording.
    """
    if not str(path).strip():  # Path('') is the current folder
        raise InputError("no recording given (an empty path)",
                         hint="give a raw capture or a pose log; samples are in trajectories/")
    path = Path(path)
    try:
        # a FIFO or device is opened without waiting for a writer, then read as bytes come
        fd = open_nonblocking(path)
        try:
            return _read_fd(fd, path)
        finally:
            os.close(fd)
    except FileNotFoundError:
        raise InputError(f"no such recording: {path}",
                         hint="check the path; sample recordings are in trajectories/") from None
    except IsADirectoryError:
        raise InputError(f"{path} is a folder, not a recording", hint="give a file") from None
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror}", hint="check permissions") from None


def _read_fd(fd: int, path: Path) -> bytes:
    """:func:`read_recording_bytes` on its open file descriptor."""
    if os.fstat(fd).st_size > MAX_RECORDING_BYTES:
        raise _too_large(path)
    read = reader_of(fd, path)
    blob = bytearray(read(FIRST_BYTES))
    more = read(1)
    _check_first_bytes(bytes(blob), str(path), whole=not more)
    while more:
        blob += more
        if len(blob) > MAX_RECORDING_BYTES:
            raise _too_large(path)
        more = read(FIRST_BYTES)
    return bytes(blob)


def _too_large(path: Path) -> InputError:
    return InputError(f"{path} is larger than {MAX_RECORDING_BYTES >> 20} MiB: not a recording "
                      "(that is some 8 hours of tracker stream)",
                      hint="replay a file written by `hubo record` or a pose-log CSV")


def _check_first_bytes(first: bytes, where: str, whole: bool) -> None:
    """Parse a recording's first bytes (``whole``: the file ends there) as a raw capture or
    a pose log up to their last complete line; InputError when they are neither."""
    if first.startswith(MAGIC):
        parse_capture(first, where)  # a chunk cut at the end is taken as a truncation
        return
    if not whole:  # up to the last whole line: a pose log's lines are some 80 bytes
        end = first.rfind(b"\n") + 1
        if len(first) - end > MAX_LINE_BYTES:
            line = first.count(b"\n") + 1
            raise InputError(f"{where} is not a recording: line {line} runs over "
                             f"{MAX_LINE_BYTES >> 10} KiB",
                             hint="replay a file written by `hubo record` or a pose-log CSV")
        first = first[:end]
    parse_pose_log(decode_pose_log(first, where), where)


def decode_pose_log(blob: bytes, where: str) -> str:
    """A pose log's bytes as text (UTF-8).

    Raises:
        InputError: bytes that are not UTF-8 text (UTF-16 text said as such).
    """
    try:
        return blob.decode("utf-8")
    except UnicodeDecodeError:
        if blob[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise InputError(f"{where} is UTF-16 text; a pose log is UTF-8",
                             hint="save it as UTF-8 (PowerShell: Out-File -Encoding utf8)"
                             ) from None
        raise InputError(f"{where} is neither a raw capture nor a text pose log",
                         hint="replay a file written by `hubo record` or a pose-log CSV"
                         ) from None


def parse_capture(blob: bytes, where: str = "capture") -> Capture:
    """Parse raw-capture bytes (a truncated last chunk is kept as far as it goes).

    Raises:
        InputError: not a capture, or a garbled header or chunk table.
    """
    if not blob.startswith(MAGIC):
        raise InputError(f"{where} is not a FASTRAK raw capture",
                         hint="a capture starts with the line 'FASTRAK-CAPTURE 1'")
    end = blob.find(b"\n", len(MAGIC))
    if end < 0:
        raise InputError(f"{where}: the capture header line is cut off",
                         hint="the file is truncated; record it again")
    try:
        header_data = json.loads(blob[len(MAGIC):end].decode("utf-8"))
        if not isinstance(header_data, dict):
            raise ValueError("not an object")
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{where}: the capture header is not valid JSON ({exc})",
                         hint="the header is the second line; it must be one JSON object"
                         ) from None
    except RecursionError:  # json's decoder recurses once an array or object deep
        raise InputError(f"{where}: the capture header is not valid JSON (arrays or objects "
                         "nested too deeply)",
                         hint="the header is the second line; it must be one JSON object"
                         ) from None
    header = CaptureHeader.from_dict(header_data, where)
    pos = end + 1
    pieces: list[bytes] = []
    ends: list[int] = []
    times: list[float] = []
    total = 0
    truncated = False
    size = len(blob)
    last_t = -math.inf
    while pos < size:
        if pos + CHUNK_HEAD.size > size:
            truncated = True
            break
        t_s, n = CHUNK_HEAD.unpack_from(blob, pos)
        pos += CHUNK_HEAD.size
        at = pos - CHUNK_HEAD.size
        if not 0 < n <= MAX_CHUNK_BYTES:  # a serial read has at least one byte
            raise InputError(f"{where}: chunk at byte {at} claims {n:,} bytes (one serial read "
                             f"is 1 to {MAX_CHUNK_BYTES:,})",
                             hint="the chunk's length is garbled; record the capture again")
        if not math.isfinite(t_s) or (pieces and bad_time_step(t_s - last_t)):
            raise InputError(f"{where}: chunk at byte {at} has time {quoted(t_s)}",
                             hint="chunk times must be finite and non-decreasing, without "
                                  "gaps of hours; the file is garbled")
        if pos + n > size:  # a cut-off file misses part of one read
            truncated = True
            n = size - pos
        last_t = t_s
        pieces.append(blob[pos:pos + n])
        total += n
        ends.append(total)
        times.append(t_s)
        pos += n
    # the bytes after the first read, less a serial buffer's backlog (4 kB), at most twice
    # what the line carries (10 bits a byte)
    chunk_times = recording_times(np.array(times, dtype=np.float64), where, "chunk",
                                  (total - (ends[0] if ends else 0) - 4096, header.baud / 5.0))
    return Capture(header, b"".join(pieces), np.array(ends, dtype=np.int64), chunk_times,
                   truncated)


def interleaved_order(t_s: np.ndarray, station: np.ndarray) -> np.ndarray | None:
    """The rows' order by time, where only rows of different stations are out of time order,
    and by at most :data:`MAX_STATION_SKEW_S` (a recorder that stamps each station's record
    with its own clock read, or merges per-station streams); None where the rows are in time
    order already or a station's own times go backwards or the skew is larger (refused as a
    time going backwards)."""
    if len(t_s) < 2 or not (np.diff(t_s) < -1e-9).any():
        return None
    if _station_goes_back(t_s, station) is not None:
        return None
    if (np.maximum.accumulate(t_s) - t_s).max() > MAX_STATION_SKEW_S:
        return None
    return np.argsort(t_s, kind="stable")


def _station_goes_back(t_s: np.ndarray, station: np.ndarray) -> tuple[int, int] | None:
    """The first row (in file order) whose time is earlier than its station's row before it:
    (that row's index, this row's), or None."""
    first = None
    for s in np.unique(station):
        rows = np.flatnonzero(station == s)
        back = np.flatnonzero(np.diff(t_s[rows]) < -1e-9)
        if back.size and (first is None or rows[back[0] + 1] < first[1]):
            first = (int(rows[back[0]]), int(rows[back[0] + 1]))
    return first


def bad_time_step(step_s):
    """True where a recording's time cannot follow the one before it ``step_s`` earlier (s; a
    number or an array): it goes backwards, or it comes more than :data:`MAX_CHUNK_GAP_S`
    later. The one rule of both formats (a capture's chunks, a pose log's rows)."""
    return (step_s < -1e-9) | (step_s > MAX_CHUNK_GAP_S)


def recording_times(t_s: np.ndarray, where: str, what: str = "row",
                    rate: tuple[float, float] | None = None) -> np.ndarray:
    """A recording's times (in file order, already checked for going backwards and for gaps),
    counted from the first when that starts before 0 or after :data:`MAX_START_S`.

    Args:
        t_s: the times, seconds.
        where: the file, for the error.
        what: what carries a time (``row``, ``chunk``), for the error.
        rate: (how many units the times carry, the most a second) for the density check
            (default: one record a time, :data:`MAX_RECORDS_PER_S`).

    Raises:
        InputError: every time at one instant, times too coarse for float64 to tell apart,
            or more records (bytes) a second than a tracker sends.
    """
    if len(t_s) > 1:
        step_s = float(np.spacing(np.abs(t_s).max()))
        if step_s > TIME_RESOLUTION_S:
            raise InputError(f"{where}: times near {t_s[-1]:.6g} s are too large to tell "
                             f"apart (float64 steps by {step_s:g} s there)",
                             hint="count t_s in seconds from the recording's start")
        span_s = float(t_s[-1] - t_s[0])
        if span_s <= 0.0:
            raise InputError(f"{where}: every {what} has the same time (t_s {t_s[0]:g} s)",
                             hint="t_s must count the seconds of the recording")
        count, most = rate or (len(t_s) - 1, MAX_RECORDS_PER_S)  # records after the first
        if count / span_s > most:
            unit = "bytes" if rate else "records"
            raise InputError(f"{where}: {count + (not rate):,} {unit} within {span_s:.3g} s, "
                             f"more than a tracker sends ({most:g} a second)",
                             hint="the times are garbled; t_s must count the seconds of the "
                                  "recording")
    if len(t_s) and not 0.0 <= t_s[0] <= MAX_START_S:
        return t_s - t_s[0]
    return t_s


def read_capture(path: str | Path) -> Capture:
    """Read a raw capture file (see :func:`parse_capture`)."""
    return parse_capture(read_recording_bytes(path), str(path))


class CaptureWriter:
    """Write a raw capture as bytes arrive (flushed often, so a crash loses little).

    Args:
        path: output file.
        header: the capture header.
        flush_every_s: flush the file at most this often, seconds of receive time.
    """

    def __init__(self, path: str | Path, header: CaptureHeader, flush_every_s: float = 0.25):
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        except OSError as exc:
            raise InputError(f"cannot write {self.path}: {exc.strerror}",
                             hint="choose a writable --out path") from None
        self._file.write(MAGIC + header.to_json().encode() + b"\n")
        self._file.flush()
        self._flush_every_s = flush_every_s
        self._last_flush = -math.inf
        self.bytes_written = 0

    def write(self, t_s: float, data: bytes) -> None:
        """Append one chunk received at ``t_s`` seconds."""
        if self._file is None or not data:
            return
        self._file.write(CHUNK_HEAD.pack(float(t_s), len(data)))
        self._file.write(data)
        self.bytes_written += len(data)
        if t_s - self._last_flush >= self._flush_every_s:
            self._file.flush()
            self._last_flush = t_s

    def close(self) -> None:
        """Flush and close (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def capture_bytes(header: CaptureHeader, chunks: Iterable[tuple[float, bytes]]) -> bytes:
    """A whole raw capture file as bytes, from (receive time s, data) chunks."""
    out = io.BytesIO()
    out.write(MAGIC + header.to_json().encode() + b"\n")
    for t_s, data in chunks:
        out.write(CHUNK_HEAD.pack(float(t_s), len(data)))
        out.write(data)
    return out.getvalue()


# ---------------------------------------------------------------------------------------------
# Synthesising streams from poses (emulator, sample recordings, tests, benchmarks)


def _as_tracks(poses) -> dict[int, PoseTrack]:
    """Group timed poses into one :class:`PoseTrack` per station.

    ``poses`` is a dict station -> PoseTrack, or an iterable of :class:`PoseSample` or of
    (t_s, station, T 4x4) tuples.
    """
    if isinstance(poses, dict):
        return {int(k): v for k, v in poses.items()}
    rows: dict[int, list[tuple[float, np.ndarray]]] = {}
    for p in poses:
        if isinstance(p, PoseSample):
            t_s, station, T = p.t_s, p.station, p.T_tracker_sensor
        else:
            t_s, station, T = p
        rows.setdefault(int(station), []).append((float(t_s), np.asarray(T, dtype=np.float64)))
    if not rows:
        raise InputError("no poses to write", hint="give at least one timed pose")
    tracks = {}
    for station, items in rows.items():
        items.sort(key=lambda r: r[0])
        T = np.stack([r[1] for r in items])
        tracks[station] = PoseTrack([r[0] for r in items], T[:, :3, 3],
                                    matrix_to_quat_wxyz(T[:, :3, :3]))
    return tracks


def synthesize_chunks(poses, fmt: str = "binary", output_list=(2, 11, 1), units: str = "cm",
                      baud: int = 115200, rate_hz: float = RECORD_RATE_HZ,
                      duration_s: float | None = None, status: str = " "
                      ) -> list[tuple[float, bytes]]:
    """Records a FASTRAK would send for timed poses: one (receive time, record bytes) per record.

    Records are emitted round-robin over the stations at ``rate_hz`` in total (120 Hz shared by
    the stations), each carrying its station's pose interpolated at the record's time; the
    receive time adds the record's transmit time at ``baud`` (10 bits per byte).

    Args:
        poses: dict station -> PoseTrack, or an iterable of PoseSample / (t_s, station, T).
        fmt, output_list, units: the record format to write.
        baud: line rate used for receive-time stamps.
        rate_hz: total record rate.
        duration_s: how long to emit (default: from the first to the last pose).
        status: status character put in every record.
    """
    tracks = _as_tracks(poses)
    layout = make_layout(fmt, output_list)
    stations = sorted(tracks)
    t0 = min(tr.start_s for tr in tracks.values())
    t1 = max(tr.end_s for tr in tracks.values())
    span = (t1 - t0) if duration_s is None else float(duration_s)
    n = int(math.floor(span * rate_hz + 1e-9)) + 1
    k = np.arange(n)
    t_rec = t0 + k / rate_hz
    station_of = np.array(stations)[k % len(stations)]
    positions = np.zeros((n, 3))
    quats = np.zeros((n, 4))
    for s in stations:
        sel = station_of == s
        positions[sel], quats[sel] = tracks[s].at(t_rec[sel])
    transmit_s = layout.length * 10.0 / baud
    records = encode_records(layout, station_of, positions, quats, units, status)
    t_recv = (t_rec - t0 + transmit_s).tolist()
    return list(zip(t_recv, records, strict=True))


def poses_to_capture(poses, fmt: str = "binary", output_list=(2, 11, 1), units: str = "cm",
                     baud: int = 115200, rate_hz: float = RECORD_RATE_HZ,
                     duration_s: float | None = None, extra: dict | None = None) -> bytes:
    """A raw capture file (bytes) of the records a FASTRAK would send for timed poses.

    See :func:`synthesize_chunks` for the arguments; ``extra`` adds header fields.
    """
    tracks = _as_tracks(poses)
    header = CaptureHeader(fmt, tuple(make_layout(fmt, output_list).output_list), units, baud,
                           tuple(sorted(tracks)), {"source": "synthesized", **(extra or {})})
    chunks = synthesize_chunks(tracks, fmt, output_list, units, baud, rate_hz, duration_s)
    return capture_bytes(header, chunks)


def write_capture(path: str | Path, poses, **kwargs) -> Path:
    """Write :func:`poses_to_capture` output to ``path``; return the path."""
    path = Path(path)
    path.write_bytes(poses_to_capture(poses, **kwargs))
    return path


# ---------------------------------------------------------------------------------------------
# Pose log (CSV)


def pose_log_text(batch: RecordBatch) -> str:
    """The pose-log CSV text of decoded records."""
    out = io.StringIO()
    out.write(",".join(POSE_LOG_COLUMNS) + "\n")
    status = [("" if c == 0x20 else chr(c)) for c in batch.status.tolist()]
    for i in range(len(batch)):
        p = batch.position_m[i]
        q = batch.quat_wxyz[i]
        out.write(f"{batch.t_s[i]:.6f},{batch.station[i]},{p[0]:.6f},{p[1]:.6f},{p[2]:.6f},"
                  f"{q[0]:.7f},{q[1]:.7f},{q[2]:.7f},{q[3]:.7f},{status[i]}\n")
    return out.getvalue()


def samples_batch(samples: Iterable[PoseSample]) -> RecordBatch:
    """Pack :class:`PoseSample` objects into a :class:`RecordBatch`."""
    samples = list(samples)
    if not samples:
        return RecordBatch.empty()
    T = np.stack([s.T_tracker_sensor for s in samples])
    return RecordBatch(
        station=np.array([s.station for s in samples], dtype=np.int64),
        status=np.array([ord(s.status or " ") for s in samples], dtype=np.uint8),
        position_m=T[:, :3, 3].copy(), quat_wxyz=matrix_to_quat_wxyz(T[:, :3, :3]),
        stylus=np.array([-1 if s.stylus is None else s.stylus for s in samples], dtype=np.int8),
        offset=np.zeros(len(samples), dtype=np.int64),
        t_s=np.array([s.t_s for s in samples], dtype=np.float64))


def write_pose_log(path: str | Path, records: RecordBatch | Iterable[PoseSample]) -> Path:
    """Write a pose-log CSV from a :class:`RecordBatch` or :class:`PoseSample` objects."""
    batch = records if isinstance(records, RecordBatch) else samples_batch(records)
    path = Path(path)
    try:
        path.write_text(pose_log_text(batch), encoding="utf-8")
    except OSError as exc:
        raise write_error(path, exc, hint="choose a writable output path") from None
    return path


def parse_pose_log(text: str, where: str = "pose log") -> RecordBatch:
    """Parse pose-log CSV text (``#`` comment lines allowed; ``status`` column optional; a
    UTF-8 byte-order mark before the header is skipped, as spreadsheets write one).

    Quaternions are normalised. The rows must be in time order; times that start before 0 or
    after :data:`MAX_START_S` are counted from the first row (see :func:`recording_times`).

    Raises:
        InputError: missing columns, a row that is not numbers, a position beyond the
            tracker's range or a quaternion that is not one, with its line number.
    """
    text = text.removeprefix("\ufeff")  # the byte-order mark some Windows programs write
    # lines end at CR LF, LF or CR only: str.splitlines also ends them at a form feed, U+0085,
    # U+2028 and others, which made the rest of a comment line a pose row (review 23) and
    # numbered the lines unlike an editor
    lines = [(i + 1, line) for i, line in enumerate(LINE_ENDS.split(text))
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{where} is empty", hint="a pose log starts with the header line "
                         + ",".join(POSE_LOG_COLUMNS))
    reader = _csv_rows(lines, where)
    header = [h.strip() for h in next(reader)[1]]
    missing = [c for c in POSE_LOG_COLUMNS[:-1] if c not in header]
    if missing:
        raise InputError(f"{where}: line {lines[0][0]}: missing column(s) {', '.join(missing)}",
                         hint="the header must be " + ",".join(POSE_LOG_COLUMNS))
    col = {name: header.index(name) for name in POSE_LOG_COLUMNS if name in header}
    numeric = POSE_LOG_COLUMNS[:-1]
    values = np.zeros((len(lines) - 1, len(numeric)))
    status = np.full(len(lines) - 1, 0x20, dtype=np.uint8)
    for row_i, (line_no, row) in enumerate(reader):
        try:
            values[row_i] = [float(row[col[name]]) for name in numeric]
        except (ValueError, IndexError):
            raise InputError(f"{where}: line {line_no}: expected numbers in columns "
                             f"{','.join(numeric)}", hint="fix or delete that line") from None
        if "status" in col and col["status"] < len(row):
            text_status = row[col["status"]]
            if len(text_status) > 1:
                raise InputError(f"{where}: line {line_no}: status {quoted(text_status)} is not "
                                 "one character", hint="leave it empty when healthy")
            if text_status and text_status not in _STATUS_TEXT:  # a NUL, a control byte
                raise InputError(f"{where}: line {line_no}: status {quoted(text_status)} is not "
                                 "a FASTRAK status", hint="leave it empty when healthy, else "
                                 "the tracker's error letter (a-z, A-Z)")
            if text_status:
                status[row_i] = ord(text_status)
    if not np.isfinite(values).all():
        bad = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise InputError(f"{where}: line {lines[bad + 1][0]}: NaN or infinite value",
                         hint="every value must be a finite number")
    station = values[:, 1].astype(np.int64)
    if ((station < 1) | (station > 4) | (values[:, 1] != station)).any():
        bad = int(np.flatnonzero((station < 1) | (station > 4) | (values[:, 1] != station))[0])
        raise InputError(f"{where}: line {lines[bad + 1][0]}: station must be 1..4",
                         hint="FASTRAK stations are numbered 1 to 4")
    unit, norm = unit_quats(values[:, 5:9])
    if (norm < 1e-6).any():
        bad = int(np.flatnonzero(norm < 1e-6)[0])
        raise InputError(f"{where}: line {lines[bad + 1][0]}: zero quaternion",
                         hint="qw,qx,qy,qz must be a unit quaternion (scalar first)")
    # a pose beyond the tracker's range (review 21: a log written in centimetres drove both
    # arms to their reach limits for 8 s; the live reader drops such records as garbled)
    reach_m = DEFAULT_PLAUSIBILITY.max_position_m
    far = np.abs(values[:, 2:5]).max(axis=1) > reach_m
    if far.any():
        bad = int(np.flatnonzero(far)[0])
        raise InputError(f"{where}: line {lines[bad + 1][0]}: a pose at "
                         f"{quoted(values[bad, 2:5].tolist())} m, beyond a FASTRAK's "
                         f"{reach_m:g} m; {int(far.sum())} of the {len(far)} rows are so",
                         hint="x_m, y_m, z_m are metres: was the file written in centimetres or "
                              "millimetres? divide them by 100 or 1000")
    far = np.abs(norm - 1.0) > QUAT_NORM_TOL
    if far.any():
        bad = int(np.flatnonzero(far)[0])
        raise InputError(f"{where}: line {lines[bad + 1][0]}: the quaternion's norm is "
                         f"{norm[bad]:.3g}, not 1 (within {QUAT_NORM_TOL:g}); {int(far.sum())} "
                         f"of the {len(norm)} rows are so", hint="qw,qx,qy,qz must be a unit "
                         "quaternion (scalar first): are these columns a quaternion?")
    batch = RecordBatch(station=station, status=status, position_m=values[:, 2:5].copy(),
                        quat_wxyz=unit, stylus=np.full(len(station), -1, np.int8),
                        offset=np.zeros(len(station), dtype=np.int64), t_s=values[:, 0].copy())
    order = interleaved_order(batch.t_s, station)
    if order is not None:  # the stations' rows merged by time (each station's kept in order)
        batch = RecordBatch(*(getattr(batch, f.name)[order] for f in fields(RecordBatch)))
        lines = [lines[0], *(lines[1 + int(i)] for i in order)]
    step = np.diff(batch.t_s)
    bad = bad_time_step(step)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])  # the row before the bad step
        line, t_before, t_after = lines[i + 2][0], batch.t_s[i], batch.t_s[i + 1]
        if step[i] > 0:
            raise InputError(f"{where}: line {line}: t_s {t_after:g} s is more than "
                             f"{MAX_CHUNK_GAP_S:g} s after the time before it",
                             hint="times must be seconds of one recording, without gaps of "
                                  "hours")
        back = _station_goes_back(batch.t_s, batch.station)
        whose = "the row"
        if back is not None and back[1] != i + 1:  # that step is the stations' skew (allowed);
            i, j = back  # a station's own time goes back further on
            line, t_before, t_after = lines[j + 1][0], batch.t_s[i], batch.t_s[j]
            whose = f"station {batch.station[j]}'s row"
        raise InputError(f"{where}: line {line}: t_s {t_after:.6g} s is earlier than {whose} "
                         f"before it ({t_before:.6g} s)",
                         hint="a pose log's rows are in time order, as recorded (the stations' "
                              f"rows within {MAX_STATION_SKEW_S:g} s of each other); two "
                              "recordings are two files")
    batch.t_s = recording_times(batch.t_s, where)
    _check_repeated_times(batch, lines, where)
    return batch


def _check_repeated_times(batch: RecordBatch, lines: list[tuple[int, str]], where: str) -> None:
    """Refuse a station whose time repeats in more than :data:`MAX_SAME_TIME_ROWS` of its rows
    in a row (``lines``: the numbered lines, header first)."""
    for s in np.unique(batch.station):
        rows = np.flatnonzero(batch.station == s)
        same = np.diff(batch.t_s[rows]) == 0.0  # row k + 1 has row k's time
        count = np.cumsum(same)
        repeats = count - np.maximum.accumulate(np.where(same, 0, count))  # in a row, to k
        over = np.flatnonzero(repeats >= MAX_SAME_TIME_ROWS)
        if over.size:
            k = int(over[0]) + 1  # the first row too many, and the run's first
            first, last = lines[rows[k - MAX_SAME_TIME_ROWS] + 1][0], lines[rows[k] + 1][0]
            raise InputError(f"{where}: lines {first}-{last}: station {s}'s rows all have t_s "
                             f"{batch.t_s[rows[k]]:g} s ({MAX_SAME_TIME_ROWS + 1} in a row; a "
                             f"tracker sends {MAX_SAME_TIME_ROWS} in 0.25 s): their motion "
                             "would replay as one instant",
                             hint="each row's t_s is the time its record was received; fix "
                                  "the times or cut those rows")


def _csv_rows(lines: list[tuple[int, str]], where: str):
    """(line number, cells) of each numbered line; a line the csv module refuses (a field
    over its size limit, a NUL) is an InputError naming it."""
    reader = csv.reader([line for _, line in lines])
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            line_no = lines[min(reader.line_num, len(lines)) - 1][0]
            raise InputError(f"{where}: line {line_no}: not a pose-log row ({exc})",
                             hint="fix or delete that line") from None
        yield lines[reader.line_num - 1][0], row


def read_pose_log(path: str | Path) -> RecordBatch:
    """Read a pose-log CSV file (see :func:`parse_pose_log`)."""
    return parse_pose_log(decode_pose_log(read_recording_bytes(path), str(path)), str(path))


# ---------------------------------------------------------------------------------------------
# Replay


@dataclass
class Recording:
    """A decoded recording: records, counters, and what it is."""

    batch: RecordBatch
    stats: SourceStats
    info: dict


def no_records_error(path: str | Path, cap: Capture) -> InputError:
    """The error for a raw capture none of whose records decodes."""
    h = cap.header
    items = quoted(",".join(map(str, h.output_list)))
    return InputError(f"{path}: no valid FASTRAK records in {len(cap.data)} bytes",
                      hint=f"the header says {h.fmt} {items} in {h.units}; check it matches "
                           "what was recorded")


def load_recording(path: str | Path, stations=None,
                   plausibility: Plausibility = DEFAULT_PLAUSIBILITY) -> Recording:
    """Read and decode a raw capture or a pose log (recognised from its first bytes).

    Args:
        path: the recording.
        stations: keep only these stations (default: all in the file).
        plausibility: limits for raw-capture records.

    Raises:
        InputError: missing, unreadable or garbled file, or no valid record in it.
    """
    blob = read_recording_bytes(path)
    stats = SourceStats()
    if blob.startswith(MAGIC):
        cap = parse_capture(blob, str(path))
        batch, bad = cap.decode(plausibility)
        stats.add(batch, bad, len(cap.data))
        h = cap.header
        info = {"kind": "capture", "path": str(path), "format": h.fmt,
                "output_list": list(h.output_list), "units": h.units, "baud": h.baud,
                "stations": list(h.stations), "truncated": cap.truncated, **h.extra}
        if len(batch) == 0:
            raise no_records_error(path, cap)
    else:
        batch = parse_pose_log(decode_pose_log(blob, str(path)), str(path))
        stats.add(batch, 0, len(blob))
        info = {"kind": "pose-log", "path": str(path),
                "stations": sorted(set(batch.station.tolist()))}
        if len(batch) == 0:
            raise InputError(f"{path}: the pose log has a header but no rows",
                             hint="record some poses first")
    if stations is not None:
        wanted = {int(s) for s in stations}
        batch = batch.select(np.isin(batch.station, list(wanted)))
        if len(batch) == 0:
            raise InputError(f"{path}: no records for station(s) {sorted(wanted)}",
                             hint=f"the file has stations {sorted(stats.per_station)}")
    return Recording(batch, stats, info)


def open_replay(path: str | Path, stations=None,
                plausibility: Plausibility = DEFAULT_PLAUSIBILITY) -> ReplaySource:
    """A :class:`ReplaySource` over a raw capture or a pose log."""
    rec = load_recording(path, stations, plausibility)
    return ReplaySource(batch_samples(rec.batch), rec.info, rec.stats)


def utc_stamp() -> str:
    """Current UTC time as ISO 8601 text (for capture headers)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
