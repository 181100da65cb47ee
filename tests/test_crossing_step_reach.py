"""tools/crossing_step_reach.py's pieces: the joints' least travel time, the time-optimal
speed profile and the capture point's margin inside the two soles' hull (synthetic inputs)."""

from __future__ import annotations

import math

import numpy as np
from tool_support import load_tool


def test_the_slowest_joint_sets_the_travel_time_and_the_profile_covers_its_distance():
    tool = load_tool("crossing_step_reach")
    v, a = np.full(2, 2.6), np.full(2, 150.0)
    # 1.4 rad of hip yaw: a ramp, a coast and a brake; 0.01 rad: a triangle
    assert math.isclose(tool.travel_time_s(np.array((1.4, -0.01)), v, a), 1.4 / 2.6 + 2.6 / 150)
    assert math.isclose(tool.travel_time_s(np.array((0.01, 0.0)), v, a), 2 * math.sqrt(0.01 / 150))
    du = 1e-5
    u = np.arange(0.0, 1.0, du)
    for distance in (1.4, -0.3, 0.01):
        speed = tool.profile_speed(distance, 2.6, 150.0, u)
        assert math.isclose(float(np.sum(speed) * du), distance, rel_tol=1e-3)
        assert np.all(np.abs(speed) <= 2.6 + 1e-12)


def test_the_hull_margin_is_the_distance_inside_and_negative_outside():
    tool = load_tool("crossing_step_reach")
    square = np.array(((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5)))
    assert math.isclose(tool.hull_margin_m(square, np.array((0.5, 0.5))), 0.5)
    assert math.isclose(tool.hull_margin_m(square, np.array((0.9, 0.5))), 0.1)
    assert math.isclose(tool.hull_margin_m(square, np.array((1.2, 0.5))), -0.2)
