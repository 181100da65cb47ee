"""Where the stance soles turn on the floor (the truth), from a walk's period log.

    python tools/sole_turns.py RUN_DIR [RUN_DIR ...]

For each run folder (a simulated `hubo walk`): each sole's true heading (the logged true torso
pose and the measured leg joints' forward kinematics), while it carries more than LOADED_N,
its change summed over each segment of a walking phase, and per phase the segments' count and
their |change| (deg): while the other foot swings (first and second half of its planned
single support) and in double support (this sole landed last / lifts next). Only while walking
(the first planned lift-off to the last planned landing, before a stop). One JSON line per run.
Measurements only (docs/history/walking.md, round 8); no module reads the truth.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
from scipy.spatial.transform import Rotation

from hubo_cli.control.log import load_log
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model

LOADED_N = 95.0  # a quarter of the body's weight: the sole stands on the floor
LEG_JOINTS = ("HY", "HR", "HP", "KN", "AP", "AR")
SIDES = ("right", "left")


def _edges(planned: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The periods a planned contact ends (lift-offs) and starts (landings)."""
    return (np.flatnonzero(~planned[1:] & planned[:-1]) + 1,
            np.flatnonzero(planned[1:] & ~planned[:-1]) + 1)


def _phase(k: int, side: int, t_s: np.ndarray, planned: list[np.ndarray],
           edges: list[tuple[np.ndarray, np.ndarray]]) -> str:
    other = 1 - side
    lifts, lands = edges[other]
    if not planned[other][k]:
        lifted, landing = lifts[lifts <= k], lands[lands > k]
        if not len(lifted) or not len(landing):
            return "other swings"
        half = (t_s[landing[0]] - t_s[lifted[-1]]) / 2
        return ("other swings, 1st half" if t_s[k] - t_s[lifted[-1]] < half
                else "other swings, 2nd half")
    mine, theirs = edges[side][0], lifts
    mine, theirs = mine[mine > k], theirs[theirs > k]
    next_mine = mine[0] if len(mine) else math.inf
    next_theirs = theirs[0] if len(theirs) else math.inf
    return ("double support, this sole lifts next" if next_mine < next_theirs
            else "double support, this sole landed last")


def analyse(run_dir: str, model) -> dict:
    log = load_log(run_dir)
    t_s = np.asarray(log["t_s"], dtype=float)
    R_world_torso = Rotation.from_euler("xyz", np.column_stack(
        [log["torso_roll_rad"], log["torso_pitch_rad"], log["torso_yaw_rad"]])).as_matrix()
    planned = [np.asarray(log[f"planned_{s}_foot_contact_flag"]).astype(bool) for s in SIDES]
    edges = [_edges(p) for p in planned]
    lift_offs = [e[0] for e in edges if len(e[0])]
    landings = [e[1] for e in edges if len(e[1])]
    if not lift_offs or not landings:
        return {"run": run_dir, "error": "no step in the log"}
    first = min(int(e[0]) for e in lift_offs)
    last = min(max(int(e[-1]) for e in landings) + int(round(0.2 / np.median(np.diff(t_s)))),
               len(t_s) - 1)
    stopping = np.flatnonzero(np.asarray(log["walk.phase_code"], dtype=float) > 0)
    if len(stopping):  # the walk's own stop (walk.phase_code: stopping, stood)
        last = min(last, int(stopping[0]))
    turns: dict[str, list[float]] = {}
    for side, name in enumerate(SIDES):
        prefix = name[0].upper()
        q_rad = np.column_stack([log[f"q_{prefix}{j}_rad"] for j in LEG_JOINTS])
        T_torso_sole = Limb(model, f"{name}-leg").fk_batch(q_rad)
        R = R_world_torso @ T_torso_sole[:, :3, :3]
        heading = np.unwrap(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
        loaded = np.asarray(log[f"{name}_foot_fz_n"], dtype=float) > LOADED_N
        segment, turned = None, 0.0
        for k in range(first, last + 1):
            phase = _phase(k, side, t_s, planned, edges) if loaded[k] else None
            if phase != segment:
                if segment is not None:
                    turns.setdefault(segment, []).append(abs(turned))
                segment, turned = phase, 0.0
            if phase is not None:
                turned += heading[k] - heading[k - 1]
        if segment is not None:
            turns.setdefault(segment, []).append(abs(turned))
    return {"run": run_dir, "phases": {
        phase: {"segments": len(v), "turned_deg": round(math.degrees(sum(v)), 3)}
        for phase, v in sorted(turns.items())},
        "turned_deg": round(math.degrees(sum(sum(v) for v in turns.values())), 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+")
    args = parser.parse_args()
    model = load_model()
    for run_dir in args.runs:
        print(json.dumps(analyse(run_dir, model)))


if __name__ == "__main__":
    main()
