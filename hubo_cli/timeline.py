"""Items stamped with times, released in time order by the caller's clock: a recording's
samples or a generated stream's poses, replayed as the control loop's time advances."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

import numpy as np

T = TypeVar("T")


class Timeline(Generic[T]):
    """``items`` sorted by ``time_s(item)`` (stably), handed out up to a time, once each.

    Attributes:
        items: every item in time order.
    """

    def __init__(self, items: Sequence[T], time_s: Callable[[T], float]) -> None:
        times = np.array([time_s(item) for item in items], dtype=np.float64)
        order = np.argsort(times, kind="stable")
        self.items: list[T] = [items[i] for i in order]
        self._times = times[order]
        self.rewind()

    @property
    def start_s(self) -> float:
        """Time of the first item (s); 0 without any."""
        return float(self._times[0]) if self._times.size else 0.0

    @property
    def end_s(self) -> float:
        """Time of the last item (s); 0 without any."""
        return float(self._times[-1]) if self._times.size else 0.0

    @property
    def recorded_s(self) -> float:
        """From the first item to the last (s)."""
        return self.end_s - self.start_s

    @property
    def done(self) -> bool:
        """Every item has been handed out."""
        return self._cursor >= len(self.items)

    def take_until(self, t_s: float) -> list[T]:
        """Every item not yet handed out with time <= ``t_s`` (s)."""
        self._now = max(self._now, float(t_s))
        end = int(self._times.searchsorted(t_s, side="right"))  # np.searchsorted's, unwrapped
        if end <= self._cursor:
            return []
        out = self.items[self._cursor:end]
        self._cursor = end
        return out

    def now_s(self) -> float:
        """The latest time asked for (before any: the first item's)."""
        return self._now if self._now != -math.inf else self.start_s

    def rewind(self) -> None:
        """Hand out from the first item again."""
        self._cursor = 0
        self._now = -math.inf


class OnTimeline:
    """What a source that releases a :class:`Timeline` (``self._timeline``) by the caller's
    clock tells of it: first and last times, span, whether all is out, and its clock."""

    _timeline: Timeline

    @property
    def start_s(self) -> float:
        """Time of the first item (s)."""
        return self._timeline.start_s

    @property
    def end_s(self) -> float:
        """Time of the last item (s)."""
        return self._timeline.end_s

    @property
    def done(self) -> bool:
        """True once every item has been released."""
        return self._timeline.done

    @property
    def recorded_s(self) -> float:
        """From the first item to the last (s)."""
        return self._timeline.recorded_s

    def now_s(self) -> float:
        """The latest time released up to (before any: the first item's)."""
        return self._timeline.now_s()
