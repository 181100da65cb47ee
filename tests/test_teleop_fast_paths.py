"""The teleop target's compiled per-period arithmetic gives what the plain numpy code gave.

Each compiled part against its numpy version as it was written before (kept here as the
reference), on drawn and hostile inputs; then the whole target against a reference target built
from those numpy versions (the collision room's first check over every pair within 5 cm of the
room, its clear search, the measurement, the torso's tilt and the measured neck frame as
before), closed loop over generated operator streams: every period the same joint targets to
1e-9 rad, the same joints commanded by the trajectory generator and the same target velocities
given to it (to 1e-8 rad and 1e-7 rad/s), the same logged values (to 1e-9) and the same summary
figures; and the collision room alone on recorded calls, to the last bit. The room's clearance
gradient is its own in both (coal's witness points and normal, tested against finite
differences in tests/test_collision_skip.py): the reference keeps the room's search and its
still-goal check as they were around it.

Closed loop, the two runs differ by rounding from the first period on (numpy's BLAS products and
the compiled loops round differently; 1e-13 rad over 4 s, seeds 3400 and 3401). The collision
room's clear search decides some steps on an exact tie (a step that leaves the closest pair's
distance unchanged is accepted when the new distance is not below the old one): such a tie,
broken the other way by a last-bit difference, sends the runs apart (seed 3402, 0.25 m/s,
4 s: at 1.845 s the left arm's search took a 0.1 rad step in one run and not the other). Any
change of rounding does that, the base code's own on another BLAS kernel too; the streams here
have no such tie.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hubo_cli.control.collision import SelfCollisionChecker
from hubo_cli.control.keys import ARM_TARGET_VELOCITY
from hubo_cli.estimation.keys import QUAT_WORLD_TORSO
from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.kinematics.arm_reach import ArmReach
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.conditioning import condition_number
from hubo_cli.kinematics.dh import kernel_array, pose_error
from hubo_cli.kinematics.limb import get_limb
from hubo_cli.kinematics.reach import DAMPING, MAX_STEP_RAD, branch_box, jacobian, rotation_error
from hubo_cli.kinematics.torso import MeasuredTorso
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import load_model
from hubo_cli.motion.limits import JointLimits
from hubo_cli.teleop import lead
from hubo_cli.teleop import room as room_module
from hubo_cli.teleop import target as target_module
from hubo_cli.teleop.mapping import MAX_OPERATOR_RANGE_M, HandGoal, HandMapper, MappingConfig
from hubo_cli.teleop.room import CollisionRoom
from hubo_cli.teleop.room_kernels import clipped_step, goal_within, weighted_error
from hubo_cli.teleop.stream_runs import follow_generated
from hubo_cli.teleop.target_kernels import hand_errors, max_abs_difference, path_swing_m, tilt_rad

# ---------------------------------------------------------------- the numpy code, as it was


def numpy_condition_number(limb, q_rad):
    base, _, offset, alpha, a, d, end, _ = limb.chain
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    jacobian(np.ascontiguousarray(q_rad, dtype=float), base, offset, alpha, a, d, end, T, J)
    J[:3] /= float(limb.lengths_m[0] + limb.lengths_m[1])
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def numpy_stop_distance(v, a, j):
    return np.where(v <= a * a / j, v * np.sqrt(v / j), v * v / (2 * a) + v * a / (2 * j))


def numpy_stop_speed(room_rad, a, j):
    room = np.maximum(room_rad, 0.0)
    low = np.cbrt(room * room * j)
    high = 0.5 * (-a * a / j + np.sqrt((a * a / j) ** 2 + 8.0 * a * room))
    return np.where(low <= a * a / j, low, high)


def numpy_reachable_velocity(v_goal, q_target, q, v, limits, share=lead.RUN_UP_SHARE):
    s = np.sign(v_goal)
    d = (q_target - q) * s
    u = np.maximum(v * s, 0.0)
    speed = np.abs(v_goal)
    a, j = share * limits.acceleration_rad_s2, limits.jerk_rad_s3
    run_up = np.where(d > 0, numpy_stop_speed(d + numpy_stop_distance(u, a, j), a, j), 0.0)
    caught_up = np.clip(1.0 - np.abs(d) / (speed * lead.CATCH_UP_S + 1e-12), 0.0, 1.0)
    return s * np.minimum(speed, run_up) * caught_up


def plain_min_time(x0, v0, x1, v1, accel, speed):
    """The double integrator's shortest time, each one-switch profile written out."""
    times = []
    for s in (1.0, -1.0):
        dx, a0, a1 = s * (x1 - x0), s * v0, s * v1
        peak2 = accel * dx + (a0 * a0 + a1 * a1) / 2
        for peak in ((math.sqrt(peak2), -math.sqrt(peak2)) if peak2 >= 0 else ()):
            if peak < max(a0, a1) - 1e-12:
                continue
            up, down = (min(peak, speed) - a0) / accel, (min(peak, speed) - a1) / accel
            covered = (min(peak, speed) ** 2 - a0 * a0 + min(peak, speed) ** 2 - a1 * a1) / (
                2 * accel)
            times.append(up + down + max(dx - covered, 0.0) / speed)
    return min(times, default=math.inf)


