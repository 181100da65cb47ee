"""Simulation and driver figures: real-time factor of the PyBullet Hubo standing with every joint
commanded, the cost of one control period split into physics and the rest, the other drivers."""

from __future__ import annotations

import time

from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

SIM_SECONDS = 5.0


def _sim_figures(report, model) -> None:
    from hubo_cli.control.balance import AnkleBalancer
    from hubo_cli.control.module import Cycle
    from hubo_cli.drivers.sim import SimDriver

    q_home = home_posture(model)
    periods = int(SIM_SECONDS / model.control_period_s)
    t0 = time.perf_counter()
    robot = SimDriver(model)
    state = robot.start(q_home)
    report("sim: start (connect, load URDF, 0.3 s settle)", time.perf_counter() - t0, "s")
    physics0 = robot.physics_wall_s
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(periods):
        robot.send(q_home)  # all 24 joints commanded every period
        state = robot.step()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    physics = robot.physics_wall_s - physics0
    report("sim: real-time factor, standing, 24 joints commanded", SIM_SECONDS / wall, "x",
           "wall clock; target >= 3")
    report("sim: real-time factor on process CPU time", SIM_SECONDS / cpu, "x",
           "insensitive to other load on the machine")
    report("sim: one 5 ms control period", wall / periods * 1e3, "ms")
    report("sim:   physics (5 x 1 kHz stepSimulation)", physics / periods * 1e3, "ms",
           f"{100 * physics / wall:.0f} %")
    report("sim:   everything else (command, sensors, wrenches)", (wall - physics) / periods * 1e3,
           "ms")
    balancer = AnkleBalancer(model)
    balancer.reset(q_home, state)
    n = 2000
    t0 = time.perf_counter()
    for k in range(n):
        balancer.update(q_home, state, Cycle(k * model.control_period_s, model.control_period_s))
    report("balance module update", (time.perf_counter() - t0) / n * 1e6, "us")
    robot.close()


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
