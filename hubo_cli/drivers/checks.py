"""Command checks every driver applies before it moves anything.

A NaN or infinite entry keeps that joint's previous command (flag ``nan-ref``); an entry outside
the joint's position limits is clipped to them (flag ``limit-clip``). The hardware driver adds its
own velocity check on top (see :mod:`hubo_cli.drivers.hardware`).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.model import RobotModel

NAN_REF = "nan-ref"
LIMIT_CLIP = "limit-clip"
NOT_STARTED_HINT = "call start() before send(), step() or read()"


def sanitize_command(model: RobotModel, last_rad: np.ndarray,
                     q_rad: np.ndarray) -> tuple[np.ndarray, list[str], np.ndarray]:
    """The command a driver may apply (rad), its flags and the mask of frozen (NaN) joints.

    Args:
        model: robot model (joint limits).
        last_rad: the previous applied command (24,), rad.
        q_rad: the requested full command (24,), rad.
    """
    q = np.array(q_rad, dtype=float)
    flags: list[str] = []
    frozen = ~np.isfinite(q)
    if frozen.any():
        q[frozen] = last_rad[frozen]
        flags.append(NAN_REF)
    # np.clip's arithmetic without its Python-level argument checks (a call every period)
    clipped = np.minimum(np.maximum(q, model.lower_rad), model.upper_rad)
    if (np.abs(clipped - q) > 1e-9).any():  # rounding at a limit is not worth a flag
        flags.append(LIMIT_CLIP)
    return clipped, flags, frozen
