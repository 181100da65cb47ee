"""Collision room: arm targets keep the collision detector's measured clearance plus a margin.

The pipeline's collision detector (:mod:`hubo_cli.control.collision`) holds the arms when the
command, where it is or where it would stop, comes closer than its tolerance (10 mm) to the body.
An operator's goal that passes just outside the body (a hand brushing past the torso) would trip
that hold although nothing is wrong. :class:`CollisionRoom` treats such postures as not
reachable: an arm target closer than ``room_m`` to the body (the detector's own distance, coal
on the URDF's primitives) is replaced.

With the arms' goals (:meth:`CollisionRoom.keep` given ``goals``), the replacement is the pose
nearest to the goal among the clear ones, position first: from the last target, a few damped
least-squares steps toward the goal (orientation weighted ``ORIENTATION_WEIGHT_M_PER_RAD``
against the position), within the joint limits and the branch's box, each step the one of least
weighted error whose linearised clearance is the room (a step toward the body slides along it,
turning the hand where that costs least), accepted when it keeps the room and the error falls.
The arms in the band are searched one after the other, each against the closest of the pairs
its own joints move (a shape of that arm on either side): a pair the search cannot change, the
other arm's target deep in the torso, would give every step the same clearance and a zero
gradient, and let the searched arm into the body down to that depth. Whether the target keeps
the room is decided on every pair. A 6-joint arm reaches most positions in front of the chest
with its hand turned: with the start orientation the upper arm and elbow meet the torso 4-6 cm
inward of the free-mode ready pose (the shoulder roll moves them in); turned 15-20 deg, they
pass outside it. Without goals (or when that search ends inside the band), the target is pushed
back along the closest pair's gradient with respect to the arms' joints (a few Newton steps),
and if that fails goes as far as it can along its step from the last target (bisection). A
target never goes deeper into the band than the last one was. The closest pair's gradient comes
from coal's witness points and normal (one check, exact to GJK's tolerance); where they give
none (shapes touching, a face against a face) from forward differences of ``DIFF_RAD`` (six
checks, each computing only the pairs that could come closer than the closest pair can move; a
check with no such pair, the closest pair not moved by the joint and every other pair's bound
beyond the band, is answered by the bounds alone:
:meth:`~hubo_cli.control.collision.SelfCollisionChecker.bound_near`, the same distance to the
last bit). It only shapes the steps: every step taken is checked.

Distances are the checker's :meth:`~hubo_cli.control.collision.SelfCollisionChecker.check_near`
(exact near the room, Lipschitz lower bounds for the pairs far from it, which it does not
compute), from a repeatable checker: the same joints give the same distances, whatever was
computed before (so the same joints and band asked again in a row are not checked again).
A search step that cuts the weighted error by less than ``REST_M`` ends the call's search (it
goes on from the arm's last target the next period): where the first step cut it by more,
each later step of the call cut it by 0.023 mm (median; 0.12 mm at the 90th percentile) on
generated seeds 3401 and 3402, against 0.85 mm for a first step, so a call takes one or two
steps where it took ``SEARCH_STEPS``. A call whose search cut the error by less than
``REST_M`` in all came to rest (no step left that helps, or creeping along the body); the next
call, if its goal is within ``STILL_GOAL_M`` and ``STILL_GOAL_RAD`` of that goal, takes the
pose it rested at again when that pose (its own pairs) still keeps the room: one check instead
of a search, and the lead below goes on toward it.

An arm the search moves, given its commanded joints (the trajectory generator's, lagging
behind the target at the joints' speed limits), gets a target at most ``LEAD_RAD`` (0.05 rad,
the detector's own sampling step along a way) from its command, on the straight joint-space
way from the command toward the searched pose, if that keeps the room; the teleop target
tracks such an arm phase synchronised, so the command goes along that short chord. The
searched pose slides round the body faster than the arm can follow (0.6-0.8 rad/s of its
joints on generated seed 3409); tracked unsynchronised 0.2 rad behind it, the command's way
cut inside the band and the detector's braking look-ahead along it held the arms. On a short
chord between two clear postures, stopped before its end (the tracker can stop at its
target at the limits the detector brakes at), the look-ahead keeps about the clearance of
its ends. ``searched`` keeps the searched pose of such an arm for the call (what the target
is on its way to).

The work of a call is bounded: it makes at most ``MAX_CHECKS`` checks (a coal distance pass
or a witness gradient, each at most every pair: about 40-50 us warm). A search step, a Newton
step or the bisection starts only if the most it can take leaves two checks for the end; a
search that runs out goes on the next period (not at rest), and a call that cannot afford
the bisection holds the arms at the last target, which keeps the room (the bisection's answer
before its first halving).
"""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.control.collision import SAMPLE_RAD, TOLERANCE_M, SelfCollisionChecker
from hubo_cli.kinematics.reach import DAMPING, MAX_STEP_RAD, branch_box
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.motion.limits import all_finite
from hubo_cli.teleop.room_kernels import clipped_step, goal_within, weighted_error
from hubo_cli.teleop.target_kernels import max_abs_difference