def numpy_tracking_target(v_goal, q_target, q, v, limits, decay_s=lead.DECAY_S):
    """lead.tracking_target in plain Python over numpy_reachable_velocity."""
    v_out = numpy_reachable_velocity(v_goal, q_target, q, v, limits)
    tau = np.broadcast_to(np.asarray(decay_s, dtype=float), np.shape(q))

    def late(t, i):
        e = math.exp(-t / tau[i])
        return plain_min_time(q[i], v[i], q_target[i] + v_goal[i] * tau[i] * (1 - e),
                              v_goal[i] * e, lead.INTERCEPT_SHARE
                              * limits.acceleration_rad_s2[i], limits.velocity_rad_s[i]) - t

    meet = np.zeros(len(q))
    for i in np.nonzero(v_goal)[0]:
        grid = [0.0] + [lead.MEET_STEP_S * k for k in range(
            1, int(lead.MEET_NONE_S / lead.MEET_STEP_S + 1e-6) + 1)]
        meet[i] = lead.MEET_NONE_S
        if late(0.0, i) <= 0:
            meet[i] = 0.0
            continue
        for lo, hi in zip(grid, grid[1:], strict=False):
            if late(hi, i) <= 0:
                for _ in range(4):
                    mid = (lo + hi) / 2
                    lo, hi = (lo, mid) if late(mid, i) <= 0 else (mid, hi)
                meet[i] = lo + (hi - lo) * late(lo, i) / (late(lo, i) - late(hi, i))
                break
    share = float(np.clip((lead.MEET_NONE_S - meet.max())
                          / (lead.MEET_NONE_S - lead.MEET_FULL_S), 0.0, 1.0))
    if share == 0.0:
        return np.array(q_target, dtype=float), v_out, 0.0
    e = np.exp(-meet / tau)
    p = np.clip(q_target + v_goal * tau * (1 - e), limits.lower_rad, limits.upper_rad)
    room = np.where(v_goal * e > 0, limits.upper_rad - p, p - limits.lower_rad)
    cap = np.minimum(0.9 * limits.velocity_rad_s, numpy_stop_speed(
        room, limits.acceleration_rad_s2, limits.jerk_rad_s3))
    moving = v_goal != 0
    q_out = np.where(moving, q_target + share * (p - q_target), q_target)
    v_out = np.where(moving, share * np.clip(v_goal * e, -cap, cap) + (1 - share) * v_out, v_out)
    return q_out, v_out, share


class NumpyGoalVelocity(lead.GoalVelocity):
    def update(self, q_target_rad, follow):
        k = len(self._q)
        self._slot = (self._slot + 1) % k
        self._q[self._slot] = q_target_rad
        self._count = min(self._count + 1, k)
        if not follow or self._count < k:
            self.v_rad_s = np.zeros(self.limits.size)
            self._v_count = 0
            return self.v_rad_s
        lim = self.limits
        v = self._weights[self._slot] @ self._q
        room = np.where(v > 0, lim.upper_rad - q_target_rad, q_target_rad - lim.lower_rad)
        cap = np.minimum(0.9 * lim.velocity_rad_s,
                         numpy_stop_speed(room, lim.acceleration_rad_s2, lim.jerk_rad_s3))
        self.v_rad_s = np.clip(v, -cap, cap)
        self._v[self._slot] = self.v_rad_s
        self._v_count = min(self._v_count + 1, k)
        return self.v_rad_s

    def decay_s(self, shortest_s, longest_s):
        """GoalVelocity.decay_s joint by joint in plain Python (w = w0 exp(-window / tau))."""
        k = len(self._q)
        out = []
        for w0, w in zip(self._v[(self._slot + 1) % k], self._v[self._slot], strict=True):
            tau = longest_s
            if self._v_count < k:
                tau = shortest_s
            elif w * w0 > 0.0 and abs(w) < abs(w0):
                tau = (k - 1) * self.dt_s / math.log(w0 / w)
            out.append(min(max(tau, shortest_s), longest_s))
        return np.array(out)


def _axis_angle(axis, angle):
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


class NumpyReach(ArmReach):
    def smoothed(self, T_goal, dt_s, follows_freely=False):
        tau = self.time_constant_s(dt_s, follows_freely)
        T = np.array(T_goal, dtype=float)
        if tau <= 0 or self.settings.mode == "paper":
            return T
        if self._R_smooth is None:
            self._R_smooth = T[:3, :3].copy()
        else:
            alpha = dt_s / (tau + dt_s)
            R_rel = self._R_smooth.T @ T[:3, :3]
            angle = float(np.arccos(np.clip((np.trace(R_rel) - 1) / 2, -1.0, 1.0)))
            if angle > 1e-12:
                axis = np.array([R_rel[2, 1] - R_rel[1, 2], R_rel[0, 2] - R_rel[2, 0],
                                 R_rel[1, 0] - R_rel[0, 1]])
                norm = np.linalg.norm(axis)
                if norm > 1e-12:
                    self._R_smooth = self._R_smooth @ _axis_angle(axis / norm, alpha * angle)
                else:
                    self._R_smooth = T[:3, :3].copy()
        T[:3, :3] = self._R_smooth
        return T


def numpy_path_swing_m(limb, path):
    points = np.array([limb.fk(q)[:3, 3] for q in path])
    p = points[1:-1] - points[0]
    line = points[-1] - points[0]
    length2 = float(line @ line)
    along = np.zeros(len(p)) if length2 < 1e-18 else np.clip(p @ line / length2, 0.0, 1.0)
    return float(np.sqrt(np.max(np.sum((p - along[:, None] * line) ** 2, axis=1))))


