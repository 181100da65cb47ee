"""Anticipation at the edge of reach: a hand parked at its reach limit leads a goal that heads
back into reach, so that it meets the goal instead of chasing it.

Near a straight elbow only the elbow brings the hand inward, and slowly at first (the hand
moves about 10 mm per rad of elbow 1 mm inside the boundary, 46 mm per rad 10 mm inside): a
hand that starts when the goal passes it is left behind by a goal coming back at 90 mm/s
(``tools/reach_return_bound.py``). :class:`ReachLead` estimates the goal's velocity causally
(the least-squares slope of its positions over the last ``WINDOW_S``, the issue's "constant
goal velocity over the last 0.1 s") and, from it, when the goal will be reachable again; over
the last ``RUN_UP_S`` before that it moves the arm's target off the nearest reachable point
along the goal's velocity, by up to ``LEAD_M``: the elbow starts bending before the goal is
back. The lead is a position for the reach search (the arm's limits and margins, the speed
scale, the collision room and the pipeline after them stay in charge); out of reach the hand
stays within ``LEAD_M`` of the nearest reachable point.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.teleop.lead import WINDOW_S

LEAD_M = 0.010  # the cap on the lead
RUN_UP_S = 1.2  # the lead grows over this long before the goal is predicted back in reach
RUN_UP_POWER = 2.0
HORIZON_S = 0.12  # the lead is where the goal will be this much later, up to LEAD_M
AHEAD_S = 1.0  # out of reach: toward the nearest reachable point of where the goal will be
# this much later
MIN_SPEED_M_S = 0.01  # a goal heading back slower than this is not led (a parked hand does
# not follow the operator's tremor)


class ReachLead:
    """One hand's goal positions and the lead toward them (see the module docstring).

    Args:
        window_s: the velocity's window (s).
        lead_m: the largest lead (m).
        run_up_s: the lead's run-up before the predicted re-entry (s).
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
        """The goal's velocity (m/s): the least-squares slope over the window, None until the
        window holds at least half its length."""
        if len(self._t) < 3 or self._t[-1] - self._t[0] < 0.5 * self.window_s:
            return None
        t = np.asarray(self._t)
        t = t - t.mean()
        p = np.asarray(self._p)
        return t @ (p - p.mean(axis=0)) / (t @ t)

    def lead_m_of(self, speed_m_s: float) -> float:
        """How far (m) the target may lead a goal moving at ``speed_m_s``: where it will be
        ``horizon_s`` later, at most ``lead_m``; zero below ``MIN_SPEED_M_S``."""
        return 0.0 if speed_m_s < MIN_SPEED_M_S else min(self.lead_m, speed_m_s * self.horizon_s)

    def run_up_share(self, v_m_s: np.ndarray, missing_m: np.ndarray) -> float:
        """For a goal ``missing_m`` beyond the reach moving at ``v_m_s``: the share of the
        lead to take, (1 - t_back / run_up_s)^2 within [0, 1], t_back the time in which it is
        predicted back in reach (its distance over the speed at which it closes in); zero when
        it closes in slower than ``MIN_SPEED_M_S``."""
        distance = float(np.linalg.norm(missing_m))
        closing = -float(v_m_s @ missing_m) / max(distance, 1e-9)
        if closing < MIN_SPEED_M_S:
            return 0.0
        return min(max(1.0 - distance / closing / self.run_up_s, 0.0), 1.0) ** RUN_UP_POWER
