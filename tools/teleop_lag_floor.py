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

Those two know the operator's future. The *receding-horizon family* (``--causal``) knows only
the past: a controller that every 25 ms plans its joints' accelerations within the limit over
the next 0.6 s from its own state (not free), to keep the hand on the goal as one member
predicts it from the goal's joints so far (held where they are; or extrapolated from a line
or a parabola fitted over the last 0.1-0.3 s, for 0.05-0.2 s, held beyond), applies the plan's
start and replans; its error is exact (forward kinematics, not linearised). Each member is a
causal controller within the speed and acceleration limits, so what the best of them does is
within reach of a controller that knows only the past: a causal bound from above, where the
two floors bound from below (the best member is chosen per hand knowing the stream, so the
figure also lists each member for all hands).

    python tools/teleop_lag_floor.py RUN_DIR [--accel 0.8] [--window 3] [--step 0.05] [--onset]
    python tools/teleop_lag_floor.py --generated 50 [--speed 0.25] [--duration 1.5]
    python tools/teleop_lag_floor.py --generated 50 --causal [--no-floors]
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
from hubo_cli.kinematics.reach import jacobian, rotation_error
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


def generated_goals(seed: int, settings, source=None) -> tuple[dict, dict]:
    """One generated stream followed by ``stream_runs.follow_generated`` (or ``source``, an
    input device standing for it, by ``follow_input``): the run's reach figures per arm (with
    ``reachable_periods``, how many periods its reachable RMS is over), and per arm (times (s),
    the exact IK of the operator's goal on the arm's branch (N x 6 rad), where the goal was
    reachable in the run and exactly so unsmoothed)."""
    from hubo_cli.kinematics.arm_reach import ArmReach
    from hubo_cli.teleop.session import TeleopSettings
    from hubo_cli.teleop.stream_runs import follow_generated, follow_input
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

    if source is None:
        hands = follow_generated(seed, settings, observe).hands
    else:
        with source:
            followed = follow_input(source, TeleopSettings(generate_seed=seed, stream=settings),
                                    settings.duration_s, observe)[0]
        hands = followed.reach_report()
    target = periods[0][3]
    for arm in target.arms:
        hands[arm]["reachable_periods"] = int(np.sum(target.reachable[arm]))
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
    return hands, out


def generated_floors(count: int, speed_m_s: float, duration_s: float, accel: float | None,
                     window_s: float, step_s: float, w_rot_m: float, causal: bool = False,
                     seeds=None, floors: bool = True) -> list[dict]:
    """Per stream and hand of the test's draw (or of ``seeds``): the run's reachable RMS and
    both floors'; with ``causal`` also the receding-horizon family's (per member and the best
    member's by the weighted cost)."""
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.teleop.stream_runs import GENERATED_SEEDS

    seeds = GENERATED_SEEDS[:count] if seeds is None else seeds
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
            if floors:
                pa, ra = floor_errors(t, q, ok, a_max, window_s, step_s, limb, w_rot_m)
                pv, rv = speed_floor_errors(t, q, ok, limits.velocity_rad_s, window_s,
                                            step_s / 2, limb, w_rot_m)
            else:
                pa = ra = pv = rv = np.full(len(t), np.nan)
            qdot = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
            extra = {}
            if causal:
                members = []
                for member in RHC_MEMBERS:
                    pc, rc = receding_horizon_errors(t, q, limb, a_max, limits.velocity_rad_s,
                                                     w_rot_m, member)
                    p_rms, r_rms = float(np.sqrt(np.mean(pc[ok]**2))), float(np.sqrt(np.mean(
                        rc[ok]**2)))
                    members.append((p_rms**2 + (w_rot_m * r_rms)**2, 1e3 * p_rms,
                                    float(np.degrees(r_rms)), member))
                best = min(members, key=lambda m: m[0])
                extra = {"causal_mm": best[1], "causal_deg": best[2], "causal_member": best[3],
                         "causal_members": [(m[1], m[2], m[3]) for m in members]}
            rows.append({**extra,
                "seed": seed, "arm": arm, "run_mm": hands[arm]["reachable_position_rms_mm"],
                "run_deg": hands[arm]["reachable_orientation_rms_deg"],
                "accel_floor_mm": 1e3 * float(np.sqrt(np.nanmean(pa**2))),
                "accel_floor_deg": float(np.degrees(np.sqrt(np.nanmean(ra**2)))),
                "speed_floor_mm": 1e3 * float(np.sqrt(np.nanmean(pv**2))),
                "speed_floor_deg": float(np.degrees(np.sqrt(np.nanmean(rv**2)))),
                "goal_joint_speed_max": float(np.max(qdot[ok[1:]])) if ok[1:].any() else 0.0})
    return rows


