"""What a period log read back must be to be a run's (:func:`hubo_cli.control.log.load_log`).

hubo logs one row per control period, its time ``t_s`` the period's number times the period,
so the times of a real run are finite and rise by the same step on every row; its sidecar
names the joints of its ``cmd_*`` columns and counts its rows. A log that breaks one of these
cannot be a run's, and is refused (:class:`~hubo_cli.errors.InputError`, one line naming the
first row at fault). A logged value a run can hold but the robot cannot be at (a world
position beyond a kilometre or infinite) is made unknown (NaN, as the log writes an unknown
pose), and a measured joint that is not a number stays so; each is said in one line naming its
rows (:func:`suspect_values`), so that what is drawn from the log is never destroyed by them.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.errors import InputError

MAX_LOG_TIME_S = 1e8  # a log's times beyond this (3 years) are not a run's
MAX_STEP_RATIO = 1.5  # a step between rows beyond this many periods is a gap no run logs
MAX_WORLD_M = 1e3  # a logged world position beyond this (1 km) is not the robot's
POSE_FRAMES = {"torso": "the torso estimated from the legs", "right_hand": "from the joints",
               "left_hand": "from the joints"}
_HINT = "give a run folder as hubo wrote it"


def check_times(t_s: np.ndarray, source) -> None:
    """Refuse times that are not finite or beyond :data:`MAX_LOG_TIME_S`, that go back or
    repeat, or that skip more than :data:`MAX_STEP_RATIO` periods (the median step).

    Raises:
        InputError: naming the first row at fault (row 1: the first period).
    """
    bad = ~(np.isfinite(t_s) & (np.abs(t_s) < MAX_LOG_TIME_S))
    if bad.any():
        raise InputError(f"the log in {source} has times (t_s) that are not finite or beyond "
                         f"{MAX_LOG_TIME_S:.0e} s (from row {int(np.argmax(bad)) + 1})", hint=_HINT)
    if len(t_s) < 2:
        return
    step_s = np.diff(t_s)
    back = step_s <= 0
    if back.any():
        k = int(np.argmax(back))
        raise InputError(f"the log in {source} has times (t_s) that do not rise: row {k + 2} "
                         f"at t = {t_s[k + 1]:.6g} s after row {k + 1} at t = {t_s[k]:.6g} s "
                         f"({int(back.sum())} such rows); a run logs one period a row",
                         hint=_HINT)
    period_s = float(np.median(step_s))
    gap = step_s > MAX_STEP_RATIO * period_s
    if gap.any():
        k = int(np.argmax(gap))
        raise InputError(f"the log in {source} skips {step_s[k]:.6g} s between row {k + 1} and "
                         f"row {k + 2} (t = {t_s[k]:.6g} s), its period {period_s:.6g} s; a "
                         "run logs one period a row", hint=_HINT)


def check_sidecar(sidecar: dict, joints: tuple[str, ...], path) -> None:
    """Refuse a sidecar (``log.json``) whose joint names are not its log's ``cmd_*`` columns'
    or whose row count is not a count.

    Raises:
        InputError: the first such field, with what it holds.
    """
    names = sidecar.get("joint_names", list(joints))
    if not isinstance(names, list) or tuple(names) != joints:
        raise InputError(f"{path} names the joints {_listed(names)}, not its log's columns' "
                         f"{_listed(list(joints))}",
                         hint=f"{_HINT} (or remove log.json to read the log without it)")
    rows = sidecar.get("rows", 0)
    if not isinstance(rows, int) or isinstance(rows, bool) or rows < 0:
        raise InputError(f"{path} counts {repr(rows)[:40]} rows, not a number of periods",
                         hint=f"{_HINT} (or remove log.json to read the log without it)")


def suspect_values(columns: dict[str, np.ndarray], joints: tuple[str, ...]) -> list[str]:
    """Make world positions beyond :data:`MAX_WORLD_M` or infinite unknown (NaN, in place) and
    say, one line each, where they were and where a measured joint is not a number."""
    t_s = columns["t_s"]
    lines = []
    for frame, shown in POSE_FRAMES.items():
        names = [f"{frame}_{axis}" for axis in ("x_m", "y_m", "z_m") if f"{frame}_{axis}" in
                 columns]
        if not names:
            continue
        xyz = np.column_stack([columns[n] for n in names])
        far = np.any(np.isinf(xyz) | (np.abs(xyz) > MAX_WORLD_M), axis=1)
        if far.any():
            for n in names:
                columns[n] = np.where(far, np.nan, columns[n])
            lines.append(f"the log's {frame.replace('_', ' ')} position is infinite or beyond "
                         f"{MAX_WORLD_M:.0f} m in {_rows(far, t_s)}: shown unknown there "
                         f"({shown})")
    q = [(j, columns[f"q_{j}_rad"]) for j in joints if f"q_{j}_rad" in columns]
    bad = {j: ~np.isfinite(v) for j, v in q}
    named = [j for j, m in bad.items() if m.any()]
    if named:
        rows = np.any([bad[j] for j in named], axis=0)
        lines.append(f"the log's measured {', '.join(named[:4])}{', ...' if len(named) > 4 else ''}"
                     f" {'is' if len(named) == 1 else 'are'} not a number in {_rows(rows, t_s)}: "
                     "unknown there in what follows")
    return lines


def _listed(names) -> str:
    """A list's first names and its length, e.g. "[RSP, RSR, RSY, ...] (24)"."""
    if not isinstance(names, list):
        return f"as {type(names).__name__}"
    more = ", ..." if len(names) > 3 else ""
    return f"[{', '.join(str(n)[:12] for n in names[:3])}{more}] ({len(names)})"


def _rows(mask: np.ndarray, t_s: np.ndarray) -> str:
    """Rows (1: the first period) and times of a mask, e.g. "rows 102-400 (t = 0.505-1.995 s)"
    or "3 rows from row 7 to 90 (t = ...)"."""
    index = np.flatnonzero(mask)
    first, last = int(index[0]), int(index[-1])
    times = f"t = {t_s[first]:.3f}-{t_s[last]:.3f} s"
    if first == last:
        return f"row {first + 1} (t = {t_s[first]:.3f} s)"
    if len(index) == last - first + 1:
        return f"rows {first + 1}-{last + 1} ({times})"
    return f"{len(index)} rows from row {first + 1} to {last + 1} ({times})"
