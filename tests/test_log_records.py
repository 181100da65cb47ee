"""The period log's records: the CSV made from them at close is the documented row text, a
process killed mid-run leaves records that load_log turns into the log, and the sidecar's
metadata is written the same in one rewrite as in several."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hubo_cli.control.log import (
    FLAGS_NAME,
    LOG_NAME,
    META_NAME,
    PARQUET_NAME,
    ROWS_NAME,
    PeriodLog,
    load_log,
    read_rows,
    recover_log,
    set_log_metadata,
    update_log_metadata,
)
from hubo_cli.errors import InputError

JOINTS = ("A", "B", "C")
EXTRAS = ("x_m", "y_count")
ODD = [0.1, -2.5e-7, 1.0, -0.0, 3.0e20, math.nan, math.inf, -math.inf, 1e-300,
       123456789.12345678, 0.30000000000000004, -7.0]


def _rows(n: int):
    """n periods with whole numbers, NaN, infinities, tiny and huge values, and flag sets."""
    rng = np.random.default_rng(5)
    flag_sets = [set(), {"holding"}, {"collision", "holding"}, {"smooth-stop"}]
    rows = []
    for k in range(n):
        q = rng.normal(0.0, 1.0, 3)
        q[k % 3] = ODD[k % len(ODD)]
        target = np.full(3, math.nan) if k % 4 == 0 else q + 0.5
        extras = {} if k % 5 == 0 else {"x_m": ODD[(k + 3) % len(ODD)], "y_count": float(k)}
        rows.append((k, k * 0.005, k % 3, 10.0 + k / 7, 0.0 if k % 2 else 2.0 + k / 3,
                     flag_sets[k % 4], target, q * 0.5, q, extras))
    return rows


def _reference_text(rows) -> str:
    """The CSV the documented format gives, one row at a time (the former row writer's rules):
    a whole number as ``%.1f``, NaN as ``NaN``, joints with 15 significant digits, the pose
    columns (NaN here: no state) with 12, the extras with 9."""

    def number(v: float, spec: str) -> str:
        if math.isfinite(v) and v == int(v):
            return "%.1f" % v
        return "NaN" if math.isnan(v) else spec % v

    pose = ["torso_x_m", "torso_y_m", "torso_z_m", "torso_roll_rad", "torso_pitch_rad",
            "torso_yaw_rad", "right_foot_fz_n", "left_foot_fz_n", "right_foot_contact_flag",
            "left_foot_contact_flag"]
    header = (["period_count", "t_s", "status_code", "compute_us", "late_us", "flags"]
              + [f"{kind}_{j}_rad" for kind in ("target", "cmd", "q") for j in JOINTS]
              + pose + list(EXTRAS))
    lines = [",".join(header)]
    for period, t_s, status, compute_us, late_us, flags, target, cmd, q, extras in rows:
        cells = [str(period), number(t_s, "%.9g"), str(status), number(compute_us, "%.6g"),
                 number(late_us, "%.6g"), ";".join(sorted(flags))]
        cells += [number(float(v), "%.15g") for v in (*target, *cmd, *q)]
        cells += ["NaN"] * len(pose)
        cells += [number(float(extras.get(c, math.nan)), "%.9g") for c in EXTRAS]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _write(path: Path, rows) -> PeriodLog:
    log = PeriodLog(path / LOG_NAME, JOINTS, EXTRAS)
    for row in rows:
        log.write(*row)
    return log


def test_the_csv_made_at_close_is_the_row_text(tmp_path):
    rows = _rows(300)
    log = _write(tmp_path, rows)
    assert not (tmp_path / LOG_NAME).exists()  # records while the run goes
    assert len(read_rows(tmp_path / ROWS_NAME, tmp_path / FLAGS_NAME)[1]) == 300
    log.close()
    log.close()  # twice is harmless
    assert (tmp_path / LOG_NAME).read_text() == _reference_text(rows)
    assert not (tmp_path / ROWS_NAME).exists() and not (tmp_path / FLAGS_NAME).exists()
    assert json.loads((tmp_path / META_NAME).read_text())["rows"] == 300
    loaded = load_log(tmp_path)  # from the Parquet copy
    assert len(loaded) == 300
    assert loaded.flags[2] == ["collision", "holding"] and loaded.flags[0] == []
    np.testing.assert_allclose(loaded["q_A_rad"], [r[8][0] for r in rows], rtol=1e-13)  # 15 digits


def test_a_state_row_logs_its_feet_and_extras(tmp_path):
    """With a state: the ankles' normal forces and the contact flags (NaN where the driver
    has none), the extras it reported and NaN for the others."""
    from hubo_cli.state import RobotState, Truth

    q = np.array([0.1, -0.2, 0.3])
    ft = {"right-ankle": np.array([1.0, 2.0, 301.25, 0.0, 0.0, 0.0])}
    truth = Truth(np.eye(4), (True, np.False_), np.array([1.0, 0.0, 0.0, 0.0]))
    states = [RobotState(0.0, q, np.zeros(3), ft=ft, truth=truth),
              RobotState(0.005, q, np.zeros(3), ft={}, truth=None)]
    log = PeriodLog(tmp_path / LOG_NAME, JOINTS, EXTRAS)
    log.write(0, 0.0, 0, 1.0, 0.0, set(), q, q, q, {"x_m": np.float64(0.25)}, state=states[0])
    log.write(1, 0.005, 0, 1.0, 0.0, set(), q, q, q, None, state=states[1])
    log.close()
    data = load_log(tmp_path)
    assert data["right_foot_fz_n"][0] == 301.25 and math.isnan(data["left_foot_fz_n"][0])
    assert data["right_foot_contact_flag"][0] == 1.0 and data["left_foot_contact_flag"][0] == 0.0
    assert data["x_m"][0] == 0.25 and math.isnan(data["y_count"][0])
    second = [data[c][1] for c in ("right_foot_fz_n", "left_foot_fz_n",
                                   "right_foot_contact_flag", "left_foot_contact_flag",
                                   "x_m", "y_count")]
    assert all(math.isnan(v) for v in second)
    # the first row: the simulator's truth; the second, without one: no world position, the
    # orientation the IMU's (level)
    assert data["torso_x_m"][0] == 0.0 and np.isnan(data["torso_x_m"][1])
    assert (data["torso_roll_rad"] == 0.0).all()


def test_the_records_grow_past_their_first_block(tmp_path):
    rows = _rows(9000)  # more than the file's first block of records
    _write(tmp_path, rows).close()
    loaded = load_log(tmp_path / LOG_NAME)
    assert len(loaded) == 9000
    assert loaded["period_count"][-1] == 8999.0


def test_a_killed_run_leaves_records_that_load_log_finishes(tmp_path):
    """A process killed outright (no finally blocks, no close) after 250 periods: the records
    are in the file; load_log writes the CSV, the Parquet copy and the row count from them."""
    script = textwrap.dedent(f"""
        import os, signal, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_log_records import _rows, _write
        from pathlib import Path
        log = _write(Path({str(tmp_path)!r}), _rows(250))
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                          timeout=120)
    assert done.returncode == -signal.SIGKILL, done.stderr.decode()
    assert (tmp_path / ROWS_NAME).exists() and not (tmp_path / LOG_NAME).exists()
    loaded = load_log(tmp_path)
    assert len(loaded) == 250
    assert (tmp_path / LOG_NAME).read_text() == _reference_text(_rows(250))
    assert (tmp_path / PARQUET_NAME).exists() and not (tmp_path / ROWS_NAME).exists()
    assert json.loads((tmp_path / META_NAME).read_text())["rows"] == 250
    assert recover_log(tmp_path) is False  # nothing left to recover


