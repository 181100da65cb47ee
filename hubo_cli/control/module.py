"""The one small interface every pipeline module implements.

Each control period the loop calls ``update`` on every module in order; a module takes the
command (joint positions, rad, ``RobotModel.joint_names`` order) and the latest robot state,
and returns the command it passes on. It reports what it did by adding flags to the shared
:class:`Cycle` (e.g. ``"joint-limit"``, ``"estop"``) and may request an emergency stop through
``cycle.estop_requests``. Modules can be added, removed or reordered without touching others.

Optional behaviour is declared here with defaults, never probed: ``log_columns`` (the
``cycle.info`` keys a module writes, logged every period), ``events`` (the safety events it
recorded), ``status()`` (a small snapshot a viewer shows), ``release()`` (let go of a latched
stop), ``dt_s`` (the control period the module was built for; the loop refuses a module built
for another period than its driver's) and ``reads``/``writes`` (the store keys it exchanges
with the estimate and the other modules: a module never reads another's attributes).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.control.status import SafetyEvent
from hubo_cli.dataflow import Key, Store
from hubo_cli.state import RobotState


@dataclass
class Cycle:
    """Shared facts of one control period.

    Attributes:
        t_s: loop time at the start of the period (s).
        dt_s: the control period (s), 0.005 at 200 Hz.
        flags: what the modules did this period (strings, see each module).
        estop_requests: sources asking for an emergency stop this period (e.g. ``"operator"``,
            ``"capture-point"``, ``"wrist-torque"``, ``"stale-input"``).
        info: per-module numbers worth logging (name -> float).
        store: the run's per-period store: the estimate and what earlier modules wrote (see
            :mod:`hubo_cli.dataflow`; a module reads only the keys it declares).
    """

    t_s: float
    dt_s: float
    flags: set[str] = field(default_factory=set)
    estop_requests: set[str] = field(default_factory=set)
    info: dict[str, float] = field(default_factory=dict)
    store: Store = field(default_factory=Store)


class Module(ABC):
    """One stage of the pipeline.

    Attributes:
        name: the module's pipeline name.
        dt_s: the control period (s) the module was built for; None when it takes the period
            from each :class:`Cycle`.
        log_columns: every ``cycle.info`` key the module writes (logged each period).
        events: safety events the module recorded (stops, releases, collision holds).
        reads, writes: the store keys it reads and writes (checked when the loop is built);
            follows: keys it reads when a stage writes them; previous: keys it reads as the
            previous period's (:class:`~hubo_cli.dataflow.Stage`).
    """

    name = "module"
    reads: tuple[Key, ...] = ()
    writes: tuple[Key, ...] = ()
    follows: tuple[Key, ...] = ()
    previous: tuple[Key, ...] = ()
    dt_s: float | None = None
    log_columns: tuple[str, ...] = ()
    events: Sequence[SafetyEvent] = ()

    def status(self) -> object | None:
        """A small snapshot of the module's state for a viewer (the safety view): a
        dataclass of :mod:`hubo_cli.control.status` (``StopperStatus``, ``CollisionStatus``,
        ``SupportStatus``, ``LimiterStatus``), or None for a module with nothing to show."""
        return None

    def release(self) -> None:
        """Let go of a latched emergency stop; modules without one ignore it."""

    def reset(self, q_rad: np.ndarray, state: RobotState, store: Store) -> None:
        """Start from the command ``q_rad`` (rad), the robot's state and the run's store (the
        first estimate written); called once before the first period and again whenever the
        loop restarts."""

    @abstractmethod
    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        """Return the command passed on this period (rad), never NaN."""