class NumpyMapper(HandMapper):
    def goal(self, hand, T_O_hand, t_s, T_S_hand_now):  # free mode, as it was
        if self.config.mode == "drill":
            return super().goal(hand, T_O_hand, t_s, T_S_hand_now)
        arm = self.config.hand_arm.get(hand)
        if arm is None:
            return None
        T_O = np.asarray(T_O_hand, dtype=float)
        if not np.isfinite(T_O).all() or np.abs(T_O[:3, 3]).max() > MAX_OPERATOR_RANGE_M:
            self.rejected += 1
            return None
        if hand not in self._refs:
            self.recenter(hand, T_O, T_S_hand_now)
            ref = self._refs[hand]
            ref.last_t_s = t_s
            return HandGoal(arm, ref.T_S_hand0.copy(), t_s, calibrated_now=True)
        ref = self._refs[hand]
        T_goal = np.eye(4)
        delta_S = self.config.scale * (T_O[:3, 3] - ref.T_O_ref[:3, 3])
        T_goal[:3, :3] = T_O[:3, :3] @ ref.T_O_ref[:3, :3].T @ ref.T_S_hand0[:3, :3]
        T_goal[:3, 3] = ref.T_S_hand0[:3, 3] + delta_S
        step = T_goal[:3, 3] - ref.last_mapped[:3, 3]
        turn_cos = (np.trace(ref.last_mapped[:3, :3].T @ T_goal[:3, :3]) - 1.0) / 2.0
        if (np.linalg.norm(step) > self.config.max_step_m
                or turn_cos < np.cos(self.config.max_turn_rad)):
            self.rejected += 1
            return None
        ref.last_mapped = T_goal.copy()
        if np.isfinite(t_s) and (ref.last_t_s is None or t_s > ref.last_t_s):
            ref.last_t_s = t_s
        ref.last_goal = T_goal
        return HandGoal(arm, T_goal, t_s)


class NumpyMeasuredTorso(MeasuredTorso):
    def __call__(self, T_world_torso, T_world_soles):
        T_world_torso = np.asarray(T_world_torso, dtype=float)
        if self.T_world_S is None:
            T_world_soles = np.asarray(T_world_soles, dtype=float)
            if not np.all(np.isfinite(T_world_soles)):
                return self._T_S_N
            self._place_stance(T_world_soles)
        if np.all(np.isfinite(T_world_torso)):
            self._T_S_N = self._T_S_world @ T_world_torso
        return self._T_S_N


def numpy_tilt_rad(q):
    q = np.asarray(q, dtype=np.float64)
    return 2.0 * np.arctan2(np.hypot(q[..., 1], q[..., 2]), np.hypot(q[..., 0], q[..., 3]))


class ReferenceRoom(CollisionRoom):
    def _distance(self, q_rad, near_m=None, arm=None):  # as before: every pair within NEAR_M
        return super()._distance(q_rad, arm=arm)        # of the room

    def _still(self, rested, T_goal):  # as it was
        T_was = rested[0]
        if np.linalg.norm(T_goal[:3, 3] - T_was[:3, 3]) > room_module.STILL_GOAL_M:
            return False
        cos = (np.trace(T_was[:3, :3].T @ T_goal[:3, :3]) - 1.0) / 2.0
        return bool(cos >= np.cos(room_module.STILL_GOAL_RAD))

    def _clear_search(self, q_prev, q_next, goals, d, pair, rested):  # as it was: q_next
        q = q_next.copy()                                             # checked again
        d, pair = self._distance(q)
        moved = set()
        for _ in range(len(self.arms)):
            arms = [a for a in self._arms_of(pair) if a in goals and a not in moved]
            if d >= self.room_m or not arms:
                break
            arm = arms[0]
            index = self._index[arm]
            reach, T_goal = goals[arm]
            T_goal = np.ascontiguousarray(T_goal, float)
            moved.add(arm)
            if arm in rested and self._still(rested[arm], T_goal):  # the last call's answer
                q[index] = rested[arm][1]
                d, pair = self._distance(q, arm=arm)
                if d >= self.room_m:
                    self.skipped += 1
                    self._rested[arm] = rested[arm]
                    d, pair = self._distance(q)
                    continue
            q[index] = q_prev[index]
            d, pair = self._distance(q, arm=arm)  # the pairs the arm moves
            q, d, at_rest = self._search_arm(q, d, pair, index, reach, T_goal, arm)
            if at_rest:
                self._rested[arm] = (T_goal, q[index].copy())
            d, pair = self._distance(q)
        return q, d, moved

    def _search_arm(self, q, d, pair, index, reach, T_goal, arm):
        # as it was, on the pairs the arm moves (its gradient the room's; no budget: it never
        # runs out on these streams)
        limb = reach.limb
        base, _, offset, alpha, a, dd, end, _ = limb.chain
        w = np.array([1.0, 1.0, 1.0] + [room_module.ORIENTATION_WEIGHT_M_PER_RAD] * 3)
        lo, hi = np.empty(6), np.empty(6)
        T, J, e = np.empty((4, 4)), np.empty((6, 6)), np.empty(6)
        branch = -1 if reach.branch is None else reach.branch
        branch_box(q[index], branch, reach.margins, limb.lower_rad, limb.upper_rad, lo, hi)

        def cost(q_arm):
            jacobian(q_arm, base, offset, alpha, a, dd, end, T, J)
            e[:3] = T_goal[:3, 3] - T[:3, 3]
            rotation_error(T, T_goal, e[3:])
            e[:] *= w
            return float(e @ e)

        c = c_start = cost(q[index])
        for _ in range(room_module.SEARCH_STEPS):
            Jw = J * w[:, None]
            H = Jw.T @ Jw + DAMPING**2 * np.eye(6)
            dq = np.linalg.solve(H, Jw.T @ e)
            grad = self._gradient(q, d, pair, index, arm)
            need = self.room_m + room_module.AIM_M - d
            if np.all(np.isfinite(grad)) and grad @ dq < need:
                h_grad = np.linalg.solve(H, grad)
                if grad @ h_grad > 1e-12:
                    dq += (need - grad @ dq) / (grad @ h_grad) * h_grad
            biggest = float(np.max(np.abs(dq)))
            if biggest < 1e-9:
                return q, d, True
            dq *= min(1.0, MAX_STEP_RAD / biggest)
            for scale in (1.0, 0.5, 0.25):
                q_try = q.copy()
                q_try[index] = np.clip(q[index] + scale * dq, lo, hi)
                d_try, pair_try = self._distance(q_try, arm=arm)
                c_try = cost(q_try[index])
                if d_try >= min(self.room_m, d) and (c_try < c or d < self.room_m <= d_try):
                    gain = math.sqrt(c) - math.sqrt(c_try)
                    q, d, c, pair = q_try, d_try, c_try, pair_try
                    break
            else:
                return q, d, True
            if gain < room_module.REST_M:  # creeping: the call's search ends here
                break
        return q, d, math.sqrt(c_start) - math.sqrt(c) < room_module.REST_M


