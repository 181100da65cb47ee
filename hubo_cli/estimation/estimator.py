"""The estimation pipeline: the observers in order, run once per period by the control loop."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hubo_cli.dataflow import FlowError, Key, Store, check_flow
from hubo_cli.estimation.keys import COM_WORLD, QUAT_WORLD_TORSO, T_WORLD_TORSO
from hubo_cli.estimation.observer import Observer
from hubo_cli.geometry import tilt_rad_of_quat_wxyz
from hubo_cli.state import RobotState

LOG_COLUMNS = {T_WORLD_TORSO: ("est_torso_x_m", "est_torso_y_m", "est_torso_z_m",
                               "est_torso_yaw_rad"),
               QUAT_WORLD_TORSO: ("est_tilt_rad",),
               COM_WORLD: ("est_com_x_m", "est_com_y_m", "est_com_z_m")}


class Estimator:
    """Runs its observers in order on each new state, into one store.

    Args:
        observers: the ordered observers; their reads and writes are checked now
            (:class:`~hubo_cli.dataflow.FlowError` on a key read before it is written, or
            read from the last period and written by none).

    Attributes:
        store: the run's per-period store (the estimate; modules add their keys to it).
    """

    def __init__(self, observers: Sequence[Observer]) -> None:
        self.observers = list(observers)
        check_flow(self.observers)
        written = {key for o in self.observers for key in o.writes}
        for observer in self.observers:
            for key in observer.previous:  # read as the last period left it
                if key not in written:
                    raise FlowError(f"{observer.name} reads the last period's {key.name}, which "
                                    "no observer writes", hint="add the observer that writes it")
        self.store = Store()
        self._views = [self.store.view(o) for o in self.observers]  # each its declared keys

    @property
    def log_columns(self) -> tuple[str, ...]:
        """The estimate's log columns (beside the simulator's truth, for reports): the torso's
        position, heading (yaw) and tilt from upright, the CoM; those of keys an observer writes."""
        written = set(self.writes)
        return tuple(column for key, columns in LOG_COLUMNS.items() if key in written
                     for column in columns)

    def log_values(self) -> dict[str, float]:
        """This period's :attr:`log_columns` (NaN where a key is not written yet)."""
        store, values = self.store, {}
        T = store.get(T_WORLD_TORSO)
        if T is not None:
            T = np.asarray(T, dtype=float)
            values.update(zip(LOG_COLUMNS[T_WORLD_TORSO],
                              (*T[:3, 3].tolist(), math.atan2(T[1, 0], T[0, 0])), strict=True))
        quat = store.get(QUAT_WORLD_TORSO)
        if quat is not None:
            values["est_tilt_rad"] = float(tilt_rad_of_quat_wxyz(np.asarray(quat, dtype=float)))
        com = store.get(COM_WORLD)
        if com is not None:
            values.update(zip(LOG_COLUMNS[COM_WORLD], np.asarray(com, dtype=float).tolist(),
                              strict=True))
        return values

    @property
    def writes(self) -> tuple[Key, ...]:
        """Every key the estimate provides."""
        return tuple(key for o in self.observers for key in o.writes)

    def reset(self, state: RobotState) -> Store:
        """Start from the first state; returns the store."""
        for observer, view in zip(self.observers, self._views, strict=True):
            observer.reset(state, view)
        return self.store

    def update(self, state: RobotState) -> Store:
        """This period's estimate from ``state``; returns the store."""
        for observer, view in zip(self.observers, self._views, strict=True):
            observer.update(state, view)
        return self.store
