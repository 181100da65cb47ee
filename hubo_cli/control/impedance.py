"""The ImpedanceController (hrpsys ``ic``, eq. 3 of the multi-layer paper): each hand yields to
the wrench it feels like a mass-damper-spring hung on its reference pose.

Per hand, on the 6-D offset x = [position (m), small-angle rotation (rad)] of the hand frame
from the pose the incoming command puts it at (the reference pose, the spring's centre)::

    M x'' + D x' + K x = F_N - F_ref_N                                      (eq. 3)

F_N is the wrench the environment applies to the hand, about the hand frame's origin, in the
neck frame's axes N (forces N, moments N m); F_ref_N the wrench the hand should feel (zero
unless :meth:`ImpedanceController.set_reference_wrench` gave one). M (kg, kg m^2), D (N s/m,
N m s/rad) and K (N/m, N m/rad) are 6x6; the defaults are diagonal, from the robot file's
``[impedance]`` table.

Discrete update: the state s = [x, x'] (12) advances over one period by the exact solution of
the linear ODE for an input held over the period (zero-order hold), s <- A_d s + B_d u, with
A_d, B_d taken once from the matrix exponential of [[A, B], [0, 0]] dt (scipy.linalg.expm).
So a step of force is followed exactly at every period and a ramp to within its staircase; no
stability limit on dt as with Euler. With no force (u = 0 and s = 0) s stays exactly 0 and the
command passes through unchanged, bit for bit: the hand tracks its reference exactly.

Force setpoint: with ``reference`` (a store key, :data:`~hubo_cli.control.wrench.HAND_WRENCH_REF`)
F_ref is read from the per-period store every period (a task step's thrust, reverted by the
emergency stopper with the motion); else :meth:`set_reference_wrench` sets it. With a nonzero
reference force and ``force_tracking_m_per_n_s`` > 0 the spring's centre c moves along that
force's direction d at ``force_tracking_m_per_n_s ((F_N - F_ref) . d)`` (m/s): the spring
still yields at once, and the centre creeps until the measured force along d equals the
reference, wherever the surface is (a wall nearer or farther than planned). In free air it
advances at ``|F_ref| force_tracking_m_per_n_s``, toward the surface. The centre is part of the
offset (eq. 3 with K (x - c)), clamped with it, and decays back to zero (time constant
``release_s``) once the reference force is zero. ``axes`` leaves some axes stiff: the input on
the others is dropped (the drill yields along its bit only, and tracks the path across it).
A hand holding no contact tool meets rigid faces: its offset's rate and its centre's step
toward the surface are capped at ``APPROACH_M_S`` (the plan's own speed comes on top).

Force input: the estimate's wrist wrenches (``WRENCHES``: the hand's and the tool's weight
removed, hrpsys RemoveForceOffset; read through
:func:`~hubo_cli.control.wrench.measured_hand_wrench`), the wrench the environment applies to
the hand in the sensor frame S (:func:`~hubo_cli.state.T_frame_sensor`: z along the forearm;
another mounting is one argument, ``T_hand_sensor``). It is moved to the hand origin in hand
axes (f_H = R_HS f_S, m_H = R_HS m_S + p_HS x f_H), then turned into N by the hand's measured
orientation (forward kinematics of the measured joints). Hubo's wrist sensors read the force
along the forearm and the two moments across it only: a hand yields to those; a hand holding a
contact tool (a drill) to the whole force at the tool's point, which those three give
(:func:`contact_wrench`). Read along the forearm alone (45 degrees off the bit), the force
across the bit (the cutting and the depth guide's friction, ~1.9 N at 10 mm/s) read into the
thrust the spring saw and changed with every turn of a cut's direction; force tracking then
took its ~1.25 s time constant to undo the spring's answer.

Offset to joints: the target pose is (p_ref + x_p, Exp(x_r) R_ref) in N, with the reference
pose FK(commanded arm joints); the arm's closed-form IK (paper II-B,
:func:`hubo_cli.kinematics.choice.solve_limb`) solves it on the candidate nearest the commanded
joints. It is exact (the IK's own 1e-6 m / 1e-6 rad check) and cheap (about 2 us compiled).
A Jacobian step was the alternative and is not exact enough: at the offset limits (30 mm with
0.1 rad), over 2000 random arm postures (a one-off comparison, not kept), one damped Newton
step missed the pose by up to 1 mm / 8 mrad even where the arm is well conditioned
(condition number < 10), two steps by 0.7 mm / 2.6 mrad, and more near a straight elbow.
When the offset pose has no exact solution within the joint limits, or its joint offset would
change by more than the joint's speed limit times the period (a branch switch, or the arm
nearing a singular posture such as a straight elbow, where a millimetre asks for ever larger
joint moves), the joint offset decays toward zero (time constant ``release_s``, at most the
joints' speed limit), the offset becomes the one those joints really give (its rate zero),
and the flag ``impedance-unreachable`` is set; the dynamics go on from there the next period
(the hand rests at the edge of what the arm can follow, or rejoins its reference,
continuously). A
joint offset merely held goes stale while the commanded posture moves (issue 36: held through
the swing past a straight elbow it never matched the new posture again). Anti-windup: while
the offset is held (unreachable, or its position at ``max_offset_m``) force tracking does not
move the spring's centre. The limiter downstream keeps every joint within its limits and
rates.

Limits: the position offset's norm is clamped to ``max_offset_m`` and the rotation's to
``max_rotation_rad`` (the velocity pushing outward is dropped, so the state does not wind up);
flag ``impedance-limit``. A non-finite wrench holds the last offset (the state is not
advanced; flag ``impedance-bad-wrench``); a non-finite command entry is replaced by the last
finite one. Release: :meth:`switch_off` blends the offset back to zero on a minimum-jerk
profile over ``release_s`` (flag ``impedance-release``), in joint space (the joint offset
scaled down, always reachable and smooth; the reported x is scaled alike), then the command
passes through unchanged; :meth:`switch_on` resumes the dynamics from where the blend is.
In a run a target switches it through the store (:data:`~hubo_cli.control.keys.IMPEDANCE_ON`,
followed at the start of each period), never by calling these.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import scipy.linalg

from hubo_cli.control.keys import IMPEDANCE_ON
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.wrench import (
    ALONG_MIN,
    MEASURED_FORCE_AXES,
    MEASURED_WRENCH_READS,
    TIP_MIN_M,
    WRENCH_AXES,
    measured_hand_wrench,
    tool_point_S_m,
    wrench_of,
)
from hubo_cli.dataflow import Key, Store
from hubo_cli.errors import ConfigError, quoted
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.geometry import min_jerk
from hubo_cli.kinematics.choice import EXACT, solve_limb
from hubo_cli.kinematics.dh import JIT, chain_fk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.motion.limits import all_finite, hold_nan
from hubo_cli.state import RobotState, T_frame_sensor

HAND_SENSORS = {"right-arm": "right-wrist", "left-arm": "left-wrist"}
# A hand (no contact tool) pressing with a reference force moves toward the surface at most
# this fast on its own (the spring's give to the reference and the force tracking's advance
# together; the plan's own speed comes on top): it meets a rigid face, with no give but the
# arm's (docs/history/manipulation.md, round 22)
APPROACH_M_S = 0.004
CONTACT_TOOLS = ("drill",)  # tools whose force acts at their frame's origin (the bit)
T_HAND_SENSOR = T_frame_sensor("right-wrist")  # the wrist sensors' axes in the hand frame
MODES = ("on", "release", "off")
ZERO3 = np.zeros(3)
MODE_CODE = {name: i for i, name in enumerate(MODES)}
LIMIT_FLAG, BAD_FLAG, UNREACHABLE_FLAG, RELEASE_FLAG = (
    "impedance-limit", "impedance-bad-wrench", "impedance-unreachable", "impedance-release")

# the robot file's [impedance] keys and the diagonal entries they fill
_DIAGONALS = {"M": ("mass_kg", "inertia_kg_m2"),
              "D": ("damping_n_s_m", "rotation_damping_n_m_s_rad"),
              "K": ("stiffness_n_m", "rotation_stiffness_n_m_rad")}


def discretize(M, D, K, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(A_d, B_d) of eq. 3 over one period for an input held over it (zero-order hold).

    The state is s = [x, x'] (12); s(t + dt) = A_d s(t) + B_d u, exact for constant u.
    """
    M, D, K = (np.asarray(m, dtype=float) for m in (M, D, K))
    Minv = np.linalg.inv(M)
    big = np.zeros((18, 18))
    big[:6, 6:12] = np.eye(6)
    big[6:12, :6] = -Minv @ K
    big[6:12, 6:12] = -Minv @ D
    big[6:12, 12:] = Minv
    E = scipy.linalg.expm(big * dt_s)
    return np.ascontiguousarray(E[:12, :12]), np.ascontiguousarray(E[:12, 12:])


