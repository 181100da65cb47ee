"""The nearest reachable pose on one IK branch: a bounded damped-least-squares search (compiled).

When the closed form has no exact solution on the branch an arm is on (within the joint limits),
teleoperation sends the hand to the reachable pose nearest to the goal instead: position first,
orientation second. "Nearest" is the weighted pose error

    cost(q) = w_pos^2 |p(q) - p_goal|^2 + w_rot^2 |log(R_goal R(q)^T)|^2

(w_pos per metre, w_rot metres per radian: how many metres of position error one radian of
orientation error is worth), minimised from the current joints by a few damped least-squares
steps with the joint limits as an active set, a trust region per step, a line search (the cost
never rises) and the branch held (a step that would leave the branch is shortened). Started from
the previous period's joints, the result moves continuously with the goal.

The branch of a joint vector is the closed form's candidate index (:mod:`.arm_ik`): bit 2 set
when sin(theta4) < 0, bit 1 when cos(theta5) < 0, bit 0 when cos(theta2) < 0 (the signs of the
three square roots). A quantity within ``BRANCH_EPS`` of zero sits on the boundary between two
branches and matches both. The boundaries are the arm's singular configurations (det J is
proportional to sin^2(theta4) cos(theta5) cos(theta2): elbow straight, wrist yaw or shoulder
roll at +-90 deg), so the search also keeps margins from them: |sin theta4|, |cos theta5| and
|cos theta2| stay at least ``margins[0..2]`` inside the branch. Each depends on one joint
only, so the branch's interior is a box of joint intervals (:func:`branch_box`), which the
search treats like the joint limits; a joint already closer to a boundary is not moved closer.

Also here: the geometric Jacobian of a DH chain, used for the search and for the singularity
measure of :func:`hubo_cli.kinematics.conditioning.condition_number`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, dh_step, end_frame

BRANCH_EPS = 1e-3      # |sin theta4|, |cos theta5|, |cos theta2| below this match either branch
MAX_STEP_RAD = 0.2     # trust region: no joint moves more than this in one iteration
DAMPING = 0.01         # lambda of the damped least squares (in the weighted units, m)


@nb.njit(**JIT)
def branch_of(q):
    """The branch index (0..7) of an arm joint vector (see the module docstring)."""
    k = 0
    if math.sin(q[3]) < 0.0:
        k += 4
    if math.cos(q[4]) < 0.0:
        k += 2
    if math.cos(q[1]) < 0.0:
        k += 1
    return k


@nb.njit(**JIT)
def on_branch(q, branch):
    """True when q is on ``branch`` (a sign within BRANCH_EPS of zero matches both sides)."""
    s4, c5, c2 = math.sin(q[3]), math.cos(q[4]), math.cos(q[1])
    if abs(s4) > BRANCH_EPS and (s4 < 0.0) != ((branch & 4) != 0):
        return False
    if abs(c5) > BRANCH_EPS and (c5 < 0.0) != ((branch & 2) != 0):
        return False
    return not (abs(c2) > BRANCH_EPS and (c2 < 0.0) != ((branch & 1) != 0))


@nb.njit(**JIT)
def branch_box(q, branch, margins, lower, upper, lo_out, hi_out):
    """Joint intervals (lo_out, hi_out) that keep q's branch with ``margins``, within the limits.

    sin(theta4), cos(theta5), cos(theta2) keep their branch signs with magnitudes at least
    margins[0], margins[1], margins[2]: each is an interval of half-width acos(margin) around
    its branch's centre angle (the one nearest the joint's value), widened to include the joint
    if it is already inside the margin.
    """
    for j in range(6):
        lo_out[j] = lower[j]
        hi_out[j] = upper[j]
    if branch < 0:
        return
    for m, j in enumerate((3, 4, 1)):
        half = math.acos(min(max(margins[m], 0.0), 1.0))
        if j == 3:  # sin(theta4) = cos(theta4 - pi/2)
            centre = -0.5 * math.pi if branch & 4 else 0.5 * math.pi
        elif j == 4:
            centre = math.pi if branch & 2 else 0.0
        else:
            centre = math.pi if branch & 1 else 0.0
        centre += 2.0 * math.pi * round((q[j] - centre) / (2.0 * math.pi))
        lo = min(centre - half, q[j])
        hi = max(centre + half, q[j])
        lo_out[j] = max(lo_out[j], lo)
        hi_out[j] = min(hi_out[j], hi)


@nb.njit(**JIT)
def jacobian(q, base, offset, alpha, a, d, end, T_out, J_out):
    """Forward kinematics and the geometric Jacobian of a DH chain's end frame.

    Args:
        q: joints (6,), rad.
        base, offset, alpha, a, d, end: the chain as in :func:`.dh.chain_fk`.
        T_out: receives the end frame (4x4, m) in the base's parent frame.
        J_out: receives the 6x6 Jacobian in that frame: rows 0-2 the end point's linear
            velocity (m/rad), rows 3-5 the angular velocity (rad/rad).
    """
    zs = np.empty((6, 3))
    ps = np.empty((6, 3))
    x0, x1, x2 = base[0, 0], base[1, 0], base[2, 0]
    y0, y1, y2 = base[0, 1], base[1, 1], base[2, 1]
    z0, z1, z2 = base[0, 2], base[1, 2], base[2, 2]
    p0, p1, p2 = base[0, 3], base[1, 3], base[2, 3]
    for i in range(6):  # joint i turns about z of frame i-1, through its origin
        zs[i, 0], zs[i, 1], zs[i, 2] = z0, z1, z2
        ps[i, 0], ps[i, 1], ps[i, 2] = p0, p1, p2
        x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2 = dh_step(
            q[i] + offset[i], alpha[i], a[i], d[i], x0, x1, x2, y0, y1, y2, z0, z1, z2,
            p0, p1, p2)
    end_frame(x0, x1, x2, y0, y1, y2, z0, z1, z2, p0, p1, p2, end, T_out)
    for i in range(6):
        r0 = T_out[0, 3] - ps[i, 0]
        r1 = T_out[1, 3] - ps[i, 1]
        r2 = T_out[2, 3] - ps[i, 2]
        zx, zy, zz = zs[i, 0], zs[i, 1], zs[i, 2]
        J_out[0, i] = zy * r2 - zz * r1
        J_out[1, i] = zz * r0 - zx * r2
        J_out[2, i] = zx * r1 - zy * r0
        J_out[3, i] = zx
        J_out[4, i] = zy
        J_out[5, i] = zz


@nb.njit(**JIT)
def rotation_error(T, T_goal, out):
    """out = log(R_goal R^T) as a rotation vector (rad, in the common frame); returns its angle."""
    E = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            E[i, j] = (T_goal[i, 0] * T[j, 0] + T_goal[i, 1] * T[j, 1]
                       + T_goal[i, 2] * T[j, 2])
    vx = E[2, 1] - E[1, 2]
    vy = E[0, 2] - E[2, 0]
    vz = E[1, 0] - E[0, 1]
    s2 = math.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
    angle = math.atan2(0.5 * s2, 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0))
    if s2 > 1e-9:
        k = angle / s2
        out[0], out[1], out[2] = k * vx, k * vy, k * vz
    elif angle < 1.0:  # no rotation
        out[0], out[1], out[2] = 0.0, 0.0, 0.0
    else:  # a half turn: the axis is the column of E + I with the largest norm
        best = 0
        for c in range(1, 3):
            if E[c, c] > E[best, best]:
                best = c
        n = math.sqrt(max(2.0 * (1.0 + E[best, best]), 1e-300))
        for r in range(3):
            out[r] = angle * (E[r, best] + (1.0 if r == best else 0.0)) / n
    return angle


@nb.njit(**JIT)
def _cost(T, T_goal, w_pos, w_rot, e):
    """Fill the weighted 6-D error e (goal minus actual) and return cost = |e|^2."""
    e[0] = w_pos * (T_goal[0, 3] - T[0, 3])
    e[1] = w_pos * (T_goal[1, 3] - T[1, 3])
    e[2] = w_pos * (T_goal[2, 3] - T[2, 3])
    rotation_error(T, T_goal, e[3:])
    e[3] *= w_rot
    e[4] *= w_rot
    e[5] *= w_rot
    s = 0.0
    for i in range(6):
        s += e[i] * e[i]
    return s


@nb.njit(**JIT)
def _solve_spd6(A, b, x):
    """x = A^-1 b for a symmetric positive definite 6x6 A (Cholesky; A is overwritten)."""
    n = 6
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        A[j, j] = math.sqrt(max(s, 1e-300))
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / A[j, j]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= A[i, k] * x[k]
        x[i] = s / A[i, i]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= A[k, i] * x[k]
        x[i] = s / A[i, i]


@nb.njit(**JIT)
def _dls_step(J, e, free, w_pos, w_rot, dq):
    """dq = (Jw^T Jw + lambda^2 I)^-1 Jw^T e over the free joints (the others stay)."""
    A = np.empty((6, 6))
    g = np.empty(6)
    for i in range(6):
        for j in range(6):
            s = 0.0
            if free[i] and free[j]:
                for r in range(3):
                    s += w_pos * w_pos * J[r, i] * J[r, j]
                for r in range(3, 6):
                    s += w_rot * w_rot * J[r, i] * J[r, j]
            A[i, j] = s
        A[i, i] += DAMPING * DAMPING
        s = 0.0
        if free[i]:
            for r in range(3):
                s += w_pos * J[r, i] * e[r]
            for r in range(3, 6):
                s += w_rot * J[r, i] * e[r]
        g[i] = s
    _solve_spd6(A, g, dq)


@nb.njit(**JIT)
def nearest_on_branch(T_goal, chain, lower, upper, q_start, branch, margins, w_pos, w_rot,
                      iterations, q_out):
    """Move from ``q_start`` toward the pose nearest to ``T_goal`` on ``branch``.

    Args:
        T_goal: the goal end frame (4x4, m) in the chain's base-parent frame (the neck frame).
        chain: the limb's DH chain (see :class:`hubo_cli.kinematics.limb.Limb`).
        lower, upper: joint limits (6,), rad; the result stays within them.
        q_start: where the search starts (the current joints), rad, within the limits.
        branch: the branch to stay on (0..7), or -1 for none.
        margins: how far inside the branch to stay (3,), see :func:`branch_box`.
        w_pos: weight of the position error (1/m).
        w_rot: weight of the orientation error (m/rad per 1/m of w_pos).
        iterations: the most damped least-squares steps to take.
        q_out: receives the joints (6,).

    Returns:
        (position error m, rotation error rad, steps taken).
    """
    base, _, offset, alpha, a, d, end, _ = chain
    T = np.empty((4, 4))
    J = np.empty((6, 6))
    e = np.empty(6)
    e_try = np.empty(6)
    dq = np.empty(6)
    q_try = np.empty(6)
    free = np.empty(6, dtype=np.bool_)
    lo = np.empty(6)
    hi = np.empty(6)
    for j in range(6):
        q_out[j] = min(max(q_start[j], lower[j]), upper[j])
    branch_box(q_out, branch, margins, lower, upper, lo, hi)
    jacobian(q_out, base, offset, alpha, a, d, end, T, J)
    cost = _cost(T, T_goal, w_pos, w_rot, e)
    steps = 0
    for _ in range(iterations):
        for j in range(6):
            free[j] = True
        accepted = False
        for _attempt in range(2):
            for _pass in range(3):  # active set: a joint on a limit and pushed outward is fixed
                _dls_step(J, e, free, w_pos, w_rot, dq)
                changed = False
                for j in range(6):
                    if free[j] and ((q_out[j] <= lo[j] and dq[j] < 0.0)
                                    or (q_out[j] >= hi[j] and dq[j] > 0.0)):
                        free[j] = False
                        changed = True
                if not changed:
                    break
            biggest = 0.0
            for j in range(6):
                if not free[j]:
                    dq[j] = 0.0
                biggest = max(biggest, abs(dq[j]))
            if biggest < 1e-12:
                break
            first = min(1.0, MAX_STEP_RAD / biggest)
            scale = first
            for _halving in range(6):  # line search: lower cost and still on the branch
                for j in range(6):
                    q_try[j] = min(max(q_out[j] + scale * dq[j], lo[j]), hi[j])
                jacobian(q_try, base, offset, alpha, a, d, end, T, J)
                cost_try = _cost(T, T_goal, w_pos, w_rot, e_try)
                if cost_try < cost:
                    accepted = True
                    break
                scale *= 0.5
            if accepted:
                break
            # the step clipped at a bound short of it does not descend (a joint just inside
            # its limit or margin, pushed outward): hold those joints and step with the others
            pinned = False
            for j in range(6):
                if free[j] and (q_out[j] + first * dq[j] > hi[j]
                                or q_out[j] + first * dq[j] < lo[j]):
                    free[j] = False
                    pinned = True
            if not pinned:
                break
            jacobian(q_out, base, offset, alpha, a, d, end, T, J)
        if not accepted:
            break
        improvement = cost - cost_try
        for j in range(6):  # element by element (no compiled shape-mismatch error path)
            q_out[j] = q_try[j]
            e[j] = e_try[j]
        cost = cost_try
        steps += 1
        if improvement < 1e-14:
            break
    jacobian(q_out, base, offset, alpha, a, d, end, T, J)
    dx = T[0, 3] - T_goal[0, 3]
    dy = T[1, 3] - T_goal[1, 3]
    dz = T[2, 3] - T_goal[2, 3]
    rot = rotation_error(T, T_goal, e[3:])
    return math.sqrt(dx * dx + dy * dy + dz * dz), rot, steps
