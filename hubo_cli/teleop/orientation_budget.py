"""Position first: an arm's orientation target turns toward the operator's only with what the
joints have left after the position.

Each period the orientation the arm's reach search is given (``R_cmd``) would turn toward the
goal's by the share ``dt / (TIME_CONSTANT_S + dt)`` of the rotation between them, plus the
goal's own angular velocity (low-passed over ``RATE_TIME_CONSTANT_S``) times dt. That turn,
about the tool point with its position held, asks the arm's joints for ``u_R = J^-1 [0, w]``
(the arm's 6x6 Jacobian at its joint target). The position asks them for
``u_P = J^-1 [v_goal, 0] + lag / HORIZON_S``: the goal's velocity (its least-squares slope over
the last 0.1 s, :class:`~hubo_cli.teleop.reach_lead.ReachLead`'s) with the orientation held,
and what the tracker still lags its target by, caught up within ``HORIZON_S``. Over
``HORIZON_S`` each joint can reach the velocities within its speed limit and its acceleration
limit times ``HORIZON_S`` of its tracker's velocity. The turn is taken by the largest share
``s`` in [0, 1] with ``u_P + s u_R`` within those on every joint; where the position alone asks
a joint for more, the turn may only take that joint's demand back (``s = 0`` if it adds to it).
So a hand whose joints are busy with the position keeps its orientation target and turns once
they are free.

Measured and not kept (docs/history/teleop.md, "The orientation given what the joints have
left"): the module-level switches below are the variants measured there (set them before a
target is built; the target's ``SLOW_AT_LIMIT`` likewise). ``TRADE = 1``: the orientation
rate nearest the one asked whose joint velocities fit the budget (penalty, active set), which
may turn away from the goal where the position alone asks too much; ``FEED = 0``: no angular
velocity fed forward; ``FLOOR = 1``: at
least the 1 s filter's turn; ``BAND_DEG``: the time constant from ``SLOW_S`` to the short one
over that band of orientation error.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, kernel_array
from hubo_cli.kinematics.reach import jacobian, rotation_error

TIME_CONSTANT_S = 1.0  # the turn asked toward the goal's orientation, as a first-order filter
HORIZON_S = 0.15  # the joints' budget: what they reach within this long at their limits
TRADE = 0  # experiment: 0 scaled turn, 1 best turn within the budget (the position first)
PENALTY = 1.0e4
MAX_RATE_RAD_S = 1.0
FEED = 1  # experiment: the goal's angular velocity fed forward
RATE_TIME_CONSTANT_S = 0.3
BAND_DEG = (0.0, 0.0)  # experiment: slow (1 s) within the band's low end, fast from its high end
SLOW_S = 1.0
FLOOR = 0  # experiment: at least the slow filter's turn


class OrientationBudget:
    """One arm's orientation target (see the module docstring).

    Args:
        chain: the arm's DH chain (:attr:`hubo_cli.kinematics.limb.Limb.chain`).
        time_constant_s: the filter's time constant toward the goal's orientation (s).
        horizon_s: the horizon of the joints' velocity budget (s).
    """

    def __init__(self, chain, time_constant_s: float = TIME_CONSTANT_S,
                 horizon_s: float = HORIZON_S) -> None:
        self.chain = chain
        self.time_constant_s, self.horizon_s = time_constant_s, horizon_s
        self.R_cmd: np.ndarray | None = None  # the orientation target (3x3, the goal's frame)
        self.share = 1.0  # of the turn asked, taken last period
        self._T_last: np.ndarray | None = None
        self.omega = np.zeros(3)

    def start(self) -> None:
        """Forget the orientation target (the next goal's orientation starts it)."""
        self.R_cmd = None
        self._T_last = None
        self.omega = np.zeros(3)

    def goal(self, T_goal: np.ndarray, dt_s: float, q_target_rad: np.ndarray, tracker,
             v_goal_m_s: np.ndarray | None, slow: bool = False) -> np.ndarray:
        """The goal (4x4, m, the arm's base frame) with the orientation target turned toward
        its orientation by what the joints have left this period.

        Args:
            T_goal: the operator's goal.
            dt_s: the time since the last call (s).
            q_target_rad: the arm's joint target so far (6,).
            tracker: the arm's tracker state (``q_rad``, ``v_rad_s``, ``limits``).
            v_goal_m_s: the goal position's velocity (3,; None: unknown, taken as zero).
        """
        T = np.array(T_goal, dtype=float)
        if self.R_cmd is None:
            self.R_cmd = T[:3, :3].copy()
            self._T_last = T
            return T
        if FEED:
            raw = np.empty(3)
            rotation_error(self._T_last, T, raw)
            self.omega += dt_s / (RATE_TIME_CONSTANT_S + dt_s) * (raw / dt_s - self.omega)
        self._T_last = T.copy()
        limits = tracker.limits
        base, _, offset, alpha, a, d, end, _ = self.chain
        kernel = _turn if TRADE == 0 else _trade
        tau = self.time_constant_s
        if BAND_DEG[1] > 0:
            T_cmd = T.copy()
            T_cmd[:3, :3] = self.R_cmd
            off = np.degrees(rotation_error(T_cmd, T, np.empty(3)))
            share = min(max((off - BAND_DEG[0]) / (BAND_DEG[1] - BAND_DEG[0]), 0.0), 1.0)
            tau = SLOW_S + share * (tau - SLOW_S)
        if slow:
            tau = SLOW_S
        floor = (dt_s / (SLOW_S + dt_s)) / (dt_s / (tau + dt_s)) if FLOOR else 0.0
        self.share = kernel(kernel_array(T), self.R_cmd, dt_s / (tau + dt_s), floor,
                           dt_s, self.horizon_s, kernel_array(q_target_rad),
                           kernel_array(tracker.q_rad), kernel_array(tracker.v_rad_s),
                           limits.velocity_rad_s, limits.acceleration_rad_s2,
                           np.zeros(3) if v_goal_m_s is None else kernel_array(v_goal_m_s),
                           self.omega, base, offset, alpha, a, d, end)
        T[:3, :3] = self.R_cmd
        return T


@nb.njit(**JIT)
def _turn(T_goal, R_cmd, alpha, floor, dt, horizon, q_target, q, v, v_max, a_max, v_goal, omega,
          base, offset, alpha_dh, a_dh, d_dh, end):
    """:meth:`OrientationBudget.goal`'s step: turns ``R_cmd`` in place by the share ``s`` of
    ``alpha`` times its rotation to ``T_goal``'s; returns ``s``."""
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    jacobian(q_target, base, offset, alpha_dh, a_dh, d_dh, end, T, J)
    T_cmd = np.eye(4)
    T_cmd[:3, :3] = R_cmd
    w = np.empty(3)
    rotation_error(T_cmd, T_goal, w)
    for i in range(3):
        w[i] = alpha * w[i] + omega[i] * dt  # the turn asked this period
    angle = math.sqrt(w @ w)
    if not angle > 1e-12:
        return 1.0
    rhs = np.zeros((6, 2))
    for i in range(3):
        rhs[i, 0] = v_goal[i]
        rhs[3 + i, 1] = w[i] / dt  # the turn asked, as an angular velocity
    u = np.linalg.solve(J, rhs)
    s = 1.0
    for i in range(6):
        u_p = u[i, 0] + (q_target[i] - q[i]) / horizon
        u_r = u[i, 1]
        hi = min(v_max[i], v[i] + a_max[i] * horizon)
        lo = max(-v_max[i], v[i] - a_max[i] * horizon)
        if u_r > 1e-12:
            s = min(s, max((hi - u_p) / u_r, 0.0))
        elif u_r < -1e-12:
            s = min(s, max((lo - u_p) / u_r, 0.0))
    if not s > floor:  # also a NaN (a singular Jacobian)
        s = floor
    turn = s * angle
    x, y, z = w[0] / angle, w[1] / angle, w[2] / angle
    sin_t, one_cos = math.sin(turn), 1.0 - math.cos(turn)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    step = np.eye(3) + sin_t * K + one_cos * (K @ K)  # about the goal frame's axis w
    R_new = step @ R_cmd
    for i in range(3):
        for j in range(3):
            R_cmd[i, j] = R_new[i, j]
    return s


@nb.njit(**JIT)
def _trade(T_goal, R_cmd, alpha, floor, dt, horizon, q_target, q, v, v_max, a_max, v_goal, omega,
           base, offset, alpha_dh, a_dh, d_dh, end):
    """The orientation rate w nearest the one asked whose joint velocities, added to the
    position's, stay within the budget (penalty, active set); the position first: where the
    position alone asks too much, w takes what it can of it back."""
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    jacobian(q_target, base, offset, alpha_dh, a_dh, d_dh, end, T, J)
    T_cmd = np.eye(4)
    T_cmd[:3, :3] = R_cmd
    w = np.empty(3)
    rotation_error(T_cmd, T_goal, w)
    Jinv = np.linalg.inv(J)
    u_p = np.empty(6)
    lo = np.empty(6)
    hi = np.empty(6)
    for i in range(6):
        u_p[i] = (q_target[i] - q[i]) / horizon
        for k in range(3):
            u_p[i] += Jinv[i, k] * v_goal[k]
        hi[i] = min(v_max[i], v[i] + a_max[i] * horizon)
        lo[i] = max(-v_max[i], v[i] - a_max[i] * horizon)
    M = np.ascontiguousarray(Jinv[:, 3:])
    w_des = alpha * w / dt + omega
    rate = w_des.copy()
    for _ in range(8):
        A = np.eye(3)
        b = w_des.copy()
        u = u_p + M @ rate
        for i in range(6):
            bound = hi[i] if u[i] > hi[i] else lo[i] if u[i] < lo[i] else np.nan
            if bound == bound:
                for r in range(3):
                    b[r] += PENALTY * M[i, r] * (bound - u_p[i])
                    for c in range(3):
                        A[r, c] += PENALTY * M[i, r] * M[i, c]
        new = np.linalg.solve(A, b)
        done = np.max(np.abs(new - rate)) < 1e-6
        rate = new
        if done:
            break
    norm = math.sqrt(rate @ rate)
    cap = max(MAX_RATE_RAD_S, math.sqrt(w_des @ w_des))
    if norm > cap:
        rate *= cap / norm
        norm = cap
    if not norm * dt > 1e-12:
        return 0.0
    turn = norm * dt
    x, y, z = rate[0] / norm, rate[1] / norm, rate[2] / norm
    sin_t, one_cos = math.sin(turn), 1.0 - math.cos(turn)
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    step = np.eye(3) + sin_t * K + one_cos * (K @ K)
    R_new = step @ R_cmd
    for i in range(3):
        for j in range(3):
            R_cmd[i, j] = R_new[i, j]
    return (rate @ w_des) / max(w_des @ w_des, 1e-12)
