"""Capture-point monitor (hrpsys Stabilizer's CP check): flags a coming fall, asks for an e-stop.

Each period, from the *measured* joints and the torso pose in the world (the driver's
``T_world_torso``; without one, the IMU orientation at the origin, which is enough because only
relative positions matter):

* the centre of mass x_G of the URDF (pinocchio);
* its velocity, finite-differenced and low-passed at 4 Hz (first order, as hrpsys);
* the capture point CP = x_G + v_G / omega with omega = sqrt(g / (z_G - z_ground)), z_ground
  being the lowest sole in contact;
* the support polygon: the convex hull of the sole corners that touch the ground, i.e. of the
  feet in contact (both when the driver does not say; a lost contact counts after 50 ms)
  the corners within 5 mm of the lowest
  one, shrunk by ``margin_m`` (3 cm, hrpsys ``cp_check_margin``). A foot that starts to tip
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
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.phase import SUPPORT_PLAN, SupportPlan
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import PinRobot, load_pin_robot
from hubo_cli.state import RobotState

GRAVITY_M_S2 = 9.80665
CP_MARGIN_M = 0.03        # hrpsys cp_check_margin
CORNER_TOLERANCE_M = 0.005  # a sole corner higher than this above the lowest one is lifted
CONTACT_HOLD_S = 0.05       # a foot still counts as down this long after its last contact
VELOCITY_CUTOFF_HZ = 4.0  # hrpsys CoM velocity low-pass
SOLE_FRAMES = ("right_sole", "left_sole")
CONTACT_LOSS_MIN_S = 0.020  # a foot unloaded longer than this while standing: a contact loss


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
def _support(sole_pose, right_down, left_down, corners, com, velocity, margin, gravity,
             corner_tolerance, cp_out, box_out, flat_out):
    """Support polygon, capture point and how far it lies outside (see CapturePointMonitor).

    Writes the CP (2,), the soles laid flat on the ground (same x, y and heading; 2 x 4 x 4)
    and the box of the flat soles in contact, shrunk (4,); returns (outside m, ground z m).
    Without a foot on the ground: CP = CoM, outside = -inf.
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
        cp_out[0], cp_out[1] = com[0], com[1]
        return -np.inf, np.inf
    ground_z = world[:n, 2].min()
    points = np.empty((n, 2))
    m = 0
    for i in range(n):  # a corner lifted off the ground (a tipping foot) does not support
        if world[i, 2] <= ground_z + corner_tolerance:
            points[m, 0] = world[i, 0]
            points[m, 1] = world[i, 1]
            m += 1
    height = max(com[2] - ground_z, 1e-3)
    omega = math.sqrt(gravity / height)
    cp_out[0] = com[0] + velocity[0] / omega
    cp_out[1] = com[1] + velocity[1] / omega
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
    return outside_distance(hull, cp_out) + margin, ground_z


@nb.njit(cache=True, nogil=True)
def _configure(q, index, q_rad, T_world_torso, has_pose, quat_wxyz):
    """Pinocchio's floating-base ``q`` (in place): the joints ``q_rad`` at ``index``, the torso
    pose ``T_world_torso`` (4x4) or without one (``has_pose`` False) the rotation of the
    quaternion w, x, y, z at the origin. The same arithmetic as
    :func:`hubo_cli.geometry.quat_wxyz_to_matrix` and Eigen's rotation-matrix-to-quaternion
    (trace m00 + (m11 + m22)) that ``pin.Quaternion`` runs."""
    for i in range(q_rad.shape[0]):
        q[index[i]] = q_rad[i]
    R = np.empty((3, 3))
    if has_pose:
        for r in range(3):
            q[r] = T_world_torso[r, 3]
            for c in range(3):
                R[r, c] = T_world_torso[r, c]
    else:
        w, x, y, z = quat_wxyz[0], quat_wxyz[1], quat_wxyz[2], quat_wxyz[3]
        n = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        R[0, 0], R[1, 1], R[2, 2] = (1 - 2 * (y * y + z * z), 1 - 2 * (x * x + z * z),
                                     1 - 2 * (x * x + y * y))
        R[0, 1], R[0, 2], R[1, 2] = 2 * (x * y - w * z), 2 * (x * z + w * y), 2 * (y * z - w * x)
        R[1, 0], R[2, 0], R[2, 1] = 2 * (x * y + w * z), 2 * (x * z - w * y), 2 * (y * z + w * x)
        q[0] = q[1] = q[2] = 0.0
    t = R[0, 0] + (R[1, 1] + R[2, 2])
    if t > 0.0:  # q[3:7]: x, y, z, w
        t = math.sqrt(t + 1.0)
        q[6] = 0.5 * t
        t = 0.5 / t
        q[3] = (R[2, 1] - R[1, 2]) * t
        q[4] = (R[0, 2] - R[2, 0]) * t
        q[5] = (R[1, 0] - R[0, 1]) * t
    else:
        i = 0
        if R[1, 1] > R[0, 0]:
            i = 1
        if R[2, 2] > R[i, i]:
            i = 2
        j = (i + 1) % 3
        k = (j + 1) % 3
        t = math.sqrt(R[i, i] - R[j, j] - R[k, k] + 1.0)
        q[3 + i] = 0.5 * t
        t = 0.5 / t
        q[6] = (R[k, j] - R[j, k]) * t
        q[3 + j] = (R[j, i] + R[i, j]) * t
        q[3 + k] = (R[k, i] + R[i, k]) * t


