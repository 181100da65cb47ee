"""Synthetic but realistic operator recordings (the samples shipped in ``trajectories/``).

A human operator's hand is not a robot: it trembles (physiological tremor, 8-12 Hz, about a
millimetre, plus slow drift), moves at an uneven speed (each stroke accelerates and slows down,
and strokes differ), hesitates, and rotates a little even when told not to. These generators put
all of that on a planned path and return timed sensor poses in the tracker frame K (x forward,
y right, z down, metres), ready for :func:`hubo_cli.fastrak.capture.poses_to_capture`, which
writes them in the real record format at 120 Hz shared by the stations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.geometry import min_jerk, rpy_to_matrix
from hubo_cli.kinematics.poses import make_transform

SAMPLE_RATE_HZ = 240.0  # the operator's motion is sampled finer than the tracker's 120 Hz


@dataclass(frozen=True)
class OperatorStyle:
    """How the synthetic operator moves.

    Attributes:
        tremor_mm: amplitude of the 8-12 Hz tremor per axis (mm).
        drift_mm: amplitude of the slow (< 0.5 Hz) wander off the path (mm).
        speed_spread: relative spread of the stroke speeds (0.25 = +-25 %).
        wobble_deg: amplitude of the involuntary wrist rotation (deg).
    """

    tremor_mm: float = 1.0
    drift_mm: float = 1.5
    speed_spread: float = 0.25
    wobble_deg: float = 2.0


def _noise(rng: np.random.Generator, t_s: np.ndarray, band_hz: tuple[float, float],
           amplitude: float, components: int = 6) -> np.ndarray:
    """Band-limited noise: a sum of random sinusoids in the band, per axis (3 columns)."""
    out = np.zeros((len(t_s), 3))
    for axis in range(3):
        f = rng.uniform(*band_hz, components)
        phase = rng.uniform(0, 2 * np.pi, components)
        a = rng.uniform(0.5, 1.0, components)
        out[:, axis] = (a[None, :] * np.sin(2 * np.pi * f[None, :] * t_s[:, None]
                                           + phase[None, :])).sum(axis=1)
    return amplitude * out / np.sqrt(np.mean(out**2, axis=0) + 1e-12) / np.sqrt(2)


def _waypoint_path(waypoints_m: np.ndarray, speeds_m_s: np.ndarray, pauses_s: np.ndarray,
                   rate_hz: float) -> np.ndarray:
    """Positions along straight strokes between waypoints, each with a minimum-jerk profile
    (peak speed 1.875 x mean) at its mean speed, followed by its pause."""
    pieces = [np.repeat(waypoints_m[:1], int(pauses_s[0] * rate_hz), axis=0)]
    for k in range(1, len(waypoints_m)):
        a, b = waypoints_m[k - 1], waypoints_m[k]
        n = max(2, int(np.linalg.norm(b - a) / speeds_m_s[k - 1] * rate_hz))
        pieces.append(a + min_jerk(np.linspace(0.0, 1.0, n))[:, None] * (b - a))
        pieces.append(np.repeat(b[None], int(pauses_s[k] * rate_hz), axis=0))
    return np.concatenate(pieces)


def _humanise(path_m: np.ndarray, rng: np.random.Generator, style: OperatorStyle,
              R_K_sensor0: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Add tremor, drift and wrist wobble to a path; returns times and sensor poses T_K."""
    t = np.arange(len(path_m)) / SAMPLE_RATE_HZ
    p = (path_m + _noise(rng, t, (8.0, 12.0), style.tremor_mm / 1000)
         + _noise(rng, t, (0.05, 0.5), style.drift_mm / 1000))
    wobble = _noise(rng, t, (0.1, 1.0), np.radians(style.wobble_deg))
    poses = [make_transform(R_K_sensor0 @ rpy_to_matrix(*w), pk) for pk, w in zip(p, wobble,
                                                                                    strict=True)]
    return t, poses


