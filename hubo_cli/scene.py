"""The scene a run places in the simulator: walls put where the robot holds its tool."""

from __future__ import annotations

from dataclasses import dataclass

from hubo_cli.drivers.base import SimulatedWorld


@dataclass(frozen=True)
class WallSize:
    """A box wall's size (m): height from the floor, width along y, thickness along x, and
    the y of its centre in the world."""

    height_m: float
    width_m: float
    thickness_m: float
    centre_y_m: float = 0.0


@dataclass(frozen=True)
class WallPlacement:
    """A wall to place once the robot holds its tool ready: ``gap_m`` ahead of where
    ``frame`` is then, or, with no frame, at x = ``gap_m`` in the world (the neck frame at
    the start, on the floor)."""

    frame: str | None
    gap_m: float
    size: WallSize

    def place(self, world: SimulatedWorld) -> dict:
        """Place it now; returns what was placed."""
        if self.frame is None:
            s = self.size
            world.add_wall(self.gap_m, s.height_m, s.width_m, s.thickness_m, s.centre_y_m)
            return {"kind": "wall", "near_face_x_world_m": self.gap_m, "height_m": s.height_m,
                    "width_m": s.width_m, "thickness_m": s.thickness_m,
                    "centre_y_m": s.centre_y_m}
        return place_wall_ahead(world, self.frame, self.gap_m, self.size)


def place_wall_ahead(world: SimulatedWorld, frame: str, gap_m: float, wall: WallSize) -> dict:
    """Put a wall's near face ``gap_m`` ahead (world +x) of where ``frame`` is now.

    A task or a drill session places its wall once the robot holds its tool ready, as an
    operator brings the standing robot up to a wall (its lean under the balancer included).
    Returns what was placed (for the summary).
    """
    x_m = float(world.frame_pose(frame)[0, 3] + gap_m)
    world.add_wall(x_m, wall.height_m, wall.width_m, wall.thickness_m, wall.centre_y_m)
    return {"kind": "wall", "near_face_x_world_m": x_m, "placed_from": frame, "gap_m": gap_m,
            "height_m": wall.height_m, "width_m": wall.width_m,
            "thickness_m": wall.thickness_m, "centre_y_m": wall.centre_y_m}
