"""One lookup for the data folders (``robots/``, ``tasks/``, ``trajectories/``).

In a wheel they live inside the package under ``hubo_cli/_data/``; in a source checkout
(editable install) they are the folders at the top of the repository.
"""

from __future__ import annotations

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
