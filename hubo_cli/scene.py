"""The scene a run places in the simulator: walls put where the robot holds its tool, the
wall material's reaction to the drill (:class:`CuttingModel`, a task file's ``[scene.cutting]``),
and, from :mod:`hubo_cli.hinged_objects`, the manipulation experiments' valve and door.

A target never holds the simulator: it gets :class:`SceneActions` (issue 33), which acts on the
scene (walls, a valve, a door, a push, the hand's grip) and reads nothing back that a controller
could steer by. Placing the scene where the robot truly stands is the simulator's business and
happens here; what an action returns is for the run's reports only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from hubo_cli.drivers.base import SimulatedWorld
from hubo_cli.hinged_objects import Door, Valve


def _bounded(default: float, maximum: float, positive: bool = False):
    """A coefficient with its default and the largest value a task file may give it."""
    return field(default=default, metadata={"maximum": maximum, "positive": positive})


@dataclass(frozen=True)
class CuttingModel:
    """The wall material's reaction to the spinning drill bit (SI units).

    The simulator applies it every physics step while the bit's flutes cross a wall
    (:class:`hubo_cli.drivers.sim.SimDriver`); task files set it in ``[scene.cutting]`` (any
    field, by name; the defaults are the cardboard's). With ``smooth(v) = v / sqrt(|v|^2 +
    smooth_m_s^2)`` (a unit vector above a few mm/s, fading to zero at rest):

    - across the bit (routing, in the wall plane): ``-(coulomb_n smooth(v) + viscous_n_s_per_m
      v)``, at the point where the bit crosses the wall's mid-plane;
    - along the bit (feed, thrust): ``-(thrust_n smooth(v_a) + thrust_n_s_per_m v_a) p``, where
      ``p`` (0..1) is how much of the bit's point (one bit radius long) is in the material: the
      thrust rises as the point enters the wall and falls once it is through;
    - about the bit (spindle): the material brakes the spinning bit with ``spindle_torque_nm``
      times the flutes' engagement (the share of the wall's thickness they fill) times the
      cutting activity ``|smooth(v)|``; the drill's body takes the reaction, a torque about
      -x of the bit frame (the bit turns clockwise seen from behind the drill, about +x);
    - the depth guide (only with ``guide_depth_m`` > 0): a ring on the bit, ``guide_depth_m``
      behind the bit's middle, that rests on the wall face, as a router's depth guide does. Its
      face pressed ``p`` into the wall pushes the tool back out with ``guide_stiffness_n_m p +
      guide_damping_n_s_m v_in`` (never pulling), and slides on the face with Coulomb friction
      ``guide_friction`` times that (smoothed as above). So the bit cuts at most
      ``guide_depth_m`` deep (its middle past the face) and a tool pressed onto the wall feels
      a steady thrust, which the cutting alone gives only while the point feeds. Off by default.

    Attributes:
        coulomb_n: speed-independent part of the force across the bit (N).
        viscous_n_s_per_m: part proportional to the speed across the bit (N per m/s).
        thrust_n: speed-independent part of the thrust opposing feed (N).
        thrust_n_s_per_m: part proportional to the feed speed (N per m/s).
        spindle_torque_nm: the material's braking torque on the bit while cutting (N m).
        smooth_m_s: speed (m/s) below which the speed-independent parts fade smoothly to zero
            (the position-controlled arm jitters by about 1 mm/s when holding still).
        guide_depth_m: the depth guide's distance behind the bit's middle (m; 0: no guide); at
            most the flutes' half length, so the bit crosses the wall wherever the guide rests.
        guide_stiffness_n_m, guide_damping_n_s_m: the guide's contact with the wall face
            (N/m, N s/m; cardboard yields).
        guide_friction: the guide's sliding friction on the face (ratio to the normal force).
    """

    coulomb_n: float = _bounded(0.5, 1000.0)
    viscous_n_s_per_m: float = _bounded(80.0, 1e5)
    thrust_n: float = _bounded(2.0, 1000.0)
    thrust_n_s_per_m: float = _bounded(200.0, 1e5)
    spindle_torque_nm: float = _bounded(0.02, 10.0)
    smooth_m_s: float = _bounded(0.005, 1.0, positive=True)
    guide_depth_m: float = _bounded(0.0, 0.02)
    guide_stiffness_n_m: float = _bounded(2000.0, 1e6, positive=True)
    guide_damping_n_s_m: float = _bounded(20.0, 1e4)
    guide_friction: float = _bounded(0.2, 2.0)

    def _smooth(self, speed_m_s: float) -> float:
        return 1.0 / math.hypot(speed_m_s, self.smooth_m_s)

    def _across(self, speed_m_s: float) -> float:
        """The force across the bit per m/s of its in-plane velocity (N s/m, negative)."""
        return -(self.coulomb_n * self._smooth(speed_m_s) + self.viscous_n_s_per_m)

    def _spindle(self, speed_m_s: float, engagement: float) -> float:
        return -self.spindle_torque_nm * float(engagement) * speed_m_s * self._smooth(speed_m_s)

    def force_n(self, v_plane_m_s: np.ndarray) -> np.ndarray:
        """The force (N) across the bit for its in-plane velocity (m/s), opposite to it."""
        v = np.asarray(v_plane_m_s, dtype=float)
        return self._across(float(np.linalg.norm(v))) * v

    def thrust_n_along(self, v_axial_m_s: float, point_in_m: float) -> float:
        """The force (N) along the bit's axis for its speed along the axis (m/s, + = feeding
        into the wall) with ``point_in_m`` (0..1) of its point in the material."""
        v = float(v_axial_m_s)
        return -(self.thrust_n * v * self._smooth(abs(v)) + self.thrust_n_s_per_m * v
                 ) * float(point_in_m)

    def spindle_nm(self, v_m_s: np.ndarray, engagement: float) -> float:
        """The torque (N m, about the bit's axis, + = the spindle's turning sense) that the
        material puts on the drill: negative, braking, while the flutes cut."""
        return self._spindle(float(np.linalg.norm(v_m_s)), engagement)

    def guide_force_n(self, pressed_m: float, v_m_s) -> tuple[float, float, float]:
        """The force (N, world; out of the wall is -x) the wall face puts on the depth guide
        pressed ``pressed_m`` into it (<= 0: not touching) moving at ``v_m_s`` (world, m/s);
        zero without a guide."""
        if self.guide_depth_m <= 0.0 or pressed_m <= 0.0:
            return (0.0, 0.0, 0.0)
        vx, vy, vz = v_m_s
        normal = max(0.0, self.guide_stiffness_n_m * pressed_m + self.guide_damping_n_s_m * vx)
        slide = -self.guide_friction * normal * self._smooth(math.sqrt(vy * vy + vz * vz))
        return (-normal, slide * vy, slide * vz)

    def wrench_on_bit(self, v_m_s, axis, flutes: float, point_in_m: float
                      ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """The force (N, world) and torque (N m, world) on a bit moving at ``v_m_s`` (world
        x, y, z; the wall's plane is y, z) along its unit ``axis``: :meth:`force_n` across it
        plus :meth:`thrust_n_along` along it, and :meth:`spindle_nm` about it, in plain floats
        (the simulator applies it every physics step)."""
        vx, vy, vz = v_m_s
        ax, ay, az = axis
        across = self._across(math.sqrt(vy * vy + vz * vz))
        thrust = self.thrust_n_along(vx * ax + vy * ay + vz * az, point_in_m)
        spindle = self._spindle(math.sqrt(vx * vx + vy * vy + vz * vz), flutes)
        return ((thrust * ax, across * vy + thrust * ay, across * vz + thrust * az),
                (spindle * ax, spindle * ay, spindle * az))


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
    """A wall to place once the robot holds its tool ready: ``gap_m`` ahead (world +x) of
    where ``frame`` is then (tasks and drill-mode teleop place it so from the bit)."""

    frame: str
    gap_m: float
    size: WallSize

    def place(self, actions: SceneActions) -> dict:
        """Place it now; returns what was placed (for the run's reports only)."""
        return actions.place_wall(self)


class SceneActions:
    """What a target may do to the simulated scene (issue 33): build walls and hinged objects,
    push the torso, close and open a hand. It has no readers: a target learns how its actions
    went from the robot's sensors (the estimate, the grip flag
    :func:`~hubo_cli.drivers.base.grip_flag`), as on a Hubo. What an action returns is the
    simulator's truth, for the run's reports only (summary, log metadata), never to steer by.
    :attr:`physics_wall_s` is the simulator's CPU clock (a benchmark figure, not the world's
    state)."""

    __slots__ = ("_world",)

    def __init__(self, world: SimulatedWorld) -> None:
        self._world = world

    def add_wall(self, distance_m: float, height_m: float, width_m: float = 1.2,
                 thickness_m: float = 0.01, centre_y_m: float = 0.0) -> None:
        """A wall at the plan's own numbers (world, m: the robot as the simulator sets it
        down, its neck over the origin)."""
        self._world.add_wall(distance_m, height_m, width_m, thickness_m, centre_y_m)

    def place_wall(self, placement: WallPlacement) -> dict:
        """A wall ``placement.gap_m`` ahead of where its frame truly is now (an operator walks
        the robot up to the wall). Returns what was placed, for the reports only."""
        return _place_wall_ahead(self._world, placement.frame, placement.gap_m,
                                 placement.size)

    def place_object(self, spec: Valve | Door, frame: str, T_N_frame: np.ndarray,
                     name: str) -> Valve | Door:
        """A valve or a door planned in the robot's neck frame N (``spec``'s world fields are
        N's), put where the simulator has the robot: moved by where ``frame`` truly is less
        where the kinematics put it (``T_N_frame``), the settled lean included. Returns the
        object as placed (world), for the reports only."""
        shift = _robot_offset_world_m(self._world, frame, T_N_frame)
        if isinstance(spec, Valve):
            placed = replace(spec, centre_world_m=tuple(
                float(v) for v in np.asarray(spec.centre_world_m) + shift))
            self._world.add_valve(placed, name)
        else:
            placed = replace(spec, near_face_x_m=spec.near_face_x_m + float(shift[0]),
                             hinge_y_m=spec.hinge_y_m + float(shift[1]))
            self._world.add_door(placed, name)
        return placed

    def push_torso(self, force_world_n, duration_s: float) -> None:
        """Push the torso at its centre of mass (world force, N) for ``duration_s`` (s)."""
        self._world.push_torso(force_world_n, duration_s)

    def grasp(self, frame: str, name: str, tolerance_m: float) -> float:
        """Close the hand ``frame`` on object ``name`` (it holds when within ``tolerance_m``
        of a grip). Returns the hand's distance from the grip (m), for the reports only; the
        hand's grip flag in the next state says whether it holds."""
        return self._world.grasp(frame, name, tolerance_m)

    def release(self, frame: str) -> None:
        """Open the hand ``frame``."""
        self._world.release(frame)

    @property
    def physics_wall_s(self) -> float:
        """Wall-clock time the simulator spent stepping its physics (s; a benchmark clock)."""
        return self._world.physics_wall_s


def _place_wall_ahead(world: SimulatedWorld, frame: str, gap_m: float, wall: WallSize) -> dict:
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


def _robot_offset_world_m(world: SimulatedWorld, frame: str, T_N_frame: np.ndarray
                          ) -> np.ndarray:
    """Where the simulator has the robot's ``frame`` now, less where the kinematics put it
    (``T_N_frame``, in the neck frame N): the shift (3, m) that places a scene's objects, planned
    in N, in front of the robot as the physics set it down (its settled lean included). Placing
    the scene is the simulator's business; no controller sees this."""
    return world.frame_pose(frame)[:3, 3] - np.asarray(T_N_frame, dtype=float)[:3, 3]
