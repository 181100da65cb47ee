"""Teleoperation figures: end-to-end replay throughput and input-to-command latency."""

from __future__ import annotations

import tempfile
import time

from hubo_cli.resources import data_file
from hubo_cli.teleop.session import TeleopSettings, run_teleop


def run(report) -> None:
    capture = data_file("trajectories", "drill-rectangle.fastrak")
    for driver in ("ideal", "sim"):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            result = run_teleop(TeleopSettings(replay=capture, mode="drill", driver=driver,
                                               out=tmp))
            wall_s = time.perf_counter() - t0
        s = result.summary
        report(f"teleop replay, drill rectangle, {driver} driver, --speed max",
               s["operate_s"] / wall_s, "input s / wall s",
               f"{s['duration_s']:.1f} s simulated in {wall_s:.1f} s; "
               f"rms {s['rms_error_mm']['right-arm']:.2f} mm")
        report(f"  input -> command latency ({driver}), median", s["latency_ms"]["median"], "ms",
               f"p99 {s['latency_ms']['p99']:.2f} ms (replay: on the loop clock)")
