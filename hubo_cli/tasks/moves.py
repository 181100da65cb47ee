"""A move does not cut: refused at planning time when it puts the tool into the wall or
starts there.

A ``move`` step is a transfer in free air (minimum-jerk, no cutting speed, no thrust); the
wall is entered along the bit by a ``plunge``, cut along by a ``follow`` and left along the bit
by a ``retract``. A move whose goal depth takes the front of the tool past the wall's face
would drive the spinning bit into (and across) the cardboard at a transfer's speed, from any
direction; so would a move that starts where an earlier step left the tool in the wall (after
a plunge or a cut, with no retract between: review 20's `move_while_in.toml` dragged the bit
300 mm sideways out of the cardboard in 1 s). Both are refused before anything moves (a safety
refusal, exit 4), naming the step.
"""

from __future__ import annotations

from hubo_cli.errors import SafetyError
from hubo_cli.model import RobotModel
from hubo_cli.tasks.spec import TaskSpec
from hubo_cli.tasks.tool import tool_front_m

TOUCH_TOLERANCE_M = 1e-6  # a tip exactly on the face (depth_mm = -20 with the drill) is outside


def check_moves(spec: TaskSpec, model: RobotModel) -> None:
    """Refuse a move whose goal puts the tool's front past the wall's face, or that starts
    with it there (where the steps before left it: a move, plunge or retract ends at its
    depth, a follow or a wait stays at the depth it began at; the first move starts in free
    air, from the robot's start posture).

    Raises:
        SafetyError: the first such move, named, with its depth and how far the tool is in.
    """
    front_m = tool_front_m(spec.stance.tool, model)
    tool, reach = (("the bit's tip", "the flutes reach {:g} mm past the bit's middle")
                   if spec.stance.tool == "drill" else
                   ("the hand", "its front reaches {:g} mm past the hand point"))
    reach = ": " + reach.format(front_m * 1000)
    depth_m = None  # where the steps so far left the tool (None: free air, the start)
    for step in spec.steps:
        if step.kind == "move" and depth_m is not None and depth_m + front_m > TOUCH_TOLERANCE_M:
            raise SafetyError(
                f"{spec.path}: {step.label} (a move) starts with {tool} "
                f"{(depth_m + front_m) * 1000:g} mm in the wall (the steps before leave it at "
                f"depth_mm = {depth_m * 1000:g}{reach}) and would drag it out at a transfer's "
                "speed; a move does not cut",
                hint=f"pull out first with a retract step to depth_mm = {-front_m * 1000:g} or "
                     "less")
        if step.kind == "move" and step.depth_m + front_m > TOUCH_TOLERANCE_M:
            raise SafetyError(
                f"{spec.path}: {step.label} (a move) takes {tool} "
                f"{(step.depth_m + front_m) * 1000:g} mm into the wall (depth_mm = "
                f"{step.depth_m * 1000:g}{reach}); a move does not cut",
                hint=f"end the move at depth_mm = {-front_m * 1000:g} or less and go in with a "
                     "plunge step")
        if step.depth_m is not None:  # a move, plunge or retract ends there; the others stay
            depth_m = step.depth_m