def default_gains(model: RobotModel) -> dict[str, np.ndarray]:
    """M, D, K (6x6 diagonal) from the robot file's ``[impedance]`` table."""
    raw = model.raw_impedance
    gains = {}
    for name, (linear, angular) in _DIAGONALS.items():
        try:
            diag = [float(raw[linear])] * 3 + [float(raw[angular])] * 3
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"[impedance] needs numbers {linear} and {angular}",
                              path=str(model.source), hint=f"missing or bad: {exc}") from None
        gains[name] = np.diag(diag)
    return gains


def _check_gains(M, D, K) -> None:
    for name, m in (("M", M), ("D", D), ("K", K)):
        if m.shape != (6, 6) or not np.all(np.isfinite(m)):
            raise ConfigError(f"impedance {name} must be a finite 6x6 matrix",
                              hint=f"got shape {m.shape}")
    if np.linalg.eigvalsh(0.5 * (M + M.T)).min() <= 0:
        raise ConfigError("impedance M must be positive definite",
                          hint="a mass (kg) and inertia (kg m^2) > 0 on every axis")
    for name, m in (("D", D), ("K", K)):
        if np.linalg.eigvalsh(0.5 * (m + m.T)).min() < 0:
            raise ConfigError(f"impedance {name} must not be negative definite on any axis",
                              hint="an unstable spring or damper would push the hand away")


