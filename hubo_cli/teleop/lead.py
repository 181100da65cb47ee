"""Feed-forward for an arm's trajectory generator: the goal's joint velocity, from its recent
joint targets.

The trajectory generator (ruckig, :mod:`hubo_cli.motion.tracker`) plans to arrive at its target
with the target velocity it is given. Given zero, it plans to stop at a goal that keeps moving,
and the hand lags the operator by about the distance it would take to brake. Given the goal's
own velocity, a tracker that has caught up stays on the goal.

:class:`GoalVelocity` estimates that velocity causally: the least-squares slope of the arm's
joint targets over the last ``window_s`` (a straight line through the recent targets: the
operator's tremor and the input's sample steps average out; for a goal at constant velocity it
is exact, for one that speeds up or slows down it lags by half the window). The estimate is
kept within 90 % of each joint's speed limit (the tracker's own clip) and below the speed from
which the joint still stops before its position limit, and it is zero whenever the caller says
the goal is not being followed (out of reach, held, clutched, a branch change, slowed near a
singularity, kept out of the collision band): then the tracker stops at its target as before,
so a hand at the edge of its reach or on hold never runs on past its target.

Ruckig takes the target velocity as the velocity to have *at* the target position: a tracker
slower than the goal and close behind it would first back away from it to gain the run-up it
needs (a joint at rest 0.075 rad behind a goal moving at 0.5 rad/s backs 0.05 rad away), and
one far behind would arrive at full speed and overshoot where the goal slows. So each joint is
given at most the speed it can reach over the distance to its target at ``RUN_UP_SHARE`` of its
acceleration limit, and that only in full where it has caught up with its target, falling to
none where it lags by what the goal covers in ``CATCH_UP_S`` (:func:`reachable_velocity`): a
joint that keeps up loses part of the lag of planning to stop, one that lags further catches
up as before.

A joint so given its goal still plans to stop at it (or to arrive at the velocity it was cut
to), and lags a goal that keeps moving. :func:`tracking_target` gives it instead the state of
the goal's prediction (its velocity decaying to rest within ``DECAY_S``) at the first time the
joint can be there within its acceleration and speed limits: the joint meets the goal instead of
chasing it, and its target leads the goal by at most ``DECAY_S`` of the goal's motion. Where a
joint of the arm cannot meet the goal soon (the goal outruns the joint's limits), the other
joints meeting it would swing the hand off the goal's path: the intercept is then blended back
to the goal with the reachable velocity (``MEET_FULL_S`` to ``MEET_NONE_S``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, kernel_array
from hubo_cli.motion.limits import TARGET_SPEED_SHARE, JointLimits

WINDOW_S = 0.1  # the slope's window: the "constant goal velocity over the last 0.1 s"
RUN_UP_SHARE = 0.5  # of the acceleration limit, for the run-up to the target velocity (a joint
# on a 0.4 rad, 1.5 rad/s sine: 0.0148 rad RMS; 0.3-0.7 0.0143-0.0162, 0.9 0.053, 1.0 0.092 as
# much as with zero target velocity, 0.093)
CATCH_UP_S = 0.2  # the goal's velocity is given in full where the joint lags its target by
# nothing, none where it lags by what the goal covers in this long. Generated streams at
# 0.25 m/s (seeds 1, 3, 4, 5, 8 s, ideal driver): the 8 hands' reachable position RMS sum to
# 250 mm, against 257 without feed-forward, 262 with 0.1 s, 279 in full up to 1.25 times the
# distance to stop from the goal's velocity, 285 with no catch-up rule: there the arms'
# 0.8 rad/s^2, not this lag, makes most of the error, and a joint arriving fast overshoots a
# goal that slows faster than it can.


def slope_weights(t_s: np.ndarray) -> np.ndarray:
    """The weights w (oldest sample first) whose sum w @ x over samples x taken at the times
    ``t_s`` is the least-squares slope of x over time (per unit of time); they sum to zero.
    Shared by :class:`GoalVelocity` (evenly spaced periods) and
    :class:`hubo_cli.teleop.reach_lead.ReachLead` (the input's sample times)."""
    t = np.asarray(t_s, dtype=float)
    t = t - t.mean()
    return t / (t @ t)


def stop_distance_rad(speed_rad_s: np.ndarray, accel_rad_s2: np.ndarray,
                      jerk_rad_s3: np.ndarray) -> np.ndarray:
    """Per joint, the distance (rad) a jerk-limited stop from ``speed_rad_s`` (>= 0, no
    acceleration at the start) covers, and so the distance a start from rest to that speed
    takes: :func:`hubo_cli.motion.limits.braking_distance` at zero acceleration."""
    v, a, j = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                    for x in (speed_rad_s, accel_rad_s2, jerk_rad_s3)))
    return np.array([_stop_distance(*x) for x in zip(v.flat, a.flat, j.flat, strict=True)]
                    ).reshape(v.shape)


