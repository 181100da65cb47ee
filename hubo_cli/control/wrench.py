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

import math

import numpy as np

from hubo_cli.dataflow import Key, Store
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.state import FT_MEASURED, RobotState

HAND_WRENCH_PLAN = Key("hand_wrench_plan", dict,
                       "arm -> [fx fy fz mx my mz] (N, N m) the motion asks the environment to "
                       "exert on the hand, about the hand origin, neck-frame axes")
HAND_WRENCH_REF = Key("hand_wrench_ref", dict,
                      "arm -> the planned hand wrench after the emergency stopper (reverted with "
                      "the motion when it stops); same frame and units")
WRENCH_AXES = ("x", "y", "z", "rx", "ry", "rz")

MEASURED_FORCE_AXES = tuple(i for i in FT_MEASURED if i < 3)  # Hubo's: f_z only
TIP_MIN_M = 0.05  # a tool point at least this far along the forearm from the wrist sensor
ALONG_MIN = 0.1  # the least sum (a_i . d)^2 force tracking trusts (d within 72 deg of an axis)

# the store keys measured_hand_wrench reads
MEASURED_WRENCH_READS: tuple[Key, ...] = (WRENCHES,)


def measured_hand_wrench(state: RobotState, store: Store, sensor: str) -> np.ndarray | None:
    """The wrench the environment applies to the hand at ``sensor`` (``right-wrist``,
    ``left-wrist``), in the sensor's frame (N, N m), or None when the robot has no such sensor.

    Every controller that uses a measured hand wrench reads it here: the estimation layer's
    compensated wrenches (:data:`hubo_cli.estimation.keys.WRENCHES`, the hand's and the tool's
    weight removed), so a caller declares :data:`MEASURED_WRENCH_READS`. ``state`` is the
    robot's (kept for a reading the estimate lacks)."""
    return store[WRENCHES].get(sensor)


def force_at_point(wrench_S, r_S_m: np.ndarray) -> np.ndarray:
    """The force (N, sensor axes) the environment applies at the point ``r_S_m`` (m, sensor
    frame), from a reading of which only ``FT_MEASURED`` are real, assuming it is a force at
    that point and no moment about it (a tool's tip: a drill bit's cutting and thrust).

    Hubo's wrist sensor reads f_z and the moments m_x, m_y; with m = r x f,
    f_x = (m_y + r_x f_z) / r_z and f_y = (r_y f_z - m_x) / r_z: the force across the forearm
    is seen through the moment it makes at the tool, wherever the tip lies off the sensor
    along the forearm (r_z != 0). A point nearer the sensor than ``TIP_MIN_M`` along z gives
    NaN (the moments cannot carry the force). A full sensor's force is returned as it is."""
    w = np.asarray(wrench_S, dtype=float)
    if set(FT_MEASURED) >= {0, 1, 2}:
        return w[:3].copy()
    rx, ry, rz = (float(v) for v in r_S_m)
    if not abs(rz) >= TIP_MIN_M:
        return np.full(3, math.nan)
    fz = float(w[2])
    return np.array([(float(w[4]) + rx * fz) / rz, (ry * fz - float(w[3])) / rz, fz])


def tool_point_S_m(model, tool: str, T_hand_sensor: np.ndarray) -> np.ndarray:
    """The origin of ``tool``'s frame (a drill: the bit's middle) in the frame of a wrist
    sensor mounted at ``T_hand_sensor`` (m): where :func:`force_at_point` takes a tool's force
    to act."""
    T_6_S = model.tool_transform("hand") @ T_hand_sensor
    return (np.linalg.inv(T_6_S) @ model.tool_transform(tool)[:, 3])[:3]


def wrench_of(references: dict | None, arm: str) -> np.ndarray | None:
    """``arm``'s finite 6-vector in a reference dict (None when absent or not finite)."""
    if not references:
        return None
    value = references.get(arm)
    if value is None:
        return None
    w = np.asarray(value, dtype=float).reshape(-1)
    return w if w.shape == (6,) and np.all(np.isfinite(w)) else None