@nb.njit(**JIT)
def advance(s, Ad, Bd, wrench_S, T_H_S, R_N_H, wrench_ref_N, mask, s_next) -> None:
    """s_next = A_d s + B_d u, u = mask (F_N - F_ref_N), with F_N the sensor's wrench moved to
    the hand origin (f_H = R_HS f_S, m_H = R_HS m_S + p_HS x f_H) and turned into N axes, and
    ``mask`` 1 on the axes that yield, 0 on the stiff ones."""
    f_H = np.empty(3)
    m_H = np.empty(3)
    for i in range(3):
        f_H[i] = T_H_S[i, 0] * wrench_S[0] + T_H_S[i, 1] * wrench_S[1] + T_H_S[i, 2] * wrench_S[2]
        m_H[i] = T_H_S[i, 0] * wrench_S[3] + T_H_S[i, 1] * wrench_S[4] + T_H_S[i, 2] * wrench_S[5]
    px, py, pz = T_H_S[0, 3], T_H_S[1, 3], T_H_S[2, 3]
    m_H[0] += py * f_H[2] - pz * f_H[1]
    m_H[1] += pz * f_H[0] - px * f_H[2]
    m_H[2] += px * f_H[1] - py * f_H[0]
    u = np.empty(6)
    for i in range(3):
        u[i] = (R_N_H[i, 0] * f_H[0] + R_N_H[i, 1] * f_H[1] + R_N_H[i, 2] * f_H[2]
                - wrench_ref_N[i]) * mask[i]
        u[3 + i] = (R_N_H[i, 0] * m_H[0] + R_N_H[i, 1] * m_H[1] + R_N_H[i, 2] * m_H[2]
                    - wrench_ref_N[3 + i]) * mask[3 + i]
    for r in range(12):
        acc = 0.0
        for c in range(12):
            acc += Ad[r, c] * s[c]
        for c in range(6):
            acc += Bd[r, c] * u[c]
        s_next[r] = acc


@nb.njit(**JIT)
def clamp_offset(s, max_offset_m, max_rotation_rad) -> bool:
    """Clamp the position and rotation parts of x to their norms, dropping the velocity that
    pushes further out; True if either was clamped."""
    position = _clamp_norm(s, 0, max_offset_m)
    rotation = _clamp_norm(s, 3, max_rotation_rad)
    return position or rotation


@nb.njit(**JIT)
def _clamp_norm(s, k, limit) -> bool:
    """Clamp |s[k:k+3]| to limit and drop the outward part of its rate s[6+k:9+k]."""
    n = math.sqrt(s[k] ** 2 + s[k + 1] ** 2 + s[k + 2] ** 2)
    if not n > limit:
        return False
    scale = limit / n
    outward = 0.0
    for i in range(3):
        s[k + i] *= scale
        if limit > 0.0:
            outward += s[6 + k + i] * s[k + i] / limit
    for i in range(3):
        if limit > 0.0 and outward > 0.0:
            s[6 + k + i] -= outward * s[k + i] / limit
        elif limit == 0.0:
            s[6 + k + i] = 0.0
    return True


@nb.njit(**JIT)
def _rotate_small(x_rot, R, out) -> None:
    """out = Exp(x_rot) R (Rodrigues), x_rot a rotation vector (rad)."""
    angle = math.sqrt(x_rot[0] ** 2 + x_rot[1] ** 2 + x_rot[2] ** 2)
    E = np.eye(3)
    if angle > 0.0:
        kx, ky, kz = x_rot[0] / angle, x_rot[1] / angle, x_rot[2] / angle
        s, c = math.sin(angle), math.cos(angle)
        v = 1.0 - c
        E[0, 0], E[0, 1], E[0, 2] = c + kx * kx * v, kx * ky * v - kz * s, kx * kz * v + ky * s
        E[1, 0], E[1, 1], E[1, 2] = ky * kx * v + kz * s, c + ky * ky * v, ky * kz * v - kx * s
        E[2, 0], E[2, 1], E[2, 2] = kz * kx * v - ky * s, kz * ky * v + kx * s, c + kz * kz * v
    for i in range(3):
        for j in range(3):
            out[i, j] = E[i, 0] * R[0, j] + E[i, 1] * R[1, j] + E[i, 2] * R[2, j]