def stop_speed_rad_s(room_rad: np.ndarray, accel_rad_s2: np.ndarray,
                     jerk_rad_s3: np.ndarray) -> np.ndarray:
    """Per joint, the largest speed (rad/s) whose :func:`stop_distance_rad` is at most
    ``room_rad`` (its inverse; 0 for no room)."""
    r, a, j = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                    for x in (room_rad, accel_rad_s2, jerk_rad_s3)))
    return np.array([_stop_speed(*x) for x in zip(r.flat, a.flat, j.flat, strict=True)]
                    ).reshape(r.shape)


@nb.njit(**JIT)
def _stop_distance(v, a, j):
    """:func:`stop_distance_rad` of one joint."""
    if v <= a * a / j:
        return v * math.sqrt(v / j)
    return v * v / (2 * a) + v * a / (2 * j)


@nb.njit(**JIT)
def _stop_speed(room, a, j):
    """:func:`stop_speed_rad_s` of one joint."""
    if room < 0.0:
        room = 0.0
    knee = a * a / j
    low = np.cbrt(room * room * j)  # v sqrt(v / j) = room, below v = a^2 / j
    if low <= knee:
        return low
    return 0.5 * (-knee + math.sqrt(knee * knee + 8.0 * a * room))  # v^2/2a + va/2j


def reachable_velocity(v_goal_rad_s: np.ndarray, q_target_rad: np.ndarray, q_rad: np.ndarray,
                       v_rad_s: np.ndarray, limits: JointLimits,
                       share: float = RUN_UP_SHARE) -> np.ndarray:
    """Per joint, the goal's velocity cut to what the joint, at ``q_rad`` moving at
    ``v_rad_s``, reaches by its target at ``share`` of its acceleration limit (and its jerk
    limit) without first moving away from it (zero where the joint is past its target), times
    the share that has caught up: 1 - |d| / (|v_goal| CATCH_UP_S) within [0, 1], d the
    distance to the target (rad/s)."""
    out = np.empty(len(v_goal_rad_s))
    _reachable(kernel_array(v_goal_rad_s), kernel_array(q_target_rad), kernel_array(q_rad),
               kernel_array(v_rad_s), limits.acceleration_rad_s2, limits.jerk_rad_s3,
               float(share), out)
    return out


@nb.njit(**JIT)
def _reachable(v_goal, q_target, q, v, accel, jerk, share, out):
    """:func:`reachable_velocity` into ``out``, one joint at a time."""
    for i in range(out.shape[0]):
        s = np.sign(v_goal[i])
        d = (q_target[i] - q[i]) * s
        u = max(v[i] * s, 0.0)
        speed = abs(v_goal[i])
        a, j = share * accel[i], jerk[i]
        run_up = _stop_speed(d + _stop_distance(u, a, j), a, j) if d > 0 else 0.0
        caught_up = min(max(1.0 - abs(d) / (speed * CATCH_UP_S + 1e-12), 0.0), 1.0)
        out[i] = s * min(speed, run_up) * caught_up


@nb.njit(**JIT)
def _estimate(weights, Q, q_target, lower, upper, velocity, accel, jerk, out):
    """:meth:`GoalVelocity.update`'s estimate into ``out``: the slope of the targets ``Q``
    (ring buffer rows) with ``weights``, within 90 % of the speed limit and the speed that
    still stops before the position limit ahead."""
    for i in range(out.shape[0]):
        v = 0.0
        for k in range(weights.shape[0]):
            v += weights[k] * Q[k, i]
        room = upper[i] - q_target[i] if v > 0 else q_target[i] - lower[i]
        cap = min(TARGET_SPEED_SHARE * velocity[i], _stop_speed(room, accel[i], jerk[i]))
        out[i] = min(max(v, -cap), cap)


