"""The grid a workspace map is solved on, and the tool orientation it is solved for.

All points are tool positions in the neck frame N (x forward = distance to a wall facing the
robot, y left, z up), in metres. Grid values are integer multiples of the resolution, so grids of
different extents but the same resolution share their points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import InputError, quoted
from hubo_cli.kinematics import Limb

ORIENTATIONS = ("wall",)  # named presets; any "roll,pitch,yaw" in degrees is accepted too
# the farthest a requested x or z may be from the neck (m): no tool point of either arm is more
# than 0.63 m away (the drill's reach sphere, centre 0.26 m ahead, radius 0.36 m)
MAX_RANGE_M = 1.0
# the most grid points a map is solved on (the default grid has 1.5 million; each takes about
# 45 bytes, so 20 million about 900 MB: the default range at 2.5 mm has 11.8 million)
MAX_GRID_POINTS = 20_000_000
MAX_ANGLE_DEG = 360.0  # an orientation's roll, pitch and yaw (degrees)


def orientation_matrix(orientation: str) -> np.ndarray:
    """R_N_E (3x3) for a named orientation or ``"roll,pitch,yaw"`` in degrees (R = Rz Ry Rx).

    ``wall``: the tool frame parallel to N, i.e. the drill bit (tool x) pointing straight
    forward, orthogonal to a wall facing the robot (paper IV).
    """
    if orientation == "wall":
        return np.eye(3)
    try:
        roll, pitch, yaw = (math.radians(float(v)) for v in orientation.split(","))
    except ValueError:
        raise InputError(f"unknown orientation {quoted(orientation)}",
                         hint="use 'wall' or 'roll,pitch,yaw' in degrees, e.g. 0,10,0") from None
    if not all(math.isfinite(a) for a in (roll, pitch, yaw)):
        raise InputError(f"orientation {quoted(orientation)} is not finite",
                         hint="use 'wall' or 'roll,pitch,yaw' in degrees, e.g. 0,10,0")
    if not all(abs(a) <= math.radians(MAX_ANGLE_DEG) for a in (roll, pitch, yaw)):
        raise InputError(f"orientation {quoted(orientation)} has an angle beyond "
                         f"±{MAX_ANGLE_DEG:g} degrees",
                         hint="use 'wall' or 'roll,pitch,yaw' in degrees, e.g. 0,10,0")
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


@dataclass(frozen=True)
class ReachSphere:
    """Where the tool point can be at all for a fixed orientation (joint limits ignored).

    The wrist centre (DH frame 5's origin) stays within lA2 + lA3 of the shoulder, and for a
    fixed tool orientation the tool point is the wrist centre plus a constant vector, so the tool
    point stays inside a sphere of that radius around ``centre_m``.
    """

    centre_m: np.ndarray
    radius_m: float


def reach_sphere(limb: Limb, R_N_E: np.ndarray) -> ReachSphere:
    """The :class:`ReachSphere` of an arm's tool point at orientation R_N_E."""
    if not limb.spec.is_arm:
        raise InputError(f"{limb.name} is not an arm", hint="workspace maps are for the arms")
    T_E_6 = np.linalg.inv(limb.T_6_end)
    lA2, lA3, lA4 = limb.lengths_m
    # frame 5's origin seen from the tool frame: frame 6's origin minus lA4 along frame 6's x
    wrist_in_E = T_E_6[:3, 3] - lA4 * T_E_6[:3, 0]
    shoulder = limb.T_N_base[:3, 3]
    return ReachSphere(shoulder - R_N_E @ wrist_in_E, float(lA2 + lA3))


def _lattice(lo_m: float, hi_m: float, step_m: float) -> np.ndarray:
    """Multiples of step_m covering [lo_m, hi_m] (inclusive, rounded outward by < 1e-9 m)."""
    k0 = math.ceil(lo_m / step_m - 1e-9)
    k1 = math.floor(hi_m / step_m + 1e-9)
    return np.arange(k0, k1 + 1) * step_m


@dataclass(frozen=True)
class Grid:
    """A box of tool positions: ``x_m`` (wall distances), ``y_m``, ``z_m`` (1-D, metres)."""

    x_m: np.ndarray
    y_m: np.ndarray
    z_m: np.ndarray
    resolution_m: float

    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, nz, ny): the layout of every per-point array of a map."""
        return len(self.x_m), len(self.z_m), len(self.y_m)

    @property
    def points(self) -> int:
        return len(self.x_m) * len(self.y_m) * len(self.z_m)


def _axis(lo_m: float, hi_m: float, step_m: float) -> np.ndarray:
    """Grid values for a requested range: the lattice points inside it, or the range's single
    value when it is one value (lo == hi), so a study can be pinned to one distance or height."""
    lo_m, hi_m = sorted((lo_m, hi_m))
    if hi_m - lo_m < 1e-9:
        return np.array([lo_m])
    return _lattice(lo_m, hi_m, step_m)


def make_grid(sphere: ReachSphere, resolution_m: float = 0.005,
              x_range_m: tuple[float, float] = (0.30, 0.65),
              z_range_m: tuple[float, float] | None = None) -> Grid:
    """A grid over the wall distances ``x_range_m`` and the y-z box of the reach sphere.

    Args:
        sphere: where the tool point can be at all (:func:`reach_sphere`).
        resolution_m: grid step in all three axes (m).
        x_range_m: first and last wall distance from the neck (m); one value (A, A) maps that
            distance only.
        z_range_m: heights to map (m); default the whole reach sphere; (A, A) maps one height.
    """
    if not (resolution_m > 0 and math.isfinite(resolution_m)):
        raise InputError(f"resolution must be positive, got {resolution_m * 1000:g} mm",
                         hint="pass --resolution 5 (mm)")
    if not all(math.isfinite(v) for v in (*x_range_m, *(z_range_m or ()))):
        raise InputError("--x-range and --z-range must be finite (mm)",
                         hint="e.g. --x-range 300 650")
    if not all(abs(v) <= MAX_RANGE_M for v in (*x_range_m, *(z_range_m or ()))):
        raise InputError(f"--x-range and --z-range must be within ±{MAX_RANGE_M * 1000:g} mm "
                         "of the neck (the arms reach 630 mm at most)",
                         hint="e.g. --x-range 300 650")
    c, r = sphere.centre_m, sphere.radius_m
    z_range_m = z_range_m or (c[2] - r, c[2] + r)
    points = math.prod(abs(b - a) / resolution_m + 1.0
                       for a, b in (x_range_m, z_range_m, (c[1] - r, c[1] + r)))
    if points > MAX_GRID_POINTS:  # counted before any array is made
        raise InputError(f"the grid would have {points:,.0f} points (at most "
                         f"{MAX_GRID_POINTS:,})", hint="make --resolution coarser or "
                                                       "--x-range / --z-range narrower")
    x, z = _axis(*x_range_m, resolution_m), _axis(*z_range_m, resolution_m)
    if len(x) == 0 or len(z) == 0:
        raise InputError("no grid point in the requested range",
                         hint="widen --x-range / --z-range or make --resolution smaller")
    return Grid(x, _lattice(c[1] - r, c[1] + r, resolution_m), z, float(resolution_m))