class ReferenceTarget(target_module.TeleopTarget):
    """The teleop target with the numpy code above in place of the compiled parts."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.reach = {arm: NumpyReach(r.limb, r.settings) for arm, r in self.reach.items()}
        self.mapper.__class__ = NumpyMapper
        if self.room is not None:
            self.room.__class__ = ReferenceRoom
        self.torso.__class__ = NumpyMeasuredTorso

    def start_operating(self, t_s):
        super().start_operating(t_s)
        self._goal_velocity = {arm: NumpyGoalVelocity(g.limits, self.dt_guard_s)
                               for arm, g in self._goal_velocity.items()}

    def _condition(self, arm, q_rad):
        return numpy_condition_number(self.reach[arm].limb, q_rad)

    def _measure(self, t_s, state, info):  # as it was
        info["phase_code"] = target_module.PHASES.index(self.phase)
        info["lift_m"] = self._lift_of(self.q_target)
        info["latency_s"] = self.latencies_s[-1] if self.latencies_s else 0.0
        operating = self.phase == "operate"
        eye = np.eye(4)
        for arm, hand in self.hands.items():
            names = self._info_names[arm]
            goal = self.goals.get(arm)
            corrected = self.correction is not None and arm in self.correction.arms
            world = (goal is not None and operating
                     and self.mapper.is_calibrated(self._hand_of[arm]))
            T_S_N = self._T_S_N() if corrected or world else eye
            base, _, offset, alpha, a, d, end, _ = self.body.arms[arm].chain
            T_actual = np.empty((4, 4))
            error, rot_error, world_error = hand_errors(
                kernel_array(state.q_rad[self.slices[arm]]), base, offset, alpha, a, d, end,
                corrected, 0.0 if corrected else self._lift_of(state.q_rad), T_S_N,
                eye if goal is None else kernel_array(goal), world, T_actual)
            actual = T_actual[:3, 3]
            hand.actual_m = actual
            x, y, z = actual
            info.update(zip(names[:6], (
                x, y, z, STATUS_NAMES.index(hand.ik_status) if hand.ik_status in STATUS_NAMES
                else -1, 0.0 if hand.missing_m is None
                else math.sqrt(hand.missing_m.dot(hand.missing_m)),
                hand.speed_scale), strict=True))
            if goal is None:
                continue
            hand.goal_m = goal_m = goal[:3, 3]
            x, y, z = goal_m
            info.update(zip(names[6:], (x, y, z, error, rot_error), strict=True))
            if world:
                self._record(arm, t_s, hand, goal_m, actual, error, rot_error, world_error)
        self.max_tilt_rad = max(self.max_tilt_rad,
                                float(numpy_tilt_rad(self.store[QUAT_WORLD_TORSO])))

    def swing_m(self, arm, tracker, target_rad, target_v_rad_s=None):
        if np.max(np.abs(target_rad - tracker.q)) < 1e-6:
            return 0.0
        path = tracker.preview(target_rad, target_module.OPERATE_SYNCHRONIZATION,
                               target_module.SWING_SAMPLES, target_v_rad_s)
        return 0.0 if len(path) < 3 else numpy_path_swing_m(self.body.arms[arm], path)


# ---------------------------------------------------------------- the compiled parts alone


@pytest.fixture(scope="module")
def arm_limits():
    model = load_model(limits="teleop")
    return JointLimits.from_model(model).subset(np.arange(24)[model.limb_slice("right-arm")])


def test_the_condition_number_matches_numpys_svd():
    """To 1e-12 relative up to 1000 (the speed scale acts between 30 and 170), near the
    straight elbow, the wrist yaw's and the shoulder roll's singular values included."""
    rng = np.random.default_rng(41)
    for name in ("right-arm", "left-arm"):
        limb = get_limb(name)
        Q = limb.random_q(rng, 3000)
        Q[:500, 3] = rng.uniform(-0.02, 0.02, 500)
        Q[500:1000, 4] = np.pi / 2 + rng.uniform(-0.02, 0.02, 500)
        Q[1000:1500, 1] = np.pi / 2 + rng.uniform(-0.02, 0.02, 500)
        for q in Q:
            expected = numpy_condition_number(limb, q)
            if expected < 1000:
                assert condition_number(limb, q) == pytest.approx(expected, rel=1e-12), q


def test_the_lead_kernels_match_numpy(arm_limits):
    rng = np.random.default_rng(42)
    a, j = arm_limits.acceleration_rad_s2, arm_limits.jerk_rad_s3
    for _ in range(2000):
        scale = rng.choice([1e-9, 1e-3, 1.0, 10.0])
        room = rng.uniform(-0.5, 2.0, 6) * scale
        assert np.allclose(lead.stop_speed_rad_s(room, a, j), numpy_stop_speed(room, a, j),
                           rtol=1e-12, atol=1e-15)
        v = np.abs(rng.normal(size=6)) * scale
        assert np.allclose(lead.stop_distance_rad(v, a, j), numpy_stop_distance(v, a, j),
                           rtol=1e-12, atol=1e-15)
        v_goal, q_target, q, v = rng.normal(size=(4, 6)) * rng.choice([1e-6, 0.1, 1.0])
        v_goal[rng.random(6) < 0.2] = 0.0
        at_target = rng.random(6) < 0.2
        q_target[at_target] = q[at_target]  # some joints at their targets
        assert np.allclose(lead.reachable_velocity(v_goal, q_target, q, v, arm_limits),
                           numpy_reachable_velocity(v_goal, q_target, q, v, arm_limits),
                           rtol=1e-12, atol=1e-15)
        v = np.clip(v, -arm_limits.velocity_rad_s, arm_limits.velocity_rad_s)
        for got, expected in zip(lead.tracking_target(v_goal, q_target, q, v, arm_limits),
                                 numpy_tracking_target(v_goal, q_target, q, v, arm_limits),
                                 strict=True):
            assert np.allclose(got, expected, rtol=1e-9, atol=1e-12)
        decay = rng.uniform(lead.DECAY_S, 1.0, 6)  # a returning hand's, per joint
        for got, expected in zip(
                lead.tracking_target(v_goal, q_target, q, v, arm_limits, decay),
                numpy_tracking_target(v_goal, q_target, q, v, arm_limits, decay), strict=True):
            assert np.allclose(got, expected, rtol=1e-9, atol=1e-12)
    fast, plain = lead.GoalVelocity(arm_limits, 0.005), NumpyGoalVelocity(arm_limits, 0.005)
    q = rng.uniform(arm_limits.lower_rad, arm_limits.upper_rad)
    for _ in range(3000):  # random walks, some to the limits, some periods not following
        q = np.clip(q + rng.normal(size=6) * rng.choice([1e-4, 0.01, 0.05]),
                    arm_limits.lower_rad, arm_limits.upper_rad)
        follow = bool(rng.random() > 0.05)
        assert np.allclose(fast.update(q, follow), plain.update(q, follow), rtol=1e-12,
                           atol=1e-12)
        assert np.allclose(fast.decay_s(0.1, 1.0), plain.decay_s(0.1, 1.0), rtol=1e-12)


def test_the_orientation_smoothing_matches_numpy():
    """Slow turns, half turns (the jump) and goals equal to the smoothed orientation."""
    limb = get_limb("right-arm")
    fast, plain = ArmReach(limb), NumpyReach(limb)
    rng = np.random.default_rng(43)
    R = Rotation.random(random_state=4)
    for k in range(6000):
        if k % 400 == 0:
            R = Rotation.random(random_state=k)
        elif k % 400 == 200:
            R = Rotation.from_rotvec(np.pi * np.array([0.0, 0.0, 1.0])) * R
        elif k % 7:
            R = Rotation.from_rotvec(rng.normal(size=3) * rng.choice([1e-9, 0.01, 0.1])) * R
        T = np.eye(4)
        T[:3, :3] = R.as_matrix()
        T[:3, 3] = rng.normal(size=3)
        dt = float(rng.choice([0.005, 0.0, 0.02]))
        assert np.allclose(fast.smoothed(T, dt), plain.smoothed(T, dt), rtol=0, atol=1e-12)


def test_the_swing_and_the_hand_errors_match_numpy():
    rng = np.random.default_rng(44)
    for name in ("right-arm", "left-arm"):
        limb = get_limb(name)
        base, _, offset, alpha, a, d, end, _ = limb.chain
        for k in range(500):
            q0 = limb.random_q(rng)
            path = q0 + np.cumsum(rng.normal(size=(8, 6)) * rng.choice([1e-8, 0.01, 0.2]),
                                  axis=0)
            if k % 50 == 0:
                path[:] = q0  # no way at all: the line has no length
            assert path_swing_m(path, base, offset, alpha, a, d, end) == pytest.approx(
                numpy_path_swing_m(limb, path), rel=1e-9, abs=1e-12)
            T_goal = limb.fk(limb.random_q(rng))
            T_S_N = np.eye(4)
            T_S_N[:3, :3] = Rotation.random(random_state=k).as_matrix()
            T_S_N[:3, 3] = rng.normal(size=3) * 0.05
            lift = float(rng.uniform(-0.1, 0.1))
            T_N_E = limb.fk(q0)
            for corrected in (False, True):
                expected = T_S_N @ T_N_E if corrected else T_N_E + np.outer(
                    [0, 0, 1, 0], [0, 0, 0, lift])
                T_actual = np.empty((4, 4))
                pos, rot, world = hand_errors(q0, base, offset, alpha, a, d, end, corrected,
                                              lift, T_S_N, T_goal, True, T_actual)
                assert np.allclose(T_actual, expected, rtol=0, atol=1e-13)
                assert np.allclose((pos, rot), pose_error(expected, T_goal), rtol=0,
                                   atol=1e-12)
                assert world == pytest.approx(
                    np.linalg.norm(T_goal[:3, 3] - (T_S_N @ T_N_E)[:3, 3]), abs=1e-12)


def test_the_free_mapping_matches_numpy():
    """Random walks of both hands with turns, jumps beyond the step limit, garbage (NaN, inf,
    beyond the range), clutches and repeated or older sample times."""
    rng = np.random.default_rng(45)
    for scale in (1.0, 0.5, 2.5):
        config = MappingConfig(mode="free", scale=scale)
        fast, plain = HandMapper(config), NumpyMapper(config)
        T_now = {hand: np.eye(4) for hand in ("right", "left")}
        T_S_hand = get_limb("right-arm").fk(np.zeros(6))
        t = 0.0
        for k in range(3000):
            hand = ("right", "left")[k % 2]
            R = Rotation.from_rotvec(rng.normal(size=3) * rng.choice([1e-3, 0.05, 1.0]))
            T_now[hand][:3, :3] = R.as_matrix() @ T_now[hand][:3, :3]
            T_now[hand][:3, 3] += rng.normal(size=3) * rng.choice([1e-4, 0.003, 0.01])
            T_O = T_now[hand].copy()
            draw = rng.random()
            if draw < 0.05:  # a jump of the samples alone (beyond the step limit mostly)
                T_O[:3, 3] += rng.normal(size=3) * 0.15
            elif draw < 0.08:
                T_O[rng.integers(4), rng.integers(4)] = rng.choice([np.nan, np.inf, -np.inf])
            elif draw < 0.11:
                T_O[rng.integers(3), 3] = rng.choice([-1.0, 1.0]) * rng.uniform(99.0, 1e300)
            elif draw < 0.13:
                fast.forget(hand)
                plain.forget(hand)
            t += float(rng.choice([0.005, 0.0, -0.01]))
            t_s = np.nan if rng.random() < 0.02 else t
            got, expected = (m.goal(hand, T_O, t_s, T_S_hand) for m in (fast, plain))
            assert (got is None) == (expected is None), k
            if got is not None:
                assert got.arm == expected.arm and got.calibrated_now == expected.calibrated_now
                assert np.allclose(got.T_S_goal, expected.T_S_goal, rtol=0, atol=1e-13), k
            assert fast.rejected == plain.rejected
            for hand_name, ref in fast._refs.items():
                other = plain._refs[hand_name]
                assert (ref.last_t_s == other.last_t_s
                        or (np.isnan(ref.last_t_s) and np.isnan(other.last_t_s)))


def test_the_largest_joint_difference_matches_numpy():
    rng = np.random.default_rng(46)
    for _ in range(3000):
        x, y = rng.normal(size=(2, 6)) * rng.choice([1e-9, 1e-6, 1.0])
        if rng.random() < 0.1:
            y[:] = x
        if rng.random() < 0.1:
            y[rng.integers(6)] = rng.choice([np.nan, np.inf])
        expected = np.max(np.abs(x - y))
        assert max_abs_difference(x, y) == pytest.approx(expected, rel=0, abs=0, nan_ok=True)


def test_the_rooms_solve_is_numpys_solve_to_the_last_bit():
    """The room solves its damped 6x6 systems with numpy's own gufunc (or, where a numpy moves
    that private function, with np.linalg.solve itself): both give the same bits, so either
    serves the room's last-bit test below."""
    from hubo_cli.teleop import room

    rng = np.random.default_rng(34)
    for _ in range(200):
        J = rng.normal(size=(6, 6))
        H = J.T @ J + 0.05**2 * np.eye(6)
        b = rng.normal(size=6)
        assert np.array_equal(room._solve(H, b), np.linalg.solve(H, b))


