"""The standing push matrix: ``hubo sim --push N`` over forces, directions and perturbation
seeds, one table.

    python tools/push_matrix.py --forces 90 --step-forces 150 --seeds 0-10 \
        --directions forward backward [--jobs 1] [--out /tmp/me/matrix] > table.txt &

Each cell is one standing run (:func:`hubo_cli.experiments.standing.stand`, the default
balancer, a 0.2 s push on the torso at 1 s; seed 0 is the nominal robot): ``--forces`` stand
without stepping (the hip strategy on), ``--step-forces`` with ``--step``. A row gives whether
the robot fell, the capture-point stop's time (if it fired), the torso's largest tilt, its largest
tilt from ``--settle`` seconds after the push to the end (the estimate's, deg) and the capture
steps taken. Runs go ``--jobs`` at a time, each in its own process (the simulator's state is
per process); rows print as they finish, the table at the end. Every run's folder is kept
under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

PUSH_AT_S = 1.0  # s, as hubo sim


def seeds_of(text: str) -> list[int]:
    """``"0-3,7"`` -> [0, 1, 2, 3, 7]."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += range(int(lo), int(hi or lo) + 1)
    return seeds


def one_run(force_n: float, step: bool, direction: str, seed: int, duration_s: float,
            settle_s: float, out: Path) -> dict:
    """One standing run; its row of the table."""
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS, stand
    from hubo_cli.model import load_model

    folder = out / f"{force_n:g}N-{'step-' if step else ''}{direction}-seed{seed}"
    result = stand(load_model(), duration_s, force_n, push_at_s=PUSH_AT_S,
                   push_direction=PUSH_DIRECTIONS[direction], step=step,
                   perturb_seed=seed or None, out=folder)
    summary = json.loads((folder / "summary.json").read_text())
    stops = [e["t_s"] for e in summary.get("estop_events", []) if e.get("kind") == "stop"]
    late = result.times_s >= PUSH_AT_S + settle_s
    return {"force_n": force_n, "step": step, "direction": direction, "seed": seed,
            "fell": result.fell, "stop_s": stops[0] if stops else None,
            "max_tilt_deg": result.max_tilt_deg,
            "settled_tilt_deg": (float(result.tilts_deg[late].max()) if late.any()
                                 else float("nan")),
            "steps": summary.get("capture_step", {}).get("steps", 0),
            "error": result.failure.message if result.failure is not None else ""}


def row_text(row: dict) -> str:
    stop = f"{row['stop_s']:.2f}" if row["stop_s"] is not None else "-"
    return (f"{row['force_n']:6g} {'step' if row['step'] else '    '} {row['direction']:9s}"
            f" {row['seed']:4d}  {'FELL' if row['fell'] else 'up  '} {stop:>6s}"
            f" {row['max_tilt_deg']:8.1f} {row['settled_tilt_deg']:8.2f} {row['steps']:5d}"
            f"  {row['error']}")


HEADER = ("     N      direction  seed  fell   stop  max tilt  settled steps\n"
          "                                   (s)     (deg)    (deg)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--forces", type=float, nargs="*", default=[90.0],
                        help="push forces (N) stood without stepping")
    parser.add_argument("--step-forces", type=float, nargs="*", default=[150.0],
                        help="push forces (N) caught with --step")
    parser.add_argument("--directions", nargs="+", default=["forward", "backward"],
                        choices=["forward", "backward", "left", "right"])
    parser.add_argument("--seeds", default="0-10", help="perturbation seeds, e.g. 0-10 or 0,3")
    parser.add_argument("--duration", type=float, default=5.0, help="simulated time (s)")
    parser.add_argument("--settle", type=float, default=3.0,
                        help="the settled tilt: the largest from this long after the push (s)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time")
    parser.add_argument("--out", type=Path, default=Path("/tmp/push-matrix"),
                        help="folder for the runs' folders")
    args = parser.parse_args(argv)
    cells = [(f, False) for f in args.forces] + [(f, True) for f in args.step_forces]
    jobs = [(f, step, d, s) for f, step in cells for d in args.directions
            for s in seeds_of(args.seeds)]
    rows = []
    print(HEADER, flush=True)
    with ProcessPoolExecutor(max_workers=args.jobs, max_tasks_per_child=1) as pool:
        futures = {pool.submit(one_run, *job, args.duration, args.settle, args.out): job
                   for job in jobs}
        for future in as_completed(futures):
            try:
                row = future.result()
            except Exception as error:  # one run's failure is its row, not the table's end
                f, step, d, s = futures[future]
                row = {"force_n": f, "step": step, "direction": d, "seed": s, "fell": True,
                       "stop_s": None, "max_tilt_deg": float("nan"),
                       "settled_tilt_deg": float("nan"), "steps": 0,
                       "error": f"{type(error).__name__}: {error}"}
            rows.append(row)
            print(row_text(row), flush=True)
    rows.sort(key=lambda r: (r["step"], r["force_n"], r["direction"], r["seed"]))
    print("\n" + HEADER)
    for row in rows:
        print(row_text(row))
    for (f, step) in cells:
        for d in args.directions:
            cell = [r for r in rows if r["force_n"] == f and r["step"] == step
                    and r["direction"] == d]
            up = sum(not r["fell"] for r in cell)
            print(f"{f:g} N {'with --step ' if step else ''}{d}: {up}/{len(cell)} up")
    return 0


if __name__ == "__main__":
    sys.exit(main())
