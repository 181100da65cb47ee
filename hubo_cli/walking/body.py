"""From the walking pattern to joint targets: the neck placed so that the whole-body CoM
follows the pattern's CoM, and the legs' closed-form IK reaching the soles from it.

The torso stays at a constant height; its heading is the mean of the feet's. The
neck's horizontal position is the pattern's CoM minus the CoM's offset from the neck, taken
from the model's masses (pinocchio, the URDF) at the previous period's joints (a fixed-point
iteration that converges within a few periods; the offset changes slowly). The arms keep the
start posture.

The cart-table model ignores the legs' and the torso's angular momentum: a swinging leg moves the
multi-body ZMP up to 40 mm from the reference along the foot. :meth:`WalkingBody.solve_corrected`
runs Kajita's second preview stage (Kajita et al. 2003, section IV): the ZMP of the solved
joints (:func:`multibody_zmp`, pinocchio's centroidal momentum) is compared with the reference,
the preview controller turns the difference into a CoM correction, and the legs are solved again.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.errors import InputError
from hubo_cli.kinematics.choice import CAPPED, EXACT, STATUS_NAMES, solve_limb
from hubo_cli.kinematics.dh import JIT, TRUE
from hubo_cli.kinematics.limb import Limb
from hubo_cli.kinematics.torso_kernels import exp3
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture
from hubo_cli.state import GRAVITY_M_S2
from hubo_cli.walking.gait import Gait
from hubo_cli.walking.preview import CoMPath, com_from_zmp, preview_gains

SIDE_LEG = {"right": "right-leg", "left": "left-leg"}
MAX_SOLE_ERROR_M = 0.05  # a capped leg solution further than this from its sole: out of reach
END_PERIODS = 10  # the multi-body ZMP correction leaves out this many periods at either end


def pose_of_row(row: np.ndarray, pitch_rad: float = 0.0) -> np.ndarray:
    """T_world_sole (4x4) of a (x, y, z, yaw) row, the sole flat or turned by ``pitch_rad``
    about its own y axis (> 0: heel up; toe-heel walking, :mod:`hubo_cli.walking.gait`)."""
    x, y, z, yaw = row.tolist() if isinstance(row, np.ndarray) else (float(v) for v in row)
    c, s = math.cos(yaw), math.sin(yaw)  # plain floats: the stabilizer runs this every period
    if pitch_rad == 0.0:
        return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z],
                         [0.0, 0.0, 0.0, 1.0]])
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)  # Rz(yaw) Ry(pitch)
    return np.array([[c * cp, -s, c * sp, x], [s * cp, c, s * sp, y], [-sp, 0.0, cp, z],
                     [0.0, 0.0, 0.0, 1.0]])


def poses_of_rows(rows: np.ndarray, pitch_rad: np.ndarray | None = None) -> np.ndarray:
    """:func:`pose_of_row` of every row of ``rows`` (n x 4) at once: (n, 4, 4), each turned by
    its ``pitch_rad`` (n,; None: flat)."""
    rows = np.asarray(rows, dtype=float)
    c, s = np.cos(rows[:, 3]), np.sin(rows[:, 3])
    pitch = np.zeros(len(rows)) if pitch_rad is None else np.asarray(pitch_rad, dtype=float)
    cp, sp = np.cos(pitch), np.sin(pitch)
    T = np.zeros((len(rows), 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 2] = c * cp, -s, c * sp
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2] = s * cp, c, s * sp
    T[:, 2, 0], T[:, 2, 2] = -sp, cp
    T[:, :3, 3] = rows[:, :3]
    T[:, 3, 3] = 1.0
    return T


@dataclass(frozen=True)
class JointPlan:
    """Joint targets for a gait, one row per period.

    Attributes:
        q_rad: (n, joints) in ``model.joint_names`` order.
        T_world_neck: (n, 4, 4) the torso pose the legs were solved for.
        com_m: (n, 3) the whole-body CoM of those joints at that torso pose (pinocchio).
        worst_ik_error_m: the largest distance between a sole goal and its FK.
    """

    q_rad: np.ndarray
    T_world_neck: np.ndarray
    com_m: np.ndarray
    worst_ik_error_m: float


class WalkingBody:
    """Turns a :class:`Gait` into joint targets (see the module docstring).

    Args:
        model: the robot model.
        q_start_rad: the start posture (arms keep it; it seeds the leg IK).
        T_world_neck_start: the torso's pose at the start (its height is kept).
        lean_rad_per_m: the torso rolls toward the stance foot by this much per metre of the
            CoM's sideways offset from between the feet (see :func:`lean_rad`).

    ``max_error_m`` (default MAX_SOLE_ERROR_M): :meth:`solve` refuses a capped leg solution
    further than this from its sole.
    """

    def __init__(self, model: RobotModel, q_start_rad: np.ndarray,
                 T_world_neck_start: np.ndarray, lean_rad_per_m: float = 0.0) -> None:
        self.model = model
        self.lean_rad_per_m = float(lean_rad_per_m)
        self.max_error_m = MAX_SOLE_ERROR_M
        self.q_start = np.asarray(q_start_rad, dtype=float)
        self.neck_z_m = float(T_world_neck_start[2, 3])
        self.legs = {name: Limb(model, name) for name in LEGS}
        self.slices = {name: model.limb_slice(name) for name in LEGS}
        # each leg's IK data as :func:`_solve_legs` takes them (right, left)
        self.leg_kernels = tuple(
            (leg.chain, leg.lengths_m, leg.spec.is_arm, leg.lower_rad, leg.upper_rad, leg.hold_m,
             self.slices[name].start)
            for leg, name in ((self.legs[SIDE_LEG[side]], SIDE_LEG[side])
                              for side in ("right", "left")))
        self.robot = load_pin_robot(model, floating=True)
        self.data = self.robot.model.createData()
        self._q_pin = np.zeros(self.robot.model.nq)

    def seeded(self, q_start_rad: np.ndarray, T_world_neck_start: np.ndarray) -> WalkingBody:
        """This body starting from other joints and torso pose (its model, legs and scratch data
        shared: no method keeps anything in them from one call to the next)."""
        body = copy.copy(self)
        body.q_start = np.asarray(q_start_rad, dtype=float)
        body.neck_z_m = float(T_world_neck_start[2, 3])
        return body

    def com_in_neck(self, q_rad: np.ndarray) -> np.ndarray:
        """The whole-body CoM in the neck frame (3,; m) for joints ``q_rad``."""
        q = self.robot.configuration(q_rad, None, out=self._q_pin)
        return pin.centerOfMass(self.robot.model, self.data, q, False).copy()

    def solve(self, gait: Gait) -> JointPlan:
        """Joint targets for every period of ``gait``.

        Raises:
            InputError: a sole the legs cannot reach (the step is too long for this posture).
        """
        return run_slices(self.solve_slices(gait, gait.n))

    def solve_slices(self, gait: Gait, rows_per_slice: int, out: JointPlan | None = None
                     ) -> Iterator[None]:
        """:meth:`solve` ``rows_per_slice`` rows at a time: yields after each slice (a
        re-plan spread over control periods, :mod:`hubo_cli.walking.replan`), the rows solved
        so far written into ``out``'s arrays when given (:func:`unsolved_plan`); returns the
        :class:`JointPlan`."""
        n = gait.n
        out = unsolved_plan(n, len(self.q_start)) if out is None else out
        q_all, T_all, com_all = out.q_rad, out.T_world_neck, out.com_m
        q = self.q_start.copy()
        offset = self.com_in_neck(q)
        worst = 0.0
        status, error = np.empty(2, dtype=np.int64), np.empty(2)
        pitch = (np.zeros((n, 2)) if gait.toe_heel is None
                 else np.ascontiguousarray(gait.toe_heel.foot_angle_rad, dtype=float))
        feet = [np.ascontiguousarray(gait.feet[side], dtype=float) for side in ("right", "left")]
        com_m = np.ascontiguousarray(gait.com.com_m, dtype=float)
        lead = np.zeros((n, 3))
        if gait.torso_lead_rad is not None:
            rows = min(n, len(gait.torso_lead_rad))
            lead[:rows] = gait.torso_lead_rad[:rows]
        for k in range(n):
            if k and k % rows_per_slice == 0:
                yield
            for _ in range(2):  # the CoM offset at the joints being solved
                row_worst = _solve_row(feet[0][k], feet[1][k], com_m[k], self.lean_rad_per_m,
                                       self.neck_z_m, offset, pitch[k], lead[k], q,
                                       *self.leg_kernels,
                                       self.max_error_m, T_all[k], status, error)
                if row_worst < 0.0:
                    side = 0 if status[0] not in (EXACT, CAPPED) \
                        or error[0] > self.max_error_m else 1
                    name = SIDE_LEG[("right", "left")[side]]
                    raise InputError(
                        f"the {name} cannot reach its sole at t = {k * gait.period_s:.2f} s "
                        f"({STATUS_NAMES[status[side]]}, {error[side] * 1000:.0f} mm off)",
                        hint="take shorter steps (walking.max_step_*_m in the robot file)")
                worst = max(worst, row_worst)
                offset = self.com_in_neck(q)
            q_all[k] = q
            com_all[k] = T_all[k, :3, :3] @ offset + T_all[k, :3, 3]
        return JointPlan(q_all, T_all, com_all, worst)

    def solve_corrected(self, gait: Gait, ground_z_m: float, preview_s: float,
                        zmp_weight: float, jerk_weight: float,
                        fix_start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                        ) -> tuple[Gait, JointPlan]:
        """The second preview stage (see the module docstring): the gait with its CoM path
        corrected for the multi-body ZMP, and its joints. ``ground_z_m`` is the soles' height;
        the other arguments are the preview controller's (:func:`preview_gains`).
        ``fix_start``: the correction's position, velocity and acceleration (2, each) at the
        gait's start (a pattern re-planned in motion continues its correction; None: at
        rest at zero)."""
        return run_slices(self.solve_corrected_slices(gait, ground_z_m, preview_s, zmp_weight,
                                                      jerk_weight, fix_start, gait.n))

    def solve_corrected_slices(self, gait: Gait, ground_z_m: float, preview_s: float,
                               zmp_weight: float, jerk_weight: float,
                               fix_start: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
                               rows_per_slice: int) -> Iterator[None]:
        """:meth:`solve_corrected` ``rows_per_slice`` rows at a time (yields after each slice
        of its three passes over the rows: solve, multi-body ZMP, solve again)."""
        plan = yield from self.solve_slices(gait, rows_per_slice)
        yield
        multibody = yield from multibody_zmp_slices(self, plan, ground_z_m, gait.period_s,
                                                    rows_per_slice)
        error = multibody - gait.zmp_ref_m
        # the ends hold still; their one-sided differences are not motion (and a step in the
        # correction's reference at the start would itself move the ZMP)
        error[:END_PERIODS] = 0.0
        error[-END_PERIODS:] = 0.0
        gains = preview_gains(gait.period_s, gait.com_height_m, preview_s, zmp_weight,
                              jerk_weight)
        fix = (com_from_zmp(-error, gains, np.zeros(2)) if fix_start is None else
               com_from_zmp(-error, gains, fix_start[0], (fix_start[1], fix_start[2])))
        com = gait.com
        corrected = replace(gait, com=CoMPath(
            com.com_m + fix.com_m, com.com_velocity_m_s + fix.com_velocity_m_s,
            com.com_acceleration_m_s2 + fix.com_acceleration_m_s2, com.zmp_m + fix.zmp_m))
        yield
        plan = yield from self.solve_slices(corrected, rows_per_slice)
        return corrected, plan


@nb.njit(**JIT)
def _solve_legs(T_neck_world, right_row, left_row, pitch_rad, q, right, left, status, error):
    """Both legs solved for their soles (rows of (x, y, z, yaw), each turned by its
    ``pitch_rad``: :func:`pose_of_row`) seen from the torso (``T_neck_world``), from the legs'
    joints in ``q`` (each leg ``(chain, lengths, is_arm, lower, upper, hold_m, start)``);
    the solutions written into ``q``, each leg's status and position error into ``status``
    and ``error`` (right, left). Compiled: :meth:`WalkingBody.solve` runs it on every row."""
    sole = np.zeros((4, 4))
    goal = np.empty((4, 4))
    solved = np.empty(6)
    for side in range(2):
        row = right_row if side == 0 else left_row
        c, s = math.cos(row[3]), math.sin(row[3])
        cp, sp = math.cos(pitch_rad[side]), math.sin(pitch_rad[side])
        sole[0, 0], sole[0, 1], sole[0, 2], sole[0, 3] = c * cp, -s, c * sp, row[0]
        sole[1, 0], sole[1, 1], sole[1, 2], sole[1, 3] = s * cp, c, s * sp, row[1]
        sole[2, 0], sole[2, 1], sole[2, 2], sole[2, 3] = -sp, 0.0, cp, row[2]
        sole[3, 3] = 1.0
        for r in range(4):
            for col in range(4):
                goal[r, col] = (T_neck_world[r, 0] * sole[0, col] + T_neck_world[r, 1]
                                * sole[1, col] + T_neck_world[r, 2] * sole[2, col]
                                + T_neck_world[r, 3] * sole[3, col])
        chain, lengths, is_arm, lower, upper, hold_m, start = right if side == 0 else left
        part = q[start:start + 6]
        status[side], error[side], _ = solve_limb(goal, chain, lengths, is_arm, lower, upper,
                                                  part, TRUE[0], hold_m, TRUE[0], solved)
        for j in range(6):
            part[j] = solved[j]


@nb.njit(**JIT)
def _solve_row(right_row, left_row, com_xy, lean_rad_per_m, neck_z_m, offset, pitch_rad,
               turn_rad, q, right, left, max_error_m, T_world_neck, status, error):
    """One row of :meth:`WalkingBody.solve`, compiled: the torso's pose (heading the feet's
    mean, rolled by the lean, turned further by the rotation vector ``turn_rad`` (its own
    frame: a correction's lead-in, :attr:`Gait.torso_lead_rad`), placed so that the CoM
    ``offset`` from it (neck frame) lies over ``com_xy`` at ``neck_z_m``; written to
    ``T_world_neck``), then both legs (:func:`_solve_legs`). Returns the legs' worse position
    error, or -1 when a leg is neither exact nor capped within ``max_error_m``."""
    turn = left_row[3] - right_row[3]
    yaw = right_row[3] + math.atan2(math.sin(turn), math.cos(turn)) / 2
    c, s = math.cos(yaw), math.sin(yaw)
    sideways = (-s * (com_xy[0] - (right_row[0] + left_row[0]) / 2)
                + c * (com_xy[1] - (right_row[1] + left_row[1]) / 2))
    roll = -lean_rad_per_m * sideways
    c_roll, s_roll = math.cos(roll), math.sin(roll)
    R = np.empty((3, 3))  # Rz(yaw) Rx(roll)
    R[0, 0], R[0, 1], R[0, 2] = c, -s * c_roll, s * s_roll
    R[1, 0], R[1, 1], R[1, 2] = s, c * c_roll, -c * s_roll
    R[2, 0], R[2, 1], R[2, 2] = 0.0, s_roll, c_roll
    if turn_rad[0] != 0.0 or turn_rad[1] != 0.0 or turn_rad[2] != 0.0:
        turn = np.empty((3, 3))  # R times the turn's rotation (Rodrigues)
        exp3(turn_rad, turn)
        R = R @ turn
    T_neck_world = np.zeros((4, 4))
    for r in range(4):
        for col in range(4):
            T_world_neck[r, col] = 0.0
    for r in range(3):
        for col in range(3):
            T_world_neck[r, col] = R[r, col]
            T_neck_world[r, col] = R[col, r]
    for r in range(2):
        T_world_neck[r, 3] = com_xy[r] - (R[r, 0] * offset[0] + R[r, 1] * offset[1]
                                          + R[r, 2] * offset[2])
    T_world_neck[2, 3] = neck_z_m
    T_world_neck[3, 3] = T_neck_world[3, 3] = 1.0
    for r in range(3):
        T_neck_world[r, 3] = -(R[0, r] * T_world_neck[0, 3] + R[1, r] * T_world_neck[1, 3]
                               + R[2, r] * T_world_neck[2, 3])
    _solve_legs(T_neck_world, right_row, left_row, pitch_rad, q, right, left, status, error)
    for side in range(2):
        if (status[side] != EXACT and status[side] != CAPPED) or error[side] > max_error_m:
            return -1.0
    return max(error[0], error[1])


def unsolved_plan(n: int, joints: int) -> JointPlan:
    """A :class:`JointPlan` of ``n`` rows to be solved (:meth:`WalkingBody.solve_slices`)."""
    return JointPlan(np.zeros((n, joints)), np.tile(np.eye(4), (n, 1, 1)), np.zeros((n, 3)), 0.0)


def run_slices(slices: Iterator[None]):
    """Run a sliced computation (a generator yielding between slices) to its end: its value."""
    while True:
        try:
            next(slices)
        except StopIteration as done:
            return done.value


def multibody_zmp(body: WalkingBody, plan: JointPlan, ground_z_m: float,
                  period_s: float) -> np.ndarray:
    """The ZMP (n, 2; m, world) of the whole body moving through ``plan``: from the CoM and
    the centroidal momentum's rate (pinocchio; velocities and rates by central differences,
    the ends repeat their neighbours) on flat ground at height ``ground_z_m``."""
    return run_slices(multibody_zmp_slices(body, plan, ground_z_m, period_s, len(plan.q_rad)))


def multibody_zmp_slices(body: WalkingBody, plan: JointPlan, ground_z_m: float,
                         period_s: float, rows_per_slice: int) -> Iterator[None]:
    """:func:`multibody_zmp` ``rows_per_slice`` rows at a time (yields after each slice)."""
    model, data = body.robot.model, body.data
    n = len(plan.q_rad)
    qs = np.zeros((n, model.nq))
    body.robot.configuration(plan.q_rad[0], plan.T_world_neck[0], out=qs[0])
    momentum = np.zeros((n, 6))
    com = np.zeros((n, 3))
    for k in range(n):
        if k and k % rows_per_slice == 0:
            yield
        if k + 1 < n:
            body.robot.configuration(plan.q_rad[k + 1], plan.T_world_neck[k + 1], out=qs[k + 1])
        before, after = qs[max(k - 1, 0)], qs[min(k + 1, n - 1)]
        span = (min(k + 1, n - 1) - max(k - 1, 0)) * period_s
        v = pin.difference(model, before, after) / span if span > 0 else np.zeros(model.nv)
        h = pin.computeCentroidalMomentum(model, data, qs[k], v)
        momentum[k, :3], momentum[k, 3:] = h.linear, h.angular
        com[k] = data.com[0]
    rate = np.gradient(momentum, period_s, axis=0) if n > 1 else np.zeros_like(momentum)
    mass = float(pin.computeTotalMass(model))
    fz = mass * GRAVITY_M_S2 + rate[:, 2]
    height = com[:, 2] - ground_z_m
    zmp = np.empty((n, 2))
    zmp[:, 0] = (mass * GRAVITY_M_S2 * com[:, 0] - height * rate[:, 0] - rate[:, 4]) / fz
    zmp[:, 1] = (mass * GRAVITY_M_S2 * com[:, 1] - height * rate[:, 1] + rate[:, 3]) / fz
    return zmp


def walking_posture(model: RobotModel, width_m: float, crouch_m: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The posture walking starts and ends in: the home posture with the soles ``width_m``
    apart (centre lines) and the torso ``crouch_m`` lower, soles flat and straight ahead.

    Returns:
        (q_rad, T_world_neck): the joints and the torso's pose in the world of the simulator
        (origin on the floor under the neck, the soles on the floor at z = 0).
    """
    q = home_posture(model)
    sole_z = None
    for name, sign in (("right-leg", -1.0), ("left-leg", 1.0)):
        leg, part = Limb(model, name), model.limb_slice(name)
        T = leg.fk(q[part])
        sole_z = float(T[2, 3])
        T[1, 3] = sign * width_m / 2
        T[2, 3] += crouch_m
        result = leg.solve(T, q[part])
        if not result.exact:
            raise InputError(f"the {name} cannot stand {width_m * 1000:.0f} mm wide "
                             f"{crouch_m * 1000:.0f} mm lower ({result.status})",
                             hint="change walking.step_width_m or walking.crouch_m")
        q[part] = result.q_rad
    T_world_neck = np.eye(4)
    T_world_neck[2, 3] = -sole_z - crouch_m
    return q, T_world_neck