@nb.njit(**JIT)
def offset_joints(q_cmd, chain, lengths, lower, upper, max_step_rad, x, dq_out) -> bool:
    """dq_out: the joint offset that puts the end frame at FK(q_cmd) moved by x (position m,
    rotation vector rad, both in N), by the arm's closed-form IK on the candidate nearest the
    commanded joints; False (dq_out untouched) when that pose has no exact solution within the
    joint limits or the new offset differs from the one in dq_out by more than max_step_rad
    on some joint (a branch switch, or the arm nearing a singular posture)."""
    base, _, offset, alpha, a, d, end, _ = chain
    T_ref = np.empty((4, 4))
    chain_fk(q_cmd, base, offset, alpha, a, d, end, T_ref)
    T_goal = np.eye(4)
    for i in range(3):
        T_goal[i, 3] = T_ref[i, 3] + x[i]
    _rotate_small(x[3:], T_ref[:3, :3], T_goal[:3, :3])
    q = np.empty(6)
    status, _, _ = solve_limb(T_goal, chain, lengths, True, lower, upper, q_cmd, True, 0.0,
                              False, q)
    if status != EXACT:
        return False
    for k in range(6):
        if not (abs(q[k] - q_cmd[k] - dq_out[k]) <= max_step_rad[k]):  # also catches NaN
            return False
    for k in range(6):
        dq_out[k] = q[k] - q_cmd[k]
    return True


@nb.njit(**JIT)
def retreat_offset(q_cmd, chain, max_step_rad, fraction, dq, x_out) -> None:
    """One period of an unreachable offset: shrink the joint offset ``dq`` toward zero (the
    reference pose, which the commanded joints reach) by ``fraction`` of itself, at most
    ``max_step_rad`` per joint; x_out is the offset (position m, rotation vector rad, N) the
    new ``dq`` gives.

    A joint offset held as it was goes stale as the commanded posture moves (the same joints
    give another offset, and the offset's own joints change by more than a period's step ever
    after): letting it decay keeps the output continuous, and the dynamics take over again
    from the offset it really gives."""
    base, _, offset, alpha, a, d, end, _ = chain
    T_ref = np.empty((4, 4))
    chain_fk(q_cmd, base, offset, alpha, a, d, end, T_ref)
    for k in range(6):
        dq[k] -= min(max(fraction * dq[k], -max_step_rad[k]), max_step_rad[k])
    q_out = np.empty(6)
    for k in range(6):
        q_out[k] = q_cmd[k] + dq[k]
    T_out = np.empty((4, 4))
    chain_fk(q_out, base, offset, alpha, a, d, end, T_out)
    for i in range(3):
        x_out[i] = T_out[i, 3] - T_ref[i, 3]
    # the rotation vector of R_out R_ref^T (atan2 form, accurate near zero)
    E = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            E[i, j] = (T_out[i, 0] * T_ref[j, 0] + T_out[i, 1] * T_ref[j, 1]
                       + T_out[i, 2] * T_ref[j, 2])
    vx, vy, vz = E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]
    norm = math.sqrt(vx * vx + vy * vy + vz * vz)
    angle = math.atan2(0.5 * norm, 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0))
    scale = angle / norm if norm > 1e-300 else 0.5
    x_out[3], x_out[4], x_out[5] = vx * scale, vy * scale, vz * scale


@nb.njit(**JIT)
def _move_centre(centre, step_m, wrench_ref_N, size, mask, max_offset_m) -> None:
    """centre += step_m d (d = F_ref / size, masked axes), its norm clamped to max_offset_m."""
    for i in range(3):
        centre[i] += step_m * wrench_ref_N[i] / size * mask[i]
    n = math.sqrt(centre[0] ** 2 + centre[1] ** 2 + centre[2] ** 2)
    if n > max_offset_m:
        for i in range(3):
            centre[i] *= max_offset_m / n


@nb.njit(**JIT)
def contact_wrench(wrench_S, contact_S, measured, out) -> None:
    """out: the reading with its force replaced by the whole force at the tool's point
    ``contact_S`` (sensor frame, m), as :func:`~hubo_cli.control.wrench.force_at_point` finds
    it from f_z and the moments (m = r x f; a full sensor's force as it is); the moments about
    the sensor stay the measured ones."""
    for i in range(6):
        out[i] = wrench_S[i]
    if not (measured[0] != 0.0 and measured[1] != 0.0):  # r_z checked when the point was set
        rx, ry, rz = contact_S[0], contact_S[1], contact_S[2]
        out[0] = (wrench_S[4] + rx * wrench_S[2]) / rz
        out[1] = (ry * wrench_S[2] - wrench_S[3]) / rz


