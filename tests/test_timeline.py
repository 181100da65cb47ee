"""The time-ordered release shared by recordings and generated input streams."""

from __future__ import annotations

import numpy as np

from hubo_cli.timeline import Timeline


def test_items_come_in_time_order_once_each_up_to_the_clock():
    rng = np.random.default_rng(3)
    times = rng.uniform(0.0, 10.0, 200).round(1)  # ties included
    items = [(float(t), k) for k, t in enumerate(times)]
    line = Timeline(items, lambda item: item[0])
    assert (line.start_s, line.end_s) == (min(times), max(times))
    assert line.now_s() == line.start_s and not line.done
    taken = []
    for clock in np.arange(-1.0, 11.0, 0.37):
        batch = line.take_until(clock)
        assert all(t <= clock for t, _ in batch)
        taken += batch
    assert line.done and line.take_until(99.0) == [] and line.now_s() == 99.0
    # every item once, by time, and items of the same time in their given order
    assert taken == sorted(items, key=lambda item: item[0])
    line.rewind()
    assert not line.done and line.take_until(99.0) == taken


def test_an_empty_timeline_is_done_at_zero():
    line = Timeline([], float)
    assert line.done and line.start_s == line.end_s == line.recorded_s == 0.0
    assert line.take_until(5.0) == []
