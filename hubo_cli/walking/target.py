"""The walking target: plans the walk from where the feet stand when the robot has started,
then sends the pattern's joints one period at a time and measures what the robot did."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba as nb
import numpy as np

from hubo_cli.balance_report import CONTACT_CUTOFF_HZ, CONTACT_THRESHOLD_N
from hubo_cli.control.capture_point import CapturePointMonitor, convex_hull, outside_distance
from hubo_cli.control.target import Target, TargetOutput
from hubo_cli.dataflow import Store
from hubo_cli.drivers.base import SimulatedWorld
from hubo_cli.errors import ConfigError
from hubo_cli.falls import has_fallen
from hubo_cli.kinematics.choice import CAPPED, EXACT, solve_limb
from hubo_cli.kinematics.dh import JIT, TRUE, chain_fk
from hubo_cli.model import RobotModel
from hubo_cli.state import RobotState
from hubo_cli.walking.body import SIDE_LEG, JointPlan, WalkingBody, pose_of_row
from hubo_cli.walking.footsteps import (
    Footstep,
    Stance,
    closing_steps,
    plan_footsteps,
    stance_of,
)
from hubo_cli.walking.gait import Gait, make_gait
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.stabilizer import SoleDamper, StabilizerGains, TorsoOffset, Touchdown

ARRIVED_M = 0.008                  # closer than this to the goal stance needs no correction
ARRIVED_RAD = math.radians(1.5)
ZMP_INSIDE_MARGIN_M = 0.001  # a ZMP closer than this to the hull's edge counts as on it (a sole
                             # tipping about that edge: the physics keeps the ZMP on the hull)
LOADED_N = 10.0  # a sole carrying more than this counts in the measured ZMP and the support
LEG_STEP_RAD = 0.005  # the stabilizer's correction of a leg's joints (torso offset, touchdown
                     # hold) changes by at most this much a period: an IK solution further from
                     # the last one (another branch, or off the goal) keeps the last correction
LEG_CAPPED_M = 1e-4  # an IK solution capped to the joint limits this close to the sole's goal
LEG_CAPPED_RAD = 1e-3  # reaches it: each hip yaw stands at its limit, 0, while the feet point
                       # ahead, and feet toed in by microradians (as the simulator reads them
                       # after a few steps) cap it; taking only exact solutions, the correction
                       # stayed zero from the first capped period on while the offset grew
SOLES = (("right", "right_sole", "right-ankle"), ("left", "left_sole", "left-ankle"))
SOLES_SENSOR = {side: sensor for side, _, sensor in SOLES}


def footstep_of(side: str, T_world_sole: np.ndarray) -> Footstep:
    """The footstep a sole's world pose (4x4) stands on."""
    return Footstep(side, float(T_world_sole[0, 3]), float(T_world_sole[1, 3]),
                    math.atan2(T_world_sole[1, 0], T_world_sole[0, 0]))


def measured_zmp(poses: np.ndarray, wrenches: np.ndarray, corners_m: np.ndarray,
                 loaded_n: float = LOADED_N) -> tuple[np.ndarray | None, float]:
    """The ZMP from the ankles' force/torque (world x, y; None when no sole is loaded) and how
    far it lies outside the loaded soles' convex hull (m; <= 0 inside). A sole is loaded when
    its F_z exceeds ``loaded_n`` (N).

    Args:
        poses: T_world_sole of the right and the left sole (2 x 4 x 4).
        wrenches: their [fx, fy, fz, mx, my, mz] of the ground on the sole, about the sole
            frame's origin in sole axes (2 x 6; N, N m).
        corners_m: the sole's corners in its own frame (4 x 3), counter-clockwise.
    """
    zmp = np.empty(2)
    outside = _zmp_outside(np.ascontiguousarray(poses, dtype=float),
                           np.ascontiguousarray(wrenches, dtype=float), corners_m,
                           float(loaded_n), zmp)
    return (None, math.inf) if outside == math.inf else (zmp, outside)  # inf: none loaded


