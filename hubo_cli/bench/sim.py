"""Simulation and driver figures: real-time factor of the PyBullet Hubo standing with every joint
commanded, at the former 1 kHz physics and at the default 400 Hz one in the same run (so the
ratio holds on a loaded machine), on process CPU time as well as wall time; the cost of one
control period split into physics and the rest; the other drivers."""

from __future__ import annotations

import time

from hubo_cli.estimation.build import build_estimator
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

SIM_SECONDS = 5.0


def _standing(model, physics: dict) -> dict:
    """Stand ``SIM_SECONDS`` with every joint commanded; wall and CPU time (s), physics share."""
    from hubo_cli.drivers.sim import SimDriver

    q_home = home_posture(model)
    periods = int(SIM_SECONDS / model.control_period_s)
    with SimDriver(model, **physics) as robot:
        robot.start(q_home)
        physics0 = robot.physics_wall_s
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for _ in range(periods):
            robot.send(q_home)  # all 24 joints commanded every period
            robot.step()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        return {"wall_s": wall, "cpu_s": cpu, "physics_s": robot.physics_wall_s - physics0,
                "periods": periods, "substeps": robot.substeps}


def _sim_figures(report, model) -> None:
    from hubo_cli.control.balance import make_balancer
    from hubo_cli.control.module import Cycle
    from hubo_cli.drivers.sim import FAST_PHYSICS, LEGACY_PHYSICS, SimDriver

    t0 = time.perf_counter()
    with SimDriver(model) as robot:
        state = robot.start(home_posture(model))
    report("sim: start (connect, load URDF, 0.3 s settle)", time.perf_counter() - t0, "s")
    runs = {"1 kHz (before)": _standing(model, LEGACY_PHYSICS),
            "400 Hz (default)": _standing(model, FAST_PHYSICS)}
    for label, r in runs.items():
        report(f"sim {label}: real-time factor standing, CPU time", SIM_SECONDS / r["cpu_s"], "x",
               "process CPU time: insensitive to other load")
        report(f"sim {label}: real-time factor standing, wall", SIM_SECONDS / r["wall_s"], "x")
        period_ms = r["wall_s"] / r["periods"] * 1e3
        physics_ms = r["physics_s"] / r["periods"] * 1e3
        report(f"sim {label}:   one 5 ms period (wall)", period_ms, "ms",
               f"physics ({r['substeps']} steps) {physics_ms:.2f} ms, "
               f"{100 * physics_ms / period_ms:.0f} %")
    old, new = runs.values()
    report("sim: speed-up of the default physics (CPU time)", old["cpu_s"] / new["cpu_s"], "x",
           "target: standing >= 5x real time")
    q_home = home_posture(model)
    for mode in ("default", "paper"):
        balancer = make_balancer(model, mode)
        store = build_estimator(model).reset(state)  # the estimate of the last state
        balancer.reset(q_home, state, store)
        n = 2000
        t0 = time.perf_counter()
        for k in range(n):
            balancer.update(q_home, state, Cycle(k * model.control_period_s,
                                                 model.control_period_s, store=store))
        report(f"balance module update ({mode})", (time.perf_counter() - t0) / n * 1e6, "us",
               "target <= 250 us")


def _driver_period(report, model, name: str, **options) -> None:
    from hubo_cli.drivers.registry import make_driver

    q = home_posture(model)
    with make_driver(name, model, **options) as robot:
        robot.start(q)
        n = 2000
        t0 = time.perf_counter()
        for _ in range(n):
            robot.send(q)
            robot.step()
        report(f"{name} driver: send + step", (time.perf_counter() - t0) / n * 1e6, "us")


def run(report) -> None:
    """Print the simulation and driver figures."""
    import tempfile

    model = load_model()
    _sim_figures(report, model)
    _driver_period(report, model, "ideal")
    with tempfile.TemporaryDirectory() as folder:
        _driver_period(report, model, "hardware", armed=True, sink="file",
                       sink_path=f"{folder}/hubo-ref.bin")
