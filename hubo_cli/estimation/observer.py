"""The one small contract every observer of the estimation layer implements.

An observer reads the robot's sensors (:class:`~hubo_cli.state.RobotState`) and the keys
earlier observers wrote, and writes its own keys into the store, once per period. It declares
both (``reads``, ``writes``): the estimator checks the order when it is built.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from hubo_cli.dataflow import Key, Store
from hubo_cli.state import RobotState


class Observer(ABC):
    """One stage of the estimation layer.

    Attributes:
        name: the observer's name (in errors and the bench).
        reads: store keys it reads (written by earlier observers).
        follows: keys it reads when an earlier stage writes them (none so far).
        previous: keys it reads as the last period left them (written by a later stage;
            absent in the first period: ``store.get``).
        writes: store keys it writes every period, including the first.
    """

    name = "observer"
    reads: tuple[Key, ...] = ()
    writes: tuple[Key, ...] = ()
    follows: tuple[Key, ...] = ()
    previous: tuple[Key, ...] = ()

    def reset(self, state: RobotState, store: Store) -> None:
        """Start from the robot's first state: called before the first period (and again when
        the loop restarts); it must write its keys, as :meth:`update` does."""
        self.update(state, store)

    @abstractmethod
    def update(self, state: RobotState, store: Store) -> None:
        """Write this period's values of :attr:`writes` from the sensors and earlier keys."""
