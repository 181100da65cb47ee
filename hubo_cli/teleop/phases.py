"""The teleoperation session's phases (:class:`~hubo_cli.control.phase.Phase`), in the order
of :data:`PHASES`: the approach, the operator's control, the settling after a replay.

Each acts on its :class:`~hubo_cli.teleop.target.TeleopTarget` (its joint target, goals and
hands) and adds what the period reports (status flags, ``done``) to the target's
:attr:`~hubo_cli.teleop.target.TeleopTarget.info` of this period: a hand-over keeps what the
phase before added. What a phase asks of the modules the target writes as store keys (the
arms' synchronisation for otg), never through a module.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hubo_cli.control.phase import Phase
from hubo_cli.state import RobotState

if TYPE_CHECKING:
    from hubo_cli.teleop.target import TeleopTarget

PHASES = ("approach", "operate", "settle")  # the log's phase_code is the index


class TeleopPhase(Phase[None]):
    """A phase of a teleoperation session (it reports through the target's ``info``)."""

    def __init__(self, teleop: TeleopTarget) -> None:
        self.teleop = teleop


class Approach(TeleopPhase):
    """A joint-space move to the first pose of each hand's approach path, then the Cartesian
    paths, then a wait until the robot is still (or the approach's timeout)."""

    name = "approach"

    def run(self, t_s: float, state: RobotState) -> tuple[None, str | None]:
        return None, ("operate" if self.teleop.approach_step(t_s, state) else None)


class Operate(TeleopPhase):
    """The operator drives the hands; a replay that has ended hands over to ``settle`` in the
    same period. Entered after the approach, it runs from the next period."""

    name = "operate"
    runs_at_start = False

    def start(self, t_s: float, state: RobotState) -> None:
        self.teleop.start_operating(t_s)

    def run(self, t_s: float, state: RobotState) -> tuple[None, str | None]:
        teleop = self.teleop
        flags = teleop.operate_step(t_s, teleop.keys_now.clutch, teleop.keys_now.branch)
        if flags:
            teleop.info["flags"] = flags
        return None, ("settle" if teleop.source.done else None)


class Settle(TeleopPhase):
    """A replay has ended: the hands hold their last goals until the robot is still (at least
    ``settle_s``, at most four times that)."""

    name = "settle"

    def start(self, t_s: float, state: RobotState) -> None:
        self.teleop.t_settle_s = t_s

    def run(self, t_s: float, state: RobotState) -> tuple[None, str | None]:
        if self.teleop.settle_step(t_s, state):
            self.teleop.info["done"] = True
        return None, None
