"""Fuzz every file-reading command with random bytes, random TOML and random CSV.

Whatever the file holds: no traceback (nor the CLI's "internal error", which marks a bug), an
exit code in {0, 1, 2, 3, 4, 5}, and no file outside the command's output changed. Bounded by
few examples per command, so the module runs in well under 30 s; no per-example wall-clock
deadline (on a machine loaded by other jobs one example may take seconds, which is not a bug).
"""

import math
import struct
import tomllib
import warnings
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hubo_cli.cli.main import main
from hubo_cli.fastrak.capture import MAGIC
from hubo_cli.resources import data_file

pytestmark = pytest.mark.xdist_group("fuzz")  # module-scoped runs: one worker

SLOT = data_file("tasks", "cut-slot.toml").read_text()
FUZZ = settings(max_examples=12, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
EXIT_CODES = {0, 1, 2, 3, 4, 5}

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(-10**30, 10**30), st.sampled_from([0, -1, 1e300, -1e300, 1e-300]))
texts = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=20)
scalars = st.one_of(numbers, texts, st.booleans())
toml_values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(min_size=1, max_size=8), inner,
                                             max_size=4), max_leaves=12)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.encode("unicode_escape").decode().replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return "{" + ", ".join(f'"{k}" = {_toml_value(v)}' for k, v in value.items()) + "}"


def _mutated_task(key_index: int, value) -> str:
    """The cut-slot task with its key_index-th ``key = value`` line's value replaced."""
    lines = SLOT.splitlines()
    assignments = [i for i, line in enumerate(lines)
                   if "=" in line and not line.lstrip().startswith("#")]
    i = assignments[key_index % len(assignments)]
    key = lines[i].split("=", 1)[0]
    lines[i] = f"{key}= {_toml_value(value)}"
    return "\n".join(lines) + "\n"


def _csv(header: list[str], rows: list[list]) -> str:
    return "\n".join([",".join(header)] + [",".join(str(v) for v in row) for row in rows]) + "\n"


POSE_HEADER = ["t_s", "station", "x_m", "y_m", "z_m", "qw", "qx", "qy", "qz", "status"]
IK_HEADER = [f"T{r}{c}" for r in range(4) for c in range(4)]
pose_rows = st.lists(st.lists(st.one_of(numbers, st.just(""), st.just("x")), min_size=10,
                              max_size=10), min_size=1, max_size=30)
ik_rows = st.lists(st.lists(numbers, min_size=16, max_size=16), min_size=1, max_size=10)


def _invoke(folder: Path, argv: list[str], outputs: tuple[Path, ...] = ()) -> None:
    """Run hubo; check the exit code, the absence of tracebacks and that only ``outputs``
    (files or folders) changed inside ``folder``."""
    def snapshot():
        return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()
                and not any(p == o or o in p.parents for o in outputs)}

    before = snapshot()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        result = CliRunner().invoke(main, argv)
    output = result.output
    assert "Traceback" not in output and "internal error" not in output, output
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        repr(result.exception), output)
    assert result.exit_code in EXIT_CODES, output
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)], output
    assert snapshot() == before


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """Run the commands once first, so that compiling the IK kernels and loading the model
    happen once and not inside the first examples."""
    folder = tmp_path_factory.mktemp("warm")
    goals = folder / "goals.csv"
    goals.write_text(_csv(IK_HEADER, [[1, 0, 0, 0.4, 0, 1, 0, -0.2, 0, 0, 1, 0, 0, 0, 0, 1]]))
    CliRunner().invoke(main, ["ik", "right-arm", "--batch", str(goals), "--out",
                              str(folder / "out.csv")])
    poses = folder / "poses.csv"
    poses.write_text(_csv(POSE_HEADER, [[0.0, 1, 0.3, -0.1, -0.2, 1, 0, 0, 0, ""]]))
    CliRunner().invoke(main, ["teleop", "--replay", str(poses), "--driver", "ideal",
                              "--duration", "0.2", "--out", str(folder / "run")])


