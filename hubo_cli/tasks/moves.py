"""A move does not cut: refused at planning time when its goal puts the tool into the wall.

A ``move`` step is a transfer in free air (minimum-jerk, no cutting speed, no thrust); the
wall is entered along the bit by a ``plunge`` and cut along by a ``follow``. A move whose goal
depth takes the front of the tool past the wall's face would drive the spinning bit into (and
across) the cardboard at a transfer's speed, from any direction: refused before anything moves
(a safety refusal, exit 4), naming the step.
"""

from __future__ import annotations

from hubo_cli.errors import SafetyError
from hubo_cli.model import RobotModel
from hubo_cli.tasks.spec import TaskSpec

TOUCH_TOLERANCE_M = 1e-6  # a tip exactly on the face (depth_mm = -20 with the drill) is outside


def tool_front_m(spec: TaskSpec, model: RobotModel) -> float:
    """How far the tool reaches past its depth reference along the bit (m): the drill's flutes
    end ``bit_tip_m`` ahead of the bit's middle; the hand's point is its front."""
    return model.drill.bit_tip_m if spec.stance.tool == "drill" else 0.0


def check_moves(spec: TaskSpec, model: RobotModel) -> None:
    """Refuse a move whose goal puts the tool's front past the wall's face.

    Raises:
        SafetyError: the first such move, named, with its depth and how far the tool goes in.
    """
    front_m = tool_front_m(spec, model)
    for step in spec.steps:
        if step.kind != "move" or step.depth_m is None:
            continue
        into_m = step.depth_m + front_m
        if into_m > TOUCH_TOLERANCE_M:
            tool = ("the bit's tip" if spec.stance.tool == "drill" else "the hand")
            reach = (f": the flutes reach {front_m * 1000:g} mm past the bit's middle"
                     if front_m > 0 else "")
            raise SafetyError(
                f"{spec.path}: {step.label} (a move) takes {tool} {into_m * 1000:g} mm into "
                f"the wall (depth_mm = {step.depth_m * 1000:g}{reach}); a move does not cut",
                hint=f"end the move at depth_mm = {-front_m * 1000:g} or less and go in with a "
                     "plunge step")
