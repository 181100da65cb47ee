"""The momentum strategy's start and profile (hubo_cli/walking/momentum.py), offline."""

from __future__ import annotations

import numpy as np

from hubo_cli.walking.momentum import (
    ACCELERATION_RAD_S2,
    DECIDE_S,
    SWING_HIP_ROLL_MAX_RAD,
    VELOCITY_RAD_S,
    MomentumStrategy,
)

DT = 0.005
LIMITS = ((-0.6, 0.0), (0.0, 0.6))  # the hip rolls' walking limits: abduction only


def _run(errors_m, pasts_m, support=(False, True)):
    """Offsets over the periods of a left stance (the right foot swinging) with the given
    capture-point errors (world y) and distances past the left sole's outer edge."""
    hips = MomentumStrategy((LIMITS[0][0], LIMITS[1][0]), (LIMITS[0][1], LIMITS[1][1]), DT)
    out = []
    for error, past in zip(errors_m, pasts_m, strict=True):
        out.append(hips.update(error, past, support, support, (-0.06, 0.05)).copy())
    return hips, np.array(out)


def test_a_push_rushing_at_the_edge_starts_it_on_a_ramp_within_the_limits():
    n = 200
    errors = np.r_[np.zeros(10), np.full(n - 10, 0.04)]  # a push toward the left (stance) side
    pasts = -0.08 + 0.5 * DT * np.maximum(np.arange(n) - 10, 0)  # 0.5 m/s at the edge
    hips, offsets = _run(errors, pasts)
    assert hips.started
    first = np.flatnonzero(np.any(offsets != 0.0, axis=1))[0]
    assert first >= 10 + round(DECIDE_S / DT)  # watched first
    speed = np.diff(offsets, axis=0) / DT
    assert np.all(np.abs(speed) <= VELOCITY_RAD_S + 1e-9)
    assert np.all(np.abs(np.diff(speed, axis=0)) / DT <= ACCELERATION_RAD_S2 + 1e-6)
    assert offsets[:, 1].max() > 0.2 and offsets[:, 1].min() >= 0.0  # the stance (left) abducts
    overshoot = ACCELERATION_RAD_S2 * DT ** 2  # (profile_step's last periods)
    assert offsets[:, 0].min() >= -(SWING_HIP_ROLL_MAX_RAD - 0.06) - overshoot  # the hand's cap
    assert offsets[:, 0].max() <= 0.0


def test_a_push_the_ankle_catches_or_a_rebound_step_does_not_start_it():
    n = 200
    errors = np.r_[np.zeros(10), np.full(n - 10, 0.04)]
    slow = -0.12 + 0.2 * DT * np.maximum(np.arange(n) - 10, 0)  # 0.6 s from the edge
    hips, offsets = _run(errors, slow)
    assert not hips.started and not np.any(offsets)
    rushing = -0.08 + 0.5 * DT * np.arange(n)
    hips, offsets = _run(np.full(n, 0.04), rushing)  # the step began with the error beyond
    assert not hips.started and not np.any(offsets)
