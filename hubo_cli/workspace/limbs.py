"""The arm a workspace map is computed for, with the tool held as a mirror image on the left.

The model mounts every tool on DH frame 6 with the same transform for both arms. Both arms
share one DH chain, and the team's ``hand`` frame (DH6 Rx(+90 deg)) is mirror-consistent: the
left arm at (q1, -q2, -q3, q4, -q5, q6) puts its hand frame exactly where the mirror image (in
the x-z plane of the neck frame) of the right hand frame is. DH frame 6 itself is not, so
``T_6_drill = Ry(phi) Tx(lE)`` on the left arm tilts the bit the other way relative to the hand:
not how a drill would be held in the left hand. For the left arm this module mounts the tool as
the mirror image of the right arm's mount *relative to the hand*:

    T_6_tool(left) = T_6_hand M (T_6_hand^-1 T_6_tool) M,   M = diag(1, -1, 1)

which is Rx(pi) Ry(phi) Tx(lE) for the drill and leaves the hand unchanged. With it the left
arm's map is the exact mirror of the right arm's whenever the joint limits are mirrored (they
are in the team-code set; Table IV's left wrist yaw [-2.5, 2.0] is not the mirror of the right
arm's [-2.5, 2.0], which would be [-2.0, 2.5]).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from hubo_cli.kinematics import Limb, get_limb
from hubo_cli.model import load_model

MIRROR_Y = np.diag([1.0, -1.0, 1.0, 1.0])
MIRRORED_TOOLS = ("drill",)  # physical tools held in the hand; "none" is DH frame 6 itself


class MirroredToolLimb(Limb):
    """A left arm whose tool is mounted as the mirror image of the right arm's mount."""

    def __init__(self, model, name: str, tool: str) -> None:
        super().__init__(model, name, tool)
        T_6_hand = model.tool_transform("hand")
        T_hand_tool = np.linalg.inv(T_6_hand) @ model.tool_transform(tool)
        T_6_end = T_6_hand @ MIRROR_Y @ T_hand_tool @ MIRROR_Y
        self.T_6_end = T_6_end
        # the chain tuple is (base, base_inv, offset, alpha, a, d, end, end_inv)
        self.chain = (*self.chain[:6], T_6_end, np.linalg.inv(T_6_end))


@cache
def arm_limb(arm: str, tool: str, params: str = "as-built", limits: str = "table4") -> Limb:
    """The ``right`` or ``left`` arm with ``tool``, the left arm's tool mirrored (see above)."""
    if arm == "left" and tool in MIRRORED_TOOLS:
        return MirroredToolLimb(load_model(params, limits), "left-arm", tool)
    return get_limb(f"{arm}-arm", tool, params, limits)
