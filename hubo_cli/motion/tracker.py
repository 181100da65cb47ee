"""A jerk-limited follower of joint targets (ruckig underneath) that never raises.

:class:`JointTracker` wraps one ruckig instance for a whole joint vector: ``track`` follows a
position target (position interface, phase synchronisation, jerk-limited), ``brake`` stops with
the velocity interface. A ruckig error switches to braking, and a failure while braking holds
the position. The pipeline's trajectory generator (:mod:`hubo_cli.control.otg`), the emergency
stopper, the collision detector and the loop's smooth stop use it, and so does the hardware
driver's stale-state brake: it sits below both the pipeline and the drivers.

A tracker resting on its target (its last sample at rest, where ruckig returned its input
unchanged) asked for the same target again returns that sample without asking ruckig: ruckig
would return it again (a standing robot's every period).

Phase synchronisation stretches every joint's profile to the slowest joint's duration. For a
joint that has (almost) nothing to do, ruckig may meet that duration with a swing away and
back: a knee 5e-12 rad from its target with 1e-10 rad/s left over, stretched to an arm's 35 ms,
swung 3.9 mrad out (jerk 15000 rad/s^3 allows it), in the period a task's arm began to move. A
joint of a new synchronised plan that leaves the stretch between its position and its target
by more than its stopping distance (:func:`stopping_distance_bound_rad`) and
SWING_TOLERANCE_RAD is taken out of the synchronisation for that target, on its own
time-optimal plan (:meth:`JointTracker._unswung`).
"""

from __future__ import annotations

import math
from itertools import chain

import numba as nb
import numpy as np
from ruckig import (
    ControlInterface,
    InputParameter,
    OutputParameter,
    Result,
    Ruckig,
    RuckigError,
    Synchronization,
    Trajectory,
)

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.motion.limits import TARGET_SPEED_SHARE, JointLimits, all_finite

SYNCHRONIZATIONS = {"phase": Synchronization.Phase, "none": Synchronization.No}
SWING_TOLERANCE_RAD = 1e-5  # a synchronised joint may leave its way by this beyond its stop


