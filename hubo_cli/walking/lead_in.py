"""A correction's lead-in: the pattern of a walk planned after another (a correction walked
after the first pattern ended off its goal) starts where the legs hold the robot, not where
the estimate says the soles are, and moves onto its plan over the rows before its first
lift-off (:attr:`~hubo_cli.walking.gait.Gait.torso_lead_rad`, the quintic
:func:`~hubo_cli.walking.gait.smoothstep5`): nothing the legs are sent jumps at its start.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from hubo_cli.walking.footsteps import wrap_angle
from hubo_cli.walking.gait import Gait, smoothstep5
from hubo_cli.walking.support import SIDES


def blend_from_held(gait: Gait, T_world_held: np.ndarray) -> int:
    """Start a correction's pattern where the legs hold the soles (``T_world_held``, right
    and left, placed by the estimated torso), moving them onto the estimated soles it was
    planned from over its lead-in (the rows before the first lift-off; the quintic), in
    place. Planned from the estimated soles alone, the legs reached 8.7 mm lower and 18 mm
    wider at once: the knees' targets stepped 3-7 deg and the robot hopped (docs/history/
    walking.md, round 7). Returns the number of lead-in rows."""
    lifted = np.flatnonzero(~gait.support.all(axis=1))
    lead = int(lifted[0]) if len(lifted) else gait.n
    s = smoothstep5((np.arange(lead) + 1.0) / lead)[:, None]
    for column, side in enumerate(SIDES):
        T = T_world_held[column]
        held = np.array([T[0, 3], T[1, 3], T[2, 3], math.atan2(T[1, 0], T[0, 0])])
        rows = gait.feet[side]
        aimed = rows[lead - 1].copy() if lead else held
        held[3] = aimed[3] + wrap_angle(held[3] - aimed[3])
        rows[:lead] = held + s * (aimed - held)
    return lead


def levelled(R_world_neck: np.ndarray, R_neck_soles: np.ndarray) -> np.ndarray:
    """The torso's orientation that sets both soles (``R_neck_soles``, right and left, as the
    legs hold them) flat on the floor, each at the heading ``R_world_neck`` (the estimate) gives
    it; their mean. The pattern's soles are flat: from the estimated torso's tilt, the ankles'
    targets stepped by it at a correction's start (10-25 mrad; docs/history/walking.md,
    round 14)."""
    each = []
    for R_neck_sole in R_neck_soles:
        R = R_world_neck @ R_neck_sole
        each.append(pin.rpy.rpyToMatrix(0.0, 0.0, math.atan2(R[1, 0], R[0, 0])) @ R_neck_sole.T)
    return each[0] @ pin.exp3(0.5 * pin.log3(each[0].T @ each[1]))


def torso_lead(gait: Gait, lead: int, R_world_held: np.ndarray,
               lean_rad_per_m: float) -> np.ndarray:
    """A correction's lead-in's torso turn (:attr:`Gait.torso_lead_rad`, ``lead`` rows):
    from the estimated torso ``R_world_held`` the legs hold the soles from onto the pattern's
    own heading and lean (:func:`~hubo_cli.walking.body.lean_rad`), on the soles' quintic.
    The pattern's first torso leans toward the estimated CoM, which the stabilizer's torso
    offset had moved sideways (2 rad/m x 23 mm: 46 mrad of roll where the robot stood
    upright); started there, the legs' targets jumped (docs/history/walking.md, round 14)."""
    right, left = gait.feet["right"][0], gait.feet["left"][0]
    yaw = right[3] + wrap_angle(left[3] - right[3]) / 2
    c, s = math.cos(yaw), math.sin(yaw)
    com = gait.com.com_m[0]
    sideways = -s * (com[0] - (right[0] + left[0]) / 2) + c * (com[1] - (right[1] + left[1]) / 2)
    R_pattern = pin.rpy.rpyToMatrix(-lean_rad_per_m * sideways, 0.0, yaw)
    turn = pin.log3(R_pattern.T @ R_world_held)
    s = smoothstep5((np.arange(lead) + 1.0) / lead)[:, None]
    return (1.0 - s) * turn
