"""A move does not cut: refused at planning time when it puts the tool into the wall or
starts there.

A ``move`` step is a transfer in free air (minimum-jerk, no cutting speed, no thrust); the
wall is entered along the bit by a ``plunge``, cut along by a ``follow`` and left along the bit
by a ``retract``. A move whose goal depth takes the front of the tool past the wall's face
would drive the spinning bit into (and across) the cardboard at a transfer's speed, from any
direction; so would a move that starts where an earlier step left the tool in the wall (after
a plunge or a cut, with no retract between: review 20's `move_while_in.toml` dragged the bit
300 mm sideways out of the cardboard in 1 s). Both are refused before anything moves (a safety
refusal, exit 4), naming the step. A step that presses with a thrust (``thrust_n``) leaves the
tool up to the hand's yield along the bit (the robot file's ``[impedance] max_offset_m``) past
its planned depth until a plunge, retract or move without a thrust takes it to a depth again:
a move straight after a press started with the bit 19 mm in the cardboard on a plan 1 mm
short of the face and dragged it sideways until the wrist-torque stop (review 28). A
``retract`` goes back along the tool: one deeper than where the steps before leave the tool
is a contradiction in the file (exit 2; review 28's "pull out" to depth_mm = 50 drove the bit
through the wall and the run completed).

:func:`in_wall` is the one home of "the tool's front is past the face": the planner's cutting
periods read it too.
"""

from __future__ import annotations

from hubo_cli.errors import ConfigError, SafetyError
from hubo_cli.model import RobotModel
from hubo_cli.tasks.spec import TaskSpec
from hubo_cli.tasks.tool import tool_front_m, tool_point

TOUCH_TOLERANCE_M = 1e-6  # a tip exactly on the face (depth_mm = -20 with the drill) is outside


def in_wall(depth_m: float, front_m: float) -> bool:
    """Whether a tool whose depth reference is ``depth_m`` past the wall face (negative: before
    it) and whose front reaches ``front_m`` past that reference has its front in the wall."""
    return depth_m + front_m > TOUCH_TOLERANCE_M


def check_moves(spec: TaskSpec, model: RobotModel) -> None:
    """Refuse a move whose goal puts the tool's front past the wall's face, or that starts
    with it there (where the steps before left it: a move, plunge or retract ends at its
    depth, a follow or a wait stays at the depth it began at, and a step pressing with a
    thrust may carry it up to the hand's yield past that; the first move starts in free air,
    from the robot's start posture); refuse a retract deeper than where the steps before
    leave the tool.

    Raises:
        SafetyError: the first such move, named, with its depth and how far the tool is in.
        ConfigError: a retract that goes deeper, named.
    """
    front_m = tool_front_m(spec.stance.tool, model)
    yield_m = model.impedance_max_offset_m
    tool, reach = (("the bit's tip", "the flutes reach {:g} mm past the bit's middle")
                   if spec.stance.tool == "drill" else
                   ("the hand", "its front reaches {:g} mm past the hand point"))
    reach = ": " + reach.format(front_m * 1000)
    depth_m = None  # where the steps so far left the tool (None: free air, the start)
    pressed = False  # a step since the last depth was reached pressed with a thrust
    for step in spec.steps:
        if step.kind == "retract" and depth_m is not None and step.depth_m > depth_m:
            raise ConfigError(
                f"{step.label} (a retract) goes deeper, to depth_mm = {step.depth_m * 1000:g}, "
                f"than the steps before leave the {tool_point(spec.stance.tool)} "
                f"(depth_mm = {depth_m * 1000:g}); a retract pulls the tool back along its "
                "axis", path=str(spec.path),
                hint="give the retract a depth_mm less than the step before it, or make it a "
                     "plunge")
        start_m = None if depth_m is None else depth_m + (yield_m if pressed else 0.0)
        if step.kind == "move" and start_m is not None and in_wall(start_m, front_m):
            pressing = (f", and a thrust before it may carry it {yield_m * 1000:g} mm past that"
                        if pressed else "")
            raise SafetyError(
                f"{spec.path}: {step.label} (a move) starts with {tool} "
                f"{'up to ' if pressed else ''}{(start_m + front_m) * 1000:g} mm in the wall "
                f"(the steps before leave it at depth_mm = {depth_m * 1000:g}{pressing}{reach}) "
                "and would drag it out at a transfer's speed; a move does not cut",
                hint=f"pull out first with a retract step to depth_mm = {-front_m * 1000:g} or "
                     "less")
        if step.kind == "move" and in_wall(step.depth_m, front_m):
            raise SafetyError(
                f"{spec.path}: {step.label} (a move) takes {tool} "
                f"{(step.depth_m + front_m) * 1000:g} mm into the wall (depth_mm = "
                f"{step.depth_m * 1000:g}{reach}); a move does not cut",
                hint=f"end the move at depth_mm = {-front_m * 1000:g} or less and go in with a "
                     "plunge step")
        if step.depth_m is not None:  # a move, plunge or retract ends there; the others stay
            depth_m = step.depth_m
            pressed = False
        pressed = pressed or step.thrust_n > 0