class JointTracker:
    """A jerk-limited follower of joint targets that never raises (ruckig underneath).

    Args:
        limits: joint limits (velocity, acceleration and jerk are used).
        dt_s: the control period (s).
        synchronization: how ``track`` times the joints: ``phase`` (all arrive together on
            a straight line in joint space) or ``none`` (each joint time-optimal on its own).

    Attributes:
        q, v, a: the state of the generated trajectory at the last sample (rad, rad/s, rad/s^2).
        finished: the last call reached its target (or standstill when braking).
        error: the last ruckig error message, or "".
    """

    def __init__(self, limits: JointLimits, dt_s: float, synchronization: str = "phase") -> None:
        if synchronization not in SYNCHRONIZATIONS:
            raise ConfigError(f"unknown synchronization {quoted(synchronization)}",
                              hint=f"use one of {', '.join(SYNCHRONIZATIONS)}")
        n = limits.size
        self._sync = SYNCHRONIZATIONS[synchronization]
        self.limits = limits
        self.dt_s = float(dt_s)
        self._otg = Ruckig(n, self.dt_s)
        self._inp = InputParameter(n)
        self._out = OutputParameter(n)
        self._inp.max_velocity = limits.velocity_rad_s
        self._inp.max_acceleration = limits.acceleration_rad_s2
        self._inp.max_jerk = limits.jerk_rad_s3
        self._zeros = np.zeros(n)
        self._v_max = TARGET_SPEED_SHARE * limits.velocity_rad_s  # a target velocity's bounds
        self._v_min = -self._v_max
        self._v_clipped = np.empty(n)  # preview's target velocity
        _clipped_velocity(self._zeros, self._v_min, self._v_max, self._v_clipped)  # compiled
        # (or loaded) now, not in a period
        self._swung = np.empty(n, dtype=np.bool_)
        _swung(self._zeros, self._zeros, self._zeros, self._zeros, self._zeros, self._zeros,
               np.ones(n), np.ones(n), 0.0, self._swung)  # the same
        self._a_max = limits.acceleration_rad_s2  # an acceleration reset() takes is clipped
        self._a_min = -self._a_max
        self.q = np.zeros(n)
        self.v = np.zeros(n)
        self.a = np.zeros(n)
        self.finished = True
        self.error = ""
        self._mode = None
        self._synced = False  # ruckig's input holds q, v, a (no need to set them again)
        self._target_v_zero = False
        self._preview = None  # ruckig, its input and a trajectory for preview()
        self._preview_sync = None  # the synchronization set in the preview's input
        # (target, minimum duration) of the last ``track`` when it left ruckig's input as it
        # found it, at rest at a sample that stays put (see :meth:`_resting`); None otherwise
        self._rest: tuple[list[float], float | None, np.ndarray] | None = None
        self._per_dof = False  # ruckig's input takes some joints out of the synchronisation

    def reset(self, q_rad, v_rad_s=None, a_rad_s2=None) -> None:
        """Start from position ``q_rad`` with the given velocity and acceleration (default 0).

        An acceleration beyond the limit (a command an emergency stop braked at its own
        limits) is taken as the limit: under the jerk limit ruckig would keep accelerating
        while it ramps it down (from 6 rad/s^2 at 4 rad/s^3: 1.5 s, reaching 4 rad/s)."""
        self.q = np.array(q_rad, dtype=float)
        self.v = self._zeros.copy() if v_rad_s is None else np.array(v_rad_s, dtype=float)
        self.a = (self._zeros.copy() if a_rad_s2 is None  # np.clip's values, cheaper:
                  else np.minimum(np.maximum(np.asarray(a_rad_s2, dtype=float), self._a_min),
                                  self._a_max))
        self.finished = True
        self.error = ""
        self._mode = None
        self._synced = False
        self._rest = None

    def set_synchronization(self, synchronization: str) -> None:
        """Time the joints of later ``track`` calls this way (``phase`` or ``none``)."""
        if synchronization not in SYNCHRONIZATIONS:
            raise ConfigError(f"unknown synchronization {quoted(synchronization)}",
                              hint=f"use one of {', '.join(SYNCHRONIZATIONS)}")
        self._sync = SYNCHRONIZATIONS[synchronization]
        self._rest = None
        if self._mode == "position":
            self._inp.synchronization = self._sync
            self._synchronize_all()

    def _synchronize_all(self) -> None:
        if self._per_dof:
            self._inp.per_dof_synchronization = None
            self._per_dof = False

    def preview(self, target_rad: np.ndarray, synchronization: str, samples: int,
                target_v_rad_s: np.ndarray | None = None) -> np.ndarray:
        """The positions ``track`` would pass through on its way to ``target_rad`` (a fixed
        target, arriving with ``target_v_rad_s``, default 0, clipped as ``track`` clips it)
        from the current state with this synchronization, at ``samples`` evenly spaced times
        from now to arrival (samples x n, rad). Nothing of the tracker changes. On a ruckig
        error: the current position alone (1 x n)."""
        if synchronization not in SYNCHRONIZATIONS:
            raise ConfigError(f"unknown synchronization {quoted(synchronization)}",
                              hint=f"use one of {', '.join(SYNCHRONIZATIONS)}")
        if self._preview is None:
            n = self.limits.size
            self._preview = (Ruckig(n), InputParameter(n), Trajectory(n))
            _, inp, _ = self._preview
            inp.max_velocity = self.limits.velocity_rad_s
            inp.max_acceleration = self.limits.acceleration_rad_s2
            inp.max_jerk = self.limits.jerk_rad_s3
        otg, inp, trajectory = self._preview
        q = self.q.tolist()
        inp.current_position = q  # lists: faster than arrays into ruckig
        inp.current_velocity = self.v.tolist()
        inp.current_acceleration = self.a.tolist()
        inp.target_position = np.asarray(target_rad, dtype=float).tolist()
        v = self._zeros if target_v_rad_s is None else np.asarray(target_v_rad_s, dtype=float)
        if v.shape == self._zeros.shape:  # _target_velocity's numbers, compiled
            _clipped_velocity(v, self._v_min, self._v_max, self._v_clipped)
            inp.target_velocity = self._v_clipped.tolist()
        else:  # one velocity for every joint: numpy broadcasts it
            inp.target_velocity = self._target_velocity(v).tolist()
        if synchronization != self._preview_sync:
            inp.synchronization = SYNCHRONIZATIONS[synchronization]
            self._preview_sync = synchronization
        try:
            result = otg.calculate(inp, trajectory)
        except (RuckigError, RuntimeError, ValueError, TypeError):
            return self.q[None, :].copy()
        if result not in (Result.Working, Result.Finished):
            return self.q[None, :].copy()
        k = max(int(samples), 2)
        duration = trajectory.duration
        at_time = trajectory.at_time
        # the first sample is the current position (ruckig's at_time(0): its profiles' start)
        rows = [q] + [at_time(duration * i / (k - 1))[0] for i in range(1, k)]
        return np.fromiter(chain.from_iterable(rows), float, k * len(q)).reshape(k, len(q))

    def _resting(self) -> bool:
        """The last sample is at rest, its velocity and acceleration exactly zero."""
        return not (self.v.any() or self.a.any())

    def _set_current(self) -> None:
        if self._synced:  # the last sample, passed on inside ruckig (the same numbers)
            return
        inp = self._inp
        inp.current_position = self.q
        inp.current_velocity = self.v
        inp.current_acceleration = self.a
        self._synced = True

    def _run(self) -> bool:
        try:
            result = self._otg.update(self._inp, self._out)
        except (RuckigError, RuntimeError, ValueError, TypeError) as exc:
            self.error = str(exc).strip()
            return False
        out = self._out
        position = out.new_position  # a list; its sum is finite when every entry is (joint
        # angles are far from overflowing a sum)
        if not math.isfinite(sum(position)):
            self.error = "ruckig returned a non-finite sample"
            return False
        self.q = np.array(position)
        self.v = np.array(out.new_velocity)
        self.a = np.array(out.new_acceleration)
        out.pass_to_input(self._inp)  # the next period starts from this sample
        self._synced = True
        self.finished = result == Result.Finished
        return True

    def track(self, target_rad: np.ndarray, min_duration_s: float | None = None,
              target_v_rad_s: np.ndarray | None = None) -> np.ndarray:
        """Advance one period toward ``target_rad`` (position interface, the synchronization).

        Args:
            target_rad: target positions (rad), finite.
            min_duration_s: reach the target no sooner than this (s), None for time-optimal.
            target_v_rad_s: target velocities (rad/s), default 0; clipped to 90 % of the limit.
        Returns the new sample (rad). On a ruckig error it brakes instead (see ``error``).
        """
        target_rad = np.ascontiguousarray(target_rad, dtype=float)  # (one kernel signature)
        target = target_rad.tolist()  # a list: 10x faster into ruckig
        rest = self._rest
        if rest is not None and target_v_rad_s is None and self._mode == "position" \
                and rest[1] == min_duration_s and rest[0] == target:
            # ruckig's input is the one it last took and returned unchanged: so it would again
            # (the sample kept apart: a caller may have changed the array it was handed)
            self.q = rest[2].copy()
            return self.q
        inp = self._inp
        if self._mode != "position":
            inp.control_interface = ControlInterface.Position
            inp.synchronization = self._sync
            inp.target_acceleration = self._zeros
            self._synchronize_all()
            self._mode = "position"
        self._set_current()
        if self._per_dof and target != inp.target_position:
            self._synchronize_all()  # a new target: every joint synchronised again
        inp.target_position = target
        if target_v_rad_s is None:
            if not self._target_v_zero:
                inp.target_velocity = self._zeros
                self._target_v_zero = True
        else:
            inp.target_velocity = self._target_velocity(target_v_rad_s)
            self._target_v_zero = False
        inp.minimum_duration = min_duration_s
        q_before = self.q  # ruckig's current state is (q, v, a), set above or passed on
        resting = target_v_rad_s is None and self._resting()
        state = (q_before, self.v, self.a)
        if self._run() and self._unswung(state, target_rad):
            self.error = ""
            self._rest = ((target, min_duration_s, self.q.copy()) if resting and self._resting()
                          and self.q.tolist() == q_before.tolist() else None)
            return self.q
        message = self.error
        out = self.brake()
        self.error = message
        return out

    def _unswung(self, state: tuple[np.ndarray, np.ndarray, np.ndarray],
                 target_rad: np.ndarray) -> bool:
        """After a new synchronised plan from ``state`` (q, v, a): take the joints it swings
        beyond their way (see the module docstring) out of the synchronisation and plan again
        from ``state``. Returns whether the sample stands (the plan again failing is a ruckig
        error, as ``_run``'s)."""
        if self._sync == Synchronization.No or not self._out.new_calculation:
            return True
        q, v, a = state
        extrema = self._out.trajectory.position_extrema
        n = len(extrema)
        low = np.fromiter((e.min for e in extrema), float, n)
        high = np.fromiter((e.max for e in extrema), float, n)
        swung = self._swung
        if not _swung(low, high, q, target_rad, v, a, self._a_max, self.limits.jerk_rad_s3,
                      SWING_TOLERANCE_RAD, swung):
            return True
        inp = self._inp
        inp.per_dof_synchronization = [Synchronization.No if s else self._sync
                                       for s in swung.tolist()]
        self._per_dof = True
        inp.current_position, inp.current_velocity, inp.current_acceleration = q, v, a
        return self._run()

    def _target_velocity(self, target_v_rad_s: np.ndarray) -> np.ndarray:
        v = np.asarray(target_v_rad_s, dtype=float)
        if not all_finite(v):
            v = np.nan_to_num(v)
        return np.minimum(np.maximum(v, self._v_min), self._v_max)  # np.clip's values, cheaper

    def brake(self) -> np.ndarray:
        """Advance one period of a velocity-interface stop (target velocity 0); returns the
        sample (rad). If even that fails the position is held."""
        self._rest = None
        inp = self._inp
        if self._mode != "velocity":
            inp.control_interface = ControlInterface.Velocity
            inp.synchronization = Synchronization.No
            self._synchronize_all()
            inp.target_velocity = self._zeros
            self._target_v_zero = True
            inp.target_acceleration = self._zeros
            inp.minimum_duration = None
            self._mode = "velocity"
        self._set_current()
        if not self._run():
            self.v = self._zeros.copy()
            self.a = self._zeros.copy()
            self._synced = False
            self.finished = True
        return self.q

    @property
    def at_rest(self) -> bool:
        """Velocity and acceleration are (numerically) zero."""
        return bool(np.all(np.abs(self.v) < 1e-9) and np.all(np.abs(self.a) < 1e-9))


