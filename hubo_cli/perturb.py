"""A simulated robot and world that differ from the nominal ones as a real Hubo and lab do.

:func:`draw` turns a seed into a :class:`Perturbation`: every draw is made from the seed with
numpy's ``Generator`` (PCG64), so the same seed gives the same robot and world on every machine,
and the simulator (:class:`~hubo_cli.drivers.sim.SimDriver`, option ``perturbation``) applies it
through the hooks below. Seed 0 (or no seed) is the nominal robot: no hook changes anything.

What is drawn (the ranges of the project's issue, chosen as a real lab's spread):

- every link's mass scaled by U(0.9, 1.1) (its inertia tensor with it) and its centre of mass
  moved by U(-10, 10) mm along each axis of the link frame (written into a copy of the URDF);
- the feet's friction coefficient U(0.4, 1.0) (the floor's is 1; PyBullet multiplies the two);
- joint encoder noise, N(0, 0.5 mrad) on every measured joint angle;
- IMU orientation noise N(0, 0.2 deg) about each axis plus a constant bias, a rotation of
  U(0, 0.5) deg about a random horizontal axis (the orientation the IMU's own filter reports,
  ``imu_quat_wxyz``);
- the IMU's raw sensors, as a MEMS IMU reads them: the gyro with white noise of density
  0.03 deg/s/sqrt(Hz) (per 5 ms sample, sampled at 200 Hz with a 100 Hz band: 0.3 deg/s) and a
  constant bias of U(-0.5, 0.5) deg/s on each axis; the accelerometer with white noise of density
  150 ug/sqrt(Hz) (1.5 mg = 0.015 m/s^2 a sample) and a constant bias of U(-0.5, 0.5) mg on each
  axis. [chosen] MEMS IMUs of the kind a humanoid's torso carries: Bosch's BMI088 datasheet gives
  0.014 deg/s/sqrt(Hz) and 175 ug/sqrt(Hz) (x, y), with a zero-rate offset of up to 1 deg/s; the
  gyro's bias is left uncalibrated (the attitude filter estimates it), the accelerometer's is
  what a lab's level calibration leaves: it is not observable from gravity and reads as a tilt
  of up to 0.04 deg;
- force/torque noise N(0, 1 N) on forces and N(0, 0.05 N m) on moments, every sensor;
- a command-to-motion delay of U{0..10} physics steps (1 ms each at the default 1 kHz);
- a floor tilted by U(0, 0.5) deg about a random horizontal axis through the origin; the robot
  is set down on it with both soles flat (as it would be placed), so gravity pulls 0-0.5 deg off
  its soles' normal. (Set down level on a tilted rigid floor, the stiff legs would leave one
  sole carrying the whole weight from a roll of 0.3 deg.)

The per-period noise comes from a second stream of the same seed, restarted when the simulator
starts, so a run is repeated exactly by the same seed on the same machine (the physics engine's
own arithmetic may differ in its last bits between CPUs).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.state import FT_MEASURED, GRAVITY_M_S2

MASS_SCALE_RANGE = (0.9, 1.1)
COM_OFFSET_MAX_M = 0.010
FOOT_FRICTION_RANGE = (0.4, 1.0)
ENCODER_NOISE_RAD = 0.5e-3
IMU_NOISE_RAD = math.radians(0.2)
IMU_BIAS_MAX_RAD = math.radians(0.5)
GYRO_NOISE_DENSITY = math.radians(0.03)   # rad/s/sqrt(Hz)
GYRO_BIAS_MAX_RAD_S = math.radians(0.5)   # each axis
ACCEL_NOISE_DENSITY = 150e-6 * GRAVITY_M_S2    # m/s^2/sqrt(Hz)
ACCEL_BIAS_MAX_M_S2 = 0.5e-3 * GRAVITY_M_S2    # each axis
FT_FORCE_NOISE_N = 1.0
FT_MOMENT_NOISE_NM = 0.05
DELAY_MAX_S = 0.010
FLOOR_TILT_MAX_RAD = math.radians(0.5)
FOOT_LINKS = ("RAR_link", "LAR_link")

# the streams of one seed: the draws and the per-period noise; the IMU's raw sensors' draws and
# noise come from streams of their own, so adding them left every other draw as it was
_DRAWS, _NOISE, _IMU_DRAWS, _IMU_NOISE = 0, 1, 2, 3


def _rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix of ``angle_rad`` about the unit vector ``axis`` (Rodrigues)."""
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1 - math.cos(angle_rad)) * K @ K


