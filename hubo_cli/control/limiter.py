"""Soft error limiter (hrpsys SoftErrorLimiter, extended): the pipeline's last line of defence.

Per joint and per period it picks the command's velocity v = (q - q_prev) / dt inside bands
applied in this order, a later band winning if two cannot both hold:

1. tracking error: |q - q_measured| <= 0.18 rad (hrpsys; just below the 0.2 rad servo-off limit),
   approached like a position limit (see 4) that moves with the measured joint's velocity, and
   never widened once exceeded;
2. acceleration: |v - v_prev| <= a_max dt;
3. velocity: |v| <= v_max;
4. position: the command may approach a limit only as fast as it can still brake before it
   (:func:`~hubo_cli.motion.limits.brake_speed`), and never moves further out once outside.

While an emergency stopper brakes (a wrist-torque stop, a revert turning the motion around;
flag ``estop-brake``), band 2 takes the
emergency braking acceleration (:meth:`~hubo_cli.motion.limits.JointLimits.for_emergency_brake`).

The limiter also runs :class:`~hubo_cli.control.following.FollowingChecks` every period: a
joint held at the tracking band too long (the band keeps every command within 0.18 rad of the
measured joint, so the driver's servo-error check, 0.2 rad, can never trip against it), a joint
that stands still while its command moves on, or a measured joint that jumps, raise a
:class:`~hubo_cli.errors.DeviceError` (exit 3) from :meth:`SoftErrorLimiter.update` and the
control loop brakes the command to rest.

When a band clamps, the wanted velocity is also capped so that the command can stop on the
wanted position instead of overshooting it, so a jump in the input becomes an acceleration-
limited move that lands without ringing. NaN inputs hold the previous command.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from hubo_cli.control.estop import BRAKE_FLAG
from hubo_cli.control.following import (  # noqa: F401 (NotFollowing: its home was here)
    NOT_FOLLOWING_PROGRESS_RAD,
    NOT_FOLLOWING_S,
    FollowingChecks,
    NotFollowing,
)
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.status import LimiterStatus
from hubo_cli.dataflow import Store
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import JointLimits, brake_speed
from hubo_cli.state import RobotState

TRACKING_ERROR_LIMIT_RAD = 0.18  # hrpsys SoftErrorLimiter default (0.2 servo-off minus 0.02)
# A command that ends within this of the wanted one is not a limit event (rounding): the hip
# yaws and rolls stand at their 0 rad limits and the modules upstream ask up to 7.5e-7 rad
# beyond them (measured over a default cut-rectangle), which flagged "joint-limit" in 80 % of
# its periods. 1e-5 rad is 13x that, and moves a hand at 0.5 m by 5 micrometres.
POSITION_ROUNDING_RAD = 1e-5

# bits of the per-joint clamp mask returned by limit_step
CLAMP_POSITION = 1
CLAMP_RATE = 2
CLAMP_TRACKING = 4


@nb.njit(cache=True, nogil=True)
def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else (hi if x > hi else x)


@nb.njit(cache=True, nogil=True)
def limit_step(q_want, want_prev, q1, q2, lower, upper, vmax, amax, dt, q_meas, v_meas,
               error_limit, out, mask, catching):
    """One limiter period for every joint (numba); returns the bitwise or of ``mask``.

    Args:
        q_want: wanted command (rad); NaN holds q1.
        want_prev: the previous period's wanted command (rad): the difference is the wanted
            command's own velocity (0 where not finite); it keeps the stop-on-target cap from
            slowing an input that moves smoothly.
        q1, q2: the two previous commands (rad).
        lower, upper, vmax, amax: limits (rad, rad/s, rad/s^2).
        dt: the period (s).
        q_meas: measured joints (rad); NaN entries skip the tracking-error band.
        v_meas: measured joint velocities (rad/s); the band moves with the joint.
        error_limit: tracking-error limit (rad); <= 0 disables it.
        out: the limited command (rad), written.
        mask: per-joint CLAMP_* bits, written.
        catching: per-joint "still catching up after a clamp" (bool), read and written.
    """
    any_bits = 0
    for i in range(q_want.shape[0]):
        target = q_want[i]
        if not np.isfinite(target):
            target = q1[i]
        v_prev = (q1[i] - q2[i]) / dt
        v_want = (target - q1[i]) / dt
        a_dt = amax[i] * dt
        acc_lo, acc_hi = v_prev - a_dt, v_prev + a_dt
        pos_lo = -brake_speed(q1[i] - lower[i], amax[i], dt)
        pos_hi = brake_speed(upper[i] - q1[i], amax[i], dt)
        use_err = error_limit > 0.0 and np.isfinite(q_meas[i])
        err_lo, err_hi = -np.inf, np.inf
        if use_err:  # a band around the measured joint, approached like a limit moving with it
            w = v_meas[i] if np.isfinite(v_meas[i]) else 0.0
            err_lo = w - brake_speed(q1[i] - (q_meas[i] - error_limit), amax[i], dt)
            err_hi = w + brake_speed(q_meas[i] + error_limit - q1[i], amax[i], dt)
        lo = max(max(acc_lo, -vmax[i]), max(pos_lo, err_lo))
        hi = min(min(acc_hi, vmax[i]), min(pos_hi, err_hi))
        bits = 0
        v = v_want
        slack = 1e-9 * vmax[i]
        clamped = v_want < lo - slack or v_want > hi + slack
        if clamped or catching[i]:
            # catching up after a clamp: aim to stop on the (moving) target, not run through it.
            # The speed relative to the target (v - w) brakes within the gap to where the
            # target was (its position a period ago, target - w dt): measured to where it is
            # now, the command settled one period's motion ahead of a moving target and
            # never landed (the limiter flagged `slowing` until the target stopped)
            w = (q_want[i] - want_prev[i]) / dt
            if not np.isfinite(w):
                w = 0.0
            gap = target - w * dt - q1[i]
            v = _clip(v_want, w - brake_speed(-gap, amax[i], dt),
                      w + brake_speed(gap, amax[i], dt))
            v0 = v
            if use_err:
                v = _clip(v, err_lo, err_hi)
                if abs(v - v0) > slack:
                    bits |= CLAMP_TRACKING
            v1 = v
            v = _clip(_clip(v, acc_lo, acc_hi), -vmax[i], vmax[i])
            if abs(v - v1) > slack:
                bits |= CLAMP_RATE
            v2 = v
            v = _clip(v, pos_lo, pos_hi)
            # (flags ignore rounding-size clips: a joint resting on its limit, wanted beyond it
            # by less than POSITION_ROUNDING_RAD in all, is not an event)
            resting = abs(v_want - v) * dt <= POSITION_ROUNDING_RAD
            if not resting and (abs(v - v2) > slack or (clamped and (v_want > pos_hi + slack
                                                                     or v_want < pos_lo - slack))):
                bits |= CLAMP_POSITION
            if bits == 0 and v != v_want and not resting:
                bits = CLAMP_RATE
        out[i] = q1[i] + v * dt
        mask[i] = bits
        any_bits |= bits
        catching[i] = (clamped or catching[i]) and abs(out[i] - target) > 1e-12
    return any_bits


def ankle_indices(model: RobotModel) -> np.ndarray:
    """Command indices of the ankle pitch and roll joints of both legs."""
    names = model.joint_names
    return np.array([names.index(model.limb(leg).joints[k]) for leg in ("right-leg", "left-leg")
                     for k in (4, 5)], dtype=np.int64)


class SoftErrorLimiter(Module):
    """The last module: velocity, acceleration, position and tracking-error limits per joint.

    Args:
        model: the robot model (limits).
        dt_s: the control period (s).
        error_limit_rad: tracking-error limit (rad); 0 disables it.
        limits: override the model's limits (tests).

    Flags: ``joint-limit`` (position band clamped), ``slowing`` (velocity or acceleration band),
    ``tracking-error``. Info: ``limiter_clamped_count`` (number of joints clamped) and
    ``limiter_ankle_clamped_count`` (of them, ankle pitch and roll joints); attributes
    ``clamped_periods`` and ``ankle_clamped_periods`` count the periods in which it changed the
    command (of any joint, of an ankle), ``periods`` the periods it ran.
    """

    name = "limiter"
    log_columns = ("limiter_clamped_count", "limiter_ankle_clamped_count")

    def __init__(self, model: RobotModel, dt_s: float,
                 error_limit_rad: float = TRACKING_ERROR_LIMIT_RAD,
                 limits: JointLimits | None = None) -> None:
        self.limits = limits or JointLimits.from_model(model)
        self._brake_accel = self.limits.for_emergency_brake(model).acceleration_rad_s2
        self.dt_s = float(dt_s)
        self.error_limit_rad = float(error_limit_rad)
        n = self.limits.size
        self.q1 = np.zeros(n)
        self.q2 = np.zeros(n)
        self._out = np.zeros(n)
        self._mask = np.zeros(n, dtype=np.int64)
        self._catching = np.zeros(n, dtype=np.bool_)
        self.clamped_periods = 0  # periods in which the limiter changed the command
        self.ankle_clamped_periods = 0  # ... of an ankle joint
        self.periods = 0
        self._ankles = (ankle_indices(model) if n == len(model.joint_names)
                        else np.zeros(0, dtype=np.int64))
        self._joint_names = (tuple(model.joint_names) if n == len(model.joint_names)
                             else tuple(f"joint {i}" for i in range(n)))
        self._nan = np.full(n, np.nan)
        self._zeros = np.zeros(n)
        self._want_prev = np.zeros(n)
        self._bits = 0  # the or of the last step's clamp bits
        self.checks = FollowingChecks(self._joint_names, self.dt_s, self.limits.velocity_rad_s,
                                      self.error_limit_rad)
        # numba compiles the kernel on its first call: make that now, not in the first period
        lim = self.limits
        limit_step(self._zeros, self._zeros, self._zeros, self._zeros, lim.lower_rad,
                   lim.upper_rad, lim.velocity_rad_s, lim.acceleration_rad_s2, self.dt_s,
                   self._zeros, self._zeros, self.error_limit_rad, np.zeros(n),
                   self._mask.copy(), self._catching.copy())

    def status(self) -> LimiterStatus:
        """What a viewer shows of the limiter: the share of periods with an ankle clamped."""
        return LimiterStatus(self.ankle_clamped_periods / self.periods if self.periods
                             else None)

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        q = np.where(np.isfinite(q_rad), q_rad, state.q_rad)
        self.q1 = np.array(q, dtype=float)
        self.q2 = self.q1.copy()
        self._want_prev = self.q1.copy()
        self._catching[:] = False
        self.checks.reset()

    def seed(self, q1_rad: np.ndarray, q2_rad: np.ndarray) -> None:
        """Continue from the last two commands ``q1_rad`` (newest) and ``q2_rad`` (rad)."""
        self.q1 = np.array(q1_rad, dtype=float)
        self.q2 = np.array(q2_rad, dtype=float)
        self._want_prev = self.q1.copy()
        self._catching[:] = False

    def step(self, q_want: np.ndarray, q_meas: np.ndarray | None = None,
             v_meas: np.ndarray | None = None, braking: bool = False) -> np.ndarray:
        """Limit one command (rad) against the previous two, with the measured joints (rad) and
        their velocities (rad/s) for the tracking-error band; ``braking``: an emergency stopper
        brakes (its acceleration limits); returns a new array."""
        lim = self.limits
        meas = self._nan if q_meas is None else np.asarray(q_meas, dtype=float)
        v_meas = self._zeros if v_meas is None else np.asarray(v_meas, dtype=float)
        want = np.asarray(q_want, dtype=float)
        out = np.empty_like(self.q1)
        self._bits = limit_step(want, self._want_prev, self.q1, self.q2, lim.lower_rad,
                                lim.upper_rad, lim.velocity_rad_s,
                                self._brake_accel if braking else lim.acceleration_rad_s2,
                                self.dt_s, meas, v_meas, self.error_limit_rad, out, self._mask,
                                self._catching)
        self._want_prev = want.copy()
        self.q2 = self.q1
        self.q1 = out
        return out

    @property
    def velocity_rad_s(self) -> np.ndarray:
        """Finite-difference velocity of the last command (rad/s)."""
        return (self.q1 - self.q2) / self.dt_s

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        self.checks.measured(state, self.q1, cycle.t_s)  # (the command the state followed)
        out = self.step(q_rad, state.q_rad, state.dq_rad_s, BRAKE_FLAG in cycle.flags)
        mask, bits = self._mask, self._bits
        clamped = int(np.count_nonzero(mask)) if bits else 0
        ankles = 0
        if clamped:
            if bits & CLAMP_POSITION:
                cycle.flags.add("joint-limit")
            if bits & CLAMP_RATE:
                cycle.flags.add("slowing")
            if bits & CLAMP_TRACKING:
                cycle.flags.add("tracking-error")
                self.checks.held(mask & CLAMP_TRACKING != 0, state.q_rad, cycle.t_s)
            ankles = int(np.count_nonzero(mask[self._ankles]))
        self.periods += 1
        if clamped:
            self.clamped_periods += 1
        if ankles:
            self.ankle_clamped_periods += 1
        if not bits & CLAMP_TRACKING:
            self.checks.clear_held()
        cycle.info["limiter_clamped_count"] = float(clamped)
        cycle.info["limiter_ankle_clamped_count"] = float(ankles)
        return out
