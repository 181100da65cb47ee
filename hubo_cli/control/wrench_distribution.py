"""The Stabilizer's force-moment distribution between the feet as a QP (multi-layer paper,
III-D.2, eq. 9-14; hrpsys-base ``ZMPDistributor.h``, which solves it with qpOASES).

The LIP feedback (:mod:`hubo_cli.control.lip_feedback`) asks for a total ground reaction: a
force ``F = (F_x, F_y, F_z)`` (N, world axes) acting at the ZMP ``u`` (m, the ground plane;
about ``u`` the horizontal moments are zero). Each sole in contact is a rectangle on the ground
plane (the paper projects the soles onto the horizontal plane) whose four vertices are the
:class:`~hubo_cli.model.FootShape` corners drawn in by ``cop_margin_m``. The unknowns are the
normal force at every vertex, ``f_ij >= 0`` (eq. 10), and each sole's horizontal force
``h_i = (h_ix, h_iy)``: 6 per foot, 12 in double support. A sole rolling on an edge (toe-heel
contact, :mod:`hubo_cli.walking.toe_heel`) touches along that line only: its four vertices are
put on the edge (``Contact.edge_x_m``). Constraints:

* the demand is met exactly (eq. 9, ``F = G f``, with the horizontal force rows added)::

      sum f_ij = F_z,   sum (p_ij,y - u_y) f_ij = 0,   -sum (p_ij,x - u_x) f_ij = 0,
      sum h_i = (F_x, F_y)

* every vertex pushes (eq. 10), so each sole's CoP lies inside its margined sole and the sole
  keeps contact;
* friction: ``|h_ix|, |h_iy| <= mu / sqrt(2) sum_j f_ij``, the pyramid inscribed in the cone of
  coefficient ``mu`` (a force inside it is inside the cone whatever the sole's yaw).

Cost (eq. 11): ``sum_i ||G_cop,i f||^2 W_cop + ||f||^2 W_f``, where ``G_cop,i f`` is foot i's
moment about its reference CoP ``p_cop,i`` (zero when its CoP is there) and
``W_f = w_f diag(1/alpha, .., 1/(1 - alpha), ..)`` on the vertex and horizontal forces of the
right and left foot. ``alpha`` is the right foot's share (Kajita 2010, hrpsys ``calcAlpha``): 1
when the ZMP is on the right sole, 0 on the left, in between the ZMP projected onto the segment
joining the two soles' points nearest to it. (The paper prints ``w_l = 1/(alpha - 1)``, which is
negative; ``1/(1 - alpha)`` is meant.)

Output (eq. 12-14): per foot the force ``(h_x, h_y, sum_j f_ij)`` and its CoP; the moment about
any point ``c`` on the ground is ``n_x = sum (p_y - c_y) f``, ``n_y = -sum (p_x - c_x) f``
(:meth:`WrenchSplit.moment_nm`), the rows of eq. 9's G and hrpsys's; eq. 13-14 print the
opposite signs, the moment the foot exerts on the floor.

Before the QP the demand is made feasible, and a flag says so: a ZMP outside the support
polygon (the convex hull of the margined vertices in contact) is moved to its nearest point;
a horizontal force outside the total friction pyramid is clipped to it. Then a solution always
exists (the force split in proportion to the normal forces satisfies each foot's pyramid). No
load (``F_z`` under ``MIN_LOAD_N``), no contact or a non-finite input gives ``found = False``
and zero wrenches: the caller holds its last command.

Solver: daqp (a dual active-set method, as qpOASES is; MIT; a wheel with no dependencies
beyond numpy), which takes the bounds f >= 0 directly and the equalities as constraints
of ``sense`` 5; see docs/stabilizer.md for the choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import daqp
import numba as nb
import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.kinematics.dh import JIT
from hubo_cli.model import FootShape, RobotModel

MIN_LOAD_N = 1.0          # below this total normal force nothing is distributed
UNLOADED_N = 1e-6         # a foot carrying less has its origin as CoP
ALPHA_FLOOR = 1e-3        # alpha kept in [floor, 1 - floor]: W_f stays finite
SENSE_EQUALITY = 5        # daqp's code of an equality row
INSIDE_TOLERANCE_M2 = 1e-12  # rounding: a point this near an edge (cross product) is on it
_INF = 1e30


@dataclass(frozen=True)
class DistributionParams:
    """The robot file's ``[wrench_distribution]`` table (see its comments).

    Attributes:
        cop_weight: W_cop on each foot's moment about its reference CoP (1/(N m)^2).
        force_weight: scale of W_f on the vertex and horizontal forces (1/N^2).
        friction_coefficient: mu of sole on floor.
        cop_margin_m: a CoP keeps this far inside its sole's edges (m).
    """

    cop_weight: float
    force_weight: float
    friction_coefficient: float
    cop_margin_m: float

    @classmethod
    def from_model(cls, model: RobotModel) -> DistributionParams:
        raw = model.raw_table("wrench_distribution")
        values = {}
        for name in cls.__dataclass_fields__:
            value = raw.get(name)
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not (math.isfinite(value) and value > 0):
                raise ConfigError(f"must be a positive number, got {quoted(value)}",
                                  path=str(model.source), field=f"wrench_distribution.{name}")
            values[name] = float(value)
        return cls(**values)


@dataclass(frozen=True)
class Contact:
    """A sole on the ground.

    Attributes:
        position_m: (x, y) of the sole frame's origin (the ankle's projection) in the world.
        yaw_rad: the sole's heading about the world z axis.
        cop_ref_m: (x, y) where its CoP should be (the toe-heel planner's); None: the origin.
        edge_x_m: the sole rolls on the edge across it at this x along the sole (m, the
            toe-heel planner's pivot, clamped into the margined sole): its contact is that
            line; None: the whole sole.
    """

    position_m: tuple[float, float]
    yaw_rad: float = 0.0
    cop_ref_m: tuple[float, float] | None = None
    edge_x_m: float | None = None


@dataclass
class WrenchSplit:
    """The distribution's result; arrays are indexed (right, left).

    Attributes:
        found: a distribution was computed (False: no load, no contact, a non-finite input or
            the solver's failure, see ``reason``; the feet's arrays are then zero).
        force_n: (2, 3) each foot's force, world axes (N).
        cop_m: (2, 2) each foot's CoP (m; a foot without load: its origin).
        vertex_force_n: (2, 4) the normal force at each vertex (N).
        zmp_m: the ZMP distributed (after ``zmp_clipped``).
        total_force_n: the force distributed (after ``friction_clipped``).
        alpha: the right foot's share of W_f.
        zmp_clipped: the ZMP asked for lay outside the support polygon.
        friction_clipped: the horizontal force asked for exceeded the friction pyramid.
        iterations: the solver's active-set iterations.
        reason: why ``found`` is False (empty otherwise).
    """

    found: bool
    force_n: np.ndarray
    cop_m: np.ndarray
    vertex_force_n: np.ndarray
    zmp_m: np.ndarray
    total_force_n: np.ndarray
    alpha: float = 0.5
    zmp_clipped: bool = False
    friction_clipped: bool = False
    iterations: int = 0
    reason: str = ""

    def moment_nm(self, foot: int, about_m) -> np.ndarray:
        """(n_x, n_y) of foot ``foot``'s vertex forces about the ground point ``about_m`` (N m);
        eq. 13-14 about the reference CoP, with eq. 9's signs (see the module docstring)."""
        fz = self.force_n[foot, 2]
        d = self.cop_m[foot] - np.asarray(about_m, dtype=float)
        return np.array([d[1] * fz, -d[0] * fz])


def _failed(reason: str, zmp_m, force_n) -> WrenchSplit:
    zmp = np.where(np.isfinite(zmp_m), zmp_m, 0.0)
    force = np.where(np.isfinite(force_n), force_n, 0.0)
    return WrenchSplit(False, np.zeros((2, 3)), np.zeros((2, 2)), np.zeros((2, 4)), zmp, force,
                       reason=reason)


@nb.njit(**JIT)
def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


@nb.njit(**JIT)
def convex_hull(points):
    """The convex hull of 2-D points (k, 2), counter-clockwise (Andrew's monotone chain)."""
    k = points.shape[0]
    order = np.argsort(points[:, 0] + 1e-9 * points[:, 1])  # x, ties by y
    pts = points[order]
    hull = np.empty((2 * k, 2))
    m = 0
    for i in range(k):  # lower half
        while m >= 2 and _cross(hull[m - 2], hull[m - 1], pts[i]) <= 0:
            m -= 1
        hull[m] = pts[i]
        m += 1
    lower = m + 1
    for i in range(k - 2, -1, -1):  # upper half
        while m >= lower and _cross(hull[m - 2], hull[m - 1], pts[i]) <= 0:
            m -= 1
        hull[m] = pts[i]
        m += 1
    return hull[:m - 1].copy()


@nb.njit(**JIT)
def project_into_polygon(point, polygon):
    """The point of the convex polygon (counter-clockwise vertices; two for a segment, the
    contact of a rolling sole) nearest to ``point``, and whether ``point`` was outside."""
    k = polygon.shape[0]
    inside = True
    for i in range(k):
        if _cross(polygon[i], polygon[(i + 1) % k], point) < -INSIDE_TOLERANCE_M2:
            inside = False
            break
    if inside:
        return point.copy(), False
    best = np.empty(2)
    best_d = np.inf
    for i in range(k):
        a, b = polygon[i], polygon[(i + 1) % k]
        ex, ey = b[0] - a[0], b[1] - a[1]
        length2 = ex * ex + ey * ey
        t = ((point[0] - a[0]) * ex + (point[1] - a[1]) * ey) / length2 if length2 > 0 else 0.0
        t = min(max(t, 0.0), 1.0)
        nx, ny = a[0] + t * ex, a[1] + t * ey
        d = (nx - point[0]) ** 2 + (ny - point[1]) ** 2
        if d < best_d:
            best_d = d
            best[0], best[1] = nx, ny
    return best, True


@nb.njit(**JIT)
def _nearest_on_sole(point, position, yaw, box):
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = point[0] - position[0], point[1] - position[1]
    lx = min(max(c * dx + s * dy, box[0]), box[1])
    ly = min(max(-s * dx + c * dy, box[2]), box[3])
    return np.array([position[0] + c * lx - s * ly, position[1] + s * lx + c * ly])


@nb.njit(**JIT)
def share_alpha(zmp, positions, yaws, box) -> float:
    """The right foot's share (hrpsys ``calcAlpha``): 1 on the right sole (index 0), 0 on the
    left, else the ZMP's place between the two soles' points nearest to it."""
    r_edge = _nearest_on_sole(zmp, positions[0], yaws[0], box)
    l_edge = _nearest_on_sole(zmp, positions[1], yaws[1], box)
    dx, dy = r_edge[0] - l_edge[0], r_edge[1] - l_edge[1]
    dd = dx * dx + dy * dy
    if dd < 1e-12:  # the ZMP on both soles (overlapping): an even split
        return 0.5
    a = (dx * (zmp[0] - l_edge[0]) + dy * (zmp[1] - l_edge[1])) / dd
    return min(max(a, 0.0), 1.0)


@nb.njit(**JIT)
def _qp_data(force, zmp_in, positions, yaws, refs, edges, local_vertices, box, right_only,
             cop_weight, force_weight, pyramid):
    """The feasible demand and the QP over x = [vertex forces (4 per foot), horizontal forces
    (2 per foot)]: daqp's H, A, bounds and senses."""
    n = positions.shape[0]
    nv, nx = 4 * n, 6 * n
    verts = np.empty((nv, 2))
    for k in range(n):
        c, s = math.cos(yaws[k]), math.sin(yaws[k])
        for j in range(4):
            lx, ly = local_vertices[j, 0], local_vertices[j, 1]
            if not math.isnan(edges[k]):  # rolling on an edge: the four on that line
                lx = min(max(edges[k], box[0]), box[1])
            verts[4 * k + j, 0] = positions[k, 0] + c * lx - s * ly
            verts[4 * k + j, 1] = positions[k, 1] + s * lx + c * ly
    polygon = convex_hull(verts)
    zmp, zmp_clipped = project_into_polygon(zmp_in, polygon)
    bound = pyramid * force[2]
    total = force.copy()
    friction_clipped = False
    for axis in range(2):
        if abs(total[axis]) > bound:
            total[axis] = math.copysign(bound, total[axis])
            friction_clipped = True
    if n == 2:
        alpha = min(max(share_alpha(zmp, positions, yaws, box), ALPHA_FLOOR), 1 - ALPHA_FLOOR)
        shares = np.array([alpha, 1 - alpha])
    else:
        alpha = 1.0 if right_only else 0.0
        shares = np.ones(1)
    H = np.zeros((nx, nx))
    for k in range(n):
        w = force_weight / shares[k]
        for a in range(4):
            ga0 = verts[4 * k + a, 1] - refs[k, 1]
            ga1 = -(verts[4 * k + a, 0] - refs[k, 0])
            for b in range(4):
                gb0 = verts[4 * k + b, 1] - refs[k, 1]
                gb1 = -(verts[4 * k + b, 0] - refs[k, 0])
                H[4 * k + a, 4 * k + b] = 2 * cop_weight * (ga0 * gb0 + ga1 * gb1)
            H[4 * k + a, 4 * k + a] += 2 * w
        for axis in range(2):
            H[nv + 2 * k + axis, nv + 2 * k + axis] = 2 * w
    m = 5 + 4 * n
    A = np.zeros((m, nx))
    for i in range(nv):
        A[0, i] = 1.0
        A[1, i] = verts[i, 1] - zmp[1]
        A[2, i] = -(verts[i, 0] - zmp[0])
    for k in range(n):
        A[3, nv + 2 * k] = 1.0
        A[4, nv + 2 * k + 1] = 1.0
    upper = np.empty(nx + m)
    lower = np.empty(nx + m)
    sense = np.zeros(nx + m, dtype=np.int32)
    upper[:nx] = _INF
    lower[:nv] = 0.0  # eq. 10
    lower[nv:nx] = -_INF
    demand = (total[2], 0.0, 0.0, total[0], total[1])
    for r in range(5):
        upper[nx + r] = lower[nx + r] = demand[r]
        sense[nx + r] = SENSE_EQUALITY
    r = 5
    for k in range(n):  # friction: +-h - mu' sum f <= 0
        for axis in range(2):
            for sign in (1.0, -1.0):
                for j in range(4):
                    A[r, 4 * k + j] = -pyramid
                A[r, nv + 2 * k + axis] = sign
                upper[nx + r] = 0.0
                lower[nx + r] = -_INF
                r += 1
    return verts, zmp, zmp_clipped, total, friction_clipped, alpha, H, A, upper, lower, sense


class WrenchDistributor:
    """Eq. 9-14 for the Hubo's soles (see the module docstring).

    Args:
        feet: the sole's shape (the robot file's ``[feet]``).
        params: the weights, friction and CoP margin.
    """

    def __init__(self, feet: FootShape, params: DistributionParams) -> None:
        m = params.cop_margin_m
        if 2 * m >= min(feet.length_m, feet.width_m):
            raise ConfigError(f"wrench_distribution.cop_margin_m {m} leaves no sole",
                              hint=f"keep it under half the sole's width ({feet.width_m} m)")
        corners = feet.sole_corners_m()[:, :2]
        centre = corners.mean(axis=0)
        self.vertices_local_m = np.ascontiguousarray(
            centre + (corners - centre) * (1 - 2 * m / np.array([feet.length_m, feet.width_m])))
        self.box_local_m = np.array([self.vertices_local_m[:, 0].min(),
                                     self.vertices_local_m[:, 0].max(),
                                     self.vertices_local_m[:, 1].min(),
                                     self.vertices_local_m[:, 1].max()])
        self.params = params
        self._pyramid = params.friction_coefficient / math.sqrt(2.0)

    @classmethod
    def from_model(cls, model: RobotModel) -> WrenchDistributor:
        return cls(model.feet, DistributionParams.from_model(model))

    def distribute(self, force_n, zmp_m, right: Contact | None,
                   left: Contact | None) -> WrenchSplit:
        """Split the total ground reaction ``force_n`` (3, N) acting at ``zmp_m`` (2, m)
        between the feet in contact (None: that foot is in the air)."""
        force = np.asarray(force_n, dtype=float).reshape(3)
        zmp = np.asarray(zmp_m, dtype=float).reshape(2)
        feet = [i for i, c in enumerate((right, left)) if c is not None]
        contacts = [c for c in (right, left) if c is not None]
        if not contacts:
            return _failed("no foot in contact", zmp, force)
        positions = np.array([c.position_m for c in contacts], dtype=float)
        yaws = np.array([c.yaw_rad for c in contacts], dtype=float)
        refs = np.array([c.position_m if c.cop_ref_m is None else c.cop_ref_m
                         for c in contacts], dtype=float)
        edges = np.array([math.nan if c.edge_x_m is None else c.edge_x_m for c in contacts],
                         dtype=float)
        if not (np.isfinite(force).all() and np.isfinite(zmp).all()
                and np.isfinite(positions).all() and np.isfinite(yaws).all()
                and np.isfinite(refs).all()
                and all(c.edge_x_m is None or math.isfinite(c.edge_x_m) for c in contacts)):
            return _failed("a non-finite demand or contact", zmp, force)
        if force[2] < MIN_LOAD_N:
            return _failed(f"no load ({force[2]:.3g} N)", zmp, force)
        p = self.params
        (verts, zmp, zmp_clipped, total, friction_clipped, alpha, H, A, upper, lower,
         sense) = _qp_data(force, zmp, positions, yaws, refs, edges, self.vertices_local_m,
                           self.box_local_m, feet[0] == 0, p.cop_weight, p.force_weight,
                           self._pyramid)
        x, _, exitflag, info = daqp.solve(H, np.zeros(H.shape[0]), A, upper, lower, sense)
        if exitflag != 1:
            return _failed(f"daqp exit flag {exitflag}", zmp, total)
        split = WrenchSplit(True, np.zeros((2, 3)), np.zeros((2, 2)), np.zeros((2, 4)), zmp,
                            total, alpha=alpha, zmp_clipped=zmp_clipped,
                            friction_clipped=friction_clipped,
                            iterations=int(info["iterations"]))
        n = len(contacts)
        for k, i in enumerate(feet):
            f = np.maximum(x[4 * k:4 * k + 4], 0.0)
            fz = float(f.sum())
            split.vertex_force_n[i] = f
            split.force_n[i] = (x[4 * n + 2 * k], x[4 * n + 2 * k + 1], fz)
            split.cop_m[i] = f @ verts[4 * k:4 * k + 4] / fz if fz > UNLOADED_N else positions[k]
        return split
