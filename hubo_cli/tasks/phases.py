"""The task's phases (:class:`~hubo_cli.control.phase.Phase`), in the order of :data:`PHASES`.

Each acts on its :class:`~hubo_cli.tasks.target.TaskTarget` (the plan row commanded, the joint
target) and returns whether the run may end this period (``done``). The plan's phases hand
over by themselves (raise -> run -> settle); ``stopped`` is entered and left from outside, by
the target, when the stopper's mode (the store's STOP_MODE of the previous period) latches or
releases: the phase it left is then started again, as hrpsys's sequence player resumes after
an emergency. What the phases ask of the modules the target writes as store keys (the
impedance controller on from the run on, the stopper's relief path), never through a module.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hubo_cli.control.phase import Phase
from hubo_cli.state import RobotState

if TYPE_CHECKING:
    from hubo_cli.tasks.target import TaskTarget

PHASES = ("raise", "run", "settle", "stopped")  # the log's phase_code is the index
SETTLE_TIMEOUT_S = 6.0
STOP_HOLD_S = 1.0  # after a stop, keep holding this long (still) before ending the run


class TaskPhase(Phase[bool]):
    """A phase of a task: its output is whether the run may end (``done``)."""

    def __init__(self, task: TaskTarget) -> None:
        self.task = task


class Raise(TaskPhase):
    """The joint-space move to the plan's first posture, then a wait until the robot is still
    with the tool on its first pose (or SETTLE_TIMEOUT_S); the wall is placed then."""

    name = "raise"

    def run(self, t_s: float, state: RobotState) -> tuple[bool, str | None]:
        task = self.task
        if (task.still(state) and task.on_first_pose(state)) or t_s >= SETTLE_TIMEOUT_S:
            task.place_wall()
            task.t_placed_s = t_s
            return False, "run"
        return False, None


class Run(TaskPhase):
    """The plan's joint targets period by period, from the row it is at (0, or where a stop
    froze it: the same row in the period it resumes, the rest in its own time). From its first
    start on, a plan with a thrust has the impedance controller on (the target writes
    IMPEDANCE_ON once ``t_run_s`` is set)."""

    name = "run"

    def start(self, t_s: float, state: RobotState) -> None:
        task = self.task
        task.t_run_s = t_s - task.k * task.plan.dt_s

    def run(self, t_s: float, state: RobotState) -> tuple[bool, str | None]:
        task = self.task
        rows = len(task.plan.t_s)
        task.k = int(round((t_s - task.t_run_s) / task.plan.dt_s))
        following = None
        if task.k >= rows:
            task.k, following = rows - 1, "settle"
        task.q_target = task.plan.q_rad[task.k]
        return False, following


class Settle(TaskPhase):
    """The plan has ended: wait until the robot is still (or SETTLE_TIMEOUT_S). Entered at the
    plan's end it waits from the next period; resumed after a stop, at once."""

    name = "settle"
    runs_at_start = False

    def start(self, t_s: float, state: RobotState) -> None:
        self.t_start_s = t_s

    def run(self, t_s: float, state: RobotState) -> tuple[bool, str | None]:
        return (self.task.still(state) or t_s - self.t_start_s >= SETTLE_TIMEOUT_S), None


class Stopped(TaskPhase):
    """An emergency stop latched: the plan is frozen where it was. Without an operator the run
    may end once the stopper holds and the robot has been still STOP_HOLD_S; with one
    (``resumable``) it holds until the operator ends it or releases the stop."""

    name = "stopped"

    def start(self, t_s: float, state: RobotState) -> None:
        task = self.task
        task.t_stop_s = t_s
        task.step_stopped = task.step
        self.t_hold_s: float | None = None  # when the stopper reached its hold

    def run(self, t_s: float, state: RobotState) -> tuple[bool, str | None]:
        task = self.task
        # the revert can outlast T2 under the limits: count the hold from its start
        holding = task.stop_mode == "hold"
        if holding and self.t_hold_s is None:
            self.t_hold_s = t_s
        still = holding and np.max(np.abs(state.dq_rad_s)) < 0.05
        if still and task.t_held_s is None:
            task.t_held_s = t_s
        return bool(still and not task.resumable and t_s - self.t_hold_s >= STOP_HOLD_S), None

    def stop(self, t_s: float) -> None:
        """Released, and the stopper has blended back to the frozen plan: it goes on."""
        self.task.resumed_t_s.append(t_s)
