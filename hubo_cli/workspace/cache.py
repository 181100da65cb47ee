"""On-disk cache of workspace branch masks, keyed by everything that determines them.

Folder: ``$HUBO_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/hubo-cli`` or ``~/.cache/hubo-cli``,
then ``workspace/<key>.npz``. The key hashes the arm's lengths, joint limits, tool transform,
the orientation and the grid, plus :data:`CACHE_VERSION` (bump it when the kernels change what
they compute). A cache that cannot be read or written is skipped, never an error.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from hubo_cli.kinematics import Limb
from hubo_cli.workspace.grid import Grid

CACHE_VERSION = 1


def cache_dir() -> Path:
    """The folder workspace masks are cached in (not created here)."""
    root = os.environ.get("HUBO_CACHE_DIR")
    if root:
        return Path(root) / "workspace"
    xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(xdg) / "hubo-cli" / "workspace"


def cache_key(limb: Limb, R_N_E: np.ndarray, grid: Grid) -> str:
    """A hex digest of everything the branch masks depend on."""
    h = hashlib.sha256(f"workspace-masks v{CACHE_VERSION} {limb.name}".encode())
    for arr in (limb.lengths_m, limb.T_N_base, limb.T_6_end, limb.lower_rad, limb.upper_rad,
                R_N_E, grid.x_m, grid.y_m, grid.z_m):
        h.update(np.ascontiguousarray(np.round(arr, 12), dtype=float).tobytes())
    return h.hexdigest()[:32]


def load_masks(key: str, shape: tuple[int, int, int]) -> np.ndarray | None:
    """The cached masks for ``key`` (None when absent, unreadable or of another shape)."""
    path = cache_dir() / f"{key}.npz"
    try:
        with np.load(path) as data:
            masks = data["masks"]
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        return None
    return masks if masks.shape == shape and masks.dtype == np.uint8 else None


def save_masks(key: str, masks: np.ndarray) -> Path | None:
    """Store masks under ``key`` (atomically); returns the path, or None if it could not."""
    folder = cache_dir()
    tmp = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, suffix=".npz", delete=False) as f:
            tmp = Path(f.name)
            np.savez_compressed(f, masks=masks)
        path = folder / f"{key}.npz"
        os.replace(tmp, path)
    except OSError:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        return None
    return path
