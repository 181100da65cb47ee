"""The ImpedanceController (eq. 3) on both hands for one period: reading both wrist wrenches,
the force tracking of a reference force, the zero-order-hold update, the clamp and the
closed-form IK of each hand's offset pose.
Target (issue 36): <= 30 us per hand per period."""

from __future__ import annotations

import time

import numpy as np

from hubo_cli.control.impedance import ImpedanceController
from hubo_cli.control.module import Cycle
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

PERIODS = 4000
WARMUP = 200


def run(report) -> None:
    model = load_model()
    dt = model.control_period_s
    q = home_posture(model)
    q[[0, 3, 6, 9]] = -0.3, -1.2, -0.3, -1.2  # both hands forward, elbows bent
    ic = ImpedanceController(model, dt, tools={"right-arm": "drill"})  # the bit's force on one
    state = RobotState(0.0, q, np.zeros(len(q)))
    store = Store()
    store[WRENCHES] = {}
    ic.reset(q, state, store)
    for arm in ("right-arm", "left-arm"):  # pressing: the force tracking runs too
        ic.set_reference_wrench(arm, [-2.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    times = []
    clock = time.perf_counter
    for k in range(PERIODS):  # a few newtons and a tenth of a newton metre, turning
        phase = 2 * np.pi * 0.5 * k * dt
        wrench = np.array([3 * np.cos(phase), 3 * np.sin(phase), 2.0, 0.1, 0.1 * np.sin(phase),
                           0.05])
        store[WRENCHES] = {"right-wrist": wrench, "left-wrist": -wrench}
        cycle = Cycle(k * dt, dt, store=store)
        t0 = clock()
        ic.update(q, state, cycle)
        times.append(clock() - t0)
    us = np.asarray(times[WARMUP:]) * 1e6 / len(ic.hands)
    report("impedance controller per hand per period, median", float(np.median(us)), "us",
           "target <= 30 us")
    report("impedance controller per hand per period, 99th percentile",
           float(np.percentile(us, 99)), "us", f"{len(ic.hands)} hands, offsets nonzero")
