"""The hole a drilling task cut through the simulated daemon, as the simulator has it.

A run with ``--driver hardware`` knows only what the robot measures, so its summary has the
bit's error by forward kinematics (``rms_error_mm``) and no hole. ``hubo hardware sim-daemon
--drill --tool-log FILE.csv`` writes the drill bit's true world position with the time of every
state it published; the run's log has, per period, the time of the state it used
(``hw_state_time_s``), the commanded bit (``goal_*_m``), the phase and whether it cut. This
takes the bit's true position at each cutting period, relative to where it stood when the run
phase began (as the sim driver places the hole, ``hole_rms_error_mm``), and prints the RMS
distance in the wall plane (y, z) to the commanded bit, in mm.

    python tools/daemon_hole.py RUN_DIR TOOL_LOG.csv
"""

from __future__ import annotations

import argparse

import numpy as np

from hubo_cli.control.log import load_log
from hubo_cli.tasks.phases import PHASES


def hole_rms_mm(log, track: np.ndarray) -> tuple[float, int, float]:
    """The hole's RMS error in the wall plane (mm), the cutting periods and the largest gap
    between a period's state time and the nearest tracked one (s)."""
    state_t = np.asarray(log["hw_state_time_s"], dtype=float)
    goal = np.column_stack([log["goal_x_m"], log["goal_y_m"], log["goal_z_m"]])
    k = np.clip(np.searchsorted(track[:, 0], state_t), 1, len(track) - 1)
    k -= (state_t - track[k - 1, 0]) < (track[k, 0] - state_t)  # the nearest row
    gap_s = np.abs(track[k, 0] - state_t)
    bit = track[k, 1:]
    run = np.flatnonzero(np.asarray(log["phase_code"]) == PHASES.index("run"))
    if not run.size:
        raise SystemExit("the run never reached its run phase")
    offset = bit[run[0]] - goal[run[0]]
    cutting = np.asarray(log["cutting"]) > 0.5
    d = (bit[cutting] - offset - goal[cutting])[:, 1:]
    return (float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))) * 1000), int(cutting.sum()),
            float(gap_s[cutting].max()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir")
    parser.add_argument("tool_log")
    args = parser.parse_args()
    track = np.loadtxt(args.tool_log, delimiter=",", skiprows=1, ndmin=2)
    rms, n, gap = hole_rms_mm(load_log(args.run_dir), track)
    print(f"hole {rms:.2f} mm RMS in the wall plane over {n} cutting periods "
          f"(state times matched within {1e3 * gap:.3f} ms)")


if __name__ == "__main__":
    main()