@nb.njit(cache=True, nogil=True)
def _zmp_outside(poses, wrenches, corners, loaded_n, zmp_out):
    """:func:`measured_zmp` compiled (one call a period instead of some twenty array
    operations): writes the ZMP to ``zmp_out``, returns how far it lies outside the hull
    (inf when no sole is loaded). One loaded sole is its own outline, corners in order."""
    total = weighted_x = weighted_y = 0.0
    points = np.empty((poses.shape[0] * corners.shape[0], 2))
    n = loaded = 0
    for s in range(poses.shape[0]):
        fz = wrenches[s, 2]
        if not fz > loaded_n:
            continue
        px, py = -wrenches[s, 4] / fz, wrenches[s, 3] / fz  # the sole's CoP: -m_y/f_z, m_x/f_z
        T = poses[s]
        weighted_x += fz * (T[0, 0] * px + T[0, 1] * py + T[0, 3])
        weighted_y += fz * (T[1, 0] * px + T[1, 1] * py + T[1, 3])
        total += fz
        for c in range(corners.shape[0]):
            points[n, 0] = corners[c, 0] * T[0, 0] + corners[c, 1] * T[0, 1] + T[0, 3]
            points[n, 1] = corners[c, 0] * T[1, 0] + corners[c, 1] * T[1, 1] + T[1, 3]
            n += 1
        loaded += 1
    if loaded == 0:
        return math.inf
    zmp_out[0] = weighted_x / total
    zmp_out[1] = weighted_y / total
    if loaded == 1:
        return outside_distance(points[:n], zmp_out)
    return outside_distance(convex_hull(points[:n]), zmp_out)


class ContactWrenches:
    """The soles' wrenches as the walk's ZMP figure reads them: each ankle's F_z, m_x and m_y
    low-passed at CONTACT_CUTOFF_HZ (first order, started at the first reading), the filter
    that decides contact in the simulator and the reports (a sole counts as support while its
    filtered F_z exceeds CONTACT_THRESHOLD_N).

    The simulated ankle sensors read the contact forces of the last physics step, which jump
    between the feet at touch-down and lift-off: for 0.1 s after a landing the two F_z sum to
    100-160 N (the robot weighs about 380 N) while the torso's height stays within 0.5 mm, a
    reading no motion of the robot produces. Averaged over the filter's 32 ms, they keep the
    momentum the ground actually gave."""

    def __init__(self, period_s: float) -> None:
        tau = 1.0 / (2.0 * math.pi * CONTACT_CUTOFF_HZ)
        self.alpha = period_s / (period_s + tau)
        self.filtered = np.full((2, 6), np.nan)  # right, left; NaN until a first reading

    def update(self, wrenches: np.ndarray) -> np.ndarray:
        """One period's raw wrenches (2 x 6: the right and the left sole's [fx, fy, fz, mx, my,
        mz]); the filtered ones (2 x 6). A sole's reading with a non-finite value is skipped."""
        _low_pass(self.filtered, np.ascontiguousarray(wrenches, dtype=float), self.alpha)
        return self.filtered


@nb.njit(cache=True, nogil=True)
def _low_pass(filtered, wrenches, alpha):
    """:meth:`ContactWrenches.update` in place, compiled (a few array operations cost more
    than the arithmetic): a row with a non-finite value is skipped, a first reading taken."""
    for s in range(wrenches.shape[0]):
        finite = True
        for i in range(wrenches.shape[1]):
            finite = finite and math.isfinite(wrenches[s, i])
        if not finite:
            continue
        for i in range(wrenches.shape[1]):
            last = filtered[s, i]
            filtered[s, i] = wrenches[s, i] if math.isnan(last) else (
                last + alpha * (wrenches[s, i] - last))


