"""Teleoperation figures: end-to-end replay throughput and input-to-command latency, and the
distribution of the hands' errors over generated operator streams on the ideal driver, with the
teleop target's own time per operating period (issue 34: median <= 300 us).

``HUBO_BENCH_BASE=<git revision>`` also measures that revision's teleop target against this
tree's, interleaved (base, this, this, base, ...: one process per run, the same streams), and
reports per stream both medians and the median of the paired ratios (each stream of each round
against itself); it needs a git checkout."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

from hubo_cli.resources import data_file
from hubo_cli.teleop.hand_report import RETURN_WINDOW_S
from hubo_cli.teleop.session import TeleopSettings, run_teleop

# generated streams: (hand speed cap m/s, streams, seconds each); HUBO_BENCH_STREAMS=N changes
# the count (each stream costs about half its length in wall time on the ideal driver)
STREAM_SETS = ((0.25, 20, 20.0), (0.6, 8, 20.0))
FIRST_SEED = 3400
BASE_ENV = "HUBO_BENCH_BASE"
# the streams given in full (a base revision's StreamSettings may default otherwise: the
# turn rate was 90 deg/s before the cap, so both trees are given the same)
COMPARE = {"seeds": [3400, 3401, 3402], "max_speed_m_s": 0.25, "max_turn_rate_deg_s": 40.0,
           "seconds": 8.0, "rounds": 3}


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
    if os.environ.get(BASE_ENV):
        compare_with(report, os.environ[BASE_ENV])


FIGURES = (  # summary key, label, unit, low is bad
    ("reachable_share", "goal reachable, share of time", "", True),
    ("reachable_position_rms_mm", "position RMS over reachable time", "mm", False),
    ("reachable_orientation_rms_deg", "orientation RMS over reachable time", "deg", False),
    ("position_rms_mm", "position RMS, all the time", "mm", False),
    ("orientation_rms_deg", "orientation RMS, all the time", "deg", False),
    ("steady_share", f"steady share of reachable time (> {RETURN_WINDOW_S:g} s after a return)",
     "", True),
    ("steady_position_rms_mm", "position RMS, steady", "mm", False),
    ("steady_orientation_rms_deg", "orientation RMS, steady", "deg", False),
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
    load_before = os.getloadavg()[0]
    runs = [replay_generated(FIRST_SEED + k, settings) for k in range(count)]
    load = f"load average {load_before:.1f}-{os.getloadavg()[0]:.1f}"
    title = (f"generated streams <= {max_speed_m_s:g} m/s: {count} x {seconds:g} s, seeds "
             f"{FIRST_SEED}-{FIRST_SEED + count - 1}, ideal driver")
    report(title, sum(r.wall_s for r in runs), "wall s",
           f"limits exceeded by {max(r.limit_excess_rad for r in runs):.2g} rad, all finite "
           f"{all(r.finite for r in runs)}, largest step {max(r.max_step_ratio for r in runs):.2f}"
           " x speed limit")
    timed = [r.target_us for r in runs if r.target_us["median"] is not None]
    medians = [t["median"] for t in timed]
    report("  teleop target per period (both arms, search, room, swing), median",
           float(np.median(medians)), "us",
           f"wall clock, of the streams' medians; thread CPU "
           f"{np.median([t['cpu_median'] for t in timed]):.0f} us; worst stream's "
           f"median {max(medians):.0f} us, worst p99 {max(t['p99'] for t in timed):.0f} us; "
           f"{load} (target: median <= 300 us)")
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


_MEASURE = """
import json, sys, time
import numpy as np
from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.teleop import target
from hubo_cli.teleop.stream_runs import replay_generated
wall, cpu, call = [], [], target.TeleopTarget.__call__
def timed(self, t_s, state):
    c0, t0 = time.thread_time(), time.perf_counter()  # the CPU clock's read outside the wall time
    out = call(self, t_s, state)
    if self.phase == "operate":
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    return out
target.TeleopTarget.__call__ = timed
c = json.loads(sys.argv[1])
replay_generated(c["seeds"][0], StreamSettings(duration_s=1.0))  # warm: caches, files
medians = []
for seed in c["seeds"]:
    wall.clear()
    cpu.clear()
    settings = StreamSettings(duration_s=c["seconds"], max_speed_m_s=c["max_speed_m_s"],
                              max_turn_rate_deg_s=c["max_turn_rate_deg_s"])
    replay_generated(seed, settings)
    medians.append((float(np.median(wall)) * 1e6, float(np.median(cpu)) * 1e6))
