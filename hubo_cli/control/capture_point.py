"""Capture-point monitor (hrpsys Stabilizer's CP check): flags a coming fall, asks for an e-stop.

Each period, from the estimate in the store (:mod:`hubo_cli.estimation.keys`: one pinocchio
pass for every module, in the estimation layer):

* the centre of mass x_G (``COM_WORLD``) and the capture point CP = x_G + v_G / omega
  (``CAPTURE_POINT_WORLD``; omega = sqrt(g / (z_G - z_ground)), z_ground the lowest sole in
  contact, v_G low-passed at 4 Hz as hrpsys);
* the support polygon: the convex hull of the sole corners (``T_WORLD_SOLES``) of the feet in
  contact (``CONTACT``: one filter, one debounce) within 5 mm of the lowest one, shrunk by
  ``margin_m`` (3 cm, hrpsys ``cp_check_margin``). A foot that starts to tip
  about its heel therefore supports only along the heel edge; the hull then collapses to a
  segment, which has no inside, and the CP is flagged as outside. (The linear-inverted-pendulum
  capture point assumes flat feet; an external push such as a wall's reaction can tip the robot
  while the CoM is still well inside the soles, and this is when it must be caught.)

When the CP stays outside the shrunk polygon for ``confirm_periods`` periods in a row (3, i.e.
15 ms: a single period's outlier in the measured sole corners -- a simulated foot's contact
point jumping while the legs crouch -- is not a fall) while a foot touches the ground, the
module flags ``cp-outside`` and requests an emergency stop from source ``capture-point``. It
passes the command through unchanged. The reference CP is the centre of mass of the commanded
posture on its feet laid flat where the measured feet are (a static reference, like
AutoBalancer's reference CoM); ``cp_error`` = actual CP - reference CP.

While walking, the feet that carry the robot change every step and a swing foot leaves the
ground on purpose; the CP then lies between the stance foot and where the swing foot will land
(and must, for the robot's hips, which only abduct). A walking target therefore gives the
monitor its *planned support* (the store key :data:`~hubo_cli.control.phase.SUPPORT_PLAN`,
written by the phase's target every period): the soles on the ground in this phase of the
step, the swing foot counted at its landing place. The polygon is then their hull (flat on
the ground, shrunk by the plan's margin: a capture step judges the CP against its planned and
stepped stance unshrunk): the CP leaving it means the step cannot catch the robot. Without a
plan (standing, tasks, or a phase that writes None) nothing changes.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.control.balance import command_configuration
from hubo_cli.control.keys import SUPPORT_BOX_WORLD
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.phase import SUPPORT_PLAN, SupportPlan
from hubo_cli.control.status import SupportStatus
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
)
from hubo_cli.geometry import pose_laid_flat
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import PinRobot, load_pin_robot
from hubo_cli.state import RobotState

CP_MARGIN_M = 0.03        # hrpsys cp_check_margin
CORNER_TOLERANCE_M = 0.005  # a sole corner higher than this above the lowest one is lifted
SOLE_FRAMES = ("right_sole", "left_sole")


@nb.njit(cache=True, nogil=True)
def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@nb.njit(cache=True, nogil=True)
def convex_hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points (N x 2), counter-clockwise, no repeated end (monotone chain)."""
    pts = points.copy()
    n = pts.shape[0]
    for i in range(1, n):  # insertion sort by (x, y): the polygons here have a few points
        x, y = pts[i, 0], pts[i, 1]
        j = i - 1
        while j >= 0 and (pts[j, 0] > x or (pts[j, 0] == x and pts[j, 1] > y)):
            pts[j + 1, 0] = pts[j, 0]  # element by element: a row copy makes numba compile its
            pts[j + 1, 1] = pts[j, 1]  # shape-mismatch error path (seconds on a cold cache)
            j -= 1
        pts[j + 1, 0] = x
        pts[j + 1, 1] = y
    if n <= 2:
        return pts
    hull = np.empty((2 * n, 2))
    k = 0
    for i in range(n):
        while k >= 2 and _cross(hull[k - 2], hull[k - 1], pts[i]) <= 0:
            k -= 1
        hull[k, 0] = pts[i, 0]
        hull[k, 1] = pts[i, 1]
        k += 1
    lower = k + 1
    for i in range(n - 2, -1, -1):
        while k >= lower and _cross(hull[k - 2], hull[k - 1], pts[i]) <= 0:
            k -= 1
        hull[k, 0] = pts[i, 0]
        hull[k, 1] = pts[i, 1]
        k += 1
    return hull[:k - 1].copy()


