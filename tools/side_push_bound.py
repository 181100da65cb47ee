"""How far joint motion within the limits could move the capture point of a walk pushed
toward its stance foot (issue 37's pushes mid-walk), against how far it went past that sole.

    python tools/side_push_bound.py --runs /tmp/walk_disturbances --seeds 6,10,18

Reads the runs of ``tools/walk_disturbances.py push`` (the same seeds, distance and
directions: the push's moment and direction are drawn again). For each push that comes in a
single support toward the stance foot it prints, from the run's log:

* the capture point (the estimate's, as the capture-point monitor has it) past the stance
  sole's outer edge (the sole from the measured legs under the simulator's torso) at the
  push's end, and when it crossed that edge;
* **a crossing step**: the swing sole, flat on the floor, with a corner beyond that edge,
  from the pelvis where the push's end has it (the stance leg cannot move it far in the time
  left), over a grid of places and turns: how many the swing leg reaches within Table IV (its
  closed-form IK, exact);
* **the angular-momentum bound**: with the ZMP on the outer edge (all the ankle can give),
  only the centroidal angular momentum's rate moves the centroidal moment pivot (CMP) beyond
  it: cmp_y = zmp_y - dL_x/dt / (m g). Joint motion started at the push's start moves the
  capture point at the push's end back by at most

      (omega^2 / (m g)) e^(omega T) sum_j |A_j| integral_0^inf qdot_j(u) e^(-omega u) du,

  where A_j is joint j's column of the centroidal map about the edge's axis with the stance
  sole held on the floor (pinocchio, at the push's end's posture), T the push's 0.2 s, and
  each joint moves toward its helpful side as fast as the walking limit set lets it
  (velocity, acceleration) over the range it has left (a bound: braking, the map's change
  with the posture and the joints' coupling are left out, each in the bound's favour).

* **a tighter bound**, in steps: (1) each joint from the push's detection on (the logged
  capture point's error toward the outer side past DETECT_M), braked at the walking set's
  acceleration to stop at its range's end; (2) that range also within the links' clearance
  (every pair the collision detector checks, TOLERANCE_M apart) and, for a joint that rolls
  the torso toward the fall, the torso's tilt left before the fall criterion; (3) the stance
  sole free to roll about its outer edge, as it is with the ZMP held on that edge: joint
  motion keeps the momentum about the edge (the pivot's row of the mass matrix), the body
  turning about the edge against it, and only the centroidal momentum left counts. Still a
  bound: the stance sole's load (which the hips' accelerations take away), the map's change
  along the motion and the body's roll after the push are left out.

The robot is caught by joint motion alone only if the bound exceeds the capture point's
distance past the edge. Measured numbers go in docs/history/walking.md, not here.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from walk_disturbances import draw, seeds_of

from hubo_cli.control.collision import TOLERANCE_M, SelfCollisionChecker
from hubo_cli.control.log import load_log
from hubo_cli.experiments.standing import PUSH_DIRECTIONS
from hubo_cli.experiments.walk import PUSH_S
from hubo_cli.falls import FALL_TILT_DEG
from hubo_cli.geometry import rpy_to_matrix
from hubo_cli.kinematics import choice
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import load_model
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.state import GRAVITY_M_S2

SIDES = ("right", "left")
CROSS_X_M = np.arange(-0.40, 0.401, 0.02)    # the crossing grid, in the stance sole's frame
CROSS_Y_M = np.arange(0.0, 0.301, 0.02)      # (outward from its outer edge: the sole's
CROSS_YAW_RAD = np.arange(-1.8, 1.801, 0.1)  # centre this far beyond it)
DETECT_M = 0.025  # the capture point's error from the pattern's toward the stance sole's outer
                  # side that a controller acting on the estimate could take for such a push
                  # (unpushed 1 m walks: at most 12.8 mm, docs/history/walking.md, round 10)
COLLISION_STEP_RAD = 0.01  # the collision room is searched in steps of this much


def best_travel_integral(range_rad: float, velocity: float, acceleration: float,
                         omega: float) -> float:
    """max of integral_0^inf qdot(u) e^(-omega u) du over 0 <= qdot <= velocity,
    |qddot| <= acceleration, integral qdot <= range (rad s): as fast as allowed, as early as
    allowed, not braked."""
    if range_rad <= 0:
        return 0.0
    du = 1e-4
    u = np.arange(0.0, 5.0, du)
    qdot = np.minimum(acceleration * u, velocity)
    travelled = np.cumsum(qdot) * du
    qdot = np.where(travelled <= range_rad, qdot, 0.0)
    return float(np.sum(qdot * np.exp(-omega * u)) * du)


def braked_travel_integral(range_rad: float, velocity: float, acceleration: float,
                           omega: float) -> float:
    """integral_0^inf qdot(u) e^(-omega u) du of the time-optimal motion over ``range_rad``
    that stops at its end: accelerate at once, run at ``velocity``, brake at
    ``acceleration`` as late as lets it stop there (rad s)."""
    if range_rad <= 0:
        return 0.0
    peak = min(velocity, math.sqrt(acceleration * range_rad))
    ramp_s = peak / acceleration
    coast_s = (range_rad - peak * ramp_s) / peak
    du = 1e-4
    u = np.arange(0.0, 2 * ramp_s + coast_s, du)
    qdot = np.minimum.reduce([acceleration * u, np.full_like(u, peak),
                              acceleration * (2 * ramp_s + coast_s - u)])
    return float(np.sum(np.maximum(qdot, 0.0) * np.exp(-omega * u)) * du)


def collision_room(checker, q: np.ndarray, j: int, sign: float, room: float) -> float:
    """How far joint ``j`` turns from ``q`` toward ``sign`` within ``room`` (rad) with every
    checked pair of links at least TOLERANCE_M apart (the collision detector's band)."""
    turned = 0.0
    while turned + COLLISION_STEP_RAD <= room:
        q_turned = q.copy()
        q_turned[j] += sign * (turned + COLLISION_STEP_RAD)
        if checker.check(q_turned).distance_m < TOLERANCE_M:
            break
        turned += COLLISION_STEP_RAD
    return turned if turned + COLLISION_STEP_RAD <= room else room


def T_world_neck_at(columns, k: int) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(*(float(columns[f"torso_{a}_rad"][k]) for a in ("roll", "pitch",
                                                                           "yaw")))
    T[:3, 3] = [float(columns[f"torso_{a}_m"][k]) for a in "xyz"]
    return T


def leg_names(model) -> dict[str, tuple[str, ...]]:
    """Each leg's joint names, hip yaw to ankle roll (the model's own order)."""
    return {side: tuple(model.joint_names[model.limb_slice(f"{side}-leg")]) for side in SIDES}


def analyse(model, walking, checker, body_checker, run_dir: Path, at_s: float,
            direction: str) -> dict | str:
    """The bounds of one pushed run, or why there are none for it."""
    log = load_log(run_dir / "log.parquet")
    names_of = leg_names(model)
    c = log.columns
    t = np.asarray(c["t_s"], dtype=float)
    k0 = int(np.searchsorted(t, at_s))
    k1 = int(np.searchsorted(t, at_s + PUSH_S))
    if k1 >= len(t):
        return f"its log ends at {t[-1]:.3f} s, before the push's end"
    planned = [float(c[f"planned_{side}_foot_contact_flag"][k0]) for side in SIDES]
    push_y = PUSH_DIRECTIONS[direction][1]
    if sum(planned) != 1 or push_y == 0:
        return "not in single support, or not pushed sideways"
    stance = SIDES[planned.index(1.0)]
    outward = 1.0 if stance == "left" else -1.0
    if push_y * outward <= 0:
        return "pushed toward the swing foot"
    swing = SIDES[1 - SIDES.index(stance)]
    names = list(model.joint_names)
    q = np.array([float(c[f"q_{n}_rad"][k1]) for n in names])
    T_world_neck = T_world_neck_at(c, k1)
    legs = {side: Limb(model, f"{side}-leg") for side in SIDES}
    leg_q = {side: q[[names.index(j) for j in names_of[side]]] for side in SIDES}
    T_world_stance = T_world_neck @ legs[stance].fk(leg_q[stance])
    corners = model.feet.sole_corners_m()

    def past_edge(k: int) -> float:
        T = T_world_neck_at(c, k) @ legs[stance].fk(
            np.array([float(c[f"q_{j}_rad"][k]) for j in names_of[stance]]))
        edge = outward * ((T[:3, :3] @ corners.T).T + T[:3, 3])[:, 1]
        return float(outward * float(c["cp_y_m"][k]) - edge.max())

    past = [past_edge(k) for k in range(k0, min(k1 + 40, len(t)))]
    crossed = next((i for i, d in enumerate(past) if d > 0), None)
    omega = math.sqrt(GRAVITY_M_S2 / float(c["est_com_z_m"][k1]))
    # the crossing step: the swing sole flat on the floor beyond the stance sole's outer edge
    half_width = model.feet.width_m / 2
    grid = []
    for x in CROSS_X_M:
        for y in CROSS_Y_M:
            for yaw in CROSS_YAW_RAD:
                T = np.eye(4)
                T[:3, :3] = rpy_to_matrix(0.0, 0.0, float(yaw))
                T[:3, 3] = [x, outward * (half_width + y), 0.0]
                grid.append(T)
    T_neck_stance = np.linalg.inv(T_world_neck) @ T_world_stance
    T_neck_goals = T_neck_stance @ np.array(grid)
    solved = legs[swing].solve_batch(T_neck_goals, allow_cap=False)
    exact = np.flatnonzero(solved.status == choice.STATUS_NAMES.index("exact"))
    swing_index = [names.index(j) for j in names_of[swing]]
    q_start = np.array([float(c[f"q_{n}_rad"][k0]) for n in names])
    swing_velocity = walking.velocity_rad_s[swing_index]
    landings = []
    for i in exact:  # the legs' links apart (the URDF's collision shapes)
        q_landed = q.copy()
        q_landed[swing_index] = solved.q_rad[i]
        if checker.check(q_landed).distance_m <= 0.0:
            continue
        T = grid[i]
        reach = float(np.max(outward * ((T[:3, :3] @ corners.T).T + T[:3, 3])[:, 1])
                      - half_width)  # its outermost corner beyond the stance sole's edge
        # the least time the swing leg's joints need to get there at the walking limit set's
        # velocities from where they stood at the push's start (no reaction time, no
        # acceleration, no way around the stance leg: a lower bound)
        travel_s = float(np.max(np.abs(solved.q_rad[i] - q_start[swing_index])
                                / swing_velocity))
        k = min(k0 + math.ceil(travel_s / model.control_period_s), len(t) - 1)
        lip = past[k1 - k0] * math.exp(omega * max(travel_s - PUSH_S, 0.0))
        landings.append((travel_s, reach, past_edge(k) if t[k] - at_s >= travel_s - 1e-9
                         else math.nan, lip, float(c["walk.tilt_deg"][k]),
                         float(T[0, 3]), math.atan2(T[1, 0], T[0, 0])))
    # the angular-momentum bound
    robot = load_pin_robot(model, floating=True)
    pm = robot.model
    data = pm.createData()
    qp = robot.configuration(q, T_world_neck)
    A = pin.computeCentroidalMap(pm, data, qp)  # 6 x nv, [linear; angular] at the CoM
    pin.computeJointJacobians(pm, data, qp)
    pin.framesForwardKinematics(pm, data, qp)
    sole = pm.getFrameId(f"{names_of[stance][-1]}_link")
    J = pin.getFrameJacobian(pm, data, sole, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    axis = T_world_stance[:3, 0]  # the stance sole's forward axis: its outer edge's direction
    v_index = [pm.joints[pm.getJointId(n)].idx_v for n in names]
    # base twist from joint rates with the stance sole held: J_base v_base + J_joints qdot = 0
    base_of_joint = -np.linalg.solve(J[:, :6], J[:, v_index])
    A_eff = axis @ (A[3:, v_index] + A[3:, :6] @ base_of_joint)
    mass = float(pin.computeTotalMass(pm))
    lower, upper = walking.lower_rad, walking.upper_rad
    velocity, acceleration = walking.velocity_rad_s, walking.acceleration_rad_s2
    # helpful: dL/dt along the axis of sign -outward (cmp_y = zmp_y - dL_x/dt / (m g))
    per_joint = []
    for j, name in enumerate(names):
        sign = -outward * np.sign(A_eff[j])  # the joint's helpful direction
        room = (upper[j] - q[j]) if sign > 0 else (q[j] - lower[j])
        integral = best_travel_integral(float(room), float(velocity[j]),
                                        float(acceleration[j]), omega)
        per_joint.append((abs(A_eff[j]) * integral, name, float(room), float(A_eff[j])))
    scale = omega ** 2 / (mass * GRAVITY_M_S2) * math.exp(omega * PUSH_S)
    bound = scale * sum(p[0] for p in per_joint)
    top = sorted(per_joint, reverse=True)[:4]
    # the tighter bound, in steps: (1) from the push's detection on, each joint braked to stop
    # at its range's end; (2) that range also within the links' clearance (the collision
    # detector's band) and the torso's tilt left before the fall criterion; (3) the stance
    # sole free to roll about its outer edge, as it is with the ZMP held on that edge: joint
    # motion then keeps the angular momentum about the edge (gravity and the push aside, as
    # over an instant), the body turning about the edge against it
    error = outward * np.asarray(c["walk.cp_error_y_m"], dtype=float)[k0:k1 + 1]
    detected = next((i for i, e in enumerate(error) if e > DETECT_M), None)
    if detected is None:
        return f"its capture point's error never passed {1000 * DETECT_M:.0f} mm in the push"
    detect_s = float(t[k0 + detected] - at_s)
    scale_detected = scale * math.exp(-omega * detect_s)
    M = pin.crba(pm, data, qp)
    M = np.triu(M) + np.triu(M, 1).T
    p_sole = data.oMf[sole].translation
    half_width = model.feet.width_m / 2
    edge = T_world_stance[:3, :3] @ np.array((0.0, outward * half_width, 0.0)) \
        + T_world_stance[:3, 3]
    pivot_twist = np.concatenate((np.cross(axis, p_sole - edge), axis))  # LWA, unit rate
    v_pivot = np.zeros(pm.nv)
    v_pivot[:6] = np.linalg.solve(J[:, :6], pivot_twist)
    base_rotation = data.oMi[1].rotation  # the base's velocity is in its own frame
    tilt_deg = float(c["walk.tilt_deg"][k1])
    tilt_room_rad = math.radians(FALL_TILT_DEG - tilt_deg)
    staged = {"braked": 0.0, "ranged": 0.0, "pivot": 0.0}
    per_joint_tight = []
    for j, name in enumerate(names):
        v_joint = np.zeros(pm.nv)
        v_joint[:6] = base_of_joint[:, j]
        v_joint[v_index[j]] = 1.0
        rate = -float(v_pivot @ M @ v_joint) / float(v_pivot @ M @ v_pivot)  # the pivot's
        v_free = v_joint + rate * v_pivot                                   # turn per rad/s
        a_pivot = float(axis @ A[3:] @ v_free)
        for stage, column in (("braked", A_eff[j]), ("ranged", A_eff[j]), ("pivot", a_pivot)):
            sign = -outward * np.sign(column)
            room = float((upper[j] - q[j]) if sign > 0 else (q[j] - lower[j]))
            if stage != "braked":
                room = collision_room(body_checker, q, j, sign, room)
                torso_turn = float(axis @ base_rotation @ (v_joint if stage == "ranged"
                                                           else v_free)[3:6])
                if sign * torso_turn * outward < 0 and abs(torso_turn) > 1e-9:
                    # (it rolls the torso toward the fall: > 0 about the axis rolls the left
                    # side up, the fall toward the left stance foot)
                    room = min(room, max(tilt_room_rad, 0.0) / abs(torso_turn))
            integral = braked_travel_integral(room, float(velocity[j]),
                                              float(acceleration[j]), omega)
            staged[stage] += abs(column) * integral
            if stage == "pivot":
                per_joint_tight.append((abs(column) * integral, name, room, column))
    top_tight = sorted(per_joint_tight, reverse=True)[:4]
    return {"stance": stance, "past_edge_at_end_mm": 1000 * past_edge(k1),
            "crossed_after_s": None if crossed is None else round(t[k0 + crossed] - at_s, 3),
            "omega": omega, "crossing_reached": len(exact), "crossing_tried": len(grid),
            "landings": sorted(landings),
            "bound_mm": 1000 * bound,
            "top": [(n, round(1000 * scale * v, 2), round(room, 3), round(a, 3))
                    for v, n, room, a in top],
            "detect_s": detect_s, "tilt_deg": tilt_deg,
            "tight_mm": {k: 1000 * scale_detected * v for k, v in staged.items()},
            "top_tight": [(n, round(1000 * scale_detected * v, 2), round(room, 3))
                          for v, n, room, _ in top_tight]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="/tmp/walk_disturbances",
                        help="walk_disturbances.py push's --out")
    parser.add_argument("--seeds", default="1-20")
    parser.add_argument("--distance", type=float, default=1.0)
    parser.add_argument("--directions", default="left,right,backward")
    args = parser.parse_args()
    model = load_model()
    walking = load_model(model.params_name, "walking")
    leg_links = {side: [f"{j}_link" for j in leg_names(model)[side]] for side in SIDES}
    checker = SelfCollisionChecker(model, pairs=[(a, b) for a in leg_links["right"]
                                                 for b in leg_links["left"]])
    body_checker = SelfCollisionChecker(model)  # every pair the collision detector checks
    for seed in seeds_of(args.seeds):
        at_s, direction = draw(model, seed, args.distance, args.directions.split(","))
        run_dir = Path(args.runs) / f"push-{seed}"
        if not (run_dir / "log.parquet").exists():
            print(f"seed {seed}: no run in {run_dir}")
            continue
        result = analyse(model, walking, checker, body_checker, run_dir, at_s, direction)
        if isinstance(result, str):
            print(f"seed {seed}: pushed {direction} at {at_s:.3f} s: {result}")
            continue
        r = result
        print(f"seed {seed}: pushed {direction} at {at_s:.3f} s toward the {r['stance']} "
              f"(stance) foot: the capture point {r['past_edge_at_end_mm']:+.1f} mm past "
              f"its outer edge at the push's end (crossed it {r['crossed_after_s']} s after "
              f"the push's start; omega {r['omega']:.2f} /s)")
        print(f"  crossing step: {r['crossing_reached']} of {r['crossing_tried']} swing-sole "
              f"places beyond the edge reached within Table IV, {len(r['landings'])} with the "
              "legs apart")
        for travel_s, reach, past_mm, lip, tilt, x, yaw in r["landings"]:
            measured = "(the run had ended)" if math.isnan(past_mm) else f"{1000 * past_mm:.0f} mm"
            print(f"    x {x:+.2f} m, turned {yaw:+.2f} rad: reaches {1000 * reach:.0f} mm "
                  f"beyond the edge; joints there in {travel_s:.2f} s at the least; the "
                  f"capture point past the edge then: {measured} (the run), {1000 * lip:.0f} "
                  f"mm (LIP from the push's end); torso tilt then {tilt:.1f} deg")
        print(f"  joint momentum: at most {r['bound_mm']:.1f} mm back at the push's end; the "
              "largest: " + ", ".join(f"{n} {v} mm ({room} rad of room)"
                                      for n, v, room, _ in r["top"]))
        tight = r["tight_mm"]
        print(f"  tighter: from the push's detection ({1000 * r['detect_s']:.0f} ms after its "
              f"start) and braked to stop {tight['braked']:.1f} mm; within the links' "
              f"clearance and the torso's tilt ({r['tilt_deg']:.1f} deg at the push's end) "
              f"{tight['ranged']:.1f} mm; the stance sole free to roll about its outer edge "
              f"{tight['pivot']:.1f} mm; the largest then: "
              + ", ".join(f"{n} {v} mm ({room} rad)" for n, v, room in r["top_tight"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