def test_the_rooms_step_kernels_match_numpy():
    """The clear search's compiled parts against the numpy lines they replace: its weighted
    error to the last bit (it becomes the step) and its square within a rounding (it only
    decides); the clipped step to the last bit, NaN and infinities included; the still-goal
    test as numpy decides it (drawn goals, none within 1e-9 of its thresholds)."""
    rng = np.random.default_rng(47)
    limb = get_limb("left-arm")
    base, _, offset, alpha, a, d, end, _ = limb.chain
    w = room_module._W
    for _ in range(500):
        q = rng.uniform(limb.lower_rad, limb.upper_rad)
        T_goal = limb.fk(rng.uniform(limb.lower_rad, limb.upper_rad))
        T, J, e = np.empty((4, 4)), np.empty((6, 6)), np.empty(6)
        c = weighted_error(q, base, offset, alpha, a, d, end, T_goal, w, T, J, e)
        T_ref, J_ref, e_ref = np.empty((4, 4)), np.empty((6, 6)), np.empty(6)
        jacobian(q, base, offset, alpha, a, d, end, T_ref, J_ref)
        e_ref[:3] = T_goal[:3, 3] - T_ref[:3, 3]
        rotation_error(T_ref, T_goal, e_ref[3:])
        e_ref[:] *= w
        assert np.array_equal(e, e_ref) and np.array_equal(J, J_ref)
        assert c == pytest.approx(float(e_ref @ e_ref), rel=1e-14)  # six terms: a few ulps

        q24, dq = rng.normal(size=24), rng.normal(size=6) * rng.choice([1e-9, 0.1, 10.0])
        lo, hi = -np.abs(rng.normal(size=6)), np.abs(rng.normal(size=6))
        if rng.random() < 0.2:
            dq[rng.integers(6)] = rng.choice([np.nan, np.inf, -np.inf])
        first, scale = int(rng.choice([0, 6, 12, 18])), float(rng.choice([1.0, 0.5, 0.25]))
        expected = q24.copy()
        expected[first:first + 6] = np.clip(q24[first:first + 6] + scale * dq, lo, hi)
        got = np.empty(24)
        clipped_step(q24, first, dq, scale, lo, hi, got)
        assert np.array_equal(got, expected, equal_nan=True)

        T_was = limb.fk(rng.uniform(limb.lower_rad, limb.upper_rad))
        T_near = T_was.copy()
        T_near[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * rng.choice(
            [1e-3, 1e-2])).as_matrix() @ T_was[:3, :3]
        T_near[:3, 3] += rng.normal(size=3) * rng.choice([1e-4, 1e-3])
        moved = np.linalg.norm(T_near[:3, 3] - T_was[:3, 3])
        cos = (np.trace(T_was[:3, :3].T @ T_near[:3, :3]) - 1.0) / 2.0
        if (abs(moved - room_module.STILL_GOAL_M) < 1e-9
                or abs(cos - np.cos(room_module.STILL_GOAL_RAD)) < 1e-9):
            continue
        expected = moved <= room_module.STILL_GOAL_M and cos >= np.cos(room_module.STILL_GOAL_RAD)
        assert goal_within(T_was, T_near, room_module.STILL_GOAL_M,
                           np.cos(room_module.STILL_GOAL_RAD)) == expected


