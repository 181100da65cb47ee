"""``hubo ik --batch``: solve a CSV of poses, one output row per input row.

Input columns: T00 .. T33 (row-major 4x4 pose in metres, in the neck frame) and optionally
qprev1 .. qprev6 (rad). Output columns: line, q1 .. q6 (rad), status, pos_err_m, rot_err_rad.
A bad row (missing field, NaN, not a number, not a rigid transform) is reported by its line
number and written with status ``invalid`` and empty values; every good row is still solved.

The common case (a clean file) is parsed in one vectorised pass; only a file with bad rows
falls back to checking line by line.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.limb import Limb

POSE_COLUMNS = [f"T{i}{j}" for i in range(4) for j in range(4)]
PREV_COLUMNS = [f"qprev{k}" for k in range(1, 7)]
OUT_HEADER = "line,q1,q2,q3,q4,q5,q6,status,pos_err_m,rot_err_rad"


@dataclass
class BatchReport:
    """What a batch run did: rows read, rows solved, bad lines (line number, reason), counts."""

    rows: int
    solved: int
    bad_lines: list[tuple[int, str]] = field(default_factory=list)
    status_counts: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


def _parse_fast(body: bytes, n_rows: int, n_cols: int) -> np.ndarray | None:
    """All rows at once, or None if anything is off (then the slow path finds what)."""
    if body.count(b",") != n_rows * (n_cols - 1):
        return None
    flat_text = body.replace(b"\n", b",").decode("ascii", errors="replace")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            flat = np.fromstring(flat_text, sep=",")  # noqa: NPY201 (text mode is supported)
        except (DeprecationWarning, ValueError):
            return None
    if flat.size != n_rows * n_cols:
        return None
    return flat.reshape(n_rows, n_cols)


def _parse_line(line: str, n_cols: int) -> tuple[np.ndarray | None, str]:
    fields = line.split(",")
    if len(fields) != n_cols:
        return None, f"expected {n_cols} fields, found {len(fields)}"
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        bad = next(f for f in fields if not _is_float(f))
        return None, f"not a number: {bad.strip()!r}"
    return values, ""


def _is_float(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _check_rows(poses: np.ndarray, prevs: np.ndarray | None) -> np.ndarray:
    """Reason per row ('' = good): NaN/inf, or a pose that is not a rigid transform."""
    reasons = np.full(len(poses), "", dtype=object)
    finite = np.isfinite(poses).all(axis=(1, 2))
    if prevs is not None:
        finite &= np.isfinite(prevs).all(axis=1)
    reasons[~finite] = "NaN or infinite value"
    R = poses[:, :3, :3]
    ortho = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2)) < 1e-6
    last_row = np.abs(poses[:, 3] - [0, 0, 0, 1]).max(axis=1) < 1e-9
    with np.errstate(invalid="ignore"):
        rigid = ortho & last_row & (np.linalg.det(np.where(finite[:, None, None], R, 0)) > 0)
    reasons[finite & ~rigid] = "pose is not a rigid transform"
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
    lines = data.replace(b"\r\n", b"\n").rstrip(b"\n").split(b"\n")
    header = [h.strip() for h in lines[0].decode("ascii", errors="replace").split(",")]
    missing = [c for c in POSE_COLUMNS if c not in header]
    if not lines[0].strip() or missing:
        raise InputError(f"{in_path}:1: header lacks columns {', '.join(missing) or 'all'}",
                         hint="the header needs T00..T33 and optionally qprev1..qprev6")
    has_prev = all(c in header for c in PREV_COLUMNS)
    n_cols = len(header)
    n_rows = len(lines) - 1
    table = _parse_fast(b"\n".join(lines[1:]), n_rows, n_cols) if n_rows else np.empty((0, n_cols))
    parse_reasons = np.full(n_rows, "", dtype=object)
    if table is None:
        table = np.full((n_rows, n_cols), np.nan)
        for i, raw in enumerate(lines[1:]):
            values, reason = _parse_line(raw.decode("ascii", errors="replace"), n_cols)
            if values is None:
                parse_reasons[i] = reason
            else:
                table[i] = values
    index = {name: k for k, name in enumerate(header)}
    poses = table[:, [index[c] for c in POSE_COLUMNS]].reshape(-1, 4, 4)
    prevs = table[:, [index[c] for c in PREV_COLUMNS]] if has_prev else None
    reasons = np.where(parse_reasons != "", parse_reasons, _check_rows(poses, prevs))
    good = reasons == ""
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
    bad = [(int(i) + 2, str(reasons[i])) for i in np.flatnonzero(~good)]
    return BatchReport(n_rows, int(good.sum()), bad, counts, time.perf_counter() - t0)


def _write(out_path, q, status, pos_err, rot_err) -> None:
    names = np.array(list(STATUS_NAMES) + ["invalid"])
    status_text = names[np.where(status < 0, len(STATUS_NAMES), status)]
    numbers = np.column_stack([q, pos_err, rot_err]).tolist()
    rows = [OUT_HEADER]
    for line, (vals, st) in enumerate(zip(numbers, status_text, strict=True), start=2):
        if st == "invalid":
            rows.append(f"{line},,,,,,,invalid,,")
        else:
            rows.append("%d,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,%s,%.3g,%.3g"
                        % (line, *vals[:6], st, vals[6], vals[7]))
    try:
        Path(out_path).write_text("\n".join(rows) + "\n")
    except OSError as exc:
        raise InputError(f"cannot write {out_path}: {exc.strerror}",
                         hint="check the path of --out") from None
