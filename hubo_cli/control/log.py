"""The per-period log: one row per control period, stored as the loop runs, a CSV at the end.

A run folder's log is three files:

* ``log.csv``: line 1 is the header, then one row per period (plain CSV: pandas, polars and
  spreadsheets read it with no options). Every column name ends in its unit (``_s`` seconds,
  ``_us`` microseconds, ``_rad`` radians, ``_m`` metres, ``_nm`` newton metres, ``_count`` a
  count, ``_code`` an enumeration, ``_flag`` 0/1) except ``flags``, a ``;``-separated list of
  words; numbers always read as floats (a whole number is written ``1.0``, a missing one
  ``NaN``). The columns, in order: ``period_count, t_s, status_code, compute_us, late_us, flags``;
  ``target_<joint>_rad`` (NaN when no target came that period), ``cmd_<joint>_rad`` (what the
  driver was sent), ``q_<joint>_rad`` (measured after the step); the torso (base) pose in the
  world ``torso_{x,y,z}_m, torso_{roll,pitch,yaw}_rad`` (URDF convention,
  R = Rz(yaw) Ry(pitch) Rx(roll); the simulator's truth, ``RobotState.truth``; on a robot
  without one the position is NaN and the orientation the IMU's); when the log knows the robot
  model, the measured hand frames in the world ``{right,left}_hand_{x,y,z}_m,
  ..._{roll,pitch,yaw}_rad`` (forward kinematics of the measured arm joints through the torso
  pose; NaN where the torso position is unknown); the feet: ``{right,left}_foot_fz_n`` (the
  ankle F/T sensor's normal force) and ``{right,left}_foot_contact_flag`` (the simulator's
  true contact; NaN without a simulator); then the modules' and the caller's extra columns
  (NaN when not reported that period; e.g. a task's commanded and measured tool positions
  ``goal_*_m``, ``actual_*_m`` in its stance frame), the estimate's beside the truth last
  (``est_torso_{x,y,z}_m``, ``est_torso_yaw_rad``, ``est_tilt_rad``, ``est_com_{x,y,z}_m``:
  :attr:`~hubo_cli.estimation.estimator.Estimator.log_columns`).
* ``log.json`` (sidecar): the format name and version, when the run started (``started_utc``,
  UTC ISO 8601) and the ``hubo_cli_version`` that wrote it, the unit legend, the status codes, the
  joint names, the columns, the row count and the run's metadata (:meth:`PeriodLog.set_metadata`:
  e.g. ``scene`` with the walls, the tool per hand and the hole's points as cut). Written when
  the log opens and again when it closes.
* ``log.parquet``: the same table, written when the log closes (smaller and faster to read;
  counters, codes and flags as integers, the sidecar's facts and each column's unit in the
  file's metadata, see :mod:`hubo_cli.control.log_parquet`).

While the run goes, each period is stored as one binary record (the row's numbers as float64,
its flags as a number into ``log.flags``, see :data:`ROWS_MAGIC`) in ``log.rows``, a file mapped
into memory: the record is in the operating system's page cache as soon as it is stored, so a
crash of the process (an exception, Ctrl-C, a kill) loses at most the period being written, as
a CSV row flushed every period would. The CSV is made from the records when the log closes (the
loop closes it however the run ends: done, an error, Ctrl-C or SIGTERM), in the same text a
row-by-row writer gives, and ``log.rows`` and ``log.flags`` are removed then. Where the process
died before that, the run folder still holds them: :func:`recover_log` writes the CSV, the
Parquet copy and the sidecar's row count from them, and :func:`load_log` does so by itself.
:func:`load_log` reads a log back into numpy arrays (the Parquet copy when there is one, else
the CSV; logs of the first format, with a leading ``#`` line, are read too).

``log.rows`` grows a block of records at a time, each block allocated on the disk before it is
mapped (``posix_fallocate``): a full disk is an ``OSError`` (ENOSPC) when a block is asked
for, never a SIGBUS while a mapped page is written. A write that fails (full disk, I/O error)
is kept in :attr:`PeriodLog.error` and the log stops there: the records stored before it stay
whole, later periods are not logged, and the loop ends the run with its smooth stop
(``ended: log-error``). Where the CSV cannot be written at close, ``log.rows`` and
``log.flags`` are kept for :func:`recover_log`.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import mmap
import os
import re
import struct
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from hubo_cli import __version__
from hubo_cli.control.log_checks import check_sidecar, check_times, suspect_values
from hubo_cli.control.log_kernels import pose_row
from hubo_cli.control.log_parquet import write_log_parquet
from hubo_cli.control.status import Status
from hubo_cli.errors import DeviceError, InputError
from hubo_cli.runs import _jsonable
from hubo_cli.streams import refuse_special_files

try:  # POSIX: a live log's records are locked by their writer
    import fcntl
except ImportError:  # pragma: no cover (no advisory locks: recover_log trusts the caller)
    fcntl = None

try:  # Linux, the BSDs: a file's blocks allocated up front
    from os import posix_fallocate as _fallocate
except ImportError:  # pragma: no cover (macOS, Windows)
    _fallocate = None

LOG_NAME = "log.csv"
META_NAME = "log.json"
PARQUET_NAME = "log.parquet"
ROWS_NAME = "log.rows"
FLAGS_NAME = "log.flags"
# log.rows: ROWS_MAGIC (16 bytes); the number of records stored (little-endian uint64, updated
# after each record); a uint32 n and n bytes of JSON (the columns and how many of them are
# joints, poses and extras); zeros to a multiple of 8 bytes; then the records, each one
# little-endian float64 per column: the flags (the line of log.flags holding their text, a JSON
# string), then every other column in order. The file grows in blocks (unused records are zero).
# log.flags: one JSON string a line, each distinct flags text once, written before its first use
ROWS_MAGIC = b"HUBO-PERIOD-ROWS"
_COUNT_AT = len(ROWS_MAGIC)
_HEAD_AT = _COUNT_AT + 8
_BLOCK_ROWS = 1024  # 5 s of periods at 200 Hz per allocation
FORMAT_NAME = "hubo-cli period log"
FORMAT_VERSION = 2
FIXED_COLUMNS = ("period_count", "t_s", "status_code", "compute_us", "late_us", "flags")
POSE_AXES = ("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")
HAND_ARMS = {"right_hand": "right-arm", "left_hand": "left-arm"}
FEET_COLUMNS = ("right_foot_fz_n", "left_foot_fz_n", "right_foot_contact_flag",
                "left_foot_contact_flag")
FEET_SENSORS = ("right-ankle", "left-ankle")
UNIT_LEGEND = ("units in column names: _s seconds, _us microseconds, _rad radians, _m metres, "
               "_n newtons, _nm newton metres, _deg degrees, _count count, _code enumeration, "
               "_flag 0/1")


def _float_text(value: float, spec: str) -> str:
    """``spec % value``, written ``%.1f`` when the value is a whole number."""
    if math.isfinite(value) and value == int(value):
        return "%.1f" % value
    return "NaN" if math.isnan(value) else spec % value


def pose_columns(frame: str) -> tuple[str, ...]:
    """The six column names of a frame's world pose (``torso``, ``right_hand``, ...)."""
    return tuple(f"{frame}_{axis}" for axis in POSE_AXES)


