"""The floating base's estimate against the simulator's truth, from a run's period log.

    python tools/estimate_vs_truth.py RUN_DIR [RUN_DIR ...] [--jumps 5]

For each run folder (a `hubo walk` / `hubo sim` run with the estimate's columns): the torso's
error (estimate less truth, both in the world frame they start in) at the end, its largest,
and the heading's (yaw) error; the heading error's drift (deg/s, a line fitted over the walk);
the torso error's largest one-period jumps (mm) outside the hops, with their time and the
soles' F_z then, and how much of the position error the hops (both soles under 25 N) account
for (the error's change over their periods; the error starts at the settled truth's offset).
One JSON line per run. Measurements only (docs/history/); no module reads the truth.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from hubo_cli.control.log import load_log

HOP_N = 25.0  # a sole lighter than this is off the floor (the contact threshold)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def analyse(run_dir: str, jumps: int) -> dict:
    log = load_log(run_dir)
    t = log["t_s"]
    ok = np.isfinite(log["est_torso_x_m"]) & np.isfinite(log["torso_x_m"])
    t = t[ok]
    est = np.column_stack([log["est_torso_x_m"], log["est_torso_y_m"]])[ok]
    true = np.column_stack([log["torso_x_m"], log["torso_y_m"]])[ok]
    err = est - true
    fz = np.column_stack([log["right_foot_fz_n"], log["left_foot_fz_n"]])[ok]
    out: dict = {"run": run_dir, "periods": int(ok.sum()),
                 "final_err_xy_mm": (1e3 * err[-1]).round(1).tolist(),
                 "max_err_xy_mm": float(1e3 * np.hypot(*err.T).max().round(4))}
    if "est_torso_yaw_rad" in log.columns:
        yaw_err = _wrap(log["est_torso_yaw_rad"][ok] - log["torso_yaw_rad"][ok])
        moving = np.abs(np.diff(true[:, 0], prepend=true[0, 0])) > 0  # the whole run
        drift = np.polyfit(t[moving], yaw_err[moving], 1)[0] if moving.sum() > 10 else math.nan
        out.update(final_yaw_err_deg=round(math.degrees(yaw_err[-1]), 3),
                   max_yaw_err_deg=round(math.degrees(np.abs(yaw_err).max()), 3),
                   yaw_err_drift_deg_s=round(math.degrees(drift), 4),
                   yaw_err_rms_deg=round(math.degrees(math.sqrt(np.mean(yaw_err ** 2))), 3))
    step = np.hypot(*np.diff(err, axis=0).T)
    hop = (fz[1:, 0] < HOP_N) & (fz[1:, 1] < HOP_N)
    out["hop_s"] = round(float(hop.sum() * np.median(np.diff(t))), 3)
    out["err_change_in_hops_mm"] = (1e3 * np.diff(err, axis=0)[hop].sum(axis=0)).round(1).tolist()
    order = np.argsort(np.where(hop, 0.0, step))[::-1][:jumps]  # outside the hops
    out["jumps"] = [{"t_s": round(float(t[i + 1]), 3), "mm": round(float(1e3 * step[i]), 2),
                     "fz_n": fz[i + 1].round(0).tolist()} for i in order]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--jumps", type=int, default=5, help="largest one-period jumps listed")
    args = parser.parse_args()
    for run in args.runs:
        print(json.dumps(analyse(run, args.jumps)))


if __name__ == "__main__":
    main()
