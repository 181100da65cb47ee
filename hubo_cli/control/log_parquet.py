"""The Parquet copy of a period log: integer columns stored as integers, and the file's own
key-value metadata saying what it holds (so that it can be read without its sidecar).

Columns named ``period_count``, ``status_code`` or ending in ``_count``, ``_code`` or ``_flag``
are stored as 64-bit integers (``_flag``: 8-bit), a missing value (NaN in the CSV) as null; a
column of that kind holding a fraction or an infinity stays float64, so nothing is lost. Every
other column stays float64 and ``flags`` text.

The Parquet metadata (``pyarrow.parquet.read_metadata(f).metadata``,
``polars.read_parquet_metadata(f)``; every value a string, JSON where it is a list or a mapping):
``format``, ``format_version``, ``started_utc`` (ISO 8601), ``hubo_cli_version``, ``units`` (the
legend), ``column_units`` (column -> unit), ``status_codes`` (code -> label), ``joint_names`` and
``pandas`` (pandas' own key: the integer columns as its nullable ``Int64``/``Int8``, so that
``pandas.read_parquet`` gives integers also where values are missing).
"""

from __future__ import annotations

import json
from pathlib import Path

import polars as pl

INTEGER_SUFFIXES = ("_count", "_code")
FLAG_SUFFIX = "_flag"
# a column name's ending -> its unit (the unit legend of the sidecar, for each column)
UNIT_SUFFIXES = (("_us", "us"), ("_s", "s"), ("_rad", "rad"), ("_deg", "deg"), ("_nm", "N m"),
                 ("_n", "N"), ("_mm", "mm"), ("_m", "m"), ("_count", "count"),
                 ("_code", "enumeration"), ("_flag", "0/1"))
# the sidecar's fields copied into the Parquet metadata
METADATA_KEYS = ("format", "version", "started_utc", "hubo_cli_version", "units",
                 "status_codes", "joint_names")


def column_unit(name: str) -> str | None:
    """The unit a column's name ends in (``t_s`` -> ``s``), or None (``flags``)."""
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return None


def _integer_type(name: str):
    if name.endswith(FLAG_SUFFIX):
        return pl.Int8
    return pl.Int64 if name.endswith(INTEGER_SUFFIXES) else None


def with_integer_columns(frame: pl.DataFrame) -> pl.DataFrame:
    """``frame`` (float columns, NaN for missing) with its counters, codes and flags as
    integers where every known value is a whole number in the type's range."""
    casts = []
    for name in frame.columns:
        kind = _integer_type(name)
        column = frame.get_column(name)
        if kind is None or not column.dtype.is_float():
            continue
        known = column.filter(column.is_not_nan())
        bound = 127 if kind == pl.Int8 else 2.0 ** 53  # exact in float64
        if len(known) and not (bool(known.is_finite().all())
                               and bool((known.round() == known).all())
                               and -bound <= known.min() and known.max() <= bound):
            continue
        casts.append(pl.col(name).fill_nan(None).cast(kind))
    return frame.with_columns(casts) if casts else frame


def _pandas_metadata(frame: pl.DataFrame) -> dict:
    """pandas' own Parquet metadata for the integer columns: its nullable integer types
    (``Int64``, ``Int8``), so that ``pandas.read_parquet`` keeps them integers where some
    values are missing (it would give float64 there) and gives every run the same types."""
    columns = []
    for name, kind in frame.schema.items():
        if kind in (pl.Int64, pl.Int8):
            bits = "64" if kind == pl.Int64 else "8"
            columns.append({"name": name, "field_name": name, "pandas_type": f"int{bits}",
                            "numpy_type": f"Int{bits}", "metadata": None})
    return {"index_columns": [], "column_indexes": [], "columns": columns,
            "creator": {"library": "hubo-cli"}, "pandas_version": "2.0.0"}


def parquet_metadata(sidecar: dict, frame: pl.DataFrame) -> dict[str, str]:
    """The Parquet key-value metadata of a log table (its integer columns already cast) from
    its sidecar's fixed part (keys it lacks, as in logs written before they were added, are left
    out)."""
    out = {("format_version" if key == "version" else key): value
           for key in METADATA_KEYS if (value := sidecar.get(key)) is not None}
    out["column_units"] = {c: unit for c in frame.columns
                           if (unit := column_unit(c)) is not None}
    out["pandas"] = _pandas_metadata(frame)
    return {k: v if isinstance(v, str) else json.dumps(v) for k, v in out.items()}


def write_log_parquet(frame: pl.DataFrame, path: Path, sidecar: dict) -> None:
    """Write the log table ``frame`` (as read from the CSV) to ``path`` with integer columns
    and the metadata of ``sidecar`` (the sidecar's fixed part)."""
    frame = with_integer_columns(frame)
    metadata = parquet_metadata(sidecar, frame)
    try:  # pyarrow (which pandas reads Parquet with) takes the metadata from the Arrow schema
        import pyarrow as pa
    except ImportError:  # no pandas either: the metadata in the file only
        arrow_schema = None
    else:
        arrow_schema = pa.schema(frame.schema).with_metadata(metadata)
    frame.write_parquet(path, metadata=metadata, arrow_schema=arrow_schema)
