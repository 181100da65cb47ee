"""Foxglove's messages of a run, built in one place for the MCAP export and the live server.

Both write the same topics, schemas and frame names (:data:`TOPICS`, :data:`WORLD_FRAME`), so
one layout (:data:`LAYOUT_PATH`) shows a recorded run and a live one alike:

* ``/robot_description`` (``std_msgs/String`` in JSON): the URDF, which Foxglove's 3D panel
  loads by itself, as it does ROS's topic of that name;
* ``/joint_states`` (``foxglove.JointStates``): joint positions (rad) and velocities (rad/s);
* ``/tf`` (``foxglove.FrameTransforms``): ``world`` -> ``torso`` and every URDF joint's
  ``parent link`` -> ``child link`` (:class:`JointFrames`);
* ``/scene`` (``foxglove.SceneUpdate``): the walls, the goal and measured tool paths and the
  hole, in ``world``;
* ``/metrics`` (JSON, ``hubo.Metrics``): the scalar series (:data:`~hubo_cli.viz.scene.SERIES`,
  left out where there is no value) and ``status`` (its label);
* ``/events`` (``foxglove.Log``): e-stop latched and released, each change of status;
* ``/safety`` (JSON, ``hubo.Safety``): the safety state, from the period's flags.

The functions take ``fm`` (``foxglove.messages``) so that importing this module does not need
foxglove-sdk (an optional dependency, :func:`~hubo_cli.viz.deps.require`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.status import FLAG_STATUS
from hubo_cli.model import RobotModel
from hubo_cli.urdf import link_frames
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, WALL_RGBA, quat_xyzw
from hubo_cli.viz.scene import SERIES

WORLD_FRAME = "world"
TOPICS = ("/robot_description", "/joint_states", "/tf", "/scene", "/metrics", "/events",
          "/safety")
LAYOUT_PATH = Path(__file__).with_name("foxglove_layout.json")
# ROS's std_msgs/String, the schema Foxglove's 3D panel reads a URDF from
STRING_SCHEMA = {"title": "std_msgs/String", "type": "object",
                 "properties": {"data": {"type": "string"}}}
# the flags of a period that say which stop acts (FLAG_STATUS' names)
SAFETY_FIELDS = {"estop": ("estop",), "collision": ("collision",),
                 "stale_state": ("stale-state", "stale-hold"), "stale_input": ("stale-input",),
                 "servo_off": ("servo-off",), "joint_limit": ("joint-limit",)}
assert all(f in FLAG_STATUS for flags in SAFETY_FIELDS.values() for f in flags)
SAFETY_SCHEMA = {"title": "hubo.Safety", "type": "object",
                 "properties": {**{name: {"type": "boolean"} for name in SAFETY_FIELDS},
                                "flags": {"type": "string"}}}


def metrics_schema() -> dict:
    """``/metrics``' JSON schema: one plain type a field, none required. Foxglove's JSON schema
    parser (``parseJsonSchema``) refuses a type list (``["number", "null"]``), ``"null"`` and
    a field without a type, so a value the run does not have is left out of the message
    (:func:`metrics_message`), never sent as null."""
    properties = {name: {"type": "number"} for name in SERIES}
    properties["status_code"] = {"type": "integer"}
    properties["status"] = {"type": "string"}
    return {"title": "hubo.Metrics", "type": "object", "properties": properties}


@dataclass
class Channels:
    """The run's channels (:data:`TOPICS`) in one foxglove context."""

    description: object
    states: object
    tf: object
    scene: object
    metrics: object
    events: object
    safety: object


def open_channels(foxglove, context) -> Channels:
    """Every topic's channel in ``context`` (an MCAP writer's or the live server's)."""
    from foxglove.channels import (
        FrameTransformsChannel,
        JointStatesChannel,
        LogChannel,
        SceneUpdateChannel,
    )

    return Channels(
        description=foxglove.Channel(TOPICS[0], schema=STRING_SCHEMA, context=context),
        states=JointStatesChannel(TOPICS[1], context=context),
        tf=FrameTransformsChannel(TOPICS[2], context=context),
        scene=SceneUpdateChannel(TOPICS[3], context=context),
        metrics=foxglove.Channel(TOPICS[4], schema=metrics_schema(), context=context),
        events=LogChannel(TOPICS[5], context=context),
        safety=foxglove.Channel(TOPICS[6], schema=SAFETY_SCHEMA, context=context))


def stamp(fm, ns: int):
    """A foxglove Timestamp of UTC nanoseconds since the epoch."""
    return fm.Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


