"""How long a limb's measured joints lag the references sent: the best-fit delay of a run.

For a run folder's log, the delay d (0 to ``--max-ms``, in ``--step-ms`` steps, the commands
interpolated linearly between periods) that minimises the RMS over the limb's joints of the
measured position against the command sent d earlier, with that RMS and the largest gap
(rad) at d. Through the hardware driver this is the reference mode's lag (hubo-daemon's filter
in mode 0) plus the bus and the motors.

Two clocks, when the log has the hardware driver's ``hw_state_time_s``: the run's periods
(``t_s``, 5 ms each) and the daemon's (the state's time, wall clock; only the periods whose
state is new). On a quiet machine they agree; on a loaded one the driver misses some of the
daemon's states (the periods clock runs slow: delays read short) and the daemon runs some of
its periods late (the wall clock stretches the filter's 39 periods: delays read long).

    python tools/ref_lag.py RUN_DIR [--limb right-arm] [--max-ms 400] [--step-ms 0.5]
"""

from __future__ import annotations

import argparse

import numpy as np

from hubo_cli.control.log import load_log
from hubo_cli.model import load_model


def best_delay(t_s: np.ndarray, cmd: np.ndarray, q: np.ndarray, max_s: float,
               step_s: float) -> tuple[float, float, float]:
    """The delay (s) minimising the RMS of ``q(t) - cmd(t - d)`` (N x joints), that RMS and
    the largest gap (rad)."""
    best = (np.inf, 0.0, 0.0)
    inside = t_s >= t_s[0] + max_s  # the same periods judged for every delay
    for d in np.arange(0.0, max_s + step_s / 2, step_s):
        shifted = np.column_stack([np.interp(t_s[inside] - d, t_s, c) for c in cmd.T])
        gap = q[inside] - shifted
        rms = float(np.sqrt(np.mean(gap ** 2)))
        if rms < best[0]:
            best = (rms, float(d), float(np.abs(gap).max()))
    return best[1], best[0], best[2]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir")
    parser.add_argument("--limb", default="right-arm")
    parser.add_argument("--max-ms", type=float, default=400.0)
    parser.add_argument("--step-ms", type=float, default=0.5)
    args = parser.parse_args()
    log = load_log(args.run_dir)
    joints = load_model().limb(args.limb).joints
    cmd = np.column_stack([log[f"cmd_{j}_rad"] for j in joints])
    q = np.column_stack([log[f"q_{j}_rad"] for j in joints])
    clocks = {"the run's periods": (np.asarray(log["t_s"], dtype=float), np.ones(len(cmd), bool))}
    if "hw_state_time_s" in log.columns:
        state_t = np.asarray(log["hw_state_time_s"], dtype=float)
        new = np.isfinite(state_t)
        new[1:] &= np.diff(state_t) > 0
        clocks["the daemon's"] = (state_t, new)
    for name, (t_s, rows) in clocks.items():
        delay, rms, largest = best_delay(t_s[rows], cmd[rows], q[rows], args.max_ms / 1e3,
                                         args.step_ms / 1e3)
        print(f"{args.limb}, {name} clock: best-fit delay {1e3 * delay:.1f} ms, RMS gap "
              f"{rms:.4f} rad, largest {largest:.4f} rad")


if __name__ == "__main__":
    main()
