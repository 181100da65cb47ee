"""The walk on perturbed robots: ``hubo walk --to 1.0 0 0`` on each seed of
``HUBO_BENCH_SEEDS`` (default 1-20), the walk acting on the estimate, its final error measured
against the simulator's truth (:func:`~hubo_cli.experiments.walk.true_final_error`) beside the
estimate's own. Target: every seed within ``TARGET_MM`` of the goal, none fallen.

Slow (about half a minute a seed on two cores): it runs only when named,
``make bench BENCH=walk_sweep``; ``HUBO_BENCH_SEEDS=1-4`` runs fewer seeds. Each seed's line
is printed as it ends.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

GOAL = (1.0, 0.0, 0.0)
TARGET_MM = 10.0


def run(report) -> None:
    from hubo_cli.experiments.walk import walk
    from hubo_cli.model import load_model
    from hubo_cli.sweep import parse_seeds

    seeds = parse_seeds(os.environ.get("HUBO_BENCH_SEEDS", "1-20"))
    model = load_model()
    errors, estimated, fell = [], [], 0
    print(f"  {'seed':>4} {'fell':>5} {'error mm':>9} {'deg':>6} {'estimated mm':>13} "
          f"{'steps':>5}", flush=True)
    with tempfile.TemporaryDirectory(prefix="hubo-walk-sweep-") as tmp:
        for seed in seeds:
            result = walk(model, GOAL, out=Path(tmp) / f"seed{seed}", perturb_seed=seed or None)
            errors.append(result.final_error_mm)
            estimated.append(result.estimated_final_error_mm)
            fell += result.fell
            print(f"  {seed:>4} {'yes' if result.fell else 'no':>5} "
                  f"{result.final_error_mm:9.2f} {result.final_error_deg:6.2f} "
                  f"{result.estimated_final_error_mm:13.2f} {result.steps:>5}", flush=True)
    errors = np.array(errors)
    within = int(np.sum(errors <= TARGET_MM))
    report(f"walk 1 m on the estimate: within {TARGET_MM:g} mm of the goal (truth)", within,
           "runs", f"of {len(seeds)}, seeds {seeds[0]}-{seeds[-1]}; fell: {fell}")
    report("  final error against the truth, median", float(np.median(errors)), "mm",
           f"worst {np.nanmax(errors):.2f} mm")
    report("  the estimate's own final error, median", float(np.median(estimated)), "mm",
           f"worst {np.nanmax(estimated):.2f} mm")
