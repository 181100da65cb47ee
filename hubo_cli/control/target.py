"""Where the loop's joint targets come from: a task's plan, an operator's stream, a standing
posture. Every source is a :class:`Target`; its optional hooks are declared here."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from hubo_cli.dataflow import Key, Store
from hubo_cli.state import RobotState

if TYPE_CHECKING:
    from hubo_cli.control.module import Module
    from hubo_cli.scene import SceneActions

TargetOutput = tuple[np.ndarray | None, dict]


class Target(ABC):
    """The loop asks it once per period for the joint target (see :mod:`control.loop`).

    Attributes:
        log_columns: the numeric ``info`` keys it returns that go into the log.
        robot_flags: the flags of the robot's latest state (set by the loop every period;
            the live view shows the driver's, e.g. ``stale-state``).
        name: the target's name in flow errors.
        reads, writes, follows, previous: the store keys it reads (the estimate's), writes
            (for the modules, e.g. hand wrench references), reads when written (checked when
            the loop is built) and reads as the previous period's (a module's, e.g. the
            stopper's mode).
        store: the run's per-period store, given in :meth:`attach` (a target reads and writes
            only the keys it declares).
    """

    name = "target"
    store: Store | None = None
    log_columns: tuple[str, ...] = ()
    reads: tuple[Key, ...] = ()
    writes: tuple[Key, ...] = ()
    follows: tuple[Key, ...] = ()
    previous: tuple[Key, ...] = ()
    robot_flags: tuple[str, ...] = ()

    @abstractmethod
    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        """The joint target for the period starting at ``t_s`` (rad; None = hold) and info."""

    def attach(self, world: SceneActions | None, modules: Sequence[Module],
               store: Store) -> None:
        """Called once the robot has started, before the first period: the simulator's scene
        actions (to place a scene, to push, to grip; None on a real robot; nothing to read), the
        pipeline that will run (to watch a stopper) and the run's store (the estimate: the
        keys in :attr:`reads`, read each period)."""


class FunctionTarget(Target):
    """A plain function ``f(t_s, state) -> (q | None, info)`` as a target."""

    def __init__(self, function: Callable[[float, RobotState], TargetOutput],
                 log_columns: tuple[str, ...] = ()) -> None:
        self.function = function
        self.log_columns = tuple(log_columns)

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        return self.function(t_s, state)


def as_target(source: Target | Callable[[float, RobotState], TargetOutput]) -> Target:
    """``source`` itself, or a plain function wrapped as a :class:`Target`."""
    return source if isinstance(source, Target) else FunctionTarget(source)
