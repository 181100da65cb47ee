"""The Stabilizer's force-moment distribution (eq. 9-14, a 12-variable QP in double support,
6 in single) for one period: the demand made feasible, the QP built (compiled) and solved by
daqp, the feet's wrenches read back; the ZMP sweeping the support polygon as in a walk, with a
horizontal force. Also the LIP state feedback (eq. 8). Target (issue 37): the QP <= 100 us
median per period."""

from __future__ import annotations

import time

import numpy as np

from hubo_cli.control.lip_feedback import LipFeedback
from hubo_cli.control.wrench_distribution import Contact, WrenchDistributor
from hubo_cli.model import load_model

PERIODS = 4000
WARMUP = 200


def _timed(call, periods: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock and CPU (this thread's) time of each call (us), after the warm-up."""
    clock, cpu_clock = time.perf_counter, time.thread_time
    wall, cpu = np.empty(periods), np.empty(periods)
    for k in range(periods):
        t0, c0 = clock(), cpu_clock()
        call(k)
        cpu[k] = cpu_clock() - c0
        wall[k] = clock() - t0
    return wall[WARMUP:] * 1e6, cpu[WARMUP:] * 1e6


def run(report) -> None:
    model = load_model()
    distributor = WrenchDistributor.from_model(model)
    right, left = Contact((0.0, -0.12), -0.05), Contact((0.1, 0.12), 0.1)
    weight_n = 380.0

    def demand(k):
        phase = 2 * np.pi * k / 800  # the ZMP from foot to foot and beyond the soles' edges
        zmp = (0.05 + 0.12 * np.sin(0.5 * phase), 0.16 * np.sin(phase))
        return (20 * np.cos(phase), 10 * np.sin(phase), weight_n), zmp

    demands = [demand(k) for k in range(PERIODS)]
    double, double_cpu = _timed(lambda k: distributor.distribute(*demands[k], right, left),
                                PERIODS)
    single, _ = _timed(lambda k: distributor.distribute(*demands[k], right, None), PERIODS)
    report("wrench distribution QP, double support (12 variables), median", float(np.median(
        double)), "us", "target <= 100 us")
    report("  99th percentile", float(np.percentile(double, 99)), "us",
           f"{PERIODS - WARMUP} periods, ZMP in and out of the polygon")
    report("  99th percentile of CPU time", float(np.percentile(double_cpu, 99)), "us",
           "the wall-clock one less the process's preemption")
    report("wrench distribution QP, single support (6 variables), median",
           float(np.median(single)), "us", "")
    feedback = LipFeedback.from_model(model, 0.7)
    lip, _ = _timed(lambda k: feedback.zmp_command((0.0, 0.0), (0.0, 0.0), (0.0, 0.0),
                                                (0.01, 0.0), (0.0, 0.02), (0.0, 0.0)), PERIODS)
    report("LIP state feedback (eq. 8), median", float(np.median(lip)), "us", "")
