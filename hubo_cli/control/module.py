"""The one small interface every pipeline module implements.

Each control period the loop calls ``update`` on every module in order; a module takes the
command (joint positions, rad, ``RobotModel.joint_names`` order) and the latest robot state,
and returns the command it passes on. It reports what it did by adding flags to the shared
:class:`Cycle` (e.g. ``"joint-limit"``, ``"estop"``) and may request an emergency stop through
``cycle.estop_requests``. Modules can be added, removed or reordered without touching others.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.drivers.base import RobotState


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
    """

    t_s: float
    dt_s: float
    flags: set[str] = field(default_factory=set)
    estop_requests: set[str] = field(default_factory=set)
    info: dict[str, float] = field(default_factory=dict)


class Module(ABC):
    """One stage of the pipeline."""

    name = "module"

    def reset(self, q_rad: np.ndarray, state: RobotState) -> None:
        """Start from the command ``q_rad`` (rad) and the robot's state; called once before the
        first period and again whenever the loop restarts."""

    @abstractmethod
    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        """Return the command passed on this period (rad), never NaN."""
