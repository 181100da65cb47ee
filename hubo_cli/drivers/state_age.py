"""A late state from hubo-daemon: each fresh ``hubo-state`` frame's ``time`` against this
computer's clock.

hubo-daemon stamps each state with its ``CLOCK_MONOTONIC``; on the computer that runs it the
state's age is now minus that ``time``. A state that keeps arriving (fresh, its ``time``
advancing: no stale-state brake) but consistently old means the controllers act on where the
robot was, not where it is: the capture point, the balance and the servo-error check then all
lag by that much. A state older than :data:`STATE_AGE_LIMIT_S` for :data:`STATE_AGE_FOR_S` of
the daemon's time (every fresh state over that span that old) is a device fault: servo-off
latches, the last reference is held and the run ends (exit 3), one line with the age.

Healthy spread (docs/history/hardware.md, "Timing" and "Motors, faults and the acceptance runs
through the simulated daemon": the simulated daemon on this 2-core machine at load 4.5-11):
median 0.4-5.5 ms, p99 8.9-33.9 ms, the largest single state 68.4 ms; the limit is 1.5 times
that single largest, and it must hold for 20 periods in a row, which no healthy run came near.

The simulated driver applies the same check to its states' time against the simulator's
clock (:class:`~hubo_cli.drivers.sim.SimDriver`): the two are one clock, so a simulated state
is never old unless the code that measures it is wrong (review 18's delayed state, round 19);
its bound is half a period (:data:`hubo_cli.drivers.sim.STATE_LATE_S`), for the same 0.1 s.

Through ``achd`` (the daemon on another computer) the two clocks differ and the age means
nothing: a first state whose age is beyond :data:`CLOCKS_DIFFER_S` either way turns the check
off for the run (:attr:`StateAgeGuard.judged` False, the summary's ``hw_state_age_checked``).
"""

from __future__ import annotations

from hubo_cli.errors import DeviceError

STATE_AGE_LIMIT_S = 0.1  # 1.5x the healthy runs' largest single state age (68.4 ms)
STATE_AGE_FOR_S = 0.1  # ... for this long of the daemon's time (20 periods)
CLOCKS_DIFFER_S = 10.0  # a first state this far from now: another computer's clock (achd)


DAEMON_HINT = ("check hubo-daemon's load and priority on the robot's computer, then start the "
               "run again")


class StateTooOld(DeviceError):
    """hubo-daemon's states arrive, but late: the robot is controlled on an old picture."""

    def __init__(self, channel: str, age_s: float, limit_s: float, for_s: float,
                 t_s: float, clock: str = "this computer's clock",
                 hint: str = DAEMON_HINT) -> None:
        super().__init__(f"{channel}'s states are {1e3 * age_s:.0f} ms old (its time against "
                         f"{clock}; older than {1e3 * limit_s:.0f} ms for {for_s:.2f} s) at "
                         f"t = {t_s:.2f} s: the robot is controlled on where it was; it holds "
                         "its last reference", hint=hint)
        self.age_s = age_s


class StateAgeGuard:
    """Trips when every fresh state over ``for_s`` of the daemon's time is older than
    ``limit_s``.

    Args:
        channel: the state channel's name (for the message).
        limit_s, for_s: see :data:`STATE_AGE_LIMIT_S`, :data:`STATE_AGE_FOR_S`.
        clock, hint: what the age is measured against and what to check (for the message).
    """

    def __init__(self, channel: str, limit_s: float = STATE_AGE_LIMIT_S,
                 for_s: float = STATE_AGE_FOR_S, clock: str = "this computer's clock",
                 hint: str = DAEMON_HINT) -> None:
        self.channel, self.limit_s, self.for_s = channel, float(limit_s), float(for_s)
        self.clock, self.hint = clock, hint
        self.judged: bool | None = None  # None until the first state: then whether clocks agree
        self._old_since_s: float | None = None

    def check(self, age_s: float, t_s: float) -> StateTooOld | None:
        """One fresh state's age (s) at the daemon's time ``t_s`` (s since the run's first
        state); the trip, or None."""
        if self.judged is None:
            self.judged = abs(age_s) <= CLOCKS_DIFFER_S
        if not self.judged or not age_s > self.limit_s:
            self._old_since_s = None
            return None
        if self._old_since_s is None:
            self._old_since_s = t_s
        if t_s - self._old_since_s >= self.for_s:
            return StateTooOld(self.channel, age_s, self.limit_s, self.for_s, t_s, self.clock,
                               self.hint)
        return None