def test_the_tilt_and_the_measured_torso_match_numpy():
    """The torso's tilt from drawn, tiny, huge, zero and non-finite quaternions (to 1e-15 rad:
    the same libm calls, one rounding apart at most), and the measured neck frame from drawn and
    non-finite estimates (a non-finite one keeps the last frame): equal."""
    rng = np.random.default_rng(47)
    for k in range(20000):
        q = rng.normal(size=4) * rng.choice([1e-300, 1e-6, 1.0, 1e6, 1e300])
        if k % 7 == 0:
            q[rng.integers(4)] = 0.0
        if k % 11 == 0:
            q[rng.integers(4)] = rng.choice([np.nan, np.inf, -np.inf])
        if k % 13 == 0:
            q[1:3] = 0.0
        expected = float(numpy_tilt_rad(q))
        got = tilt_rad(q)
        assert (np.isnan(got) and np.isnan(expected)) or abs(got - expected) <= 1e-15, q
    body = WholeBody(load_model())
    fast, plain = MeasuredTorso(body), NumpyMeasuredTorso(body)
    soles = np.stack([body.T_S_sole[leg] for leg in ("right-leg", "left-leg")])
    soles[:, :3, 3] += rng.normal(size=(2, 3)) * 0.01
    for k in range(3000):
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=k).as_matrix()
        T[:3, 3] = rng.normal(size=3)
        if k % 5 == 0:
            T[rng.integers(4), rng.integers(4)] = rng.choice([np.nan, np.inf, -np.inf])
        bad_soles = soles.copy()
        if k < 10:
            bad_soles[0, 0, 3] = np.nan  # no stance placed until the soles are finite
        got, expected = fast(T, bad_soles), plain(T, bad_soles)
        assert np.array_equal(got, expected), k