def test_a_record_not_yet_counted_is_left_out(tmp_path):
    """The count is updated after each record: a record being stored when the process died
    (its numbers partly there, the count not yet raised) is not read."""
    log = _write(tmp_path, _rows(40))
    at = log._data_at + 40 * log._record_bytes
    log._map[at:at + 16] = np.array([0.0, 40.0]).tobytes()  # half a 41st record
    layout, numbers, flags = read_rows(tmp_path / ROWS_NAME, tmp_path / FLAGS_NAME)
    assert numbers.shape == (40, len(layout["columns"]) - 1) and len(flags) == 40
    log._map.close()
    log._rows_file.close()  # the process's end releases the writer's lock
    assert len(load_log(tmp_path)) == 40


def test_a_killed_run_in_a_folder_it_cannot_write_is_read_from_its_records(tmp_path,
                                                                          monkeypatch):
    """A killed run's folder that cannot be written (read-only; the test makes every
    ``open`` for writing there fail with EACCES, as chmod would for any user but root):
    load_log reads the records as they are, writes nothing (main failed: PermissionError),
    says why, and gives the numbers the finished log gives."""
    import builtins
    import errno

    from hubo_cli.control import log as log_module

    log = _write(tmp_path, _rows(40))
    log._map.close()
    log._rows_file.close()  # the process's end releases the writer's lock

    def read_only(file, mode="r", *args, **kwargs):
        if "r" not in mode or "+" in mode:
            raise PermissionError(errno.EACCES, "Permission denied", str(file))
        return builtins.open(file, mode, *args, **kwargs)

    before = sorted(p.name for p in tmp_path.iterdir())
    monkeypatch.setattr(log_module, "open", read_only, raising=False)
    unfinished = load_log(tmp_path)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written or removed
    assert "log.rows" in unfinished.unfinished and "Permission denied" in unfinished.unfinished
    finished = load_log(tmp_path)  # writable again: the usual CSV
    assert not finished.unfinished and (tmp_path / LOG_NAME).exists()
    assert unfinished.flags == finished.flags and len(unfinished) == 40
    assert unfinished.joint_names == finished.joint_names == JOINTS
    assert unfinished.columns.keys() == finished.columns.keys()
    for name, values in finished.columns.items():  # to the CSV's digits (6 for the timings)
        np.testing.assert_allclose(unfinished[name], values, rtol=1e-5, err_msg=name)