try:
    from numpy.linalg._umath_linalg import solve1 as _solve1
except ImportError:  # numpy's private module: a numpy that moves it gets np.linalg.solve
    _solve = np.linalg.solve
else:
    def _solve(H: np.ndarray, b: np.ndarray) -> np.ndarray:
        """np.linalg.solve's own gufunc for one right-hand side (the same LAPACK call)
        without its wrappers (type checks and an error state: H below is damped, positive
        definite, never singular)."""
        return _solve1(H, b, signature="dd->d")

ROOM_M = TOLERANCE_M + 0.005  # the detector's band and 5 mm for the command's braking look-ahead
NEWTON_STEPS = 3
BISECTIONS = 8
MAX_CHECKS = 40              # the checks one keep call may make (a witness gradient counts as
                             # one): see the module docstring
_END_CHECKS = 2              # ... two kept for the end: the last target's check, the final one
_TRIES = (1.0, 0.5, 0.25)    # a search step's tries, each one check
DIFF_RAD = 1e-4              # finite-difference step of the gradient where witness points fail
DIFF_SLACK_M = 1e-5          # ... its checks' band beyond the closest pair's reach: ten times
                             # coal's GJK tolerance (1e-6 m) on each of two distances
SEARCH_STEPS = 3             # the clear search's steps per call (it goes on the next period)
ORIENTATION_WEIGHT_M_PER_RAD = 0.01  # the clear search's: position first (1 deg = 0.17 mm)
AIM_M = 0.001                # its steps aim this far beyond the room (the body's curvature)
REST_M = 0.0001              # a search call cutting its weighted error less: at rest
STILL_GOAL_M = 0.0005       # a goal this close (and STILL_GOAL_RAD) to the one a clear search
STILL_GOAL_RAD = np.radians(0.5)  # came to rest at is not searched again
_STILL_GOAL_COS = np.cos(STILL_GOAL_RAD)
LEAD_RAD = SAMPLE_RAD  # a searched arm's target leads its command by at most this (each joint)
NEAR_M = 0.05  # distances are exact up to the room and this much more, lower bounds beyond
# (the checker's Lipschitz bounds skip the pairs that cannot be that close)
_W = np.array([1.0, 1.0, 1.0] + [ORIENTATION_WEIGHT_M_PER_RAD] * 3)  # the search's weights
_W_ROWS = _W[:, None]
_DAMPED = DAMPING**2 * np.eye(6)


