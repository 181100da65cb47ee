"""Run folders: every command writes ``runs/<time>-<command>/`` with its log and summary."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np


def make_run_dir(command: str, out: str | Path | None = None) -> Path:
    """Create and return the run folder (``out`` if given, else runs/<UTC time>-<command>)."""
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
        path = Path("runs") / f"{stamp}-{command}"
        n = 1
        while path.exists():
            n += 1
            path = Path("runs") / f"{stamp}-{command}-{n}"
    else:
        path = Path(out)
    path.mkdir(parents=True, exist_ok=True)
    return path


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: str | Path, data: dict) -> Path:
    """Write ``data`` as pretty JSON (numpy values converted, NaN/inf as null)."""
    path = Path(path)
    path.write_text(json.dumps(_jsonable(data), indent=2) + "\n")
    return path
