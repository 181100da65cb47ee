"""Self-collision detector (hrpsys CollisionDetector): hold the last safe posture, then recover.

Geometry: the URDF's collision primitives loaded into pinocchio + coal (boxes, cylinders,
spheres), plus, with ``drill=True``, two capsules for the drill held in the right hand (the
drill body and the bit, sized by the model's :class:`~hubo_cli.model.DrillShape` like the
URDF's drill, which has no collision shape of its own). Pairs checked: each arm's upper arm,
elbow, forearm and hand with the torso; forearm and hand with the head; elbow, forearm and hand
with the pelvis and both thighs; every right-arm link with every left-arm link; and the drill
with every link except the hand and forearm that hold it. Measured on the 2-core development
machine: one check of these 46 pairs (54 with the drill) costs about 30 us with pinocchio + coal
against about 145 us with PyBullet's ``getClosestPoints`` in a DIRECT client, so pinocchio is
used.

Only the arm joints are held (hrpsys ``collision_mask``); the legs pass through so that the
balancer keeps working. Each period the input command is checked where it is and on its way to
where it would stop if it braked now (its position plus the jerk-limited braking distance of its
velocity and acceleration, per joint, at the emergency braking limits while a stopper
brakes, flag ``estop-brake``; sampled every 0.05 rad, so a fast motion cannot step over
a thin part of the body), so the hold can start early enough to stay clear. A pair closer than
``tolerance_m`` is a collision: the arms go back to the last safe input (jerk-limited, within
the joint limits) and hold; once the input is clear again they recover toward the live
input, arriving no sooner than ``recover_s`` (2.5 s). The way back is checked too: a straight
joint-space path between two clear postures can pass through the body, so while recovering the
output itself is checked on its way to where it would stop, and it holds where it is if that
comes within ``BLOCK_M`` of the body (retrying when the input has moved, or after
``recover_s``).

Skipping far pairs and clear periods (a Lipschitz bound): a revolute joint turned by dq moves a
point it carries by at most |dq| times the point's distance from the joint's origin, which is at
most the sum of the joint offsets along the chain from that joint to the link plus the shape's
offset and bounding radius, whatever the posture (triangle inequality). Turning the joints one
after another from a posture q0 to q, a pair's distance thus falls by at most
sum_j |q_j - q0_j| r_j, with r_j that reach for the one shape of the pair joint j carries (0 for
a joint that carries both, as it moves them together; the legs count for the thighs). The
checker keeps each pair's last computed distance and the joints it was computed at; a check
bounds every pair from there and computes (one coal pass over the pairs it activates) only
those whose bound comes within the band, ``tolerance_m`` (or ``BLOCK_M`` if larger) plus
``SKIP_MARGIN_M`` (2 mm: far above coal's 1e-6 m GJK tolerance); the others report their bound.
A check's closest distance is therefore exact wherever it is within the band, and beyond the
band a lower bound that stays beyond it: every test against ``tolerance_m`` and ``BLOCK_M``
(and the way back's closing test, which only matters below ``BLOCK_M``) comes out as with exact
checks. While the mode is ``safe``, a period whose input and braking posture both lie in a box
around those postures where every pair's bound stays beyond the band needs no check at all.
Holds, recoveries and outputs are the same as with every pair computed in every period
(``skip = False``); only the logged distances beyond the band differ: they are bounds, never
more clearance than there is. Measured on the 2-core development machine: ``make bench``'s
pipeline (hands on fast circles) skips 29 % of its periods and computes about 4 of the 46
pairs in a check (about 3 checks in a checked period): its collision module's median falls from
160 to 96 us (mean of its CPU time, the bench's inputs replayed: 114 to 68 us; every pair in
every period: 130 us); the default ``task cut-rectangle`` skips 90 % of its 12,833 periods, so
there the module costs little either way (20.7 s of CPU for the run, as with one bound for all
pairs from the last input checked).

Logged: ``collision_distance_m`` is the closest pair at the posture this module passes on (what
the robot is told: the number that must never be negative), ``collision_ahead_m`` the closest
pair of the input where it is or would stop, whichever is closer (what starts a hold; it goes
negative while the operator's goal lies inside the body and the arms hold). In a skipped period
both are lower bounds (see above).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import coal
import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.control.estop import BRAKE_FLAG
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.status import CollisionStatus, SafetyEvent
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.geometry import rpy_to_matrix
from hubo_cli.model import LEGS, DrillShape, RobotModel
from hubo_cli.motion.limits import JointLimits, braking_distance, braking_distance_of
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.pin_robot import PinRobot, load_pin_robot
from hubo_cli.state import RobotState
from hubo_cli.urdf import DRILL_FRAME

TOLERANCE_M = 0.01   # MoveIt Servo's self-collision proximity threshold
RECOVER_S = 2.5      # hrpsys default_recover_time
SAMPLE_RAD = 0.05     # the way to a stopping posture is checked every this much joint travel
MAX_SAMPLES = 8       # ... in at most this many checks
STILL_RAD = 1e-7     # joints moving less than this move no point of a link within 1 m of them
                     # by more than 0.1 um (0.6 um for a chain of six): within coal's GJK
                     # tolerance, so the distances they set are taken as unchanged
BLOCK_M = 0.01       # while recovering, the output stopping this close to the body holds it
CLOSING_M = 1e-4     # ... if it is closing in by more than this
UNBLOCK_RAD = 0.05   # after the way back was blocked, retry once the input moved this far
                     # (or after recover_s)
SKIP_MARGIN_M = 0.002  # a period's checks are skipped while the Lipschitz lower bound of every
                       # pair over the period's postures stays this far beyond tolerance_m


WITNESS_MIN_M = 1e-5  # distance_gradient: closer shapes have no reliable normal
FLAT_RAD = 1e-3  # ... a face or an edge within this angle of facing the other shape: flat


SHAPE_KINDS = ("point", "flat", "box", "cylinder", "capsule")  # _support's kind, by index


def _shape_kind(shape) -> int:
    """How :func:`_support` treats a coal shape (an index of :data:`SHAPE_KINDS`)."""
    for kind, cls in (("point", coal.Sphere), ("box", coal.Box), ("cylinder", coal.Cylinder),
                      ("capsule", coal.Capsule)):
        if isinstance(shape, cls):
            return SHAPE_KINDS.index(kind)
    return SHAPE_KINDS.index("flat")  # another shape: taken as flat (never a gradient from it)


@nb.njit(cache=True, nogil=True)
def _support(kind, R, n, first):
    """How many directions (world) a shape of ``kind`` (:data:`SHAPE_KINDS`, rotation ``R``)
    touches its supporting plane of normal +-``n`` along within FLAT_RAD rad: 0 (a point), 1
    (an edge, a cylinder's or a capsule's side) or 2 (a face, a cylinder's cap); the first of
    them (a column of ``R``) to ``first``."""
    if kind == 0:  # a point
        return 0
    count, column = 0, 0
    if kind == 1:  # flat: its x and y
        count = 2
    else:
        for k in range(3):  # n against the shape's axes
            cos = n[0] * R[0, k] + n[1] * R[1, k] + n[2] * R[2, k]
            if kind == 2:  # a box: its axes square to n
                if abs(cos) < FLAT_RAD:
                    if count == 0:
                        column = k
                    count += 1
            elif k == 2:  # cylinders and capsules lie along their local z
                along = abs(cos)
                if along < FLAT_RAD:
                    count, column = 1, 2
                elif kind == 3 and 1.0 - along * along < FLAT_RAD * FLAT_RAD:
                    count = 2  # a cylinder's cap: its x and y
    for i in range(3):
        first[i] = R[i, column]
    return count


@nb.njit(cache=True, nogil=True)
def _witness_unique(kind_1, R_1, kind_2, R_2, n):
    """The two shapes' supports (:func:`_support`) meet in a point, not more: neither is a
    face with an edge or a face, nor are both parallel edges."""
    e_1, e_2 = np.empty(3), np.empty(3)
    count_1, count_2 = _support(kind_1, R_1, n, e_1), _support(kind_2, R_2, n, e_2)
    if count_1 == 0 or count_2 == 0:
        return True
    if count_1 == 2 or count_2 == 2:
        return False
    sx = e_1[1] * e_2[2] - e_1[2] * e_2[1]  # e_1 x e_2
    sy = e_1[2] * e_2[0] - e_1[0] * e_2[2]
    sz = e_1[0] * e_2[1] - e_1[1] * e_2[0]
    return not math.sqrt(sx * sx + sy * sy + sz * sz) < FLAT_RAD


_REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")


def _arm_links(side: str) -> list[str]:
    return [f"{side}SY_link", f"{side}EB_link", f"{side}WY_link", f"{side}WP_link"]


def default_pairs(drill: bool = False) -> list[tuple[str, str]]:
    """The link pairs that can touch (link names; ``drill`` for the drill capsules)."""
    pairs: list[tuple[str, str]] = []
    for side in "RL":
        arm = _arm_links(side)
        pairs += [(link, "torso") for link in arm]
        pairs += [(link, "head") for link in arm[2:]]
        pairs += [(link, hip) for link in arm[1:] for hip in ("pelvis", "RHP_link", "LHP_link")]
    pairs += [(a, b) for a in _arm_links("R") for b in _arm_links("L")]
    if drill:
        others = (["torso", "head", "pelvis", "RSY_link", "REB_link"] + _arm_links("L")
                  + ["RHP_link", "LHP_link", "RKN_link", "LKN_link"])
        pairs += [("drill", link) for link in others]
    return pairs


@dataclass
class Clearance:
    """The closest pair of one check: distance (m) and the two geometry names."""

    distance_m: float
    pair: tuple[str, str]


class SelfCollisionChecker:
    """Minimum distance between the checked link pairs for a joint vector (pinocchio + coal).

    The pairs fall into two groups: those a leg joint moves (an arm against a thigh) and the
    others, which only the other joints move. While those other joints stand (moved less than
    STILL_RAD since the last check: the walking robot's arms, which the trajectory generator's
    phase synchronisation creeps by 1e-12 to 1e-8 rad a period), the others' closest pair is
    remembered with the joints it was computed for, and a check costs the legs' pairs only;
    when they move, every pair is computed in one pass as before.

    Repeatable distances (``repeatable=True``): pinocchio's distance requests start each pair's
    GJK from its last answer (``enable_cached_gjk_guess``), so a distance computed a second
    time at the same joints differs within GJK's tolerance (1e-6 m; by 3e-9 m median on drawn
    postures), depending on what was computed before. Started from coal's fixed default guess
    instead, a pair's distance depends only on its placements, and :meth:`check_near` takes the
    distance of a pair whose joints (those with a rate for it) are exactly those of its last
    computed distance, or (every joint that moves one of its shapes exactly: pinocchio places a
    shape from its own chain's joints only) of the one before, without computing it again: the
    same number by construction (a posture the teleop's collision room returns to every other
    check, a still goal's, or an arm back at its last target after the legs and the other arm
    moved, costs nothing the second time); the one before bounds the pair too. Beyond the band
    a pair reports a lower bound, which depends on what was computed before (the room's
    searches take it as such). The pipeline's detector keeps the cached guess (its results as
    they were); the teleop's collision room uses the repeatable checker.

    Args:
        model: the robot model.
        drill: add the drill capsules to the right hand.
        pairs: link pairs to check (default :func:`default_pairs`).
        repeatable: the fixed initial guess, and no second computation of an unmoved pair.
    """

    def __init__(self, model: RobotModel, drill: bool = False,
                 pairs: list[tuple[str, str]] | None = None, repeatable: bool = False) -> None:
        self.robot: PinRobot = load_pin_robot(model)
        pmodel = self.robot.model
        path = str(self.robot.urdf_path)
        geom = pin.buildGeomFromUrdf(pmodel, path, pin.GeometryType.COLLISION)
        if drill:
            self._add_drill(geom, model.drill)
        by_link: dict[str, list[int]] = {}
        for i, obj in enumerate(geom.geometryObjects):
            link = obj.name.rsplit("_", 1)[0]
            by_link.setdefault(link, []).append(i)
        self.pair_names: list[tuple[str, str]] = []
        for a, b in pairs if pairs is not None else default_pairs(drill):
            for ia in by_link.get(a, ()):
                for ib in by_link.get(b, ()):
                    geom.addCollisionPair(pin.CollisionPair(ia, ib))
                    self.pair_names.append((geom.geometryObjects[ia].name,
                                            geom.geometryObjects[ib].name))
        self.geom = geom
        self.data = pmodel.createData()
        self._q = np.zeros(pmodel.nq)
        self.geom_data = pin.GeometryData(geom)  # every pair
        legs = {pmodel.getJointId(j) for limb in LEGS for j in model.limb(limb).joints}
        moved_by_legs = [not legs.isdisjoint(pmodel.supports[obj.parentJoint])
                         for obj in geom.geometryObjects]
        self._split = []  # the pairs the legs move, then the others: each active in its data
        for with_legs in (True, False):
            active = np.zeros((len(moved_by_legs), len(moved_by_legs)), dtype=bool)
            for pair in geom.collisionPairs:
                if (moved_by_legs[pair.first] or moved_by_legs[pair.second]) == with_legs:
                    active[min(pair.first, pair.second), max(pair.first, pair.second)] = True
            data = pin.GeometryData(geom)
            data.setActiveCollisionPairs(geom, active)
            self._split.append(data)
        # the configuration's entries the legs do not move: what the others' closest pair
        # depends on
        self._still_q = np.array([i for j in range(1, pmodel.njoints) if j not in legs
                                  for i in range(pmodel.joints[j].idx_q,
                                                 pmodel.joints[j].idx_q + pmodel.joints[j].nq)],
                                 dtype=int)
        self._last_key: np.ndarray | None = None
        self._remembered: tuple[np.ndarray, float, int] | None = None  # key, distance, pair
        self._last_full = True  # the last check computed every pair in geom_data
        self._legs_pair = np.array([moved_by_legs[p.first] or moved_by_legs[p.second]
                                    for p in geom.collisionPairs], dtype=bool)
        self.rate_m_rad = self._pair_rates()
        self.pair_joints, self.pair_rates = _joint_lists(self._pair_shape_joints(),
                                                         self.rate_m_rad)
        # check_near's bounds: each pair's last computed distance and the joints it was
        # computed at (-inf: none yet)
        self.anchor_q = np.zeros((len(self.pair_names), len(self.robot.q_index)))
        self.anchor_m = np.full(len(self.pair_names), -np.inf)
        # and the one before (a repeatable checker's bounds and reuse count it too)
        self.earlier_q = self.anchor_q.copy()
        self.earlier_m = self.anchor_m.copy()
        self._bounds_m = np.empty(len(self.pair_names))
        self._every_pair = np.ones(len(self.pair_names), dtype=bool)  # check_near's default
        self._near = np.zeros(len(self.pair_names), dtype=bool)  # the active pairs of:
        self._near_data = pin.GeometryData(geom)
        self._near_data.deactivateAllCollisionPairs()
        # live references into the results (the vector never resizes): five times as fast to
        # read as through distanceResults
        self._near_results = list(self._near_data.distanceResults)
        self._listed = np.zeros(2 * len(self.pair_names), dtype=np.int64)
        # the others' distances are taken at joints up to STILL_RAD away from the check's
        self._still_slack_m = np.where(self._legs_pair, 0.0,
                                       STILL_RAD * self.rate_m_rad.sum(axis=1))
        self.repeatable = bool(repeatable)
        if self.repeatable:  # distance_gradient's own data (only a repeatable checker has it)
            self._grad_data = pmodel.createData()
            self._pair_shapes = [tuple((g, _shape_kind(geom.geometryObjects[g].geometry),
                                        geom.geometryObjects[g].parentJoint)
                                       for g in (pair.first, pair.second))
                                 for pair in geom.collisionPairs]
            self._grad_geom_data = pin.GeometryData(geom)
            # compile distance_gradient's kernel now (for the layouts pinocchio hands it), not
            # in the first period that needs it
            pin.computeJointJacobians(pmodel, self._grad_data, pin.neutral(pmodel))
            J = pin.getJointJacobian(pmodel, self._grad_data, 1, pin.LOCAL_WORLD_ALIGNED)
            o, R = self._grad_data.oMi[1].translation, self._grad_data.oMi[1].rotation
            _witness_gradient(o, o + 1.0, 1.0, 2, R, 3, R, o, J, o, J, self.robot.q_index,
                              self.robot.q_index[:1], np.empty(1))
            self.bound_near(np.zeros(len(self.robot.q_index)), 0.0)  # and bound_near's
            with warnings.catch_warnings():  # coal marks the flag deprecated; it still rules
                warnings.simplefilter("ignore", DeprecationWarning)
                for data in (self.geom_data, *self._split, self._near_data,
                             self._grad_geom_data):
                    for request in data.distanceRequests:
                        request.enable_cached_gjk_guess = False
                        request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess

    def _pair_rates(self) -> np.ndarray:
        """How fast each joint can change each pair's distance: (pairs, joints), m/rad.

        A revolute joint j turned by dq moves a point p it carries by at most |dq| times p's
        distance from its axis, which is at most p's distance from the joint's origin, and that
        is at most the sum of the joint offsets along the chain from j to the link plus the
        shape's offset and bounding radius (triangle inequality: independent of the posture).
        Turning the joints one after another from q0 to q, a pair's distance changes by at
        most sum_j |q_j - q0_j| rate_j, where rate_j is that reach for the one shape of the
        pair that j carries; a joint carrying both shapes moves them rigidly together (0)."""
        pmodel, geom = self.robot.model, self.geom
        column = {int(qi): i for i, qi in enumerate(self.robot.q_index)}
        reach = np.zeros((len(geom.geometryObjects), len(self.robot.q_index)))
        for g, obj in enumerate(geom.geometryObjects):
            shape = obj.geometry
            shape.computeLocalAABB()
            radius = float(np.linalg.norm(shape.aabb_center)) + float(shape.aabb_radius)
            chain = [j for j in pmodel.supports[obj.parentJoint] if j > 0]
            beyond = float(np.linalg.norm(obj.placement.translation)) + radius
            for j in reversed(chain):  # from the link back to the root
                joint = pmodel.joints[j]
                if joint.shortname() not in _REVOLUTE:
                    raise ConfigError(f"the collision bound needs revolute joints, not "
                                      f"{joint.shortname()}", path=str(self.robot.urdf_path))
                if joint.idx_q in column:  # joints outside the 24 stand at zero
                    reach[g, column[joint.idx_q]] = beyond
                beyond += float(np.linalg.norm(pmodel.jointPlacements[j].translation))
        rates = np.zeros((len(geom.collisionPairs), reach.shape[1]))
        for k, pair in enumerate(geom.collisionPairs):
            a, b = (set(pmodel.supports[geom.geometryObjects[g].parentJoint])
                    for g in (pair.first, pair.second))
            for shape, own, other in ((pair.first, a, b), (pair.second, b, a)):
                for i in (column[pmodel.joints[j].idx_q] for j in own - other
                          if j > 0 and pmodel.joints[j].idx_q in column):
                    rates[k, i] = reach[shape, i]
        return rates

    def _pair_shape_joints(self) -> np.ndarray:
        """Which joints move each pair's shapes, either or both: (pairs, joints), bool. A
        pair's distance, as coal computes it, depends on those joints only."""
        pmodel, geom = self.robot.model, self.geom
        column = {int(qi): i for i, qi in enumerate(self.robot.q_index)}
        joints = np.zeros((len(geom.collisionPairs), len(self.robot.q_index)), dtype=bool)
        for k, pair in enumerate(geom.collisionPairs):
            for shape in (pair.first, pair.second):
                for j in pmodel.supports[geom.geometryObjects[shape].parentJoint]:
                    if j > 0 and pmodel.joints[j].idx_q in column:
                        joints[k, column[pmodel.joints[j].idx_q]] = True
        return joints

    def pair_distances_m(self) -> np.ndarray:
        """Each pair's distance (m) at the posture of the last :meth:`check`, or a lower bound of
        it where the check reused the distances of joints that stood (within STILL_RAD)."""
        if self._last_full:
            return np.array([r.min_distance for r in self.geom_data.distanceResults])
        legs, others = (np.array([r.min_distance for r in data.distanceResults])
                        for data in self._split)
        return np.where(self._legs_pair, legs, others) - self._still_slack_m

    def _add_drill(self, geom: pin.GeometryModel, drill: DrillShape) -> None:
        pmodel = self.robot.model
        frame = pmodel.frames[self.robot.frame_id(DRILL_FRAME)]
        # capsules along the bit axis (frame x): coal capsules lie along their local z
        R = rpy_to_matrix(0.0, np.pi / 2, 0.0)
        body_mid = drill.body_front_m - drill.body_length_m / 2
        bit_mid = (drill.body_front_m + drill.bit_tip_m) / 2
        parts = [("drill_0", coal.Capsule(drill.body_radius_m, drill.body_length_m), body_mid),
                 ("drill_1", coal.Capsule(drill.bit_radius_m, drill.bit_out_m), bit_mid)]
        for name, shape, x in parts:
            placement = frame.placement * pin.SE3(R, np.array([x, 0.0, 0.0]))
            obj = pin.GeometryObject(name, frame.parentJoint, placement, shape)
            geom.addGeometryObject(obj)

    def distance_gradient(self, q_rad: np.ndarray, pair: int,
                          columns: np.ndarray) -> np.ndarray | None:
        """The gradient of pair ``pair``'s distance with respect to the joints ``columns`` of
        the 24 ``q_rad`` (m/rad), from coal's witness points p1, p2 and normal n at ``q_rad``:
        n^T (J_2(p2) - J_1(p1)), the shapes' point Jacobians (world axes). None where that is
        not the derivative: shapes touching or overlapping (closer than ``WITNESS_MIN_M``), or
        witness points not unique (within ``FLAT_RAD`` of a face on a face or an edge, or two
        parallel edges: the distance has a kink there). A repeatable checker's only (the
        gradient is taken at the distance a repeated check gives)."""
        if not self.repeatable:
            raise ValueError("distance_gradient needs a repeatable checker")
        pmodel, data, gdata = self.robot.model, self._grad_data, self._grad_geom_data
        q = self.robot.configuration(q_rad, out=self._q)
        pin.computeJointJacobians(pmodel, data, q)
        pin.updateGeometryPlacements(pmodel, data, self.geom, gdata)
        result = pin.computeDistance(self.geom, gdata, pair)
        d = float(result.min_distance)
        if not d > WITNESS_MIN_M:
            return None
        (g1, kind1, joint1), (g2, kind2, joint2) = self._pair_shapes[pair]
        gradient = np.empty(len(columns))
        oMg, oMi, local = gdata.oMg, data.oMi, pin.LOCAL_WORLD_ALIGNED
        if not _witness_gradient(result.getNearestPoint1(), result.getNearestPoint2(), d,
                                 kind1, oMg[g1].rotation, kind2, oMg[g2].rotation,
                                 oMi[joint1].translation,
                                 pin.getJointJacobian(pmodel, data, joint1, local),
                                 oMi[joint2].translation,
                                 pin.getJointJacobian(pmodel, data, joint2, local),
                                 self.robot.q_index, columns, gradient):
            return None
        return gradient

    def check(self, q_rad: np.ndarray) -> Clearance:
        """The closest checked pair for the 24 joints ``q_rad`` (rad)."""
        q = self.robot.configuration(q_rad, out=self._q)
        if not self.pair_names:
            return Clearance(np.inf, ("", ""))
        pmodel, geom = self.robot.model, self.geom
        key = q[self._still_q]
        still = (self._last_key is not None
                 and float(abs(key - self._last_key).max()) <= STILL_RAD)
        self._last_key = key
        self._last_full = not still
        if not still:  # the other joints move too: every pair in one pass
            self._remembered = None
            best = pin.computeDistances(pmodel, self.data, geom, self.geom_data, q)
            return Clearance(float(self.geom_data.distanceResults[best].min_distance),
                             self.pair_names[best])
        pin.forwardKinematics(pmodel, self.data, q)
        legs, others = self._split
        if (self._remembered is None
                or float(abs(key - self._remembered[0]).max()) > STILL_RAD):
            self._remembered = (key, *self._closest(others))
        closest = min(self._closest(legs), self._remembered[1:])  # ties: the first pair
        return Clearance(closest[0], self.pair_names[closest[1]])

    def check_near(self, q_rad: np.ndarray, band_m: float,
                   pairs: np.ndarray | None = None) -> Clearance:
        """:meth:`check` computing only the pairs whose Lipschitz lower bound at ``q_rad`` (from
        their last distance here) comes within ``band_m``; the others report their bound. So
        the result equals the exact closest pair's where that is at most ``band_m`` and
        exceeds ``band_m`` (a lower bound of it) otherwise. ``pairs`` (a boolean per pair of
        :attr:`pair_names`, default all) limits the check to those pairs: the closest of them
        (inf if none)."""
        if not self.pair_names:
            return Clearance(np.inf, ("", ""))
        bounds, listed, data = self._bounds_m, self._listed, self._near_data
        n_changed, n_near, best = _pair_bounds(q_rad, self.anchor_q, self.anchor_m,
                                               self.earlier_q, self.earlier_m, self.pair_joints,
                                               self.pair_rates, band_m, self.repeatable, bounds,
                                               self._near, listed, self._every_pair
                                               if pairs is None else pairs)
        if n_changed:  # the near pairs are the active ones of data
            near = self._near
            for p in listed[:n_changed].tolist():
                (data.activateCollisionPair if near[p] else data.deactivateCollisionPair)(p)
        if n_near:
            pin.computeDistances(self.robot.model, self.data, self.geom, data,
                                 self.robot.configuration(q_rad, out=self._q))
            pairs = listed[n_changed:n_changed + n_near]
            results = self._near_results
            for p in pairs.tolist():
                bounds[p] = results[p].min_distance
            best = _take_near(q_rad, pairs, bounds, self.anchor_q, self.anchor_m,
                              self.earlier_q, self.earlier_m)
        return Clearance(float(bounds[best]), self.pair_names[best])

    def bound_near(self, q_rad: np.ndarray, band_m: float,
                   pairs: np.ndarray | None = None) -> float:
        """The distance :meth:`check_near` would return for ``q_rad``, ``band_m`` and ``pairs``
        when it would compute no pair (every pair's bound beyond ``band_m`` or its distance
        reused), to the last bit; NaN when it would compute one. Nothing of the checker
        changes (a reused earlier distance is not made the last one, as :meth:`check_near`
        makes it)."""
        if not self.pair_names:
            return np.inf
        return _bound_near(q_rad, self.anchor_q, self.anchor_m, self.earlier_q, self.earlier_m,
                           self.pair_joints, self.pair_rates, band_m, self.repeatable,
                           self._every_pair if pairs is None else pairs)

    def _closest(self, data: pin.GeometryData) -> tuple[float, int]:
        """(distance, pair index) of the closest active pair of ``data`` at the placements of
        the last forward kinematics; (inf, number of pairs) when it has none."""
        pmodel, geom = self.robot.model, self.geom
        pin.updateGeometryPlacements(pmodel, self.data, geom, data)
        best = pin.computeDistances(geom, data)
        if best >= len(self.pair_names):
            return np.inf, best
        return float(data.distanceResults[best].min_distance), best