class CollisionRoom:
    """Keeps arm targets at least ``room_m`` from the body (see the module docstring).

    Args:
        model: the robot model (URDF, limits).
        drill: the right hand holds the drill (its capsules are checked too).
        room_m: the clearance an arm target keeps (m).
        arms: the arms that may be moved (the driven ones).

    Attributes:
        pushed_periods: per arm, how many calls moved its target out of the band.
        last_clearance_m: the closest pair's distance at the last returned target (m; a lower
            bound of it when it exceeds the room).
        moved: the arms whose targets the last call replaced.
        short: how many calls ran out of checks (``MAX_CHECKS``: a step not taken);
            ``held``: how many of them held the arms at the last target.
        led: how many searched targets were brought back to ``LEAD_RAD`` from their arm's
            command; ``searched``: the last call's searched poses of those arms (arm -> 6
            joints, rad).
    """

    def __init__(self, model: RobotModel, drill: bool = False, room_m: float = ROOM_M,
                 arms: tuple[str, ...] = ARMS) -> None:
        self.model = model
        self.room_m = float(room_m)
        self.checker = SelfCollisionChecker(model, drill=drill, repeatable=True)
        self.arms = tuple(arms)
        self.lower = np.asarray(model.lower_rad, dtype=float)
        self.upper = np.asarray(model.upper_rad, dtype=float)
        self._slices = {arm: model.limb_slice(arm) for arm in self.arms}
        self._index = {arm: np.arange(len(model.joint_names))[sl]
                       for arm, sl in self._slices.items()}
        self._link_arm = {f"{joint}_link": arm for arm in self.arms
                          for joint in model.limb(arm).joints}
        if drill and "right-arm" in self.arms:
            self._link_arm["drill"] = "right-arm"
        self._pair_index = {names: k for k, names in enumerate(self.checker.pair_names)}
        # per arm, the pairs its joints move (a rate for one of its shapes): the only ones its
        # clear search can change
        self._arm_pairs = {arm: self.checker.rate_m_rad[:, index].max(axis=1) > 0.0
                           for arm, index in self._index.items()}
        self._pair_arms: dict[tuple[str, str], tuple[str, ...]] = {}
        self.pushed_periods = dict.fromkeys(self.arms, 0)
        self.moved: set[str] = set()  # the arms the last call moved
        # arm -> (goal, joints) the last call's search of the arm came to rest at
        self._rested: dict[str, tuple] = {}
        self.skipped = 0  # clear searches skipped: the goal still where one came to rest
        self.last_clearance_m = np.inf
        self._last_key: tuple | None = None  # _distance's last check: (joints' bytes, near_m)
        self._last = (np.inf, ("", ""))  # ... and its answer
        self._checks_left = MAX_CHECKS  # keep's budget (set anew each call)
        self.short = 0  # keep calls that ran out of checks (a step or the bisection not taken)
        self.held = 0  # ... of them, those that held the last target (no bisection)
        self._short = False  # ... this call did
        self.led = 0  # searched targets brought back to LEAD_RAD from the arm's command
        self.searched: dict[str, np.ndarray] = {}  # ... the last call's: arm -> its joints
        _compile_kernels()

    def _arms_of(self, pair: tuple[str, str]) -> tuple[str, ...]:
        """The movable arms carrying a shape of ``pair`` (remembered per pair)."""
        found = self._pair_arms.get(pair)
        if found is None:
            arms = (self._link_arm.get(name.rsplit("_", 1)[0]) for name in pair)
            found = self._pair_arms[pair] = tuple(dict.fromkeys(a for a in arms if a is not None))
        return found

    def _distance(self, q_rad: np.ndarray, near_m: float = NEAR_M, arm: str | None = None
                  ) -> tuple[float, tuple[str, str]]:
        """The closest pair's distance (m; exact up to ``room_m + near_m``, a lower bound
        beyond) and names. ``near_m`` 0 computes only the pairs whose bounds come within the
        room: enough to tell whether a target keeps it (most periods no pair is computed).
        With ``arm``, the closest of the pairs that arm's joints move."""
        key = (q_rad.tobytes(), near_m, arm)
        if key != self._last_key:  # the same joints and band again: nothing would be computed
            self._checks_left -= 1
            c = self.checker.check_near(q_rad, self.room_m + near_m,
                                        None if arm is None else self._arm_pairs[arm])
            self._last_key, self._last = key, (c.distance_m, c.pair)
        return self._last

    def _own_closest(self, q_rad: np.ndarray, arm: str, d: float, pair: tuple[str, str]
                     ) -> tuple[float, tuple[str, str]]:
        """``_distance(q_rad, arm=arm)`` right after ``_distance(q_rad)`` gave ``d`` and
        ``pair``. Where that pair is one the arm moves, it is the answer: the second check
        would bound or reuse every pair as the first left it (the same joints and band: each
        pair's distance computed or reused there is its anchor now, the others' bounds are
        the same numbers) and take the first smallest of the arm's pairs, which the first
        smallest of all is. It still counts as a check (the call's budget as before); the
        checker only skips its own bookkeeping of which pairs coal has active."""
        if not self._arm_pairs[arm][self._pair_index[pair]]:
            return self._distance(q_rad, arm=arm)
        key = (q_rad.tobytes(), NEAR_M, arm)
        if key != self._last_key:
            self._checks_left -= 1
            self._last_key, self._last = key, (d, pair)
        return self._last

    def clears(self, q_rad: np.ndarray) -> bool:
        """``q_rad`` (24 joints, rad) keeps the room (the check :meth:`keep` makes first)."""
        return self._distance(np.asarray(q_rad, dtype=float), near_m=0.0)[0] >= self.room_m

    def keep(self, q_prev_rad: np.ndarray, q_next_rad: np.ndarray,
             goals: dict | None = None, commanded: dict | None = None) -> np.ndarray:
        """The target to use instead of ``q_next_rad`` (24 joints, rad) after ``q_prev_rad``.

        Args:
            goals: arm -> (its :class:`~hubo_cli.kinematics.arm_reach.ArmReach`, its goal
                T_N_E 4x4 in the neck frame): search the nearest clear pose to the goal.
            commanded: arm -> its commanded joints (6, rad; the trajectory generator's): an
                arm the search moves gets a target on the straight way from there toward the
                searched one, at most ``LEAD_RAD`` ahead (see the module docstring).
        """
        q_next = np.asarray(q_next_rad, dtype=float)
        self._checks_left = MAX_CHECKS
        self._short = False
        self.searched = {}
        last_rests, self._rested = self._rested, {}
        d, pair = self._distance(q_next, near_m=0.0)
        if d >= self.room_m:
            self.last_clearance_m = d
            self.moved = set()
            return q_next
        if goals:
            q, d_q, moved = self._clear_search(np.asarray(q_prev_rad, dtype=float), q_next, goals,
                                               d, pair, last_rests)
            if d_q >= self.room_m:
                if commanded:
                    q, d_q = self._led_from_command(q, d_q, moved, commanded)
                return self._done(q, d_q, moved)
            self._rested = {}
        q = q_next.copy()
        moved = set()
        for _ in range(NEWTON_STEPS):
            arms = self._arms_of(pair)
            if not arms:  # the legs alone: nothing an arm target can do
                break
            index = np.concatenate([self._index[a] for a in arms])
            if not self._affords(1 + len(index) + 1):  # its gradient and its check
                break
            grad = self._gradient(q, d, pair, index)
            norm2 = float(grad @ grad)
            if not np.isfinite(norm2) or norm2 < 1e-12:
                break
            q[index] = np.clip(q[index] + grad * (self.room_m + 1e-4 - d) / norm2,
                               self.lower[index], self.upper[index])
            moved.update(arms)
            d, pair = self._distance(q)
            if d >= self.room_m:
                return self._done(q, d, moved)
        arm_index = np.concatenate([self._index[a] for a in self.arms])
        q_prev = q_next.copy()  # the legs as asked, the arms where they were
        q_prev[arm_index] = np.asarray(q_prev_rad, dtype=float)[arm_index]
        d_prev = self._distance(q_prev)[0]
        if d_prev < self.room_m:  # already inside: never deeper than the last target
            best, d_best = (q, d) if d >= d_prev else (q_prev, d_prev)
            return self._done(best, d_best, moved or set(self._arms_of(pair)))
        moved = {a for a in self.arms if np.any(q_next[self._index[a]] != q_prev[self._index[a]])}
        if self._checks_left < BISECTIONS + 1:  # out of checks: the last target holds (clear)
            self._short = True
            self.held += 1
            return self._done(q_prev, d_prev, moved)
        lo, hi = 0.0, 1.0  # the furthest clear point of the arms' step from the last target
        for _ in range(BISECTIONS):
            mid = (lo + hi) / 2
            if self._distance(q_prev + mid * (q_next - q_prev))[0] >= self.room_m:
                lo = mid
            else:
                hi = mid
        q = q_prev + lo * (q_next - q_prev)
        moved = {a for a in self.arms if np.any(q_next[self._index[a]] != q[self._index[a]])}
        return self._done(q, self._distance(q)[0], moved)

    def _clear_search(self, q_prev: np.ndarray, q_next: np.ndarray, goals: dict, d: float,
                      pair: tuple[str, str], last_rests: dict
                      ) -> tuple[np.ndarray, float, set[str]]:
        """The arms in the band (``q_next``'s closest pair ``pair`` at ``d`` < room, exact):
        from their last targets toward their goals, clear of the body (see the module
        docstring). Returns (joints, their clearance, the arms moved)."""
        q = q_next.copy()
        moved: set[str] = set()
        for _ in range(len(self.arms)):  # the arms of the closest pair, one after the other
            arms = [a for a in self._arms_of(pair) if a in goals and a not in moved]
            # an arm's search: its two first checks and the last one
            if d >= self.room_m or not arms or not self._affords(3):
                break
            arm = arms[0]
            index, sl = self._index[arm], self._slices[arm]
            reach, T_goal = goals[arm]
            T_goal = np.ascontiguousarray(T_goal, float)
            moved.add(arm)
            rested = last_rests.get(arm)  # (goal, pose) the last call's search rested at
            if rested is not None and goal_within(rested[0], T_goal, STILL_GOAL_M,
                                                  _STILL_GOAL_COS):
                # the goal still where it was: the last call's answer, if it keeps the room
                # (one check; the legs and the other arm may have moved)
                q[sl] = rested[1]
                d, pair_prev = self._distance(q)
                if self._own_closest(q, arm, d, pair_prev)[0] >= self.room_m:
                    self.skipped += 1
                    self._rested[arm] = rested
                    pair = pair_prev  # the check just made (repeatable: the same a second time)
                    continue
            q[sl] = q_prev[sl]
            d, pair_prev = self._distance(q)
            # the arm's own pairs (the others it cannot change: the other arm's elbow deep in
            # the torso leaves every step of this arm's search the same clearance and a zero
            # gradient)
            d_arm, pair_arm = self._own_closest(q, arm, d, pair_prev)
            q, d, at_rest = self._search_arm(q, d_arm, pair_arm, index, reach, T_goal, arm)
            if at_rest:
                self._rested[arm] = (T_goal, q[sl].copy())
            d, pair = self._distance(q)
        return q, d, moved

    def _led_from_command(self, q: np.ndarray, d: float, moved: set[str],
                          commanded: dict) -> tuple[np.ndarray, float]:
        """The searched targets ``q`` (clearance ``d``, the room kept) with each moved arm's
        target more than ``LEAD_RAD`` from its command (``commanded``) brought back along the
        straight way from the command to it, ``LEAD_RAD`` from the command, if that keeps
        the room (else as searched). Returns (joints, their clearance)."""
        for arm in self.arms:
            if arm not in moved or arm not in commanded:
                continue
            sl = self._slices[arm]
            q_cmd = np.asarray(commanded[arm], dtype=float)
            lead = max_abs_difference(q[sl], q_cmd)
            if not lead > LEAD_RAD or not self._affords(1):  # (a NaN command: as searched)
                continue
            q_led = q.copy()
            q_led[sl] = q_cmd + (LEAD_RAD / lead) * (q[sl] - q_cmd)
            d_led = self._distance(q_led, near_m=0.0)[0]
            if d_led >= self.room_m:
                self.searched[arm] = q[sl].copy()
                q, d = q_led, d_led
                self.led += 1
        return q, d

    def _gradient(self, q: np.ndarray, d: float, pair: tuple[str, str],
                  index: np.ndarray, arm: str | None = None) -> np.ndarray:
        """The gradient of the clearance ``d`` at ``q`` (closest pair ``pair``; with ``arm``,
        of the pairs that arm moves) with respect to the joints ``index`` (m/rad): coal's
        witness points and normal
        (:meth:`~hubo_cli.control.collision.SelfCollisionChecker.distance_gradient`), or
        where they give none (touching, a face on a face), forward differences of DIFF_RAD."""
        self._checks_left -= 1
        grad = self.checker.distance_gradient(q, self._pair_index[pair], index)
        if grad is not None:
            return grad
        grad = np.empty(len(index))
        q_d = q.copy()
        # the closest distance at q_d is at most the pair's, at most d + its rate DIFF_RAD
        # (each within coal's tolerance): the pairs whose bounds lie beyond that and
        # DIFF_SLACK_M cannot be the closest and need not be computed (the same closest
        # distance, to the last bit; d is exact here, within the room and NEAR_M)
        near_m = min(d + DIFF_RAD * float(self.checker.rate_m_rad[self._pair_index[pair]].max())
                     + DIFF_SLACK_M - self.room_m, NEAR_M)
        band_m = self.room_m + near_m
        for k, i in enumerate(index.tolist()):
            q_d[i] = q[i] + DIFF_RAD
            # where every pair's bound answers (no pair to compute: the closest pair not
            # moved by joint i, the others beyond the band), the check's distance without it
            d_d = self.checker.bound_near(q_d, band_m,
                                          None if arm is None else self._arm_pairs[arm])
            if math.isnan(d_d):
                d_d = self._distance(q_d, near_m, arm)[0]
            grad[k] = (d_d - d) / DIFF_RAD
            q_d[i] = q[i]
        return grad

    def _search_arm(self, q: np.ndarray, d: float, pair: tuple[str, str], index: np.ndarray,
                    reach, T_goal: np.ndarray, arm: str) -> tuple[np.ndarray, float, bool]:
        """A few steps of the clear search for one arm (see the module docstring) from ``q``,
        whose closest pair among those the arm moves is ``pair`` at ``d``; returns (joints,
        the clearance of the arm's pairs, whether it came to rest: no step left that helps)."""
        limb = reach.limb
        base, _, offset, alpha, a, dd, end, _ = limb.chain
        lo, hi = np.empty(6), np.empty(6)
        T, J, e, zeros = np.empty((4, 4)), np.empty((6, 6)), np.empty(6), np.zeros(6)
        branch = -1 if reach.branch is None else reach.branch
        first = int(index[0])  # the arm's joints are index: first, first + 1, ... first + 5
        q_arm = q[first:first + 6]
        branch_box(q_arm, branch, reach.margins, limb.lower_rad, limb.upper_rad, lo, hi)
        # the weighted error e and its square c at q: with numpy, e[:3] = p_goal - p, the
        # rotation error, e *= W, c = e @ e (c decides only: its last bit may differ)
        c = c_start = weighted_error(q_arm, base, offset, alpha, a, dd, end, T_goal, _W, T, J, e)
        for _ in range(SEARCH_STEPS):
            # its gradient (the witness, or a check per joint) and its tries, then the
            # search's last check: if not, not at rest (it goes on the next period)
            if not self._affords(1 + len(index) + len(_TRIES) + 1):
                return q, d, False
            # the linear algebra as numpy does it (its BLAS and LAPACK calls): the step's last
            # bits, and the ties the search breaks on them, as they were
            Jw = J * _W_ROWS
            H = Jw.T @ Jw + _DAMPED
            dq = _solve(H, Jw.T @ e)
            grad = self._gradient(q, d, pair, index, arm)
            need = self.room_m + AIM_M - d
            if all_finite(grad):
                along = grad @ dq
                if along < need:
                    # the step of least weighted error whose linearised clearance is the room:
                    # it slides along the body, turning the hand where that costs the least
                    h_grad = _solve(H, grad)
                    curvature = grad @ h_grad
                    if curvature > 1e-12:
                        dq += (need - along) / curvature * h_grad
            biggest = max_abs_difference(dq, zeros)  # np.max(np.abs(dq)), NaN as NaN
            if biggest < 1e-9:
                return q, d, True
            dq *= min(1.0, MAX_STEP_RAD / biggest)
            for scale in _TRIES:
                q_try = np.empty_like(q)
                clipped_step(q, first, dq, scale, lo, hi, q_try)  # np.clip(q_arm + scale dq)
                d_try, pair_try = self._distance(q_try, arm=arm)
                if not d_try >= min(self.room_m, d):  # deeper (or NaN): no need of its error
                    continue
                c_try = weighted_error(q_try[first:first + 6], base, offset, alpha, a, dd, end,
                                       T_goal, _W, T, J, e)
                if c_try < c or d < self.room_m <= d_try:
                    gain = math.sqrt(c) - math.sqrt(c_try)
                    q, d, c, pair = q_try, d_try, c_try, pair_try
                    break
            else:
                return q, d, True
            if gain < REST_M:  # creeping: the call's search ends here (at rest if this was
                break          # its first step)
        # creeping along the body (its weighted error falling by less than REST_M a call):
        # at rest too
        return q, d, math.sqrt(c_start) - math.sqrt(c) < REST_M

    def _affords(self, checks: int) -> bool:
        """``checks`` more checks leave keep's last ones (:data:`_END_CHECKS`)."""
        if self._checks_left - checks >= _END_CHECKS:
            return True
        self._short = True
        return False

    def _done(self, q: np.ndarray, d: float, moved: set[str]) -> np.ndarray:
        self.last_clearance_m = d
        self.moved = set(moved)
        self.short += self._short
        for arm in moved:
            self.pushed_periods[arm] += 1
        return q


def _compile_kernels() -> None:
    """Call each kernel of the clear search once: compiled (or loaded from numba's cache)
    when the room is made, not in the first period that searches."""
    eye, zeros = np.eye(4), np.zeros(6)
    weighted_error(zeros, eye, zeros, zeros, zeros, zeros, eye, eye, _W, np.empty((4, 4)),
                   np.empty((6, 6)), np.empty(6))
    clipped_step(np.zeros(24), 0, zeros, 1.0, zeros, zeros, np.empty(24))
    goal_within(eye, eye, STILL_GOAL_M, _STILL_GOAL_COS)
    branch_box(zeros, 0, np.zeros(3), zeros - 1.0, zeros + 1.0, np.empty(6), np.empty(6))