@dataclass(frozen=True)
class Perturbation:
    """One drawn robot and world (SI units). ``seed`` None is the nominal robot.

    Attributes:
        seed: the seed it was drawn from (None: nominal).
        mass_scale: link name -> factor on its mass and inertia.
        com_offset_m: link name -> (x, y, z) offset of its centre of mass in the link frame.
        foot_friction: friction coefficient of the soles.
        encoder_noise_rad: standard deviation of the joint-angle noise.
        imu_noise_rad: standard deviation of the IMU orientation noise about each axis.
        imu_bias_rad: the IMU's constant bias as a rotation vector (x, y, z).
        gyro_noise_density: the gyro's white noise (rad/s/sqrt(Hz)).
        gyro_bias_rad_s: the gyro's constant bias (x, y, z; torso axes).
        accel_noise_density: the accelerometer's white noise (m/s^2/sqrt(Hz)).
        accel_bias_m_s2: the accelerometer's constant bias (x, y, z; torso axes).
        ft_force_noise_n: standard deviation of every force component.
        ft_moment_noise_nm: standard deviation of every moment component.
        delay_s: command-to-motion delay.
        floor_tilt_rad: the floor's tilt as a rotation vector (x, y, 0).
    """

    seed: int | None = None
    mass_scale: tuple[tuple[str, float], ...] = ()
    com_offset_m: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    foot_friction: float | None = None
    encoder_noise_rad: float = 0.0
    imu_noise_rad: float = 0.0
    imu_bias_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_noise_density: float = 0.0
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_noise_density: float = 0.0
    accel_bias_m_s2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ft_force_noise_n: float = 0.0
    ft_moment_noise_nm: float = 0.0
    delay_s: float = 0.0
    floor_tilt_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def nominal(self) -> bool:
        """True for the nominal robot (nothing is changed)."""
        return self.seed is None

    def to_json(self) -> dict:
        """The draws for ``summary.json`` (mm and degrees where people read them)."""
        if self.nominal:
            return {"seed": None, "nominal": True}
        return {
            "seed": self.seed, "nominal": False,
            "link_mass_scale": dict(self.mass_scale),
            "link_com_offset_mm": {k: [1000 * v for v in d] for k, d in self.com_offset_m},
            "foot_friction": self.foot_friction,
            "encoder_noise_sigma_mrad": 1000 * self.encoder_noise_rad,
            "imu_noise_sigma_deg": math.degrees(self.imu_noise_rad),
            "imu_bias_deg": [math.degrees(v) for v in self.imu_bias_rad],
            "gyro_noise_density_deg_s_rt_hz": math.degrees(self.gyro_noise_density),
            "gyro_bias_deg_s": [math.degrees(v) for v in self.gyro_bias_rad_s],
            "accel_noise_density_m_s2_rt_hz": self.accel_noise_density,
            "accel_bias_m_s2": list(self.accel_bias_m_s2),
            "ft_noise_sigma": {"force_n": self.ft_force_noise_n,
                               "moment_nm": self.ft_moment_noise_nm},
            "delay_ms": 1000 * self.delay_s,
            "floor_tilt_deg": [math.degrees(v) for v in self.floor_tilt_rad],
        }

    # ------------------------------------------------------------------ hooks of the simulator
    def urdf_text(self, text: str) -> str:
        """The URDF ``text`` with the link masses, inertias and centres of mass perturbed."""
        if self.nominal:
            return text
        scale, offset = dict(self.mass_scale), dict(self.com_offset_m)
        root = ET.fromstring(text)
        for link in root.iter("link"):
            name = link.get("name")
            inertial = link.find("inertial")
            if name not in scale or inertial is None:
                continue
            mass = inertial.find("mass")
            mass.set("value", repr(float(mass.get("value")) * scale[name]))
            inertia = inertial.find("inertia")
            for key in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz"):
                inertia.set(key, repr(float(inertia.get(key)) * scale[name]))
            origin = inertial.find("origin")
            if origin is None:
                origin = ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
            xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
            origin.set("xyz", " ".join(repr(float(v)) for v in xyz + offset[name]))
        return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"

    def floor_quat_xyzw(self) -> list[float]:
        """The floor's orientation (PyBullet quaternion x, y, z, w)."""
        rv = np.array(self.floor_tilt_rad)
        angle = float(np.linalg.norm(rv))
        if angle == 0.0:
            return [0.0, 0.0, 0.0, 1.0]
        axis = rv / angle
        return [*(axis * math.sin(angle / 2)).tolist(), math.cos(angle / 2)]

    def T_world_floor(self) -> np.ndarray:
        """The floor's pose in the world (4x4): turned by the tilt about the world origin (the
        simulator stands the robot on it with its soles flat, as it was set down)."""
        T = np.eye(4)
        rv = np.array(self.floor_tilt_rad)
        angle = float(np.linalg.norm(rv))
        if angle > 0.0:
            T[:3, :3] = _rotation(rv / angle, angle)
        return T

    def delay_steps(self, physics_dt_s: float) -> int:
        """The command delay in whole physics steps."""
        return int(round(self.delay_s / physics_dt_s))

    def noise(self, period_s: float = 0.005) -> SensorNoise:
        """A fresh per-period noise source for samples ``period_s`` apart (restart it whenever
        the simulation starts)."""
        return SensorNoise(self, period_s)


