"""The files a workspace run writes: workspace.npz (grids, masks, per-distance results) and the
summary dictionary that becomes summary.json.

workspace.npz holds, for every mapped arm (key prefix ``right_`` or ``left_``), in SI units:

- ``x_m``, ``y_m``, ``z_m``: the grid axes (1-D, m);
- ``masks``: uint8 (nx, nz, ny); bit k set when IK candidate k reaches the point exactly within
  the joint limits (candidate k: bits 2, 1, 0 = negative root of theta4, theta5, theta2);
- ``reachable``: bool (nx, nz, ny), ``masks != 0`` (the map's green points);
- ``widths_m``, ``segment_z_m``, ``segment_y_min_m``, ``segment_y_max_m``,
  ``segment_branch``: the widest one-branch segment per x (NaN / -1 where none);
- ``rect_y_min_m``, ``rect_y_max_m``, ``rect_z_min_m``, ``rect_z_max_m``, ``rect_branch``: the
  largest one-branch rectangle per x.

Plus ``arms`` (the arm names) and ``R_N_E`` (the tool orientation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hubo_cli.outputs import replacing
from hubo_cli.workspace.maps import PAPER_BEST, WorkspaceMap


def _per_x(wmap: WorkspaceMap) -> dict[str, np.ndarray]:
    g = wmap.grid
    n = wmap.run_length
    ok = n > 0
    start = np.clip(wmap.run_start, 0, None)
    end = np.clip(wmap.run_start + n - 1, 0, None)
    r = wmap.rect_cells
    has = r[:, 0] >= 0
    ri = np.clip(r, 0, None)
    nan = np.nan
    return {
        "widths_m": wmap.widths_m,
        "segment_z_m": np.where(ok, g.z_m[wmap.run_z_index], nan),
        "segment_y_min_m": np.where(ok, g.y_m[start], nan),
        "segment_y_max_m": np.where(ok, g.y_m[end], nan),
        "segment_branch": np.where(ok, wmap.run_branch, -1),
        "rect_y_min_m": np.where(has, g.y_m[ri[:, 3]], nan),
        "rect_y_max_m": np.where(has, g.y_m[ri[:, 4]], nan),
        "rect_z_min_m": np.where(has, g.z_m[ri[:, 1]], nan),
        "rect_z_max_m": np.where(has, g.z_m[ri[:, 2]], nan),
        "rect_branch": r[:, 0],
    }


def save_npz(maps: list[WorkspaceMap], path: str | Path) -> Path:
    """Write workspace.npz for one or more arms' maps (layout in the module docstring)."""
    arrays: dict[str, np.ndarray] = {"arms": np.array([m.arm for m in maps]),
                                     "R_N_E": maps[0].R_N_E}
    for m in maps:
        p = f"{m.arm}_"
        arrays.update({p + "x_m": m.grid.x_m, p + "y_m": m.grid.y_m, p + "z_m": m.grid.z_m,
                       p + "masks": m.masks, p + "reachable": m.reachable})
        arrays.update({p + k: v for k, v in _per_x(m).items()})
    path = Path(path)
    with replacing(path) as temporary:  # a full disk leaves no part of it
        np.savez_compressed(temporary, **arrays)
    return path


def paper_points(wmap: WorkspaceMap) -> list[dict]:
    """The paper's two segment ends (mirrored for the left arm): where they land and whether
    the map reaches them, on which branches. Empty unless the map is the paper's set-up."""
    if not wmap.paper_setup:
        return []
    Q, P, masks = wmap.paper_ends()
    return [{"position_mm": p * 1000, "q_rad": q, "reachable": bool(m),
             "branches": [k for k in range(8) if m & (1 << k)]}
            for p, q, m in zip(P, Q, masks, strict=True)]


def summary(maps: list[WorkspaceMap], seconds: float) -> dict:
    """summary.json: the first arm's figures at the top level, every arm under ``arms``."""
    first = maps[0].summary()
    out = {**first, "seconds": round(seconds, 3),
           "paper": PAPER_BEST if maps[0].paper_setup else None,
           "paper_points": paper_points(maps[0]), "arms": {}}
    for m in maps:
        out["arms"][m.arm] = {**m.summary(), "paper_points": paper_points(m)}
    if len(maps) > 1:
        out["arm"] = "both"
        out["points"] = sum(m.grid.points for m in maps)
    return out
