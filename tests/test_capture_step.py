"""Stepping to catch a push (``hubo sim --push N --step``): one short pushed run on the
simulated robot with the ``walking`` limit set."""

import json

import pytest

from hubo_cli.experiments.standing import stand
from hubo_cli.model import load_model


@pytest.mark.slow
def test_a_75_n_push_is_caught_with_two_steps(tmp_path):
    """75 N forward for 0.2 s: the robot steps (once to catch, once to bring the other foot
    beside it) and stands; the limiter bounded every command by the walking limit set."""
    result = stand(load_model(), 3.0, 75.0, step=True, push_at_s=0.3, out=tmp_path / "run")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False
    assert summary["capture_step"]["stepped"] is True
    assert summary["capture_step"]["steps"] == 2
    step = summary["capture_step"]["footsteps"][0]
    assert step["x_m"] > 0.05  # the catching foot went the push's way
    assert summary["max_joint_velocity_ratio"] <= 1.0 + 1e-9


@pytest.mark.slow
def test_a_90_n_push_is_caught_by_a_long_step_and_a_swing_in(tmp_path):
    """90 N forward for 0.2 s (`hubo sim --push 90 --step --no-estop`): the first step is long
    (past the trailing foot's reach with the CoM over the landed sole), so the trailing foot
    swings in beside the landed one while the CoM comes to rest; two steps, no fall, the
    torso well away from the 30 degrees of a fall.

    Without the emergency stop: with it, the capture-point monitor may fire in the catch and
    the stop's revert then does not always hold the stepped stance, which fell 85 N and 92 N
    (and 90 N on one perturbation seed) that the stepping alone catches (84-100 N, seeds 1-3
    and 5: all caught, 2.4-8 degrees): whether it fires and holds is chaotic there, so it is
    no test (README)."""
    result = stand(load_model(), 5.0, 90.0, step=True, estop=False, out=tmp_path / "run")
    summary = json.loads((result.run_dir / "summary.json").read_text())
    assert result.fell is False
    assert summary["capture_step"]["steps"] == 2
    first = summary["capture_step"]["footsteps"][0]
    assert first["x_m"] > 0.15  # a long step (as landed): the swing-in path
    assert result.max_tilt_deg < 20.0
    assert summary["max_joint_velocity_ratio"] <= 1.0 + 1e-9