@nb.njit(**JIT)
def _correct_legs(T_neck_soles, R_neck_world, offset_x, offset_y, lift_right, lift_left, q,
                  deltas, right, left, step_rad):
    """The stabilizer's correction of both legs, compiled (one call a period): each planned
    sole goal in the torso's frame (``T_neck_soles``: right, left) moved by the torso offset
    (world x, y) and the sole's lift (world z), both turned into the torso's frame by
    ``R_neck_world``, then :func:`_correct_leg` with the leg's ``(chain, lengths, is_arm,
    lower, upper, hold_m, start)`` and its row of ``deltas`` (2 x 6)."""
    goal = np.empty((4, 4))
    for side in range(2):
        lift = lift_right if side == 0 else lift_left
        for r in range(4):  # a loop, not goal[:, :] = ...: see choice._copy6
            for c in range(4):
                goal[r, c] = T_neck_soles[side, r, c]
        for r in range(3):
            goal[r, 3] += (R_neck_world[r, 0] * -offset_x + R_neck_world[r, 1] * -offset_y
                           + R_neck_world[r, 2] * lift)
        _correct_leg(goal, right if side == 0 else left, q, deltas[side], step_rad)


@nb.njit(**JIT)
def _correct_leg(T_neck_goal, leg, q, delta, step_rad):
    """One leg's correction: the leg's joints ``q[start:start + 6]`` (the pattern's) solved
    for the goal sole ``T_neck_goal`` (:func:`~hubo_cli.kinematics.choice.solve_limb` from
    those joints); an exact solution, or one capped to the joint limits within LEG_CAPPED_M
    and LEG_CAPPED_RAD of the goal, whose difference to them changes no joint by more than
    ``step_rad`` from the last correction ``delta`` becomes the new correction (written to
    ``delta``); the correction is added to the leg's joints of ``q`` in place."""
    chain, lengths, is_arm, lower, upper, hold_m, start = leg
    part = q[start:start + 6]
    solved = np.empty(6)
    status, position_m, rotation_rad = solve_limb(T_neck_goal, chain, lengths, is_arm, lower,
                                                  upper, part, TRUE[0], hold_m, TRUE[0], solved)
    if status == EXACT or (status == CAPPED and position_m <= LEG_CAPPED_M
                           and rotation_rad <= LEG_CAPPED_RAD):
        within = True
        for j in range(6):
            within = within and abs(solved[j] - part[j] - delta[j]) <= step_rad
        if within:
            for j in range(6):
                delta[j] = solved[j] - part[j]
    for j in range(6):
        part[j] += delta[j]


@nb.njit(**JIT)
def tilt_between(z_from: np.ndarray, z_to: np.ndarray) -> np.ndarray:
    """The smallest rotation (3x3) turning the unit vector ``z_from`` onto ``z_to`` (Rodrigues'
    formula; compiled: it runs every control period)."""
    ax, ay, az = z_from[0], z_from[1], z_from[2]
    bx, by, bz = z_to[0], z_to[1], z_to[2]
    kx, ky, kz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    s = math.sqrt(kx * kx + ky * ky + kz * kz)
    if s < 1e-12:
        return np.eye(3)
    c = ax * bx + ay * by + az * bz
    kx, ky, kz = kx / s, ky / s, kz / s
    angle = math.atan2(s, c)
    sn, vc = math.sin(angle), 1.0 - math.cos(angle)
    R = np.empty((3, 3))
    R[0, 0] = 1.0 - vc * (ky * ky + kz * kz)
    R[0, 1] = -sn * kz + vc * kx * ky
    R[0, 2] = sn * ky + vc * kx * kz
    R[1, 0] = sn * kz + vc * kx * ky
    R[1, 1] = 1.0 - vc * (kx * kx + kz * kz)
    R[1, 2] = -sn * kx + vc * ky * kz
    R[2, 0] = -sn * ky + vc * kx * kz
    R[2, 1] = sn * kx + vc * ky * kz
    R[2, 2] = 1.0 - vc * (kx * kx + ky * ky)
    return R