def rpy_from_rotation(R: np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) with R = Rz(yaw) Ry(pitch) Rx(roll) (URDF convention)."""
    return _rpy_from_rows(*np.asarray(R, dtype=float)[:3, :3].tolist())


def _rpy_from_rows(r0, r1, r2) -> tuple[float, float, float]:
    """:func:`rpy_from_rotation` of a rotation's rows given as Python floats (a pose's rows
    may carry a fourth entry, the translation, which is ignored)."""
    cos_pitch = math.hypot(r0[0], r1[0])
    pitch = math.atan2(-r2[0], cos_pitch)
    if cos_pitch < 1e-12:  # gimbal lock: put everything in yaw
        return 0.0, pitch, math.atan2(-r0[1], r1[1])
    return math.atan2(r2[1], r2[2]), pitch, math.atan2(r1[0], r0[0])


def rotation_from_rpy(roll, pitch, yaw) -> np.ndarray:
    """Rotation matrices Rz(yaw) Ry(pitch) Rx(roll) for scalars (3x3) or arrays (N x 3 x 3)."""
    roll, pitch, yaw = (np.asarray(v, dtype=float) for v in (roll, pitch, yaw))
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    R = np.stack([np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
                  np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
                  np.stack([-sp, cp * sr, cp * cr], -1)], -2)
    return R


def _rotation_from_quat_wxyz(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _feet_values(state) -> list[float]:
    """The FEET_COLUMNS of a state: the ankles' F_z (N) and the true contact flags (NaN
    without a simulator's truth)."""
    values = []
    for sensor in FEET_SENSORS:
        wrench = state.ft.get(sensor)
        values.append(math.nan if wrench is None else float(wrench[2]))
    truth = state.truth
    values += ([math.nan, math.nan] if truth is None
               else [float(bool(c)) for c in truth.feet_contact])
    return values


def _stacked_chains(hands, joints: int) -> tuple[np.ndarray, ...]:
    """The hands' arm chains (``(limb, joint slice)`` pairs) stacked for
    :func:`~hubo_cli.control.log_kernels.pose_row`: joint index, base, offset, alpha, a, d and
    end, one row per hand (empty without hands); ``joints`` is the length of a joint vector."""
    hands = list(hands)
    index = np.array([np.arange(joints)[sl] for _, sl in hands],
                     dtype=np.int64).reshape(len(hands), 6)
    parts = [np.array([limb.fk_chain[k] for limb, _ in hands], dtype=float) for k in range(6)]
    shapes = ((4, 4), (6,), (6,), (6,), (6,), (4, 4))
    parts = [p.reshape(len(hands), *shape) for p, shape in zip(parts, shapes, strict=True)]
    return (index, *parts)


