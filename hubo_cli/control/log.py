"""The per-period log: one CSV row per control period, written and flushed as the loop runs.

Layout of ``log.csv``:

* line 1: ``# hubo-cli period log v1`` followed by the unit legend and the status codes;
* line 2: the header; every column name ends in its unit (``_s`` seconds, ``_us``
  microseconds, ``_rad`` radians, ``_m`` metres, ``_nm`` newton metres, ``_count`` a count,
  ``_code`` an enumeration, ``_flag`` 0/1) except ``flags``, a ``;``-separated list of words;
* then one row per period: ``period_count, t_s, status_code, compute_us, late_us, flags``,
  ``target_<joint>_rad`` (NaN when no target came that period), ``cmd_<joint>_rad`` (what the
  driver was sent), ``q_<joint>_rad`` (measured after the step), then the modules' and the
  caller's extra columns (NaN when not reported that period).

Each row is flushed to the operating system when written, so a crash loses at most the period
being written. :func:`load_log` reads the file back into numpy arrays.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.status import Status

LOG_NAME = "log.csv"
FIXED_COLUMNS = ("period_count", "t_s", "status_code", "compute_us", "late_us", "flags")
_UNIT_LEGEND = ("units in column names: _s seconds, _us microseconds, _rad radians, _m metres, "
                "_nm newton metres, _deg degrees, _count count, _code enumeration, _flag 0/1")


def _legend() -> str:
    codes = ", ".join(f"{s.value} {s.label}" for s in Status)
    return f"# hubo-cli period log v1; {_UNIT_LEGEND}; status_code: {codes}\n"


class PeriodLog:
    """Append-as-you-go CSV log of a control run.

    Args:
        path: the CSV file to create (its folder must exist).
        joint_names: joint names in command order.
        extra_columns: further numeric columns (names ending in their unit).
    """

    def __init__(self, path: str | Path, joint_names, extra_columns=()) -> None:
        self.path = Path(path)
        self.joint_names = tuple(joint_names)
        self.extra_columns = tuple(dict.fromkeys(extra_columns))
        joints = self.joint_names
        self.columns = (FIXED_COLUMNS[:5] + ("flags",)
                        + tuple(f"target_{j}_rad" for j in joints)
                        + tuple(f"cmd_{j}_rad" for j in joints)
                        + tuple(f"q_{j}_rad" for j in joints)
                        + self.extra_columns)
        n_num = 5
        self._head_fmt = ",".join(["%d", "%.9g", "%d", "%.6g", "%.6g"][:n_num]) + ",%s"
        # joints with 15 significant digits, so that finite differences of the log (velocity,
        # acceleration) are exact to about 1e-9 rad/s^2; the other numbers with 9
        self._body_fmt = ",".join(["%.15g"] * (3 * len(joints))
                                  + ["%.9g"] * len(self.extra_columns))
        self._nan_extras = [float("nan")] * len(self.extra_columns)
        self._file = open(self.path, "w", buffering=1 << 16)  # noqa: SIM115 (kept open)
        self._file.write(_legend())
        self._file.write(",".join(self.columns) + "\n")
        self._file.flush()
        self.rows = 0

    def write(self, period: int, t_s: float, status: int, compute_us: float, late_us: float,
              flags, target_rad, cmd_rad, q_rad, extras: dict | None = None) -> None:
        """Append one period and flush it."""
        if self._file.closed:
            return
        values = list(target_rad) + list(cmd_rad) + list(q_rad)
        if self.extra_columns:
            if extras:
                values += [float(extras.get(c, float("nan"))) for c in self.extra_columns]
            else:
                values += self._nan_extras
        flag_text = ";".join(sorted(flags))
        line = (self._head_fmt % (period, t_s, int(status), compute_us, late_us, flag_text)
                + "," + (self._body_fmt % tuple(values)) + "\n")
        self._file.write(line)
        self._file.flush()
        self.rows += 1

    def close(self) -> None:
        """Flush and close; safe to call twice."""
        if not self._file.closed:
            self._file.flush()
            self._file.close()

    def __enter__(self) -> PeriodLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class LogData:
    """A loaded period log.

    Attributes:
        columns: column name -> numpy array (float), every column except ``flags``.
        flags: the ``flags`` column, one list of words per period.
        joint_names: the joints found in the ``cmd_*`` columns, in order.
    """

    columns: dict[str, np.ndarray]
    flags: list[list[str]]
    joint_names: tuple[str, ...]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t_s"])

    def joints(self, kind: str) -> np.ndarray:
        """An (N, joints) array of ``target``, ``cmd`` or ``q`` values (rad)."""
        return np.column_stack([self.columns[f"{kind}_{j}_rad"] for j in self.joint_names])

    @property
    def status(self) -> np.ndarray:
        """Status codes (int array); see :class:`~hubo_cli.control.status.Status`."""
        return self.columns["status_code"].astype(int)


def load_log(path: str | Path) -> LogData:
    """Read a period log (a run folder or the CSV itself) into numpy arrays."""
    path = Path(path)
    if path.is_dir():
        path = path / LOG_NAME
    with open(path, newline="") as f:
        lines = (line for line in f if not line.startswith("#"))
        reader = csv.reader(lines)
        header = next(reader)
        rows = [row for row in reader if len(row) == len(header)]
    flag_index = header.index("flags")
    columns: dict[str, np.ndarray] = {}
    if rows:
        table = list(zip(*rows, strict=True))
    else:
        table = [()] * len(header)
    for i, name in enumerate(header):
        if i != flag_index:
            columns[name] = np.array(table[i], dtype=float)
    flags = [[w for w in text.split(";") if w] for text in table[flag_index]]
    joints = tuple(n[4:-4] for n in header if n.startswith("cmd_") and n.endswith("_rad"))
    return LogData(columns, flags, joints)


def max_velocity_ratio(model, log: LogData) -> float:
    """The largest joint speed of the commands in a log as a fraction of the joint's velocity
    limit (1.0 = at the limit)."""
    cmd = log.joints("cmd")
    if len(cmd) < 2:
        return 0.0
    index = [model.joint_names.index(j) for j in log.joint_names]
    dq = np.abs(np.diff(cmd, axis=0)) / model.control_period_s
    return float(np.max(dq / model.velocity_rad_s[index]))