def causal_fits(t_s: np.ndarray, q: np.ndarray, kind: str, window_s: float):
    """Per sample k, the slope (rad/s) and half the curvature (rad/s^2; 0 for ``velocity``) of
    the least-squares polynomial through the goal's joints over (t_k - window_s, t_k], in
    powers of (t - t_k): what a controller knows at k."""
    order = 1 if kind == "velocity" else 2
    c1, c2 = np.zeros_like(q), np.zeros_like(q)
    for k in range(len(t_s)):
        b = int(np.searchsorted(t_s, t_s[k] - window_s, side="right"))
        if k - b < order:
            continue
        dt = t_s[b:k + 1] - t_s[k]
        V = np.vander(dt, order + 1, increasing=True)
        coef = np.linalg.lstsq(V, q[b:k + 1], rcond=None)[0]
        c1[k] = coef[1]
        if order == 2:
            c2[k] = coef[2]
    return c1, c2


RHC_BLOCKS_S = (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.6)
"""The receding-horizon plan's piecewise-constant accelerations: they change at these times
after now (finer near now, where the plan is applied), up to its horizon, 0.6 s."""
RHC_REPLAN_S = 0.025   # replanned this often (the first half of the first block applied)
RHC_SAMPLE_S = 0.05    # its error counted at this spacing over the horizon
RHC_MEMBERS = (("hold", 0.0, 0.0),) + tuple(
    (kind, window, h) for kind, window in (("velocity", 0.1), ("acceleration", 0.3))
    for h in (0.05, 0.1, 0.2))
"""The receding-horizon family: the goal's joints predicted from the past (``hold``: where
they are; else a fit over ``window`` s as in :func:`causal_fits`) for ``h`` s, held there
beyond. (``future``, not causal, is the planner's check: the goal's future as it comes, for
``h`` s.)"""


def receding_horizon_errors(t_s, q_goal, limb, accel_rad_s2, velocity_rad_s, w_rot_m,
                            member):
    """Per sample, the exact position error (m) and rotation error (rad) of a causal
    controller within the joints' acceleration and speed limits: every ``RHC_REPLAN_S`` it
    plans piecewise-constant joint accelerations within the limit (``RHC_BLOCKS_S``)
    from its state (its position and velocity, not free) that minimise the mean of |p error|^2
    + w^2 |rotation error|^2 (linearised about the predicted goal's joints) against the goal
    as ``member`` predicts it from the samples up to now, applies the plan's start until the
    next replan (velocities clipped to the speed limit), and so on. The joints start at rest
    on the first goal; sample k's error is the state the goals up to k - 1 commanded."""
    kind, window, h_cap = member
    c1, c2 = ((np.zeros_like(q_goal), np.zeros_like(q_goal)) if kind in ("hold", "future")
              else causal_fits(t_s, q_goal, kind, window))
    a = np.broadcast_to(np.asarray(accel_rad_s2, dtype=float), (6,))
    vmax = np.broadcast_to(np.asarray(velocity_rad_s, dtype=float), (6,))
    base, _, offset, alpha, a_dh, d, end, _ = limb.chain
    T, J, T_goal, e = np.empty((4, 4)), np.empty((6, 6)), np.empty((4, 4)), np.empty(3)
    scale = np.r_[np.ones(3), np.full(3, w_rot_m)][:, None]
    edges = np.asarray(RHC_BLOCKS_S)
    nb_ = len(edges) - 1
    tau = np.arange(1, int(round(edges[-1] / RHC_SAMPLE_S)) + 1) * RHC_SAMPLE_S  # after now
    start, stop = edges[None, :-1], edges[None, 1:]
    inside = np.clip(tau[:, None] - start, 0.0, stop - start)  # each block's time before tau
    coef = inside * (tau[:, None] - start - inside / 2)  # its acceleration's share of q(tau)
    bounds = (np.tile(-a, nb_), np.tile(a, nb_))
    n = len(t_s)
    q, v = q_goal[0].copy(), np.zeros(6)
    u = np.zeros(6)
    next_plan = t_s[0]
    pos, rot = np.empty(n), np.empty(n)
    for k in range(n):
        jacobian(np.ascontiguousarray(q_goal[k]), base, offset, alpha, a_dh, d, end, T_goal, J)
        jacobian(np.ascontiguousarray(q), base, offset, alpha, a_dh, d, end, T, J)
        pos[k] = np.linalg.norm(T[:3, 3] - T_goal[:3, 3])
        rot[k] = rotation_error(T, T_goal, e)
        if k == n - 1:
            break
        if t_s[k] >= next_plan - 1e-9:
            next_plan = t_s[k] + RHC_REPLAN_S
            hs = np.minimum(tau, h_cap)[:, None]
            q_hat = q_goal[k] + c1[k] * hs + c2[k] * hs * hs  # nb x 6
            if kind == "future":  # the planner's check: the goal's future itself
                q_hat = np.column_stack([np.interp(t_s[k] + hs[:, 0], t_s, q_goal[:, j])
                                         for j in range(6)])
            A = np.zeros((6 * len(tau), 6 * nb_))
            b = np.empty(6 * len(tau))
            for i in range(len(tau)):
                jacobian(np.ascontiguousarray(q_hat[i]), base, offset, alpha, a_dh, d, end, T,
                         J)
                Jp = J * scale
                for j in range(nb_):
                    if coef[i, j]:
                        A[6 * i:6 * i + 6, 6 * j:6 * j + 6] = Jp * coef[i, j]
                b[6 * i:6 * i + 6] = Jp @ (q_hat[i] - q - v * tau[i])
            u = lsq_linear(A, b, bounds=bounds, method="bvls").x[:6]
        dt = t_s[k + 1] - t_s[k]
        v_new = np.clip(v + u * dt, -vmax, vmax)
        q = q + 0.5 * (v + v_new) * dt
        v = v_new
    return pos, rot


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


