"""One lookup for the data folders (``robots/``, ``tasks/``, ``trajectories/``).

In a wheel they live inside the package under ``hubo_cli/_data/``; in a source checkout
(editable install) they are the folders at the top of the repository.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Sequence
from pathlib import Path

from hubo_cli.errors import ConfigError, quoted

_PACKAGE_DIR = Path(__file__).resolve().parent
_FOLDERS = ("robots", "tasks", "trajectories")


def data_dir(folder: str) -> Path:
    """Return the directory holding one of the shipped data folders.

    Args:
        folder: ``"robots"``, ``"tasks"`` or ``"trajectories"``.
    """
    if folder not in _FOLDERS:
        raise ConfigError(f"unknown data folder {quoted(folder)}", hint=f"use one of {_FOLDERS}")
    for candidate in (_PACKAGE_DIR / "_data" / folder, _PACKAGE_DIR.parent / folder):
        if candidate.is_dir():
            return candidate
    raise ConfigError(
        f"the {folder}/ data folder is not installed next to {_PACKAGE_DIR}",
        hint="reinstall hubo-cli (pip install .) so the data ships with the package",
    )


def data_file(folder: str, relative: str) -> Path:
    """Return the path of a file inside a shipped data folder, checking that it exists."""
    path = data_dir(folder) / relative
    if not path.is_file():
        existing = sorted(p.name for p in path.parent.glob("*")) if path.parent.is_dir() else []
        raise ConfigError(
            f"no file {quoted(relative)} in {folder}/",
            path=str(path),
            hint=f"files there: {', '.join(existing) or 'none'}",
        )
    return path


def tree_fingerprint(trees: Sequence[tuple[str, Path, str]]) -> str:
    """A SHA-256 (its first 16 hex digits) of the files under each ``(label, root, glob
    pattern)``, by their paths relative to the root (with its label) and their bytes: equal
    trees give equal fingerprints wherever they lie (``__pycache__`` is left out)."""
    digest = hashlib.sha256()
    for label, root, pattern in trees:
        for path in sorted(p for p in root.rglob(pattern) if p.is_file()
                           and "__pycache__" not in p.parts):
            digest.update(f"{label}/{path.relative_to(root).as_posix()}\0".encode())
            digest.update(path.read_bytes())
            digest.update(b"\0")
    return digest.hexdigest()[:16]


@functools.cache
def source_fingerprint() -> str:
    """What decides a run beyond the version number: the package's Python source files and
    the robot files it reads (``robots/``), hashed once per process (about 40 ms). Two
    checkouts of the same version with different code differ here; ``hubo sweep`` compares it
    between the client and every worker. The tasks are not in it (a sweep sends a task's
    text with its jobs)."""
    return tree_fingerprint([("hubo_cli", _PACKAGE_DIR, "*.py"),
                             ("robots", data_dir("robots"), "*")])
