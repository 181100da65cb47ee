"""A task's tool (``[stance] tool``, ``drill`` or ``hand``): what the run calls its working
point and how far its front reaches, the one home of both.

The drill works with its bit, the hand with itself: the summary (its keys too: the travel
after a stop, ``bit_along_wall_mm`` or ``hand_along_wall_mm``), the ``--json`` document, the
run folder's plots and the live view name it by :func:`tool_point`. The front is where the
tool meets the wall face, ahead of the point the depths of the task's steps are given for
(:func:`tool_front_m`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hubo_cli.model import RobotModel

TOOL_POINT = {"drill": "bit", "hand": "hand"}  # tool -> the word for its working point
TRAVEL_KEYS = ("along_wall_mm", "into_wall_mm", "out_of_wall_mm")  # after a stop, per point


def tool_point(tool: str) -> str:
    """The working point of ``tool`` in the run's words: ``bit`` (the drill) or ``hand``."""
    return TOOL_POINT[tool]


def travel_keys(tool: str) -> tuple[str, str, str]:
    """The summary keys of how far the tool's point moved after a stop (mm): along the wall,
    into it and out of it (``bit_along_wall_mm``, ... with the drill)."""
    return tuple(f"{tool_point(tool)}_{key}" for key in TRAVEL_KEYS)


def tool_front_m(tool: str, model: RobotModel) -> float:
    """How far ``tool`` reaches past its depth reference along the bit, the wall's normal (m):
    the drill's flutes end ``bit_tip_m`` ahead of the bit's middle; the hand's front face
    :func:`~hubo_cli.urdf.hand_front_m` ahead of the hand point."""
    from hubo_cli.urdf import hand_front_m

    return model.drill.bit_tip_m if tool == "drill" else hand_front_m(model)
