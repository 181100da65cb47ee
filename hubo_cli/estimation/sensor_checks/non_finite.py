"""Readings that are not numbers (review 22): NaN or infinity from a joint encoder (position or
velocity), a joint torque, the IMU (quaternion, gyro, accelerometer) or a force-torque sensor.

Every comparison with NaN is false, so none of the other checks, and no bound downstream,
sees one: the simulated robot with a NaN ankle sensor, accelerometer, gyro, quaternion or knee
encoder stood 0.5 s to exit 0 (review 22), the estimate built on the reading NaN where it
entered and the commands held by the loop's finite-command rule. The hardware driver refuses
such a state from hubo-ach (``DeviceError``); this check holds the same for every driver whose
sensors are measured. A non-finite number is never noise, so there is no window: refused at the
start, a fault the first period later.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.state import RobotState


def _readings(state: RobotState, joint_names: tuple[str, ...]) -> list[tuple[str, np.ndarray]]:
    """What the robot senses, each reading with the name an operator knows it by ("{}": the
    element's joint, for the per-joint readings)."""
    named = [("{} joint's encoder (position)", state.q_rad),
             ("{} joint's encoder (velocity)", state.dq_rad_s),
             ("IMU's quaternion", state.imu_quat_wxyz),
             ("IMU's gyro", state.imu_gyro_rad_s),
             ("IMU's accelerometer", state.imu_accel_m_s2)]
    named += [(f"{sensor} force-torque sensor", wrench) for sensor, wrench in state.ft.items()]
    if state.tau_nm is not None:
        named.append(("{} joint's torque", state.tau_nm))
    return [(name, np.ravel(np.asarray(x, dtype=float))) for name, x in named]


def check_finite(state: RobotState, joint_names: tuple[str, ...], start: bool = False) -> None:
    """Raise the fault (``start``: the refusal) naming the first reading of ``state`` that is
    not a finite number; nothing when all are (one vectorised test, a few microseconds)."""
    readings = _readings(state, joint_names)
    if np.isfinite(np.concatenate([x for _, x in readings])).all():
        return
    name, values = next((n, x) for n, x in readings if not np.isfinite(x).all())
    k = int(np.flatnonzero(~np.isfinite(values))[0])
    when = ("at the start: refused before anything moved" if start else
            f"at t = {state.time_s:.3f} s")
    joint = joint_names[k] if k < len(joint_names) else f"#{k}"
    raise sensor_fault(f"the {name.format(joint)} read "
                       f"{values[k]} {when}: a reading that is not a number (no bound or "
                       "estimate can judge it)", refuse=start)
