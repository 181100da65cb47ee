"""Whether a crossing step could catch a walk pushed toward its stance foot (issue 37's 100 N
pushes mid-walk), from the pushed runs' own logs: the earliest time a clear crossing landing
can be on the floor, and whether the capture point is then inside the two soles.

    python tools/crossing_step_reach.py --runs /tmp/walk_disturbances --seeds 6,10,18

Reads the runs of ``tools/walk_disturbances.py push`` (the same seeds, distance and
directions). For each push in a single support toward the stance foot:

* **the decision** (the estimate only; ``--decision``): the momentum strategy's watch (the
  capture point's error toward the stance sole's outer side past its TRIGGER_M, watched its
  DECIDE_S), the estimated capture point past the stance sole's outer edge and heading out,
  or the first of the two; the swing leg's joints as the log has them then are the start;
* **the landings**, every TIME_STEP_S from the decision to the log's end (the fall, or the
  run's last period): the swing sole flat on the floor (where the stance sole stood at the
  push's start), over a grid of places beyond the stance sole's outer edge and turns, from
  the pelvis where the run has it at that moment (a body rolled over the edge lifts the swing
  hip; a body gone outward brings it over the crossing places): reached within Table IV (the
  swing leg's closed-form IK, exact), the legs' collision shapes apart, and **in time**: the
  joints there from the decision's within the time since, at the walking limit set's
  velocity and acceleration, each joint on its own time-optimal profile (no path around the
  stance leg, no reaction time: a lower bound on the time; whether the straight path in joint
  space keeps the legs apart is said);
* **then**: how far the estimated capture point lies inside the convex hull of the two soles
  (the stance sole where the measured leg under the logged torso has it), also with the
  swing leg's own momentum counted (its motion toward the fall moves the centroidal moment
  pivot: the centroidal map about the stance sole's forward axis at the decision's posture,
  rough: the leg's turn changes the map), and the torso's tilt (the fall criterion
  FALL_TILT_DEG).

A summary per push: the first landing in time with the capture point inside the hull, and the
tilt if the body then came to rest with its CoM over that capture point (its roll about the
stance sole's edge grown by the CoM's distance to the capture point over the CoM's height);
and the least speed, as a multiple of the walking set's, that would land the swing foot with
the capture point inside the hull and that tilt under the criterion. All of it is necessary,
not sufficient: the body is the run's, not one that steps; the landing's impact is left out.
Measured numbers go in docs/history/walking.md, not here.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from side_push_bound import SIDES, T_world_neck_at, leg_names
from walk_disturbances import draw, seeds_of

from hubo_cli.control.collision import SelfCollisionChecker
from hubo_cli.control.log import load_log
from hubo_cli.experiments.standing import PUSH_DIRECTIONS
from hubo_cli.falls import FALL_TILT_DEG
from hubo_cli.geometry import rpy_to_matrix
from hubo_cli.kinematics import choice
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import GRAVITY_M_S2
from hubo_cli.walking.momentum import DECIDE_S, TRIGGER_M

CROSS_X_M = np.arange(-0.40, 0.401, 0.02)    # the landings, in the stance sole's frame on the
CROSS_Y_M = np.arange(0.0, 0.301, 0.02)      # floor (outward from its outer edge: the sole's
CROSS_YAW_RAD = np.arange(-1.8, 1.801, 0.1)  # centre this far beyond it)
TIME_STEP_S = 0.01  # landings are tried this often after the decision
PATH_SAMPLES = 20  # the straight joint-space path is checked at this many points


def travel_time_s(distance_rad: np.ndarray, velocity: np.ndarray,
                  acceleration: np.ndarray) -> float:
    """The least time for every joint to cover its ``distance_rad`` from rest to rest, each on
    its own time-optimal profile (s): the slowest joint's."""
    d = np.abs(distance_rad)
    triangle = d < velocity ** 2 / acceleration
    t = np.where(triangle, 2.0 * np.sqrt(d / acceleration),
                 d / velocity + velocity / acceleration)
    return float(t.max())


def profile_speed(distance_rad: float, velocity: float, acceleration: float,
                  u: np.ndarray) -> np.ndarray:
    """The speed (rad/s, signed as ``distance_rad``) at times ``u`` (s, from its start) of
    the time-optimal rest-to-rest motion over ``distance_rad``."""
    d = abs(distance_rad)
    peak = min(velocity, math.sqrt(acceleration * d))
    ramp = peak / acceleration
    end = 2 * ramp + (d - peak * ramp) / peak if peak > 0 else 0.0
    speed = np.minimum.reduce([acceleration * u, np.full_like(u, peak),
                               acceleration * (end - u)])
    return math.copysign(1.0, distance_rad) * np.maximum(speed, 0.0)


