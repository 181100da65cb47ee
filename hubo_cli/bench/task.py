"""Scripted-task figures: the default cut-rectangle run's real-time factor at the former 1 kHz
physics and at the default 400 Hz one in the same run (process CPU time as well as wall time),
and the time pre-flight takes."""

from __future__ import annotations

import tempfile
import time

from hubo_cli.drivers.sim import FAST_PHYSICS, LEGACY_PHYSICS
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
    cpu = {}
    for label, physics in (("1 kHz (before)", LEGACY_PHYSICS), ("400 Hz (default)", FAST_PHYSICS)):
        with tempfile.TemporaryDirectory() as tmp:
            wall0, cpu0 = time.perf_counter(), time.process_time()
            done = run_task(plan, out=tmp, driver_options=physics)
            wall_s, cpu[label] = time.perf_counter() - wall0, time.process_time() - cpu0
        s = done.summary
        report(f"cut-rectangle {label}: real-time factor, CPU time",
               s["duration_s"] / cpu[label], "sim s / CPU s",
               f"{s['duration_s']:.1f} s simulated; completed {s['completed']}; bit rms "
               f"{s['rms_error_mm']:.2f} mm, hole rms {s['hole_rms_error_mm']:.2f} mm")
        report(f"cut-rectangle {label}: real-time factor, wall", s["duration_s"] / wall_s,
               "sim s / wall s", f"{wall_s:.1f} s wall, run folder and plots included")
    old, new = cpu.values()
    report("cut-rectangle: speed-up of the default physics (CPU time)", old / new, "x",
           "target: >= 3x real time")