def rectangle_session(width_m: float = 0.150, height_m: float = 0.100,
                      speed_m_s: float = 0.012, seed: int = 7,
                      style: OperatorStyle | None = None) -> list[tuple[float, int, np.ndarray]]:
    """The paper's experiment: the operator traces a rectangle counter-clockwise (as the robot
    sees the wall) starting at its upper-left corner, right hand on station 1; the idle left
    hand rests on station 2.

    The first sample is at the upper-left corner (teleop calibrates there). Seen from behind the
    robot, left is the robot's +y, i.e. the tracker's -y; up is the tracker's -z. One pause
    of about a second happens at the lower-right corner.

    Returns:
        (t_s, station, T_K_sensor) tuples.
    """
    style = style or OperatorStyle()
    rng = np.random.default_rng(seed)
    start = np.array([0.30, -0.10, -0.20])          # hand 30 cm in front of the transmitter
    # robot view: left = K's -y, up = K's -z; CCW from upper-left: down, right, up, left
    corners = start + np.array([[0, 0, 0], [0, 0, height_m], [0, width_m, height_m],
                                [0, width_m, 0], [0, 0, 0]])
    speeds = speed_m_s * (1 + style.speed_spread * rng.uniform(-1, 1, 4))
    pauses = np.array([1.0, 0.3, 1.1, 0.3, 1.0]) + rng.uniform(0, 0.2, 5)
    path = _waypoint_path(corners, speeds, pauses, SAMPLE_RATE_HZ)
    t, right = _humanise(path, rng, style, np.eye(3))
    rest = np.repeat((start + [0.0, -0.45, 0.05])[None], len(t), axis=0)
    _, left = _humanise(rest, rng, OperatorStyle(0.6, 1.0, 0.0, 1.0), np.eye(3))
    return ([(float(ti), 1, T) for ti, T in zip(t, right, strict=True)]
            + [(float(ti), 2, T) for ti, T in zip(t, left, strict=True)])


def free_session(duration_s: float = 24.0, seed: int = 11,
                 style: OperatorStyle | None = None) -> list[tuple[float, int, np.ndarray]]:
    """Two hands moving freely: reaches, a circle, wrist turns, and a pause mid-way.

    Station 1 is the right hand, station 2 the left. Motions stay within about 8 cm of the
    starting pose and above it or level with it, so the robot's arms can follow from their ready
    posture without reaching down to their own knees or in across the chest (the URDF's
    primitive torso leaves the upper arms about 15 mm of room).
    """
    style = style or OperatorStyle()
    rng = np.random.default_rng(seed)
    out: list[tuple[float, int, np.ndarray]] = []
    for station, side in ((1, 1.0), (2, -1.0)):
        start = np.array([0.30, 0.20 * side, -0.10])
        offsets = np.array([[0, 0, 0], [0.06, 0.02 * side, -0.04], [0.02, 0.05 * side, -0.01],
                            [0.07, 0.03 * side, -0.02], [0, 0, 0]])
        speeds = 0.05 * (1 + style.speed_spread * rng.uniform(-1, 1, 4))
        pauses = np.array([1.0, 0.4, 1.5, 0.4, 0.5])
        reach = _waypoint_path(start + offsets, speeds, pauses, SAMPLE_RATE_HZ)
        n_circle = int(6.0 * SAMPLE_RATE_HZ)
        phase = np.linspace(0, 2 * np.pi, n_circle)
        # a circle above the start (tracker z points down): hands stay clear of the knees
        circle = start + 0.035 * np.column_stack([np.zeros(n_circle), np.sin(phase) * side,
                                                   np.cos(phase) - 1])
        path = np.concatenate([reach, circle])
        total = int(duration_s * SAMPLE_RATE_HZ)
        path = np.concatenate([path, np.repeat(path[-1:], max(0, total - len(path)), axis=0)])
        t, poses = _humanise(path[:total], rng, style, np.eye(3))
        turn = np.radians(20) * np.sin(np.pi * np.clip((t - 8.0) / 4.0, 0, 1)) ** 2
        poses = [T @ make_transform(rpy_to_matrix(a, 0, 0), np.zeros(3))
                 for T, a in zip(poses, turn, strict=True)]
        out += [(float(ti), station, T) for ti, T in zip(t, poses, strict=True)]
    return out