class JointFrames:
    """The URDF's joints as transforms of the joint positions: (parent link, child link,
    N x 4 x 4) for N rows of joint positions (the limb joints rotate about z of their frames).

    Args:
        model: the robot model (its joint names order the positions).
    """

    def __init__(self, model: RobotModel) -> None:
        index = {name: i for i, name in enumerate(model.joint_names)}
        self.joints = [(parent, child, origin, index[name] if kind == "revolute" else None)
                       for name, kind, parent, child, origin, _ in link_frames(model).joints]
        self._origins = np.array([origin for _, _, origin, _ in self.joints])
        self._names = [(WORLD_FRAME, "torso")] + [(p, c) for p, c, _, _ in self.joints]

    def transforms(self, q_rad: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """Every joint's transform for ``q_rad`` (N x joints)."""
        q_rad = np.atleast_2d(q_rad)
        out = []
        for parent, child, origin, i in self.joints:
            if i is None:
                T = np.broadcast_to(origin, (len(q_rad), 4, 4))
            else:
                T = origin @ _rz(q_rad[:, i])
            out.append((parent, child, T))
        return out

    def columns_at(self, T_world_torso: np.ndarray, q_rad: np.ndarray) -> list[tuple]:
        """:func:`transform_columns` of one instant (``world`` -> ``torso`` first, then every
        joint's), for :func:`frame_transforms` with ``k = 0``: all joints in one product."""
        angles = np.array([0.0 if i is None else q_rad[i] for *_, i in self.joints])
        T = np.concatenate([T_world_torso[None], self._origins @ _rz(angles)])
        p, r = T[:, :3, 3].tolist(), quat_xyzw(T[:, :3, :3]).tolist()
        return [(parent, child, [p[k]], [r[k]])
                for k, (parent, child) in enumerate(self._names)]


def _rz(angles: np.ndarray) -> np.ndarray:
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((len(angles), 4, 4))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = c, -s, s, c
    R[:, 2, 2] = R[:, 3, 3] = 1.0
    return R


def transform_columns(parent: str, child: str, T: np.ndarray) -> tuple:
    """(parent, child, translations, quaternions x y z w) of N x 4 x 4 transforms as Python
    lists, for fast messages."""
    return parent, child, T[:, :3, 3].tolist(), quat_xyzw(T[:, :3, :3]).tolist()


def frame_transforms(fm, columns: Sequence[tuple], k: int, ts):
    """The ``/tf`` message of row ``k`` of :func:`transform_columns`' ``columns``."""
    return fm.FrameTransforms(transforms=[
        fm.FrameTransform(timestamp=ts, parent_frame_id=parent, child_frame_id=child,
                          translation=fm.Vector3(x=p[k][0], y=p[k][1], z=p[k][2]),
                          rotation=fm.Quaternion(x=r[k][0], y=r[k][1], z=r[k][2], w=r[k][3]))
        for parent, child, p, r in columns])


def joint_states(fm, names: Sequence[str], q: Sequence[float], dq: Sequence[float], ts):
    """The ``/joint_states`` message of one instant (lists of floats)."""
    return fm.JointStates(timestamp=ts, joints=[
        fm.JointState(name=n, position=p, velocity=v)
        for n, p, v in zip(names, q, dq, strict=True)])


def _color(fm, rgba):
    r, g, b = rgba[:3]
    return fm.Color(r=r, g=g, b=b, a=rgba[3] if len(rgba) > 3 else 1.0)


def scene_update(fm, walls: Iterable[dict], goal_world_m: np.ndarray,
                 tool_world_m: np.ndarray, hole_world_m: np.ndarray, ts):
    """The ``/scene`` message: the walls (as a run's scene metadata places them), the goal
    and measured tool paths (line strips) and the hole (a line list, drawn where given: on the
    wall's face, :func:`~hubo_cli.viz.scene.hole_on_face`); non-finite points are left out."""
    identity = fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    cubes = []
    for wall in walls:
        w, x, y, z = wall["quat_wxyz"]
        cx, cy, cz = wall["centre_world_m"]
        sx, sy, sz = wall["size_m"]
        cubes.append(fm.CubePrimitive(
            pose=fm.Pose(position=fm.Vector3(x=cx, y=cy, z=cz),
                         orientation=fm.Quaternion(x=x, y=y, z=z, w=w)),
            size=fm.Vector3(x=sx, y=sy, z=sz), color=_color(fm, WALL_RGBA)))
    lines = []
    for points, rgb, kind in ((goal_world_m, GOAL_RGB, fm.LinePrimitiveLineType.LineStrip),
                              (tool_world_m, ACTUAL_RGB, fm.LinePrimitiveLineType.LineStrip),
                              (hole_world_m, HOLE_RGB, fm.LinePrimitiveLineType.LineList)):
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        finite = points[np.all(np.isfinite(points), axis=1)]
        if kind == fm.LinePrimitiveLineType.LineList:
            finite = finite[: len(finite) // 2 * 2]
        if len(finite) > 1:
            lines.append(fm.LinePrimitive(
                type=kind, pose=fm.Pose(position=fm.Vector3(x=0.0, y=0.0, z=0.0),
                                        orientation=identity),
                thickness=0.002, scale_invariant=False,
                points=[fm.Point3(x=a, y=b, z=c) for a, b, c in finite.tolist()],
                color=_color(fm, rgb)))
    entity = fm.SceneEntity(timestamp=ts, frame_id=WORLD_FRAME, id="scene", cubes=cubes,
                            lines=lines)
    return fm.SceneUpdate(entities=[entity])


def metrics_message(values: Sequence[float], labels: dict[int, str]) -> dict:
    """One ``/metrics`` message from the values of :data:`SERIES` in order and the status
    labels by code. A field without a value (NaN) is left out: the schema's types
    (:func:`metrics_schema`) hold for every field present."""
    message = {n: v for n, v in zip(SERIES, values, strict=True) if math.isfinite(v)}
    if "status_code" in message:
        code = message["status_code"] = int(message["status_code"])
        message["status"] = labels.get(code, f"code {code}")
    return message


def safety_message(flags: Iterable[str]) -> dict:
    """The ``/safety`` message of a period's flags: which stop acts, and the flags."""
    flags = set(flags)
    message: dict = {name: not flags.isdisjoint(names) for name, names in SAFETY_FIELDS.items()}
    message["flags"] = ";".join(sorted(flags))
    return message


def log_message(fm, level: str, text: str, ts):
    """An ``/events`` message (level ``info`` or ``warning``)."""
    levels = {"info": fm.LogLevel.Info, "warning": fm.LogLevel.Warning}
    return fm.Log(timestamp=ts, level=levels[level], message=text, name="hubo-cli")
