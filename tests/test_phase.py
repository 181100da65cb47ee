"""The phase contract: each phase started once when entered, run every period it is in force,
stopped once when left; hand-overs in the same period or from the next."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.control.phase import Phase, Phases
from hubo_cli.state import RobotState

STATE = RobotState(0.0, np.zeros(3), np.zeros(3))


class Recorded(Phase):
    def __init__(self, name, calls, until_s=None, following=None, at_start=True):
        self.name, self.calls = name, calls
        self.until_s, self.following, self.runs_at_start = until_s, following, at_start

    def start(self, t_s, state):
        self.calls.append(("start", self.name, t_s))

    def run(self, t_s, state):
        self.calls.append(("run", self.name, t_s))
        done = self.until_s is not None and t_s >= self.until_s
        return self.name, (self.following if done else None)

    def stop(self, t_s):
        self.calls.append(("stop", self.name, t_s))


def test_phases_start_run_and_stop_in_order_with_either_hand_over():
    calls = []
    phases = Phases([Recorded("walk", calls, 1.0, "rise"),
                     Recorded("rise", calls, 2.0, "then", at_start=False),
                     Recorded("then", calls)])
    outputs = [(t, phases(t, STATE), phases.ran.name, phases.current.name)
               for t in (0.0, 1.0, 2.0, 3.0)]
    # the walk's last output stands in the period it ends (the rise runs from the next);
    # the session's target runs in the period the rise hands over
    assert outputs == [(0.0, "walk", "walk", "walk"), (1.0, "walk", "walk", "rise"),
                       (2.0, "then", "then", "then"), (3.0, "then", "then", "then")]
    assert calls == [("start", "walk", 0.0), ("run", "walk", 0.0), ("run", "walk", 1.0),
                     ("stop", "walk", 1.0), ("start", "rise", 1.0), ("run", "rise", 2.0),
                     ("stop", "rise", 2.0), ("start", "then", 2.0), ("run", "then", 2.0),
                     ("run", "then", 3.0)]
    assert phases.code == 2.0


def test_phases_that_hand_over_in_a_circle_or_share_a_name_are_refused():
    calls = []
    circle = Phases([Recorded("a", calls, 0.0, "b"), Recorded("b", calls, 0.0, "a")])
    with pytest.raises(RuntimeError, match="in a circle"):
        circle(0.0, STATE)
    with pytest.raises(ValueError, match="distinct names"):
        Phases([Recorded("a", calls), Recorded("a", calls)])
