"""The balance modules' cost per 5 ms control period: every module of the pipeline that is not
the trajectory generator, a stopper, the collision detector or the limiter (so the
capture-point monitor, the balancer and whatever the balance pipeline adds), timed together in
the pipeline ``--balance default`` and ``--balance paper`` build, on the simulated robot
standing with the drill in its hand (real sensor readings: the feet loaded, the IMU).
Target: median <= 250 us. The whole pipeline is timed in the same periods, so the share holds
on a loaded machine."""

from __future__ import annotations

import time

import numpy as np

PERIODS = 1000
WARMUP = 100
OTHER_MODULES = {"otg", "hoff-arbib", "estop", "hard-estop", "collision", "limiter"}
TOOLS = {"right-arm": "drill", "left-arm": "hand"}


def _timed(model, choice: str) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray,
                                          np.ndarray]:
    """(per balance module its per-period wall time, per-period wall time of the balance
    modules and of the whole pipeline, and the balance modules' thread CPU time (s)) for
    ``--balance choice`` on the standing simulated robot."""
    from hubo_cli.control.module import Cycle
    from hubo_cli.control.pipeline import SafetyProfile
    from hubo_cli.drivers.sim import SimDriver
    from hubo_cli.estimation.build import build_estimator
    from hubo_cli.posture import home_posture

    dt = model.control_period_s
    q_home = home_posture(model)
    modules = SafetyProfile().with_balance(choice).build(model, dt, TOOLS)
    each = {m.name: np.zeros(PERIODS) for m in modules if m.name not in OTHER_MODULES}
    balance, total, cpu = np.zeros(PERIODS), np.zeros(PERIODS), np.zeros(PERIODS)
    clock, cpu_clock = time.perf_counter, time.thread_time
    estimator = build_estimator(model, TOOLS, dt)  # the estimate, timed in its own bench line
    with SimDriver(model, drill=True) as robot:
        state = robot.start(q_home)
        store = estimator.reset(state)
        for m in modules:
            m.reset(q_home.copy(), state, store)
        for k in range(PERIODS):
            cycle = Cycle(k * dt, dt, store=store)
            q = q_home
            for m in modules:
                c0, t0 = cpu_clock(), clock()
                q = m.update(q, state, cycle)
                spent, cpu_spent = clock() - t0, cpu_clock() - c0
                total[k] += spent
                if m.name in each:
                    each[m.name][k] = spent
                    balance[k] += spent
                    cpu[k] += cpu_spent
            robot.send(q)
            state = robot.step()
            estimator.update(state)
    each = {name: times[WARMUP:] for name, times in each.items()}
    return each, balance[WARMUP:], total[WARMUP:], cpu[WARMUP:]


def run(report) -> None:
    from hubo_cli.model import load_model

    model = load_model()
    for choice in ("default", "paper"):
        each, balance, total, cpu = _timed(model, choice)
        median = float(np.median(balance) * 1e6)
        report(f"balance modules per period, --balance {choice}, median", median, "us",
               "target <= 250 us: " + " + ".join(
                   f"{name} {np.median(times) * 1e6:.0f}" for name, times in each.items()))
        report("  the same on thread CPU time, median", float(np.median(cpu) * 1e6), "us",
               "without the time other processes held the core")
        report("  their share of the pipeline's time (same periods)",
               float(np.sum(balance) / np.sum(total) * 100), "%",
               f"pipeline median {np.median(total) * 1e6:.0f} us, "
               f"balance p99 {np.percentile(balance, 99) * 1e6:.0f} us")