def test_the_collision_room_gives_the_same_targets_to_the_last_bit(monkeypatch):
    """The room as it is and as it was (the reference room with its first check as it is: the
    closed-loop test covers that one) called in turn on the inputs a generated stream gave it:
    the same targets to the last bit, call after call. A last-bit difference is not harmless
    here: the clear search breaks ties on it. Skipping a still goal's second check at the same
    joints with pinocchio's cached GJK guess (coal's distances then depend on what it computed
    before, within GJK's tolerance) gave 5e-15 rad after 393 calls of this stream and 3-10 mrad
    apart within 6 s of it and two others, and passed the closed-loop comparison below; the
    room's repeatable checker makes it exact (the reference checks again)."""
    inputs = []
    keep = CollisionRoom.keep
    made = {"checks": 0, "gradients": 0}
    check_near, distance_gradient = (SelfCollisionChecker.check_near,
                                     SelfCollisionChecker.distance_gradient)

    def recorded(self, q_prev, q_next, goals=None, commanded=None):
        # (the search compared below; the lead from the command after it is not mirrored)
        inputs.append((np.array(q_prev, dtype=float), np.array(q_next, dtype=float),
                       {a: (r, np.array(T)) for a, (r, T) in (goals or {}).items()}))
        return keep(self, q_prev, q_next, goals, commanded)

    def counted(method, key):
        def call(self, *args, **kwargs):
            made[key] += 1
            return method(self, *args, **kwargs)
        return call

    with monkeypatch.context() as patch:
        patch.setattr(CollisionRoom, "keep", recorded)
        patch.setattr(SelfCollisionChecker, "check_near", counted(check_near, "checks"))
        patch.setattr(SelfCollisionChecker, "distance_gradient",
                      counted(distance_gradient, "gradients"))
        follow_generated(3401, StreamSettings(duration_s=4.0, max_speed_m_s=0.25))
    # the search's work in the stream (round 19): a step cutting the error by less than
    # REST_M ends a call's search, a still goal takes the pose the last call rested at; the
    # same on both code paths: 3399 checks and 405 witness gradients in 1199 calls, 643
    # moving an arm (before: 3824 and 798 in 1191, 635)
    assert (made["checks"] + made["gradients"]) / len(inputs) < 3.5, (made, len(inputs))
    assert made["gradients"] < 600, made

    class Reference(ReferenceRoom):
        _distance = CollisionRoom._distance

    model = load_model(limits="teleop")
    new = CollisionRoom(model, arms=("left-arm", "right-arm"))
    old = Reference(model, arms=("left-arm", "right-arm"))
    for k, (q_prev, q_next, goals) in enumerate(inputs):
        assert np.array_equal(new.keep(q_prev, q_next, goals), old.keep(q_prev, q_next, goals)), k
    # measured: 1199 calls, 401 with a still goal, 643 moving the left arm out of the band
    assert new.skipped > 100 and sum(new.pushed_periods.values()) > 200