@nb.njit(cache=True, nogil=True)
def _measure(com, prev_com, filtered, velocity, alpha, dt, sole_pose, right_down, left_down,
             corners, margin, gravity, corner_tolerance, cp_out, box_out, flat_out):
    """The CoM velocity low-passed in place (``velocity``: zero unless ``filtered``, with the
    previous CoM ``prev_com``), then :func:`_support`; ``prev_com`` becomes ``com``."""
    for i in range(3):
        if filtered:
            velocity[i] = velocity[i] + alpha * ((com[i] - prev_com[i]) / dt - velocity[i])
        else:
            velocity[i] = 0.0
        prev_com[i] = com[i]
    return _support(sole_pose, right_down, left_down, corners, com, velocity, margin, gravity,
                    corner_tolerance, cp_out, box_out, flat_out)


class CapturePointMonitor(Module):
    """The ``capture-point`` module (see the module docstring).

    Args:
        model: the robot model (URDF).
        dt_s: the control period (s).
        margin_m: shrink of the support polygon (m).
        corner_tolerance_m: a sole corner more than this above the lowest sole point no longer
            supports (the foot is tipping on an edge), m.
        contact_hold_s: a foot counts as in contact until it has reported none this long (s).
        cutoff_hz: low-pass cut-off of the CoM velocity (Hz).
        request_estop: request an emergency stop when the CP leaves the polygon.
        confirm_periods: periods in a row the CP must be outside before the flag.
        drill: the robot holds the drill in its right hand (its mass counts in the CoM).

    Attributes after each update: ``com_m`` (3,), ``cp_m`` (2,), ``cp_ref_m`` (2,),
    ``outside_m`` (CP beyond the shrunk polygon, m; > 0 = flag), ``ground_z_m`` (lowest sole
    in contact), ``support_box_m`` (min x, max x, min y, max y of the soles in contact taken
    flat, shrunk by the margin: the nominal thresholds), ``flag``; over the run (the live
    view): ``min_margin_m`` and ``min_margin_t_s`` (the capture point's smallest distance inside
    the support polygon, unshrunk, and when), ``feet_loaded`` (the driver's contacts, right and
    left, None unknown) and ``contact_losses`` (intervals longer than CONTACT_LOSS_MIN_S with a
    foot unloaded).

    It follows :data:`~hubo_cli.control.phase.SUPPORT_PLAN` (a phase's planned support, its
    sole poses and margin; None or unwritten: the measured soles in contact).
    """

    name = "capture-point"
    follows = (SUPPORT_PLAN,)
    log_columns = ("com_x_m", "com_y_m", "com_z_m", "cp_x_m", "cp_y_m", "cp_ref_x_m",
                   "cp_ref_y_m", "cp_error_x_m", "cp_error_y_m", "cp_outside_m",
                   "support_min_x_m", "support_max_x_m", "support_min_y_m", "support_max_y_m",
                   "cp_flag")

    def __init__(self, model: RobotModel, dt_s: float, margin_m: float = CP_MARGIN_M,
                 cutoff_hz: float = VELOCITY_CUTOFF_HZ, request_estop: bool = True,
                 corner_tolerance_m: float = CORNER_TOLERANCE_M,
                 contact_hold_s: float = CONTACT_HOLD_S, confirm_periods: int = 3,
                 drill: bool = False) -> None:
        self.dt_s = float(dt_s)
        self.confirm_periods = max(1, int(confirm_periods))
        self._outside_periods = 0
        self.contact_hold_s = float(contact_hold_s)
        self._last_contact_s: list[float | None] = [None, None]
        self.margin_m = float(margin_m)
        self.corner_tolerance_m = float(corner_tolerance_m)
        self.request_estop = request_estop
        tau = 1.0 / (2 * math.pi * cutoff_hz)
        self.alpha = self.dt_s / (self.dt_s + tau)
        # the body as it is: with the drill's 0.6 kg on the right hand
        self.robot: PinRobot = load_pin_robot(model, floating=True,
                                              urdf_path=model.urdf_path(drill))
        self.data = self.robot.model.createData()
        self._sole_ids = [self.robot.frame_id(f) for f in SOLE_FRAMES]
        self._corners = model.feet.sole_corners_m()
        self._q = np.zeros(self.robot.model.nq)
        self._q_ref = self.robot.configuration(np.zeros(len(model.joint_names)))  # at origin
        self._last_cmd = np.full(len(model.joint_names), np.nan)  # of the reference CoM
        self._in_sole: np.ndarray | None = None  # the reference CoM in the sole's frame
        self._in_sole_foot = -1
        self._eye = np.eye(4)
        self._sole_pose = np.zeros((2, 4, 4))
        self._flat_sole = np.tile(np.eye(4), (2, 1, 1))
        self._prev_com = np.zeros(3)
        self._filtered = False  # the velocity has a previous CoM to difference
        self.velocity_m_s = np.zeros(3)
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
        _measure(np.zeros(3), np.zeros(3), True, np.zeros(3), self.alpha, self.dt_s,
                 self._flat_sole.copy(), True, True, self._corners, self.margin_m, GRAVITY_M_S2,
                 self.corner_tolerance_m, np.zeros(2), np.zeros(4), self._flat_sole.copy())
        _configure(self._q, self.robot.q_index, np.zeros(len(model.joint_names)), self._eye,
                   True, np.array([1.0, 0.0, 0.0, 0.0]))
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

    def reset(self, q_rad: np.ndarray, state: RobotState) -> None:
        self._filtered = False
        self._last_contact_s = [None, None]
        self.velocity_m_s = np.zeros(3)
        self.flag = False
        self._outside_periods = 0
        self.reset_watch()

    def watch(self, state: RobotState) -> None:
        """The run's worst margin and contact losses (as the balance report counts them)."""
        margin = self._margin_used_m - self.outside_m
        if margin < self.min_margin_m:
            self.min_margin_m, self.min_margin_t_s = margin, state.time_s
        contact = state.feet_contact
        self.feet_loaded = None if contact is None else (bool(contact[0]), bool(contact[1]))
        if contact is None or all(contact):
            self._unloaded_periods = 0
            return
        self._unloaded_periods += 1
        lasted = self._unloaded_periods * self.dt_s
        if lasted > CONTACT_LOSS_MIN_S + 1e-9 >= lasted - self.dt_s:
            self.contact_losses += 1

    def _configuration(self, state: RobotState) -> np.ndarray:
        """Pinocchio's q of the measured joints and torso pose (without one, the IMU
        orientation at the origin: only relative positions matter)."""
        T = state.T_world_torso
        _configure(self._q, self.robot.q_index, np.asarray(state.q_rad, dtype=float),
                   self._eye if T is None else np.ascontiguousarray(T, dtype=float),
                   T is not None, np.asarray(state.imu_quat_wxyz, dtype=float))
        return self._q

    def _debounced_contact(self, state: RobotState) -> tuple[bool, bool]:
        """Feet contacts, each held for ``contact_hold_s`` after it was last reported (a
        simulated or sensed contact flickers for a period now and then)."""
        if state.feet_contact is None:
            return True, True
        held = []
        for k, touching in enumerate(state.feet_contact):
            if touching:
                self._last_contact_s[k] = state.time_s
            last = self._last_contact_s[k]
            held.append(bool(touching or (last is not None
                                          and state.time_s - last <= self.contact_hold_s)))
        return held[0], held[1]

    def measure(self, state: RobotState, q_cmd_rad: np.ndarray | None = None,
                plan: SupportPlan | None = None) -> bool:
        """Update the estimate from ``state`` (and the reference from the command, rad);
        return True when the CP has been outside the shrunk support polygon with a foot on the
        ground for ``confirm_periods`` periods. ``plan``: a phase's planned support (None: the
        measured soles in contact)."""
        pmodel, data = self.robot.model, self.data
        q = self._configuration(state)
        com = pin.centerOfMass(pmodel, data, q, False).copy()
        contact = self._debounced_contact(state)
        self.com_m = com
        margin = self.margin_m
        if plan is not None:
            poses, contact = np.ascontiguousarray(plan.T_world_soles, dtype=float), (True, True)
            margin = self.margin_m if plan.margin_m is None else plan.margin_m
        else:  # the measured soles (the placements of the joints' kinematics above)
            poses = self._sole_pose
            for k, fid in enumerate(self._sole_ids):
                poses[k] = pin.updateFramePlacement(pmodel, data, fid).homogeneous
        self._margin_used_m = margin
        outside, ground_z = _measure(com, self._prev_com, self._filtered, self.velocity_m_s,
                                     self.alpha, self.dt_s, poses, bool(contact[0]),
                                     bool(contact[1]), self._corners, margin, GRAVITY_M_S2,
                                     self.corner_tolerance_m, self.cp_m, self.support_box_m,
                                     self._flat_sole)
        self._filtered = True
        self.outside_m = outside
        self.ground_z_m = ground_z
        if q_cmd_rad is not None and (contact[0] or contact[1]):
            self.cp_ref_m = self._reference_com(q_cmd_rad, state, 0 if contact[0] else 1)
        self._outside_periods = self._outside_periods + 1 if outside > 0.0 else 0
        self.flag = self._outside_periods >= self.confirm_periods
        self.watch(state)
        return self.flag

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
        flat = self._flat_sole[foot]
        return flat[:2, :3] @ self._in_sole + flat[:2, 3]

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        flag = self.measure(state, q_rad, cycle.store.get(SUPPORT_PLAN))
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
