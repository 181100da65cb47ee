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


# a robot measured further than this from the posture a run starts holding (a real one stands
# where it was left) is refused: the first references would throw it into the posture
START_TOLERANCE_RAD = 0.05


def check_stands_in(model: RobotModel, q_measured_rad, q_posture_rad, posture: str) -> None:
    """Refuse a run whose robot is measured more than START_TOLERANCE_RAD from the posture
    (``posture``: its name, e.g. ``walking``) it starts holding.

    Raises:
        SafetyError: a joint that far (or not finite), named with the hint to stand it so.
    """
    from hubo_cli.errors import SafetyError

    off = np.abs(np.asarray(q_measured_rad, dtype=float) - np.asarray(q_posture_rad))
    if np.all(off <= START_TOLERANCE_RAD):
        return
    i = int(np.argmax(np.where(np.isfinite(off), off, np.inf)))
    raise SafetyError(f"the robot does not stand in the {posture} posture: "
                      f"{model.joint_names[i]} is {off[i]:.3f} rad from it "
                      f"(at most {START_TOLERANCE_RAD:g})",
                      hint=f"stand it in the {posture} posture first (the simulated daemon: "
                           f"hubo hardware sim-daemon --posture {posture})")
