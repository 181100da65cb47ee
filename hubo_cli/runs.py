"""Run folders: every command writes ``runs/<time>-<command>/`` with its log and summary.

A run folder carries a small marker file (``.hubo-run``, the command's safe name) so that a later
run of the same command may reuse it (``--out`` given twice), while a folder holding anything
else (a user's own files, another command's run) is refused: a run never writes over files it
did not make. A default folder's name is made safe (:func:`folder_name`: a task file's
``name`` cannot lead out of ``runs/``). Output files outside run folders go through
:mod:`hubo_cli.outputs`.

A reused folder loses its previous run's files first (those its ``summary.json`` lists under
``files``, and the summary itself; :func:`_clear_previous_run`): a plot the new run does not
draw would otherwise lie beside the new summary (review 28: an e-stopped cut's folder kept
the completed run's ``path.png``). Files the previous run did not list stay.

A run holds its folder locked while it writes it (``flock`` on the marker, held from
:func:`make_run_dir` to :func:`release_run_dir`, or the process's end): a second run into the
same folder is refused before it writes anything, and the first is left alone.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import sys
import time
import unicodedata
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.outputs import replacing

try:  # POSIX: advisory locks
    import fcntl
except ImportError:  # pragma: no cover (no locks: a second run is not detected)
    fcntl = None

MARKER = ".hubo-run"
RUNS_DIR = Path("runs")
NAME_MAX_BYTES = 96  # of a folder name's command part in UTF-8 (a file system allows 255)


def folder_name(command: str) -> str:
    """``command`` (e.g. ``task-<the task file's name>``) as one safe folder name: letters,
    digits, ``-``, ``_`` and single dots are kept; every other run of characters (path
    separators, ``..``, spaces, control and bidi characters) becomes ``_``; no leading or
    trailing dot or dash; at most :data:`NAME_MAX_BYTES` bytes; ``unnamed`` if nothing is left.
    A letter the file system's encoding cannot write (``café`` under ``LANG=C``, whose file
    names are ASCII) becomes ``_`` too."""
    encoding = sys.getfilesystemencoding()
    text = unicodedata.normalize("NFC", command)
    name = "".join(c if (c.isalnum() or c in "-_.") and _encodable(c, encoding) else "_"
                   for c in text)
    name = re.sub(r"[_.]*\.\.[_.]*|__+", "_", name)[:NAME_MAX_BYTES]
    while len(name.encode(encoding)) > NAME_MAX_BYTES:
        name = name[:-1]
    return name.strip("._-") or "unnamed"


def _encodable(char: str, encoding: str) -> bool:
    try:
        char.encode(encoding)
    except UnicodeEncodeError:
        return False
    return True


SHOWN_MAX_CHARS = 80  # of a name shown on the terminal or in a plot title


def shown_name(text: str) -> str:
    """``text`` (e.g. a task file's ``name``) safe to print or draw: control and format
    characters (Unicode Cc, Cf, Zl, Zp: newlines, escape sequences, bidi overrides) become a
    visible escape (``\\n``, ``\\x1b``, ``\\u202e``), at most :data:`SHOWN_MAX_CHARS`
    characters (``...`` marks a cut)."""
    shown = "".join(c.encode("unicode_escape").decode("ascii")
                    if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp") else c
                    for c in str(text))
    return shown if len(shown) <= SHOWN_MAX_CHARS else shown[:SHOWN_MAX_CHARS - 3] + "..."
# run folder (resolved) -> [the marker's file descriptor, holding its lock; how many holders
# in this process]: make_run_dir takes a hold, release_run_dir gives one back
_LOCKS: dict[Path, list[int]] = {}


def _default_dir(command: str) -> Path:
    """A new folder ``runs/<UTC time>-<command>`` (``-2``, ``-3`` ... if taken), checked to be
    inside ``runs/``."""
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    base = f"{stamp}-{folder_name(command)}"
    path = RUNS_DIR / base
    n = 1
    while os.path.lexists(path):
        n += 1
        path = RUNS_DIR / f"{base}-{n}"
    if path.resolve().parent != RUNS_DIR.resolve():
        raise InputError(f"the run folder {path} would lie outside {RUNS_DIR}/",
                         hint="give the run folder with --out")
    return path


def run_dir_owner(path: str | Path) -> str | None:
    """The command that made the run folder ``path`` (from its marker), or None."""
    try:
        return (Path(path) / MARKER).read_text(encoding="utf-8").strip() or None
    except (OSError, UnicodeDecodeError):
        return None


def check_run_dir(command: str, out: str | Path) -> None:
    """Refuse an ``--out`` folder a run of ``command`` must not write into (nothing is created).

    Raises:
        InputError: ``out`` (or a folder above it) is a file, or ``out`` holds files that are
            not a previous run of the same command.
    """
    path = Path(out)
    for parent in (path, *path.parents):
        if parent.exists() and not parent.is_dir():
            where = "" if parent == path else f" ({parent} is a file)"
            raise InputError(f"--out {path} cannot be a run folder{where}",
                             hint="give a folder path for the run (it is created if missing)")
    if path.is_dir():
        try:
            entries = [p.name for p in path.iterdir()]
        except OSError as exc:
            raise InputError(f"cannot read --out {path}: {exc.strerror or exc}",
                             hint="choose a folder you can write") from None
        owner = run_dir_owner(path)
        if entries and entries != [MARKER] and owner != folder_name(command):
            whose = (f"a 'hubo {shown_name(owner)}' run" if owner
                     else f"files that are not a hubo run ({', '.join(sorted(entries)[:3])}"
                          f"{', ...' if len(entries) > 3 else ''})")
            raise InputError(f"--out {path} already holds {whose}; nothing was written",
                             hint="choose a new or empty folder, or leave out --out "
                                  f"(runs/<time>-{folder_name(command)})")


def make_run_dir(command: str, out: str | Path | None = None) -> Path:
    """Create and return the run folder (``out`` if given, else runs/<UTC time>-<command>).

    The folder gets its marker; a folder already marked for ``command`` is reused. The
    folder stays locked until :func:`release_run_dir` (or the process ends).

    Raises:
        InputError: ``out`` is refused (see :func:`check_run_dir`), another run is writing it,
            or it cannot be created or written (the operating system's reason).
    """
    path = _default_dir(command) if out is None else Path(out)
    check_run_dir(command, path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        _lock(path, folder_name(command))
    except OSError as exc:
        raise InputError(f"cannot create the run folder {path}: {exc.strerror or exc}",
                         hint="choose a writable --out folder") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise InputError(f"the run folder {path} is not writable",
                         hint="choose a writable --out folder")
    return path


def _lock(path: Path, command: str) -> None:
    """Take a hold of the run folder's lock (the marker, written with ``command``); a lock
    another process holds is refused (InputError)."""
    held = _LOCKS.get(path.resolve())
    if held is not None:  # this process's run already holds it
        held[1] += 1
        return
    fd = os.open(path / MARKER, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.ftruncate(fd, 0)
        os.write(fd, (command + "\n").encode())
    except BlockingIOError:
        os.close(fd)
        raise InputError(f"--out {path} is being written by another run; nothing was written",
                         hint="wait for that run to end, or choose another --out") from None
    except BaseException:
        os.close(fd)
        raise
    _LOCKS[path.resolve()] = [fd, 1]
    _clear_previous_run(path)


def _clear_previous_run(path: Path) -> None:
    """Remove the files of the run that last wrote ``path`` (its summary's ``files`` and the
    summary), the folder locked for the next; names that are not plain file names in the
    folder are left alone, and a file that cannot be removed is left to be replaced."""
    summary = path / "summary.json"
    try:  # only a plain file is read (a FIFO there would hold the run)
        listed = (json.loads(summary.read_text(encoding="utf-8")).get("files", [])
                  if summary.is_file() else [])
    except (OSError, ValueError, AttributeError):
        listed = []
    names = {"summary.json"} | {name for name in listed if isinstance(name, str)}
    for name in names:
        if name in ("", ".", "..", MARKER) or Path(name).name != name:
            continue
        with contextlib.suppress(OSError):
            if (path / name).is_file():
                (path / name).unlink()


def release_run_dir(path: str | Path) -> None:
    """Give back a hold of the run folder's lock (:func:`make_run_dir` took it); the last
    one unlocks the folder."""
    key = Path(path).resolve()
    held = _LOCKS.get(key)
    if held is None:
        return
    held[1] -= 1
    if held[1] <= 0:
        del _LOCKS[key]
        os.close(held[0])


@contextlib.contextmanager
def reserved_run_dir(command: str, out: str | Path | None = None) -> Iterator[Path]:
    """Create the run folder before any work (so a bad ``--out`` fails at once) and remove it
    again if the command ends without writing anything into it (a refused run)."""
    path = make_run_dir(command, out)
    try:
        yield path
    finally:
        discard_if_unused(path)
        release_run_dir(path)


def discard_if_unused(path: str | Path) -> bool:
    """Remove a run folder that holds nothing but its marker (a run refused before it wrote
    anything). Returns True if it was removed."""
    path = Path(path)
    try:
        entries = [p.name for p in path.iterdir()]
    except OSError:
        return False
    if entries != [MARKER]:
        return False
    with contextlib.suppress(OSError):
        (path / MARKER).unlink()
        path.rmdir()
        return True
    return False


def _jsonable(value):
    kind = type(value)  # the plain types first: a run's metadata holds some 10^5 floats
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is int or kind is str or kind is bool or value is None:
        return value
    if kind is list or kind is tuple:
        return [_jsonable(v) for v in value]
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
    """Write ``data`` as pretty JSON (numpy values converted, NaN/inf as null), whole or not
    at all: written beside ``path`` and renamed over it, so a full disk or an interrupt never
    leaves a summary cut short.

    Raises:
        InputError: the file cannot be written (the former one, if any, is kept).
    """
    path = Path(path)
    text = json.dumps(_jsonable(data), indent=2) + "\n"
    with replacing(path) as temporary:
        try:
            temporary.write_text(text, encoding="utf-8")
        except OSError as exc:
            raise InputError(f"cannot write {path}: {exc.strerror or exc}",
                             hint="free disk space or choose a writable path") from None
    return path