@nb.njit(**JIT)
def track_force(centre, wrench_ref_N, wrench_S, T_H_S, T_N_H, measured, mask, K, gain_m_per_n,
                decay, max_offset_m, has_contact, wrench_ref_eff_N) -> None:
    """One period of force tracking: with a nonzero reference force F_ref (N axes) the centre
    c moves by ``gain_m_per_n (F_d - |F_ref|) d`` (d = F_ref / |F_ref|, masked axes only,
    |c| clamped to ``max_offset_m``), F_d the force along d from the sensor's ``measured``
    force axes a_i (1 measured, 0 not) assuming it lies along d, sum f_i (a_i . d) /
    sum (a_i . d)^2 (held where that sum is under ``ALONG_MIN``), or with ``has_contact``
    the whole force of ``wrench_S`` (a :func:`contact_wrench`: the force at the tool's point);
    without a reference it shrinks by the factor ``1 - decay``. Then
    wrench_ref_eff_N = F_ref - K [c, 0]."""
    size = math.sqrt(wrench_ref_N[0] ** 2 + wrench_ref_N[1] ** 2 + wrench_ref_N[2] ** 2)
    if size > 0.0 and gain_m_per_n > 0.0 and has_contact:
        f = wrench_S
        along = -size
        for r in range(3):
            f_H = T_H_S[r, 0] * f[0] + T_H_S[r, 1] * f[1] + T_H_S[r, 2] * f[2]
            for c in range(3):
                along += T_N_H[c, r] * f_H * wrench_ref_N[c] / size
        _move_centre(centre, gain_m_per_n * along, wrench_ref_N, size, mask, max_offset_m)
    elif size > 0.0 and gain_m_per_n > 0.0:
        num = den = 0.0
        for i in range(3):  # the sensor's force axis i in N, against d
            if measured[i] == 0.0:
                continue
            c = 0.0
            for r in range(3):
                a_r = (T_N_H[r, 0] * T_H_S[0, i] + T_N_H[r, 1] * T_H_S[1, i]
                       + T_N_H[r, 2] * T_H_S[2, i])
                c += a_r * wrench_ref_N[r] / size
            num += wrench_S[i] * c
            den += c * c
        if den < ALONG_MIN:
            along = 0.0  # the sensor cannot see a force along d: hold the centre
        else:
            along = num / den - size  # F_d - |F_ref|
        _move_centre(centre, gain_m_per_n * along, wrench_ref_N, size, mask, max_offset_m)
    else:
        keep = max(0.0, 1.0 - decay)
        n = 0.0
        for i in range(3):
            centre[i] *= keep
            n += centre[i] ** 2
        if math.sqrt(n) < 1e-9:
            for i in range(3):
                centre[i] = 0.0
    for r in range(6):
        wrench_ref_eff_N[r] = wrench_ref_N[r] - (K[r, 0] * centre[0] + K[r, 1] * centre[1]
                                                 + K[r, 2] * centre[2])


@nb.njit(**JIT)
def cap_toward(v, v_last, wrench_ref_N, mask, most) -> None:
    """Cap the change of ``v`` (3, N axes) since ``v_last`` toward the surface, along
    n = -F_ref / |F_ref| (masked axes), at ``most``: the part beyond it is taken off along n
    (with ``v_last`` zero, ``v`` itself: a rate)."""
    size = math.sqrt(wrench_ref_N[0] ** 2 + wrench_ref_N[1] ** 2 + wrench_ref_N[2] ** 2)
    if not size > 0.0:
        return
    toward = 0.0
    for i in range(3):
        toward -= (v[i] - v_last[i]) * wrench_ref_N[i] / size * mask[i]
    if toward > most:
        for i in range(3):
            v[i] += (toward - most) * wrench_ref_N[i] / size * mask[i]


class _Hand:
    """One hand's state: the limb, its joints' slice, sensor, s = [x, x'], the reference
    wrench and the joint offset last applied."""

    def __init__(self, model: RobotModel, arm: str, dt_s: float) -> None:
        self.arm = arm
        self.limb = Limb(model, arm, "hand")
        self.slice = model.limb_slice(arm)
        self.sensor = HAND_SENSORS[arm]
        self.fk_chain = self.limb.fk_chain  # as chain_fk takes it
        # as offset_joints takes it; the offset's joints move at most at the joints' speed limit
        self.ik = (self.limb.chain, self.limb.lengths_m, self.limb.lower_rad,
                   self.limb.upper_rad, self.limb.spec.velocity_rad_s * dt_s)
        self.s = np.zeros(12)
        self.s_next = np.zeros(12)
        self.wrench_ref_N = np.zeros(6)
        self.wrench_ref_eff_N = np.zeros(6)  # F_ref - K [c, 0]: the spring centred on c
        self.centre_m = np.zeros(3)  # the force tracking's spring centre c (N axes, m)
        self.contact_S_m = np.zeros(3)  # the tool's point in the sensor frame (m) ...
        self.has_contact = False  # ... if eq. 3 and force tracking read the force there
        self.wrench_contact = np.zeros(6)  # this period's reading with the force at that point
        self.dq_rad = np.zeros(6)
        self.centre_last_m = np.zeros(3)  # the spring's centre last period
        self.held = False  # last period's offset was held (unreachable or at its limit)
        self.T_N_H = np.empty((4, 4))
        self.release_from = np.zeros(6)
        self.dq_release_rad = np.zeros(6)
        side = arm.split("-")[0]
        self.offset_column = f"impedance_{side}_offset_m"
        self.rotation_column = f"impedance_{side}_rotation_rad"
        self.force_ref_columns = tuple(f"impedance_{side}_force_ref_{a}_n" for a in "xyz")
        self.centre_column = f"impedance_{side}_centre_m"