def test_the_log_of_a_run_still_going_is_left_alone(tmp_path):
    """Reading a run folder while its run still writes (the writer holds its records' lock)
    is refused with a one-line error, and the records stay for the writer to finish; once it
    has closed, the folder reads as usual."""
    log = _write(tmp_path, _rows(30))
    with pytest.raises(InputError, match="still going"):
        load_log(tmp_path)
    assert (tmp_path / ROWS_NAME).exists() and not (tmp_path / LOG_NAME).exists()
    log.close()
    assert len(load_log(tmp_path)) == 30 and not (tmp_path / ROWS_NAME).exists()


def test_not_a_record_file_is_refused(tmp_path):
    (tmp_path / ROWS_NAME).write_bytes(b"period_count,t_s\n")
    (tmp_path / FLAGS_NAME).write_text("")
    with pytest.raises(InputError, match="not a period log"):
        read_rows(tmp_path / ROWS_NAME, tmp_path / FLAGS_NAME)


def _killed_run(folder: Path, rows: int = 40) -> None:
    """A run folder as a killed run leaves it: the records and their flags, no CSV."""
    log = _write(folder, _rows(rows))
    log._map.close()
    log._rows_file.close()  # the process's end releases the writer's lock


def test_damaged_records_are_a_one_line_input_error(tmp_path):
    """Review 28: a killed run's log.rows with a damaged header or a record's flags index
    beyond log.flags, or log.flags gone, ended in an internal error. Each byte of the header
    and the records' flags indices is damaged in turn (and random bytes): load_log either
    reads the run or says the records are damaged (exit 2), never another error."""
    rng = np.random.default_rng(28)
    folder = tmp_path / "run"
    folder.mkdir()
    _killed_run(folder)
    whole = (folder / ROWS_NAME).read_bytes()
    flags = (folder / FLAGS_NAME).read_bytes()
    n_head = int.from_bytes(whole[24:28], "little")
    spots = [*range(16, 28 + n_head), *rng.integers(0, len(whole), 40).tolist()]
    refused = 0
    for k, at in enumerate(spots):
        case = tmp_path / f"case{k}"
        case.mkdir()
        damaged = bytearray(whole)
        damaged[at] ^= 1 << int(rng.integers(0, 8)) if k % 2 else 0xFF
        (case / ROWS_NAME).write_bytes(bytes(damaged))
        (case / FLAGS_NAME).write_bytes(flags)
        try:
            load_log(case)
        except InputError as exc:
            refused += 1
            assert exc.hint and "\n" not in str(exc)
    assert refused >= 20  # the header's damage is seen
    (folder / FLAGS_NAME).unlink()
    with pytest.raises(InputError, match="log.flags is missing") as caught:
        load_log(folder)
    assert caught.value.hint and (folder / ROWS_NAME).exists()
    (folder / FLAGS_NAME).write_bytes(flags[:len(flags) // 2])  # records past its lines
    with pytest.raises(InputError, match=r"log\.rows is damaged: a record's flags"):
        load_log(folder)


@pytest.mark.parametrize("name", [LOG_NAME, META_NAME, PARQUET_NAME, ROWS_NAME, FLAGS_NAME])
def test_a_fifo_in_place_of_a_log_file_is_refused_not_waited_on(tmp_path, name):
    """Review 28: a FIFO as log.parquet held hubo export for ever, deaf to SIGTERM (a
    blocking read in the Parquet reader). Any of a run folder's log files that is not a plain
    file is refused at once (exit 2)."""
    if name in (ROWS_NAME, FLAGS_NAME):
        _killed_run(tmp_path)
    else:
        _write(tmp_path, _rows(10)).close()
    (tmp_path / name).unlink()
    os.mkfifo(tmp_path / name)
    with pytest.raises(InputError, match=f"{name} is not a plain file"):
        load_log(tmp_path)


def test_metadata_in_one_rewrite_equals_one_key_at_a_time(tmp_path):
    one, many = tmp_path / "one", tmp_path / "many"
    items = {"scene": {"hole_world_m": [np.array([0.1, -0.2, 1e-7]), [1.0, math.nan, 3]],
                       "size": (np.float64(0.5), np.int64(3), np.bool_(True))},
             "command": "task-cut", "balance": None, "limit": math.inf}
    for folder in (one, many):
        folder.mkdir()
        _write(folder, _rows(3)).close()
    for key, value in items.items():
        set_log_metadata(one, key, value)
    update_log_metadata(many, items)
    texts = [[line for line in (folder / META_NAME).read_text().splitlines()
              if '"started_utc"' not in line] for folder in (one, many)]  # two logs: two starts
    assert texts[0] == texts[1]
    metadata = load_log(many).metadata
    assert metadata["scene"] == {"hole_world_m": [[0.1, -0.2, 1e-7], [1.0, None, 3]],
                                 "size": [0.5, 3, True]}
    assert metadata["limit"] is None and metadata["balance"] is None
    assert list(metadata) == ["scene", "command", "balance", "limit"]


@pytest.mark.parametrize("version,message", [
    (99, "format version 99; this hubo-cli .* reads up to version 2"),  # was read, exit 0
    (1, "claims format version 1; no hubo-cli wrote a version below 2"),  # review 19: read
    (-3, "claims format version -3; no hubo-cli wrote a version below 2"),  # without a word
    ("2", "not a period log's sidecar"),
    (True, "not a period log's sidecar"),
])
def test_a_log_of_a_newer_or_unknown_format_is_refused(tmp_path, version, message):
    _write(tmp_path, _rows(5)).close()
    sidecar = json.loads((tmp_path / META_NAME).read_text())
    (tmp_path / META_NAME).write_text(json.dumps(sidecar | {"version": version}))
    with pytest.raises(InputError, match=message) as info:
        load_log(tmp_path)
    assert ("upgrade hubo-cli" in info.value.hint) == (version == 99)
    (tmp_path / META_NAME).write_text("[" * 5000 + "]" * 5000)  # was a RecursionError
    with pytest.raises(InputError, match="not a period log's sidecar"):
        load_log(tmp_path)


def test_a_cut_log_says_it_ends_early(tmp_path):
    """Review 19: a run's log.csv cut to half (no log.parquet) was exported and replayed
    without a word. The log says how many periods it holds of those its log.json counts, and
    hubo export / replay say it on a warning line and in their JSON (``periods_expected``)."""
    from hubo_cli.cli.output import report_log_warnings

    _write(tmp_path, _rows(40)).close()
    whole = load_log(tmp_path)
    assert whole.periods_expected == 40 and whole.cut_short == ""
    (tmp_path / PARQUET_NAME).unlink()
    lines = (tmp_path / LOG_NAME).read_text().splitlines(keepends=True)
    (tmp_path / LOG_NAME).write_text("".join(lines[:1 + 17]))
    cut = load_log(tmp_path)
    assert len(cut) == 17 and cut.cut_short.startswith("the log ends early: 17 of the 40 periods")
    report: dict = {}
    report_log_warnings(cut, report, as_json=True)
    assert report["periods_expected"] == 40
    report_log_warnings(whole, report := {}, as_json=True)
    assert "periods_expected" not in report  # (its odd measured joints are log_suspect)
