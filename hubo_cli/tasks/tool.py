"""A task's tool (``[stance] tool``, ``drill`` or ``hand``): how far its front reaches, where
it meets the wall face, ahead of the point the depths of the task's steps are given for
(:func:`tool_front_m`), the one home of it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hubo_cli.model import RobotModel

def tool_front_m(tool: str, model: RobotModel) -> float:
    """How far ``tool`` reaches past its depth reference along the bit, the wall's normal (m):
    the drill's flutes end ``bit_tip_m`` ahead of the bit's middle; the hand's front face
    :func:`~hubo_cli.urdf.hand_front_m` ahead of the hand point."""
    from hubo_cli.urdf import hand_front_m

    return model.drill.bit_tip_m if tool == "drill" else hand_front_m(model)
