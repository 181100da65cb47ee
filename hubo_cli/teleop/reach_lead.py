"""Anticipation at the edge of reach: a hand parked at its reach limit leads a goal that heads
back into reach, so that it meets the goal instead of chasing it.

Near a straight elbow only the elbow brings the hand inward, and slowly at first (about 10 mm
per rad of elbow 1 mm inside the boundary, 46 mm per rad 10 mm inside): a hand that starts
when the goal passes it is left behind by a goal coming back at 90 mm/s
(``tools/reach_return_bound.py``). :class:`ReachLead` estimates the goal's velocity v causally
(the least-squares slope of its positions over the last ``WINDOW_S``, the issue's "constant
goal velocity over the last 0.1 s"). While the goal is out of reach and closes in on it, the
arm's target moves off the nearest reachable point toward the nearest reachable point of where
the goal will be ``AHEAD_S`` later (down along the boundary and inward), by where the goal will
be ``HORIZON_S`` later (at most ``LEAD_M``, :meth:`ReachLead.lead_m_of`) times a share that
grows from 0 to 1 over the ``RUN_UP_S`` before the goal is predicted back in reach (its
distance over its closing speed): the elbow starts bending before the goal is back, and the
hand stays near the nearest reachable point. Once the goal is back, the hand follows it as any
reachable goal, with two differences while it returns from ``LEAD_BEYOND_M`` or more beyond
the reach and still moves (:meth:`ReachLead.back_lead_m`): the target leads it along its
velocity, by the lead until the goal has passed the hand and then by no more than the hand lags
behind it (leading every goal back in reach by its velocity x 0.12 s brought the walk's lasting
2 mm from 2.45 to 2.24 s but made the generated streams' reachable position RMS worse); and its
goal is followed (the trajectory generator given the goal's velocity) while the singularity
scale slows it, the goal moving inward, away from the straight elbow. Without them the target
falls back from the led pose to the goal's, nearer the straight elbow, and the elbow brakes
from its run-up at re-entry (docs/history/teleop.md, round 9).

While the hand is ``RETURN_BEHIND_M`` or more behind a returning goal, its tracker meets the
goal's prediction with the goal's joint velocity decaying as measured over the last window
(at most ``RETURN_DECAY_S``) instead of within :data:`hubo_cli.teleop.lead.DECAY_S`: near the
straight elbow the goal's joints slow down as the elbow bends, and a tracker that predicts
them at rest within 0.1 s plans to stop at the goal and creeps up on it.

Only a goal that went ``LEAD_BEYOND_M`` or more out of reach and moves between
``MIN_SPEED_M_S`` and ``MAX_SPEED_M_S`` is led. The lead is a pose for the arm's reach search
(:mod:`hubo_cli.teleop.target` applies it): its limits and margins, the speed scale (times
``LEAD_SCALE_SHARE`` for a led target), the collision room and the pipeline after them stay in
charge.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.teleop.lead import WINDOW_S, slope_weights

LEAD_M = 0.010  # the cap on the lead
RUN_UP_S = 1.2  # the lead grows over this long before the goal is predicted back in reach
RUN_UP_POWER = 2.0  # the share grows as the square of the time run up (slowly at first, where
# the elbow near straight moves the hand least). Tuned on the out-of-reach walk at full, half
# and a quarter of its speed (tests/test_teleop_reach.py): RUN_UP_S 0.8 / 1.0 / 1.2 / 1.5 s,
# AHEAD_S 0.5 / 0.75 / 1.0 s, HORIZON_S 0.08 / 0.12 / 0.25 s; docs/history/teleop.md
HORIZON_S = 0.12  # the lead is where the goal will be this much later, up to LEAD_M
AHEAD_S = 1.0  # out of reach: toward the nearest reachable point of where the goal will be
# this much later
HEADING_SHARE = 0.7  # and closing in at this share of its speed at least (heading back, not
# passing by)
MAX_SPEED_M_S = 0.2  # nor one faster than this: at the generated streams' 0.6 m/s a goal
# heading back often turns away again, and a hand led toward where it would have come back ended
# up further from it (one hand's largest excursion 288 -> 322 mm over the bench's 8 x 20 s
# streams; with this gate out of reach only, the reachable position RMS p90 82 -> 97 mm)
LEAD_BEYOND_M = 0.02  # a hand is led toward a goal coming back from this far out of reach or
# further (closer, the hand at its limit follows it along the boundary: drill-rectangle.csv's
# goal, just beyond the right hand's reach for 18 s in free mode, 2.56 mm RMS without a lead,
# 2.75 mm with it from any distance)
LEAD_SCALE_SHARE = 0.9  # of the singularity speed scale, for a led target: it leaves no faster
# than the approach's band allows, with a margin for the tracker catching up (0.45 of the speed
# limits at kappa 100)
MIN_SPEED_M_S = 0.01  # a goal heading back slower than this is not led (a parked hand does
# not follow the operator's tremor)
RETURN_BEHIND_M = 0.005  # a returning hand this far or more behind its goal along the goal's
# velocity meets the goal's prediction with its joint velocity decaying as measured
# (teleop/lead.GoalVelocity.decay_s, at most RETURN_DECAY_S), not within lead.DECAY_S: the
# goal's joints slow as its elbow bends, far slower than the 0.1 s that suits a goal followed
# closely. The out-of-reach walk over 13 walks (7-32 s back, 20-40 cm beyond), within 2 mm
# for good 2.04-2.63 s against 2.34-2.72 s; every walk as soon or sooner with 4-8 mm here
# and 0.5-2 s there; with 2-3 mm half speed's 2.81 s (docs/history/teleop.md, round 10)
RETURN_DECAY_S = 1.0


class ReachLead:
    """One hand's goal positions and the lead toward them (see the module docstring).

    Args:
        window_s: the velocity's window (s).
        lead_m: the largest lead (m).
        run_up_s: the lead's run-up before the predicted re-entry (s).
        horizon_s: the lead is where the goal will be this much later (s), at most ``lead_m``
            (:meth:`lead_m_of`).
    """

    def __init__(self, window_s: float = WINDOW_S, lead_m: float = LEAD_M,
                 run_up_s: float = RUN_UP_S, horizon_s: float = HORIZON_S) -> None:
        self.window_s, self.lead_m, self.run_up_s = window_s, lead_m, run_up_s
        self.horizon_s = horizon_s
        self._t: list[float] = []
        self._p: list[np.ndarray] = []

    def clear(self) -> None:
        """Forget the goal's history (a re-centred or held hand starts anew)."""
        self._t, self._p = [], []

    def push(self, t_s: float, goal_m: np.ndarray) -> None:
        """The goal's position (m) at ``t_s``; positions older than the window are dropped."""
        self._t.append(t_s)
        self._p.append(np.array(goal_m, dtype=float))
        while self._t[0] < t_s - self.window_s - 1e-9:
            del self._t[0], self._p[0]

    def velocity_m_s(self) -> np.ndarray | None:
        """The goal's velocity (m/s): the least-squares slope over the window
        (:func:`hubo_cli.teleop.lead.slope_weights`); None until the window holds at least half
        its length, and None when it is not finite (a NaN or inf among the positions)."""
        if len(self._t) < 3 or self._t[-1] - self._t[0] < 0.5 * self.window_s:
            return None
        v = slope_weights(self._t) @ np.asarray(self._p)
        return v if np.all(np.isfinite(v)) else None

    def lead_m_of(self, speed_m_s: float) -> float:
        """How far (m) the target may lead a goal moving at ``speed_m_s``: where it will be
        ``horizon_s`` later, at most ``lead_m``; zero below ``MIN_SPEED_M_S`` and above
        ``MAX_SPEED_M_S``."""
        if not MIN_SPEED_M_S <= speed_m_s <= MAX_SPEED_M_S:
            return 0.0
        return min(self.lead_m, speed_m_s * self.horizon_s)

    def back_lead_m(self, speed_m_s: float, behind_m: float, passed: bool) -> float:
        """Once the goal moving at ``speed_m_s`` is back in reach: how far (m) the target leads
        it along its velocity: :meth:`lead_m_of` its speed until the goal has ``passed`` the
        hand, then at most how far the hand is ``behind_m`` it along that velocity (none once
        the hand has caught up)."""
        lead_m = self.lead_m_of(speed_m_s)
        return min(lead_m, max(behind_m, 0.0)) if passed else lead_m

    def time_back_s(self, v_m_s: np.ndarray, missing_m: np.ndarray) -> float:
        """In how long a goal ``missing_m`` beyond the reach, moving at ``v_m_s``, is predicted
        back in reach (s): its distance over the speed at which it closes in; inf when it closes in
        slower than ``MIN_SPEED_M_S`` or than ``HEADING_SHARE`` of its speed (it does not head
        back)."""
        distance = float(np.linalg.norm(missing_m))
        closing = -float(v_m_s @ missing_m) / max(distance, 1e-9)
        if closing < max(MIN_SPEED_M_S, HEADING_SHARE * float(np.linalg.norm(v_m_s))):
            return np.inf
        return distance / closing

    def run_up_share(self, v_m_s: np.ndarray, missing_m: np.ndarray) -> float:
        """The share of the lead to take for a goal ``missing_m`` beyond the reach moving at
        ``v_m_s``: (1 - t_back / run_up_s)^RUN_UP_POWER within [0, 1], t_back from
        :meth:`time_back_s`."""
        t_back = self.time_back_s(v_m_s, missing_m)
        return min(max(1.0 - t_back / self.run_up_s, 0.0), 1.0) ** RUN_UP_POWER