def stopping_distance_bound_rad(v_rad_s, a_rad_s2, a_max_rad_s2, j_max_rad_s3):
    """An upper bound (rad) of how far a joint at velocity ``v_rad_s`` and acceleration
    ``a_rad_s2`` travels while it stops under its acceleration and jerk limits: its
    acceleration ramps to zero (|a| / j), then it brakes, the acceleration ramping up to at most
    the limit and down again (|v| / a_max + 2 a_max / j), all at the largest speed reached."""
    v_peak = abs(v_rad_s) + a_rad_s2 * a_rad_s2 / (2.0 * j_max_rad_s3)
    return v_peak * (abs(a_rad_s2) / j_max_rad_s3 + v_peak / a_max_rad_s2
                     + 2.0 * a_max_rad_s2 / j_max_rad_s3)


# (numpy's error model: a zero limit, which ruckig refuses anyway, divides to inf or NaN and
# flags nothing, where Python's would raise)
_stopping_distance = nb.njit(cache=True, nogil=True, error_model="numpy")(
    stopping_distance_bound_rad)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _swung(low, high, q, target, v, a, a_max, j_max, tolerance, out):
    """``out``: the joints whose plan (its extrema ``low``, ``high``) leaves the stretch between
    ``q`` and ``target`` by more than their stopping distance and ``tolerance`` (rad). Returns
    whether any does."""
    any_swung = False
    for i in range(q.shape[0]):
        beyond = max(min(q[i], target[i]) - low[i], high[i] - max(q[i], target[i]))
        out[i] = beyond > _stopping_distance(v[i], a[i], a_max[i], j_max[i]) + tolerance
        any_swung = any_swung or out[i]
    return any_swung


@nb.njit(cache=True, nogil=True)
def _clipped_velocity(v, lo, hi, out):
    """``out`` = :meth:`JointTracker._target_velocity`'s numbers for a vector ``v``: NaN as 0,
    then within [``lo``, ``hi``] (an infinity at its bound, -0 kept). Returns nothing: an array
    a kernel returns costs about 1 us more than the work (numba unpickles its type to box it)."""
    for i in range(v.shape[0]):
        x = v[i]
        out[i] = min(max(x, lo[i]), hi[i]) if x == x else 0.0
