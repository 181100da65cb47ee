"""The driver contract every robot back end implements (simulation, hardware, ideal).

A driver is a context manager. Life cycle::

    with make_driver("sim", model) as robot:
        state = robot.start()            # initial posture (home_posture unless given)
        while ...:
            applied = robot.send(q_cmd)  # joint position command, after the driver's checks
            state = robot.step()         # advance one control period (5 ms) and read back
        robot.stop()                     # safe hold; never raises (also done by __exit__)

Drivers are created by name through :func:`hubo_cli.drivers.registry.make_driver`.
Joint vectors are numpy arrays in :attr:`RobotModel.joint_names` order (24 limb joints, rad).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import RobotModel
from hubo_cli.perturb import Perturbation
from hubo_cli.state import RobotState

if TYPE_CHECKING:
    from hubo_cli.hinged_objects import Door, Valve


@dataclass(frozen=True)
class RunContext:
    """What a driver may take from the run it serves.

    Attributes:
        run_dir: the run folder (files a driver writes belong there).
        tools: arm -> tool held (``hand``, ``drill``).
        gui: the user asked for a window.
        cutting: the wall material's cutting coefficients (``coulomb_n``,
            ``viscous_n_s_per_m``), where the scene has one.
        perturb_seed: the seed of a perturbed simulated robot and world (None: nominal).
    """

    run_dir: Path
    tools: Mapping[str, str]
    gui: bool = False
    cutting: Mapping[str, float] | None = None
    perturb_seed: int | None = None


def grip_flag(frame: str) -> str:
    """The state flag a driver raises every period the hand ``frame``'s grip holds an object
    (its fingers closed on it, as the hand's grip sensor reports): how a target learns that a
    grasp took, since it never reads the world (:class:`hubo_cli.scene.SceneActions`)."""
    return f"gripping-{frame}"


class SimulatedWorld(ABC):
    """What a simulator offers beyond the driver contract: a scene, forces, frames, pictures.

    A real robot has none of it: :attr:`Driver.world` is None there, so callers ask for the
    capability once instead of probing a driver for methods. Only the run (session: the scene,
    snapshot and ground truth for the reports) holds it; targets get its actions alone
    (:class:`hubo_cli.scene.SceneActions`).
    """

    @abstractmethod
    def add_wall(self, distance_m: float, height_m: float, width_m: float = 1.2,
                 thickness_m: float = 0.01, centre_y_m: float = 0.0):
        """A static box wall: near face at x = ``distance_m`` in the world (m)."""

    @abstractmethod
    def add_valve(self, valve: Valve, name: str = "valve") -> None:
        """A valve wheel on a revolute joint with friction
        (:class:`~hubo_cli.hinged_objects.Valve`)."""

    @abstractmethod
    def add_door(self, door: Door, name: str = "door") -> None:
        """A hinged door with a closer and a stop (:class:`~hubo_cli.hinged_objects.Door`)."""

    @abstractmethod
    def hinge_angle_rad(self, name: str) -> float:
        """A hinged object's joint angle now (rad)."""

    @abstractmethod
    def grasp(self, frame: str, name: str, tolerance_m: float) -> float:
        """Close the hand ``frame`` on object ``name``; it holds only when the hand point is
        within ``tolerance_m`` of what can be gripped. Returns that distance (m)."""

    @abstractmethod
    def release(self, frame: str) -> None:
        """Open the hand ``frame``."""

    @abstractmethod
    def holding(self, frame: str) -> bool:
        """Whether the hand ``frame`` holds an object."""

    @abstractmethod
    def push_torso(self, force_world_n, duration_s: float) -> None:
        """Push the torso at its centre of mass with a world-frame force (N) for a while (s)."""

    @abstractmethod
    def frame_pose(self, frame: str) -> np.ndarray:
        """World pose (4x4, m) of ``torso`` or a named end frame."""

    @abstractmethod
    def snapshot_png(self, path: str | Path) -> Path:
        """Render the scene headless into a PNG; returns its path."""

    @abstractmethod
    def scene(self) -> dict:
        """What has been placed, for the run's log metadata (JSON-able): ``walls`` (each
        ``centre_world_m``, ``quat_wxyz``, ``size_m``), ``tools`` (arm -> tool),
        ``objects`` (name -> a hinged object's spec, ``kind`` and ``angle_deg`` now),
        ``held`` (hand frame -> the kind it holds) and ``hole_world_m`` / ``hole_t_s`` (where
        and when a drill bit crossed a wall)."""

    @property
    @abstractmethod
    def perturbation(self) -> Perturbation:
        """How the simulated robot and world differ from the nominal ones (the draws)."""

    @property
    @abstractmethod
    def max_tilt_deg(self) -> float:
        """The largest true torso tilt from upright since the start (deg)."""

    @property
    @abstractmethod
    def physics_wall_s(self) -> float:
        """Wall-clock time spent stepping the physics so far (s), for benchmarks."""


class Driver(ABC):
    """One robot back end. Subclasses implement the five abstract methods.

    Class attributes:
        name: the registry name.
        real_time: the driver moves a real robot (or feeds a process that does), so the loop
            must run at wall-clock pace whatever the caller asked for.
        log_columns: numbers the driver adds to every log row (see :meth:`log_values`).

    Attributes (what the driver's sensors are: a class's default, which a driver whose
    answer depends on how it was opened, as the hardware driver's dry run, makes a property):
        accel_measured: the state's ``imu_accel_m_s2`` is a measured specific force (False:
            rebuilt from the tilt, it reads rest whatever the motion, and the estimate
            removes no inertia from the wrists' readings).
        sensors_measured: the state's IMU and force sensors are measured, so a reading no
            working sensor gives is a fault (:mod:`hubo_cli.estimation.plausibility`); False:
            they are made up (the ideal driver, a hardware dry run's echo) and not checked.

    Args:
        model: the robot model (joint names and limits).
    """

    name = "abstract"
    real_time: ClassVar[bool] = False
    accel_measured: bool = True
    sensors_measured: bool = True
    log_columns: tuple[str, ...] = ()

    @property
    def world(self) -> SimulatedWorld | None:
        """The simulator's extras (scene, pushes, frames, snapshots); None on a real robot."""
        return None

    def log_values(self) -> dict[str, float]:
        """This period's values of :attr:`log_columns` (driver-level numbers for the log)."""
        return {}

    def summary_values(self) -> dict[str, object]:
        """The driver's own fields for the run's ``summary.json`` (read at the run's end)."""
        return {}

    @classmethod
    def run_options(cls, run: RunContext) -> dict:
        """Options this driver takes from the run it serves (its files, tools, window)."""
        return {}

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
        if type(q_cmd_rad) is not np.ndarray and isinstance(q_cmd_rad, Mapping):  # (an ABC)
            q = np.array(last_rad, dtype=float)
            index = {n: i for i, n in enumerate(self.joint_names)}
            for name, value in q_cmd_rad.items():
                if name not in index:
                    raise ConfigError(f"unknown joint {quoted(name)}",
                                      hint=f"joints: {', '.join(self.joint_names)}")
                q[index[name]] = float(value)
            return q
        q = np.asarray(q_cmd_rad, dtype=float)
        if q.shape != (len(self.joint_names),):
            raise ConfigError(f"command has shape {q.shape}, expected ({len(self.joint_names)},)")
        return q