@nb.njit(cache=True, nogil=True)
def outside_distance(hull: np.ndarray, p: np.ndarray) -> float:
    """How far p lies outside a counter-clockwise convex polygon (m): the largest signed
    distance beyond an edge line, > 0 outside, <= 0 inside (minus the distance to the nearest
    edge line); shrinking the polygon by m moves every edge line in by m. A polygon that has
    collapsed to a segment or a point has no inside: the distance to it (>= 0)."""
    n = hull.shape[0]
    if n < 3:
        a = hull[0]
        b = hull[n - 1]
        ex, ey = b[0] - a[0], b[1] - a[1]
        length2 = ex * ex + ey * ey
        s = 0.0
        if length2 > 0.0:
            s = min(1.0, max(0.0, ((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / length2))
        return math.hypot(p[0] - a[0] - s * ex, p[1] - a[1] - s * ey)
    best = -np.inf
    for i in range(n):
        a = hull[i]
        b = hull[(i + 1) % n]
        ex, ey = b[0] - a[0], b[1] - a[1]
        length = math.sqrt(ex * ex + ey * ey)
        if length == 0.0:
            continue
        # outward normal of a counter-clockwise polygon: (ey, -ex) / length
        d = ((p[0] - a[0]) * ey - (p[1] - a[1]) * ex) / length
        if d > best:
            best = d
    return best


@nb.njit(cache=True, nogil=True)
def _support(sole_pose, right_down, left_down, corners, cp, margin, corner_tolerance,
             box_out, flat_out):
    """Support polygon and how far the capture point ``cp`` (x, y) lies outside it (see
    CapturePointMonitor).

    Writes the soles laid flat on the ground (same x, y and heading; 2 x 4 x 4) and the box of
    the flat soles in contact, shrunk (4,); returns (outside m, ground z m). Without a foot on
    the ground: outside = -inf.
    """
    down = (right_down, left_down)
    n = 0
    world = np.empty((8, 3))
    for k in range(2):
        if not down[k]:
            continue
        T = sole_pose[k]
        for c in range(4):
            for row in range(3):
                world[n, row] = (T[row, 0] * corners[c, 0] + T[row, 1] * corners[c, 1]
                                 + T[row, 2] * corners[c, 2] + T[row, 3])
            n += 1
    if n == 0:
        return -np.inf, np.inf
    ground_z = world[:n, 2].min()
    points = np.empty((n, 2))
    m = 0
    for i in range(n):  # a corner lifted off the ground (a tipping foot) does not support
        if world[i, 2] <= ground_z + corner_tolerance:
            points[m, 0] = world[i, 0]
            points[m, 1] = world[i, 1]
            m += 1
    # the soles laid flat where they are, and their box shrunk: the nominal thresholds
    box_out[0], box_out[1] = np.inf, -np.inf
    box_out[2], box_out[3] = np.inf, -np.inf
    for k in range(2):
        T = sole_pose[k]
        yaw = math.atan2(T[1, 0], T[0, 0])
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        F = flat_out[k]
        F[:, :] = 0.0
        F[0, 0], F[0, 1], F[1, 0], F[1, 1] = cos_yaw, -sin_yaw, sin_yaw, cos_yaw
        F[2, 2], F[3, 3] = 1.0, 1.0
        F[0, 3], F[1, 3], F[2, 3] = T[0, 3], T[1, 3], ground_z
        if not down[k]:
            continue
        for i in range(4):
            x = F[0, 0] * corners[i, 0] + F[0, 1] * corners[i, 1] + F[0, 3]
            y = F[1, 0] * corners[i, 0] + F[1, 1] * corners[i, 1] + F[1, 3]
            box_out[0], box_out[1] = min(box_out[0], x), max(box_out[1], x)
            box_out[2], box_out[3] = min(box_out[2], y), max(box_out[3], y)
    box_out[0] += margin
    box_out[1] -= margin
    box_out[2] += margin
    box_out[3] -= margin
    hull = convex_hull(points[:m])
    return outside_distance(hull, cp) + margin, ground_z


class CapturePointMonitor(Module):
    """The ``capture-point`` module (see the module docstring).

    Args:
        model: the robot model (URDF).
        dt_s: the control period (s).
        margin_m: shrink of the support polygon (m).
        corner_tolerance_m: a sole corner more than this above the lowest sole point no longer
            supports (the foot is tipping on an edge), m.
        request_estop: request an emergency stop when the CP leaves the polygon.
        confirm_periods: periods in a row the CP must be outside before the flag.
        drill: the robot holds the drill in its right hand (its mass counts in the reference
            CoM of the commanded posture).

    It reads the estimate's CoM, capture point, contact and sole poses and writes
    :data:`~hubo_cli.control.keys.SUPPORT_BOX_WORLD` (the hip strategy's input). What it
    publishes for a viewer is :meth:`status` (:class:`SupportStatus`).

    Attributes after each update: ``com_m`` (3,) and ``cp_m`` (2,) as the estimate gave
    them, ``cp_ref_m`` (2,), ``outside_m`` (CP beyond the shrunk polygon, m; > 0 = flag),
    ``ground_z_m`` (lowest sole in contact), ``support_box_m`` (min x, max x, min y, max y of
    the soles in contact taken flat, shrunk by the margin: the nominal thresholds), ``flag``.

    It follows :data:`~hubo_cli.control.phase.SUPPORT_PLAN` (a phase's planned support, its
    sole poses and margin; None or unwritten: the estimated soles in contact).
    """

    name = "capture-point"
    reads = (COM_WORLD, CAPTURE_POINT_WORLD, CONTACT, T_WORLD_SOLES)
    follows = (SUPPORT_PLAN,)
    writes = (SUPPORT_BOX_WORLD,)
    log_columns = ("com_x_m", "com_y_m", "com_z_m", "cp_x_m", "cp_y_m", "cp_ref_x_m",
                   "cp_ref_y_m", "cp_error_x_m", "cp_error_y_m", "cp_outside_m",
                   "support_min_x_m", "support_max_x_m", "support_min_y_m", "support_max_y_m",
                   "cp_flag")

    def __init__(self, model: RobotModel, dt_s: float, margin_m: float = CP_MARGIN_M,
                 request_estop: bool = True, corner_tolerance_m: float = CORNER_TOLERANCE_M,
                 confirm_periods: int = 3, drill: bool = False) -> None:
        self.dt_s = float(dt_s)
        self._contact_loss_min_s = model.estimation.contact_loss_min_s
        self.confirm_periods = max(1, int(confirm_periods))
        self._outside_periods = 0
        self.margin_m = float(margin_m)
        self.corner_tolerance_m = float(corner_tolerance_m)
        self.request_estop = request_estop
        # the reference: the commanded posture, with the drill's 0.6 kg on the right hand
        self.robot: PinRobot = load_pin_robot(model, floating=True,
                                              urdf_path=model.urdf_path(drill))
        self.data = self.robot.model.createData()
        self._sole_ids = [self.robot.frame_id(f) for f in SOLE_FRAMES]
        self._corners = model.feet.sole_corners_m()
        self._q_ref = self.robot.configuration(np.zeros(len(model.joint_names)))  # at origin
        self._last_cmd = np.full(len(model.joint_names), np.nan)  # of the reference CoM
        self._in_sole: np.ndarray | None = None  # the reference CoM in the sole's frame
        self._in_sole_foot = -1
        self._flat_sole = np.tile(np.eye(4), (2, 1, 1))
        self.com_m = np.zeros(3)
        self.cp_m = np.zeros(2)
        self.cp_ref_m = np.zeros(2)
        self.outside_m = -np.inf
        self.ground_z_m = 0.0
        self.support_box_m = np.zeros(4)
        self.flag = False
        self._margin_used_m = float(margin_m)
        self.reset_watch()
        # numba compiles a kernel on its first call: make that now, not in the first period
        # of a run (seconds on a fresh install; cached afterwards)
        _support(self._flat_sole.copy(), True, True, self._corners, np.zeros(2), self.margin_m,
                 self.corner_tolerance_m, np.zeros(4), self._flat_sole.copy())
        command_configuration(np.zeros(len(model.joint_names)), np.zeros(len(model.joint_names)),
                              np.zeros(len(model.joint_names)), np.zeros(self.robot.model.nq),
                              self.robot.q_index)

    def reset_watch(self) -> None:
        """Forget the run's worst margin and contact losses."""
        self.min_margin_m = math.inf
        self.min_margin_t_s: float | None = None
        self.feet_loaded: tuple[bool, bool] | None = None
        self.contact_losses = 0
        self._unloaded_periods = 0

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        self.flag = False
        self._outside_periods = 0
        self.reset_watch()

    def status(self) -> SupportStatus:
        """What a viewer shows of the balance (see :class:`SupportStatus`)."""
        return SupportStatus(
            margin_m=self.margin_m - self.outside_m if math.isfinite(self.outside_m) else None,
            min_margin_m=self.min_margin_m if math.isfinite(self.min_margin_m) else None,
            min_margin_t_s=self.min_margin_t_s, feet_loaded=self.feet_loaded,
            contact_losses=self.contact_losses)

    def watch(self, t_s: float, contact: tuple[bool, bool]) -> None:
        """The run's worst margin and contact losses (as the balance report counts them)."""
        margin = self._margin_used_m - self.outside_m
        if margin < self.min_margin_m:
            self.min_margin_m, self.min_margin_t_s = margin, t_s
        self.feet_loaded = contact
        if all(contact):
            self._unloaded_periods = 0
            return
        self._unloaded_periods += 1
        lasted = self._unloaded_periods * self.dt_s
        if lasted > self._contact_loss_min_s + 1e-9 >= lasted - self.dt_s:
            self.contact_losses += 1

    def measure(self, state: RobotState, store: Store,
                q_cmd_rad: np.ndarray | None = None) -> bool:
        """Judge this period's estimate in ``store`` (and the reference from the command,
        rad); return True when the CP has been outside the shrunk support polygon with a foot
        on the ground for ``confirm_periods`` periods."""
        self.com_m = np.asarray(store[COM_WORLD], dtype=float)
        self.cp_m = np.ascontiguousarray(store[CAPTURE_POINT_WORLD][:2], dtype=float)
        measured = store[CONTACT]
        contact = measured = (bool(measured[0]), bool(measured[1]))
        plan = store.get(SUPPORT_PLAN)
        margin = self.margin_m
        if plan is not None:
            poses, contact = np.ascontiguousarray(plan.T_world_soles, dtype=float), (True, True)
            margin = self.margin_m if plan.margin_m is None else plan.margin_m
        else:  # the estimated soles
            poses = np.ascontiguousarray(store[T_WORLD_SOLES], dtype=float)
        self._margin_used_m = margin
        self.support_box_m = np.zeros(4)
        outside, ground_z = _support(poses, contact[0], contact[1], self._corners, self.cp_m,
                                     margin, self.corner_tolerance_m, self.support_box_m,
                                     self._flat_sole)
        if plan is not None and outside > 0.0:
            outside = min(outside, self._outside_with_carrying_swing(plan, measured, store))
        self.outside_m = outside
        self.ground_z_m = ground_z
        if q_cmd_rad is not None and (contact[0] or contact[1]):
            self.cp_ref_m = self._reference_com(q_cmd_rad, state, 0 if contact[0] else 1)
        self._outside_periods = self._outside_periods + 1 if outside > 0.0 else 0
        self.flag = self._outside_periods >= self.confirm_periods
        self.watch(state.time_s, measured)
        return self.flag

    def _outside_with_carrying_swing(self, plan: SupportPlan, measured: tuple[bool, bool],
                                     store: Store) -> float:
        """How far the CP lies outside the plan's soles with each sole the plan has swinging
        but the estimate still has in contact (its ankle sensor reads it carrying) taken
        where the estimate has it, laid flat on the plan's floor (m; inf: no such sole).

        A late hand-off: the plan's hull has the swing foot at its landing place from the
        period its swing starts, while the foot still carries the robot where it stands and
        the stance foot lands a few periods late. The fast 2 m walks of AVX-512 seed 22 (at
        7.30 s) and portable 22 (8.80 s) were stopped there with the capture point 3-35 mm
        outside the plan's hull and between the two soles that carried; with the stop
        relaxed neither fell (docs/history/walking.md, round 18)."""
        swinging = [plan.swinging[side] and measured[side] for side in range(2)]
        if not any(swinging):
            return math.inf
        poses = np.array(plan.T_world_soles, dtype=float)
        estimated = store[T_WORLD_SOLES]
        for side in range(2):
            if swinging[side]:  # on the plan's floor
                poses[side] = pose_laid_flat(estimated[side], poses[1 - side][2, 3])
        outside, _ = _support(poses, True, True, self._corners, self.cp_m, self._margin_used_m,
                              self.corner_tolerance_m, np.zeros(4), np.empty((2, 4, 4)))
        return outside

    def _reference_com(self, q_cmd_rad: np.ndarray, state: RobotState, foot: int) -> np.ndarray:
        """x, y (m) of the commanded posture's CoM standing with sole ``foot`` flat where it is
        (the reference CP of a static posture, as AutoBalancer's reference CoM)."""
        pmodel, data = self.robot.model, self.data
        changed = command_configuration(np.asarray(q_cmd_rad, dtype=float), state.q_rad,
                                        self._last_cmd, self._q_ref, self.robot.q_index)
        if changed or foot != self._in_sole_foot:
            com_torso = pin.centerOfMass(pmodel, data, self._q_ref, False)  # torso at origin
            oMf = pin.updateFramePlacement(pmodel, data, self._sole_ids[foot])  # T_torso_sole
            self._in_sole, self._in_sole_foot = oMf.actInv(com_torso), foot  # R^T (com - p)
        (f00, f01, f02, fx), (f10, f11, f12, fy), _, _ = self._flat_sole[foot].tolist()
        c0, c1, c2 = self._in_sole.tolist()  # flat[:2, :3] @ in_sole + flat[:2, 3] in floats
        return np.array((f00 * c0 + f01 * c1 + f02 * c2 + fx, f10 * c0 + f11 * c1 + f12 * c2 + fy))

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        flag = self.measure(state, cycle.store, q_rad)
        cycle.store[SUPPORT_BOX_WORLD] = self.support_box_m
        if flag:
            cycle.flags.add("cp-outside")
            if self.request_estop:
                cycle.estop_requests.add("capture-point")
        info = cycle.info  # Python floats in one conversion per vector (tolist)
        info["com_x_m"], info["com_y_m"], info["com_z_m"] = self.com_m.tolist()[:3]
        cp_x, cp_y = self.cp_m.tolist()[:2]
        ref_x, ref_y = self.cp_ref_m.tolist()[:2]
        info["cp_x_m"], info["cp_y_m"] = cp_x, cp_y
        info["cp_ref_x_m"], info["cp_ref_y_m"] = ref_x, ref_y
        info["cp_error_x_m"] = cp_x - ref_x
        info["cp_error_y_m"] = cp_y - ref_y
        info["cp_outside_m"] = float(self.outside_m)
        (info["support_min_x_m"], info["support_max_x_m"], info["support_min_y_m"],
         info["support_max_y_m"]) = self.support_box_m.tolist()[:4]
        info["cp_flag"] = 1.0 if flag else 0.0
        return q_rad
