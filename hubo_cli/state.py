"""What a robot reports each period: the neutral data type shared by drivers and control.

It lives apart from the drivers so that control modules, targets and reports can use it
without importing any driver.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubo_cli.geometry import roll_pitch_of_quat_wxyz

FT_SENSORS = ("right-wrist", "left-wrist", "right-ankle", "left-ankle")
GRAVITY_M_S2 = 9.80665  # standard gravity: what an accelerometer at rest reads (m/s^2)


@dataclass
class RobotState:
    """What a driver knows about the robot at one instant.

    Attributes:
        time_s: driver time since start (s).
        q_rad, dq_rad_s: joint positions (rad) and velocities (rad/s), joint_names order.
        imu_quat_wxyz: torso (IMU) orientation in the world frame, unit quaternion w, x, y, z.
        imu_gyro_rad_s: torso angular rate in the IMU frame (rad/s), as the gyro reads it
            (with its noise and bias).
        imu_accel_m_s2: the accelerometer's specific force in the IMU frame (m/s^2): the
            acceleration minus gravity, in the torso axes; about [0, 0, +9.81] upright at rest.
        ft: per sensor in FT_SENSORS, the wrench [fx, fy, fz, mx, my, mz] (N, N m) in the
            sensor frame (wrists: hand frame; ankles: sole frame).
        tau_nm: joint torques (N m) where the driver knows them, else None.
        T_world_torso: torso pose in the world (4x4, m) where known (simulation), else None.
        feet_contact: (right, left) sole touches the ground, where known, else None.
        flags: driver-level events this period (e.g. ``"nan-ref"``, ``"servo-off"``).
    """

    time_s: float
    q_rad: np.ndarray
    dq_rad_s: np.ndarray
    imu_quat_wxyz: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    imu_gyro_rad_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    imu_accel_m_s2: np.ndarray = field(
        default_factory=lambda: np.array([0.0, 0.0, GRAVITY_M_S2]))
    ft: dict[str, np.ndarray] = field(
        default_factory=lambda: {name: np.zeros(6) for name in FT_SENSORS})
    tau_nm: np.ndarray | None = None
    T_world_torso: np.ndarray | None = None
    feet_contact: tuple[bool, bool] | None = None
    flags: tuple[str, ...] = ()

    def tilt_rad(self) -> tuple[float, float]:
        """Torso tilt about world x (roll) and y (pitch) from the IMU quaternion (rad)."""
        return roll_pitch_of_quat_wxyz(self.imu_quat_wxyz)
