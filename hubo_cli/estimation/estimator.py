"""The estimation pipeline: the observers in order, run once per period by the control loop."""

from __future__ import annotations

from collections.abc import Sequence

from hubo_cli.dataflow import Key, Store, check_flow
from hubo_cli.estimation.observer import Observer
from hubo_cli.state import RobotState


class Estimator:
    """Runs its observers in order on each new state, into one store.

    Args:
        observers: the ordered observers; their reads and writes are checked now
            (:class:`~hubo_cli.dataflow.FlowError` on a key read before it is written).

    Attributes:
        store: the run's per-period store (the estimate; modules add their keys to it).
    """

    def __init__(self, observers: Sequence[Observer]) -> None:
        self.observers = list(observers)
        check_flow(self.observers)
        self.store = Store()

    @property
    def writes(self) -> tuple[Key, ...]:
        """Every key the estimate provides."""
        return tuple(key for o in self.observers for key in o.writes)

    def reset(self, state: RobotState) -> Store:
        """Start from the first state; returns the store."""
        for observer in self.observers:
            observer.reset(state, self.store)
        return self.store

    def update(self, state: RobotState) -> Store:
        """This period's estimate from ``state``; returns the store."""
        for observer in self.observers:
            observer.update(state, self.store)
        return self.store
