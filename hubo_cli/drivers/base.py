"""The driver contract every robot back end implements (simulation, hardware, ideal).

A driver is a context manager. Life cycle::

    with make_driver("sim", model) as robot:
        state = robot.start()            # initial posture (home_posture unless given)
        while ...:
            applied = robot.send(q_cmd)  # joint position command, after the driver's checks
            state = robot.step()         # advance one control period (5 ms) and read back
        robot.stop()                     # safe hold; never raises (also done by __exit__)

Joint vectors are numpy arrays in :attr:`RobotModel.joint_names` order (24 limb joints, rad).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.errors import ConfigError
from hubo_cli.geometry import roll_pitch_of_quat_wxyz
from hubo_cli.model import RobotModel

FT_SENSORS = ("right-wrist", "left-wrist", "right-ankle", "left-ankle")


@dataclass
class RobotState:
    """What a driver knows about the robot at one instant.

    Attributes:
        time_s: driver time since start (s).
        q_rad, dq_rad_s: joint positions (rad) and velocities (rad/s), joint_names order.
        imu_quat_wxyz: torso (IMU) orientation in the world frame, unit quaternion w, x, y, z.
        imu_gyro_rad_s: torso angular rate in the IMU frame (rad/s).
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
    ft: dict[str, np.ndarray] = field(
        default_factory=lambda: {name: np.zeros(6) for name in FT_SENSORS})
    tau_nm: np.ndarray | None = None
    T_world_torso: np.ndarray | None = None
    feet_contact: tuple[bool, bool] | None = None
    flags: tuple[str, ...] = ()

    def tilt_rad(self) -> tuple[float, float]:
        """Torso tilt about world x (roll) and y (pitch) from the IMU quaternion (rad)."""
        return roll_pitch_of_quat_wxyz(self.imu_quat_wxyz)


class Driver(ABC):
    """One robot back end. Subclasses implement the five abstract methods.

    Args:
        model: the robot model (joint names and limits).
    """

    name = "abstract"

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self.period_s = model.control_period_s
        self.joint_names = model.joint_names

    @abstractmethod
    def start(self, q0_rad: np.ndarray | None = None) -> RobotState:
        """Bring the robot to its initial posture (home_posture by default) and return its state."""

    @abstractmethod
    def read(self) -> RobotState:
        """The latest state, without advancing time."""

    @abstractmethod
    def send(self, q_cmd_rad: np.ndarray | Mapping[str, float]) -> np.ndarray:
        """Command joint positions (full vector, or a mapping name -> rad for some joints; the
        others keep their last command). Returns the full command actually applied after the
        driver's own checks."""

    @abstractmethod
    def step(self) -> RobotState:
        """Advance one control period (5 ms) and return the new state."""

    @abstractmethod
    def stop(self) -> None:
        """Bring the robot to a safe hold. Never raises; safe to call twice."""

    def close(self) -> None:
        """Release resources (windows, files, ports). Safe to call twice."""

    def __enter__(self) -> Driver:
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.stop()
        finally:
            self.close()

    def full_command(self, last_rad: np.ndarray, q_cmd_rad) -> np.ndarray:
        """Expand a partial mapping command onto the last full command (helper for subclasses)."""
        if isinstance(q_cmd_rad, Mapping):
            q = np.array(last_rad, dtype=float)
            index = {n: i for i, n in enumerate(self.joint_names)}
            for name, value in q_cmd_rad.items():
                if name not in index:
                    raise ConfigError(f"unknown joint {name!r}",
                                      hint=f"joints: {', '.join(self.joint_names)}")
                q[index[name]] = float(value)
            return q
        q = np.asarray(q_cmd_rad, dtype=float)
        if q.shape != (len(self.joint_names),):
            raise ConfigError(f"command has shape {q.shape}, expected ({len(self.joint_names)},)")
        return q


_REGISTRY: dict[str, Callable[..., Driver]] = {}


def register(name: str, factory: Callable[..., Driver]) -> None:
    """Make a driver available to :func:`make_driver` under ``name``."""
    _REGISTRY[name] = factory


def make_driver(name: str, model: RobotModel, **options) -> Driver:
    """Create a driver by name (``sim``, ``hardware``, ``ideal``)."""
    import hubo_cli.drivers.registry  # noqa: F401  (registers the built-in drivers)

    if name not in _REGISTRY:
        raise ConfigError(f"unknown driver {name!r}", hint=f"use one of {', '.join(_REGISTRY)}")
    return _REGISTRY[name](model, **options)
