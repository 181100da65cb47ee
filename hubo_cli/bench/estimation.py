"""The estimation layer (hubo_cli/estimation/build.py, the drill held) for one period: the
attitude, the compensated wrenches, contact, floating base and soles, CoM with the capture
point and the ZMP, on states recorded from the simulated robot standing and pushed.
Target (issue 33): <= 100 us median per period."""

from __future__ import annotations

import os
import time

import numpy as np

from hubo_cli.drivers.sim import SimDriver
from hubo_cli.estimation.build import build_estimator
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

STATES = 400
ROUNDS = 10
WARMUP = 200


def run(report) -> None:
    model = load_model()
    dt = model.control_period_s
    tools = {"right-arm": "drill"}
    with SimDriver(model, drill=True) as sim:
        states = [sim.start()]
        for k in range(STATES):
            if k == 100:
                sim.push_torso([60.0, 0.0, 0.0], 0.1)
            sim.send(home_posture(model))
            states.append(sim.step())
    estimator = build_estimator(model, tools, dt)
    estimator.reset(states[0])
    clock, cpu_clock = time.perf_counter, time.thread_time
    whole, cpu, parts = [], [], {o.name: [] for o in estimator.observers}
    for _ in range(ROUNDS):
        for state in states[1:]:
            c0, t0 = cpu_clock(), clock()
            estimator.update(state)
            whole.append(clock() - t0)
            cpu.append(cpu_clock() - c0)
    for _ in range(2):  # each observer alone, in order, on the same states
        for state in states[1:]:
            for observer in estimator.observers:
                t0 = clock()
                observer.update(state, estimator.store)
                parts[observer.name].append(clock() - t0)
    us = np.asarray(whole[WARMUP:]) * 1e6
    report("estimation layer per period, median", float(np.median(us)), "us",
           f"target <= 100 us; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    report("  the same on thread CPU time, median", float(np.median(cpu[WARMUP:]) * 1e6), "us",
           "without the time other processes held the core")
    report("estimation layer per period, 99th percentile", float(np.percentile(us, 99)), "us",
           f"{len(estimator.observers)} observers, drill held")
    for name, times in parts.items():
        report(f"  {name}, median", float(np.median(times[WARMUP:]) * 1e6), "us")
