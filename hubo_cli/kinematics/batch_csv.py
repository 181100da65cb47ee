"""``hubo ik --batch``: solve a CSV of poses, one output row per input row.

Input columns: T00 .. T33 (row-major 4x4 pose in metres, in the neck frame) and optionally
qprev1 .. qprev6 (rad). Output columns: line, q1 .. q6 (rad), status, pos_err_m, rot_err_rad.
A bad row (missing field, NaN, not a number, not a rigid transform) is reported by its line
number and written with status ``invalid`` and empty values; every good row is still solved.

Numbers are read and written by compiled code (:mod:`.csv_codec`); only the rows it flags are
looked at again in Python to say what is wrong with them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.kinematics import csv_codec
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.limb import Limb

POSE_COLUMNS = [f"T{i}{j}" for i in range(4) for j in range(4)]
PREV_COLUMNS = [f"qprev{k}" for k in range(1, 7)]
OUT_HEADER = "line,q1,q2,q3,q4,q5,q6,status,pos_err_m,rot_err_rad"
MAX_ENTRY = 1e6  # no pose entry (rotation, metres) is this large: a typo or garbage


@dataclass
class BatchReport:
    """What a batch run did: rows read, rows solved, bad lines (line number, reason), counts."""

    rows: int
    solved: int
    bad_lines: list[tuple[int, str]] = field(default_factory=list)
    status_counts: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


def _why_bad(line: str, header: list[str]) -> str:
    """Why one bad line is bad, in words (only for the rows the compiled parser flagged)."""
    fields = line.split(",")
    if len(fields) != len(header):
        return f"expected {len(header)} fields, found {len(fields)}"
    for name, text in zip(header, fields, strict=True):
        try:
            float(text)
        except ValueError:
            return f"not a number in {name}: {text.strip()!r}"
    return "unreadable row"


def _check_rows(poses: np.ndarray, prevs: np.ndarray | None) -> dict[int, str]:
    """Row index -> reason for rows with NaN/inf or a pose that is not a rigid transform."""
    finite = np.isfinite(poses).all(axis=(1, 2))
    if prevs is not None:
        finite &= np.isfinite(prevs).all(axis=1)
    # magnitudes no pose has (1e300 would overflow the checks below)
    huge = finite & (np.abs(np.where(finite[:, None, None], poses, 0.0)) > MAX_ENTRY).any(
        axis=(1, 2))
    finite &= ~huge
    R = np.where(finite[:, None, None], poses[:, :3, :3], np.eye(3))
    ortho = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2)) < 1e-6
    last_row = np.abs(np.where(finite[:, None], poses[:, 3], 0.0) - [0, 0, 0, 1]).max(axis=1)
    rigid = ortho & (last_row < 1e-9) & (np.linalg.det(R) > 0)
    reasons = {int(i): "NaN or infinite value" for i in np.flatnonzero(~finite & ~huge)}
    reasons.update({int(i): f"a value beyond {MAX_ENTRY:g}" for i in np.flatnonzero(huge)})
    reasons.update({int(i): "pose is not a rigid transform"
                    for i in np.flatnonzero(finite & ~rigid)})
    return reasons


def solve_csv(limb: Limb, in_path: str | Path, out_path: str | Path) -> BatchReport:
    """Solve every pose of ``in_path`` with ``limb`` and write ``out_path``.

    Raises:
        InputError: the file is missing, empty, or its header lacks T00..T33.
    """
    t0 = time.perf_counter()
    in_path = Path(in_path)
    try:
        data = in_path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {in_path}: {exc.strerror}",
                         hint="check the path of --batch") from None
    buf = np.frombuffer(data, dtype=np.uint8)
    first_newline = data.find(b"\n")
    header_line = data if first_newline < 0 else data[:first_newline]
    header = [h.strip() for h in header_line.decode("ascii", errors="replace").split(",")]
    missing = [c for c in POSE_COLUMNS if c not in header]
    if not header_line.strip() or missing:
        raise InputError(f"{in_path}:1: header lacks columns {', '.join(missing) or 'all'}",
                         hint="the header needs T00..T33 and optionally qprev1..qprev6")
    has_prev = all(c in header for c in PREV_COLUMNS)
    if first_newline < 0:
        starts = ends = np.zeros(0, dtype=np.int64)
    else:
        starts, ends = csv_codec.line_bounds(buf, first_newline + 1)
    n_rows = len(starts)
    table, errors = csv_codec.parse_rows(buf, starts, ends, len(header))

    def line(i: int) -> str:
        return data[starts[i]:ends[i]].rstrip(b"\r").decode("ascii", errors="replace")

    index = {name: k for k, name in enumerate(header)}
    poses = table[:, [index[c] for c in POSE_COLUMNS]].reshape(-1, 4, 4)
    prevs = table[:, [index[c] for c in PREV_COLUMNS]] if has_prev else None
    reasons = _check_rows(poses, prevs)
    reasons.update({int(i): _why_bad(line(i), header) for i in np.flatnonzero(errors)})
    good = np.ones(n_rows, dtype=bool)
    good[list(reasons)] = False
    q = np.full((n_rows, 6), np.nan)
    status = np.full(n_rows, -1)
    pos_err = np.full(n_rows, np.nan)
    rot_err = np.full(n_rows, np.nan)
    if good.any():
        result = limb.solve_batch(poses[good], prevs[good] if has_prev else None)
        q[good], status[good] = result.q_rad, result.status
        pos_err[good], rot_err[good] = result.position_error_m, result.rotation_error_rad
    _write(out_path, q, status, pos_err, rot_err)
    counts = {name: int((status == k).sum()) for k, name in enumerate(STATUS_NAMES)}
    counts["invalid"] = int((~good).sum())
    bad = [(i + 2, reasons[i]) for i in sorted(reasons)]
    return BatchReport(n_rows, int(good.sum()), bad, counts, time.perf_counter() - t0)


_STATUS_BYTES = np.zeros((len(STATUS_NAMES) + 1, 12), dtype=np.uint8)
for _k, _name in enumerate((*STATUS_NAMES, "invalid")):
    _STATUS_BYTES[_k, :len(_name)] = np.frombuffer(_name.encode(), dtype=np.uint8)


def _write(out_path, q, status, pos_err, rot_err) -> None:
    code = np.where(status < 0, len(STATUS_NAMES), status).astype(np.int64)
    body = csv_codec.format_rows(2, np.ascontiguousarray(q), code, pos_err, rot_err,
                                 _STATUS_BYTES)
    try:
        with open(out_path, "wb") as f:
            f.write((OUT_HEADER + "\n").encode())
            f.write(body)  # the array's buffer, no copy
    except OSError as exc:
        raise InputError(f"cannot write {out_path}: {exc.strerror}",
                         hint="check the path of --out") from None
