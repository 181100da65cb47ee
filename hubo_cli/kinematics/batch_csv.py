"""``hubo ik --batch``: solve a CSV of poses, one output row per input row.

Input columns: T00 .. T33 (row-major 4x4 pose in metres, in the neck frame) and optionally
qprev1 .. qprev6 (rad); a UTF-8 byte-order mark before the header is skipped. Output columns:
line, q1 .. q6 (rad), status, pos_err_m, rot_err_rad. A bad row is reported by its line number
and the field at fault (empty, not a complete number, NaN or infinite, beyond
``MAX_INPUT_MAGNITUDE`` as ``hubo ik`` refuses it, a missing or extra field, a pose that is not
a rigid transform) and written with status ``invalid`` and empty values; every good row is
still solved.

The file is read and written by polars (its CSV reader parses every field as a float64 in
compiled code on all cores; a field that is not a complete number becomes null and only those
rows are looked at again in Python to say what is wrong with them). Numbers are written in
their shortest form that reads back to the same float64.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np
import polars as pl

from hubo_cli.errors import InputError, quoted
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.dh import JIT
from hubo_cli.kinematics.limb import Limb
from hubo_cli.kinematics.poses import MAX_INPUT_MAGNITUDE
from hubo_cli.outputs import OutputFile, write_error

POSE_COLUMNS = [f"T{i}{j}" for i in range(4) for j in range(4)]
PREV_COLUMNS = [f"qprev{k}" for k in range(1, 7)]
OUT_COLUMNS = ["line", "q1", "q2", "q3", "q4", "q5", "q6", "status", "pos_err_m", "rot_err_rad"]
_EXTRA = "__extra_field__"  # catches a field past the header's last column
# the largest batch read (a pose row is about 300 bytes: some 900,000 poses); a bigger file,
# or an endless one (/dev/zero), is refused, never read whole
MAX_BATCH_BYTES = 256 << 20


@dataclass
class BatchReport:
    """What a batch run did: rows read, rows solved, bad lines (line number, reason), counts."""

    rows: int
    solved: int
    bad_lines: list[tuple[int, str]] = field(default_factory=list)
    status_counts: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def invalid(self) -> int:
        """Rows that could not be solved because the row itself is bad."""
        return len(self.bad_lines)


def _why_bad(line: str, header: list[str]) -> str:
    """Why one bad line is bad, in words (only for the rows the reader flagged)."""
    fields = line.split(",")
    if len(fields) < len(header):
        return f"expected {len(header)} fields, found {len(fields)} (no {header[len(fields)]})"
    if len(fields) > len(header):
        return f"expected {len(header)} fields, found {len(fields)}"
    for name, text in zip(header, fields, strict=True):
        if not text.strip():
            return f"empty field {name}"
        try:
            float(text)
        except ValueError:
            return f"not a number in {name}: {quoted(text.strip())}"
    return "unreadable row"


@nb.njit(**JIT)  # serial: microseconds per 1000 rows, a parallel kernel compiles ~1 s longer
def _rigid(values):
    """Per row of T00..T33: whether the pose is a rigid transform (orthonormal rotation with
    determinant +1 to 1e-6, last row 0 0 0 1 to 1e-9); False for rows with NaN/inf."""
    n = values.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for r in range(n):
        v = values[r]
        finite = True
        for k in range(16):
            finite = finite and math.isfinite(v[k])
        worst = 0.0
        for a in range(3):
            for b in range(a, 3):
                dot = v[a] * v[b] + v[4 + a] * v[4 + b] + v[8 + a] * v[8 + b]
                worst = max(worst, abs(dot - (1.0 if a == b else 0.0)))
        det = (v[0] * (v[5] * v[10] - v[9] * v[6]) - v[4] * (v[1] * v[10] - v[9] * v[2])
               + v[8] * (v[1] * v[6] - v[5] * v[2]))
        last = max(max(abs(v[12]), abs(v[13])), max(abs(v[14]), abs(v[15] - 1.0)))
        out[r] = finite and worst < 1e-6 and det > 0.0 and last < 1e-9
    return out


def _check_rows(values: np.ndarray, names: list[str]) -> dict[int, str]:
    """Row index -> reason for rows with NaN/inf or a pose that is not a rigid transform.

    ``values`` holds T00..T33 (and qprev1..qprev6) per row, ``names`` their column names.
    """
    rigid = _rigid(np.ascontiguousarray(values))
    finite = np.isfinite(values[:, 16:]).all(axis=1) if values.shape[1] > 16 else True
    too_large = np.abs(np.nan_to_num(values, posinf=0.0, neginf=0.0)) > MAX_INPUT_MAGNITUDE
    reasons = {}
    for i in np.flatnonzero(~(rigid & finite) | too_large.any(axis=1)):
        bad = np.flatnonzero(~np.isfinite(values[i]))
        large = np.flatnonzero(too_large[i])
        if len(bad):
            reasons[int(i)] = f"{values[i, bad[0]]} in {names[bad[0]]}"
        elif len(large):  # as `hubo ik --matrix` refuses it
            reasons[int(i)] = (f"{names[large[0]]} {values[i, large[0]]:g} is beyond "
                               f"{MAX_INPUT_MAGNITUDE:,.0f}")
        else:
            reasons[int(i)] = "pose is not a rigid transform"
    return reasons


def _read_header(in_path: Path, data: bytes) -> list[str]:
    first_newline = data.find(b"\n")
    header_line = data if first_newline < 0 else data[:first_newline]
    header = [h.strip() for h in header_line.decode("ascii", errors="replace").split(",")]
    missing = [c for c in POSE_COLUMNS if c not in header]
    if not header_line.strip() or missing:
        raise InputError(f"{in_path}:1: header lacks columns {', '.join(missing) or 'all'}",
                         hint="the header needs T00..T33 and optionally qprev1..qprev6")
    return header


def _read_table(data: bytes, header: list[str]) -> pl.DataFrame:
    """Every field as float64 (null where it is empty or not a complete number); one column
    more than the header, non-null where a line has too many fields."""
    body = data[data.find(b"\n") + 1:].rstrip(b"\r\n")
    names = [*header, _EXTRA]
    if not body:
        return pl.DataFrame(schema={name: pl.Float64 for name in names})
    try:
        return pl.read_csv(body, has_header=False, schema={name: pl.Float64 for name in names},
                           missing_columns="insert", extra_columns="ignore",
                           ignore_errors=True, truncate_ragged_lines=True, raise_if_empty=False,
                           quote_char=None)
    except pl.exceptions.PolarsError as exc:
        raise InputError(f"cannot read the CSV: {exc}".splitlines()[0],
                         hint="one pose per line, fields separated by commas") from None


def solve_csv(limb: Limb, in_path: str | Path, out_path: str | Path, *,
              force: bool = False) -> BatchReport:
    """Solve every pose of ``in_path`` with ``limb`` and write ``out_path`` (whole or not at
    all: see :mod:`hubo_cli.outputs`).

    Raises:
        InputError: the file is missing, empty or its header lacks T00..T33, or ``out_path``
            is refused (the input file, a run's file, or an existing file without ``force``).
    """
    t0 = time.perf_counter()
    in_path, out_path = Path(in_path), Path(out_path)
    try:
        with in_path.open("rb") as file:
            data = file.read(MAX_BATCH_BYTES + 1)
    except OSError as exc:
        raise InputError(f"cannot read {in_path}: {exc.strerror}",
                         hint="check the path of --batch") from None
    if len(data) > MAX_BATCH_BYTES:
        raise InputError(f"{in_path} is larger than {MAX_BATCH_BYTES >> 20} MiB: not read",
                         hint="split the poses into smaller files")
    data = data.removeprefix(b"\xef\xbb\xbf")  # the byte-order mark some Windows editors write
    out = OutputFile(out_path, inputs=(in_path,), force=force)
    header = _read_header(in_path, data)
    table = _read_table(data, header)
    n_rows = table.height
    has_prev = all(c in header for c in PREV_COLUMNS)
    used = POSE_COLUMNS + (PREV_COLUMNS if has_prev else [])
    values = table.select(used).to_numpy()
    poses = values[:, :16].reshape(-1, 4, 4)
    prevs = values[:, 16:] if has_prev else None
    unread = table.select(pl.any_horizontal(pl.all().exclude(_EXTRA).is_null())
                          | pl.col(_EXTRA).is_not_null()).to_series().to_numpy()
    unread_rows = np.flatnonzero(unread)
    checked = np.where(unread[:, None], 0.0, values) if len(unread_rows) else values
    reasons = _check_rows(checked, used)  # the unread rows get their reason below
    if len(unread_rows):
        newlines = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == ord("\n"))
        ends = np.append(newlines[1:], len(data))
        for i in unread_rows:
            line = data[newlines[i] + 1:ends[i]].rstrip(b"\r").decode("ascii", "replace")
            reasons[int(i)] = _why_bad(line, header)
    good = np.ones(n_rows, dtype=bool)
    good[list(reasons)] = False
    q = np.full((n_rows, 6), np.nan)
    status = np.full(n_rows, len(STATUS_NAMES))
    pos_err = np.full(n_rows, np.nan)
    rot_err = np.full(n_rows, np.nan)
    if good.any():
        result = limb.solve_batch(poses[good], prevs[good] if has_prev else None)
        q[good], status[good] = result.q_rad, result.status
        pos_err[good], rot_err[good] = result.position_error_m, result.rotation_error_rad
    with out.writing() as temporary:
        _write(temporary, out_path, q, status, pos_err, rot_err)
    names = (*STATUS_NAMES, "invalid")
    counts = {name: int(n) for name, n in zip(names, np.bincount(status, minlength=len(names)),
                                               strict=True)}
    bad = [(i + 2, reasons[i]) for i in sorted(reasons)]
    return BatchReport(n_rows, int(good.sum()), bad, counts, time.perf_counter() - t0)


def _write(path: Path, out_path: Path, q, status, pos_err, rot_err) -> None:
    """Write the results to ``path`` (a temporary name of ``out_path``, named in errors)."""
    names = pl.Series([*STATUS_NAMES, "invalid"], dtype=pl.String)
    columns = {"line": pl.Series(np.arange(2, len(q) + 2, dtype=np.int64))}
    columns |= {f"q{k + 1}": pl.Series(q[:, k], nan_to_null=True) for k in range(6)}
    columns |= {"status": names.gather(status),
                "pos_err_m": pl.Series(pos_err, nan_to_null=True),
                "rot_err_rad": pl.Series(rot_err, nan_to_null=True)}
    try:
        pl.DataFrame(columns).write_csv(path)
    except OSError as exc:  # polars gives no errno: a full disk is told by the space left
        raise write_error(out_path, exc, hint="check the path of --out") from None