@nb.njit(**JIT)
def imu_z_axis(q_wxyz: np.ndarray) -> np.ndarray:
    """The world's view of the torso's z axis (3,) from the IMU's quaternion (w, x, y, z;
    normalised here): the third column of its rotation matrix."""
    w, x, y, z = q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]
    n2 = w * w + x * x + y * y + z * z
    axis = np.empty(3)
    axis[0] = 2.0 * (x * z + w * y) / n2
    axis[1] = 2.0 * (y * z - w * x) / n2
    axis[2] = 1.0 - 2.0 * (x * x + y * y) / n2
    return axis


@nb.njit(**JIT)
def _com_from_sole(q_leg, chain, com_in_neck, R_world_neck, q_imu_wxyz):
    """The CoM's world x, y offset from a sole (m): ``com_in_neck`` less the sole's place in
    the neck frame (the leg's FK at ``q_leg``), turned into the world by the planned torso
    rotation ``R_world_neck`` tilted as the IMU's quaternion says (:func:`tilt_between`)."""
    base, _, offset, alpha, a, d, end, _ = chain
    T = np.empty((4, 4))
    chain_fk(q_leg, base, offset, alpha, a, d, end, T)
    tilt = tilt_between(R_world_neck[:, 2], imu_z_axis(q_imu_wxyz))
    r0, r1, r2 = (com_in_neck[0] - T[0, 3], com_in_neck[1] - T[1, 3],
                  com_in_neck[2] - T[2, 3])
    xy = np.zeros(2)
    for i in range(2):
        for j in range(3):
            R_ij = (tilt[i, 0] * R_world_neck[0, j] + tilt[i, 1] * R_world_neck[1, j]
                    + tilt[i, 2] * R_world_neck[2, j])
            xy[i] += R_ij * (r0 if j == 0 else (r1 if j == 1 else r2))
    return xy[0], xy[1]


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """The inverse of rigid transforms (4x4, or a stack of them: ... x 4 x 4): [R^T, -R^T p]."""
    T = np.asarray(T, dtype=float)
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    out = np.zeros(T.shape)
    out[..., :3, :3] = R_t
    out[..., :3, 3] = -(R_t @ T[..., :3, 3, None])[..., 0]
    out[..., 3, 3] = 1.0
    return out


def planned_support(gait: Gait) -> np.ndarray:
    """Per period the soles that carry the robot in this phase of the step, the swing foot at
    its landing place: (n, 2, 4, 4) world poses (right, left), for the capture-point monitor."""
    poses = np.empty((gait.n, 2, 4, 4))
    for column, side in enumerate(("right", "left")):
        rows = gait.feet[side].copy()
        swinging = ~gait.support[:, column]
        # a swing phase ends with the foot down: each swinging period takes the row where the
        # swing ends (the next period on the ground)
        landing = rows[-1].copy()
        for i in range(gait.n - 1, -1, -1):
            if swinging[i]:
                rows[i] = landing
            else:
                landing = rows[i].copy()
        rows[:, 2] = gait.feet[side][0, 2]
        poses[:, column] = np.array([pose_of_row(r) for r in rows])
    return poses


