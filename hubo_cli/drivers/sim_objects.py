"""The simulator's hinged objects (:class:`~hubo_cli.hinged_objects.Valve`,
:class:`~hubo_cli.hinged_objects.Door`) as PyBullet multibodies, and a hand's grip on one.

Each object is one ``createMultiBody``: a static base (the valve's panel, the door's frame post)
and one link on a revolute joint. The joint's dry friction is a velocity motor held at zero
speed whose force is capped at the friction torque (PyBullet's usual Coulomb friction: it
holds the joint until the torque on it exceeds the cap, then brakes it with the cap). The
door's closer is an external torque about the hinge, set every physics step from the joint's
angle and rate (:meth:`~hubo_cli.hinged_objects.Door.closer_torque_nm`); its stop is the
joint's limit (closed at 0). Everything else (the wheel's and the leaf's inertia, the
contacts with the robot) is PyBullet's.

The grip (:class:`Grip`) is a stiff spring-damper between the hand link and the valve's wheel at
the hand point, made only when the hand point lies within a tolerance of the rim's centre line
(:meth:`HingedBody.grip_distance_m`), so a hand sent to a misrecognised valve closes on
nothing. A spring rather than a PyBullet constraint: its force is known exactly, so the wrist
sensor reads it with the contacts (``getConstraintState`` of a point-to-point constraint on a
multibody gave neither the size nor the direction of a known 20 N load in a check).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.hinged_objects import Door, Valve

# PyBullet builds at most 16 shapes of a compound (MAX_COMPOUND_COLLISION_SHAPES): more are
# dropped without a word (a 24-segment rim lost its left half, hub and spokes)
RIM_SEGMENTS = 12
HUB_RADIUS_M = 0.03
SPOKES = 3
MAX_COMPOUND_SHAPES = 16
PANEL_HALF_M = (0.01, 0.35, 0.35)   # the valve's mounting panel (x thickness, y, z half sizes)
POST_HALF_M = (0.05, 0.05)          # the door frame's hinge post (x, y half sizes)
# the grip: the fingers and the play between them and the rim give 1 cm under 20 N (a stiffer
# grip against the position-controlled arm turned the few millimetres by which the hand's path
# misses the rim's circle into 100 N); stretched 4 cm (80 N) it slips
GRIP_STIFFNESS_N_M = 2000.0
GRIP_DAMPING_N_S_M = 60.0
GRIP_SLIP_M = 0.04
WOOD_FRICTION = 0.6
# The moving link's contacts are compliant, as the soles' (hubo_cli.drivers.sim): with PyBullet's
# rigid contacts a hand pushing a door open slowly moved it by the solver's position correction
# alone, every contact reporting 0 N while the closer held it shut with 14 N at the hand
CONTACT_STIFFNESS_N_M = 1.0e6
CONTACT_DAMPING_N_S_M = 1.0e4


@dataclass
class HingedBody:
    """One object as built in PyBullet: its body id, its spec and the kind (``valve``,
    ``door``)."""

    kind: str
    spec: Valve | Door
    body_id: int

    def angle_rad(self, p, cid: int) -> float:
        """The joint's angle (rad; the spec's sign)."""
        return float(p.getJointState(self.body_id, 0, physicsClientId=cid)[0])

    def apply_closer(self, p, cid: int) -> None:
        """The door closer's torque for this physics step (nothing for a valve)."""
        if self.kind != "door":
            return
        q, dq = p.getJointState(self.body_id, 0, physicsClientId=cid)[:2]
        tau = self.spec.closer_torque_nm(q, dq)
        if tau:
            p.applyExternalTorque(self.body_id, 0, [0.0, 0.0, tau], p.WORLD_FRAME,
                                  physicsClientId=cid)

    def grip_distance_m(self, p, cid: int, point_world_m: np.ndarray) -> float:
        """How far a point is from the valve rim's centre line (m; inf for a door)."""
        if self.kind != "valve":
            return math.inf
        c = np.asarray(self.spec.centre_world_m, dtype=float)
        d = np.asarray(point_world_m, dtype=float) - c
        in_plane = math.hypot(d[1], d[2])
        return math.hypot(d[0], in_plane - self.spec.radius_m)

    def to_json(self, p, cid: int) -> dict:
        """What the scene report says of it: the spec and its angle now (deg)."""
        spec = {k: (list(v) if isinstance(v, tuple) else v)
                for k, v in self.spec.__dict__.items()}
        return {"kind": self.kind, **spec,
                "angle_deg": round(math.degrees(self.angle_rad(p, cid)), 3)}


