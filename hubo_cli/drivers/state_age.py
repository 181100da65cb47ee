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
clock (:class:`~hubo_cli.drivers.sim.SimDriver`): the two are one clock (``one_clock``: judged
against 0, so a lag from the first state is seen too), so a simulated state is never old unless
the code that measures it is wrong (review 18's delayed state, round 19); its bound is half a
period (:data:`hubo_cli.drivers.sim.STATE_LATE_PERIODS`), for the same 0.1 s.

On the robot the two clocks need not be one. Through ``achd`` (the daemon on another
computer, e.g. Hubo's body and vision computers powered up seconds apart) each state's age is
the two ``CLOCK_MONOTONIC``'s difference plus the transport's latency, and the difference is unknown
(review 19: a healthy robot 0.5-9 s apart tripped at 0.1 s, one -3 s apart was never judged).
So an age is judged against the smallest age of the last :data:`BASELINE_BLOCK_S` to twice that
of the daemon's time: that smallest age is the clocks' difference plus the quickest state's
latency, so what lies beyond it is a state's lateness, whatever the difference. A state later
than that by more than the limit for the span trips. What this sees: a daemon or a stream that
falls behind after the first states (a lag that grows by more than 0.1 s within 30 s: a stream
slipping 3.3 ms a second or faster), a daemon whose states stop being fresh in time. What it
cannot see: a lag present from the first state (it reads as the clocks' difference) and one
that grows slower than the window forgets it (under 3.3 ms a second; two computers' clocks
drift apart by 0.1 ms a second at most, 100 ppm). The summary's ``hw_state_age_checked`` is
true once the guard has judged states over :data:`STATE_AGE_FOR_S` (a trip was possible), false
on a simulated clock (no age) or a run shorter than that; ``hw_state_age_baseline_ms`` is the
last smallest age (the clocks' difference plus the quickest latency).
"""

from __future__ import annotations

from hubo_cli.errors import DeviceError

STATE_AGE_LIMIT_S = 0.1  # 1.5x the healthy runs' largest single state age (68.4 ms)
STATE_AGE_FOR_S = 0.1  # ... for this long of the daemon's time (20 periods)
# Ages are judged against the smallest of the last 30-60 s of the daemon's time: the clocks'
# difference plus the quickest latency (a lag growing 3.3 ms/s or faster is seen; clocks drift
# apart 0.1 ms/s at most)
BASELINE_BLOCK_S = 30.0

DAEMON_HINT = ("check hubo-daemon's load and priority on the robot's computer, then start the "
               "run again")


class StateTooOld(DeviceError):
    """hubo-daemon's states arrive, but late: the robot is controlled on an old picture."""

    def __init__(self, channel: str, age_s: float, limit_s: float, for_s: float,
                 t_s: float, baseline_s: float = 0.0, clock: str = "this computer's clock",
                 hint: str = DAEMON_HINT) -> None:
        how = (f"{1e3 * (age_s - baseline_s):.0f} ms late ({1e3 * age_s:.0f} ms old against "
               f"{clock}, the quickest of the last states {1e3 * baseline_s:.0f} ms; later than "
               f"that by over" if baseline_s else
               f"{1e3 * age_s:.0f} ms old (its time against {clock}; older than")
        super().__init__(f"{channel}'s states are {how} {1e3 * limit_s:.0f} ms for "
                         f"{for_s:.2f} s) at t = {t_s:.2f} s: the robot is controlled on where "
                         "it was; it holds its last reference", hint=hint)
        self.age_s, self.baseline_s = age_s, baseline_s


class StateAgeGuard:
    """Trips when every fresh state over ``for_s`` of the daemon's time is later than
    ``limit_s`` beyond the smallest age of the last ``BASELINE_BLOCK_S`` to twice that (the two
    clocks' difference and the quickest latency: module docstring).

    Args:
        channel: the state channel's name (for the message).
        limit_s, for_s: see :data:`STATE_AGE_LIMIT_S`, :data:`STATE_AGE_FOR_S`.
        clock, hint: what the age is measured against and what to check (for the message).
        one_clock: the states' time and the age's clock are one (the simulator): the age is
            judged against 0, not against the smallest recent one.
    """

    def __init__(self, channel: str, limit_s: float = STATE_AGE_LIMIT_S,
                 for_s: float = STATE_AGE_FOR_S, clock: str = "this computer's clock",
                 hint: str = DAEMON_HINT, one_clock: bool = False) -> None:
        self.channel, self.limit_s, self.for_s = channel, float(limit_s), float(for_s)
        self.clock, self.hint, self.one_clock = clock, hint, one_clock
        self.judged: bool | None = None  # None before the first state; True once a trip could be
        self.baseline_s = float("nan")  # the smallest age of the window (s)
        self._old_since_s: float | None = None
        self._first_s: float | None = None  # the first state's time (s)
        self._block = (float("nan"), float("inf"), float("inf"))  # start, this min, the last's

    def check(self, age_s: float, t_s: float) -> StateTooOld | None:
        """One fresh state's age (s) at the daemon's time ``t_s`` (s since the run's first
        state); the trip, or None."""
        start_s, least_s, last_s = self._block
        if not t_s - start_s < BASELINE_BLOCK_S:  # (NaN: the first state) a new block
            start_s, least_s, last_s = t_s, float("inf"), least_s
        least_s = min(least_s, age_s)
        self._block = start_s, least_s, last_s
        self.baseline_s = 0.0 if self.one_clock else min(least_s, last_s)
        if self._first_s is None:
            self._first_s = t_s
        self.judged = t_s - self._first_s >= self.for_s
        if not age_s - self.baseline_s > self.limit_s:
            self._old_since_s = None
            return None
        if self._old_since_s is None:
            self._old_since_s = t_s
        if t_s - self._old_since_s >= self.for_s:
            return StateTooOld(self.channel, age_s, self.limit_s, self.for_s, t_s,
                               self.baseline_s, self.clock, self.hint)
        return None
