"""Trading one arm joint for another where a joint cannot follow its goal.

Each arm joint's trajectory generator follows its own goal time-optimally
(:func:`hubo_cli.teleop.lead.tracking_target`); where a stroke asks more of one joint than its
acceleration, speed or position limit gives, that joint lags and the hand with it, while the
other joints, which could make up part of it, keep to their own goals. :func:`traded_goal`
looks ``HORIZON_S`` ahead: each joint can then be within an interval (``ACCEL_SHARE`` of its
acceleration limit, its speed and position limits, from its state now), and the goal's joints
are predicted along their velocity. Where a predicted goal joint lies outside its interval
(the joint is *short*), every joint's goal is offset to minimise the hand's predicted pose
error (position in m, rotation weighted ``ROTATION_WEIGHT_M`` m/rad: position first) within
those intervals: a 6-joint box-constrained least squares (:func:`_box_lsq`, a primal active
set, exact), linearised where the arm will be (the short joints at their interval's nearest
end, the others at the goal) with the exact pose error there. The offsets found are added to
the goal's joints, the short joints' too: a short joint's offset is measured from its
interval's end but added to its goal, so it keeps going for the goal at full effort (an
empirical choice: adding the offsets where the solve assumed the joints would be, or pinning
the short joints, followed the generated streams worse; docs/history/teleop.md, round 8's
review). ``OFFSET_CAP_RAD`` is a guard: at ``HORIZON_S`` an interval is at most
``ACCEL_SHARE`` x 0.8 rad/s^2 x (0.3 s)^2 = 0.065 rad wide, so it binds only for a longer
horizon or a faster arm. The pose error is against the arm's goal as the reach search gave
it (its orientation smoothed): traded against the operator's unsmoothed orientation, the
generated streams gain in orientation but the shipped samples lose position
(docs/history/teleop.md, round 8). The trajectory generator and the safety modules after it
are unchanged.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, chain_fk, kernel_array
from hubo_cli.kinematics.reach import jacobian
from hubo_cli.motion.limits import JointLimits

HORIZON_S = 0.3  # 0.1 / 0.5 s: 82 of the 100 hands within 10 mm against 85 (the test's 50
# streams at 0.25 m/s; docs/history/teleop.md, round 8)
ROTATION_WEIGHT_M = 0.19  # m/rad: 10 mm against 3 deg, the targets
OFFSET_CAP_RAD = 0.1
ACCEL_SHARE = 0.9
REGULARISATION = 1e-6  # m^2/rad^2 on each offset (a unique solution near a singularity)


@nb.njit(**JIT)
def _max_advance(v, accel, speed, h):
    """The largest displacement (rad) in ``h`` s from speed ``v`` with |a| <= ``accel``,
    |v| <= ``speed`` (from above the speed limit: slowing down to it at ``accel``)."""
    if v > speed:
        t1 = (v - speed) / accel
        if t1 >= h:
            return v * h - 0.5 * accel * h * h
        return v * t1 - 0.5 * accel * t1 * t1 + speed * (h - t1)
    t1 = (speed - v) / accel
    if t1 >= h:
        return v * h + 0.5 * accel * h * h
    return v * t1 + 0.5 * accel * t1 * t1 + speed * (h - t1)


@nb.njit(**JIT)
def _solve_free(H, f, y, state, n):
    """y[free] = the minimiser of 0.5 y'Hy + f'y over the free entries (state 0), the others
    held: Gaussian elimination on the free block (at most 6x6)."""
    idx = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if state[i] == 0:
            idx[m] = i
            m += 1
    out = np.empty(n)
    for i in range(n):
        out[i] = y[i]
    if m == 0:
        return out
    A = np.empty((m, m + 1))
    for r in range(m):
        i = idx[r]
        rhs = -f[i]
        for k in range(n):
            if state[k] != 0:
                rhs -= H[i, k] * y[k]
        for c in range(m):
            A[r, c] = H[i, idx[c]]
        A[r, m] = rhs
    for c in range(m):  # H is positive definite: no pivoting needed
        piv = A[c, c]
        for r in range(c + 1, m):
            fct = A[r, c] / piv
            for k in range(c, m + 1):
                A[r, k] -= fct * A[c, k]
    for r in range(m - 1, -1, -1):
        s = A[r, m]
        for c in range(r + 1, m):
            s -= A[r, c] * out[idx[c]]
        out[idx[r]] = s / A[r, r]
    return out


@nb.njit(**JIT)
def _box_lsq(H, f, lo, hi, y):
    """Minimise 0.5 y'Hy + f'y within lo <= y <= hi (H positive definite), from ``y``
    (clipped into the box first), in place: a primal active set (exact; a handful of
    iterations for 6 variables)."""
    n = y.shape[0]
    state = np.zeros(n, dtype=np.int64)  # 0 free, -1 at lo, +1 at hi
    for i in range(n):
        if y[i] <= lo[i]:
            y[i], state[i] = lo[i], -1
        elif y[i] >= hi[i]:
            y[i], state[i] = hi[i], 1
    for _ in range(4 * n + 4):
        target = _solve_free(H, f, y, state, n)
        step, block = 1.0, -1
        for i in range(n):
            if state[i] != 0:
                continue
            d = target[i] - y[i]
            if d < 0.0 and target[i] < lo[i]:
                t = (lo[i] - y[i]) / d
            elif d > 0.0 and target[i] > hi[i]:
                t = (hi[i] - y[i]) / d
            else:
                continue
            if t < step:
                step, block = t, i
        for i in range(n):
            if state[i] == 0:
                y[i] += step * (target[i] - y[i])
        if block >= 0:
            if target[block] < lo[block]:
                y[block], state[block] = lo[block], -1
            else:
                y[block], state[block] = hi[block], 1
            continue
        worst, release = 1e-15, -1
        for i in range(n):
            if state[i] == 0:
                continue
            g = f[i]
            for k in range(n):
                g += H[i, k] * y[k]
            pull = -g if state[i] < 0 else g  # > 0: the objective pulls it into the box
            if pull > worst:
                worst, release = pull, i
        if release < 0:
            return
        state[release] = 0


@nb.njit(**JIT)
def _traded(q_goal, v_goal, q, v, lower, upper, velocity, accel, horizon_s, w_rot, cap,
            base, offset, alpha, a, d, end, out):
    """:func:`traded_goal` into ``out``; returns how many joints cannot reach their goal."""
    n = q_goal.shape[0]
    lo, hi, g, y = np.empty(n), np.empty(n), np.empty(n), np.zeros(n)
    count = 0
    for i in range(n):
        out[i] = q_goal[i]
    for i in range(n):
        if not (math.isfinite(q_goal[i]) and math.isfinite(v_goal[i]) and math.isfinite(q[i])
                and math.isfinite(v[i])):
            return 0  # a state not finite: the goal as it was
    for i in range(n):
        g[i] = min(max(q_goal[i] + v_goal[i] * horizon_s, lower[i]), upper[i])
        acc = ACCEL_SHARE * accel[i]
        # each end within the position limits (a joint braking into a limit: that limit)
        up = min(max(q[i] + _max_advance(v[i], acc, velocity[i], horizon_s), lower[i]),
                 upper[i])
        down = min(max(q[i] - _max_advance(-v[i], acc, velocity[i], horizon_s), lower[i]),
                   upper[i])
        lo[i], hi[i] = down - g[i], up - g[i]
        if lo[i] > 0.0 or hi[i] < 0.0:
            count += 1
        else:  # the others' offsets stay within the cap
            lo[i], hi[i] = max(lo[i], -cap), min(hi[i], cap)
    if count == 0:
        return 0
    # linearised where the arm will be (the short joints at their interval's nearest end, the
    # others at the goal), with the exact pose error there
    x0 = np.empty(n)
    for i in range(n):
        x0[i] = g[i] + min(max(0.0, lo[i]), hi[i])
        lo[i] -= x0[i] - g[i]
        hi[i] -= x0[i] - g[i]
    T_goal, T, J = np.empty((4, 4)), np.empty((4, 4)), np.empty((6, 6))
    chain_fk(g, base, offset, alpha, a, d, end, T_goal)
    jacobian(x0, base, offset, alpha, a, d, end, T, J)
    e = np.empty(6)
    for r in range(3):
        e[r] = T[r, 3] - T_goal[r, 3]
    R = np.ascontiguousarray(T[:3, :3]) @ np.ascontiguousarray(T_goal[:3, :3]).T  # the
    # hand's turn from the goal's (its small-angle vector below)
    e[3] = 0.5 * (R[2, 1] - R[1, 2]) * w_rot
    e[4] = 0.5 * (R[0, 2] - R[2, 0]) * w_rot
    e[5] = 0.5 * (R[1, 0] - R[0, 1]) * w_rot
    for r in range(3, 6):
        for i in range(n):
            J[r, i] *= w_rot
    H = J.T @ J
    f = J.T @ e
    for i in range(n):
        H[i, i] += REGULARISATION
    _box_lsq(H, f, lo, hi, y)
    for i in range(n):
        out[i] = min(max(q_goal[i] + min(max(y[i], -cap), cap), lower[i]), upper[i])
    return count


def traded_goal(q_goal_rad: np.ndarray, v_goal_rad_s: np.ndarray, q_rad: np.ndarray,
                v_rad_s: np.ndarray, limits: JointLimits, chain: tuple,
                horizon_s: float = HORIZON_S, rotation_weight_m: float = ROTATION_WEIGHT_M,
                cap_rad: float = OFFSET_CAP_RAD) -> tuple[np.ndarray, int]:
    """An arm's goal (rad), its joints offset where some cannot reach theirs ``horizon_s``
    ahead (see the module docstring), the arm at ``q_rad`` moving at ``v_rad_s``, the goal at
    ``q_goal_rad`` moving at ``v_goal_rad_s``; ``chain`` the arm's (base, offset, alpha, a, d,
    end) as the compiled kernels take it. Also how many joints cannot reach theirs (0: the
    goal as it was)."""
    out = np.empty(len(q_goal_rad))
    count = _traded(kernel_array(q_goal_rad), kernel_array(v_goal_rad_s), kernel_array(q_rad),
                    kernel_array(v_rad_s), limits.lower_rad, limits.upper_rad,
                    limits.velocity_rad_s, limits.acceleration_rad_s2, float(horizon_s),
                    float(rotation_weight_m), float(cap_rad), *chain, out)
    return out, count
