"""Hand wrenches in the control layer: the references a motion asks for, and the one place the
measured hand wrench is read.

A task step may ask for a hand force (a plunge held at a thrust, a push held at a force). The
target writes it every period as :data:`HAND_WRENCH_PLAN`; the soft emergency stopper passes it
on as :data:`HAND_WRENCH_REF`, reverted with the motion when it stops (eq. 15); the
ImpedanceController takes that as its spring's force setpoint (eq. 3's F_ref). A wrench here is
[fx, fy, fz, mx, my, mz] (N, N m) that the environment exerts on the hand, about the hand
frame's origin, in the neck frame N's axes: a hand pushing a wall in front of the robot with
3 N feels fx = -3.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Key, Store
from hubo_cli.state import RobotState

HAND_WRENCH_PLAN = Key("hand_wrench_plan", dict,
                       "arm -> [fx fy fz mx my mz] (N, N m) the motion asks the environment to "
                       "exert on the hand, about the hand origin, neck-frame axes")
HAND_WRENCH_REF = Key("hand_wrench_ref", dict,
                      "arm -> the planned hand wrench after the emergency stopper (reverted with "
                      "the motion when it stops); same frame and units")
WRENCH_AXES = ("x", "y", "z", "rx", "ry", "rz")

# the store keys measured_hand_wrench reads (none while it takes the raw reading)
MEASURED_WRENCH_READS: tuple[Key, ...] = ()


def measured_hand_wrench(state: RobotState, store: Store, sensor: str) -> np.ndarray | None:
    """The wrench the environment applies to the hand at ``sensor`` (``right-wrist``,
    ``left-wrist``), in the sensor's frame (N, N m), or None when the robot has no such sensor.

    Every controller that uses a measured hand wrench reads it here. It is the raw reading
    (``state.ft``) until the estimation layer's compensated wrenches
    (:data:`hubo_cli.estimation.keys.WRENCHES`, the tool's weight and the sensor's offset
    removed) exist: then this reads ``store[WRENCHES].get(sensor)`` and
    :data:`MEASURED_WRENCH_READS` names that key."""
    return state.ft.get(sensor)


def wrench_of(references: dict | None, arm: str) -> np.ndarray | None:
    """``arm``'s finite 6-vector in a reference dict (None when absent or not finite)."""
    if not references:
        return None
    value = references.get(arm)
    if value is None:
        return None
    w = np.asarray(value, dtype=float).reshape(-1)
    return w if w.shape == (6,) and np.all(np.isfinite(w)) else None