print(json.dumps(medians))
"""


def _tree_at(revision: str) -> Path | str:
    """The package at a git revision, unpacked once per commit into the temporary folder (its
    numba cache stays with it) with this checkout's data folders; or why it could not be."""
    from hubo_cli.resources import data_dir

    root = Path(__file__).resolve().parents[2]
    sha = subprocess.run(["git", "-C", str(root), "rev-parse", "--verify",
                          f"{revision}^{{commit}}"], capture_output=True, text=True, check=False)
    if sha.returncode:
        return f"{revision!r} is not a commit of {root} ({sha.stderr.strip() or 'no git'})"
    tree = Path(tempfile.gettempdir()) / f"hubo-bench-{sha.stdout.strip()[:12]}"
    if not (tree / "hubo_cli").is_dir():
        archive = subprocess.run(["git", "-C", str(root), "archive", sha.stdout.strip(),
                                  "hubo_cli"], capture_output=True, check=False)
        if archive.returncode:
            return f"git archive {revision} failed: {archive.stderr.decode().strip()}"
        tree.mkdir(exist_ok=True)
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(tree, filter="data")
        for folder in ("robots", "tasks", "trajectories"):
            if not (tree / folder).exists():
                (tree / folder).symlink_to(data_dir(folder))
    return tree


def compare_with(report, revision: str) -> None:
    """The teleop target's median time per operating period at ``revision`` and in this tree,
    interleaved (:data:`COMPARE`'s streams, one process per run, the order alternating)."""
    base = _tree_at(revision)
    if isinstance(base, str):
        report(f"teleop target against {revision}: not measured", float("nan"), "", base)
        return
    this = Path(__file__).resolve().parents[2]
    results: dict[str, list] = {"base": [], "this": []}
    load_before = os.getloadavg()[0]
    for k in range(COMPARE["rounds"]):
        for name in (("base", "this") if k % 2 == 0 else ("this", "base")):
            tree = base if name == "base" else this
            run = subprocess.run([sys.executable, "-c", _MEASURE, json.dumps(COMPARE)],
                                 capture_output=True, text=True, check=False,
                                 env={**os.environ, "PYTHONPATH": str(tree)})
            if run.returncode:
                report(f"teleop target against {revision}: failed", float("nan"), "",
                       run.stderr.strip().splitlines()[-1] if run.stderr.strip() else "")
                return
            results[name] += json.loads(run.stdout.strip().splitlines()[-1])
    load = f"load average {load_before:.1f}-{os.getloadavg()[0]:.1f}"
    streams = (f"seeds {COMPARE['seeds'][0]}-{COMPARE['seeds'][-1]}, "
               f"{COMPARE['max_speed_m_s']:g} m/s, {COMPARE['seconds']:g} s, "
               f"{COMPARE['rounds']} rounds interleaved")
    for column, label in ((0, "wall clock"), (1, "thread CPU")):
        # each stream of each round against itself: the streams' own costs differ by 3x
        before, after = (np.array([m[column] for m in results[name]]) for name in ("base", "this"))
        n = len(COMPARE["seeds"])  # results: round after round, each the seeds in order
        per_seed = ", ".join(
            f"{seed}: {np.median(before[k::n]):.0f} -> {np.median(after[k::n]):.0f} us"
            for k, seed in enumerate(COMPARE["seeds"]))
        report(f"  teleop target per operating period, {label}: this tree / {revision}",
               float(np.median(after / before)), "", f"median of the paired ratios; per stream "
               f"{per_seed} ({streams}; {load})")
