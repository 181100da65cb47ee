"""tools/walk_disturbances.py's draw, outcomes and table (no physics: the walk's plan only)."""

from __future__ import annotations

import numpy as np
import pytest
from tool_support import load_tool

from hubo_cli.model import load_model
from hubo_cli.walking.footsteps import Footstep, Stance, plan_footsteps
from hubo_cli.walking.gait import make_gait
from hubo_cli.walking.params import walking_params

tool = load_tool("walk_disturbances")
DIRECTIONS = ["left", "right", "backward"]


def swing_span_s(model, distance_m: float, gait: str) -> tuple[float, float]:
    """From the plan's first lift-off to its last landing (s): its rows with one sole down."""
    params = walking_params(model.with_limits("walking"), gait)
    right = Footstep("right", 0.0, -params.step_width_m / 2, 0.0)
    left = Footstep("left", 0.0, params.step_width_m / 2, 0.0)
    steps = plan_footsteps(right, left, Stance(distance_m, 0.0, 0.0), params)
    plan = make_gait(right, left, steps, params, 0.005, 0.7)
    single = np.flatnonzero(~plan.support.all(axis=1))
    return single[0] * plan.period_s, (single[-1] + 1) * plan.period_s


@pytest.mark.parametrize(("distance_m", "gait"), [(1.0, "normal"), (2.0, "normal"),
                                                   (2.0, "fast")])
def test_the_moments_span_the_gaits_own_steps(distance_m, gait):
    # the fast gait's 12 steps end at 9.4 s; drawn over the normal gait's 16 (to 16.6 s), as
    # before --gait, 111 of these 200 moments came after the walk
    model = load_model()
    first_s, last_s = swing_span_s(model, distance_m, gait)
    moments = np.array([tool.draw(model, seed, distance_m, DIRECTIONS, gait)[0]
                        for seed in range(1, 201)])
    assert moments.min() >= first_s - 1e-9 and moments.max() <= last_s + 1e-9
    # uniform over the span: the first and last steps drawn as well (200 draws, 16 steps)
    step_s = (last_s - first_s) / 16
    assert moments.min() < first_s + step_s and moments.max() > last_s - step_s


def test_a_seed_draws_the_same_moment_as_the_history_tables():
    # docs/history/walking.md, "Stopping while walking": seeds 1, 6, 20 of the 1 m walk
    model = load_model()
    got = [tool.draw(model, seed, 1.0, DIRECTIONS) for seed in (1, 6, 20)]
    assert [round(at_s, 3) for at_s, _ in got] == [4.841, 5.044, 3.057]
    assert [direction for _, direction in got] == ["backward", "right", "left"]


def row(**changes) -> dict:
    base = {"seed": 3, "at_s": 1.5591, "phase": "step 0 swing", "direction": "left",
            "fell": False, "stopped_s": 1.8, "stood": True, "both_feet_down": True,
            "held": True, "max_torso_tilt_deg": 8.61, "end_max_tilt_deg": 0.071}
    return base | changes


@pytest.mark.parametrize(("changes", "outcome"), [
    ({}, tool.STANDING),
    ({"fell": True, "stood": False, "both_feet_down": False}, tool.FELL),
    ({"stopped_s": None}, tool.WALKED_ON),
    ({"held": False}, tool.STANDING),  # the walk stopped itself (2 m walk, pushed seed 4)
    ({"both_feet_down": False}, tool.STOPPED_OTHER),
    ({"stood": False}, tool.STOPPED_OTHER),
])
def test_a_runs_outcome(changes, outcome):
    assert tool.outcome_of(row(**changes)) == outcome


def test_the_table_has_a_line_per_run():
    rows = [row(outcome=tool.STANDING),
            row(seed=6, direction=None, stopped_s=None, outcome=tool.WALKED_ON)]
    lines = tool.table(rows).splitlines()
    assert len(lines) == 4
    assert lines[2] == ("| 3 | 1.559 | step 0 swing | left | standing in double support | 1.800 "
                        "| 8.6 | 0.07 |")
    assert lines[3].startswith("| 6 | 1.559 | step 0 swing | - | walked on | - |")
