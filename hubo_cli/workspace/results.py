"""Result objects of the workspace study: a segment, a rectangle, and their JSON forms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def mm(value_m: float) -> float:
    """Metres to millimetres, rounded to the micrometre (for reports)."""
    return round(float(value_m) * 1000.0, 3)


@dataclass(frozen=True)
class Segment:
    """A horizontal segment of tool positions reachable on one IK branch.

    Attributes:
        wall_distance_m: x of the segment in the neck frame (the wall's distance from the neck).
        z_m: height of the segment above the neck (m).
        y_min_m, y_max_m: its ends (m; y_min is the robot's right end).
        branch: the IK candidate index (0-7) every point of it is reached with.
        q_min_rad, q_max_rad: the arm's joints (6,) at the y_min and y_max ends.
    """

    wall_distance_m: float
    z_m: float
    y_min_m: float
    y_max_m: float
    branch: int
    q_min_rad: np.ndarray
    q_max_rad: np.ndarray

    @property
    def width_m(self) -> float:
        return self.y_max_m - self.y_min_m

    def to_json(self) -> dict:
        """Millimetres and radians, for summary.json and ``--json``."""
        return {
            "wall_distance_mm": mm(self.wall_distance_m),
            "width_mm": mm(self.width_m),
            "height_mm": mm(self.z_m),
            "y_min_mm": mm(self.y_min_m),
            "y_max_mm": mm(self.y_max_m),
            "branch": self.branch,
            "q_y_min_rad": [round(float(v), 4) for v in self.q_min_rad],
            "q_y_max_rad": [round(float(v), 4) for v in self.q_max_rad],
        }


@dataclass(frozen=True)
class Rectangle:
    """An axis-aligned rectangle in a wall's y-z plane, every grid point of it reachable on
    one IK branch.

    Attributes:
        wall_distance_m: x of the wall plane in the neck frame (m).
        y_min_m, y_max_m, z_min_m, z_max_m: bounds in the neck frame (m).
        branch: the IK candidate index (0-7) that reaches all of it.
    """

    wall_distance_m: float
    y_min_m: float
    y_max_m: float
    z_min_m: float
    z_max_m: float
    branch: int

    @property
    def width_m(self) -> float:
        return self.y_max_m - self.y_min_m

    @property
    def height_m(self) -> float:
        return self.z_max_m - self.z_min_m

    @property
    def area_m2(self) -> float:
        return self.width_m * self.height_m

    @property
    def centre_m(self) -> np.ndarray:
        """Centre of the rectangle in the neck frame (x, y, z), m."""
        return np.array([self.wall_distance_m, 0.5 * (self.y_min_m + self.y_max_m),
                         0.5 * (self.z_min_m + self.z_max_m)])

    def to_json(self) -> dict:
        """Millimetres, for summary.json and ``--json``."""
        return {
            "wall_distance_mm": mm(self.wall_distance_m),
            "width_mm": mm(self.width_m),
            "height_mm": mm(self.height_m),
            "y_min_mm": mm(self.y_min_m),
            "y_max_mm": mm(self.y_max_m),
            "z_min_mm": mm(self.z_min_m),
            "z_max_mm": mm(self.z_max_m),
            "branch": self.branch,
        }
