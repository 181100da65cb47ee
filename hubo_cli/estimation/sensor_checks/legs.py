"""What the sensor checks read of the legs: a sole loaded, both soles loaded, and how far the
torso turned on them."""

from __future__ import annotations

import numpy as np

from hubo_cli.state import ANKLE_SENSORS, RobotState

SOLE_LOADED_WEIGHTS = 0.25  # a sole loaded: its F_z at least this many robot weights


def both_soles_loaded(state: RobotState, weight_n: float) -> bool:
    """Both ankle sensors read F_z (raw, N) of at least :data:`SOLE_LOADED_WEIGHTS` of the
    robot's ``weight_n`` (a sensor missing or not finite: not loaded)."""
    loaded_n = SOLE_LOADED_WEIGHTS * weight_n
    return all(float(state.ft[s][2]) >= loaded_n if s in state.ft else False
               for s in ANKLE_SENSORS)


def angle_rad(R: np.ndarray) -> float:
    """The angle of the rotation ``R`` (rad)."""
    return float(np.arccos(np.clip(0.5 * (np.trace(R) - 1.0), -1.0, 1.0)))
