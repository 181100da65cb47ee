"""Robustness figures: the shipped cutting tasks on perturbed robots (``hubo sweep``).

For the default cut-rectangle, the cut-slot and a 60 x 40 mm rectangle, over the seeds of
``HUBO_BENCH_SEEDS`` (default 1-20): how many runs completed, the worst support margin (the
capture point's smallest distance inside the support polygon), the hole's RMS error (median and
worst of the runs that cut), the largest torso tilt, and what stopped the others. Then the
wall-clock of the cut-slot sweep with 1 and with 2 worker processes (and whether their rows
agree). Slow (tens of minutes for 20 seeds): it runs only when named,
``make bench BENCH=robustness``; ``HUBO_BENCH_SEEDS=1-4`` runs fewer seeds,
``HUBO_BENCH_BALANCE=paper`` (or ``off``) another ``--balance``.
"""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from hubo_cli.sweep import Row, make_jobs, parse_seeds, run_sweep

TASKS = (("cut-rectangle (150 x 100 mm)", "cut-rectangle", {}),
         ("cut-slot (300 mm)", "cut-slot", {}),
         ("cut-rectangle 60 x 40 mm", "cut-rectangle", {"width_mm": [60.0], "height_mm": [40.0]}))
TIMED = 1  # the task whose sweep is timed with 1 and 2 workers


def _line(label: str, rows: list[Row]) -> str:
    done = sum(r.completed for r in rows)
    margins = [r.min_support_margin_mm for r in rows if r.min_support_margin_mm is not None]
    holes = [r.hole_rms_mm for r in rows if r.hole_rms_mm is not None]
    stops = Counter(r.estop or r.ended for r in rows if not r.completed)
    why = ", ".join(f"{k} x{n}" for k, n in stops.most_common()) or "-"
    tilts = [r.max_tilt_deg for r in rows if r.max_tilt_deg is not None]
    worst_margin = f"{min(margins):7.1f}" if margins else "      -"
    hole = (f"{np.median(holes):6.1f} / {max(holes):6.1f}" if holes else "     - /      -")
    tilt = f"{max(tilts):5.2f}" if tilts else "    -"
    return (f"  {label:<30} {done:>3}/{len(rows):<3} {worst_margin}    {hole}    {tilt}    "
            f"{why}")


def run(report) -> None:
    seeds = parse_seeds(os.environ.get("HUBO_BENCH_SEEDS", "1-20"))
    balance = os.environ.get("HUBO_BENCH_BALANCE", "default")
    lines = []
    with tempfile.TemporaryDirectory(prefix="hubo-robustness-") as tmp:
        timed: dict[int, object] = {}
        for k, (label, command, sets) in enumerate(TASKS):
            jobs = make_jobs(command, seeds, sets, balance)
            result = run_sweep(jobs, Path(tmp) / f"{k}-w2", workers=2)
            if k == TIMED:
                timed[2] = result
            rows = result.rows
            lines.append(_line(label, rows))
            margins = [r.min_support_margin_mm for r in rows
                       if r.min_support_margin_mm is not None]
            holes = [r.hole_rms_mm for r in rows if r.hole_rms_mm is not None]
            report(f"{label}: completed of {len(rows)} perturbed runs",
                   sum(r.completed for r in rows), "runs",
                   f"seeds {seeds[0]}-{seeds[-1]}")
            if margins:
                report(f"{label}: worst support margin", min(margins), "mm",
                       "< 30 mm: the capture-point stop fires")
            if holes:
                report(f"{label}: hole RMS, median / worst", float(np.median(holes)), "mm",
                       f"worst {max(holes):.1f} mm")
        label, command, sets = TASKS[TIMED]
        timed[1] = run_sweep(make_jobs(command, seeds, sets, balance), Path(tmp) / "timed-w1",
                             workers=1)
    same = ([r.outcome() for r in timed[1].rows] == [r.outcome() for r in timed[2].rows])
    report(f"sweep of {command} x {len(seeds)} seeds, 1 worker, wall-clock",
           timed[1].wall_clock_s, "s", "local Dask cluster")
    report(f"sweep of {command} x {len(seeds)} seeds, 2 workers, wall-clock",
           timed[2].wall_clock_s, "s",
           f"speed-up {timed[1].wall_clock_s / timed[2].wall_clock_s:.2f}x; rows identical: "
           f"{'yes' if same else 'NO'}")
    print(f"\n  {'task':<30} {'completed':>7} {'worst margin mm':>16} "
          f"{'hole RMS mm median / worst':>27} {'tilt deg':>8}  what stopped the others")
    for line in lines:
        print(line)
    print(flush=True)
