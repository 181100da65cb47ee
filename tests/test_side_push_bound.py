"""tools/side_push_bound.py's tighter bound: the braked joint motion's weight and the room a
joint has before the links come within the collision detector's band (synthetic inputs)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from tool_support import load_tool


def test_braking_weighs_less_than_the_unbraked_bound_and_matches_its_closed_form():
    tool = load_tool("side_push_bound")
    omega, v, a = 4.0, 2.6, 150.0
    for range_rad in (0.3, 0.54):  # (below about 0.1 rad the two differ by under 0.2 %)
        braked = tool.braked_travel_integral(range_rad, v, a, omega)
        assert 0.0 < braked < tool.best_travel_integral(range_rad, v, a, omega)
    # a long range: ramp, coast and brake are each integrable by hand
    r = 0.5
    ramp, coast = v / a, (r - v * v / a) / v
    up = a * (1 - math.exp(-omega * ramp) * (1 + omega * ramp)) / omega ** 2
    flat = v * math.exp(-omega * ramp) * (1 - math.exp(-omega * coast)) / omega
    t2 = ramp + coast  # braking: qdot = v - a (u - t2) over [t2, t2 + ramp]
    down = math.exp(-omega * t2) * (v * (1 - math.exp(-omega * ramp)) / omega
                                    - a * (1 - math.exp(-omega * ramp) * (1 + omega * ramp))
                                    / omega ** 2)
    assert math.isclose(tool.braked_travel_integral(r, v, a, omega), up + flat + down,
                        rel_tol=2e-3)
    assert tool.braked_travel_integral(0.0, v, a, omega) == 0.0


@dataclass
class _Clearance:
    distance_m: float


class _Wall:
    """A checker whose links meet when joint 1 passes 0.25 rad."""

    def check(self, q):
        return _Clearance(0.25 - q[1] + 0.005)


def test_the_collision_room_stops_before_the_band():
    tool = load_tool("side_push_bound")
    q = np.zeros(3)
    room = tool.collision_room(_Wall(), q, 1, 1.0, 0.5)
    assert 0.25 + 0.005 - room >= tool.TOLERANCE_M  # within the band at the next step
    assert 0.25 + 0.005 - (room + tool.COLLISION_STEP_RAD) < tool.TOLERANCE_M
    assert tool.collision_room(_Wall(), q, 1, -1.0, 0.5) == 0.5  # the other way: clear
