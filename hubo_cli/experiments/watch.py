"""What the experiments watch while they run, on the estimate: the torso's tilt and height,
the soles' lift,
and when the robot fell (:data:`hubo_cli.falls` criterion); the run ends
``STOP_AFTER_FALL_S`` after a fall. A sole corner rising more than ``TIP_LIFT_M`` off the
floor (the robot rocked onto its heels or onto one foot) counts as ``tipped``, even when the
robot comes back down."""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.control.target import Target
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import T_WORLD_SOLES, T_WORLD_TORSO
from hubo_cli.falls import has_fallen
from hubo_cli.geometry import tilt_rad_of_matrix
from hubo_cli.model import RobotModel
from hubo_cli.scene import SceneActions

TIP_LIFT_M = 0.02      # a sole corner this far above its start height: the robot tipped
STOP_AFTER_FALL_S = 0.5


class WatchedTarget(Target):
    """A target that watches the robot stand (:meth:`watch`, once a period) on the estimate:
    the largest tilt, the lowest torso height, the highest sole lift and the time of a fall.
    Subclasses that override :meth:`attach` call this one."""

    reads = (T_WORLD_TORSO, T_WORLD_SOLES)

    def __init__(self, model: RobotModel) -> None:
        self.max_tilt_deg = 0.0
        self.start_z_m: float | None = None
        self.t_fall_s: float | None = None
        self.min_z_m = math.inf
        self.lift_m = 0.0
        self.max_lift_m = 0.0
        self.store: Store | None = None
        self._corners = model.feet.sole_corners_m()
        self._sole_start_z: np.ndarray | None = None

    def attach(self, world: SceneActions | None, modules, store: Store) -> None:
        self.store = store

    def _sole_lift_m(self) -> float:
        """How far the highest sole corner has risen above its start height (m)."""
        z = np.concatenate([self._corners @ T[2, :3] + T[2, 3]
                            for T in self.store[T_WORLD_SOLES]])
        if self._sole_start_z is None:
            self._sole_start_z = z
        return float(np.max(z - self._sole_start_z))

    def watch(self, t_s: float, state) -> tuple[float, float]:
        """Update the watch with this period's estimate; returns the torso tilt (deg) and
        height (m)."""
        T = self.store[T_WORLD_TORSO]
        tilt_deg = math.degrees(tilt_rad_of_matrix(T[:3, :3]))
        z = float(T[2, 3])
        if self.start_z_m is None:
            self.start_z_m = z
        self.max_tilt_deg = max(self.max_tilt_deg, tilt_deg)
        self.min_z_m = min(self.min_z_m, z)
        self.lift_m = self._sole_lift_m()
        self.max_lift_m = max(self.max_lift_m, self.lift_m)
        if has_fallen(tilt_deg, self.start_z_m - z) and self.t_fall_s is None:
            self.t_fall_s = t_s
        return tilt_deg, z

    @property
    def fell(self) -> bool:
        return self.t_fall_s is not None

    @property
    def tipped(self) -> bool:
        return self.max_lift_m > TIP_LIFT_M

    def fall_done(self, t_s: float) -> bool:
        """Whether the run should end now: ``STOP_AFTER_FALL_S`` after a fall."""
        return self.t_fall_s is not None and t_s >= self.t_fall_s + STOP_AFTER_FALL_S