def utc_now_iso() -> str:
    """Now as UTC ISO 8601 to the microsecond, ``2026-11-28T18:17:32.123456Z``."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def status_codes() -> dict[int, str]:
    """Status code -> label, as written in the sidecar."""
    return {s.value: s.label for s in Status}


class PeriodLog:
    """Append-as-you-go log of a control run (records while it runs, see the module
    docstring), with its CSV, JSON sidecar and Parquet copy.

    Args:
        path: the CSV file to create at close (its folder must exist); the sidecar, the
            Parquet copy and, while the log is open, the records are beside it (``log.json``,
            ``log.parquet``, ``log.rows`` and ``log.flags`` for ``log.csv``).
        joint_names: joint names in command order.
        extra_columns: further numeric columns (names ending in their unit).
        model: the robot model; when given (and the joints are the model's), the measured hand
            frames' world poses are logged too.
    """

    def __init__(self, path: str | Path, joint_names, extra_columns=(), model=None) -> None:
        self.path = Path(path)
        self.meta_path = self.path.with_suffix(".json")
        self.parquet_path = self.path.with_suffix(".parquet")
        self.joint_names = tuple(joint_names)
        self._hands = self._hand_kinematics(model)
        pose_names = (pose_columns("torso") + sum((pose_columns(f) for f in self._hands), ())
                      + FEET_COLUMNS)
        self.extra_columns = tuple(c for c in dict.fromkeys(extra_columns)
                                   if c not in pose_names)
        joints = self.joint_names
        self.columns = (FIXED_COLUMNS
                        + tuple(f"target_{j}_rad" for j in joints)
                        + tuple(f"cmd_{j}_rad" for j in joints)
                        + tuple(f"q_{j}_rad" for j in joints)
                        + pose_names + self.extra_columns)
        # one record as float64, filled in place each period (see write)
        self._record = np.zeros(len(self.columns), dtype="<f8")
        n = len(joints)
        self._at_joints = (len(FIXED_COLUMNS), len(FIXED_COLUMNS) + n,
                           len(FIXED_COLUMNS) + 2 * n, len(FIXED_COLUMNS) + 3 * n)
        self._at_feet = self._at_joints[3] + 6 * (1 + len(self._hands))
        self._at_extras = self._at_feet + len(FEET_COLUMNS)
        self._hand_chains = _stacked_chains(self._hands.values(), n)
        self._no_extras = (math.nan,) * len(self.extra_columns)  # a column without a value
        self.metadata: dict = {}
        self.started_utc = utc_now_iso()  # just before the first period
        self.rows = 0
        self.rows_path, self.flags_path = _record_paths(self.path)
        layout = {"columns": list(self.columns), "joints": len(joints),
                  "poses": len(pose_names), "extras": len(self.extra_columns)}
        head = json.dumps(layout).encode()
        self._data_at = -(-(_HEAD_AT + 4 + len(head)) // 8) * 8
        self._record_bytes = 8 * len(self.columns)
        self._flag_ids: dict[str, float] = {}
        self.error = ""  # the first write that failed (one line); the log stopped there
        self._map: mmap.mmap | None = None
        try:
            self.path.unlink(missing_ok=True)  # the CSV comes at close
            self._flags_fd = os.open(self.flags_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
                                     0o644)
            # held open and locked while the run writes, so that recover_log leaves a live
            # log alone
            self._rows_file = open(self.rows_path, "w+b")  # noqa: SIM115 (kept open)
            if fcntl is not None:
                fcntl.flock(self._rows_file, fcntl.LOCK_EX)
            self._rows_file.write(ROWS_MAGIC + struct.pack("<QI", 0, len(head)) + head)
            self._rows_file.flush()
            _allocate(self._rows_file.fileno(), self._data_at + _BLOCK_ROWS * self._record_bytes)
            self._map = mmap.mmap(self._rows_file.fileno(), 0)
            self._write_sidecar()
        except OSError as exc:  # nothing has moved yet: the run is refused
            self._discard()
            raise DeviceError(f"cannot start the log in {self.path.parent}: "
                              f"{_os_reason(exc)}",
                              hint="free space on that disk or choose another --out") from None

    def _hand_kinematics(self, model) -> dict:
        if model is None or tuple(model.joint_names) != self.joint_names:
            return {}
        from hubo_cli.kinematics.limb import Limb

        return {frame: (Limb(model, arm, "hand"), model.limb_slice(arm))
                for frame, arm in HAND_ARMS.items()}

    def write(self, period: int, t_s: float, status: int, compute_us: float, late_us: float,
              flags, target_rad, cmd_rad, q_rad, extras: dict | None = None,
              state=None) -> None:
        """Append one period (one record in ``log.rows``, with the operating system when this
        returns).

        ``state`` (the :class:`~hubo_cli.state.RobotState` after the step) gives the
        torso and hand poses; without it they are NaN.
        """
        if self._map is None or self.error:
            return
        flag_text = ";".join(sorted(flags))
        flag_id = self._flag_ids.get(flag_text)
        if flag_id is None:  # a new flags text: in log.flags before a record points to it
            try:
                _write_all(self._flags_fd, (json.dumps(flag_text) + "\n").encode())
            except OSError as exc:
                self._failed(exc, self.flags_path)
                return
            flag_id = self._flag_ids[flag_text] = float(len(self._flag_ids))
        # the record filled in place: numbers as numpy converts them (float64, as struct does)
        record = self._record
        record[:6] = (flag_id, period, t_s, status, compute_us, late_us)
        a, b, c, d = self._at_joints
        record[a:b] = target_rad
        record[b:c] = cmd_rad
        record[c:d] = q_rad
        self._pose_record(q_rad, state)
        if self.extra_columns:
            if extras:
                # numpy converts each as float() does (a None, which float() refuses, as NaN)
                record[self._at_extras:] = list(map(extras.get, self.extra_columns,
                                                    self._no_extras))
            else:
                record[self._at_extras:] = math.nan
        at = self._data_at + self.rows * self._record_bytes
        if at + self._record_bytes > len(self._map):  # the next block, on the disk first
            size = len(self._map) + _BLOCK_ROWS * self._record_bytes
            try:
                _allocate(self._rows_file.fileno(), size)
                self._map.resize(size)
            except OSError as exc:
                self._failed(exc, self.rows_path)
                return
        self._map[at:at + self._record_bytes] = record  # its buffer: no bytes copy first
        self.rows += 1
        self._map[_COUNT_AT:_HEAD_AT] = self.rows.to_bytes(8, "little")  # the record counts

    def _discard(self) -> None:
        """Close and remove what a log that could not start had opened."""
        for name in ("_flags_fd", "_rows_file"):
            handle = self.__dict__.pop(name, None)
            with contextlib.suppress(OSError):
                if isinstance(handle, int):
                    os.close(handle)
                elif handle is not None:
                    handle.close()
        for path in (self.rows_path, self.flags_path, self.meta_path):
            with contextlib.suppress(OSError):
                path.unlink(missing_ok=True)

    def _failed(self, exc: OSError, path: Path) -> None:
        """Keep the first failed write as :attr:`error`; the log takes no more periods."""
        if not self.error:
            self.error = f"cannot write the log {path}: {_os_reason(exc)}"

    def _pose_record(self, q_rad, state) -> None:
        """The record's torso, hand and feet columns: the torso's and hands' world poses
        (compiled, :func:`~hubo_cli.control.log_kernels.pose_row`), then the feet."""
        record, at = self._record, self._at_joints[3]
        if state is None:
            record[at:self._at_extras] = math.nan
            return
        T_world_torso = None if state.truth is None else state.truth.T_world_torso
        if T_world_torso is None:
            T_world_torso = np.eye(4)
            T_world_torso[:3, :3] = _rotation_from_quat_wxyz(state.imu_quat_wxyz)
            T_world_torso[:3, 3] = math.nan
        pose_row(np.ascontiguousarray(T_world_torso, dtype=float),
                 np.ascontiguousarray(q_rad, dtype=float), *self._hand_chains, record, at)
        record[self._at_feet:self._at_extras] = _feet_values(state)

    def set_metadata(self, key: str, value) -> None:
        """Record run metadata (JSON-able: numbers, strings, lists, dicts, numpy arrays) in the
        sidecar. Before :meth:`close` it is written at close; after, the sidecar is rewritten."""
        self.metadata[str(key)] = _jsonable(value)
        if self._map is None:
            self._write_sidecar()

    def _write_sidecar(self) -> None:
        _write_sidecar_json(self.meta_path, self._sidecar_head(), self.metadata, jsonable=True)

    def _sidecar_head(self) -> dict:
        """The sidecar's fixed part (all but the metadata)."""
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION,
                "started_utc": self.started_utc, "hubo_cli_version": __version__,
                "csv": self.path.name,
                "parquet": self.parquet_path.name if self.parquet_path.exists() else None,
                "units": UNIT_LEGEND, "status_codes": status_codes(),
                "joint_names": list(self.joint_names), "rows": self.rows,
                "columns": list(self.columns)}

    def close(self) -> None:
        """Write the CSV from the records, then the Parquet copy and the sidecar, and remove
        ``log.rows`` and ``log.flags``; safe to call twice."""
        if self._map is None:
            return
        # the count again: an interrupt may have landed between a record and its count
        self._map[_COUNT_AT:_HEAD_AT] = self.rows.to_bytes(8, "little")
        self._map.close()
        self._map = None
        os.close(self._flags_fd)
        try:
            if not self.error:  # else the records are all there is: kept for recover_log
                _csv_from_rows(self.rows_path, self.flags_path, self.path)
                write_log_parquet(_read_csv(self.path), self.parquet_path, self._sidecar_head())
                self._write_sidecar()
                self.rows_path.unlink()
                self.flags_path.unlink()
        except OSError as exc:  # a full disk at the end: the records stay, no half CSV
            self._failed(exc, self.path)
            for path in (self.path, self.parquet_path):
                with contextlib.suppress(OSError):
                    path.unlink(missing_ok=True)
        finally:
            self._rows_file.close()  # releases the lock

    def __enter__(self) -> PeriodLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def set_log_metadata(run_dir: str | Path, key: str, value) -> None:
    """Add metadata to a closed run's sidecar (``log.json``), e.g. the scene after the run."""
    update_log_metadata(run_dir, {key: value})


