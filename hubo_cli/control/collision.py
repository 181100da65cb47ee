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
velocity and acceleration, per joint; sampled every 0.05 rad, so a fast motion cannot step over
a thin part of the body), so the hold can start early enough to stay clear. A pair closer than
``tolerance_m`` is a collision: the arms go back to the last safe input (jerk-limited, within
the joint limits) and hold; once the input is clear again they recover toward the live
input, arriving no sooner than ``recover_s`` (2.5 s). The way back is checked too: a straight
joint-space path between two clear postures can pass through the body, so while recovering the
output itself is checked on its way to where it would stop, and it holds where it is if that
comes within ``BLOCK_M`` of the body (retrying when the input has moved, or after
``recover_s``).

Logged: ``collision_distance_m`` is the closest pair at the posture this module passes on (what
the robot is told: the number that must never be negative), ``collision_ahead_m`` the closest
pair of the input where it is or would stop, whichever is closer (what starts a hold; it goes
negative while the operator's goal lies inside the body and the arms hold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.control.limits import JointLimits, braking_distance, braking_distance_of
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.otg import JointTracker
from hubo_cli.control.pin_robot import PinRobot, load_pin_robot
from hubo_cli.control.status import SafetyEvent
from hubo_cli.geometry import rpy_to_matrix
from hubo_cli.model import LEGS, DrillShape, RobotModel
from hubo_cli.state import RobotState
from hubo_cli.urdf import DRILL_FRAME

TOLERANCE_M = 0.01   # MoveIt Servo's self-collision proximity threshold
RECOVER_S = 2.5      # hrpsys default_recover_time
SAMPLE_RAD = 0.05     # the way to a stopping posture is checked every this much joint travel
MAX_SAMPLES = 8       # ... in at most this many checks (about 30 us each)
STILL_RAD = 1e-7     # joints moving less than this move no point of a link within 1 m of them
                     # by more than 0.1 um (0.6 um for a chain of six): within coal's GJK
                     # tolerance, so the distances they set are taken as unchanged
BLOCK_M = 0.01       # while recovering, the output stopping this close to the body holds it
CLOSING_M = 1e-4     # ... if it is closing in by more than this
UNBLOCK_RAD = 0.05   # after the way back was blocked, retry once the input moved this far
                     # (or after recover_s)
REFRESH_M = 0.01     # the bounded re-checks compute every pair again once a geometry can
                     # have moved this far since the last full pass
REFERENCES = 2       # ... against the last this many full passes
BOUND_SLACK_M = 1e-4  # ... and compute every pair whose bound is within this of the closest
                      # (far above coal's GJK tolerance, 1e-6 m)


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
    when they move, the pairs are bounded (:meth:`_closest_bounded`): each pair's distance at the
    last full pass, less how far its geometries can have moved since, leaves out the pairs that
    cannot be the closest, so a slowly moving arm (a cut) costs one or two pairs a check, not
    all of them; every pair is computed again once a geometry can have moved 1 cm.

    Args:
        model: the robot model.
        drill: add the drill capsules to the right hand.
        pairs: link pairs to check (default :func:`default_pairs`).
    """

    def __init__(self, model: RobotModel, drill: bool = False,
                 pairs: list[tuple[str, str]] | None = None) -> None:
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
        # bounded re-checks (see _closest_bounded): how far each geometry can have moved
        self._lever = self._levers()
        pairs = geom.collisionPairs
        self._pair_first = np.array([pair.first for pair in pairs], dtype=int)
        self._pair_second = np.array([pair.second for pair in pairs], dtype=int)
        unpaired = np.setdiff1d(np.arange(len(self._lever)),
                                np.r_[self._pair_first, self._pair_second])
        self._lever[unpaired] = 0.0  # a geometry in no pair (a sole) never calls for a pass
        # the last full passes (at most REFERENCES): configuration, each pair's distance there;
        # the most recently used first (a detector checks its input and where it would stop,
        # two postures a little apart, in turn: each keeps its own)
        self._refs: list[tuple[np.ndarray, np.ndarray]] = []
        self._bound = np.zeros(len(pairs))      # each pair's lower bound now
        _pair_bounds(self._q, self._q.copy(), self._lever, self._bound, self._pair_first,
                     self._pair_second, REFRESH_M, self._bound)  # compile now, not in a period

    def _levers(self) -> np.ndarray:
        """(geometries x configuration entries): for each joint that moves a geometry, a
        bound on how far any of its points lies from the joint's origin (m), whatever the
        posture: the joints' offsets along the chain, the geometry's placement and its
        bounding sphere. A point at most r from a revolute joint's axis moves at most
        r |dq| when the joint turns by dq, so ``lever @ |q - q_ref|`` bounds each geometry's
        motion since q_ref."""
        pmodel = self.robot.model
        lever = np.zeros((len(self.geom.geometryObjects), pmodel.nq))
        for g, obj in enumerate(self.geom.geometryObjects):
            shape = obj.geometry
            shape.computeLocalAABB()
            reach = (float(np.linalg.norm(obj.placement.translation))
                     + float(np.linalg.norm(shape.aabb_center)) + float(shape.aabb_radius))
            joint = obj.parentJoint
            while joint > 0:  # from the geometry's joint up to the root
                lever[g, pmodel.joints[joint].idx_q] = reach
                reach += float(np.linalg.norm(pmodel.jointPlacements[joint].translation))
                joint = pmodel.parents[joint]
        return lever

    def _add_drill(self, geom: pin.GeometryModel, drill: DrillShape) -> None:
        pmodel = self.robot.model
        frame = pmodel.frames[self.robot.frame_id(DRILL_FRAME)]
        # capsules along the bit axis (frame x): coal capsules lie along their local z
        R = rpy_to_matrix(0.0, np.pi / 2, 0.0)
        body_mid = drill.body_front_m - drill.body_length_m / 2
        bit_mid = (drill.body_front_m + drill.bit_tip_m) / 2
        bit_length = drill.bit_tip_m - drill.body_front_m
        parts = [("drill_0", coal.Capsule(drill.body_radius_m, drill.body_length_m), body_mid),
                 ("drill_1", coal.Capsule(drill.bit_radius_m, bit_length), bit_mid)]
        for name, shape, x in parts:
            placement = frame.placement * pin.SE3(R, np.array([x, 0.0, 0.0]))
            obj = pin.GeometryObject(name, frame.parentJoint, placement, shape)
            geom.addGeometryObject(obj)

    def check(self, q_rad: np.ndarray) -> Clearance:
        """The closest checked pair for the 24 joints ``q_rad`` (rad)."""
        q = self.robot.configuration(q_rad, out=self._q)
        if not self.pair_names:
            return Clearance(np.inf, ("", ""))
        pmodel = self.robot.model
        key = q[self._still_q]
        still = (self._last_key is not None
                 and float(abs(key - self._last_key).max()) <= STILL_RAD)
        self._last_key = key
        if not still:  # the other joints move too
            self._remembered = None
            distance_m, best = self._closest_bounded(q)
            return Clearance(distance_m, self.pair_names[best])
        pin.forwardKinematics(pmodel, self.data, q)
        legs, others = self._split
        if (self._remembered is None
                or float(abs(key - self._remembered[0]).max()) > STILL_RAD):
            self._remembered = (key, *self._closest(others))
        closest = min(self._closest(legs), self._remembered[1:])  # ties: the first pair
        return Clearance(closest[0], self.pair_names[closest[1]])

    def _closest_bounded(self, q: np.ndarray) -> tuple[float, int]:
        """(distance, pair index) of the closest pair at configuration ``q``, computing only
        the pairs that can be it. Each pair's distance at a recent full pass (the first of
        the last REFERENCES from which no geometry can have moved REFRESH_M), less how far
        its two geometries can have moved since (:meth:`_levers`), bounds it from below; the
        pair with the lowest bound is computed, and then every pair whose bound does not
        exceed that distance (plus BOUND_SLACK_M, far above coal's tolerance): a pair left
        out is further than the closest. Without such a pass, every pair is computed. The
        result is a full pass's to coal's GJK tolerance (its guesses start from each pair's
        last result)."""
        pmodel, geom, data = self.robot.model, self.geom, self.geom_data
        bound = self._bound
        for k, (ref_q, ref_m) in enumerate(self._refs):
            first = _pair_bounds(q, ref_q, self._lever, ref_m, self._pair_first,
                                 self._pair_second, REFRESH_M, bound)
            if first < 0:
                continue
            if k:
                self._refs.insert(0, self._refs.pop(k))
            pin.updateGeometryPlacements(pmodel, self.data, geom, data, q)
            nearest = pin.computeDistance(geom, data, first).min_distance
            best_m, best = np.inf, len(self.pair_names)
            for i in np.flatnonzero(bound <= nearest + BOUND_SLACK_M).tolist():
                d = nearest if i == first else pin.computeDistance(geom, data, i).min_distance
                if d < best_m:  # in pair order, the first of equals: as a full pass
                    best_m, best = d, i
            return float(best_m), best
        best = pin.computeDistances(pmodel, self.data, geom, data, q)
        ref_m = np.array([r.min_distance for r in data.distanceResults])
        self._refs = [(q.copy(), ref_m), *self._refs[:REFERENCES - 1]]
        return float(ref_m[best]), best

    def _closest(self, data: pin.GeometryData) -> tuple[float, int]:
        """(distance, pair index) of the closest active pair of ``data`` at the placements of
        the last forward kinematics; (inf, number of pairs) when it has none."""
        pmodel, geom = self.robot.model, self.geom
        pin.updateGeometryPlacements(pmodel, self.data, geom, data)
        best = pin.computeDistances(geom, data)
        if best >= len(self.pair_names):
            return np.inf, best
        return float(data.distanceResults[best].min_distance), best


@nb.njit(cache=True, nogil=True)
def _pair_bounds(q, ref_q, lever, ref_m, first, second, refresh_m, bound):
    """:meth:`SelfCollisionChecker._closest_bounded`'s bounds: each geometry's largest motion
    since ``ref_q`` (``lever @ |q - ref_q|``, m), then each pair's lower bound (its distance
    ``ref_m`` then, less both motions) into ``bound``. Returns the pair of the lowest bound, or
    -1 once a geometry can have moved more than ``refresh_m`` (every pair is due again)."""
    n_geom, n_q = lever.shape
    moved = np.empty(n_geom)
    for g in range(n_geom):
        m = 0.0
        for j in range(n_q):
            if lever[g, j] != 0.0:
                m += lever[g, j] * abs(q[j] - ref_q[j])
        if m > refresh_m:
            return -1
        moved[g] = m
    lowest = 0
    for i in range(ref_m.shape[0]):
        bound[i] = ref_m[i] - moved[first[i]] - moved[second[i]]
        if bound[i] < bound[lowest]:
            lowest = i
    return lowest


@nb.njit(cache=True, nogil=True)
def _input_ahead(q_rad, last_in, w_last, dt_s, lower, upper, amax, jmax, q_in, w_in, ahead):
    """The input's side of :meth:`CollisionDetector.update` in one compiled pass: the input
    (a NaN entry keeps the last input), its speed and acceleration by differences, and where
    it would stop if it braked now (:func:`~hubo_cli.control.limits.braking_distance`, within
    the position limits), written to ``q_in``, ``w_in`` and ``ahead``."""
    for i in range(q_rad.shape[0]):
        q = q_rad[i] if math.isfinite(q_rad[i]) else last_in[i]
        w = (q - last_in[i]) / dt_s
        q_in[i] = q
        w_in[i] = w
        stop = q + braking_distance_of(w, (w - w_last[i]) / dt_s, amax[i], jmax[i])
        ahead[i] = min(max(stop, lower[i]), upper[i])


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
        self.dt_s = float(dt_s)
        self.tolerance_m = float(tolerance_m)
        self.recover_s = float(recover_s)
        self.block_m = BLOCK_M
        if joints is None:
            joints = model.limb("right-arm").joints + model.limb("left-arm").joints
        self.index = np.array([model.joint_names.index(j) for j in joints], dtype=int)
        self.checker = SelfCollisionChecker(model, drill=drill)
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

    def reset(self, q_rad: np.ndarray, state: RobotState) -> None:
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

    def _closest_on_way(self, q: np.ndarray, stop: np.ndarray) -> Clearance:
        """The closest pair along the way from ``q`` to its stopping posture ``stop`` (sampled
        every ``SAMPLE_RAD`` of the largest joint's travel, so a thin part of the body between
        the two is not stepped over); ``q`` itself not included."""
        n = min(MAX_SAMPLES, max(1, math.ceil(float(abs(stop - q).max()) / SAMPLE_RAD)))
        closest = None
        for k in range(1, n + 1):
            clearance = self.checker.check(q + (stop - q) * (k / n))
            if closest is None or clearance.distance_m < closest.distance_m:
                closest = clearance
        return closest

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q_in, w_in, ahead = np.empty((3, len(q_rad)))
        limits = self.limits
        _input_ahead(np.asarray(q_rad, dtype=float), self.last_in, self._w_last, self.dt_s,
                     limits.lower_rad, limits.upper_rad, limits.acceleration_rad_s2,
                     limits.jerk_rad_s3, q_in, w_in, ahead)
        self.last_in = q_in
        self._w_last = w_in
        at_input = self.checker.check(q_in)
        clearance = min(self._closest_on_way(q_in, ahead), at_input, key=lambda c: c.distance_m)
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
        self.last_clearance = at_input if passed_on else self.checker.check(out)
        cycle.info["collision_distance_m"] = self.last_clearance.distance_m
        self.out3, self.out2, self.out1 = self.out2, self.out1, out
        return out
