"""What a robot reports each period: the neutral data type shared by drivers and control.

It lives apart from the drivers so that control modules, targets and reports can use it
without importing any driver.

A :class:`RobotState` holds what a Hubo's sensors report (encoders, IMU, force-torque
sensors) and nothing else. What only a simulator knows (the torso's true pose, the feet's true
contact) travels beside it in :attr:`RobotState.truth`, for logs, reports, plots and the
viewers only: modules, targets and planners act on the estimate
(:mod:`hubo_cli.estimation.keys`), and tests/test_truth_isolation.py holds them to it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubo_cli.geometry import roll_pitch_of_quat_wxyz

FT_SENSORS = ("right-wrist", "left-wrist", "right-ankle", "left-ankle")
ANKLE_SENSORS = FT_SENSORS[2:]  # (right, left), as the feet are always ordered
GRAVITY_M_S2 = 9.80665  # standard gravity: what an accelerometer at rest reads (m/s^2)
FT_MEASURED = (2, 3, 4)
"""What Hubo's three-axis force-torque sensors measure of [fx, fy, fz, mx, my, mz]: f_z, m_x,
m_y (hubo-ach ``hubo_ft_t``); the other components read 0."""
# The wrist sensor's axes in the hand frame (whose x runs along the forearm out through the
# palm): the sensor's z along the forearm (its f_z the axial force), its x and y across it (m_x,
# m_y the two bending moments) = the hand's y and z. The ankle sensors' frames are the soles'.
R_HAND_WRIST_SENSOR = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
R_HAND_WRIST_SENSOR.flags.writeable = False


def T_frame_sensor(sensor: str) -> np.ndarray:
    """A force-torque sensor's axes in its frame (4x4): a wrist's in the hand frame
    (R_HAND_WRIST_SENSOR), an ankle's are the sole's (identity)."""
    T = np.eye(4)
    if sensor.endswith("wrist"):
        T[:3, :3] = R_HAND_WRIST_SENSOR
    return T


@dataclass(frozen=True)
class Truth:
    """The simulator's ground truth of one instant: for logs, reports, plots and viewers only.

    Attributes:
        T_world_torso: the torso's (neck frame's) true pose in the world (4x4, m).
        feet_contact: (right, left) the sole truly carries load (the simulator's filtered
            ankle F_z above its threshold).
        quat_world_torso_wxyz: the torso's true attitude (unit quaternion w, x, y, z), before
            any IMU noise or bias.
    """

    T_world_torso: np.ndarray
    feet_contact: tuple[bool, bool]
    quat_world_torso_wxyz: np.ndarray


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
        ft: per sensor in FT_SENSORS, the wrench [fx, fy, fz, mx, my, mz] (N, N m) the sensor
            reads, in its own frame (wrists: z along the forearm, R_HAND_WRIST_SENSOR; ankles:
            the sole frame), about its origin (the hand point, the sole's middle): what the
            body beyond it and the environment load onto it, the weight of that body and of a
            held tool included (the estimation layer removes them). Hubo's sensors measure
            fz, mx, my (FT_MEASURED); fx, fy, mz read 0.
        tau_nm: joint torques (N m) where the driver knows them, else None.
        truth: the simulator's ground truth (:class:`Truth`), None on a real robot; read by
            logs, reports, plots and viewers only, never by a module, target or planner.
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
    truth: Truth | None = None
    flags: tuple[str, ...] = ()

    def tilt_rad(self) -> tuple[float, float]:
        """Torso tilt about world x (roll) and y (pitch) from the IMU quaternion (rad)."""
        return roll_pitch_of_quat_wxyz(self.imu_quat_wxyz)
