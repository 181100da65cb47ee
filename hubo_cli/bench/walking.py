"""Walking control's cost per 5 ms period: the simulated robot walks 0.3 m forward through the
full pipeline (``hubo walk``), and the loop's own per-period compute time (the walking target
with its stabilizer, then every pipeline module; physics excluded) is read from the run's log;
then again walking on toe and heel with the LIP feedback and the force-distribution QP
(``hubo walk --toe-heel --lip-feedback``). Target: median <= 10 % of the control period.
Last, the walk stopped in mid-swing (``--stop-at 2.2``): the worst period from the stop on,
while its re-plan is computed a part a period (:mod:`hubo_cli.walking.replan`); target: within
the period."""

from __future__ import annotations

import tempfile

import numpy as np

GOAL = (0.3, 0.0, 0.0)


def run(report) -> None:
    from hubo_cli.control.log import load_log
    from hubo_cli.experiments.walk import Disturbance, walk
    from hubo_cli.model import load_model

    model = load_model()
    period_us = model.control_period_s * 1e6
    for label, options in (("", {}),
                           (" toe-heel, LIP feedback and QP",
                            {"toe_heel": True, "lip_feedback": True})):
        with tempfile.TemporaryDirectory() as tmp:
            result = walk(model, GOAL, out=tmp, corrections=0, **options)
            compute = np.asarray(load_log(result.run_dir)["compute_us"], dtype=float)
        compute = compute[np.isfinite(compute)]
        median = float(np.median(compute))
        report(f"walking control per period (target + stabilizer + pipeline){label}, median",
               median, "us", f"{100 * median / period_us:.1f} % of the period; target <= 10 %")
        report("  99th percentile", float(np.percentile(compute, 99)), "us",
               f"{compute.size} periods, {result.steps} steps, fell: {result.fell}")
    with tempfile.TemporaryDirectory() as tmp:
        result = walk(model, GOAL, out=tmp, corrections=0,
                      disturbances=[Disturbance(2.2, stop=True)])
        log = load_log(result.run_dir)
        compute = np.asarray(log["compute_us"], dtype=float)
        stopping = np.asarray(log["walk.phase_code"], dtype=float) >= 1
    worst = float(np.nanmax(compute[stopping]))
    report("worst period from a stop in mid-swing on (its re-plan a part a period)", worst,
           "us", f"{100 * worst / period_us:.0f} % of the period; median before the stop "
           f"{float(np.nanmedian(compute[~stopping])):.0f} us; stood: {result.stood}")