def _joint_lists(shape_joints: np.ndarray, rate_m_rad: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per pair, the joints that move one of its shapes (``shape_joints``, pairs x joints), in
    increasing order and -1 after the last, and their rates (``rate_m_rad``; 0 for a joint
    moving both shapes): the bound kernels loop over these few (about 7 of the 24), adding
    the same terms in the same order as over every joint with a rate (a joint with a rate
    moves one of the pair's shapes: its rate comes from that shape's chain)."""
    width = max(1, int(shape_joints.sum(axis=1).max(initial=0)))
    joints = np.full((len(shape_joints), width), -1, dtype=np.int64)
    rates = np.zeros((len(shape_joints), width))
    for p, row in enumerate(shape_joints):
        listed = np.flatnonzero(row)
        joints[p, :len(listed)] = listed
        rates[p, :len(listed)] = rate_m_rad[p, listed]
    return joints, rates


@nb.njit(cache=True, nogil=True)
def _witness_gradient(p1, p2, d, kind1, R1, kind2, R2, o1, J1, o2, J2, q_index, columns, out):
    """n^T (J_2(p2) - J_1(p1)) on the joints ``columns`` (pinocchio's ``q_index[columns]``)
    to ``out``, n = (p2 - p1) / d: J_k the 6 x nv Jacobian (world axes) of the joint at
    ``o_k`` carrying shape k, the point's velocity v_o + w x (p - o), so n.v_p = n.v_o +
    ((p - o) x n).w. Returns False (``out`` unset) where the witness points are not unique
    (:func:`_witness_unique`, shapes of kinds ``kind1``, ``kind2``, rotations ``R1``, ``R2``)."""
    n = np.empty(3)
    for i in range(3):
        n[i] = (p2[i] - p1[i]) / d
    if kind1 != 0 and kind2 != 0 and not _witness_unique(kind1, R1, kind2, R2, n):
        return False
    c1, c2 = np.empty(3), np.empty(3)
    for c, p, o in ((c1, p1, o1), (c2, p2, o2)):
        rx, ry, rz = p[0] - o[0], p[1] - o[1], p[2] - o[2]
        c[0] = ry * n[2] - rz * n[1]
        c[1] = rz * n[0] - rx * n[2]
        c[2] = rx * n[1] - ry * n[0]
    for k in range(columns.shape[0]):
        j = q_index[columns[k]]
        g = 0.0
        for i in range(3):
            g += n[i] * (J2[i, j] - J1[i, j]) + c2[i] * J2[3 + i, j] - c1[i] * J1[3 + i, j]
        out[k] = g
    return True


@nb.njit(cache=True, nogil=True)
def _input_ahead(q_rad, last_in, w_last, dt_s, lower, upper, amax, jmax, q_in, w_in, ahead):
    """The input's side of :meth:`CollisionDetector.update` in one compiled pass: the input
    (a NaN entry keeps the last input), its speed and acceleration by differences, and where
    it would stop if it braked now (:func:`~hubo_cli.motion.limits.braking_distance`, within
    the position limits), written to ``q_in``, ``w_in`` and ``ahead``."""
    for i in range(q_rad.shape[0]):
        q = q_rad[i] if math.isfinite(q_rad[i]) else last_in[i]
        w = (q - last_in[i]) / dt_s
        q_in[i] = q
        w_in[i] = w
        stop = q + braking_distance_of(w, (w - w_last[i]) / dt_s, amax[i], jmax[i])
        ahead[i] = min(max(stop, lower[i]), upper[i])


@nb.njit(cache=True, nogil=True)
def _lower_bound(q_in, ahead, q0, d0, joints, rates):
    """The smallest Lipschitz lower bound of the pairs' distances (m) at ``q_in`` and over the
    box of postures whose every joint lies within its larger offset from pair p's ``q0[p]`` at
    ``q_in`` or ``ahead`` (which holds the way from one to the other), from the distances
    ``d0[p]`` at ``q0[p]`` and the rates of :meth:`SelfCollisionChecker._pair_rates` (as
    :func:`_joint_lists` lists them): (at_input, pair, box, pair)."""
    best_in, pair_in, best_box, pair_box = np.inf, 0, np.inf, 0
    for p in range(d0.shape[0]):
        near, far = d0[p], d0[p]
        for k in range(joints.shape[1]):
            j = joints[p, k]
            if j < 0:
                break
            if rates[p, k] > 0.0:
                a = abs(q_in[j] - q0[p, j])
                near -= rates[p, k] * a
                far -= rates[p, k] * max(a, abs(ahead[j] - q0[p, j]))
        if near < best_in:
            best_in, pair_in = near, p
        if far < best_box:
            best_box, pair_box = far, p
    return best_in, pair_in, best_box, pair_box


@nb.njit(cache=True, nogil=True)
def _pair_bound_each(q, q0, d0, q1, d1, joints, rates, band_m, reuse, taken):
    """Each pair's Lipschitz lower bound at ``q`` (m) from its distance ``d0[p]`` at ``q0[p]``:
    arrays (bound, moved, earlier), inf / False / False for a pair not ``taken``.
    ``joints[p]``, ``rates[p]``: the joints that move one of its shapes and their rates
    (:func:`_joint_lists`). ``moved``: its distance must be computed if the bound is within
    ``band_m``. With ``reuse``, a pair whose joints with a rate are exactly ``q0[p]``'s has not
    moved (its bound is its distance), and a pair that would be near counts its earlier
    distance ``d1[p]`` at ``q1[p]`` too: the bound is the larger of the two, and where every
    joint that moves one of its shapes is exactly ``q1[p]``'s the bound is ``d1[p]``, not
    moved, and ``earlier`` True. Every pair in one loop: a compiled call per pair cost ten
    times its arithmetic (each array argument's reference count taken and given back)."""
    n = d0.shape[0]
    bounds = np.full(n, np.inf)
    moved_each = np.zeros(n, dtype=np.bool_)
    earlier_each = np.zeros(n, dtype=np.bool_)
    for p in range(n):
        if not taken[p]:
            continue
        bound = d0[p]
        moved = not reuse or d0[p] == -np.inf
        for k in range(joints.shape[1]):
            j = joints[p, k]
            if j < 0:
                break
            if rates[p, k] > 0.0:
                bound -= rates[p, k] * abs(q[j] - q0[p, j])
                moved = moved or q[j] != q0[p, j]
        if moved and reuse and bound <= band_m and d1[p] != -np.inf:
            # (the loop above again, for the earlier distance, written out: a compiled helper
            # for both, even inline="always", took _bound_near from 1.7 to 4.5 us)
            earlier = d1[p]
            moved_1 = False
            for k in range(joints.shape[1]):
                j = joints[p, k]
                if j < 0:
                    break
                if rates[p, k] > 0.0:
                    earlier -= rates[p, k] * abs(q[j] - q1[p, j])
                # every joint that moves a shape, not only those with a rate: a joint moving
                # both shapes leaves the distance but not its last bits; the others leave the
                # shapes' placements to the last bit (pinocchio places a link from its own
                # chain's joints only), so coal would compute the same number
                moved_1 = moved_1 or q[j] != q1[p, j]
            if not moved_1:
                bound, moved = d1[p], False
                earlier_each[p] = True
            elif earlier > bound:
                bound = earlier
        bounds[p] = bound
        moved_each[p] = moved
    return bounds, moved_each, earlier_each


@nb.njit(cache=True, nogil=True)
def _pair_bounds(q, q0, d0, q1, d1, joints, rates, band_m, reuse, bounds, near, changed,
                 taken):
    """Each pair's bound at ``q`` (:func:`_pair_bound_each`, m, to ``bounds``); ``near`` set
    to the pairs that moved with a bound at most ``band_m``, listing in ``changed`` first the
    pairs whose entry changed, then the near pairs. Returns (how many changed, how many are
    near, the pair of the smallest bound). A pair at its earlier joints swaps its two
    distances (``q0``, ``d0`` stay the last one used). Only the pairs ``taken`` count: the
    others are neither bounded nor computed (their entry of ``bounds`` inf, their anchors
    untouched)."""
    each, moved, earlier = _pair_bound_each(q, q0, d0, q1, d1, joints, rates, band_m, reuse,
                                            taken)
    n_changed, best = 0, 0
    for p in range(d0.shape[0]):
        bounds[p] = each[p]
        if not taken[p]:
            if near[p]:
                near[p] = False
                changed[n_changed] = p
                n_changed += 1
            continue
        if earlier[p]:  # the earlier joints: the earlier distance, now the last used
            for j in range(q.shape[0]):
                q0[p, j], q1[p, j] = q1[p, j], q0[p, j]
            d0[p], d1[p] = d1[p], d0[p]
        if each[p] < bounds[best]:
            best = p
        compute = moved[p] and each[p] <= band_m
        if compute != near[p]:
            near[p] = compute
            changed[n_changed] = p
            n_changed += 1
    n_near = 0
    for p in range(d0.shape[0]):
        if near[p]:
            changed[n_changed + n_near] = p
            n_near += 1
    return n_changed, n_near, best


@nb.njit(cache=True, nogil=True)
def _bound_near(q, q0, d0, q1, d1, joints, rates, band_m, reuse, taken):
    """:func:`_pair_bounds`'s bounds at ``q`` (of the pairs ``taken``) without writing
    anything: their smallest, or NaN where a pair would be computed (moved, its bound at
    most ``band_m``)."""
    each, moved, _ = _pair_bound_each(q, q0, d0, q1, d1, joints, rates, band_m, reuse, taken)
    best = np.inf
    for p in range(d0.shape[0]):
        if moved[p] and each[p] <= band_m:
            return np.nan
        if each[p] < best:
            best = each[p]
    return best


@nb.njit(cache=True, nogil=True)
def _take_near(q, pairs, bounds, q0, d0, q1, d1):
    """The near ``pairs``' distances (in ``bounds``) become their anchors at ``q`` (``q0``,
    ``d0``; the anchors they replace become ``q1``, ``d1``); returns the pair of the smallest
    entry of ``bounds``."""
    for p in pairs:
        q1[p, :] = q0[p, :]
        d1[p] = d0[p]
        q0[p, :] = q
        d0[p] = bounds[p]
    best = 0
    for p in range(bounds.shape[0]):
        if bounds[p] < bounds[best]:
            best = p
    return best


class CollisionDetector(Module):
    """The ``collision`` module (see the module docstring).

    Args:
        model: the robot model (limits, URDF).
        dt_s: the control period (s).
        tolerance_m: a pair closer than this is a collision (m).
        recover_s: shortest time back to the live input once clear (s).
        drill: check the drill in the right hand too.
        joints: the joints it holds (hrpsys ``collision_mask``); default both arms, so the
            legs keep following the balancer while an arm is held.
        limits: override the model's limits (tests).

    Flags: ``collision`` while holding, ``recovering`` while going back. Info:
    ``collision_distance_m`` (closest pair at the output), ``collision_ahead_m`` (closest pair
    where the input would stop). Attributes: ``last_clearance`` (at the output),
    ``ahead_clearance`` (where the input would stop), ``mode`` (``safe``, ``hold``,
    ``recover``), ``events``.
    """

    name = "collision"
    log_columns = ("collision_distance_m", "collision_ahead_m")

    def __init__(self, model: RobotModel, dt_s: float, tolerance_m: float = TOLERANCE_M,
                 recover_s: float = RECOVER_S, drill: bool = False,
                 joints: tuple[str, ...] | None = None,
                 limits: JointLimits | None = None) -> None:
        self.limits = limits or JointLimits.from_model(model)
        # while a wrist-torque stop brakes, its input would stop at the braking limits
        self._brake_limits = self.limits.for_emergency_brake(model)
        self.dt_s = float(dt_s)
        self.tolerance_m = float(tolerance_m)
        self.recover_s = float(recover_s)
        self.block_m = BLOCK_M
        if joints is None:
            joints = model.limb("right-arm").joints + model.limb("left-arm").joints
        self.index = np.array([model.joint_names.index(j) for j in joints], dtype=int)
        self.checker = SelfCollisionChecker(model, drill=drill)
        # the Lipschitz skip (False: every period and every pair checked, for comparison; no
        # pairs: nothing to skip)
        self.skip = bool(self.checker.pair_names)
        self.band_m = max(self.tolerance_m, self.block_m) + SKIP_MARGIN_M
        self.skipped_periods = 0
        self.checked_periods = 0
        self.tracker = JointTracker(self.limits.subset(self.index), self.dt_s)
        self.events: list[SafetyEvent] = []
        self.last_clearance: Clearance | None = None
        self.ahead_clearance: Clearance | None = None
        self._clear_state(np.zeros(self.limits.size))
        # numba compiles on the first call: make that now, not in the first period of a run
        braking_distance(np.zeros(self.limits.size), np.zeros(self.limits.size), self.limits)
        _input_ahead(*np.zeros((3, self.limits.size)), self.dt_s, self.limits.lower_rad,
                     self.limits.upper_rad, self.limits.acceleration_rad_s2,
                     self.limits.jerk_rad_s3, *np.zeros((3, self.limits.size)))
        lists = _joint_lists(np.ones((1, self.limits.size), dtype=bool),
                             np.ones((1, self.limits.size)))
        _lower_bound(*np.zeros((2, self.limits.size)), np.zeros((1, self.limits.size)),
                     np.zeros(1), *lists)
        anchors = (np.zeros((1, self.limits.size)), np.zeros(1)) * 2
        _pair_bounds(np.zeros(self.limits.size), *anchors, *lists, 0.0,
                     False, np.zeros(1), np.zeros(1, dtype=bool), np.zeros(2, dtype=np.int64),
                     np.ones(1, dtype=bool))
        _take_near(np.zeros(self.limits.size), np.zeros(1, dtype=np.int64), np.zeros(1),
                   *anchors)

    def _clear_state(self, q: np.ndarray) -> None:
        self.mode = "safe"
        self.safe_rad = q.copy()
        self.hold_rad = q[self.index].copy()
        self.last_in = q.copy()
        self._w_last = np.zeros_like(q)
        self.out1 = q.copy()
        self.out2 = q.copy()
        self.out3 = q.copy()
        self.t_recover_end_s = 0.0
        self._blocked_in: np.ndarray | None = None  # input when the way back was blocked
        self._blocked_t_s = 0.0

    def status(self) -> CollisionStatus:
        """What a viewer shows of the detector: its mode and the closest pair at its output."""
        clearance = self.last_clearance
        return CollisionStatus(self.mode, None if clearance is None else clearance.pair,
                               None if clearance is None else clearance.distance_m)

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        q = np.where(np.isfinite(q_rad), q_rad, state.q_rad).astype(float)
        self._clear_state(q)
        self.tracker.reset(q[self.index])

    def _seed_tracker(self) -> None:
        dt, i = self.dt_s, self.index
        v = (self.out1[i] - self.out2[i]) / dt
        a = (self.out1[i] - 2 * self.out2[i] + self.out3[i]) / dt**2
        self.tracker.reset(self.out1[i], v + 0.5 * a * dt, a)

    def _hold(self, t_s: float, hold_rad: np.ndarray, pair: tuple[str, str]) -> None:
        self._blocked_in = None
        self._seed_tracker()
        self.hold_rad = hold_rad[self.index].copy()
        self.mode = "hold"
        self.events.append(SafetyEvent(t_s, "collision", pair))

    def _stopping_posture(self, q: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """Where ``q`` (after q1, q2) would stop if it braked now (within the limits)."""
        v = (q - q1) / self.dt_s
        a = (q - 2 * q1 + q2) / self.dt_s**2
        return self.limits.clip(q + braking_distance(v, a, self.limits))

    def _check(self, q: np.ndarray) -> Clearance:
        """The closest pair at ``q``: exact, or beyond the band when skipping (see check_near)."""
        if self.skip:
            return self.checker.check_near(q, self.band_m)
        return self.checker.check(q)

    def _closest_on_way(self, q: np.ndarray, stop: np.ndarray) -> Clearance:
        """The closest pair along the way from ``q`` to its stopping posture ``stop`` (sampled
        every ``SAMPLE_RAD`` of the largest joint's travel, so a thin part of the body between
        the two is not stepped over); ``q`` itself not included."""
        n = min(MAX_SAMPLES, max(1, math.ceil(float(abs(stop - q).max()) / SAMPLE_RAD)))
        closest = None
        for k in range(1, n + 1):
            clearance = self._check(q + (stop - q) * (k / n))
            if closest is None or clearance.distance_m < closest.distance_m:
                closest = clearance
        return closest

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q_in, w_in, ahead = np.empty((3, len(q_rad)))
        limits = self._brake_limits if BRAKE_FLAG in cycle.flags else self.limits
        _input_ahead(np.asarray(q_rad, dtype=float), self.last_in, self._w_last, self.dt_s,
                     limits.lower_rad, limits.upper_rad, limits.acceleration_rad_s2,
                     limits.jerk_rad_s3, q_in, w_in, ahead)
        self.last_in = q_in
        self._w_last = w_in
        at_input = clearance = None
        if self.mode == "safe" and self.skip:
            near_m, near, far_m, far = _lower_bound(q_in, ahead, self.checker.anchor_q,
                                                    self.checker.anchor_m,
                                                    self.checker.pair_joints,
                                                    self.checker.pair_rates)
            if far_m > self.band_m:  # no posture checked this period can come within the band
                names = self.checker.pair_names
                at_input = Clearance(near_m, names[near])
                clearance = Clearance(far_m, names[far])
                self.skipped_periods += 1
        if clearance is None:
            self.checked_periods += 1
            at_input = self._check(q_in)
            clearance = min(self._closest_on_way(q_in, ahead), at_input,
                            key=lambda c: c.distance_m)
        self.ahead_clearance = clearance
        cycle.info["collision_ahead_m"] = clearance.distance_m
        colliding = clearance.distance_m <= self.tolerance_m
        i = self.index
        if colliding and self.mode != "hold":
            self._hold(cycle.t_s, self.safe_rad if self.mode == "safe" else self.out1,
                       clearance.pair)
        elif not colliding and self.mode == "hold" and (
                self._blocked_in is None
                or np.max(np.abs(q_in[i] - self._blocked_in)) > UNBLOCK_RAD
                or cycle.t_s - self._blocked_t_s >= self.recover_s):
            self.mode = "recover"
            self.t_recover_end_s = cycle.t_s + self.recover_s

        out = np.array(q_in, dtype=float)
        if self.mode == "safe":
            self.safe_rad = q_in
        elif self.mode == "hold":
            out[i] = self.tracker.track(self.hold_rad)
            cycle.flags.add("collision")
        else:
            remaining = self.t_recover_end_s - cycle.t_s
            sub = self.tracker.track(q_in[i], min_duration_s=remaining if remaining > 0 else None,
                                     target_v_rad_s=w_in[i])
            out[i] = sub
            cycle.flags.add("recovering")
            back = self._closest_on_way(out, self._stopping_posture(out, self.out1, self.out2))
            now_m = np.inf if self.last_clearance is None else self.last_clearance.distance_m
            if back.distance_m <= self.block_m and back.distance_m < now_m - CLOSING_M:
                # the way back runs into the body: hold where it is
                self._hold(cycle.t_s, self.out1, back.pair)
                self._blocked_in = q_in[i].copy()
                self._blocked_t_s = cycle.t_s
                out = np.array(q_in, dtype=float)
                out[i] = self.tracker.track(self.hold_rad)
                cycle.flags.discard("recovering")
                cycle.flags.add("collision")
            elif (remaining <= 0 and np.max(np.abs(sub - q_in[i])) < 1e-6
                    and np.max(np.abs(self.tracker.v - w_in[i])) < 1e-3):
                out = np.array(q_in, dtype=float)
                self.mode = "safe"
                self.safe_rad = q_in
        passed_on = self.mode == "safe" or np.array_equal(out, q_in)  # safe: out is q_in
        self.last_clearance = at_input if passed_on else self._check(out)
        cycle.info["collision_distance_m"] = self.last_clearance.distance_m
        self.out3, self.out2, self.out1 = self.out2, self.out1, out
        return out