def create_valve(p, cid: int, valve: Valve) -> HingedBody:
    """The valve as a multibody: the panel (static) and the wheel on its x axis."""
    cx, cy, cz = valve.centre_world_m
    r, t = valve.radius_m, valve.tube_radius_m
    types, radii, halves, lengths, positions, orientations = [], [], [], [], [], []
    segment = 2 * math.pi * r / RIM_SEGMENTS
    for k in range(RIM_SEGMENTS):  # the rim: boxes along the ring (a square section of 2t)
        a = 2 * math.pi * k / RIM_SEGMENTS
        types.append(p.GEOM_BOX)
        halves.append([t, 0.55 * segment, t])
        radii.append(0.0)
        lengths.append(0.0)
        positions.append([0.0, -r * math.sin(a), r * math.cos(a)])
        orientations.append(p.getQuaternionFromEuler([a, 0.0, 0.0]))
    types.append(p.GEOM_BOX)  # the hub
    halves.append([t, HUB_RADIUS_M, HUB_RADIUS_M])
    radii.append(0.0)
    lengths.append(0.0)
    positions.append([0.0, 0.0, 0.0])
    orientations.append([0.0, 0.0, 0.0, 1.0])
    for k in range(SPOKES):
        a = 2 * math.pi * k / SPOKES
        types.append(p.GEOM_BOX)
        halves.append([t * 0.6, t * 0.6, r / 2])
        radii.append(0.0)
        lengths.append(0.0)
        positions.append([0.0, -r / 2 * math.sin(a), r / 2 * math.cos(a)])
        orientations.append(p.getQuaternionFromEuler([a, 0.0, 0.0]))
    assert len(types) <= MAX_COMPOUND_SHAPES
    wheel = p.createCollisionShapeArray(types, radii=radii, halfExtents=halves, lengths=lengths,
                                        collisionFramePositions=positions,
                                        collisionFrameOrientations=orientations,
                                        physicsClientId=cid)
    panel = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(PANEL_HALF_M),
                                   physicsClientId=cid)
    panel_x = cx + valve.stem_m + PANEL_HALF_M[0]
    body = p.createMultiBody(
        0.0, panel, -1, [panel_x, cy, cz],
        linkMasses=[valve.mass_kg], linkCollisionShapeIndices=[wheel],
        linkVisualShapeIndices=[-1], linkPositions=[[cx - panel_x, 0.0, 0.0]],
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]], linkInertialFramePositions=[[0.0, 0.0, 0.0]],
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]], linkParentIndices=[0],
        linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[1.0, 0.0, 0.0]],
        physicsClientId=cid)
    _brake(p, cid, body, valve.friction_nm)
    p.changeVisualShape(body, -1, rgbaColor=[0.55, 0.55, 0.6, 1], physicsClientId=cid)
    p.changeVisualShape(body, 0, rgbaColor=[0.85, 0.65, 0.1, 1], physicsClientId=cid)
    return HingedBody("valve", valve, body)


def create_door(p, cid: int, door: Door) -> HingedBody:
    """The door as a multibody: the hinge post (static) and the leaf on a vertical axis."""
    w, h, th = door.width_m, door.height_m, door.thickness_m
    post = p.createCollisionShape(p.GEOM_BOX, halfExtents=[POST_HALF_M[0], POST_HALF_M[1],
                                                            h / 2], physicsClientId=cid)
    leaf = p.createCollisionShape(p.GEOM_BOX, halfExtents=[th / 2, w / 2, h / 2 - 0.005],
                                  collisionFramePosition=[th / 2, -w / 2, h / 2 + 0.005],
                                  physicsClientId=cid)
    # the hinge on the leaf's near face at its left edge; the post beyond it, left of the leaf
    hinge = [door.near_face_x_m, door.hinge_y_m, 0.0]
    post_centre = [hinge[0] + POST_HALF_M[0], hinge[1] + POST_HALF_M[1] + 0.002, h / 2]
    body = p.createMultiBody(
        0.0, post, -1, post_centre,
        linkMasses=[door.mass_kg], linkCollisionShapeIndices=[leaf],
        linkVisualShapeIndices=[-1],
        linkPositions=[[hinge[i] - post_centre[i] for i in range(3)]],
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
        linkInertialFramePositions=[[th / 2, -w / 2, h / 2]],
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]], linkParentIndices=[0],
        linkJointTypes=[p.JOINT_REVOLUTE], linkJointAxis=[[0.0, 0.0, 1.0]],
        physicsClientId=cid)
    low, high = door.limits_rad
    p.changeDynamics(body, 0, jointLowerLimit=low, jointUpperLimit=high,
                     lateralFriction=WOOD_FRICTION, physicsClientId=cid)
    _brake(p, cid, body, door.friction_nm)
    p.changeVisualShape(body, -1, rgbaColor=[0.45, 0.35, 0.25, 1], physicsClientId=cid)
    p.changeVisualShape(body, 0, rgbaColor=[0.76, 0.6, 0.42, 1], physicsClientId=cid)
    return HingedBody("door", door, body)


