"""A standing period's cost as a multiple of the physics step: ``hubo sim`` (the default
balancer, the simulated robot standing, no push) run as fast as possible, each control period
timed whole (the target, the modules, the driver's send and step with its physics and sensors,
the estimation layer, the log row) against PyBullet's physics steps in the same periods, on
the thread's CPU time (the time other processes hold the core counts in neither) and on wall
time. Target (issue 33): no more physics steps a period than before the estimation layer
(docs/history/performance-latest-round.md)."""

from __future__ import annotations

import os
import tempfile
import time
from contextlib import contextmanager

import numpy as np

SECONDS = 4.0
RUNS = 3
WARMUP = 40  # periods


class _TimedPhysics:
    """The driver's PyBullet client, its ``stepSimulation`` timed (thread CPU and wall s)."""

    def __init__(self, client, spent: list[float]) -> None:
        self._client, self._spent = client, spent

    def stepSimulation(self, *args, **kwargs):  # noqa: N802 (PyBullet's name)
        cpu, wall = time.thread_time(), time.perf_counter()
        result = self._client.stepSimulation(*args, **kwargs)
        self._spent[0] += time.thread_time() - cpu
        self._spent[1] += time.perf_counter() - wall
        self._spent[2] += 1
        return result

    def __getattr__(self, name):
        return getattr(self._client, name)


@contextmanager
def _period_clock(marks: list[tuple[float, ...]]):
    """Each control period's start while the loop runs: (wall s, thread CPU s, then the
    physics steps' thread CPU s, wall s and count so far), from the loop's pacing call (a
    no-op as fast as possible)."""
    from hubo_cli.control.loop import ControlLoop

    pace = ControlLoop._pace
    spent = [0.0, 0.0, 0]

    def marked(loop, *args, **kwargs):
        driver = loop.driver
        if not isinstance(driver._p, _TimedPhysics):
            driver._p = _TimedPhysics(driver._p, spent)
        marks.append((time.perf_counter(), time.thread_time(), *spent))
        return pace(loop, *args, **kwargs)

    ControlLoop._pace = marked
    try:
        yield
    finally:
        ControlLoop._pace = pace


def _standing_run(model) -> dict[str, float]:
    """A standing run's medians per period: wall and thread CPU time, one physics step's."""
    from hubo_cli.experiments.standing import stand

    marks: list[tuple[float, ...]] = []
    with tempfile.TemporaryDirectory() as folder, _period_clock(marks):
        stand(model, duration_s=SECONDS, out=folder)
    d = np.diff(np.asarray(marks), axis=0)[WARMUP:]
    steps = d[:, 4]
    return {"wall_s": float(np.median(d[:, 0])), "cpu_s": float(np.median(d[:, 1])),
            "step_cpu_s": float(np.median(d[:, 2] / steps)),
            "step_wall_s": float(np.median(d[:, 3] / steps)),
            "cpu_ratio": float(np.median(d[:, 1] / d[:, 2] * steps)),
            "wall_ratio": float(np.median(d[:, 0] / d[:, 3] * steps))}


def run(report) -> None:
    from hubo_cli.model import load_model

    model = load_model()
    runs = [_standing_run(model) for _ in range(RUNS)]

    def median(name: str) -> float:
        return float(np.median([r[name] for r in runs]))

    cpu_ratios = [r["cpu_ratio"] for r in runs]
    report("standing period (hubo sim, default balancer), thread CPU, median",
           median("cpu_s") * 1e6, "us", f"wall {median('wall_s') * 1e6:.0f} us; load average "
           f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    report("  one physics step, thread CPU, median", median("step_cpu_s") * 1e6, "us",
           f"wall {median('step_wall_s') * 1e6:.0f} us; PyBullet's stepSimulation")
    report("standing period / physics step, thread CPU", median("cpu_ratio"), "x",
           f"median of {RUNS} runs ({min(cpu_ratios):.2f}-{max(cpu_ratios):.2f}); target: no "
           "more than before the estimation layer")
    report("  the same on wall time", median("wall_ratio"), "x")
