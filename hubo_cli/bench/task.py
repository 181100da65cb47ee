"""Scripted-task figures: the default cut-rectangle run's wall-clock time and real-time factor,
and the time pre-flight takes."""

from __future__ import annotations

import tempfile
import time

from hubo_cli.model import load_model
from hubo_cli.tasks.runner import check_task, run_task
from hubo_cli.tasks.spec import load_task


def run(report) -> None:
    model = load_model()
    spec = load_task("cut-rectangle")
    check_task(spec, model)  # warm the workspace cache and numba
    t0 = time.perf_counter()
    plan = check_task(spec, model)
    preflight_s = time.perf_counter() - t0
    report("cut-rectangle pre-flight (plan + IK of every period)", preflight_s * 1000, "ms",
           f"{len(plan.t_s):,} periods checked")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        done = run_task(plan, out=tmp)
        wall_s = time.perf_counter() - t0
    s = done.summary
    report("cut-rectangle (default, sim), wall-clock", wall_s, "s",
           f"{s['duration_s']:.1f} s simulated; rms {s['rms_error_mm']:.2f} mm, "
           f"completed {s['completed']}")
    report("cut-rectangle (default, sim), real-time factor", s["duration_s"] / wall_s,
           "sim s / wall s", "target: >= 1 (the run is faster than the robot)")