class ImpedanceController(Module):
    """Eq. 3 on each hand (see the module docstring).

    Args:
        model: the robot model (arms, the ``[impedance]`` defaults).
        dt_s: the control period (s).
        M, D, K: 6x6 inertia (kg, kg m^2), damping (N s/m, N m s/rad) and stiffness (N/m,
            N m/rad) on [x, y, z, rx, ry, rz] in the neck frame's axes; None: the robot file's.
        max_offset_m, max_rotation_rad: the largest offset the module adds (m, rad).
        release_s: how long :meth:`switch_off` takes to blend the offset back to zero (s).
        arms: the hands it acts on (default both).
        T_hand_sensor: the wrist sensor's frame in the hand frame (4x4, m).
        active: start switched on (True) or off.
        reference: the store key of the reference wrenches (arm -> 6-vector; read every
            period), or None: :meth:`set_reference_wrench` sets them.
        axes: the axes that yield (of ``x y z rx ry rz``, neck-frame axes); the input on the
            others is dropped. Default all.
        force_tracking_m_per_n_s: how fast the spring's centre moves per newton of force error
            along a nonzero reference force (m/s per N; 0: never); None: the robot file's.
        tools: arm -> the tool it holds; for a drill eq. 3 and force tracking read the whole
            force at the bit (f_z and the two moments, :func:`contact_wrench`) instead of the
            force along the forearm alone, and force tracking no longer assumes it lies along
            the reference.

    Flags: ``impedance-limit`` (an offset clamped), ``impedance-bad-wrench`` (a non-finite
    reading: offset held), ``impedance-unreachable`` (joint offset held), ``impedance-release``.
    Info: ``impedance_mode_code`` (0 on, 1 release, 2 off) and per hand
    ``impedance_<side>_offset_m`` and ``impedance_<side>_rotation_rad`` (norms of x),
    ``impedance_<side>_force_ref_{x,y,z}_n`` (the reference force used, N axes) and
    ``impedance_<side>_centre_m`` (how far force tracking moved the spring's centre).
    """

    name = "impedance"
    reads = (WRENCHES,)
    follows = (IMPEDANCE_ON,)

    def __init__(self, model: RobotModel, dt_s: float, M=None, D=None, K=None,
                 max_offset_m: float | None = None, max_rotation_rad: float | None = None,
                 release_s: float | None = None, arms: tuple[str, ...] = ARMS,
                 T_hand_sensor: np.ndarray = T_HAND_SENSOR, active: bool = True,
                 reference: Key | None = None, axes: tuple[str, ...] = WRENCH_AXES,
                 force_tracking_m_per_n_s: float | None = None,
                 tools: dict[str, str] | None = None) -> None:
        raw = model.raw_impedance
        defaults = default_gains(model) if M is None or D is None or K is None else {}
        self.M, self.D, self.K = (
            np.array(defaults[n] if given is None else given, dtype=float)
            for n, given in (("M", M), ("D", D), ("K", K)))
        _check_gains(self.M, self.D, self.K)
        self.max_offset_m = (model.impedance_max_offset_m if max_offset_m is None
                             else float(max_offset_m))
        try:
            self.max_rotation_rad = float(raw["max_rotation_rad"] if max_rotation_rad is None
                                          else max_rotation_rad)
            self.release_s = float(raw["release_s"] if release_s is None else release_s)
            self.force_tracking_m_per_n_s = float(
                raw["force_tracking_m_per_n_s"] if force_tracking_m_per_n_s is None
                else force_tracking_m_per_n_s)
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError("[impedance] needs numbers max_rotation_rad, release_s and "
                              "force_tracking_m_per_n_s", path=str(model.source),
                              hint=str(exc)) from None
        if not (self.max_offset_m >= 0 and self.max_rotation_rad >= 0 and self.release_s >= 0
                and self.force_tracking_m_per_n_s >= 0
                and math.isfinite(self.max_offset_m + self.max_rotation_rad + self.release_s
                                  + self.force_tracking_m_per_n_s)):
            raise ConfigError("impedance limits, release time and force tracking rate must be "
                              "finite and >= 0")
        unknown_axes = [a for a in axes if a not in WRENCH_AXES]
        if unknown_axes:
            raise ConfigError(f"impedance on unknown axis {quoted(unknown_axes[0])}",
                              hint=f"use some of {' '.join(WRENCH_AXES)}")
        self.axes_mask = np.array([a in axes for a in WRENCH_AXES], dtype=float)
        self.measured_force = np.array([i in MEASURED_FORCE_AXES for i in range(3)], dtype=float)
        self.reference = reference
        self.reads = MEASURED_WRENCH_READS + (() if reference is None else (reference,))
        unknown = [a for a in arms if a not in HAND_SENSORS]
        if unknown:
            raise ConfigError(f"impedance on unknown arm {quoted(unknown[0])}",
                              hint=f"use {', '.join(HAND_SENSORS)}")
        self.dt_s = float(dt_s)
        self.Ad, self.Bd = discretize(self.M, self.D, self.K, self.dt_s)
        self._retreat = self.dt_s / max(self.release_s, self.dt_s)  # time constant release_s
        self.T_hand_sensor = np.ascontiguousarray(T_hand_sensor, dtype=float)
        self.hands = [_Hand(model, arm, self.dt_s) for arm in arms]
        for h in self.hands:
            tool = (tools or {}).get(h.arm)
            if tool in CONTACT_TOOLS:
                h.contact_S_m[:] = tool_point_S_m(model, tool, self.T_hand_sensor)
                h.has_contact = abs(h.contact_S_m[2]) >= TIP_MIN_M
        self._initially_active = active
        self.log_columns = ("impedance_mode_code",) + tuple(
            c for h in self.hands for c in (h.offset_column, h.rotation_column,
                                             *h.force_ref_columns, h.centre_column))
        self._last_in = np.zeros(len(model.joint_names))
        self._clear()
        self._warm_up()

    # ------------------------------------------------------------------ commands
    def switch_off(self) -> None:
        """Blend every hand's offset back to zero over ``release_s``, then pass through."""
        if self.mode == "on":
            self.mode = "release"
            self._release_k = 0
            for h in self.hands:
                h.release_from = h.s[:6].copy()
                h.dq_release_rad = h.dq_rad.copy()
                h.centre_m[:] = 0.0

    def switch_on(self) -> None:
        """Resume eq. 3 from the current offset (and its rate while blending back)."""
        self.mode = "on"

    def set_reference_wrench(self, arm: str, wrench_ref_N) -> None:
        """The wrench (N, N m; about the hand origin, neck-frame axes) the hand ``arm`` should
        feel from its environment at the spring's centre: the hand settles where the measured
        wrench equals it. Non-finite values are refused."""
        w = np.asarray(wrench_ref_N, dtype=float).reshape(6)
        if not np.all(np.isfinite(w)):
            raise ConfigError(f"reference wrench for {arm} is not finite", hint=str(w))
        for h in self.hands:
            if h.arm == arm:
                h.wrench_ref_N[:] = w
                h.wrench_ref_eff_N[:] = w
                return
        raise ConfigError(f"no impedance on {quoted(arm)}",
                          hint=f"it acts on {', '.join(h.arm for h in self.hands)}")

    def offset(self, arm: str) -> np.ndarray:
        """The hand's current offset x (position m, rotation vector rad; neck-frame axes)."""
        return next(h.s[:6].copy() for h in self.hands if h.arm == arm)

    # ------------------------------------------------------------------ module
    def _clear(self) -> None:
        self.mode = "on" if self._initially_active else "off"
        self._release_k = 0
        for h in self.hands:
            h.s[:] = 0.0
            h.dq_rad[:] = 0.0
            h.held = False
            h.centre_m[:] = 0.0
            h.wrench_ref_eff_N[:] = h.wrench_ref_N

    def _warm_up(self) -> None:
        """Compile the kernels now, not in a control period."""
        h = self.hands[0]
        scratch = h.s.copy()
        chain_fk(np.zeros(6), *h.fk_chain, h.T_N_H)
        advance(scratch, self.Ad, self.Bd, np.zeros(6), self.T_hand_sensor, h.T_N_H[:3, :3],
                h.wrench_ref_N, self.axes_mask, h.s_next)
        clamp_offset(scratch, 1.0, 1.0)
        for has_contact in (False, True):
            track_force(np.zeros(3), np.ones(6), np.zeros(6), self.T_hand_sensor, h.T_N_H,
                        self.measured_force, self.axes_mask, self.K, 1e-9, 0.0, 1.0,
                        has_contact, h.wrench_ref_eff_N.copy())
        contact_wrench(np.zeros(6), np.ones(3), self.measured_force, np.zeros(6))
        cap_toward(np.zeros(3), ZERO3, np.ones(6), self.axes_mask, 1.0)
        offset_joints(np.zeros(6), *h.ik, np.zeros(6), np.zeros(6))
        retreat_offset(np.zeros(6), h.limb.chain, h.ik[-1], 0.5, np.zeros(6), np.zeros(6))
        all_finite(scratch)
        hold_nan(self._last_in, self._last_in, self._last_in.copy())

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        """Start with zero offsets (switched on if built ``active``)."""
        self._last_in = np.where(np.isfinite(q_rad), q_rad, state.q_rad).astype(float)
        self._clear()

    def _release_step(self) -> None:
        """One period of the blend back: x = x_off (1 - min_jerk(k / n))."""
        n = max(1, math.ceil(self.release_s / self.dt_s - 1e-9))
        self._release_k += 1
        u = self._release_k / n
        w = 1.0 - float(min_jerk(u))
        rate = -30.0 * u * u * (1.0 - u) ** 2 / (n * self.dt_s) if u < 1.0 else 0.0
        for h in self.hands:
            h.s[:6] = h.release_from * w
            h.s[6:] = h.release_from * rate
            h.dq_rad[:] = h.dq_release_rad * w
        if self._release_k >= n:
            self.mode = "off"
            for h in self.hands:
                h.s[:] = 0.0
                h.dq_rad[:] = 0.0

    def _track_force(self, h: _Hand, wrench_S: np.ndarray) -> None:
        """Move the spring's centre c along the reference force (see the module docstring) and
        set the input's reference to F_ref - K [c, 0]. Called with a finite reading after
        ``h.T_N_H`` holds the measured hand pose."""
        # anti-windup: while the offset is held (unreachable, or at its limit) the centre
        # stays where it is; without a reference force it still decays
        frozen = h.held and bool(h.wrench_ref_N[:3].any())
        track_force(h.centre_m, h.wrench_ref_N, wrench_S, self.T_hand_sensor, h.T_N_H,
                    self.measured_force, self.axes_mask, self.K,
                    0.0 if frozen else self.force_tracking_m_per_n_s * self.dt_s,
                    0.0 if frozen else self.dt_s / max(self.release_s, self.dt_s),
                    self.max_offset_m, h.has_contact, h.wrench_ref_eff_N)

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        q_in = np.empty(self._last_in.shape[0])
        hold_nan(np.ascontiguousarray(q_rad, dtype=float), self._last_in, q_in)
        self._last_in = q_in
        on = cycle.store.get(IMPEDANCE_ON)  # a target's phase switches it on or off
        if on is not None and bool(on) != (self.mode == "on"):
            if on:
                self.switch_on()
            else:
                self.switch_off()
        if self.mode == "release":
            cycle.flags.add(RELEASE_FLAG)
            self._release_step()
        out = q_in
        references = None if self.reference is None else cycle.store.get(self.reference)
        for h in self.hands:
            stepped = False  # eq. 3 advanced this period (not on a bad reading)
            if self.reference is not None:
                w = wrench_of(references, h.arm)
                h.wrench_ref_N[:] = 0.0 if w is None else w
            if self.mode == "on":
                wrench_S = measured_hand_wrench(state, cycle.store, h.sensor)
                if wrench_S is None:
                    wrench_S = np.zeros(6)
                if not all_finite(wrench_S):
                    cycle.flags.add(BAD_FLAG)  # hold the offset: s is not advanced
                else:
                    q_hand = state.q_rad[h.slice]  # the measured joints turn the reading
                    if not all_finite(q_hand):
                        q_hand = q_in[h.slice]
                    chain_fk(q_hand, *h.fk_chain, h.T_N_H)
                    if h.has_contact:  # the tool's whole force, at its point
                        contact_wrench(wrench_S, h.contact_S_m, self.measured_force,
                                       h.wrench_contact)
                        wrench_S = h.wrench_contact
                    h.centre_last_m[:] = h.centre_m
                    self._track_force(h, wrench_S)
                    capped = not h.has_contact and bool(h.wrench_ref_N[:3].any())
                    if capped:  # a hand pressing: toward the face at most APPROACH_M_S itself
                        cap_toward(h.centre_m, h.centre_last_m, h.wrench_ref_N, self.axes_mask,
                                   APPROACH_M_S * self.dt_s)
                        h.wrench_ref_eff_N[:] = h.wrench_ref_N - self.K[:, :3] @ h.centre_m
                    advance(h.s, self.Ad, self.Bd, wrench_S, self.T_hand_sensor,
                            h.T_N_H[:3, :3], h.wrench_ref_eff_N, self.axes_mask, h.s_next)
                    stepped = all_finite(h.s_next)
                    if stepped:  # else (overflow) the offset is held
                        h.s, h.s_next = h.s_next, h.s
                        if capped:
                            cap_toward(h.s[6:9], ZERO3, h.wrench_ref_N, self.axes_mask,
                                       APPROACH_M_S)
                    else:
                        cycle.flags.add(BAD_FLAG)
                    if clamp_offset(h.s, self.max_offset_m, self.max_rotation_rad):
                        cycle.flags.add(LIMIT_FLAG)
            x = h.s[:6]
            cycle.info[h.offset_column] = float(np.linalg.norm(x[:3]))
            cycle.info[h.rotation_column] = float(np.linalg.norm(x[3:]))
            for column, value in zip(h.force_ref_columns, h.wrench_ref_N[:3], strict=True):
                cycle.info[column] = float(value)
            cycle.info[h.centre_column] = float(np.linalg.norm(h.centre_m))
            if not x.any():
                h.dq_rad[:] = 0.0
                h.held = False
                continue  # exact tracking: this arm's command passes through unchanged
            if stepped:
                q_arm = np.ascontiguousarray(q_in[h.slice])
                h.held = not offset_joints(q_arm, *h.ik, x, h.dq_rad)
                if h.held:  # the joint offset decays toward zero
                    cycle.flags.add(UNREACHABLE_FLAG)
                    retreat_offset(q_arm, h.limb.chain, h.ik[-1], self._retreat, h.dq_rad, h.s)
                    h.s[6:] = 0.0
                h.held = h.held or np.linalg.norm(h.s[:3]) >= self.max_offset_m * (1 - 1e-9)
            if out is q_in:
                out = q_in.copy()
            out[h.slice] += h.dq_rad
        cycle.info["impedance_mode_code"] = float(MODE_CODE[self.mode])
        return out