def update_log_metadata(run_dir: str | Path, items: dict) -> None:
    """Add several metadata keys to a closed run's sidecar at once (in ``items``' order)."""
    path = Path(run_dir)
    path = path / META_NAME if path.is_dir() else path.with_suffix(".json")
    sidecar = json.loads(path.read_text(encoding="utf-8"))
    metadata = sidecar.pop("metadata", {})  # read from JSON: already JSON-able
    for key, value in items.items():
        metadata[str(key)] = _jsonable(value)
    _write_sidecar_json(path, sidecar, metadata, jsonable=True)


def _write_sidecar_json(path: Path, head: dict, metadata: dict, jsonable: bool = False) -> None:
    """The sidecar: its fixed part indented, the metadata (point lists) on one line each key
    (``jsonable``: the metadata's values are JSON-able already)."""
    lines = json.dumps(_jsonable(head), indent=1)[:-2]  # without the closing "\n}"
    items = ",\n".join(f"  {json.dumps(k)}: {json.dumps(v if jsonable else _jsonable(v))}"
                        for k, v in metadata.items())
    body = f"{{\n{items}\n }}" if items else "{}"
    path.write_text(f"{lines},\n \"metadata\": {body}\n}}\n", encoding="utf-8")


def _allocate(fd: int, size: int) -> None:
    """Make a file ``size`` bytes long with its blocks allocated on the disk (ENOSPC now
    rather than a SIGBUS when a mapped page is first written)."""
    if _fallocate is not None:
        _fallocate(fd, 0, size)
    else:  # pragma: no cover (macOS: no preallocation; a full disk may still SIGBUS there)
        os.ftruncate(fd, size)


