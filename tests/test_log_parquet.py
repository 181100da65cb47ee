"""The Parquet copy of a log: counters, codes and flags become integers only where nothing is
lost, values read back equal to the CSV's, and the file's metadata describes it."""

import json
import sys

import numpy as np
import polars as pl
import pytest

from hubo_cli.control.log_parquet import column_unit, parquet_metadata, write_log_parquet


def _table(rng: np.random.Generator, rows: int) -> pl.DataFrame:
    """A log-like table: whole-valued counters with gaps, and hostile ones of each kind."""
    def gaps(values):
        values = np.asarray(values, dtype=float)
        values[rng.random(rows) < 0.3] = np.nan
        return values

    return pl.DataFrame({
        "period_count": np.arange(rows, dtype=float),
        "t_s": np.arange(rows) * 0.005,
        "status_code": rng.integers(0, 8, rows).astype(float),
        "flags": ["estop;slowing" if k % 3 else "" for k in range(rows)],
        "limiter_clamped_count": gaps(rng.integers(0, 24, rows)),
        "phase_code": gaps(rng.integers(-3, 3, rows)),
        "cp_flag": gaps(rng.integers(0, 2, rows)),
        "all_missing_count": np.full(rows, np.nan),
        "fraction_count": gaps(rng.integers(0, 5, rows) + 0.5),  # not whole: stays float
        "inf_code": np.where(np.arange(rows) == rows // 2, np.inf, 1.0),
        "huge_count": np.full(rows, 1e300),
        "wide_flag": gaps(rng.integers(0, 1000, rows)),  # beyond int8: stays float
        "q_RSY_rad": rng.normal(size=rows),
    })


@pytest.mark.parametrize("seed", range(4))
def test_integers_only_where_nothing_is_lost_and_values_read_back(tmp_path, seed):
    rng = np.random.default_rng(seed)
    frame = _table(rng, int(rng.integers(1, 300)))
    path = tmp_path / "log.parquet"
    write_log_parquet(frame, path, {"started_utc": "2026-01-01T00:00:00.000000Z",
                                    "hubo_cli_version": "0.1.0", "units": "legend"})
    back = pl.read_parquet(path)
    assert back.columns == frame.columns
    kinds = back.schema
    for name in ("period_count", "status_code", "limiter_clamped_count", "phase_code",
                 "all_missing_count"):
        assert kinds[name] == pl.Int64, name
    assert kinds["cp_flag"] == pl.Int8
    for name in ("fraction_count", "inf_code", "huge_count", "wide_flag", "q_RSY_rad", "t_s"):
        assert kinds[name] == pl.Float64, name
    for name in frame.columns:
        if name == "flags":
            assert back[name].to_list() == frame[name].to_list()
            continue
        got = back[name].cast(pl.Float64).fill_null(np.nan).to_numpy()
        assert np.array_equal(got, frame[name].to_numpy(), equal_nan=True), name
    metadata = pl.read_parquet_metadata(path)
    assert metadata["started_utc"] == "2026-01-01T00:00:00.000000Z"
    assert json.loads(metadata["column_units"])["limiter_clamped_count"] == "count"
    pandas = json.loads(metadata["pandas"])
    assert {c["name"]: c["numpy_type"] for c in pandas["columns"]} == {
        "period_count": "Int64", "status_code": "Int64", "limiter_clamped_count": "Int64",
        "phase_code": "Int64", "cp_flag": "Int8", "all_missing_count": "Int64"}


def test_metadata_of_an_old_sidecar_leaves_out_what_it_lacks():
    frame = pl.DataFrame({"t_s": [0.0], "flags": [""]})
    metadata = parquet_metadata({"format": "hubo-cli period log", "version": 2}, frame)
    assert "started_utc" not in metadata and metadata["format_version"] == "2"
    assert json.loads(metadata["column_units"]) == {"t_s": "s"}
    assert all(isinstance(v, str) for v in metadata.values())


def test_column_units_follow_the_name_endings():
    assert [column_unit(n) for n in ("compute_us", "t_s", "cmd_RSP_rad", "torso_x_m",
                                     "right_foot_fz_n", "wrist_torque_nm", "limiter_clamped_count",
                                     "status_code", "cp_flag", "flags")] == [
        "us", "s", "rad", "m", "N", "N m", "count", "enumeration", "0/1", None]


def test_without_pyarrow_polars_writes_the_same_types_and_metadata(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow fails
    frame = _table(np.random.default_rng(9), 50)
    write_log_parquet(frame, tmp_path / "log.parquet", {"started_utc": "2026-01-01T00:00:00Z"})
    back = pl.read_parquet(tmp_path / "log.parquet")
    assert back.schema["status_code"] == pl.Int64 and back.schema["cp_flag"] == pl.Int8
    assert pl.read_parquet_metadata(tmp_path / "log.parquet")["started_utc"].startswith("2026")


def test_a_log_written_by_a_run_and_one_recovered_after_a_crash_describe_themselves(tmp_path):
    from hubo_cli.control.log import META_NAME, PeriodLog, load_log

    folders = []
    for name, closes in (("closed", True), ("crashed", False)):
        folder = tmp_path / name
        folder.mkdir()
        log = PeriodLog(folder / "log.csv", ("A", "B"), ("phase_code", "x_m"))
        for k in range(25):
            q = np.array([0.1 * k, -0.2])
            log.write(k, k * 0.005, k % 3, 10.0, 0.0, {"holding"} if k % 2 else set(), q, q,
                      q, {"phase_code": float(k // 10)} if k % 4 else {})
        if closes:
            log.close()
        else:  # the process dies: its mapping and lock go, the log is never closed
            log._map.close()
            log._rows_file.close()
        assert len(load_log(folder)) == 25  # a crashed run's log is finished here
        folders.append(folder)
    for folder in folders:
        sidecar = json.loads((folder / META_NAME).read_text())
        metadata = pl.read_parquet_metadata(folder / "log.parquet")
        assert metadata["started_utc"] == sidecar["started_utc"]
        assert json.loads(metadata["joint_names"]) == ["A", "B"]
        table = pl.read_parquet(folder / "log.parquet")
        assert table.schema["phase_code"] == table.schema["status_code"] == pl.Int64
        assert table["phase_code"].null_count() == 7  # the periods that did not report it