def _link_names(urdf_text: str) -> list[str]:
    """The links of a URDF that carry mass, in file order."""
    names = []
    for link in ET.fromstring(urdf_text).iter("link"):
        mass = link.find("inertial/mass")
        if mass is not None and float(mass.get("value")) > 0.0:
            names.append(link.get("name"))
    return names


def draw(seed: int | None, urdf_text: str, physics_dt_s: float = 0.001) -> Perturbation:
    """Draw the robot and world of ``seed`` for the robot described by ``urdf_text``.

    Args:
        seed: a non-negative integer; 0 or None gives the nominal robot.
        urdf_text: the robot's URDF (its links with mass are perturbed, in file order).
        physics_dt_s: the physics step; the delay is a whole number of steps.

    Raises:
        ConfigError: the seed is negative or not an integer.
    """
    if seed is None or seed == 0:
        return Perturbation()
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ConfigError(f"perturbation seed must be a non-negative integer, not {quoted(seed)}",
                          hint="use --perturb 1 (0 is the nominal robot)")
    rng = np.random.default_rng([int(seed), _DRAWS])
    links = _link_names(urdf_text)
    masses = rng.uniform(*MASS_SCALE_RANGE, len(links))
    offsets = rng.uniform(-COM_OFFSET_MAX_M, COM_OFFSET_MAX_M, (len(links), 3))
    friction = rng.uniform(*FOOT_FRICTION_RANGE)
    bias_angle, bias_heading = rng.uniform(0, IMU_BIAS_MAX_RAD), rng.uniform(0, 2 * math.pi)
    delay_steps = int(rng.integers(0, int(round(DELAY_MAX_S / physics_dt_s)) + 1))
    tilt_angle, tilt_heading = rng.uniform(0, FLOOR_TILT_MAX_RAD), rng.uniform(0, 2 * math.pi)

    def horizontal(angle: float, heading: float) -> tuple[float, float, float]:
        return (angle * math.cos(heading), angle * math.sin(heading), 0.0)

    imu = np.random.default_rng([int(seed), _IMU_DRAWS])
    gyro_bias = imu.uniform(-GYRO_BIAS_MAX_RAD_S, GYRO_BIAS_MAX_RAD_S, 3)
    accel_bias = imu.uniform(-ACCEL_BIAS_MAX_M_S2, ACCEL_BIAS_MAX_M_S2, 3)

    return Perturbation(
        seed=int(seed),
        mass_scale=tuple((n, float(s)) for n, s in zip(links, masses, strict=True)),
        com_offset_m=tuple((n, tuple(float(v) for v in d))
                           for n, d in zip(links, offsets, strict=True)),
        foot_friction=float(friction), encoder_noise_rad=ENCODER_NOISE_RAD,
        imu_noise_rad=IMU_NOISE_RAD, imu_bias_rad=horizontal(bias_angle, bias_heading),
        gyro_noise_density=GYRO_NOISE_DENSITY,
        gyro_bias_rad_s=tuple(float(v) for v in gyro_bias),
        accel_noise_density=ACCEL_NOISE_DENSITY,
        accel_bias_m_s2=tuple(float(v) for v in accel_bias),
        ft_force_noise_n=FT_FORCE_NOISE_N, ft_moment_noise_nm=FT_MOMENT_NOISE_NM,
        delay_s=delay_steps * physics_dt_s, floor_tilt_rad=horizontal(tilt_angle, tilt_heading))