def _half_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """One half of the convex hull of ``points`` sorted along x (Andrew's monotone chain)."""
    chain: list[tuple[float, float]] = []
    for q in points:
        while len(chain) >= 2 and ((chain[-1][0] - chain[-2][0]) * (q[1] - chain[-2][1])
                                   - (chain[-1][1] - chain[-2][1]) * (q[0] - chain[-2][0])
                                   ) <= 0:
            chain.pop()
        chain.append(q)
    return chain


def hull_margin_m(points_xy: np.ndarray, p_xy: np.ndarray) -> float:
    """How far ``p_xy`` lies inside the convex hull of ``points_xy`` (m; < 0 outside: the
    distance to the most violated edge's line)."""
    pts = sorted(map(tuple, points_xy))
    hull = _half_hull(pts)[:-1] + _half_hull(pts[::-1])[:-1]  # counter-clockwise
    margins = []
    for a, b in zip(hull, hull[1:] + hull[:1], strict=True):
        edge = np.subtract(b, a)
        inward = np.array((-edge[1], edge[0])) / np.linalg.norm(edge)
        margins.append(float(inward @ (p_xy - np.asarray(a))))
    return min(margins)


def roll_map(model, c, k: int, stance: str, axis: np.ndarray) -> tuple[np.ndarray, float]:
    """Each joint's column of the centroidal angular momentum about ``axis`` (the stance
    sole's forward axis) with the stance sole held on the floor, at row ``k``'s posture (as
    side_push_bound.py's), and the robot's mass (kg)."""
    names = list(model.joint_names)
    robot = load_pin_robot(model, floating=True)
    pm = robot.model
    data = pm.createData()
    q = np.array([float(c[f"q_{n}_rad"][k]) for n in names])
    qp = robot.configuration(q, T_world_neck_at(c, k))
    A = pin.computeCentroidalMap(pm, data, qp)
    pin.computeJointJacobians(pm, data, qp)
    pin.framesForwardKinematics(pm, data, qp)
    sole = pm.getFrameId(f"{leg_names(model)[stance][-1]}_link")
    J = pin.getFrameJacobian(pm, data, sole, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    v_index = [pm.joints[pm.getJointId(n)].idx_v for n in names]
    base_of_joint = -np.linalg.solve(J[:, :6], J[:, v_index])
    return axis @ (A[3:, v_index] + A[3:, :6] @ base_of_joint), float(pin.computeTotalMass(pm))


def leg_momentum_cp_m(A_swing: np.ndarray, mass: float, distance_rad: np.ndarray,
                      velocity: np.ndarray, acceleration: np.ndarray, horizon_s: float,
                      omega: float, outward: float) -> float:
    """How far the swing leg's own motion (each joint on its time-optimal profile over
    ``distance_rad``, columns ``A_swing`` of :func:`roll_map`) moves the capture point
    toward the fall (``outward``) by ``horizon_s`` later (m): with the ZMP held on the
    stance sole's outer edge, cmp_y = zmp_y - dL_x/dt / (m g), and L zero at both ends, the
    capture point moves by (omega^2 / (m g)) integral e^(omega (T - u)) L(u) du."""
    du = 1e-3
    u = np.arange(0.0, horizon_s, du)
    L = np.zeros_like(u)
    for n in range(len(A_swing)):
        L += A_swing[n] * profile_speed(float(distance_rad[n]), float(velocity[n]),
                                        float(acceleration[n]), u)
    return outward * omega ** 2 / (mass * GRAVITY_M_S2) * float(
        np.sum(np.exp(omega * (horizon_s - u)) * L) * du)


def edge_frame(columns, legs, names_of, stance: str, k: int) -> np.ndarray:
    """The stance sole's pose at row ``k`` (world; from the measured leg under the logged
    torso)."""
    q = np.array([float(columns[f"q_{j}_rad"][k]) for j in names_of[stance]])
    return T_world_neck_at(columns, k) @ legs[stance].fk(q)


def analyse(model, walking, checker, run_dir: Path, at_s: float, direction: str,
            decision: str = "first") -> dict | str:
    """The earliest landings of one pushed run, or why there are none for it."""
    log = load_log(run_dir / "log.parquet")
    c = log.columns
    names_of = leg_names(model)
    names = list(model.joint_names)
    t = np.asarray(c["t_s"], dtype=float)
    k0 = int(np.searchsorted(t, at_s))
    planned = [float(c[f"planned_{side}_foot_contact_flag"][k0]) for side in SIDES]
    push_y = PUSH_DIRECTIONS[direction][1]
    if sum(planned) != 1 or push_y == 0:
        return "not in single support, or not pushed sideways"
    stance = SIDES[planned.index(1.0)]
    swing = SIDES[1 - SIDES.index(stance)]
    outward = 1.0 if stance == "left" else -1.0
    if push_y * outward <= 0:
        return "pushed toward the swing foot"
    legs = {side: Limb(model, f"{side}-leg") for side in SIDES}
    corners = model.feet.sole_corners_m()
    half_width = model.feet.width_m / 2
    ran = np.flatnonzero(np.isfinite(np.asarray(c["walk.tilt_deg"], dtype=float)))
    k_end = int(ran[-1])

    def past_edge(k: int) -> float:
        T = edge_frame(c, legs, names_of, stance, k)
        edge = outward * ((T[:3, :3] @ corners.T).T + T[:3, 3])[:, 1]
        return float(outward * float(c["cp_y_m"][k]) - edge.max())

    error = outward * np.asarray(c["walk.cp_error_y_m"], dtype=float)
    watch = next((k for k in range(k0, k_end) if error[k] > TRIGGER_M), None)
    k_watch = None if watch is None else watch + round(DECIDE_S / model.control_period_s)
    k_out = next((k for k in range(k0 + 1, k_end) if past_edge(k) > 0.0
                  and past_edge(k) > past_edge(k - 1)), None)
    candidates = [k for k, name in ((k_watch, "watch"), (k_out, "edge"))
                  if k is not None and decision in (name, "first")]
    if not candidates:
        return "no decision: the error never passed the trigger and the capture point stayed in"
    k_decide = min(candidates)
    swing_index = [names.index(j) for j in names_of[swing]]
    stance_index = [names.index(j) for j in names_of[stance]]
    q_decide = np.array([float(c[f"q_{n}_rad"][k_decide]) for n in names])
    velocity = walking.velocity_rad_s[swing_index]
    A_all, mass = roll_map(model, c, k_decide, stance,
                           edge_frame(c, legs, names_of, stance, k_decide)[:3, 0])
    A_swing = A_all[swing_index]
    omega = math.sqrt(GRAVITY_M_S2 / float(c["est_com_z_m"][k_decide]))
    acceleration = walking.acceleration_rad_s2[swing_index]
    T_floor = edge_frame(c, legs, names_of, stance, k0)  # the stance sole flat, at the push
    yaw0 = math.atan2(T_floor[1, 0], T_floor[0, 0])
    R_floor = rpy_to_matrix(0.0, 0.0, yaw0)
    grid, reach = [], []
    for x in CROSS_X_M:
        for y in CROSS_Y_M:
            for yaw in CROSS_YAW_RAD:
                T = np.eye(4)
                T[:3, :3] = R_floor @ rpy_to_matrix(0.0, 0.0, float(yaw))
                local = R_floor @ np.array((x, outward * (half_width + y), 0.0))
                T[:3, 3] = T_floor[:3, 3] + local
                grid.append(T)
                R = rpy_to_matrix(0.0, 0.0, float(yaw))
                reach.append(float(np.max(outward * ((R @ corners.T).T[:, 1]
                                                     + outward * (half_width + y))) - half_width))
    grid = np.array(grid)
    reach = np.array(reach)
    step = max(1, round(TIME_STEP_S / model.control_period_s))
    rows = []
    for k in range(k_decide, k_end + 1, step):
        T_world_neck = T_world_neck_at(c, k)
        solved = legs[swing].solve_batch(np.linalg.inv(T_world_neck) @ grid, allow_cap=False)
        exact = np.flatnonzero(solved.status == choice.STATUS_NAMES.index("exact"))
        q_k = np.array([float(c[f"q_{n}_rad"][k]) for n in names])
        in_time, clear, least_s = [], 0, math.inf
        T_stance = edge_frame(c, legs, names_of, stance, k)
        stance_xy = ((T_stance[:3, :3] @ corners.T).T + T_stance[:3, 3])[:, :2]
        cp = np.array((float(c["cp_x_m"][k]), float(c["cp_y_m"][k])))
        inside_s = math.inf  # the least joint time to a clear landing with the capture point
        for i in exact:
            q_landed = q_k.copy()
            q_landed[swing_index] = solved.q_rad[i]
            if checker.check(q_landed).distance_m <= 0.0:
                continue
            clear += 1
            landing_xy = ((grid[i][:3, :3] @ corners.T).T + grid[i][:3, 3])[:, :2]
            need_s = travel_time_s(solved.q_rad[i] - q_decide[swing_index], velocity,
                                   acceleration)
            least_s = min(least_s, need_s)
            if need_s < inside_s and hull_margin_m(np.vstack((stance_xy, landing_xy)), cp) >= 0:
                inside_s = need_s  # (inside the two soles' hull, in time or not)
            if need_s <= t[k] - t[k_decide] + 1e-9:
                in_time.append(i)
        row = {"t_s": t[k] - at_s, "reached": len(exact), "clear": clear,
               "in_time": len(in_time), "least_s": least_s,
               "inside_s": inside_s, "past_mm": 1000 * past_edge(k),
               "tilt_deg": float(c["walk.tilt_deg"][k]),
               "cp_x_m": float(R_floor[:2, 0] @ (np.array((float(c["cp_x_m"][k]),
                                                           float(c["cp_y_m"][k])))
                                                 - T_floor[:2, 3])),
               "com_z_m": float(c["est_com_z_m"][k]),
               "com_to_cp_mm": 1000 * outward * (float(c["cp_y_m"][k])
                                                 - float(c["est_com_y_m"][k]))}
        if in_time:
            scored = []
            for i in in_time:
                distance = solved.q_rad[i] - q_decide[swing_index]
                own = leg_momentum_cp_m(A_swing, mass, distance, velocity, acceleration,
                                        t[k] - t[k_decide], omega, outward)
                landing_xy = ((grid[i][:3, :3] @ corners.T).T + grid[i][:3, 3])[:, :2]
                points = np.vstack((stance_xy, landing_xy))
                scored.append((hull_margin_m(points, cp),
                               hull_margin_m(points, cp + np.array((0.0, outward * own))),
                               own, i))
            margin_still, margin, own, i = max(scored)
            need_s = travel_time_s(solved.q_rad[i] - q_decide[swing_index], velocity,
                                   acceleration)
            best_reach = reach[i]
            q_path = q_decide.copy()
            path_clear = True
            for s in np.linspace(0.0, 1.0, PATH_SAMPLES):
                q_path[swing_index] = ((1 - s) * q_decide[swing_index]
                                       + s * solved.q_rad[i])
                q_path[stance_index] = q_k[stance_index]
                path_clear &= checker.check(q_path).distance_m > 0.0
            T = grid[i]
            local = R_floor.T @ (T[:3, 3] - T_floor[:3, 3])
            row.update(margin_mm=1000 * margin_still, margin_own_mm=1000 * margin,
                       own_mm=1000 * own, reach_mm=1000 * best_reach, x_m=float(local[0]),
                       out_m=outward * float(local[1]) - half_width,
                       yaw_rad=math.atan2(T[1, 0], T[0, 0]) - yaw0, need_s=need_s,
                       path_clear=bool(path_clear))
        rows.append(row)
    return {"stance": stance, "decide_s": t[k_decide] - at_s,
            "watch_s": None if k_watch is None else t[k_watch] - at_s,
            "out_s": None if k_out is None else t[k_out] - at_s,
            "end_s": t[k_end] - at_s, "fell_tilt": float(c["walk.tilt_deg"][k_end]),
            "rows": rows}


def summary(rows: list[dict], decide_s: float) -> str:
    """The first landing in time with the capture point inside the two soles' hull, and the
    torso's tilt if the body then came to rest with its CoM over that capture point (its roll
    about the stance sole's edge growing by the CoM's distance to it over the CoM's height);
    or the nearest any landing in time came."""
    rest = [row for row in rows if math.isfinite(row["inside_s"]) and row["t_s"] > decide_s
            and row["tilt_deg"] + math.degrees(row["com_to_cp_mm"] / 1000 / row["com_z_m"])
            < FALL_TILT_DEG]
    if rest:
        fast = min(rest, key=lambda row: row["inside_s"] / (row["t_s"] - decide_s))
        ignoring = (f"; to land with the capture point inside and at rest under the criterion "
                    f"the swing leg would need {fast['inside_s'] / (fast['t_s'] - decide_s):.2f}"
                    f" times the walking set's speeds (landing +{fast['t_s']:.3f} s)")
    else:
        ignoring = "; no landing puts it inside with the body at rest under the criterion"
    timely = [row for row in rows if row["in_time"]]
    if not timely:
        return "summary: no clear crossing landing in time before the log's end" + ignoring
    inside = next((row for row in timely if row["margin_mm"] >= 0.0), None)
    if inside is None:
        best = max(timely, key=lambda row: row["margin_mm"])
        return (f"summary: the capture point never inside the hull of a landing in time; "
                f"nearest {best['margin_mm']:+.0f} mm at +{best['t_s']:.3f} s (tilt "
                f"{best['tilt_deg']:.1f} deg)" + ignoring)
    at_rest = inside["tilt_deg"] + math.degrees(inside["com_to_cp_mm"] / 1000
                                                / inside["com_z_m"])
    return (f"summary: first inside at +{inside['t_s']:.3f} s ({inside['margin_mm']:+.0f} mm),"
            f" tilt {inside['tilt_deg']:.1f} deg, the CoM {inside['com_to_cp_mm']:.0f} mm "
            f"short of the capture point: at rest over it about {at_rest:.1f} deg" + ignoring)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="/tmp/walk_disturbances",
                        help="walk_disturbances.py push's --out")
    parser.add_argument("--seeds", default="6,10,18")
    parser.add_argument("--distance", type=float, default=1.0)
    parser.add_argument("--directions", default="left,right,backward")
    parser.add_argument("--decision", choices=("first", "watch", "edge"), default="first",
                        help="the decision: the momentum strategy's watch, the capture point "
                        "past the edge and heading out, or the first of the two")
    args = parser.parse_args()
    model = load_model()
    walking = load_model(model.params_name, "walking")
    leg_links = {side: [f"{j}_link" for j in leg_names(model)[side]] for side in SIDES}
    checker = SelfCollisionChecker(model, pairs=[(a, b) for a in leg_links["right"]
                                                 for b in leg_links["left"]])
    for seed in seeds_of(args.seeds):
        at_s, direction = draw(model, seed, args.distance, args.directions.split(","))
        run_dir = Path(args.runs) / f"push-{seed}"
        if not (run_dir / "log.parquet").exists():
            print(f"seed {seed}: no run in {run_dir}")
            continue
        r = analyse(model, walking, checker, run_dir, at_s, direction, args.decision)
        if isinstance(r, str):
            print(f"seed {seed}: pushed {direction} at {at_s:.3f} s: {r}")
            continue
        print(f"seed {seed}: pushed {direction} at {at_s:.3f} s toward the {r['stance']} "
              f"(stance) foot; decided +{r['decide_s']:.3f} s (the watch's "
              f"{r['watch_s']}, out past the edge {r['out_s']}); the log ends +{r['end_s']:.3f}"
              f" s at {r['fell_tilt']:.1f} deg (criterion {FALL_TILT_DEG:.0f})")
        for row in r["rows"]:
            line = (f"  +{row['t_s']:.3f} s: {row['reached']} reached, {row['clear']} clear, "
                    f"{row['in_time']} in time (the least joint time to a clear one "
                    f"{row['least_s']:.3f} s, {row['t_s'] - r['decide_s']:.3f} s since the "
                    f"decision); capture point {row['past_mm']:+.0f} mm past the edge and "
                    f"{row['cp_x_m']:+.2f} m ahead of the stance ankle, tilt "
                    f"{row['tilt_deg']:.1f} deg; the least joint time to a clear landing "
                    f"with it inside {row['inside_s']:.3f} s")
            if row["in_time"]:
                line += (f"; the best in time: the capture point {row['margin_mm']:+.0f} mm "
                         f"inside the two soles' hull ({row['margin_own_mm']:+.0f} mm with "
                         f"the swing leg's own momentum, {row['own_mm']:+.0f} mm outward); "
                         f"it reaches {row['reach_mm']:.0f} mm (x {row['x_m']:+.2f} m, its centre "
                         f"{row['out_m']:.2f} m beyond the edge, turned "
                         f"{row['yaw_rad']:+.2f} rad, joints {row['need_s']:.3f} s, straight "
                         f"path {'clear' if row['path_clear'] else 'through the stance leg'})")
            print(line)
        print("  " + summary(r["rows"], r["decide_s"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
