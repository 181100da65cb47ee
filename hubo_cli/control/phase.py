"""The phases of a run (a walk, a rise, a capture step and its catch, a cut) and what they tell
the pipeline.

A phase is an explicit state (:class:`Phase`): started once when entered, run every period,
stopped once when left; a :class:`Phases` machine runs one at a time and says which. What a
phase asks of the modules are store keys its target writes every period and the modules follow
(``follows``: a run without such a phase writes none of them, and the modules then do as when
standing).

A target switches the modules through these keys, never through their attributes or by
resetting them: the capture-point monitor judges the capture point against the support the
phase plans (:data:`SUPPORT_PLAN`), the standing balancers are switched off while a phase
moves the centre of mass itself (:data:`BALANCERS_REST`: they drop their correction once,
pass the command through while off, and start afresh when switched on), and a phase that
cannot stop by reverting (a step in the air) tells the soft stopper how it stops itself
(:data:`PHASE_STOP`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from hubo_cli.dataflow import Key
from hubo_cli.state import RobotState

Out = TypeVar("Out")


class Phase(ABC, Generic[Out]):
    """One state of a run. ``start`` is called once when it is entered, ``run`` every period
    it is the current one, ``stop`` once when it is left.

    Attributes:
        name: the phase's name (in the log's phase codes and the report).
        runs_at_start: entered, it runs in the same period and its output is the period's
            (True), or the output of the phase it follows stands and it runs from the next
            period on (False).
    """

    name = "phase"
    runs_at_start = True

    def start(self, t_s: float, state: RobotState) -> None:
        """Entered at ``t_s`` (s, the target's clock)."""

    @abstractmethod
    def run(self, t_s: float, state: RobotState) -> tuple[Out, str | None]:
        """This period's output and the name of the phase to go to (None: stay)."""

    def stop(self, t_s: float) -> None:
        """Left at ``t_s``."""


class Phases(Generic[Out]):
    """Runs one of ``phases`` at a time, from the first: a phase's ``run`` names the next one,
    which is started in the same period (``stop`` of the one left first) and run then or from
    the next period (its ``runs_at_start``).

    Args:
        phases: the phases, each with its own name.

    Attributes:
        current: the phase in force now; ran: the one whose output the last call returned.
    """

    def __init__(self, phases: Sequence[Phase[Out]]) -> None:
        self.by_name = {p.name: p for p in phases}
        if len(self.by_name) != len(phases) or not phases:
            raise ValueError("phases need distinct names, at least one")
        self.names = tuple(self.by_name)
        self.current: Phase[Out] = phases[0]
        self.ran: Phase[Out] = self.current
        self._started = False

    @property
    def code(self) -> float:
        """The current phase's index (the log's ``phase_code``)."""
        return float(self.names.index(self.current.name))

    def __call__(self, t_s: float, state: RobotState) -> Out:
        if not self._started:
            self._started = True
            self.current.start(t_s, state)
        for _ in range(len(self.names) + 1):  # a phase may hand over at once, never loop
            out, following = self.current.run(t_s, state)
            self.ran = self.current
            if following is None or following == self.current.name:
                return out
            self.go(following, t_s, state)
            if not self.current.runs_at_start:
                return out
        raise RuntimeError(f"phases hand over in a circle at {t_s:.3f} s")

    def go(self, name: str, t_s: float, state: RobotState) -> None:
        """Leave the current phase for ``name`` (from outside: a stop latched)."""
        self.current.stop(t_s)
        self.current = self.by_name[name]
        self.current.start(t_s, state)


@dataclass(frozen=True)
class SupportPlan:
    """The support a phase plans for this period.

    Attributes:
        T_world_soles: (2, 4, 4) the right and left sole poses the robot stands on in this
            phase of the step (a swing foot at its landing place), on the floor.
        margin_m: the capture-point monitor shrinks their hull by this much (m; None: by
            its own margin).
        swinging: (right, left) True for a sole the plan has off the floor in this period
            (counted at its landing place): while the soles' sensors still read it carrying
            (the estimate's contact), the monitor also judges the capture point against it
            where it stands.
    """

    T_world_soles: np.ndarray
    margin_m: float | None = None
    swinging: tuple[bool, bool] = (False, False)


SUPPORT_PLAN = Key("support_plan", object,
                   "SupportPlan of this period, or None: the estimate's soles in contact, "
                   "shrunk by the monitor's own margin")
BALANCERS_REST = Key("standing_balancers_rest", bool,
                     "True while a phase moves the centre of mass itself: the standing "
                     "balancers send no correction and start afresh when it ends")



@dataclass(frozen=True)
class PhaseStop:
    """How this phase stops itself when the soft stopper latches: a walk cannot revert in
    mid-step (the swing foot in the air), so it finishes the step into a double-support stance
    and holds there. The stop itself stays the stopper's: it latches, flags ``estop`` and waits
    for a release as always; it only passes the phase's own stopping motion through (mode
    ``finish``) until the phase says it stands (``settled``), then holds that posture. A phase
    that does not settle within ``within_s`` of the latch (or stops writing this key) is braked
    and held where it is (:mod:`hubo_cli.control.estop`).

    Attributes:
        settled: the phase stands in its stop stance: hold from this period on.
        within_s: it settles within this long of a stop latched now (s; the stopper caps it).
    """

    settled: bool
    within_s: float


PHASE_STOP = Key("phase_stop", object,
                 "PhaseStop of this period, or None: a stop reverts the motion (eq. 15)")

PHASE_KEYS = (SUPPORT_PLAN, BALANCERS_REST, PHASE_STOP)
