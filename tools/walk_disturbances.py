"""Disturb simulated walks at random moments and count the falls (issue 37's measurements).

    python tools/walk_disturbances.py stop --seeds 1-20 [--source operator|capture-point]
    python tools/walk_disturbances.py push --seeds 1-20 --force 100 --directions left,right,backward
    python tools/walk_disturbances.py push --seeds 1-20 --distance 2.0 --table

Each seed draws a moment uniformly over the walk's steps (from the first step's lift-off to the
last one's landing) and, for pushes, a direction from ``--directions``; the walk
(``hubo walk --to DISTANCE 0 0 [--gait GAIT] [--lip-feedback]`` through the full pipeline)
then runs with the operator's stop (``stop``), with a 0.2 s push on the torso (``push``), or,
``stop --source capture-point``, with a push of ``--force`` (default 100 N) left to the
capture-point monitor to stop it: the same runs as ``push`` with the same seeds and directions.
One JSON line per run (seed, moment, the walk's phase at it, direction, fell, stopped, stood,
both feet down over the run's last 0.5 s, the soft stopper holding at the end, footstep changes,
e-stop events, max tilt, the torso's true tilt in the run's last period and its largest over
the last 0.5 s, the outcome), then a summary line; ``--table`` then prints the runs as a
Markdown table (seed, moment, outcome, largest tilt).
Run folders go under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from hubo_cli.balance_report import tilt_deg_of_roll_pitch
from hubo_cli.control.estop import MODE_CODE
from hubo_cli.control.log import load_log
from hubo_cli.experiments.standing import PUSH_DIRECTIONS
from hubo_cli.experiments.walk import Disturbance, walk
from hubo_cli.model import load_model
from hubo_cli.walking.footsteps import Stance, step_count
from hubo_cli.walking.params import DEFAULT_GAIT, walking_params

# a run's outcome (:func:`outcome_of`)
STANDING = "standing in double support"
FELL = "fell"
WALKED_ON = "walked on"
STOPPED_OTHER = "stopped other"


def seeds_of(text: str) -> list[int]:
    """``1-20`` or ``1,4,7``."""
    if "-" in text:
        first, last = (int(v) for v in text.split("-"))
        return list(range(first, last + 1))
    return [int(v) for v in text.split(",")]


def draw(model, seed: int, distance_m: float, directions: list[str],
         gait: str = DEFAULT_GAIT) -> tuple[float, str]:
    """Seed ``seed``'s moment (loop time, s), uniform over the steps of a walk of
    ``distance_m`` in ``gait`` (as plan_footsteps counts them: from the first lift-off, after
    start_s and one double support, to the last landing), and its push direction from
    ``directions``."""
    params = walking_params(model.with_limits("walking"), gait)
    n_steps = step_count(Stance(0.0, 0.0, 0.0), Stance(distance_m, 0.0, 0.0), params)
    first_s = params.start_s + params.double_support_s
    last_s = first_s + n_steps * params.step_s - params.double_support_s
    rng = np.random.default_rng(seed)
    at_s = float(rng.uniform(first_s, last_s))
    return at_s, directions[int(rng.integers(len(directions)))]


def outcome_of(row: dict) -> str:
    """A run's outcome: fell; stopped and standing in double support (stood, both feet down
    over its last 0.5 s; the soft stopper holds unless the walk stopped itself, as after a
    landing that bounced: ``held`` is the row's own field); walked on (never stopped); or
    stopped otherwise (a sole still lifting at the end, or a stop that did not stand)."""
    if row["fell"]:
        return FELL
    if row["stopped_s"] is None:
        return WALKED_ON
    if row["stood"] and row["both_feet_down"]:
        return STANDING
    return STOPPED_OTHER


def table(rows: list[dict]) -> str:
    """The runs as a Markdown table: seed, moment, the walk's phase then, the push's
    direction, outcome, stop time, largest tilt and the largest over the last 0.5 s (deg)."""
    lines = ["| seed | moment (s) | walk at the moment | push | outcome | stopped at (s) "
             "| largest tilt (deg) | over the last 0.5 s (deg) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        stopped = "-" if r["stopped_s"] is None else f"{r['stopped_s']:.3f}"
        lines.append(f"| {r['seed']} | {r['at_s']:.3f} | {r['phase']} | {r['direction'] or '-'} "
                     f"| {r['outcome']} | {stopped} | {r['max_torso_tilt_deg']:.1f} "
                     f"| {r['end_max_tilt_deg']:.2f} |")
    return "\n".join(lines)


def phase_at(log, at_s: float) -> str:
    """The walk's pattern at ``at_s``: its step and whether the plan had one sole or both down."""
    t_s = np.asarray(log["t_s"], dtype=float)
    steps = np.asarray(log["walk.step"], dtype=float)
    ran = np.flatnonzero(np.isfinite(steps))  # the loop's closing rows have no pipeline
    if not len(ran) or at_s > t_s[ran[-1]]:
        return "after the walk's last period"
    k = ran[min(int(np.searchsorted(t_s[ran], at_s)), len(ran) - 1)]
    step = int(steps[k])
    both = all(np.asarray(log[f"planned_{side}_foot_contact_flag"], dtype=float)[k] == 1
               for side in ("right", "left"))
    return f"step {step} {'double support' if both else 'swing'}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=("stop", "push"))
    parser.add_argument("--seeds", default="1-20")
    parser.add_argument("--distance", type=float, default=1.0, help="walk forward (m)")
    parser.add_argument("--force", type=float, default=100.0, help="push (N), 0.2 s")
    parser.add_argument("--directions", default="left,right,backward",
                        help="push directions drawn from (forward, backward, left, right)")
    parser.add_argument("--source", choices=("operator", "capture-point"), default="operator")
    parser.add_argument("--gait", default=DEFAULT_GAIT, help="the robot file's gait")
    parser.add_argument("--lip-feedback", action="store_true",
                        help="the Stabilizer's LIP feedback and force distribution "
                             "(hubo walk --lip-feedback)")
    parser.add_argument("--table", action="store_true",
                        help="print the runs as a Markdown table at the end")
    parser.add_argument("--out", default="/tmp/walk_disturbances")
    args = parser.parse_args()
    model = load_model()
    directions = args.directions.split(",")
    results = []
    for seed in seeds_of(args.seeds):
        at_s, direction = draw(model, seed, args.distance, directions, args.gait)
        if args.kind == "stop" and args.source == "operator":
            events = [Disturbance(at_s, stop=True)]
        else:
            events = [Disturbance(at_s, args.force, PUSH_DIRECTIONS[direction])]
        result = walk(model, (args.distance, 0.0, 0.0), out=Path(args.out) / f"{args.kind}-{seed}",
                      disturbances=events, gait=args.gait, lip_feedback=args.lip_feedback)
        summary = json.loads((result.run_dir / "summary.json").read_text())
        log = load_log(result.run_dir / "log.parquet")
        mode = np.asarray(log["estop_mode_code"], dtype=float)
        rows = np.isfinite(mode)  # the loop's closing rows have no pipeline
        down = np.column_stack([np.asarray(log[f"{side}_foot_contact_flag"], dtype=float)[rows]
                                for side in ("right", "left")])[-100:]
        roll, pitch = (np.asarray(log[f"torso_{axis}_rad"], dtype=float)[rows][-100:]
                       for axis in ("roll", "pitch"))
        end_tilt_deg = tilt_deg_of_roll_pitch(roll, pitch)
        row = {"seed": seed, "at_s": round(at_s, 3), "phase": phase_at(log, at_s),
               "direction": None if args.kind == "stop" and args.source == "operator"
               else direction, "fell": result.fell, "stopped_s": result.stopped_s,
               "stood": result.stood, "both_feet_down": bool(np.all(down == 1)),
               "held": bool(mode[rows][-1] == MODE_CODE["hold"]), "shifts": result.shifts,
               "touchdowns_early": result.touchdowns_early,
               "liftoff_waits": result.liftoff_waits, "landing_waits": result.landing_waits,
               "estop_events": len(summary.get("estop_events", [])),
               "max_torso_tilt_deg": summary.get("max_torso_tilt_deg"),
               "final_tilt_deg": round(float(end_tilt_deg[-1]), 2),
               "end_max_tilt_deg": round(float(end_tilt_deg.max()), 2),
               "final_error_mm": result.final_error_mm}
        row["outcome"] = outcome_of(row)
        results.append(row)
        print(json.dumps(row), flush=True)
    falls = sum(r["fell"] for r in results)
    print(json.dumps({"kind": args.kind, "source": args.source, "force_n": args.force,
                      "distance_m": args.distance, "gait": args.gait,
                      "lip_feedback": args.lip_feedback,
                      "runs": len(results), "falls": falls,
                      "stood": sum(bool(r["stood"]) for r in results),
                      "standing_in_double_support": sum(r["outcome"] == STANDING
                                                        for r in results)}), flush=True)
    if args.table:
        print(table(results), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
