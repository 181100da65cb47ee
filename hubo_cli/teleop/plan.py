"""A receding-horizon plan of one arm's six joint accelerations (issue 34; docs/history/teleop.md,
rounds 16, 19 and 22), executed through the trajectory generator's velocity interface.

Each period, while the arm follows its goal freely and every joint is within ``GATE_RAD`` of
its target, the six joints' accelerations over 0-0.05-0.2-0.6 s (piecewise constant, 18
variables, each within ``ACCEL_SHARE`` of its limit, the first segment also within the jerk
limit times 0.05 s of the acceleration now) are planned from the generator's state (position,
velocity) to minimise the sum over ``SAMPLE_TIMES_S`` of |J (q(t) - q_goal(t)) - e0|^2: J the
arm's Jacobian at its target (rotation rows weighted ``ROTATION_WEIGHT_M`` m/rad as
:mod:`hubo_cli.teleop.trade`), q_goal(t) the target's joints moved along the goal's estimated
velocity for ``PREDICT_S`` and held beyond, e0 the share ``ORIENTATION_SHARE`` of the turn from
the target's orientation (the orientation filter's) to the operator's. The Hessian is a 3x3
matrix Kronecker J'J; it is solved by :func:`hubo_cli.teleop.trade._box_lsq` (a primal active
set, exact), warm-started from the last period's plan. The arm's tracker is then given the
plan's velocity ``AHEAD_S`` ahead (ruckig's velocity interface: jerk, acceleration and speed
limited).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT
from hubo_cli.kinematics.reach import jacobian
from hubo_cli.teleop.trade import ROTATION_WEIGHT_M, _box_lsq

SEGMENTS_S = np.array([0.0, 0.05, 0.2, 0.6])  # the accelerations' pieces (s)
SAMPLE_TIMES_S = np.array([0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6])
PREDICT_S = 0.2  # the goal moved along its velocity this long, held beyond
AHEAD_S = 0.05  # the tracker is given the plan's velocity this far ahead
ACCEL_SHARE = 0.9
GATE_RAD = 0.1  # planned in full while every joint is within this of its target
HANDOVER_RAD = 0.1  # and not at all beyond this: between, the plan's velocity blended with
# the position interface's
LAG_GATE_M = 1.0  # and the hand within this of its goal
LAG_HANDOVER_M = 1.0
ORIENTATION_SHARE = 0.6  # of the turn from the filtered target to the operator's orientation
JOINT_WEIGHT_M = 0.0  # m/rad: each joint's distance to its goal's joint, in the cost
TURN_FROM_RAD = 0.0  # the orientation share from this lag of the filtered orientation
TURN_FULL_RAD = 0.0  # in full from this one
ACROSS_WEIGHT = 1.0  # the hand's position error across the goal's way, against along it
REGULARISATION = 1e-9  # relative, on the Hessian's diagonal


def _ramp(x: float, full: float, none: float) -> float:
    """1 up to ``full``, 0 from ``none`` on, linear between."""
    if x <= full:
        return 1.0
    if x >= none:
        return 0.0
    return (none - x) / (none - full)


def plan_share(distance_rad: float, lag_m: float = 0.0) -> float:
    """The plan's share of an arm's velocity when its joints are at most ``distance_rad`` from
    their targets and the hand ``lag_m`` from its goal (the last period's): 1 within
    ``GATE_RAD`` and ``LAG_GATE_M``, 0 beyond ``HANDOVER_RAD`` or ``LAG_HANDOVER_M``, linear
    between."""
    return min(_ramp(distance_rad, GATE_RAD, HANDOVER_RAD),
               _ramp(lag_m, LAG_GATE_M, LAG_HANDOVER_M))


def position_coefficients(segments_s: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """C[m, k]: the position (rad) at ``times_s[m]`` that a unit acceleration over segment k
    (between ``segments_s[k]`` and ``segments_s[k + 1]``) adds, from rest."""
    C = np.zeros((len(times_s), len(segments_s) - 1))
    for m, t in enumerate(times_s):
        for k in range(len(segments_s) - 1):
            s, e = segments_s[k], segments_s[k + 1]
            if t <= s:
                continue
            tau = min(t, e) - s
            C[m, k] = 0.5 * tau * tau + tau * (t - s - tau)
    return C


_C = position_coefficients(SEGMENTS_S, SAMPLE_TIMES_S)


@nb.njit(**JIT)
def _plan(q, v, a, q_goal, v_goal, R_goal, share, accel, jerk, C, times, predict_s, first_s,
          w_rot, joint_w, across_w, turn_from, turn_full, base, offset, alpha, a_dh, d, end,
          y):
    """The plan (``y``, 18: segment-major accelerations, rad/s^2) in place, warm-started from
    ``y``; the hand aimed ``share`` of the way from the target's orientation to ``R_goal``."""
    n = 6
    K = C.shape[1]
    T, J = np.empty((4, 4)), np.empty((6, 6))
    jacobian(q_goal, base, offset, alpha, a_dh, d, end, T, J)
    for r in range(3, 6):
        for i in range(n):
            J[r, i] *= w_rot
    p0 = p1 = p2 = 0.0  # the goal's velocity at the hand (m/s)
    for i in range(n):
        p0 += J[0, i] * v_goal[i]
        p1 += J[1, i] * v_goal[i]
        p2 += J[2, i] * v_goal[i]
    speed = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    if across_w != 1.0 and speed > 1e-4:  # the position error across the goal's way weighted
        # across_w, along it 1: a hand that lags does so along the goal's path
        u = np.array([p0, p1, p2]) / speed
        W = np.empty((3, 3))
        for r in range(3):
            for c in range(3):
                W[r, c] = across_w * ((1.0 if r == c else 0.0) - u[r] * u[c]) + u[r] * u[c]
        Jp = W @ np.ascontiguousarray(J[:3, :])
        for r in range(3):
            for i in range(n):
                J[r, i] = Jp[r, i]
    G = J.T @ J
    for i in range(n):  # each joint's own distance to its goal, weighted: the arm's weak
        # directions (the shoulder yaw against the wrist yaw) pinned to the goal's joints
        G[i, i] += joint_w * joint_w
    e0 = np.zeros(6)  # the turn from the target's orientation to the goal's (small angle)
    if share > 0.0:
        R = R_goal @ np.ascontiguousarray(T[:3, :3]).T
        e0[3] = 0.5 * (R[2, 1] - R[1, 2]) * w_rot * share
        e0[4] = 0.5 * (R[0, 2] - R[2, 0]) * w_rot * share
        e0[5] = 0.5 * (R[1, 0] - R[0, 1]) * w_rot * share
        lag = np.sqrt(e0[3] * e0[3] + e0[4] * e0[4] + e0[5] * e0[5]) / (w_rot * share)
        if lag < turn_full:  # the filter's lag behind a turning goal (tau x its turn rate),
            # not a wobble's: the share only in part below turn_full, none below turn_from
            ramp = max(0.0, (lag - turn_from) / max(turn_full - turn_from, 1e-12))
            for r in range(3, 6):
                e0[r] *= ramp
    Je0 = J.T @ e0
    f = np.zeros(K * n)
    M = C.T @ C
    for m in range(times.shape[0]):
        t = times[m]
        tg = min(t, predict_s)
        dm = np.empty(n)
        for i in range(n):
            dm[i] = q[i] + v[i] * t - (q_goal[i] + v_goal[i] * tg)
        g = G @ dm
        for k in range(K):
            c = C[m, k]
            if c == 0.0:
                continue
            for i in range(n):
                f[k * n + i] += c * (g[i] - Je0[i])
    H = np.empty((K * n, K * n))
    for k in range(K):
        for l in range(K):
            for i in range(n):
                for j in range(n):
                    H[k * n + i, l * n + j] = M[k, l] * G[i, j]
    scale = 0.0
    for i in range(K * n):
        scale += H[i, i]
    scale = REGULARISATION * scale / (K * n) + 1e-15
    for i in range(K * n):
        H[i, i] += scale
    lo, hi = np.empty(K * n), np.empty(K * n)
    for k in range(K):
        for i in range(n):
            lim = ACCEL_SHARE * accel[i]
            lo[k * n + i], hi[k * n + i] = -lim, lim
    for i in range(n):
        lo[i] = max(lo[i], a[i] - jerk[i] * first_s)
        hi[i] = min(hi[i], a[i] + jerk[i] * first_s)
        if lo[i] > hi[i]:  # the acceleration now beyond the share: the nearest bound
            lo[i] = hi[i] = min(max(a[i], -ACCEL_SHARE * accel[i]), ACCEL_SHARE * accel[i])
    _box_lsq(H, f, lo, hi, y)


class ArmPlan:
    """One arm's plan, warm-started period to period (see the module docstring).

    Args:
        chain: the arm's (base, offset, alpha, a, d, end) as the compiled kernels take it.
        accel_rad_s2, jerk_rad_s3: the arm's joints' limits.
    """

    def __init__(self, chain: tuple, accel_rad_s2: np.ndarray, jerk_rad_s3: np.ndarray) -> None:
        self.chain = chain
        self.accel = np.ascontiguousarray(accel_rad_s2, dtype=float)
        self.jerk = np.ascontiguousarray(jerk_rad_s3, dtype=float)
        self.y = np.zeros(_C.shape[1] * 6)

    def reset(self) -> None:
        """Forget the last plan (the next starts cold)."""
        self.y[:] = 0.0

    def velocity(self, q_rad, v_rad_s, a_rad_s2, q_goal_rad, v_goal_rad_s,
                 R_goal: np.ndarray) -> np.ndarray:
        """The plan's joint velocity ``AHEAD_S`` ahead (rad/s) from the state (q, v, a), for the
        goal's joints ``q_goal_rad`` moving at ``v_goal_rad_s`` and the hand aimed
        ``ORIENTATION_SHARE`` of the way from their orientation to ``R_goal`` (3x3, the
        operator's, in the arm's base frame)."""
        _plan(np.ascontiguousarray(q_rad, dtype=float), np.ascontiguousarray(v_rad_s, dtype=float),
              np.ascontiguousarray(a_rad_s2, dtype=float),
              np.ascontiguousarray(q_goal_rad, dtype=float),
              np.ascontiguousarray(v_goal_rad_s, dtype=float),
              np.ascontiguousarray(R_goal, dtype=float), float(ORIENTATION_SHARE), self.accel,
              self.jerk, _C,
              SAMPLE_TIMES_S, PREDICT_S, SEGMENTS_S[1], ROTATION_WEIGHT_M, JOINT_WEIGHT_M,
              float(ACROSS_WEIGHT), float(TURN_FROM_RAD), float(TURN_FULL_RAD), *self.chain,
              self.y)
        return np.asarray(v_rad_s, dtype=float) + self.y[:6] * AHEAD_S