def _os_reason(exc: OSError) -> str:
    """The operating system's words for a failed write (``No space left on device``)."""
    return exc.strerror or str(exc) or type(exc).__name__


def _write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte is written (a regular file takes them in one call)."""
    while data:
        data = data[os.write(fd, data):]


def _float_column_formats(whole: np.ndarray, specs: list[str]):
    """Per row, the format of its numbers: ``%.1f`` where one is a whole number, else its
    column's spec (one format string per distinct pattern)."""
    keys = np.packbits(whole, axis=1)
    formats: dict[bytes, str] = {}
    out = []
    for key, row in zip(keys, whole, strict=True):
        k = key.tobytes()
        fmt = formats.get(k)
        if fmt is None:
            fmt = formats[k] = ",".join("%.1f" if w else spec
                                         for w, spec in zip(row.tolist(), specs, strict=True))
        out.append(fmt)
    return out


def _record_paths(csv_path: Path) -> tuple[Path, Path]:
    """(``log.rows``, ``log.flags``) beside a log's CSV."""
    return csv_path.with_suffix(".rows"), csv_path.with_suffix(".flags")


def read_rows(rows_path: str | Path, flags_path: str | Path) -> tuple[dict, np.ndarray,
                                                                        list[str]]:
    """The records of a ``log.rows`` file and its ``log.flags``: the layout (``columns``,
    ``joints``, ``poses``, ``extras``), the numbers (rows x columns but the flags, float64)
    and each row's flags text. Only the records the file counts are read (one being written
    when the process died is not counted).

    Raises:
        InputError: not a record file, a damaged one (its header, layout or a record's flags
            index; review 28: an internal error), or its ``log.flags`` missing or damaged.
    """
    data = Path(rows_path).read_bytes()
    if not data.startswith(ROWS_MAGIC):
        raise InputError(f"{rows_path} is not a period log's record file",
                         hint="give a run folder written by hubo, or remove the file")
    try:
        text = Path(flags_path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{flags_path} is missing: the flags of {rows_path}'s records are "
                         "lost", hint=_DAMAGED_RECORDS_HINT) from None
    try:
        count, n_head = struct.unpack_from("<QI", data, _COUNT_AT)
        layout = json.loads(data[_HEAD_AT + 4:_HEAD_AT + 4 + n_head])
        _check_layout(layout)
        data_at = -(-(_HEAD_AT + 4 + n_head) // 8) * 8
        width = len(layout["columns"])
        count = max(0, min(count, (len(data) - data_at) // (8 * width)))
        table = np.frombuffer(data, dtype="<f8", count=count * width,
                              offset=data_at).reshape(count, width)
        # a line cut short by a failed write is not used by any record
        texts = [json.loads(line) for line in text[:text.rfind("\n") + 1].splitlines()]
        index = table[:, 0]
        if not np.all((index >= 0) & (index < len(texts)) & (index == np.round(index))):
            raise ValueError("a record's flags are not in log.flags")
        flags = [texts[i] for i in index.astype(int).tolist()]
        if not all(isinstance(f, str) for f in flags):
            raise ValueError("log.flags holds a line that is not text")
    except (struct.error, ValueError, KeyError, TypeError, IndexError, ZeroDivisionError,
            RecursionError) as exc:
        raise InputError(f"{rows_path} is damaged: {str(exc)[:120] or type(exc).__name__}",
                         hint=_DAMAGED_RECORDS_HINT) from None
    return layout, table[:, 1:].astype(float), flags


_COLUMN_NAME = re.compile(r'[^\s,"]+')  # what a CSV header holds unquoted


def _check_layout(layout) -> None:
    """Raise ValueError unless ``layout`` is one a :class:`PeriodLog` writes: unique plain
    column names, ``flags`` sixth, and as many numbers as its joints, poses and extras."""
    columns = layout.get("columns") if isinstance(layout, dict) else None
    counts = [layout.get(k) for k in ("joints", "poses", "extras")] if columns else []
    if not (isinstance(columns, list) and all(isinstance(n, int) and not isinstance(n, bool)
                                               and n >= 0 for n in counts)
            and all(isinstance(c, str) and _COLUMN_NAME.fullmatch(c) for c in columns)
            and len(set(columns)) == len(columns) and columns[:6] == list(FIXED_COLUMNS)
            and len(columns) == 6 + 3 * counts[0] + counts[1] + counts[2]):
        raise ValueError("its layout is not a period log's")


_DAMAGED_RECORDS_HINT = ("the run's records cannot be made into its log; keep the folder as it "
                         "is for inspection, or give another run")


def _csv_from_rows(rows_path: Path, flags_path: Path, csv_path: Path) -> int:
    """Write the CSV of a ``log.rows`` file; returns its row count. Numbers always carry a
    ``.`` (or are ``NaN``/``inf``), so that CSV readers that guess types from the first rows
    (polars, pandas) read every real-valued column as floats; a whole number is written
    ``1.0``; the period count and the status code are integers. Joints have 15 significant
    digits, so that finite differences of the log (velocity, acceleration) are exact to about
    1e-9 rad/s^2; poses 12 (sub-nanometre); the other numbers 9."""
    layout, rows, flags = read_rows(rows_path, flags_path)
    specs = (["%.15g"] * (3 * layout["joints"]) + ["%.12g"] * layout["poses"]
             + ["%.9g"] * layout["extras"])
    body = rows[:, 5:]
    whole = np.isfinite(body) & (body == np.trunc(body))
    formats = _float_column_formats(whole, specs)
    with open(csv_path, "w", encoding="utf-8") as f:
        f.write(",".join(layout["columns"]) + "\n")
        for start in range(0, len(rows), _BLOCK_ROWS):  # a block of lines at a time
            block = range(start, min(start + _BLOCK_ROWS, len(rows)))
            lines = []
            for row, k in zip(rows[block.start:block.stop].tolist(), block, strict=True):
                period, t_s, status, compute_us, late_us = row[:5]
                lines.append(
                    f"{int(period):d},{_float_text(t_s, '%.9g')},{int(status):d},"
                    f"{_float_text(compute_us, '%.6g')},{_float_text(late_us, '%.6g')},"
                    f"{flags[k]},{(formats[k] % tuple(row[5:])).replace('nan', 'NaN')}\n")
            f.write("".join(lines))
    return len(rows)


def recover_log(path: str | Path) -> bool:
    """Finish the log of a run whose process died before closing it: the CSV, the Parquet
    copy and the sidecar's row count from ``log.rows`` and ``log.flags`` (a run folder or any
    of its log files), which are removed then. Returns False when there is nothing to
    recover."""
    csv_path, meta_path, parquet_path = log_paths(path)
    rows_path, flags_path = _record_paths(csv_path)
    try:
        rows_file = open(rows_path, "rb")  # noqa: SIM115 (closed below)
    except FileNotFoundError:
        return False
    with rows_file:
        try:  # the writer holds this lock until its log is closed
            if fcntl is not None:
                fcntl.flock(rows_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(f"the run writing {csv_path.parent} is still going: its log is "
                             "made when it ends", hint="wait for the run to end, then read it"
                             ) from None
        return _recover(rows_path, flags_path, csv_path, meta_path, parquet_path)


def _recover(rows_path: Path, flags_path: Path, csv_path: Path, meta_path: Path,
             parquet_path: Path) -> bool:
    """:func:`recover_log`'s work, with the record file locked. A CSV it could not write
    whole (a read-only folder, a full disk) is not left behind."""
    try:
        rows = _csv_from_rows(rows_path, flags_path, csv_path)
    except OSError:
        with contextlib.suppress(OSError):
            csv_path.unlink(missing_ok=True)
        raise
    sidecar = json.loads(meta_path.read_text(encoding="utf-8")) if meta_path.exists() else {}
    metadata = sidecar.pop("metadata", {})
    write_log_parquet(_read_csv(csv_path), parquet_path, sidecar)
    if meta_path.exists():
        sidecar.update(rows=rows, parquet=parquet_path.name)
        _write_sidecar_json(meta_path, sidecar, metadata, jsonable=True)
    rows_path.unlink()
    flags_path.unlink(missing_ok=True)
    return True


def _read_csv(path: Path):
    """The CSV as a polars DataFrame: numbers as float64, ``flags`` as text; a leading ``#``
    line (first format) is skipped and a last row cut short by a crash is dropped."""
    import polars as pl

    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        data = data[:data.rfind(b"\n") + 1]
    start = data.find(b"\n") + 1 if data.startswith(b"#") else 0
    end = data.find(b"\n", start)
    header = data[start:end if end >= 0 else len(data)].decode().strip().split(",")
    schema = {name: (pl.String if name == "flags" else pl.Float64) for name in header}
    return pl.read_csv(io.BytesIO(data[start:]), schema=schema, has_header=True)


@dataclass
class LogData:
    """A loaded period log.

    Attributes:
        columns: column name -> numpy array (float), every column except ``flags``.
        flags: the ``flags`` column, one list of words per period.
        joint_names: the joints found in the ``cmd_*`` columns, in order.
        metadata: the run metadata from the sidecar (empty for logs without one).
        started_utc: when the run started (UTC, ISO 8601), from the sidecar; None for logs
            written before it was recorded.
        hubo_cli_version: the hubo-cli that wrote the log (None, likewise).
        unfinished: "" for a finished log; for a killed run's records that could not be
            made into its CSV (a read-only folder), one line saying so and why.
        periods_expected: the periods the run logged, from the sidecar (None without one);
            more than were read when the log file was cut (:attr:`cut_short`).
        suspect: one line per kind of value the robot cannot have logged, naming its rows
            (made unknown where it was a position; :mod:`hubo_cli.control.log_checks`).
    """

    columns: dict[str, np.ndarray]
    flags: list[list[str]]
    joint_names: tuple[str, ...]
    metadata: dict = field(default_factory=dict)
    started_utc: str | None = None
    hubo_cli_version: str | None = None
    unfinished: str = ""
    periods_expected: int | None = None
    suspect: list[str] = field(default_factory=list)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    @property
    def cut_short(self) -> str:
        """"" for a whole log; else one line saying it ends early: the periods read and the
        periods its sidecar says the run logged (a log.csv cut after the run, no log.parquet)."""
        if self.periods_expected is None or len(self) >= self.periods_expected:
            return ""
        return (f"the log ends early: {len(self)} of the {self.periods_expected} periods the "
                f"run logged (its log.json); what follows shows the first "
                f"{len(self) / self.periods_expected:.0%}")

    def joints(self, kind: str) -> np.ndarray:
        """An (N, joints) array of ``target``, ``cmd`` or ``q`` values (rad)."""
        return np.column_stack([self.columns[f"{kind}_{j}_rad"] for j in self.joint_names])

    def has_pose(self, frame: str) -> bool:
        """Whether the log has the world pose columns of ``frame`` (``torso``, ``right_hand``)."""
        return all(c in self.columns for c in pose_columns(frame))

    def poses(self, frame: str) -> np.ndarray:
        """World poses of a logged frame (``torso``, ``right_hand``, ``left_hand``): N x 4 x 4
        (m); NaN where unknown."""
        x, y, z, roll, pitch, yaw = (self.columns[c] for c in pose_columns(frame))
        T = np.zeros((len(x), 4, 4))
        T[:, :3, :3] = rotation_from_rpy(roll, pitch, yaw)
        T[:, :3, 3] = np.column_stack([x, y, z])
        T[:, 3, 3] = 1.0
        return T

    @property
    def status(self) -> np.ndarray:
        """Status codes (int array); see :class:`~hubo_cli.control.status.Status`."""
        return self.columns["status_code"].astype(int)


def log_paths(path: str | Path) -> tuple[Path, Path, Path]:
    """(csv, sidecar, parquet) paths of a run folder or of any one of its log files."""
    path = Path(path)
    csv_path = path / LOG_NAME if path.is_dir() else path.with_suffix(".csv")
    return csv_path, csv_path.with_suffix(".json"), csv_path.with_suffix(".parquet")


def load_log(path: str | Path) -> LogData:
    """Read a period log (a run folder, its CSV or its Parquet copy) into numpy arrays.

    A run folder is read from ``log.parquet`` when the run closed its log, else from
    ``log.csv``; the sidecar's metadata comes along where there is one. A log whose process
    died before closing it (``log.rows`` still there) is finished first (:func:`recover_log`);
    where its folder cannot be written (read-only, a full disk) the records are read as they
    are, nothing written, and :attr:`LogData.unfinished` says why.
    """
    import polars as pl

    path = Path(path)
    csv_path, meta_path, parquet_path = log_paths(path)
    refuse_special_files(csv_path, meta_path, parquet_path, *_record_paths(csv_path))
    try:
        recover_log(path)
    except OSError as exc:
        return _unfinished_log(csv_path, meta_path, _os_reason(exc))
    use_parquet = path.suffix == ".parquet" or (path.is_dir() and parquet_path.exists())
    source = parquet_path if use_parquet else csv_path
    sidecar = _read_sidecar(meta_path)  # first: a newer format is refused before it is parsed
    try:
        frame = pl.read_parquet(parquet_path) if use_parquet else _read_csv(csv_path)
        columns = {name: frame.get_column(name).to_numpy().astype(float, copy=False)
                   for name in frame.columns if name != "flags"}
        flags = [text.split(";") if text else []
                 for text in frame.get_column("flags").cast(pl.String).fill_null("").to_list()]
    except (pl.exceptions.PolarsError, OSError, UnicodeDecodeError, ValueError) as exc:
        reason = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot read the period log {source}: {reason}",
                         hint="give a run folder as hubo wrote it (a damaged log.parquet can be "
                              "removed: the log is then read from log.csv)") from None
    joints = tuple(n[4:-4] for n in frame.columns if n.startswith("cmd_") and n.endswith("_rad"))
    rows = sidecar.get("rows")
    return _checked(LogData(columns, flags, joints, sidecar.get("metadata", {}),
                            sidecar.get("started_utc"), sidecar.get("hubo_cli_version"),
                            periods_expected=rows if isinstance(rows, int) and rows > 0
                            else None), sidecar, meta_path)


def _checked(log: LogData, sidecar: dict, meta_path: Path) -> LogData:
    """``log`` once it is a run's (:mod:`hubo_cli.control.log_checks`), its suspect values
    said and the impossible positions among them made unknown."""
    check_sidecar(sidecar, log.joint_names, meta_path)
    if "t_s" in log.columns:
        check_times(log.columns["t_s"], meta_path.parent)
        log.suspect = suspect_values(log.columns, log.joint_names)
    return log


def _unfinished_log(csv_path: Path, meta_path: Path, reason: str) -> LogData:
    """A killed run's log read from its records (``log.rows``, ``log.flags``) where its CSV
    could not be written: ``reason`` why."""
    layout, table, flag_texts = read_rows(*_record_paths(csv_path))
    sidecar = _read_sidecar(meta_path)
    names = [n for n in layout["columns"] if n != "flags"]
    columns = {name: table[:, i] for i, name in enumerate(names)}
    joints = tuple(n[4:-4] for n in names if n.startswith("cmd_") and n.endswith("_rad"))
    return _checked(LogData(columns, [t.split(";") if t else [] for t in flag_texts], joints,
                            sidecar.get("metadata", {}), sidecar.get("started_utc"),
                            sidecar.get("hubo_cli_version"),
                            unfinished=f"{csv_path.parent}: its log was read from log.rows, "
                                       f"not made into log.csv ({reason})"), sidecar, meta_path)


def _read_sidecar(path: Path) -> dict:
    """A log's sidecar as a dict (empty when there is none).

    Raises:
        InputError: the file is not a JSON object with a mapping as its metadata.
    """
    if not path.exists():
        return {}
    try:
        sidecar = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        sidecar = None
    version = sidecar.get("version", FORMAT_VERSION) if isinstance(sidecar, dict) else None
    if (not isinstance(sidecar, dict) or not isinstance(sidecar.get("metadata", {}), dict)
            or not isinstance(version, int) or isinstance(version, bool)):
        raise InputError(f"{path} is not a period log's sidecar (a JSON object with its "
                         "metadata)", hint="give a run folder as hubo wrote it (or remove the "
                                           "file to read the log without its metadata)")
    if version > FORMAT_VERSION:
        raise InputError(f"{path}: the log is format version {version}; this hubo-cli "
                         f"({__version__}) reads up to version {FORMAT_VERSION}",
                         hint="upgrade hubo-cli to read it (hubo-cli "
                              f"{sidecar.get('hubo_cli_version', '?')} wrote it)")
    if version < FORMAT_VERSION:  # the first format hubo-cli wrote is FORMAT_VERSION's
        raise InputError(f"{path}: the log claims format version {version}; no hubo-cli wrote "
                         f"a version below {FORMAT_VERSION}, the one this hubo-cli "
                         f"({__version__}) reads", hint="give a run folder as hubo wrote it (or "
                         "remove log.json to read the log without its metadata)")
    return sidecar


def max_velocity_ratio(model, log: LogData) -> float:
    """The largest joint speed of the commands in a log as a fraction of the joint's velocity
    limit (1.0 = at the limit)."""
    cmd = log.joints("cmd")
    if len(cmd) < 2:
        return 0.0
    index = [model.joint_names.index(j) for j in log.joint_names]
    dq = np.abs(np.diff(cmd, axis=0)) / model.control_period_s
    return float(np.max(dq / model.velocity_rad_s[index]))