@pytest.fixture
def folder(tmp_path, monkeypatch, warm):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "user.txt").write_text("the user's own file\n")
    return tmp_path


@FUZZ
@given(blob=st.binary(max_size=400))
def test_random_bytes(folder, blob):
    path = folder / "input.bin"
    path.write_bytes(blob)
    capture = folder / "capture.fastrak"
    capture.write_bytes(MAGIC + blob)
    out = folder / "out"
    _invoke(folder, ["task", "run", str(path), "--driver", "ideal", "--out", str(out)], (out,))
    _invoke(folder, ["teleop", "--replay", str(path), "--driver", "ideal", "--duration", "0.2",
                     "--out", str(out)], (out,))
    for source in (path, capture):
        _invoke(folder, ["fastrak", "decode", str(source), "--out", str(out / "p.csv"),
                         "--force"], (out,))
    _invoke(folder, ["ik", "right-arm", "--batch", str(path), "--out", str(out / "ik.csv")],
            (out,))


@FUZZ
@given(document=st.dictionaries(st.text(min_size=1, max_size=10), toml_values, max_size=6))
def test_random_toml_documents(folder, document):
    path = folder / "task.toml"
    path.write_text("\n".join(f'"{k.encode("unicode_escape").decode().replace(chr(34), "")}" = '
                              f"{_toml_value(v)}" for k, v in document.items()) + "\n")
    out = folder / "out"
    _invoke(folder, ["task", "run", str(path), "--driver", "ideal", "--out", str(out)], (out,))
    _invoke(folder, ["task", "show", str(path)])


@FUZZ
@given(key_index=st.integers(0, 200), value=toml_values)
def test_shipped_task_with_one_value_garbled(folder, key_index, value):
    text = _mutated_task(key_index, value)
    path = folder / "task.toml"
    path.write_text(text)
    _invoke(folder, ["task", "show", str(path)])
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        data = None
    # running a task that still loads would cut a slot for a minute: the loader is what the
    # fuzz exercises, so only files it refuses are run
    if data is None or "steps" not in data or not isinstance(data["steps"], list):
        _invoke(folder, ["task", "run", str(path), "--driver", "ideal",
                         "--out", str(folder / "out")], (folder / "out",))


@FUZZ
@given(rows=pose_rows)
def test_random_pose_logs(folder, rows):
    path = folder / "poses.csv"
    path.write_text(_csv(POSE_HEADER, rows))
    out = folder / "out"
    _invoke(folder, ["teleop", "--replay", str(path), "--driver", "ideal", "--duration", "0.2",
                     "--out", str(out)], (out,))
    _invoke(folder, ["fastrak", "decode", str(path), "--out", str(out / "p.csv")], (out,))


@FUZZ
@given(rows=ik_rows)
def test_random_ik_batches(folder, rows):
    path = folder / "goals.csv"
    path.write_text(_csv(IK_HEADER, rows))
    out = folder / "out.csv"
    _invoke(folder, ["ik", "right-arm", "--batch", str(path), "--out", str(out)], (out,))


@FUZZ
@given(chunks=st.lists(st.tuples(st.floats(allow_nan=True, allow_infinity=True),
                                 st.integers(0, 2**32 - 1), st.binary(max_size=40)),
                       max_size=6))
def test_random_capture_chunks(folder, chunks):
    header = b'{"format": "binary", "output_list": [2, 11, 1], "units": "cm", ' \
             b'"baud": 115200, "stations": [1]}\n'
    body = b"".join(struct.pack("<dI", t, n) + data for t, n, data in chunks)
    path = folder / "c.fastrak"
    path.write_bytes(MAGIC + header + body)
    out = folder / "out"
    _invoke(folder, ["fastrak", "decode", str(path), "--out", str(out / "p.csv"), "--force"],
            (out,))
    _invoke(folder, ["teleop", "--replay", str(path), "--driver", "ideal", "--duration", "0.2",
                     "--out", str(out)], (out,))