# ---------------------------------------------------------------- the whole target, closed loop


STREAMS = [(3400, 0.25), (3401, 0.25), (3407, 0.6)]  # 2 s each (see the module docstring)


def _joint_targets(monkeypatch, target_class, seed, max_speed):
    """Per period of a generated stream (follow_generated's loop): the target's joint targets,
    the joints the arms were at (the trajectory generator's last command, on the ideal
    driver) and the arms' target velocities for it; and the run."""
    recorded, logged = [], []

    class Recorded(target_class):
        def __call__(self, t_s, state):
            q, info = super().__call__(t_s, state)
            velocity = self.store.get(ARM_TARGET_VELOCITY) or {}
            recorded.append(np.concatenate([q, state.q_rad] + [
                velocity.get(arm, np.zeros(6)) for arm in ("right-arm", "left-arm")]))
            logged.append({key: value for key, value in info.items()
                           if isinstance(value, (int, float))})  # what the loop logs
            return q, info

    with monkeypatch.context() as patch:
        patch.setattr(target_module, "TeleopTarget", Recorded)
        # the joints' trade (teleop/trade.py, the same compiled kernel in both, checked against
        # daqp in tests/test_teleop_trade.py) left out: with it the two runs agree to 4e-11 rad
        # through every traded period of seed 3407 at 0.6 m/s, but the traded run reaches a
        # knife edge 485 periods later (the left arm at its reach limit, slowed to half
        # speed) where they part by 4e-6 rad; not located further (round 8's review)
        patch.setattr(target_module, "traded_goal", lambda q_goal, *_: (q_goal, 0))
        # and, on seed 3407 at 0.6 m/s only, free mode's orientation law (kinematics/
        # arm_reach.py: faster while the arm follows freely; the same Python in both) held at
        # its slower time constant: with it the two runs' joint targets agree to 2e-13 rad
        # throughout that stream, but from period 530 the left arm's synchronisation alternates
        # every period (none / phase) and the generator's commands part from 1e-10 rad, growing
        # about 1.3x a period, to 1.1e-4 (the other streams compare the law as shipped)
        if (seed, max_speed) == (3407, 0.6):
            patch.setattr(ArmReach, "time_constant_s",
                          lambda self, dt_s, follows_freely:
                          self.settings.orientation_time_constant_s)
        if target_class is ReferenceTarget:
            patch.setattr(target_module, "tracking_target", numpy_tracking_target)
        run = follow_generated(seed, StreamSettings(duration_s=2.0, max_speed_m_s=max_speed))
    return np.array(recorded), logged, run


@pytest.mark.parametrize("seed, max_speed", STREAMS)
def test_the_compiled_target_moves_the_arms_as_the_numpy_target(monkeypatch, seed, max_speed):
    fast, fast_log, fast_run = _joint_targets(monkeypatch, target_module.TeleopTarget, seed,
                                              max_speed)
    plain, plain_log, plain_run = _joint_targets(monkeypatch, ReferenceTarget, seed, max_speed)
    assert fast.shape == plain.shape
    # measured on these streams: joint targets 3e-14 rad apart, the generator's commands
    # 3e-10 rad and the target velocities 4e-9 rad/s (ruckig's time-optimal profiles and the
    # velocity's catch-up share magnify the rounding), bounds 30x and more over them
    difference = np.abs(fast - plain)
    assert np.max(difference[:, :24]) <= 1e-9
    assert np.max(difference[:, 24:48]) <= 1e-8
    assert np.max(difference[:, 48:]) <= 1e-7
    # the logged values of every period: the same keys, the same numbers (the hands' positions
    # and errors follow the joints, to 1e-9)
    assert len(fast_log) == len(plain_log)
    for got, expected in zip(fast_log, plain_log, strict=True):
        assert got.keys() == expected.keys()
        assert np.allclose(list(got.values()), list(expected.values()), rtol=0, atol=1e-9)
    for arm, figures in plain_run.hands.items():
        for key, value in figures.items():
            assert fast_run.hands[arm][key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
    if (seed, max_speed) == (3407, 0.6):  # the clear search compared: this stream keeps the right
        # arm's target out of the collision band 2.68 s (of the 2 s stream and its settling;
        # with the generator's 40 deg/s turns seed 3402 no longer comes near the body, and
        # seeds 3409, 3410 and 3417 meet a tie, see the module docstring)
        assert max(hand["collision_room_s"] for hand in plain_run.hands.values()) > 1.0
