"""Online trajectory generation with ruckig: the pipeline's first module.

Its joints are followed by :class:`~hubo_cli.motion.tracker.JointTracker` (the jerk-limited
follower the emergency stopper, the collision detector and the loop's smooth stop use too).
:class:`TrajectoryGenerator` is the ``otg`` module: targets are clamped to the joint limits
before ruckig, NaN entries keep that joint's previous target, a missing target for longer than
``stale_timeout_s`` brakes to a stop and requests an emergency stop (source ``stale-input``).
It is seeded from the last command, never from the measured state. Its joints are timed by one
tracker (``groups="body"``: every joint phase-synchronised, an arm waits for the legs' slowest
joint) or by one tracker per group (``groups="limbs"``: each arm on its own, the legs together,
so a hand is not slowed by the other hand or the legs); the safety behaviour is the same: a
ruckig error in any group brakes every group to rest.

With ``groups="limbs"`` it writes its trackers' states every period (the store's
:data:`~hubo_cli.control.keys.TRACKER_STATES`) and follows the synchronization a target asks
of each arm's tracker (:data:`~hubo_cli.control.keys.ARM_SYNC`), applied before it tracks, and
the velocity the target asks an arm to arrive with (:data:`~hubo_cli.control.keys.
ARM_TARGET_VELOCITY`: the goal's own, so the arm does not plan to stop at a moving goal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from hubo_cli.control.keys import ARM_SYNC, ARM_TARGET_VELOCITY, TRACKER_STATES
from hubo_cli.control.module import Cycle, Module
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import ARMS, LEGS, RobotModel
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.state import RobotState

STALE_TIMEOUT_S = 0.5  # hubo-motion-rt timeOut: no fresh command for this long -> stop
TRACKER_GROUPS = ("body", "limbs")  # one tracker for every joint / one per arm + the legs
CLAMP_TOLERANCE_RAD = 1e-9  # a target moved by less at a limit is rounding, not a clamp


@nb.njit(cache=True, nogil=True)
def take_target(q_rad, held_rad, lower_rad, upper_rad, out_rad):
    """One period's target (numba): ``out_rad`` = ``q_rad`` with its NaN entries taken from
    ``held_rad``, clamped into [lower, upper] as ``np.minimum(np.maximum(.))`` does. Returns
    (the number of finite entries of ``q_rad``, whether the clamp moved an entry by more than
    CLAMP_TOLERANCE_RAD). ``out_rad`` is written only when some entry is finite."""
    fresh = 0
    for i in range(q_rad.shape[0]):
        if np.isfinite(q_rad[i]):
            fresh += 1
    if fresh == 0:
        return 0, False
    clamped = False
    for i in range(q_rad.shape[0]):
        wanted = q_rad[i] if np.isfinite(q_rad[i]) else held_rad[i]
        x = wanted if wanted >= lower_rad[i] else lower_rad[i]
        x = x if x <= upper_rad[i] else upper_rad[i]
        if abs(x - wanted) > CLAMP_TOLERANCE_RAD:
            clamped = True
        out_rad[i] = x
    return fresh, clamped


@dataclass(frozen=True)
class TrackerState:
    """One tracker of the trajectory generator after its update: its limits and period, and
    its position (rad), velocity (rad/s) and acceleration (rad/s^2)."""

    limits: JointLimits
    dt_s: float
    q_rad: np.ndarray
    v_rad_s: np.ndarray
    a_rad_s2: np.ndarray


def tracker_groups(model: RobotModel, groups: str) -> dict[str, np.ndarray]:
    """The joint indices each tracker times, by group name: ``body`` = all joints in one group
    (``body``), ``limbs`` = the right arm, the left arm (``right-arm``, ``left-arm``) and the
    legs together (``legs``: their joints move the torso as one)."""
    if groups not in TRACKER_GROUPS:
        raise ConfigError(f"unknown tracker groups {quoted(groups)}",
                          hint=f"use one of {', '.join(TRACKER_GROUPS)}")
    n = len(model.joint_names)
    if groups == "body":
        return {"body": np.arange(n)}
    out = {arm: np.arange(n)[model.limb_slice(arm)] for arm in ARMS}
    out["legs"] = np.concatenate([np.arange(n)[model.limb_slice(leg)] for leg in LEGS])
    return out


class TargetInput:
    """The target side shared by the generators: clamping, NaN holding and the stale timeout.

    Args:
        limits: joint limits (positions are used).
        stale_timeout_s: how long without any new target counts as stale (s).
    """

    def __init__(self, limits: JointLimits, stale_timeout_s: float = STALE_TIMEOUT_S) -> None:
        self.limits = limits
        self.stale_timeout_s = float(stale_timeout_s)
        self.target = np.zeros(limits.size)
        self._last_fresh_s: float | None = None
        take_target(self.target, self.target, limits.lower_rad, limits.upper_rad,
                    np.zeros(limits.size))  # numba compiles it now, not in a control period

    def reset(self, q_rad: np.ndarray) -> None:
        """Hold ``q_rad`` (clamped) until the first target arrives."""
        self.target = self.limits.clip(np.asarray(q_rad, dtype=float))
        self._last_fresh_s = None

    def take(self, q_rad: np.ndarray, cycle: Cycle) -> bool:
        """Update the target from this period's input; return True when the input is stale.

        Flags ``joint-limit`` (clamped), ``holding`` (some joints NaN) and ``stale-input`` (also
        requested as an emergency stop).
        """
        if self._last_fresh_s is None:
            self._last_fresh_s = cycle.t_s
        q = np.ascontiguousarray(q_rad, dtype=float)  # a no-op for the loop's own vectors
        target = np.empty(self.limits.size)
        fresh, clamped = take_target(q, self.target, self.limits.lower_rad,
                                     self.limits.upper_rad, target)
        if fresh:
            if clamped:
                cycle.flags.add("joint-limit")
            if fresh < target.shape[0]:
                cycle.flags.add("holding")
            self.target = target
            self._last_fresh_s = cycle.t_s
            return False
        if cycle.t_s - self._last_fresh_s > self.stale_timeout_s:
            cycle.flags.add("stale-input")
            cycle.estop_requests.add("stale-input")
            return True
        return False


class TrajectoryGenerator(Module):
    """The ``otg`` module: jerk-limited motion toward the latest target (ruckig).

    Args:
        model: the robot model (limits).
        dt_s: the control period (s).
        stale_timeout_s: brake and request an emergency stop after this long without a target.
        limits: override the model's limits (tests).
        groups: ``body`` (one tracker for every joint) or ``limbs`` (one per arm and one for
            the legs: a hand keeps its own pace); see :func:`tracker_groups`.
        synchronization: within each tracker, ``phase`` (the joints arrive together on a
            straight line in joint space) or ``none`` (each joint time-optimal on its own).

    Input: the target (rad); NaN entries keep their last target, an all-NaN vector means
    "no new target". Flags: ``joint-limit`` (target clamped), ``holding`` (some joints kept their
    last target), ``stale-input``, ``slowing`` (braking after a ruckig error: every group
    brakes until all are at rest).
    """

    name = "otg"
    log_columns = ("otg_error_flag",)

    def __init__(self, model: RobotModel, dt_s: float, stale_timeout_s: float = STALE_TIMEOUT_S,
                 limits: JointLimits | None = None, groups: str = "body",
                 synchronization: str = "phase") -> None:
        self.limits = limits or JointLimits.from_model(model)
        self.dt_s = float(dt_s)
        self.groups = groups
        self.input = TargetInput(self.limits, stale_timeout_s)
        named = tracker_groups(model, groups)
        self.group_names = tuple(named)
        self._index = list(named.values())
        self.trackers = [JointTracker(self.limits.subset(i), self.dt_s, synchronization)
                         for i in self._index]
        self._single = len(self.trackers) == 1
        if groups == "limbs":
            self.writes, self.follows = (TRACKER_STATES,), (ARM_SYNC, ARM_TARGET_VELOCITY)
        self._q = np.zeros(self.limits.size)
        self._fault = False
        self.errors = 0

    @property
    def target(self) -> np.ndarray:
        """The current (clamped) target (rad)."""
        return self.input.target

    def synchronize(self, synchronization: str, groups: tuple[str, ...] | None = None) -> None:
        """Time the joints of the named groups' trackers (default all) this way from the next
        period on (``phase`` or ``none``). Teleoperation lets each arm joint track on its own
        while the operator drives, and keeps the straight joint-space line of ``phase`` for the
        moves before (:class:`hubo_cli.teleop.target.TeleopTarget`)."""
        for name, tracker in zip(self.group_names, self.trackers, strict=True):
            if groups is None or name in groups:
                tracker.set_synchronization(synchronization)

    @property
    def at_rest(self) -> bool:
        """Every tracker's velocity and acceleration are (numerically) zero."""
        return all(t.at_rest for t in self.trackers)

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        q = np.where(np.isfinite(q_rad), q_rad, state.q_rad)
        for index, tracker in zip(self._index, self.trackers, strict=True):
            tracker.reset(q[index])
        self._q = np.array(q, dtype=float)
        self.input.reset(q)
        self._fault = False

    def _brake(self) -> np.ndarray:
        if self._single:
            return self.trackers[0].brake()
        for index, tracker in zip(self._index, self.trackers, strict=True):
            self._q[index] = tracker.brake()
        return self._q.copy()

    def _track(self, target: np.ndarray, velocities: dict | None = None
               ) -> tuple[np.ndarray, bool]:
        """One period toward ``target`` (with ``velocities``: group -> the velocity that group
        arrives with, rad/s; default zero); returns (sample, whether any group's ruckig
        failed)."""
        if self._single:
            tracker = self.trackers[0]
            return tracker.track(target), bool(tracker.error)
        failed = False
        velocities = velocities or {}
        for name, index, tracker in zip(self.group_names, self._index, self.trackers,
                                        strict=True):
            self._q[index] = tracker.track(target[index],  # a failing group brakes already
                                           target_v_rad_s=velocities.get(name))
            failed = failed or bool(tracker.error)
        return self._q.copy(), failed

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        if not self.writes:
            return self._update(q_rad, cycle)
        for group, synchronization in (cycle.store.get(ARM_SYNC) or {}).items():
            self.synchronize(synchronization, groups=(group,))
        q = self._update(q_rad, cycle, cycle.store.get(ARM_TARGET_VELOCITY))
        cycle.store[TRACKER_STATES] = {
            name: TrackerState(t.limits, self.dt_s, t.q.copy(), t.v.copy(), t.a.copy())
            for name, t in zip(self.group_names, self.trackers, strict=True)}
        return q

    def _update(self, q_rad: np.ndarray, cycle: Cycle, velocities: dict | None = None
                ) -> np.ndarray:
        stale = self.input.take(q_rad, cycle)
        cycle.info["otg_error_flag"] = 0.0
        if stale:
            return self._brake()
        if self._fault:
            q = self._brake()
            cycle.flags.add("slowing")
            if self.at_rest:
                self._fault = False
            return q
        q, failed = self._track(self.input.target, velocities)
        if failed:
            self.errors += 1
            self._fault = True
            cycle.flags.add("slowing")
            cycle.info["otg_error_flag"] = 1.0
        return q
