"""Command checks every driver applies before it moves anything.

A NaN or infinite entry keeps that joint's previous command (flag ``nan-ref``); an entry outside
the joint's position limits is clipped to them (flag ``limit-clip``). The hardware driver adds its
own velocity check on top (see :mod:`hubo_cli.drivers.hardware`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from hubo_cli.kinematics.dh import JIT, kernel_array
from hubo_cli.model import RobotModel

NAN_REF = "nan-ref"
LIMIT_CLIP = "limit-clip"
NOT_STARTED_HINT = "call start() before send(), step() or read()"


# the signature declared: numba loads the kernel from its cache at import and never compiles it
# during a run (every period of every driver calls it)
@nb.njit("int64(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1])", **JIT)
def sanitize_into(last_rad, q_rad, lower_rad, upper_rad, out_rad):
    """The command a driver may apply, into ``out_rad``: a non-finite entry of ``q_rad`` keeps
    ``last_rad``'s, then every entry is clipped to [``lower_rad``, ``upper_rad``]. Returns 1 if
    an entry was kept, plus 2 if one was clipped by more than 1e-9 rad (rounding at a limit is
    not worth a flag). All arrays float64, C-ordered and writable (the one signature)."""
    code = 0
    for i in range(q_rad.shape[0]):
        x = q_rad[i]
        if not math.isfinite(x):
            x = last_rad[i]
            code |= 1
        c = x
        if c < lower_rad[i]:
            c = lower_rad[i]
        if c > upper_rad[i]:
            c = upper_rad[i]
        if abs(c - x) > 1e-9:
            code |= 2
        out_rad[i] = c
    return code


def flags_of(code: int) -> list[str]:
    """The flags of :func:`sanitize_into`'s return value."""
    return [flag for bit, flag in ((1, NAN_REF), (2, LIMIT_CLIP)) if code & bit]


def sanitize_command(model: RobotModel, last_rad: np.ndarray,
                     q_rad: np.ndarray) -> tuple[np.ndarray, list[str], np.ndarray]:
    """The command a driver may apply (rad), its flags and the mask of frozen (NaN) joints.

    Args:
        model: robot model (joint limits).
        last_rad: the previous applied command (24,), rad.
        q_rad: the requested full command (24,), rad.
    """
    q = np.array(q_rad, dtype=float)
    out, flags = _sanitized(model, last_rad, q)
    return out, flags, ~np.isfinite(q)


def sanitize(model: RobotModel, last_rad: np.ndarray, q_rad) -> tuple[np.ndarray, list[str]]:
    """:func:`sanitize_command` without the mask of frozen joints."""
    return _sanitized(model, last_rad, kernel_array(q_rad))


def _sanitized(model: RobotModel, last_rad: np.ndarray, q: np.ndarray
               ) -> tuple[np.ndarray, list[str]]:
    out = np.empty(len(q))
    code = sanitize_into(kernel_array(last_rad), q, kernel_array(model.lower_rad),
                         kernel_array(model.upper_rad), out)
    return out, flags_of(code)
