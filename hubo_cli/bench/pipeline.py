"""One control period without physics: both arms' and both legs' IK, then the default pipeline
(ruckig on every joint, capture point, both emergency stoppers, ankle balance, collision,
limiter) and a send/step of the ideal driver. Target: median <= 300 us, p99 <= 1 ms (5x headroom
in the 5 ms period)."""

from __future__ import annotations

import os
import time

import numpy as np

from hubo_cli.control.log import PeriodLog
from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.drivers.registry import make_driver
from hubo_cli.estimation.build import build_estimator
from hubo_cli.kinematics import get_limb
from hubo_cli.model import ARMS, LEGS, load_model

PERIODS = 4000
WARMUP = 200


def _goals(limbs, q0, t_s):
    """End-effector goals (4x4, neck frame) at time t: hands on 5 cm circles in the sagittal
    plane (clear of the body), soles bobbing 1 cm."""
    goals = {}
    for name, limb in limbs.items():
        T = limb.fk(q0[name]).copy()
        if name in ARMS:
            phase = 2 * np.pi * 0.5 * t_s
            T[0, 3] += 0.05 * np.cos(phase)
            T[2, 3] += 0.05 * np.sin(phase)
        else:
            T[2, 3] += 0.01 * np.sin(2 * np.pi * 0.25 * t_s)
        goals[name] = T
    return goals


def run(report) -> None:
    model = load_model()
    dt = model.control_period_s
    driver = make_driver("ideal", model)
    state = driver.start()
    q0_all = state.q_rad.copy()
    limbs = {name: get_limb(name, "hand") for name in ARMS + LEGS}
    slices = {name: model.limb_slice(name) for name in limbs}
    q0 = {name: q0_all[slices[name]] for name in limbs}
    modules = build_pipeline(model)
    estimator = build_estimator(model, period_s=dt)  # the estimate: its own bench line
    store = estimator.reset(state)
    for m in modules:
        m.reset(q0_all.copy(), state, store)
    goal_sets = [_goals(limbs, q0, k * dt) for k in range(PERIODS)]
    q_prev = {name: q0[name].copy() for name in limbs}
    per_module = {m.name: [] for m in modules}
    ik_times, totals, cpu_totals = [], [], []
    clock = time.perf_counter
    cpu_clock = time.thread_time  # CPU time of this thread: excludes time other processes ran
    for k in range(PERIODS):
        cycle = Cycle(k * dt, dt, store=store)
        cpu_started = cpu_clock()
        started = clock()
        target = np.empty(len(q0_all))
        for name, limb in limbs.items():
            result = limb.solve(goal_sets[k][name], q_prev[name])
            q_prev[name] = result.q_rad
            target[slices[name]] = result.q_rad
        after_ik = clock()
        q = target
        for m in modules:
            t0 = clock()
            q = m.update(q, state, cycle)
            per_module[m.name].append(clock() - t0)
        driver.send(q)
        state = driver.step()
        estimator.update(state)
        totals.append(clock() - started)
        cpu_totals.append(cpu_clock() - cpu_started)
        ik_times.append(after_ik - started)

    def stats(values):
        us = np.asarray(values[WARMUP:]) * 1e6
        return float(np.median(us)), float(np.percentile(us, 99))

    median, p99 = stats(totals)
    report("pipeline period (4 IK + 7 modules + ideal driver), median", median, "us",
           "target <= 300 us")
    report("pipeline period, 99th percentile", p99, "us", "target <= 1000 us")
    cpu_median, cpu_p99 = stats(cpu_totals)
    load = os.getloadavg()[0]
    report("pipeline period CPU time (thread), median", cpu_median, "us",
           f"load average {load:.1f} on {os.cpu_count()} cores")
    report("pipeline period CPU time (thread), 99th percentile", cpu_p99, "us",
           "wall p99 minus time other processes held the core")
    report("  4 limb IK solves, median", stats(ik_times)[0], "us")
    for name, values in per_module.items():
        m_med, m_p99 = stats(values)
        report(f"  module {name}, median", m_med, "us", f"p99 {m_p99:.0f} us")

    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        log = PeriodLog(Path(tmp) / "log.csv", model.joint_names,
                        [c for m in modules for c in m.log_columns])
        times = []
        for _ in range(1000):
            t0 = clock()
            log.write(1, 0.1, 0, 100.0, 1.0, {"ok"}, q0_all, q0_all, q0_all, cycle.info)
            times.append(clock() - t0)
        log.close()
    report("log row (a record in the memory-mapped file), median",
           float(np.median(times) * 1e6), "us",
           f"{len(log.columns)} columns")
