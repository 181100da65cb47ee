"""Named whole-robot postures (rad, in :attr:`RobotModel.joint_names` order)."""

from __future__ import annotations

import numpy as np

from hubo_cli.model import RobotModel

# Crouched stance: hip pitch -0.3, knee +0.6, ankle pitch -0.3 keeps the sole flat and parallel
# to the neck frame, with the knees forward and away from the straight-knee singularity.
CROUCH_LEG_RAD = (0.0, 0.0, -0.3, 0.6, -0.3, 0.0)
# Arms relaxed in front of the body: elbows bent 0.5 rad, clear of the torso and the hips.
READY_ARM_RAD = (0.0, 0.0, 0.0, -0.5, 0.0, 0.0)


def home_posture(model: RobotModel) -> np.ndarray:
    """The posture every driver starts in: crouched legs, arms relaxed (rad)."""
    q = np.zeros(len(model.joint_names))
    for limb in ("right-arm", "left-arm"):
        q[model.limb_slice(limb)] = READY_ARM_RAD
    for limb in ("right-leg", "left-leg"):
        q[model.limb_slice(limb)] = CROUCH_LEG_RAD
    return q
