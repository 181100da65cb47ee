"""Footsteps from the current stance to a goal stance.

A *stance* is the frame midway between the two soles on the ground (x forward along the feet,
y left, yaw about z, in the world frame). The planner interpolates the stance from start to
goal and places the feet alternately on either side of it, ``step_width_m`` apart:

* forward and lateral motion: footprint i lies on the stance interpolated at i / (n - 1), so
  consecutive footprints are one n-th of the way apart (the alternating gait); the last step
  brings the trailing foot beside the leading one;
* turning: the hips only turn the toes out (Table IV: right hip yaw <= 0, left >= 0), so the
  foot on the turn side leads and opens by the step's share of the turn, and the other foot
  follows to the same heading; the feet are never toed in.

The leading foot is the one on the side of the turn, else on the side of the lateral motion,
else the left. The number of steps is the smallest that keeps every step within the forward,
backward, lateral and turn limits of :class:`~hubo_cli.walking.params.WalkingParams`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import InputError
from hubo_cli.walking.params import WalkingParams

SIDES = ("right", "left")
SIDE_SIGN = {"right": -1.0, "left": 1.0}
MAX_STEPS = 200  # a goal needing more steps than this is refused (InputError)
TOE_IN_TOLERANCE_RAD = 0.01  # measured feet stand straight to within this
LIMIT_TOLERANCE_M = 0.002  # a step may exceed a length limit by this much: the feet a walk
                           # starts from are measured, a fraction of a mm off their nominal
                           # places, which would otherwise add two steps to a walk (1 m forward:
                           # eight steps of 0.14 m instead of six of 0.2 m)
LIMIT_TOLERANCE_RAD = 0.005  # the same for the turn limit


def wrap_angle(a: float) -> float:
    """An angle wrapped to (-pi, pi] (rad)."""
    return math.atan2(math.sin(a), math.cos(a))


@dataclass(frozen=True)
class Stance:
    """The frame midway between the feet: position (m) and heading (rad) in the world."""

    x_m: float
    y_m: float
    yaw_rad: float

    def foot(self, side: str, width_m: float) -> Footstep:
        """Where foot ``side`` stands in this stance, ``width_m`` from the other."""
        offset = SIDE_SIGN[side] * width_m / 2
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return Footstep(side, self.x_m - s * offset, self.y_m + c * offset, self.yaw_rad)

    def relative(self, other: Stance) -> tuple[float, float, float]:
        """``other`` seen from this stance: (forward m, left m, turn rad)."""
        dx, dy = other.x_m - self.x_m, other.y_m - self.y_m
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return c * dx + s * dy, -s * dx + c * dy, wrap_angle(other.yaw_rad - self.yaw_rad)


@dataclass(frozen=True)
class Footstep:
    """One sole on the ground: ``side`` (``right``/``left``), position (m) and heading (rad)."""

    side: str
    x_m: float
    y_m: float
    yaw_rad: float

    def pose(self, z_m: float = 0.0) -> np.ndarray:
        """T_world_sole (4x4), the sole flat at height ``z_m``."""
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        T = np.eye(4)
        T[:2, :2] = [[c, -s], [s, c]]
        T[:3, 3] = self.x_m, self.y_m, z_m
        return T

    def to_json(self) -> dict:
        return {"side": self.side, "x_m": self.x_m, "y_m": self.y_m, "yaw_rad": self.yaw_rad}


def stance_of(right: Footstep, left: Footstep) -> Stance:
    """The stance midway between two feet (heading: the mean of theirs)."""
    yaw = right.yaw_rad + wrap_angle(left.yaw_rad - right.yaw_rad) / 2
    return Stance((right.x_m + left.x_m) / 2, (right.y_m + left.y_m) / 2, wrap_angle(yaw))


def _interpolate(start: Stance, goal: Stance, s: float) -> Stance:
    forward, left, turn = start.relative(goal)
    c, si = math.cos(start.yaw_rad), math.sin(start.yaw_rad)
    dx, dy = s * forward, s * left
    return Stance(start.x_m + c * dx - si * dy, start.y_m + si * dx + c * dy,
                  wrap_angle(start.yaw_rad + s * turn))


def step_count(start: Stance, goal: Stance, params: WalkingParams) -> int:
    """How many steps the walk from ``start`` to ``goal`` takes (0: already there)."""
    forward, left, turn = start.relative(goal)
    if max(abs(forward), abs(left)) < 1e-4 and abs(turn) < 1e-4:
        return 0
    reach = params.max_step_forward_m if forward >= 0 else params.max_step_backward_m
    # alternating gait: footprints 1 / (n - 1) of the way apart, the last one closes
    moving = max(abs(forward) / reach, abs(left) / params.max_step_lateral_m)
    n_moving = math.ceil(moving - 1e-9) + 1 if moving > 1e-9 else 0
    n_turning = 2 * math.ceil(abs(turn) / params.max_turn_rad - 1e-9)
    n = max(n_moving, n_turning, 2)
    return n + (n % 2)  # whole pairs: the feet end side by side, both having stepped


def within_limits(steps: list[Footstep], right: Footstep, left: Footstep,
                  params: WalkingParams) -> bool:
    """Every step lands within the forward/backward, lateral and turn limits (to within
    LIMIT_TOLERANCE_M / LIMIT_TOLERANCE_RAD), seen from the stance foot it steps from, and the
    feet are never toed in (left heading >= right)."""
    feet = {"right": right, "left": left}
    low = params.step_width_m - 2 * params.max_step_lateral_m - LIMIT_TOLERANCE_M
    high = params.step_width_m + 2 * params.max_step_lateral_m + LIMIT_TOLERANCE_M
    for step in steps:
        stance = feet["left" if step.side == "right" else "right"]
        forward, sideways, turn = Stance(stance.x_m, stance.y_m, stance.yaw_rad).relative(
            Stance(step.x_m, step.y_m, step.yaw_rad))
        if not (-params.max_step_backward_m - LIMIT_TOLERANCE_M <= forward
                <= params.max_step_forward_m + LIMIT_TOLERANCE_M and low <= abs(sideways) <= high
                and abs(turn) <= params.max_turn_rad + LIMIT_TOLERANCE_RAD):
            return False
        feet[step.side] = step
        if wrap_angle(feet["left"].yaw_rad - feet["right"].yaw_rad) < -TOE_IN_TOLERANCE_RAD:
            return False
    return True


def plan_footsteps(right: Footstep, left: Footstep, goal: Stance,
                   params: WalkingParams) -> list[Footstep]:
    """The footsteps (swing feet, in order) that take the feet from where they stand to the
    goal stance; empty when they are already there. The step count starts at
    :func:`step_count` and grows (two at a time) until every step is within the limits seen
    from its stance foot (:func:`within_limits`; a turn changes what "forward" means).

    Raises:
        InputError: a goal that needs more than MAX_STEPS steps.
    """
    start = stance_of(right, left)
    n = step_count(start, goal, params)
    if n == 0:
        return []
    while n <= MAX_STEPS:
        steps = _place(right, left, start, goal, n, params)
        if within_limits(steps, right, left, params):
            return steps
        n += 2
    raise InputError(f"the goal needs more than {MAX_STEPS} steps",
                     hint="walk there in shorter legs")


def _place(right: Footstep, left: Footstep, start: Stance, goal: Stance, n: int,
           params: WalkingParams) -> list[Footstep]:
    """n footsteps from ``start`` to ``goal`` (see the module docstring)."""
    _, lateral, turn = start.relative(goal)
    if abs(turn) > 1e-4:
        lead = "left" if turn > 0 else "right"
    elif abs(lateral) > 1e-4:
        lead = "left" if lateral > 0 else "right"
    else:
        lead = "left"
    trail = "right" if lead == "left" else "left"
    width = params.step_width_m
    steps: list[Footstep] = []
    yaw = start.yaw_rad
    for i in range(1, n + 1):
        side = lead if i % 2 else trail
        place = _interpolate(start, goal, min(i / (n - 1), 1.0))
        if side == lead:  # the turn side opens first; the other foot follows to its heading
            yaw = _interpolate(start, goal, (i + 1) / n).yaw_rad
        steps.append(Stance(place.x_m, place.y_m, yaw).foot(side, width))
    return steps


def closing_steps(right: Footstep, left: Footstep, goal: Stance, width_m: float,
                  first: str = "right", tolerance_m: float = 0.001) -> list[Footstep]:
    """The two steps that bring feet standing on ``goal`` to ``width_m`` apart (the stance a
    task or an operator starts from is narrower than the walking one): ``first``, then the
    other foot, so that the feet keep alternating (give the side that did not step last).
    Empty when both feet stand within ``tolerance_m`` of their places."""
    feet = {"right": right, "left": left}
    places = {side: goal.foot(side, width_m) for side in SIDES}
    if all(math.hypot(places[s].x_m - feet[s].x_m, places[s].y_m - feet[s].y_m) <= tolerance_m
           and abs(wrap_angle(places[s].yaw_rad - feet[s].yaw_rad)) <= TOE_IN_TOLERANCE_RAD
           for s in SIDES):
        return []
    second = "left" if first == "right" else "right"
    return [places[first], places[second]]
