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

That floor knows the operator's future. The *onset floor* does not: where the goal has rested
(``REST_S`` with its joints within ``REST_RAD``) and starts to move, a controller that holds
the hand on the resting goal moves its joints at most at the resting goal's speed, taken
generously as u = 2 REST_RAD / REST_S, so each joint is at most min(u t + a t^2 / 2, v t)
from where it rested t seconds later, whatever it knows; the hand's error
then is at least the distance (linearised about the goal's joints) from the goal to the poses
of that box of joints. Counted over the stroke that follows each onset (until the goal rests
again, ``ONSET_HORIZON_S`` at most) and zero elsewhere, it is a floor for any controller that
keeps the hand on the goal while the goal rests and cannot know when the operator will move.

The *speed floor* is the same relaxation under the joints' speed limit instead of their
acceleration limit (piecewise-constant joint velocities within +-the limit, the position at the
start of each window free): the share of a goal's turn or stroke that asks more of a joint than
its speed shows there. Both floors bound every controller within the limits from below, so the
larger of the two does.

    python tools/teleop_lag_floor.py RUN_DIR [--accel 0.8] [--window 3] [--step 0.05] [--onset]
    python tools/teleop_lag_floor.py --generated 50 [--speed 0.25] [--duration 1.5]
    python tools/teleop_lag_floor.py --rates

(``--onset``: the onset floor alone, in seconds instead of minutes. ``--generated N``: the first
N streams of tests/test_teleop_streams.py's draw, followed by ``stream_runs.follow_generated``;
per stream and hand the run's reachable RMS and both floors, the goal's joint targets being the
exact IK of the goal as the operator gave it, its orientation not smoothed. ``--rates``: at
the free-mode ready pose, the fastest joint a turn of the hand (its position held) and a move
of the hand (its orientation held) ask per rad/s and per m/s, over the axes and directions, and
so the turn rate and hand speed the joints' speed limit allows.)
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


def _windowed_floor(t_s, q_target, weight, window_s, step_s, limb, w_rot_m, row_of, bounds_of):
    """Per sample of the resampled grid (NaN where not reachable), the linearised position
    error (m) and rotation error (rad) of the trajectory closest to the goal's joints, window by
    window: ``row_of(Jp, i, n)`` gives sample i's row of the linear model (Jp the weighted
    Jacobian there), ``bounds_of(n)`` its variables' bounds (lo, hi)."""
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
        rows, rhs = [], []
        for i, gi in enumerate(k):
            if not w[gi]:
                continue
            jacobian(np.ascontiguousarray(q_star[gi]), base, offset, alpha, a, d, end, T, J)
            Jp = J * scale
            rows.append(row_of(Jp, i, len(k)))
            rhs.append(Jp @ q_star[gi])
        A, b = np.vstack(rows), np.concatenate(rhs)
        x = lsq_linear(A, b, bounds=bounds_of(len(k)), method="bvls").x
        r = (A @ x - b).reshape(-1, 6)
        errors[k[w[k]]] = np.linalg.norm(r[:, :3], axis=1)
        rot_errors[k[w[k]]] = np.linalg.norm(r[:, 3:], axis=1) / w_rot_m
    return errors, rot_errors


def floor_errors(t_s, q_target, weight, accel_rad_s2, window_s, step_s, limb, w_rot_m):
    """Per sample of the resampled grid (NaN where not reachable), the floor trajectory's
    linearised position error (m) and rotation error (rad) under the acceleration limit:
    piecewise-constant accelerations within it, free start and velocity per window."""
    per = max(2, int(round(window_s / step_s)))
    tk = np.arange(per) * step_s
    # q_i = q0 + v0 t_i + sum_{j < i} u_j h (t_i - t_j - h / 2), per joint
    coef = np.maximum(tk[:, None] - tk[None, :] - step_s / 2, 0.0) * step_s
    coef[tk[:, None] <= tk[None, :]] = 0.0

    def row_of(Jp, i, n):
        row = np.zeros((6, 6 * (2 + n)))
        row[:, 0:6] = Jp
        row[:, 6:12] = Jp * tk[i]
        for j in range(n):
            if coef[i, j]:
                row[:, 6 * (2 + j):6 * (3 + j)] = Jp * coef[i, j]
        return row

    def bounds_of(n):
        lo = np.r_[np.full(12, -np.inf), np.full(6 * n, -accel_rad_s2)]
        hi = -lo
        hi[:12] = np.inf
        return lo, hi

    return _windowed_floor(t_s, q_target, weight, window_s, step_s, limb, w_rot_m, row_of,
                           bounds_of)


def speed_floor_errors(t_s, q_target, weight, velocity_rad_s, window_s, step_s, limb, w_rot_m):
    """As :func:`floor_errors` under the speed limit ``velocity_rad_s`` (per joint) instead of
    an acceleration limit: piecewise-constant velocities within it, free start per window."""
    vmax = np.broadcast_to(np.asarray(velocity_rad_s, dtype=float), (6,))

    def row_of(Jp, i, n):  # q_i = q0 + h sum_{j < i} v_j
        row = np.zeros((6, 6 * (1 + n)))
        row[:, 0:6] = Jp
        for j in range(i):
            row[:, 6 * (1 + j):6 * (2 + j)] = Jp * step_s
        return row

    def bounds_of(n):
        lo = np.r_[np.full(6, -np.inf), -np.tile(vmax, n)]
        hi = -lo
        hi[:6] = np.inf
        return lo, hi

    return _windowed_floor(t_s, q_target, weight, window_s, step_s, limb, w_rot_m, row_of,
                           bounds_of)


def joint_speed_per_rate(arm: str, directions: int = 20000) -> dict[str, np.ndarray]:
    """At the free-mode ready pose, over ``directions`` random unit axes: the fastest joint
    (rad/s) a hand turn of 1 rad/s about the axis with the hand's position held asks
    (``turn``), and the fastest a hand speed of 1 m/s along it with the orientation held asks
    (``move``): the rows of the inverse Jacobian."""
    from hubo_cli.teleop.session import FREE_READY_ARM_RAD

    base, _, offset, alpha, a, d, end, _ = get_limb(arm, "hand").chain
    T, J = np.empty((4, 4)), np.empty((6, 6))
    jacobian(np.array(FREE_READY_ARM_RAD[arm], dtype=float), base, offset, alpha, a, d, end,
             T, J)
    J_inv = np.linalg.inv(J)
    axes = np.random.default_rng(0).normal(size=(3, directions))
    axes /= np.linalg.norm(axes, axis=0)
    return {"turn": np.abs(J_inv[:, 3:] @ axes).max(axis=0),
            "move": np.abs(J_inv[:, :3] @ axes).max(axis=0)}


def generated_goals(seed: int, settings) -> tuple[dict, dict]:
    """One generated stream followed by ``stream_runs.follow_generated``: the run's reach
    figures per arm, and per arm (times (s), the exact IK of the operator's goal on the arm's
    branch (N x 6 rad), where the goal was reachable in the run and exactly so unsmoothed)."""
    from hubo_cli.kinematics.arm_reach import ArmReach
    from hubo_cli.teleop.stream_runs import follow_generated
    from hubo_cli.teleop.target import REACHABLE_POSITION_M, REACHABLE_ROTATION_RAD

    periods = []

    def observe(target, t_s):
        if target.phase != "operate":
            return
        lift = target.body.lift_of(target.q_target)
        periods.append((t_s, {arm: (None if target.goals.get(arm) is None
                                    else target.goals[arm].copy(),
                                    target.hands[arm].reachable,
                                    target.q_target[target.slices[arm]].copy())
                              for arm in target.arms}, lift, target))

    run = follow_generated(seed, settings, observe)
    target = periods[0][3]
    out = {}
    for arm in target.arms:
        reach = ArmReach(target.body.arms[arm], target.reach_settings)
        q_prev = periods[0][1][arm][2]
        reach.start(q_prev)
        t, q, ok = [], [], []
        for t_s, arms, lift, _ in periods:
            T_goal, reachable, _ = arms[arm]
            if T_goal is None:
                continue
            T_N = T_goal.copy()
            T_N[2, 3] -= lift
            result = reach.solve(T_N, q_prev)
            q_prev = result.q_rad
            t.append(t_s)
            q.append(result.q_rad)
            ok.append(reachable and result.position_error_m <= REACHABLE_POSITION_M
                      and result.rotation_error_rad <= REACHABLE_ROTATION_RAD)
        out[arm] = (np.array(t), np.array(q), np.array(ok, dtype=bool))
    return run.hands, out


def generated_floors(count: int, speed_m_s: float, duration_s: float, accel: float | None,
                     window_s: float, step_s: float, w_rot_m: float) -> list[dict]:
    """Per stream and hand of the test's draw: the run's reachable RMS and both floors'."""
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.teleop.stream_runs import GENERATED_SEEDS

    seeds = GENERATED_SEEDS[:count]
    model = load_model(limits="teleop")
    rows = []
    for seed in seeds:
        hands, goals = generated_goals(seed, StreamSettings(duration_s=duration_s,
                                                            max_speed_m_s=speed_m_s))
        for arm, (t, q, ok) in goals.items():
            if ok.sum() < 2:
                continue
            limits = model.limb(arm)
            limb = get_limb(arm, "hand")
            a_max = accel or float(limits.acceleration_rad_s2[0])
            pa, ra = floor_errors(t, q, ok, a_max, window_s, step_s, limb, w_rot_m)
            pv, rv = speed_floor_errors(t, q, ok, limits.velocity_rad_s, window_s, step_s / 2,
                                        limb, w_rot_m)
            qdot = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
            rows.append({
                "seed": seed, "arm": arm, "run_mm": hands[arm]["reachable_position_rms_mm"],
                "run_deg": hands[arm]["reachable_orientation_rms_deg"],
                "accel_floor_mm": 1e3 * float(np.sqrt(np.nanmean(pa**2))),
                "accel_floor_deg": float(np.degrees(np.sqrt(np.nanmean(ra**2)))),
                "speed_floor_mm": 1e3 * float(np.sqrt(np.nanmean(pv**2))),
                "speed_floor_deg": float(np.degrees(np.sqrt(np.nanmean(rv**2)))),
                "goal_joint_speed_max": float(np.max(qdot[ok[1:]])) if ok[1:].any() else 0.0})
    return rows


REST_S = 0.3           # the goal rests: its joints moved less than REST_RAD over this long
REST_RAD = 0.02        # (the generated operator's slow wander moves a resting hand 1-3 mm)
ONSET_HORIZON_S = 1.5  # an onset's stroke is counted this long at most


def onset_floor_errors(t_s, q_target, weight, accel_rad_s2, velocity_rad_s, limb):
    """Per sample (0 outside the strokes that follow a rest, NaN where not reachable), the onset
    floor's linearised position error (m) and rotation error (rad) (see the module
    docstring)."""
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T, J = np.empty((4, 4)), np.empty((6, 6))
    pos, rot = np.zeros(len(t_s)), np.zeros(len(t_s))
    back = np.searchsorted(t_s, t_s - REST_S)
    moved = np.array([np.max(np.abs(q_target[b:i + 1] - q_target[i]))
                      for i, b in enumerate(back)])
    resting = moved < REST_RAD
    i = 0
    while i < len(t_s) - 1:
        if not (resting[i] and not resting[i + 1]):
            i += 1
            continue
        t0, q0 = t_s[i], q_target[i]
        k = i + 1
        while k < len(t_s) and not resting[k] and t_s[k] - t0 <= ONSET_HORIZON_S:
            if weight[k]:
                dt = t_s[k] - t0
                box = np.minimum(2 * REST_RAD / REST_S * dt + 0.5 * accel_rad_s2 * dt * dt,
                                 velocity_rad_s * dt)
                jacobian(np.ascontiguousarray(q_target[k]), base, offset, alpha, a, d, end, T, J)
                delta = q_target[k] - q0  # the joints' way the box must cover
                for rows, out in ((J[:3], pos), (J[3:], rot)):
                    x = lsq_linear(rows, rows @ delta, bounds=(-box, box)).x
                    out[k] = float(np.linalg.norm(rows @ (x - delta)))
            k += 1
        i = k
    pos[~weight], rot[~weight] = np.nan, np.nan
    return pos, rot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, nargs="?")
    parser.add_argument("--generated", type=int, default=0,
                        help="the floors of the first N generated test streams instead of a run")
    parser.add_argument("--rates", action="store_true",
                        help="the joint speeds a hand's turn and move ask at the ready pose")
    parser.add_argument("--speed", type=float, default=0.25, help="their hand speed cap (m/s)")
    parser.add_argument("--duration", type=float, default=1.5, help="their length (s)")
    parser.add_argument("--accel", type=float, default=None,
                        help="arm joint acceleration limit, rad/s^2 (default: the robot file's)")
    parser.add_argument("--window", type=float, default=3.0, help="window length (s)")
    parser.add_argument("--step", type=float, default=0.05, help="acceleration step (s)")
    parser.add_argument("--weight", type=float, default=TARGET_POSITION_M / TARGET_ROTATION_RAD,
                        help="metres of position error one radian is worth (default 10 mm / "
                             "3 deg)")
    parser.add_argument("--onset", action="store_true", help="the onset floor alone")
    args = parser.parse_args()
    if args.rates:
        model = load_model(limits="teleop")
        for arm in SHORT:
            vmax = float(model.limb(arm).velocity_rad_s.min())
            need = joint_speed_per_rate(arm)
            turn = (np.median(need["turn"]), need["turn"].max())
            move = (np.median(need["move"]), need["move"].max())
            print(f"{arm} at the ready pose: a turn of 1 rad/s asks a joint for {turn[0]:.2f} "
                  f"rad/s (median axis), {turn[1]:.2f} (worst): at {vmax:g} rad/s the hand turns "
                  f"at {np.degrees(vmax / turn[0]):.0f} / {np.degrees(vmax / turn[1]):.0f} "
                  f"deg/s; a move of 1 m/s {move[0]:.2f} / {move[1]:.2f} rad/s: "
                  f"{vmax / move[0]:.3f} / {vmax / move[1]:.3f} m/s")
        return
    if args.generated:
        rows = generated_floors(args.generated, args.speed, args.duration, args.accel,
                                args.window, args.step, args.weight)
        for r in rows:
            print(f"seed {r['seed']} {r['arm']}: run {r['run_mm']:.1f} mm / {r['run_deg']:.1f} "
                  f"deg; acceleration floor {r['accel_floor_mm']:.1f} mm / "
                  f"{r['accel_floor_deg']:.1f} deg; speed floor {r['speed_floor_mm']:.1f} mm / "
                  f"{r['speed_floor_deg']:.1f} deg; the goal's fastest joint "
                  f"{r['goal_joint_speed_max']:.2f} rad/s")
        for key in ("run_mm", "run_deg", "accel_floor_mm", "accel_floor_deg", "speed_floor_mm",
                    "speed_floor_deg", "goal_joint_speed_max"):
            v = np.array([r[key] for r in rows])
            print(f"{key}: median {np.median(v):.2f}, worst {v.max():.2f}")
        return
    if args.run_dir is None:
        parser.error("give a run folder or --generated N")
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
        error = log[f"error_m_{key}"].to_numpy()[reachable]
        rot_run = log[f"rot_error_rad_{key}"].to_numpy()[reachable]
        vmax = float(model.limb(arm).velocity_rad_s[0])
        pos, rot = onset_floor_errors(t, q, reachable, accel, vmax, limb)
        print(f"{arm}: over the reachable time ({reachable.mean():.0%}) the run "
              f"{1e3 * np.sqrt(np.mean(error**2)):.1f} mm / "
              f"{np.degrees(np.sqrt(np.mean(rot_run**2))):.1f} deg RMS; the onset floor (no "
              f"knowledge of when the operator moves) at {accel:g} rad/s^2 "
              f"{1e3 * np.sqrt(np.nanmean(pos**2)):.1f} mm / "
              f"{np.degrees(np.sqrt(np.nanmean(rot**2))):.1f} deg RMS")
        if args.onset:
            continue
        pos, rot = floor_errors(t, q, reachable, accel, args.window, args.step, limb,
                                args.weight)
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