class WalkTarget(Target):
    """Walk to ``goal`` (forward, left, turn relative to the stance at the start).

    The plan is made in :meth:`attach` from the soles' poses in the simulator; each period
    sends the pattern's joints and logs the reference and measured ZMP and CoM. When the
    pattern has ended (its last ``settle_s`` standing) and the feet, which slip a little on
    every step, stand further than ARRIVED_M / ARRIVED_RAD from the goal, it plans again from
    where they stand, up to ``corrections`` times. The run ends then, or on a fall.

    ``end_width_m`` (None: the walking width) ends every walk with the feet this far apart
    (:func:`~hubo_cli.walking.footsteps.closing_steps`): the stance a task starts from.
    """

    log_columns = ("walk.zmp_ref_x_m", "walk.zmp_ref_y_m", "walk.com_ref_x_m",
                   "walk.com_ref_y_m", "walk.zmp_x_m", "walk.zmp_y_m", "walk.zmp_outside_m",
                   "walk.contact_zmp_outside_m", "walk.step", "walk.tilt_deg",
                   "planned_right_foot_contact_flag", "planned_left_foot_contact_flag",
                   "walk.offset_x_m", "walk.offset_y_m", "walk.right_lift_m", "walk.left_lift_m",
                   "walk.right_sole_roll_rad", "walk.right_sole_pitch_rad",
                   "walk.left_sole_roll_rad", "walk.left_sole_pitch_rad")

    def __init__(self, model: RobotModel, params: WalkingParams, goal: tuple[float, float, float],
                 q_start_rad: np.ndarray, T_world_neck_start: np.ndarray,
                 corrections: int = 1, end_width_m: float | None = None,
                 stabilizer: StabilizerGains | None = None) -> None:
        self.model = model
        self.end_width_m = end_width_m
        self.params = params
        self.goal_relative = goal
        self.q_start = np.asarray(q_start_rad, dtype=float)
        self.T_world_neck_start = T_world_neck_start
        self.world: SimulatedWorld | None = None
        self.gait: Gait | None = None
        self.plan: JointPlan | None = None
        self.start: Stance | None = None
        self.goal: Stance | None = None
        self.corners = np.ascontiguousarray(model.feet.sole_corners_m()[:, :3])
        self.k = 0
        self.fell = False
        self.zmp_periods = 0
        self.zmp_inside_periods = 0
        self.raw_zmp_periods = 0
        self.raw_zmp_inside_periods = 0
        self.contact_wrenches = ContactWrenches(model.control_period_s)
        self.torso_z0_m: float | None = None
        self.final_feet: dict[str, np.ndarray] = {}
        self.steps: list[Footstep] = []
        self.start_feet: list[Footstep] = []
        self.corrections_left = int(corrections)
        self.plan_start_s = 0.0
        self.last_step_end_s = 0.0
        self.body: WalkingBody | None = None
        self.stabilizer = stabilizer
        dt = model.control_period_s
        xs, ys = self.corners[:, 0], self.corners[:, 1]
        box = (float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max()))
        if stabilizer is not None:
            self.dampers = {side: SoleDamper(stabilizer, box, dt) for side in ("right", "left")}
            self.torso_offset = TorsoOffset(stabilizer, dt)
            self.touchdowns = {side: Touchdown(stabilizer, dt) for side in ("right", "left")}
            self._leg_delta = np.zeros((2, 6))  # the legs' corrections: right, left
        names = list(model.joint_names)
        self._ankle = {"right": (names.index("RAR"), names.index("RAP")),
                       "left": (names.index("LAR"), names.index("LAP"))}

    def attach(self, world: SimulatedWorld | None, modules: Sequence, store: Store) -> None:
        if world is None:
            raise ConfigError("walking needs the simulator (the soles' poses in the world)",
                              hint="run it with the sim driver")
        self.world = world
        feet = self._measured_feet()
        self.start_feet = [feet["right"], feet["left"]]
        self.start = stance_of(feet["right"], feet["left"])
        forward, left, turn = self.goal_relative
        c, s = math.cos(self.start.yaw_rad), math.sin(self.start.yaw_rad)
        self.goal = Stance(self.start.x_m + c * forward - s * left,
                           self.start.y_m + s * forward + c * left, self.start.yaw_rad + turn)
        self._plan(self.q_start, 0.0)
        if self.stabilizer is not None:
            # numba compiles a kernel on its first call: make that now with the run's types,
            # not in the first period (seconds on a fresh install; cached afterwards)
            q, body = self.q_start.copy(), self.body
            _correct_legs(self._T_neck_soles[0], self._R_neck_world[0], 0.0, 0.0, 0.0, 0.0, q,
                          np.zeros((2, 6)), *self._leg_kernel, LEG_STEP_RAD)
            leg = SIDE_LEG["right"]
            _com_from_sole(q[body.slices[leg]], body.legs[leg].chain, body.com_in_neck(q),
                           self.plan.T_world_neck[0, :3, :3], np.array((1.0, 0.0, 0.0, 0.0)))
        for module in modules:
            if isinstance(module, CapturePointMonitor):
                module.support_override = self.support_at

    def _measured_feet(self) -> dict[str, Footstep]:
        return {side: footstep_of(side, self.world.frame_pose(frame)) for side, frame, _ in SOLES}

    def _plan(self, q_rad: np.ndarray, t_s: float) -> None:
        """Plan the walk from where the feet stand now (the stance frame moves with them),
        starting at loop time ``t_s`` from the commanded joints ``q_rad``."""
        world = self.world
        feet = self._measured_feet()
        steps = plan_footsteps(feet["right"], feet["left"], self.goal, self.params)
        if self.end_width_m is not None:
            placed = {step.side: step for step in steps}
            first = "left" if steps and steps[-1].side == "right" else "right"
            steps = steps + closing_steps(placed.get("right", feet["right"]),
                                          placed.get("left", feet["left"]), self.goal,
                                          self.end_width_m, first)
        T_world_neck = world.frame_pose("torso")
        T_world_neck[2, 3] = self.T_world_neck_start[2, 3] if self.gait is None \
            else self.plan.T_world_neck[-1, 2, 3]
        body = WalkingBody(self.model, q_rad, T_world_neck, self.params.lean_rad_per_m)
        sole_z = float(world.frame_pose("right_sole")[2, 3])
        com = body.com_in_neck(q_rad)
        com_world = T_world_neck[:3, :3] @ com + T_world_neck[:3, 3]
        self.gait = make_gait(feet["right"], feet["left"], steps, self.params,
                              self.model.control_period_s, float(com_world[2]) - sole_z, sole_z,
                              self.model.feet.forward_m, com_start_m=com_world[:2])
        params = self.params
        self.gait, self.plan = body.solve_corrected(self.gait, sole_z, params.preview_s,
                                                    params.zmp_weight, params.jerk_weight)
        self.body = body
        # each leg's IK data as :func:`_correct_legs` takes them (right, left)
        self._leg_kernel = tuple(
            (leg.chain, leg.lengths_m, leg.spec.is_arm, leg.lower_rad, leg.upper_rad, leg.hold_m,
             body.slices[name].start)
            for leg, name in ((body.legs[SIDE_LEG[side]], SIDE_LEG[side])
                              for side in ("right", "left")))
        self._support_poses = planned_support(self.gait)
        # per-period rows as plain floats and bools for the loop (cheaper than numpy scalars)
        gait = self.gait
        self._rows = {"support": gait.support.tolist(), "zmp_ref": gait.zmp_ref_m.tolist(),
                      "com_ref": gait.com.com_m.tolist(), "plan_com": self.plan.com_m.tolist(),
                      "step": gait.step_index.tolist(),
                      **{side: gait.feet[side].tolist() for side in ("right", "left")}}
        self._sole_z0 = {side: float(gait.feet[side][0, 2]) for side in ("right", "left")}
        # the soles' goals in the planned torso's frame, per period: the stabilizer only moves
        # them by its torso offset and a touchdown's lift (:meth:`_stabilized`)
        T_neck_world = rigid_inverse(self.plan.T_world_neck)
        self._R_neck_world = T_neck_world[:, :3, :3].copy()
        self._T_neck_soles = np.stack([T_neck_world @ np.array([pose_of_row(row)
                                                                for row in gait.feet[side]])
                                       for side in ("right", "left")], axis=1)  # n x 2 x 4 x 4
        self.plan_start_s = t_s
        self.k = 0
        self.steps.extend(steps)

    def support_at(self, t_s: float) -> np.ndarray:
        """The planned support at time ``t_s`` (see :func:`planned_support`)."""
        k = int(round((t_s - self.plan_start_s) / self.gait.period_s))
        return self._support_poses[min(max(k, 0), self.gait.n - 1)]

    @property
    def walking_s(self) -> float:
        """From the start to the end of the last step's double support (s)."""
        gait = self.gait
        moving = np.nonzero(gait.step_index >= 0)[0]
        if not len(moving):
            return self.last_step_end_s
        return self.plan_start_s + float((moving[-1] + 1) * gait.period_s)

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        if self.k >= self.gait.n and not self.fell and self.corrections_left > 0 \
                and not self.arrived():
            self.corrections_left -= 1
            self.last_step_end_s = self.walking_s
            self._plan(self.plan.q_rad[-1], t_s)
        gait, plan, world = self.gait, self.plan, self.world
        k = min(self.k, gait.n - 1)
        self.k += 1
        (_, _, r02, _), (_, _, r12, _), (_, _, r22, torso_z) = \
            state.truth.T_world_torso[:3].tolist()
        tilt = math.degrees(math.atan2(math.hypot(r02, r12), r22))  # tilt_rad_of_matrix
        if self.torso_z0_m is None:
            self.torso_z0_m = torso_z
        if has_fallen(tilt, self.torso_z0_m - torso_z):
            self.fell = True
        poses = np.array([world.frame_pose(frame) for _, frame, _ in SOLES])
        wrenches = np.array([state.ft[sensor] for _, _, sensor in SOLES])
        zmp, outside = measured_zmp(poses, wrenches, self.corners)
        if zmp is not None:
            self.raw_zmp_periods += 1
            self.raw_zmp_inside_periods += outside <= -ZMP_INSIDE_MARGIN_M
        support_zmp, support_outside = measured_zmp(
            poses, self.contact_wrenches.update(wrenches), self.corners, CONTACT_THRESHOLD_N)
        if support_zmp is not None:
            self.zmp_periods += 1
            self.zmp_inside_periods += support_outside <= -ZMP_INSIDE_MARGIN_M
        self.final_feet = {"right": poses[0], "left": poses[1]}
        q = plan.q_rad[k]
        if self.stabilizer is not None:
            q = self._stabilized(k, q.copy(), state, zmp)
        rows = self._rows
        zmp_x, zmp_y = (math.nan, math.nan) if zmp is None else zmp.tolist()
        support = rows["support"][k]
        (zmp_ref_x, zmp_ref_y), (com_ref_x, com_ref_y) = rows["zmp_ref"][k], rows["com_ref"][k]
        info = {"walk.zmp_ref_x_m": zmp_ref_x, "walk.zmp_ref_y_m": zmp_ref_y,
                "walk.com_ref_x_m": com_ref_x, "walk.com_ref_y_m": com_ref_y,
                "walk.zmp_x_m": zmp_x, "walk.zmp_y_m": zmp_y,
                "walk.zmp_outside_m": outside if math.isfinite(outside) else math.nan,
                "walk.contact_zmp_outside_m": (support_outside if math.isfinite(support_outside)
                                               else math.nan),
                "walk.step": float(rows["step"][k]), "walk.tilt_deg": tilt,
                "planned_right_foot_contact_flag": float(support[0]),
                "planned_left_foot_contact_flag": float(support[1]),
                **self._stabilizer_info(),
                "done": self.fell or (self.k >= gait.n and (self.corrections_left == 0
                                                             or self.arrived()))}
        return q, info

    def _stabilizer_info(self) -> dict[str, float]:
        """The stabilizer's corrections for the log (NaN without a stabilizer)."""
        if self.stabilizer is None:
            return dict.fromkeys(self.log_columns[-8:], math.nan)
        right, left = self.dampers["right"].delta_rad, self.dampers["left"].delta_rad
        offset = self.torso_offset.offset_m
        return {"walk.offset_x_m": float(offset[0]), "walk.offset_y_m": float(offset[1]),
                "walk.right_lift_m": self.touchdowns["right"].lift_m,
                "walk.left_lift_m": self.touchdowns["left"].lift_m,
                "walk.right_sole_roll_rad": float(right[0]),
                "walk.right_sole_pitch_rad": float(right[1]),
                "walk.left_sole_roll_rad": float(left[0]),
                "walk.left_sole_pitch_rad": float(left[1])}

    def _measured_com(self, k: int, state: RobotState) -> tuple[float, float]:
        """The whole-body CoM's world x, y as a real robot can measure it: the torso tilted as
        the IMU says (heading from the pattern), placed by the measured leg kinematics of the
        more loaded planned support sole standing where the pattern put it."""
        body = self.body
        right_down, left_down = self._rows["support"][k]
        ranks = {"right": (right_down, float(state.ft[SOLES_SENSOR["right"]][2])),
                 "left": (left_down, float(state.ft[SOLES_SENSOR["left"]][2]))}
        side = "left" if ranks["left"] > ranks["right"] else "right"
        name = SIDE_LEG[side]
        x, y = _com_from_sole(state.q_rad[body.slices[name]], body.legs[name].chain,
                              body.com_in_neck(state.q_rad), self.plan.T_world_neck[k, :3, :3],
                              state.imu_quat_wxyz)
        sole_x, sole_y = self._rows[side][k][:2]
        return sole_x + x, sole_y + y

    def _stabilized(self, k: int, q: np.ndarray, state: RobotState,
                    zmp: np.ndarray | None) -> np.ndarray:
        """The pattern's joints ``q`` with the stabilizer's corrections (see
        :mod:`hubo_cli.walking.stabilizer`)."""
        rows = self._rows
        offset_x, offset_y = self.torso_offset.update(
            zmp, rows["zmp_ref"][k], self._measured_com(k, state), rows["plan_com"][k]).tolist()
        lifts = [self.touchdowns[side].update(not down, rows[side][k][2] - self._sole_z0[side],
                                              float(state.ft[SOLES_SENSOR[side]][2]))
                 for side, down in zip(("right", "left"), rows["support"][k], strict=True)]
        _correct_legs(self._T_neck_soles[k], self._R_neck_world[k], offset_x, offset_y, *lifts,
                      q, self._leg_delta, *self._leg_kernel, LEG_STEP_RAD)
        for side in ("right", "left"):
            delta = self.dampers[side].update(state.ft[SOLES_SENSOR[side]])
            roll, pitch = self._ankle[side]
            q[roll] += delta[0]
            q[pitch] += delta[1]
        return q

    def arrived(self) -> bool:
        """The feet stand within ARRIVED_M and ARRIVED_RAD of the goal stance."""
        if not self.final_feet:
            return False
        error_m, error_rad = self.final_error()
        return error_m <= ARRIVED_M and error_rad <= ARRIVED_RAD

    def final_error(self) -> tuple[float, float]:
        """The final stance's distance (m) and heading error (rad) from the goal; NaN when
        the walk ended (Ctrl-C, SIGTERM, an error) before its last step came down."""
        if not self.final_feet:
            return math.nan, math.nan
        feet = {side: footstep_of(side, T) for side, T in self.final_feet.items()}
        reached = stance_of(feet["right"], feet["left"])
        return (math.hypot(reached.x_m - self.goal.x_m, reached.y_m - self.goal.y_m),
                abs(math.atan2(math.sin(reached.yaw_rad - self.goal.yaw_rad),
                               math.cos(reached.yaw_rad - self.goal.yaw_rad))))
