"""The measuring tools of the hardware runs: a run's best-fit delay (tools/ref_lag.py) and the
hole a run cut through the simulated daemon (tools/daemon_hole.py), on synthetic data whose
answers are known."""

from __future__ import annotations

import numpy as np
import pytest
from tool_support import load_tool

from hubo_cli.tasks.phases import PHASES


@pytest.mark.parametrize("delay_s", [0.0, 0.0015, 0.0425, 0.197])
def test_the_best_fit_delay_finds_a_known_one(delay_s):
    rng = np.random.default_rng(int(delay_s * 1e4))
    t = np.arange(0, 6, 0.005)
    cmd = np.column_stack([np.sin(w * t + p) for w, p in rng.uniform(0.5, 4, size=(3, 2))])
    q = np.column_stack([np.interp(t - delay_s, t, c) for c in cmd.T])
    found, rms, largest = load_tool("ref_lag").best_delay(t, cmd, q, 0.3, 0.0005)
    assert found == pytest.approx(delay_s, abs=0.0005) and rms < 1e-3 and largest < 5e-3


def test_the_hole_is_the_true_bit_against_the_commanded_one_from_the_run_phase():
    """A bit that stood 0.3 m off the commanded point when the run began and then followed it
    with a constant 2 mm sideways error: a 2 mm hole, whatever the offset and the frames'
    clocks' rows in between."""
    rng = np.random.default_rng(3)
    n = 400
    state_t = 100.0 + 0.005 * np.arange(n)
    goal = np.column_stack([np.full(n, 0.4), 0.05 * np.sin(np.arange(n) / 40),
                            0.02 * np.arange(n) / n])
    phase = np.where(np.arange(n) < 50, PHASES.index("raise"), PHASES.index("run"))
    cutting = (np.arange(n) >= 80).astype(float)
    bit = goal + np.array([0.3, -0.1, 0.05])
    bit[50:, 1] += 0.002
    bit[50, 1] -= 0.002  # at the run's start the bit stood exactly at its offset
    # the daemon's track: every state published, a few more than the run read
    track_t = np.sort(np.concatenate([state_t, state_t[:-1] + 0.0025]))
    track = np.column_stack([track_t, *[np.interp(track_t, state_t, b) for b in bit.T]])
    log = {"hw_state_time_s": state_t + rng.uniform(-2e-5, 2e-5, n), "goal_x_m": goal[:, 0],
           "goal_y_m": goal[:, 1], "goal_z_m": goal[:, 2], "phase_code": phase,
           "cutting": cutting}
    rms, periods, gap = load_tool("daemon_hole").hole_rms_mm(log, track)
    assert rms == pytest.approx(2.0, abs=1e-6) and periods == n - 80 and gap < 3e-5
