"""A robot state that stops coming is device trouble: brake, hold, end the run.

The hardware driver flies blind without hubo-daemon's ``hubo-state`` (a daemon killed or hung,
an ``achd`` link lost). :class:`StaleStateBrake` judges the state's freshness by the wall clock
(periods stretch while the driver waits for a state that does not come). After ``after_s``
(0.1 s) without a fresh state it takes over the reference from the pipeline: a jerk-limited
velocity-interface brake (the control loop's smooth stop, :class:`JointTracker`) from the
reference's own velocity and acceleration to rest, then a hold. ``grace_s`` (0.8 s) after the
brake began, or when it reaches rest if that is later, the run ends with :class:`StateLost`
(exit 3). A state that comes back within the grace is reported but never resumes the motion:
the plan went on while the robot was held, so carrying on needs the operator, and a new run
starts from the measured posture.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hubo_cli.errors import DeviceError
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker


class StateLost(DeviceError):
    """No fresh robot state for longer than the grace: the robot was braked and held.

    Args:
        channel: the state channel.
        since_t_s: run time of the last fresh state (s).
        stale_s: how long no fresh state came (s): until the run ended, or until it came back
            (then ``back`` is True).
        back: fresh state came again within the grace (the motion was still not resumed).
    """

    def __init__(self, channel: str, since_t_s: float, stale_s: float, back: bool) -> None:
        what = (f"{channel} stopped at t = {since_t_s:.2f} s and came back {stale_s:.2f} s "
                "later; the cut is not resumed unattended" if back else
                f"no fresh {channel} for {stale_s:.2f} s since t = {since_t_s:.2f} s")
        super().__init__(f"robot state lost: {what}; the robot was braked and holds its "
                         "last reference",
                         hint="check hubo-daemon (hubo-ach status) and the achd link, then "
                              "start the run again (it starts from the measured posture)")
        self.channel = channel
        self.since_t_s = since_t_s
        self.stale_s = stale_s
        self.back = back


class StaleStateBrake:
    """Watches the robot state's freshness; brakes and holds the reference when it stops.

    Args:
        model: the robot (its 24 limb joints' velocity, acceleration and jerk limits).
        period_s: the control period (s).
        after_s: wall time without a fresh state before the brake (s).
        grace_s: how long after the brake began the run ends (s).
        clock: the wall clock (s).

    Attributes:
        back: fresh state came again after the brake began.
        advanced: :meth:`advance` ran since the owner last cleared it (once per period).
    """

    def __init__(self, model: RobotModel, period_s: float, after_s: float, grace_s: float,
                 clock: Callable[[], float]) -> None:
        self.limits = JointLimits.from_model(model)
        self.period_s = period_s
        self.after_s = after_s
        self.grace_s = grace_s
        self.clock = clock
        self.reset()

    def reset(self) -> None:
        """Start afresh: the state counts as fresh now, no brake."""
        self._fresh_s = self.clock()
        self._hold_s: float | None = None
        self._lost_s = self._back_s = self._since_t_s = 0.0
        self._tracker: JointTracker | None = None
        self.back = False
        self.advanced = False

    # ------------------------------------------------------------------ the state
    def fresh(self) -> None:
        """A fresh state has just arrived."""
        self._fresh_s = self.clock()
        if self.holding and not self.back:
            self.back, self._back_s = True, self._fresh_s

    @property
    def age_s(self) -> float:
        """Wall time since the last fresh state (s)."""
        return self.clock() - self._fresh_s

    def watch(self, since_t_s: float, sent_rad: tuple[np.ndarray, np.ndarray, np.ndarray]
              ) -> None:
        """Begin the brake (once) when the state is ``after_s`` old.

        Args:
            since_t_s: run time of the last fresh state (s), for the message.
            sent_rad: the last three references put, oldest first (their velocity and
                acceleration start the brake).
        """
        if self.holding or self.age_s < self.after_s:
            return
        self._hold_s, self._lost_s, self._since_t_s = self.clock(), self._fresh_s, since_t_s
        dt = self.period_s
        q2, q1, q0 = sent_rad
        v = (q0 - q1) / dt
        a = (q0 - 2 * q1 + q2) / dt**2
        self._tracker = JointTracker(self.limits, dt)
        self._tracker.reset(q0, v + 0.5 * a * dt, a)  # as the loop's smooth stop starts

    # ------------------------------------------------------------------ the brake
    @property
    def holding(self) -> bool:
        """The brake began: the pipeline's commands are ignored for the rest of the run."""
        return self._hold_s is not None

    @property
    def braking(self) -> bool:
        """The brake has not yet brought the reference to rest."""
        return self._tracker is not None and not self._tracker.at_rest

    def advance(self) -> np.ndarray:
        """The brake's reference one period on (rad, clipped to the position limits)."""
        self.advanced = True
        return self.limits.clip(self._tracker.brake())

    def flags(self) -> tuple[str, ...]:
        """``stale-state`` while no fresh state comes after the brake began, ``stale-hold``
        once it has come back."""
        if not self.holding:
            return ()
        return ("stale-hold",) if self.back else ("stale-state",)

    def lost(self, channel: str, braking: bool) -> StateLost | None:
        """The error that ends the run once the grace is over and the brake done (``braking``:
        the owner's brake still moves), else None."""
        if not self.holding or braking or self.clock() - self._hold_s < self.grace_s:
            return None
        stale_s = (self._back_s if self.back else self.clock()) - self._lost_s
        return StateLost(channel, self._since_t_s, stale_s, self.back)
