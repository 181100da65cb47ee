"""The swing foot kept over the floor while the body rolls over the stance sole's outer edge
(:mod:`hubo_cli.walking.floor_reach`): its geometry and when it acts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hubo_cli.walking.floor_reach import (
    REACH_DEAD_RAD,
    REACH_MAX_RAD,
    REACH_RATE_RAD_S,
    REACH_RETURN_RAD_S,
    REACH_STOP_RAD,
    FloorReach,
    _turn_about,
)

DT = 0.005
HALF_WIDTH_M = 0.065


def _sole(y_m: float) -> np.ndarray:
    """A flat sole 0.7 m below the torso, ``y_m`` to its left (the torso's frame)."""
    T = np.eye(4)
    T[:3, 3] = (0.0, y_m, -0.7)
    return T


@pytest.mark.parametrize("stance", [0, 1])
def test_the_turn_keeps_the_swing_sole_where_the_plan_has_it_over_the_floor(stance):
    """The body turned by the roll about the stance sole's outer edge (the robot on that edge),
    the swing sole's goal turned back by the reach lands where the plan put it in the world,
    flat; without the turn it hangs 40-50 mm higher and rolled with the body."""
    soles = np.stack([_sole(-0.12), _sole(0.12)])  # right, left
    swing = 1 - stance
    toward = 1.0 if stance == 0 else -1.0  # the roll that puts the stance side down
    roll = toward * 0.15
    reach = FloorReach(HALF_WIDTH_M, DT)
    for _ in range(200):  # swinging, the stance sole down
        reach.update(roll, (stance == 0, stance == 1), (stance == 0, stance == 1))
    assert reach.angle_rad[swing] == pytest.approx(roll - toward * REACH_DEAD_RAD)
    assert reach.angle_rad[stance] == 0.0
    # the body as the robot has it: turned by the turn taken about the stance sole's outer edge
    edge = soles[stance][:3, 3] + np.array((0.0, -toward * HALF_WIDTH_M, 0.0))
    T_world_neck = _turn_about(np.array((1.0, 0.0, 0.0)), float(reach.angle_rad[swing]), edge)
    planned = soles[swing]
    turned = reach.turns(soles)[swing] @ planned
    np.testing.assert_allclose(T_world_neck @ turned, planned, atol=1e-12)
    # the stance sole stands on its edge (its goal unchanged: the body turns about it)
    raised_m = (T_world_neck @ planned)[2, 3] - planned[2, 3]
    assert 0.030 < raised_m < 0.050


def test_it_acts_only_toward_the_stance_side_beyond_its_dead_band_and_at_its_rate():
    reach = FloorReach(HALF_WIDTH_M, DT)
    right_stance = ((True, False), (True, False))
    for roll in (-0.2, 0.5 * REACH_DEAD_RAD, math.nan):  # toward the swing side, small, unknown
        reach.update(roll, *right_stance)
        assert not np.any(reach.angle_rad)
    assert reach.turns(np.stack([_sole(-0.12), _sole(0.12)])) is None
    reach.update(1.0, *right_stance)
    assert reach.angle_rad[1] == pytest.approx(REACH_RATE_RAD_S * DT)
    for _ in range(400):
        reach.update(1.0, *right_stance)
    assert reach.angle_rad[1] == pytest.approx(REACH_MAX_RAD)
    assert reach.tipped and REACH_STOP_RAD < REACH_MAX_RAD


def test_a_landed_leg_gives_its_turn_back_and_an_unloaded_one_holds_it():
    reach = FloorReach(HALF_WIDTH_M, DT)
    reach.angle_rad[1] = 0.1
    reach.update(0.0, (True, True), (True, False))  # planned down, not yet in contact: holds
    assert reach.angle_rad[1] == 0.1
    reach.update(0.3, (True, True), (True, True))  # down and in contact: goes back
    assert reach.angle_rad[1] == pytest.approx(0.1 - REACH_RETURN_RAD_S * DT)
    reach.reset()
    assert not np.any(reach.angle_rad) and not reach.tipped


def test_the_right_legs_turn_stops_the_walk_past_its_bound_as_the_left_ones():
    """The right leg swinging over the left stance sole turns the other way (its angle < 0):
    beyond REACH_STOP_RAD it is tipped all the same, and an angle unknown (NaN) turns it."""
    reach = FloorReach(HALF_WIDTH_M, DT)
    left_stance = ((False, True), (False, True))
    soles = np.stack([_sole(-0.12), _sole(0.12)])
    while reach.angle_rad[0] >= -REACH_STOP_RAD:
        assert not reach.tipped
        reach.update(-1.0, *left_stance)
    assert reach.tipped and reach.turns(soles) is not None
    reach.reset()
    reach.angle_rad[0] = math.nan
    assert reach.turns(soles) is not None