def print_causal(rows: list[dict], w_rot_m: float) -> None:
    """Per hand the run, the receding-horizon family's best member (by the weighted cost) and
    the perfect-future floor (the larger of the acceleration and speed floors); then per
    figure the median and worst and the hands over the targets, and the family's members
    one by one (a member for all hands is a causal controller; the best per hand is chosen
    knowing the stream)."""
    mm, deg = 1e3 * TARGET_POSITION_M, np.degrees(TARGET_ROTATION_RAD)
    for r in rows:
        r["future_mm"] = max(r["accel_floor_mm"], r["speed_floor_mm"])
        r["future_deg"] = max(r["accel_floor_deg"], r["speed_floor_deg"])
        print(f"seed {r['seed']} {r['arm']}: run {r['run_mm']:.1f} mm / {r['run_deg']:.2f} "
              f"deg; causal {r['causal_mm']:.1f} / {r['causal_deg']:.2f} "
              f"({' '.join(map(str, r['causal_member']))}); perfect future "
              f"{r['future_mm']:.1f} / {r['future_deg']:.2f}")
    for name in ("run", "causal", "future"):
        p = np.array([r[f"{name}_mm"] for r in rows])
        o = np.array([r[f"{name}_deg"] for r in rows])
        if np.isnan(p).all():  # --no-floors
            continue
        print(f"{name}: position median / worst {np.nanmedian(p):.2f} / {np.nanmax(p):.2f} mm, "
              f"orientation {np.nanmedian(o):.2f} / {np.nanmax(o):.2f} deg; hands over "
              f"{mm:g} mm {int(np.sum(p > mm))}, over {deg:g} deg {int(np.sum(o > deg))}, over "
              f"either {int(np.sum((p > mm) | (o > deg)))} of {len(rows)}; streams whose "
              f"hands all meet both {_streams_within(rows, p, o)}")
    for i, member in enumerate(RHC_MEMBERS):
        p = np.array([r["causal_members"][i][0] for r in rows])
        o = np.array([r["causal_members"][i][1] for r in rows])
        print(f"member {' '.join(map(str, member))}: position median {np.median(p):.2f} mm, "
              f"orientation {np.median(o):.2f} deg; hands over either "
              f"{int(np.sum((p > mm) | (o > deg)))}; streams whose hands all meet both "
              f"{_streams_within(rows, p, o)}")


def _streams_within(rows: list[dict], p_mm: np.ndarray, o_deg: np.ndarray) -> int:
    """How many streams have every hand within 10 mm and 3 deg (row i's figures p_mm[i],
    o_deg[i])."""
    within = (p_mm <= 1e3 * TARGET_POSITION_M) & (o_deg <= np.degrees(TARGET_ROTATION_RAD))
    seeds = {r["seed"] for r in rows}
    return sum(all(w for r, w in zip(rows, within, strict=True) if r["seed"] == s)
               for s in seeds)


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
    parser.add_argument("--causal", action="store_true",
                        help="with --generated: the receding-horizon family too")
    parser.add_argument("--no-floors", action="store_true",
                        help="with --generated --causal: the family alone, not the floors")
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
                                args.window, args.step, args.weight, causal=args.causal,
                                floors=not args.no_floors)
        if args.causal:
            print_causal(rows, args.weight)
            return
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
