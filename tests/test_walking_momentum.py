"""The momentum strategy's start and profile (hubo_cli/walking/momentum.py), offline."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hubo_cli.walking.momentum import (
    ACCELERATION_RAD_S2,
    DECIDE_S,
    PAST_M,
    STANCE_DELAY_S,
    SWING_HIP_ROLL_MAX_RAD,
    VELOCITY_RAD_S,
    MomentumStrategy,
)

DT = 0.005
LIMITS = ((-0.6, 0.0), (0.0, 0.6))  # the hip rolls' walking limits: abduction only


def _run(errors_m, pasts_m, support=(False, True), phases=None):
    """Offsets over the periods of a left stance (the right foot swinging) with the given
    capture-point errors (world y) and distances past the left sole's outer edge (``support``
    one per period, or the same for all); each period's phase appended to ``phases``."""
    hips = MomentumStrategy((LIMITS[0][0], LIMITS[1][0]), (LIMITS[0][1], LIMITS[1][1]), DT)
    supports = support if isinstance(support, list) else [support] * len(errors_m)
    out = []
    for error, past, down in zip(errors_m, pasts_m, supports, strict=True):
        out.append(hips.update(error, past, down, down, (-0.06, 0.05)).copy())
        if phases is not None:
            phases.append(hips.phase)
    return hips, np.array(out)


def _runs(phases):
    """The phases in the order they came, each once per run of periods."""
    return [p for k, p in enumerate(phases) if k == 0 or p != phases[k - 1]]


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
    slow = np.minimum(slow, -0.005)  # (caught short of the edge)
    hips, offsets = _run(errors, slow)
    assert not hips.started and not np.any(offsets)
    rushing = -0.08 + 0.5 * DT * np.arange(n)
    hips, offsets = _run(np.full(n, 0.04), rushing)  # the step began with the error beyond
    assert not hips.started and not np.any(offsets)


def test_its_phases_arm_watch_act_return_and_end_once_per_walk():
    """A single support under the trigger arms it, the push past it is watched DECIDE_S, acts
    (the rush at the edge), returns once both soles are down and the offsets stand still, and
    is done: a second push in a later step starts nothing."""
    n = 200
    errors = np.r_[np.zeros(10), np.full(n - 10, 0.04), np.zeros(n), np.full(n, 0.04)]
    pasts = np.r_[-0.08 + 0.5 * DT * np.maximum(np.arange(n) - 10, 0), np.full(n, -0.1),
                  -0.08 + 0.5 * DT * np.arange(n)]
    support = [(False, True)] * n + [(True, True)] * n + [(True, False)] * n
    phases = []
    _, offsets = _run(errors, pasts, support, phases)
    assert _runs(phases) == ["armed", "watching", "acting", "returning", "done"]
    assert phases.index("acting") == 10 + round(DECIDE_S / DT)
    assert not np.any(offsets[-1])


def test_a_push_left_alone_passes_its_step_and_a_missing_estimate_rearms():
    """A push the ankle catches is passed until its single support ends, then a new step arms
    again; a watch losing the capture point's estimate goes back to armed."""
    n = 100
    slow = -0.12 + 0.2 * DT * np.maximum(np.arange(n) - 10, 0)  # 0.6 s from the edge
    errors = np.r_[np.zeros(10), np.full(n - 10, 0.04), np.zeros(5), np.zeros(5)]
    pasts = np.r_[slow, np.full(5, -0.1), np.full(5, -0.1)]
    support = [(False, True)] * n + [(True, True)] * 5 + [(True, False)] * 5
    phases = []
    _run(errors, pasts, support, phases)
    assert _runs(phases) == ["armed", "watching", "passed", "idle", "armed"]
    pasts = np.r_[np.full(10, -0.08), -0.07, math.nan, -0.06]
    phases = []
    _run(np.r_[np.zeros(10), np.full(3, 0.04)], pasts, phases=phases)
    assert _runs(phases) == ["armed", "watching", "armed", "watching"]


SEED18 = Path(__file__).parent / "data" / "momentum_push_seed18.csv"


def test_a_push_left_alone_that_goes_on_past_the_edge_starts_it_after_all():
    """Pushed seed 18's recorded capture point (main, 70 and 75 N): the watch passes both (30
    ms at about 0.3 m/s: 0.23 s from the edge); at 75 N it goes on 15 mm past the edge and the
    walk fell on main, at 70 N it turned back 5 mm inside and the walk stood. The strategy
    starts in the first once it is PAST_M past the edge, never in the second."""
    t_s, error_70, past_70, error_75, past_75 = np.loadtxt(SEED18, delimiter=",",
                                                           skiprows=5, unpack=True)
    phases = []
    hips, _ = _run(error_75 / 1000, past_75 / 1000, phases=phases)
    assert _runs(phases) == ["armed", "watching", "passed", "acting"]
    start = phases.index("acting")
    assert past_75[start] >= PAST_M * 1000 > past_75[start - 1]
    assert 0.3 < t_s[start] < 0.4  # (the push's start at 0)
    assert hips.goal_rad[1] > 0.2 and hips.goal_rad[0] < -0.2  # both hips, as a watched start
    phases = []
    hips, offsets = _run(error_70 / 1000, past_70 / 1000, phases=phases)
    assert _runs(phases) == ["armed", "watching", "passed"] and not np.any(offsets)


def test_a_late_start_holds_while_its_hips_pull_the_capture_point_in():
    """Started past the edge, the hips' own motion pulls the capture point in (it goes out again
    as they brake): its retreat counts only from their arrival, so it holds on, and hands back
    once both soles are down and in contact."""
    n = 300
    errors = np.r_[np.zeros(10), np.full(n - 10, 0.04)]
    past = np.r_[np.linspace(-0.10, -0.085, 16), np.linspace(-0.08, PAST_M + 0.005, 60),
                 np.linspace(PAST_M + 0.005, -0.05, 40), np.full(n - 116, -0.03)]
    support = [(False, True)] * 250 + [(True, True)] * 50
    phases = []
    _, offsets = _run(errors, past, support, phases)
    assert _runs(phases) == ["armed", "watching", "passed", "acting", "returning"]
    assert phases.index("returning") == 250  # (both soles down: it held till then)
    held = phases.index("acting") + round(STANCE_DELAY_S / DT) + 1  # (the stance hip's delay)
    assert np.all(offsets[held:250, 1] > 0.0)