class GoalVelocity:
    """The causal estimate of one arm's goal velocity in joint space (see the module docstring).

    Args:
        limits: the arm's joint limits.
        dt_s: the control period (s): one target is pushed per period.
        window_s: the slope's window (s).
    """

    def __init__(self, limits: JointLimits, dt_s: float, window_s: float = WINDOW_S) -> None:
        self.limits = limits
        k = max(3, int(round(window_s / dt_s)) + 1)
        self.samples = k  # the window's length in periods
        self.dt_s = dt_s
        slope = slope_weights(np.arange(k) * dt_s)  # oldest sample first
        # row i: the slope's weights for the ring buffer whose newest entry is slot i
        self._weights = np.array([np.roll(slope, i + 1) for i in range(k)])
        self._q = np.zeros((k, limits.size))
        self._slot = -1
        self._count = 0
        self.v_rad_s = np.zeros(limits.size)
        self._v = np.zeros((k, limits.size))  # the estimates, in the targets' slots
        self._v_count = 0  # estimates in a row while following

    def clear(self) -> None:
        """Forget the history (the next estimates are zero until the window has filled)."""
        self._count = 0
        self._v_count = 0
        self.v_rad_s = np.zeros(self.limits.size)

    def update(self, q_target_rad: np.ndarray, follow: bool) -> np.ndarray:
        """Push this period's joint target; return the target velocity (rad/s) to give the
        tracker: the estimate, within the limits, or zero when ``follow`` is False or the
        window has not filled yet."""
        k = len(self._q)
        self._slot = (self._slot + 1) % k
        self._q[self._slot] = q_target_rad
        self._count = min(self._count + 1, k)
        if not follow or self._count < k:
            self.v_rad_s = np.zeros(self.limits.size)
            self._v_count = 0
            return self.v_rad_s
        lim = self.limits
        self.v_rad_s = np.empty(lim.size)
        _estimate(self._weights[self._slot], self._q, kernel_array(q_target_rad), lim.lower_rad,
                  lim.upper_rad, lim.velocity_rad_s, lim.acceleration_rad_s2, lim.jerk_rad_s3,
                  self.v_rad_s)
        self._v[self._slot] = self.v_rad_s
        self._v_count = min(self._v_count + 1, k)
        return self.v_rad_s

    def decay_s(self, shortest_s: float, longest_s: float) -> np.ndarray:
        """Per joint, the time constant (s) with which the goal's velocity decays: w = w0
        exp(-window / tau), w the estimate now and w0 the one a window before (the same sign,
        slower), within [``shortest_s``, ``longest_s``]; ``longest_s`` where the goal does not
        slow so, ``shortest_s`` until the window holds estimates in a row."""
        k = len(self._q)
        if self._v_count < k:
            return np.full(self.limits.size, float(shortest_s))
        w0, w = self._v[(self._slot + 1) % k], self._v[self._slot]
        out = np.full(self.limits.size, float(longest_s))
        slowing = (w * w0 > 0.0) & (np.abs(w) < np.abs(w0))
        out[slowing] = (k - 1) * self.dt_s / np.log(w0[slowing] / w[slowing])
        return np.clip(out, shortest_s, longest_s)


# The intercept (:func:`tracking_target`): where ruckig's stop at the target leaves a joint
# w^2 / 2a behind a goal moving at w, the joint is given the predicted goal's state at the
# first time it can be there. The goal is predicted from its velocity decaying to rest with
# DECAY_S (the target leads the goal by at most its velocity x DECAY_S); the intercept is
# used in full where every joint of the arm meets it within MEET_FULL_S, not at all where one
# needs MEET_NONE_S or more (a joint the goal outruns would swing the hand off the goal's path
# while the others catch up), blended between. Tuned on the 50 + 10 short generated streams,
# the shipped samples in free mode and the out-of-reach walk at three speeds (DECAY_S 0.1 /
# 0.15 / 0.3 s, gates at 0.5 / 0.7 / 1.0 s and blends 0.2-0.6 / 0.3-0.8 s):
# docs/history/teleop.md, round 7.
DECAY_S = 0.1
MEET_FULL_S = 0.3
MEET_NONE_S = 0.8
INTERCEPT_SHARE = 0.9  # of the acceleration limit, for the intercept (the rest for the jerk)
MEET_STEP_S = 0.05  # the scan for the first time the joint meets the goal, then refined


@nb.njit(**JIT)
def _min_time(x0, v0, x1, v1, accel, speed):
    """The shortest time (s) in which a double integrator with |acceleration| <= ``accel``
    and |velocity| <= ``speed`` goes from (x0, v0) to (x1, v1), both speeds within the
    limit: full acceleration one way, then the other (a cruise at the speed limit between
    where the peak would pass it)."""
    best = np.inf
    for s in (1.0, -1.0):  # first toward +x, then toward -x (mirrored)
        dx, a0, a1 = s * (x1 - x0), s * v0, s * v1
        peak2 = accel * dx + 0.5 * (a0 * a0 + a1 * a1)
        if peak2 < 0.0:
            continue
        root = math.sqrt(peak2)
        for peak in (root, -root):
            if peak < max(a0, a1) - 1e-12:
                continue
            if peak <= speed:
                t = (2.0 * peak - a0 - a1) / accel
            else:
                t = ((2.0 * speed - a0 - a1) / accel
                     + (dx - (2.0 * speed * speed - a0 * a0 - a1 * a1) / (2.0 * accel)) / speed)
            best = min(best, t)
    return best