def _brake(p, cid: int, body: int, friction_nm: float) -> None:
    """Dry friction on the joint: a zero-speed velocity motor capped at ``friction_nm``; and
    the moving link's contacts made compliant (``CONTACT_STIFFNESS_N_M``)."""
    p.changeDynamics(body, 0, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                     contactStiffness=CONTACT_STIFFNESS_N_M, contactDamping=CONTACT_DAMPING_N_S_M,
                     physicsClientId=cid)
    p.setJointMotorControl2(body, 0, p.VELOCITY_CONTROL, targetVelocity=0.0,
                            force=float(friction_nm), physicsClientId=cid)


@dataclass
class Grip:
    """A hand holding an object at one point: a stiff spring-damper between the point on the
    hand and the point on the object where it closed (the fingers' compliance), applied by
    :meth:`apply` every physics step to both. Its force is known exactly, so the wrist sensor
    reads it (:meth:`row`). Stretched past ``GRIP_SLIP_M`` (a pull beyond the grip's
    strength, ``GRIP_STIFFNESS_N_M`` times that) the hand loses its hold (:attr:`slipped`)."""

    robot: int
    link: int
    body: HingedBody
    on_hand_m: tuple  # the grip point in the hand link's centre-of-mass frame
    on_object_m: tuple  # ... in the object link's
    force_on_hand_n: tuple = (0.0, 0.0, 0.0)
    at_world_m: tuple = (0.0, 0.0, 0.0)
    slipped: bool = False

    def _point(self, p, cid: int, body: int, link: int, local) -> tuple[tuple, tuple]:
        """A point fixed in a link: where it is and how fast it moves (world)."""
        state = p.getLinkState(body, link, computeLinkVelocity=1, physicsClientId=cid)
        at = p.multiplyTransforms(state[0], state[1], local, (0, 0, 0, 1))[0]
        (vx, vy, vz), (wx, wy, wz) = state[6], state[7]
        rx, ry, rz = at[0] - state[0][0], at[1] - state[0][1], at[2] - state[0][2]
        return at, (vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx)

    def apply(self, p, cid: int) -> None:
        """This physics step's grip force on the hand and its reaction on the object."""
        if self.slipped:
            return
        hand, v_hand = self._point(p, cid, self.robot, self.link, self.on_hand_m)
        held, v_held = self._point(p, cid, self.body.body_id, 0, self.on_object_m)
        stretch = [h - o for h, o in zip(hand, held, strict=True)]
        if math.sqrt(sum(d * d for d in stretch)) > GRIP_SLIP_M:
            self.slipped = True
            self.force_on_hand_n = (0.0, 0.0, 0.0)
            return
        force = tuple(-GRIP_STIFFNESS_N_M * d - GRIP_DAMPING_N_S_M * (a - b)
                      for d, a, b in zip(stretch, v_hand, v_held, strict=True))
        self.force_on_hand_n, self.at_world_m = force, hand
        p.applyExternalForce(self.robot, self.link, force, hand, p.WORLD_FRAME,
                             physicsClientId=cid)
        p.applyExternalForce(self.body.body_id, 0, [-f for f in force], held, p.WORLD_FRAME,
                             physicsClientId=cid)

    def row(self) -> tuple:
        """The last step's grip force on the hand as one row of the simulator's wrench sum
        (the point and the force in the world as a normal times 1, no friction)."""
        return (*self.at_world_m, *self.force_on_hand_n, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0, 0.0)


def make_grip(p, cid: int, robot: int, link: int, point_world_m, body: HingedBody) -> Grip:
    """Hold ``body`` at ``point_world_m`` with the robot's ``link`` (no jump: both ends of the
    spring are that point now)."""
    def local(body_id: int, link_id: int) -> tuple:
        state = p.getLinkState(body_id, link_id, computeForwardKinematics=1,
                               physicsClientId=cid)
        inv_pos, inv_orn = p.invertTransform(state[0], state[1])
        return tuple(p.multiplyTransforms(inv_pos, inv_orn, list(point_world_m),
                                          [0, 0, 0, 1])[0])

    return Grip(robot, link, body, local(robot, link), local(body.body_id, 0),
                at_world_m=tuple(float(v) for v in point_world_m))
