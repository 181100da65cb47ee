"""How closely could any controller within the arms' acceleration limit have followed a teleop run?

Reads a teleoperation run folder (``hubo teleop ... --out DIR``) and, per arm, takes the arm's
joint targets as logged (the goal's exact IK while the goal is reachable; on the generated
streams they are within a fraction of a millimetre of the goal) and finds the joint trajectory
nearest to them in hand pose whose joint accelerations stay within the limit: it minimises the
mean over the reachable samples of |p error|^2 + w^2 |rotation error|^2 (both linearised about
the targets q*: J(q*) (q - q*)), over piecewise-constant accelerations within +-the limit, the
position and speed at the start of each window free. Free starts and no speed or jerk limit
make it a relaxation: no controller within the acceleration limit does better, with perfect
knowledge of the operator's future included (to first order in the error). So when that floor
exceeds 10 mm^2 + w^2 (3 deg)^2 (``w`` = 10 mm / 3 deg by default), no controller meets both
of issue 34's targets (position RMS <= 10 mm and orientation RMS <= 3 deg over the reachable
time) on that run's goals. It prints the floor's position and orientation RMS, the certificate,
and what the run did.

    python tools/teleop_lag_floor.py RUN_DIR [--accel 0.8] [--window 3] [--step 0.05]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import polars as pl
from scipy.optimize import lsq_linear

from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.reach import jacobian
from hubo_cli.model import load_model

SHORT = {"right-arm": "r", "left-arm": "l"}


TARGET_POSITION_M = 0.010
TARGET_ROTATION_RAD = np.radians(3.0)


def floor_errors(t_s, q_target, weight, accel_rad_s2, window_s, step_s, limb, w_rot_m):
    """Per sample of the resampled grid (NaN where not reachable), the floor trajectory's
    linearised position error (m) and rotation error (rad)."""
    grid = np.arange(t_s[0], t_s[-1], step_s)
    q_star = np.column_stack([np.interp(grid, t_s, q_target[:, j]) for j in range(6)])
    w = np.interp(grid, t_s, weight.astype(float)) > 0.5
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T, J = np.empty((4, 4)), np.empty((6, 6))
    errors = np.full(len(grid), np.nan)
    rot_errors = np.full(len(grid), np.nan)
    scale = np.r_[np.ones(3), np.full(3, w_rot_m)][:, None]
    per = max(2, int(round(window_s / step_s)))
    for start in range(0, len(grid), per):
        k = np.arange(start, min(start + per, len(grid)))
        if not w[k].any():
            continue
        n = len(k)
        tk = (k - start) * step_s
        # q_i = q0 + v0 t_i + sum_{j < i} u_j h (t_i - t_j - h / 2), per joint
        coef = np.maximum(tk[:, None] - tk[None, :] - step_s / 2, 0.0) * step_s
        coef[tk[:, None] <= tk[None, :]] = 0.0
        rows, rhs = [], []
        for i, gi in enumerate(k):
            if not w[gi]:
                continue
            jacobian(np.ascontiguousarray(q_star[gi]), base, offset, alpha, a, d, end, T, J)
            Jp = J * scale
            row = np.zeros((6, 6 * (2 + n)))
            row[:, 0:6] = Jp
            row[:, 6:12] = Jp * tk[i]
            for j in range(n):
                if coef[i, j]:
                    row[:, 6 * (2 + j):6 * (3 + j)] = Jp * coef[i, j]
            rows.append(row)
            rhs.append(Jp @ q_star[gi])
        A, b = np.vstack(rows), np.concatenate(rhs)
        lo = np.r_[np.full(12, -np.inf), np.full(6 * n, -accel_rad_s2)]
        hi = -lo
        hi[:12] = np.inf
        x = lsq_linear(A, b, bounds=(lo, hi), method="bvls").x
        r = (A @ x - b).reshape(-1, 6)
        errors[k[w[k]]] = np.linalg.norm(r[:, :3], axis=1)
        rot_errors[k[w[k]]] = np.linalg.norm(r[:, 3:], axis=1) / w_rot_m
    return errors, rot_errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--accel", type=float, default=None,
                        help="arm joint acceleration limit, rad/s^2 (default: the robot file's)")
    parser.add_argument("--window", type=float, default=3.0, help="window length (s)")
    parser.add_argument("--step", type=float, default=0.05, help="acceleration step (s)")
    parser.add_argument("--weight", type=float, default=TARGET_POSITION_M / TARGET_ROTATION_RAD,
                        help="metres of position error one radian is worth (default 10 mm / "
                             "3 deg)")
    args = parser.parse_args()
    log = pl.read_parquet(args.run_dir / "log.parquet").filter(pl.col("phase_code") == 1)
    t = log["t_s"].to_numpy()
    model = load_model()
    for arm, key in SHORT.items():
        if f"error_m_{key}" not in log.columns:
            continue
        limb = get_limb(arm, "hand")
        joints = model.limb(arm).joints
        q = np.column_stack([log[f"target_{j}_rad"].to_numpy() for j in joints])
        reachable = log[f"reach_limit_m_{key}"].to_numpy() == 0.0
        accel = args.accel or float(model.limb(arm).acceleration_rad_s2[0])
        pos, rot = floor_errors(t, q, reachable, accel, args.window, args.step, limb,
                                args.weight)
        error = log[f"error_m_{key}"].to_numpy()[reachable]
        rot_run = log[f"rot_error_rad_{key}"].to_numpy()[reachable]
        cost = float(np.nanmean(pos**2 + (args.weight * rot) ** 2))
        bound = TARGET_POSITION_M**2 + (args.weight * TARGET_ROTATION_RAD) ** 2
        print(f"{arm}: goal reachable {reachable.mean():.0%} of the time; over it the run "
              f"{1e3 * np.sqrt(np.mean(error**2)):.1f} mm / "
              f"{np.degrees(np.sqrt(np.mean(rot_run**2))):.1f} deg RMS; the floor at {accel:g} "
              f"rad/s^2 {1e3 * np.sqrt(np.nanmean(pos**2)):.1f} mm / "
              f"{np.degrees(np.sqrt(np.nanmean(rot**2))):.1f} deg RMS: the targets "
              + ("cannot be met" if cost > bound else "are not ruled out")
              + f" (weighted floor {1e3 * np.sqrt(cost):.1f} mm against "
              f"{1e3 * np.sqrt(bound):.1f} mm)")


if __name__ == "__main__":
    main()