def _quat_wxyz_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _matrix_to_quat_wxyz(R: np.ndarray) -> np.ndarray:
    w = math.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


class SensorNoise:
    """The per-period sensor noise of one run (encoders, IMU, force/torque sensors), for
    samples ``period_s`` apart: a white noise of density D has the standard deviation
    D sqrt(1 / (2 period_s)) a sample (its band up to half the sampling rate)."""

    def __init__(self, perturbation: Perturbation, period_s: float = 0.005) -> None:
        self.p = perturbation
        seed = 0 if perturbation.seed is None else perturbation.seed
        self._rng = np.random.default_rng([seed, _NOISE])
        self._imu_rng = np.random.default_rng([seed, _IMU_NOISE])
        band = math.sqrt(0.5 / period_s)
        self._gyro_sigma = perturbation.gyro_noise_density * band
        self._accel_sigma = perturbation.accel_noise_density * band
        self._gyro_bias = np.array(perturbation.gyro_bias_rad_s)
        self._accel_bias = np.array(perturbation.accel_bias_m_s2)
        bias = np.array(perturbation.imu_bias_rad)
        angle = float(np.linalg.norm(bias))
        self._R_bias = np.eye(3) if angle == 0.0 else _rotation(bias / angle, angle)

    def measure(self, state):
        """A copy of ``state`` (a :class:`~hubo_cli.drivers.base.RobotState`) as the noisy
        sensors read it. The simulator's ground truth (``state.truth``) is left as it is."""
        p, rng = self.p, self._rng
        if p.nominal:
            return state
        q = state.q_rad + rng.normal(0.0, p.encoder_noise_rad, state.q_rad.shape)
        noise = rng.normal(0.0, p.imu_noise_rad, 3)
        angle = float(np.linalg.norm(noise))
        R_noise = np.eye(3) if angle == 0.0 else _rotation(noise / angle, angle)
        R_imu = self._R_bias @ R_noise @ _quat_wxyz_to_matrix(state.imu_quat_wxyz)
        sigma = np.array([p.ft_force_noise_n] * 3 + [p.ft_moment_noise_nm] * 3)
        sigma[[k for k in range(6) if k not in FT_MEASURED]] = 0.0  # what the sensors lack
        ft = {name: wrench + rng.normal(0.0, 1.0, 6) * sigma
              for name, wrench in sorted(state.ft.items())}
        imu = self._imu_rng.normal(0.0, 1.0, 6)
        gyro = state.imu_gyro_rad_s + self._gyro_bias + self._gyro_sigma * imu[:3]
        accel = state.imu_accel_m_s2 + self._accel_bias + self._accel_sigma * imu[3:]
        return replace(state, q_rad=q, imu_quat_wxyz=_matrix_to_quat_wxyz(R_imu), ft=ft,
                       imu_gyro_rad_s=gyro, imu_accel_m_s2=accel)


class CommandDelay:
    """Joint commands that reach the motors ``steps`` physics steps after they were sent."""

    def __init__(self, steps: int) -> None:
        self.steps = steps
        self._queue: deque[tuple[int, np.ndarray]] = deque()

    def push(self, now_step: int, q_cmd_rad: np.ndarray) -> None:
        """A command sent at physics step ``now_step``."""
        self._queue.append((now_step + self.steps, np.array(q_cmd_rad, dtype=float)))

    def due(self, now_step: int) -> np.ndarray | None:
        """The latest command whose time has come at ``now_step`` (None: nothing new)."""
        command = None
        while self._queue and self._queue[0][0] <= now_step:
            command = self._queue.popleft()[1]
        return command

    def clear(self) -> None:
        """Drop the commands still on their way (the robot stops)."""
        self._queue.clear()
