"""Teleoperation figures: end-to-end replay throughput and input-to-command latency, and the
distribution of the hands' errors over generated operator streams on the ideal driver."""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np

from hubo_cli.resources import data_file
from hubo_cli.teleop.session import TeleopSettings, run_teleop

# generated streams: (hand speed cap m/s, streams, seconds each); HUBO_BENCH_STREAMS=N changes
# the count (each stream costs about half its length in wall time on the ideal driver)
STREAM_SETS = ((0.25, 20, 20.0), (0.6, 8, 20.0))
FIRST_SEED = 3400


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
    for speed, count, seconds in STREAM_SETS:
        generated(report, speed, int(os.environ.get("HUBO_BENCH_STREAMS", count)), seconds)


FIGURES = (  # summary key, label, unit, low is bad
    ("reachable_share", "goal reachable, share of time", "", True),
    ("reachable_position_rms_mm", "position RMS over reachable time", "mm", False),
    ("reachable_orientation_rms_deg", "orientation RMS over reachable time", "deg", False),
    ("position_rms_mm", "position RMS, all the time", "mm", False),
    ("orientation_rms_deg", "orientation RMS, all the time", "deg", False),
    ("reachable_max_excursion_mm", "largest excursion over reachable time", "mm", False),
    ("max_excursion_mm", "largest excursion, all the time", "mm", False),
    ("collision_room_s", "target kept out of the collision band", "s", False),
    ("at_limit_s", "at the reach limit", "s", False),
)


def generated(report, max_speed_m_s: float, count: int, seconds: float) -> list:
    """Replay ``count`` generated streams on the ideal driver and report, per hand, the
    distribution (median, p90, worst over the streams) of each figure; returns the runs."""
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.teleop.stream_runs import distribution, meets_targets, replay_generated

    settings = StreamSettings(duration_s=seconds, max_speed_m_s=max_speed_m_s)
    runs = [replay_generated(FIRST_SEED + k, settings) for k in range(count)]
    title = (f"generated streams <= {max_speed_m_s:g} m/s: {count} x {seconds:g} s, seeds "
             f"{FIRST_SEED}-{FIRST_SEED + count - 1}, ideal driver")
    report(title, sum(r.wall_s for r in runs), "wall s",
           f"limits exceeded by {max(r.limit_excess_rad for r in runs):.2g} rad, all finite "
           f"{all(r.finite for r in runs)}, largest step {max(r.max_step_ratio for r in runs):.2f}"
           " x speed limit")
    medians = [r.target_us["median"] for r in runs if r.target_us["median"] is not None]
    report("  teleop target per operating period (both arms), median over the streams",
           float(np.median(medians)), "us",
           f"worst stream's median {max(medians):.0f} us, worst p99 "
           f"{max(r.target_us['p99'] for r in runs if r.target_us['p99'] is not None):.0f} us"
           " (target: median <= 300 us)")
    for arm in runs[0].hands:
        for key, label, unit, low_is_bad in FIGURES:
            d = distribution([r.hands[arm][key] for r in runs], low_is_bad)
            scale = 100.0 if unit == "" else 1.0
            report(f"  {arm}: {label}, median", d["median"] * scale, unit or "%",
                   f"p{10 if low_is_bad else 90} {d['p90'] * scale:.3g}, worst "
                   f"{d['worst'] * scale:.3g} (n {d['n']})")
        changes = sum(r.hands[arm]["branch_changes"] for r in runs)
        report(f"  {arm}: branch changes, all streams", changes, "")
        met = sum(meets_targets(r.hands[arm]) for r in runs)
        report(f"  {arm}: streams meeting issue 34's targets", met, f"of {len(runs)}",
               "position <= 10 mm, orientation <= 3 deg RMS over reachable time, "
               "excursion <= 15 mm")
    return runs
