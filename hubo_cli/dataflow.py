"""Declared data flow: typed keys of a per-period store, checked when a pipeline is built.

Every stage of a run's period (an observer of the estimation layer, a pipeline module, a target)
declares the keys it ``reads`` and ``writes``. :func:`check_flow` is called once, when the
stages are put in order: a key read before any stage writes it, or written by two stages, is a
build error (:class:`FlowError`), not a surprise in the middle of a run. During the run the
stages exchange values only through the :class:`Store`, never through each other's attributes,
and each stage sees the store through its own :class:`StoreView` (:meth:`Store.view`), which
refuses a key the stage did not declare: the declarations are what the stage really does.

A key carries its value's type, unit and frame in its name and documentation
(``com_world_m``: metres in the world frame), so that one place says what a value means.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

from hubo_cli.errors import ConfigError

T = TypeVar("T")


class FlowError(ConfigError):
    """A pipeline whose stages read a key nobody writes, or that two stages write."""


@dataclass(frozen=True, eq=False)
class Key(Generic[T]):
    """One quantity of the per-period store.

    Attributes:
        name: unique name, with frame and unit (``com_world_m``).
        kind: the Python type of its value (``float``, ``np.ndarray``, ``tuple``).
        doc: one line: what it is, in which frame and unit.
    """

    name: str
    kind: type
    doc: str

    def __repr__(self) -> str:
        return f"Key({self.name})"


def _written(values: dict, key: Key[T]) -> T:
    """``key``'s value in ``values``; FlowError when nothing has written it yet."""
    try:
        return values[key]
    except KeyError:
        raise FlowError(f"nothing has written {key.name} yet",
                        hint="declare a stage that writes it before the one that reads it"
                        ) from None


class Store:
    """The values of one run's keys: each stage writes its keys every period, later stages
    read them. Reading a key nobody has written yet raises :class:`FlowError`."""

    __slots__ = ("_values",)

    def __init__(self) -> None:
        self._values: dict[Key, object] = {}

    def __getitem__(self, key: Key[T]) -> T:
        return _written(self._values, key)

    def __setitem__(self, key: Key[T], value: T) -> None:
        self._values[key] = value

    def __contains__(self, key: Key) -> bool:
        return key in self._values

    def get(self, key: Key[T], default: T | None = None) -> T | None:
        """The key's value, or ``default`` when nothing has written it."""
        return self._values.get(key, default)  # type: ignore[return-value]

    def view(self, stage: Stage) -> StoreView:
        """This store as ``stage`` may use it: reading only the keys it declares it reads,
        follows or writes, writing only those it declares it writes."""
        return StoreView(self, stage)


class StoreView:
    """One stage's view of a :class:`Store`: the same values, but reading a key the stage did
    not declare (``reads``, ``follows``, ``previous``, ``writes``) or writing one it did not declare
    (``writes``) raises :class:`FlowError`. The declarations are taken when the view is made."""

    __slots__ = ("_values", "_readable", "_writable", "_name")

    def __init__(self, store: Store, stage: Stage) -> None:
        self._values = store._values
        self._name = stage.name
        self._writable = frozenset(stage.writes)
        self._readable = frozenset((*stage.reads, *stage.follows, *stage.previous)
                                   ) | self._writable

    def _refuse(self, verb: str, key: Key, declaration: str) -> FlowError:
        return FlowError(f"{self._name} {verb} {key.name}, which it does not declare",
                         hint=f"add it to the stage's {declaration}")

    def __getitem__(self, key: Key[T]) -> T:
        if key not in self._readable:
            raise self._refuse("reads", key, "reads (or follows)")
        return _written(self._values, key)

    def __setitem__(self, key: Key[T], value: T) -> None:
        if key not in self._writable:
            raise self._refuse("writes", key, "writes")
        self._values[key] = value

    def __contains__(self, key: Key) -> bool:
        if key not in self._readable:
            raise self._refuse("asks for", key, "reads (or follows)")
        return key in self._values

    def get(self, key: Key[T], default: T | None = None) -> T | None:
        """The key's value, or ``default`` when nothing has written it."""
        if key not in self._readable:
            raise self._refuse("reads", key, "follows (or reads)")
        return self._values.get(key, default)  # type: ignore[return-value]


class Stage(Protocol):
    """Anything that takes part in the flow: a name and the keys it reads and writes.

    ``follows``: keys it reads when some stage writes them and does without otherwise
    (``store.get(key, default)``), such as the support a walking phase plans for the
    capture-point monitor; a writer of one must still come before it.

    ``previous``: keys it reads as the previous period's value (``store.get(key, default)``),
    written by any stage, a later one too: a declared feedback, such as the stopper's mode a
    target reads before the stopper runs.
    """

    name: str
    reads: tuple[Key, ...]
    writes: tuple[Key, ...]
    follows: tuple[Key, ...]
    previous: tuple[Key, ...]


def check_flow(stages: Iterable[Stage], provided: Iterable[Key] = ()) -> None:
    """Check that every key a stage reads is written by an earlier stage (or ``provided``)
    and that no key has two writers.

    Raises:
        FlowError: naming the stage and the key.
    """
    stages = list(stages)
    writer: dict[Key, str] = {key: "the loop" for key in provided}
    later = {key: stage.name for stage in stages for key in stage.writes}
    for stage in stages:
        for key in stage.follows:
            if key not in writer and key in later:
                raise FlowError(f"{stage.name} follows {key.name}, which {later[key]} writes "
                                "after it", hint="put the stage that writes it first")
        for key in stage.reads:
            if key not in writer:
                raise FlowError(
                    f"{stage.name} reads {key.name}, which no earlier stage writes",
                    hint="add the stage that writes it, or put it before this one")
        for key in stage.writes:
            if key in writer:
                raise FlowError(f"{key.name} is written by both {writer[key]} and {stage.name}",
                                hint="one quantity has one producer")
            writer[key] = stage.name
