"""Export a run to an MCAP file in Foxglove's schemas (protobuf), for Foxglove Studio.

Topics (log times are the run's seconds since its start, in nanoseconds; one message per period
on each of the first two):

* ``/joint_states`` (``foxglove.JointStates``): the measured joint positions (rad) and
  velocities (rad/s, from the log by finite differences) with the joint names of the URDF;
* ``/tf`` (``foxglove.FrameTransforms``): ``world`` -> ``torso`` (the torso pose) and every URDF
  joint's ``parent link`` -> ``child link``, so Foxglove's 3D panel animates the URDF (add
  ``robots/hubo2plus/hubo2plus[-drill].urdf`` as a URDF layer);
* ``/scene`` (``foxglove.SceneUpdate``, once at the start): the walls, the goal and measured
  tool paths and the hole, in ``world``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.urdf import link_frames
from hubo_cli.viz.deps import require
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, WALL_RGBA, quat_xyzw
from hubo_cli.viz.scene import RunScene

WORLD_FRAME = "world"
TOPICS = ("/joint_states", "/tf", "/scene")


@dataclass
class McapResult:
    """What :func:`export_mcap` wrote: the file, messages per topic and wall time (s)."""

    path: Path
    messages: dict[str, int]
    wall_s: float


def _rz(angles: np.ndarray) -> np.ndarray:
    c, s = np.cos(angles), np.sin(angles)
    R = np.zeros((len(angles), 4, 4))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = c, -s, s, c
    R[:, 2, 2] = R[:, 3, 3] = 1.0
    return R


def joint_transforms(scene: RunScene) -> list[tuple[str, str, np.ndarray]]:
    """(parent link, child link, N x 4 x 4 transform) of every URDF joint over the run (the
    limb joints rotate about z of their frames)."""
    frames = link_frames(scene.model)
    q = scene.log.joints("q")
    index = {name: i for i, name in enumerate(scene.log.joint_names)}
    out = []
    for name, kind, parent, child, origin, _ in frames.joints:
        if kind == "revolute":
            T = origin @ _rz(q[:, index[name]])
        else:
            T = np.broadcast_to(origin, (len(q), 4, 4))
        out.append((parent, child, T))
    return out


def _transform_columns(parent: str, child: str, T: np.ndarray) -> tuple:
    """(parent, child, translations, quaternions x y z w) as Python lists, for fast messages."""
    return parent, child, T[:, :3, 3].tolist(), quat_xyzw(T[:, :3, :3]).tolist()


def _transform(fm, parent: str, child: str, p, q, stamp):
    return fm.FrameTransform(timestamp=stamp, parent_frame_id=parent, child_frame_id=child,
                             translation=fm.Vector3(x=p[0], y=p[1], z=p[2]),
                             rotation=fm.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))


def _color(fm, rgba):
    r, g, b = rgba[:3]
    return fm.Color(r=r, g=g, b=b, a=rgba[3] if len(rgba) > 3 else 1.0)


def _scene_update(fm, scene: RunScene, stamp):
    identity = fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
    cubes = []
    for wall in scene.walls:
        w, x, y, z = wall["quat_wxyz"]
        cx, cy, cz = wall["centre_world_m"]
        sx, sy, sz = wall["size_m"]
        cubes.append(fm.CubePrimitive(
            pose=fm.Pose(position=fm.Vector3(x=cx, y=cy, z=cz),
                         orientation=fm.Quaternion(x=x, y=y, z=z, w=w)),
            size=fm.Vector3(x=sx, y=sy, z=sz), color=_color(fm, WALL_RGBA)))
    lines = []
    for points, rgb, kind in ((scene.goal_world_m, GOAL_RGB, fm.LinePrimitiveLineType.LineStrip),
                              (scene.tool_world_m, ACTUAL_RGB, fm.LinePrimitiveLineType.LineStrip),
                              (scene.hole_world_m, HOLE_RGB, fm.LinePrimitiveLineType.LineList)):
        finite = points[np.all(np.isfinite(points), axis=1)] if len(points) else points
        if kind == fm.LinePrimitiveLineType.LineList:
            finite = finite[: len(finite) // 2 * 2]
        if len(finite) > 1:
            lines.append(fm.LinePrimitive(
                type=kind, pose=fm.Pose(position=fm.Vector3(x=0.0, y=0.0, z=0.0),
                                        orientation=identity),
                thickness=0.002, scale_invariant=False,
                points=[fm.Point3(x=float(a), y=float(b), z=float(c)) for a, b, c in finite],
                color=_color(fm, rgb)))
    entity = fm.SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id="scene", cubes=cubes,
                            lines=lines)
    return fm.SceneUpdate(entities=[entity])


def export_mcap(scene: RunScene, out: str | Path) -> McapResult:
    """Write ``scene`` as an MCAP file in Foxglove's schemas at ``out`` (replaced if present).

    Raises:
        MissingOptionalDependency: foxglove-sdk is not installed.
    """
    foxglove = require("foxglove", "the MCAP file")
    import foxglove.messages as fm
    from foxglove.channels import FrameTransformsChannel, JointStatesChannel, SceneUpdateChannel

    started = time.perf_counter()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t_s = scene.t_s
    t_ns = np.round(t_s * 1e9).astype(np.int64)
    q = scene.log.joints("q")
    dq = np.gradient(q, t_s, axis=0) if len(t_s) > 1 else np.zeros_like(q)
    names = list(scene.log.joint_names)
    columns = [_transform_columns(WORLD_FRAME, "torso", scene.T_world_torso)]
    columns += [_transform_columns(*joint) for joint in joint_transforms(scene)]
    q_list, dq_list = q.tolist(), dq.tolist()
    counts = dict.fromkeys(TOPICS, 0)
    context = foxglove.Context()
    with foxglove.open_mcap(str(out), allow_overwrite=True, context=context):
        states = JointStatesChannel(TOPICS[0], context=context)
        tf = FrameTransformsChannel(TOPICS[1], context=context)
        scene_channel = SceneUpdateChannel(TOPICS[2], context=context)
        scene_channel.log(_scene_update(fm, scene, _stamp(fm, t_ns[0])), log_time=int(t_ns[0]))
        counts[TOPICS[2]] += 1
        for k, ns in enumerate(t_ns.tolist()):
            stamp = _stamp(fm, ns)
            states.log(fm.JointStates(timestamp=stamp, joints=[
                fm.JointState(name=n, position=p, velocity=v)
                for n, p, v in zip(names, q_list[k], dq_list[k], strict=True)]), log_time=ns)
            tf.log(fm.FrameTransforms(transforms=[
                _transform(fm, parent, child, p[k], r[k], stamp)
                for parent, child, p, r in columns]), log_time=ns)
        counts[TOPICS[0]] = counts[TOPICS[1]] = len(t_ns)
    return McapResult(out, counts, time.perf_counter() - started)


def _stamp(fm, ns: int):
    return fm.Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


def read_mcap_summary(path: str | Path) -> dict[str, dict]:
    """Per topic of an MCAP file: schema name, message count and first/last log time (s),
    read back with the ``mcap`` reader."""
    require("mcap", "reading the MCAP file")
    from mcap.reader import make_reader

    topics: dict[str, dict] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            entry = topics.setdefault(channel.topic, {"schema": schema.name if schema else None,
                                                      "messages": 0, "first_s": None,
                                                      "last_s": None})
            entry["messages"] += 1
            t = message.log_time / 1e9
            entry["first_s"] = t if entry["first_s"] is None else min(entry["first_s"], t)
            entry["last_s"] = t if entry["last_s"] is None else max(entry["last_s"], t)
    return topics
