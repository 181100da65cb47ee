"""Where a walk through the simulated daemon arrived, as the simulator has it.

A run with ``--driver hardware`` knows only what the robot measures, so its final error is the
estimate's. ``hubo hardware sim-daemon --truth-log FILE.csv`` writes the simulator's truth (the
torso's position and tilt, the soles' places) with the time of every state it published; the
run's log has the time of the state each period used (``hw_state_time_s``). This takes the
stance (midway between the true soles, averaged over the last FINAL_ROWS states) at the run's
first and last period, and prints the final error from the goal seen from the start, the
torso's largest true tilt and drop during the run, and whether that is a fall
(:func:`hubo_cli.falls.has_fallen`).

    python tools/daemon_walk.py RUN_DIR TRUTH_LOG.csv --to 1 0 0

or runs the whole measurement (a daemon on its own channels in the walking posture, the walk
on the hardware driver, the daemon stopped, the figures; both at SCHED_FIFO priority with
``--fifo``, as hubo-daemon runs on the robot; needs libach, ``HUBO_LIBACH``):

    python tools/daemon_walk.py --run OUT_DIR --to 1 0 0 [--fifo]
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hubo_cli.control.log import load_log
from hubo_cli.experiments.walk import FINAL_ROWS, arrival_error
from hubo_cli.falls import has_fallen
from hubo_cli.walking.footsteps import Footstep, Stance, stance_of

COLUMNS = {"torso_z_m": 3, "torso_tilt_deg": 4, "right": slice(5, 8), "left": slice(8, 11)}


def truth_stance(rows: np.ndarray) -> Stance:
    """The stance of the true soles in truth-log rows, averaged."""
    mean = rows.mean(axis=0)
    return stance_of(Footstep("right", *mean[COLUMNS["right"]]),
                     Footstep("left", *mean[COLUMNS["left"]]))


def walk_truth(log, truth: np.ndarray, goal: tuple[float, float, float]) -> dict:
    """The walk's true final error (mm, deg), largest tilt (deg), torso drop (m) and fall, from
    the truth log's rows (time first) over the run's state times."""
    state_t = np.asarray(log["hw_state_time_s"], dtype=float)
    state_t = state_t[np.isfinite(state_t)]
    first, last = np.searchsorted(truth[:, 0], [state_t[0], state_t[-1]], side="right")
    if first < FINAL_ROWS or last < first + FINAL_ROWS:
        raise SystemExit("the truth log does not cover the run (was it the run's daemon?)")
    start = truth_stance(truth[first - FINAL_ROWS:first])
    end = truth_stance(truth[last - FINAL_ROWS:last])
    error_m, error_rad = arrival_error(start, end, goal)
    during = truth[first - 1:last]
    tilt_deg = float(during[:, COLUMNS["torso_tilt_deg"]].max())
    drop_m = float(during[0, COLUMNS["torso_z_m"]] - during[:, COLUMNS["torso_z_m"]].min())
    return {"final_error_mm": 1000 * error_m, "final_error_deg": math.degrees(error_rad),
            "max_tilt_deg": tilt_deg, "torso_drop_m": drop_m,
            "fell": bool(has_fallen(tilt_deg, drop_m))}


def measure(out_dir: Path, goal: tuple[float, float, float], fifo: bool) -> tuple[Path, Path]:
    """Run a daemon and the walk into ``out_dir`` (its ``walk`` run folder, ``truth.csv``)."""
    from hubo_cli.drivers.ach import load_libach
    from hubo_cli.drivers.hubo_ach_daemon import channel_published

    out_dir.mkdir(parents=True, exist_ok=True)
    tag = f"daemon-walk-{os.getpid()}"
    ref, state, truth = f"{tag}-ref", f"{tag}-state", out_dir / "truth.csv"
    hubo = [sys.executable, "-m", "hubo_cli.cli.main"]
    daemon = subprocess.Popen([*(["chrt", "-f", "40"] if fifo else []), *hubo, "hardware",
                               "sim-daemon", "--posture", "walking", "--ach-ref", ref,
                               "--ach-state", state, "--truth-log", str(truth), "--json"],
                              stdout=(out_dir / "daemon.json").open("w"))
    try:
        lib, end = load_libach(), time.monotonic() + 120
        while not channel_published(lib, state):
            if daemon.poll() is not None or time.monotonic() > end:
                raise SystemExit("the daemon did not start")
        subprocess.run([*(["chrt", "-f", "30"] if fifo else []), *hubo, "walk", "--to",
                        *map(str, goal), "--driver", "hardware", "--arm", "--ach-ref", ref,
                        "--ach-state", state, "--out", str(out_dir / "walk")], check=False)
    finally:
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(timeout=60)
    return out_dir / "walk", truth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", nargs="?")
    parser.add_argument("truth_log", nargs="?")
    parser.add_argument("--to", type=float, nargs=3, required=True, metavar=("X", "Y", "YAW"))
    parser.add_argument("--run", metavar="OUT_DIR", help="run the daemon and the walk first")
    parser.add_argument("--fifo", action="store_true",
                        help="with --run: both at SCHED_FIFO priority (chrt -f)")
    args = parser.parse_args()
    goal = tuple(args.to)
    if args.run:
        run_dir, truth_log = measure(Path(args.run), goal, args.fifo)
    elif args.run_dir and args.truth_log:
        run_dir, truth_log = args.run_dir, args.truth_log
    else:
        parser.error("give RUN_DIR and TRUTH_LOG, or --run OUT_DIR")
    truth = np.loadtxt(truth_log, delimiter=",", skiprows=1, ndmin=2)
    found = walk_truth(load_log(run_dir), truth, goal)
    print(f"final error {found['final_error_mm']:.1f} mm, {found['final_error_deg']:.2f} deg "
          f"(the simulator's truth); max tilt {found['max_tilt_deg']:.2f} deg, torso drop "
          f"{1000 * found['torso_drop_m']:.1f} mm; fell: {'YES' if found['fell'] else 'no'}")


if __name__ == "__main__":
    main()