@nb.njit(**JIT)
def _late_s(t, w, g, q, v, accel, speed, decay):
    """How much later than ``t`` (s) the joint (``q``, ``v``) can at the soonest be in the
    predicted goal's state at ``t`` (the goal at ``g`` moving at ``w``, decaying with the time
    constant ``decay``); <= 0 where it can be there by then."""
    e = math.exp(-t / decay)
    return _min_time(q, v, g + w * decay * (1.0 - e), w * e, accel, speed) - t


@nb.njit(**JIT)
def _meet_s(w, g, q, v, accel, speed, decay):
    """The first time (s) at which the joint can be in the predicted goal's state (MEET_NONE_S
    if not before): a scan, bisection, then the secant (continuous in the joint's state)."""
    lo, f_lo = 0.0, _late_s(0.0, w, g, q, v, accel, speed, decay)
    if f_lo <= 0.0:
        return 0.0
    t = MEET_STEP_S
    while t <= MEET_NONE_S + 1e-9:
        f = _late_s(t, w, g, q, v, accel, speed, decay)
        if f <= 0.0:
            hi, f_hi = t, f
            for _ in range(4):
                mid = 0.5 * (lo + hi)
                f_mid = _late_s(mid, w, g, q, v, accel, speed, decay)
                if f_mid <= 0.0:
                    hi, f_hi = mid, f_mid
                else:
                    lo, f_lo = mid, f_mid
            return lo + (hi - lo) * f_lo / (f_lo - f_hi)
        lo, f_lo = t, f
        t += MEET_STEP_S
    return MEET_NONE_S


@nb.njit(**JIT)
def _tracking_target(v_goal, q_target, q, v, lower, upper, velocity, accel, jerk, decay,
                     out_q, out_v):
    """:func:`tracking_target` into ``out_q`` and ``out_v``; returns the intercept's share."""
    n = out_q.shape[0]
    _reachable(v_goal, q_target, q, v, accel, jerk, RUN_UP_SHARE, out_v)
    meet = np.zeros(n)  # each joint's own (a time common to the arm's joints: excursions
    # up to 31.7 mm on the 50 streams, docs/history/teleop.md)
    for i in range(n):
        out_q[i] = q_target[i]
        if v_goal[i] != 0.0:
            meet[i] = _meet_s(v_goal[i], q_target[i], q[i], v[i], INTERCEPT_SHARE * accel[i],
                              velocity[i], decay[i])
    share = min(max((MEET_NONE_S - meet.max()) / (MEET_NONE_S - MEET_FULL_S), 0.0), 1.0)
    if share == 0.0:
        return 0.0
    for i in range(n):
        w = v_goal[i]
        if w == 0.0:
            continue
        e = math.exp(-meet[i] / decay[i])
        p = min(max(q_target[i] + w * decay[i] * (1.0 - e), lower[i]), upper[i])
        vt = w * e  # within the speed that still stops before the position limit from p
        room = upper[i] - p if vt > 0 else p - lower[i]
        cap = min(TARGET_SPEED_SHARE * velocity[i], _stop_speed(room, accel[i], jerk[i]))
        out_q[i] = q_target[i] + share * (p - q_target[i])
        out_v[i] = share * min(max(vt, -cap), cap) + (1.0 - share) * out_v[i]
    return share


def tracking_target(v_goal_rad_s: np.ndarray, q_target_rad: np.ndarray, q_rad: np.ndarray,
                    v_rad_s: np.ndarray, limits: JointLimits,
                    decay_s: np.ndarray | float = DECAY_S
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """Per joint, the target (position rad, velocity rad/s) to give an arm's trajectory
    generator, the joints at ``q_rad`` moving at ``v_rad_s``, their goal at ``q_target_rad``
    moving at ``v_goal_rad_s`` (zero: not followed): :func:`reachable_velocity` at the goal
    blended with the intercept of the goal's prediction (its velocity decaying with the time
    constant ``decay_s``, s, one for every joint or per joint; see DECAY_S); and the
    intercept's share (0: the goal and the reachable velocity, as they were). A ``decay_s``
    array of the joints' length is taken as it is: a caller calling every period keeps one
    (not a new numpy ``full`` a call)."""
    n = len(v_goal_rad_s)
    out_q, out_v = np.empty(n), np.empty(n)
    decay = (kernel_array(decay_s) if type(decay_s) is np.ndarray and decay_s.shape == (n,)
             else np.full(n, decay_s, dtype=float))
    share = _tracking_target(kernel_array(v_goal_rad_s), kernel_array(q_target_rad),
                             kernel_array(q_rad), kernel_array(v_rad_s), limits.lower_rad,
                             limits.upper_rad, limits.velocity_rad_s,
                             limits.acceleration_rad_s2, limits.jerk_rad_s3, decay, out_q,
                             out_v)
    return out_q, out_v, share
