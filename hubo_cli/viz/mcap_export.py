"""Export a run to an MCAP file in Foxglove's schemas, for Foxglove (opens with the robot shown).

Times are UTC: the run's start (the log's ``started_utc``; for an older log, its file's
modification time, which the metadata then says) plus each period's time. Topics:

* ``/robot_description`` (``std_msgs/String`` in JSON, once at the start): the URDF the run used,
  which Foxglove's 3D panel loads by itself, as it does ROS's topic of that name;
* ``/joint_states`` (``foxglove.JointStates``, each period): the measured joint positions (rad)
  and velocities (rad/s, from the log by finite differences) with the joint names of the URDF;
* ``/tf`` (``foxglove.FrameTransforms``, each period): ``world`` -> ``torso`` (the torso pose)
  and every URDF joint's ``parent link`` -> ``child link``, so the 3D panel animates the URDF;
* ``/scene`` (``foxglove.SceneUpdate``, once at the start): the walls, the goal and measured
  tool paths and the hole (drawn on the wall's face on the robot's side), in ``world``;
* ``/metrics`` (JSON, ``hubo.Metrics``, each period): the run's scalar series
  (:func:`~hubo_cli.viz.scene.time_series`: ``error_mm``, ``wrist_torque_nm``, ``cp_margin_mm``,
  ``torso_pitch_deg``, ``status_code``; every field in every message, null where the run has
  no value) and ``status`` (its label), for Foxglove's plots;
* ``/events`` (``foxglove.Log``): e-stop latched and released, and each change of status.

The file also holds the URDF as an attachment and one metadata record, ``hubo-cli run``
(:func:`~hubo_cli.viz.scene.run_metadata`). The layout :data:`LAYOUT_PATH` (Foxglove: Layouts,
Import from file) shows the 3D panel, the plots and the event log.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.log import status_codes
from hubo_cli.urdf import link_frames
from hubo_cli.viz.deps import require
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, WALL_RGBA, quat_xyzw
from hubo_cli.viz.scene import SERIES, RunScene, events, run_metadata, time_series

WORLD_FRAME = "world"
TOPICS = ("/robot_description", "/joint_states", "/tf", "/scene", "/metrics", "/events")
METADATA_NAME = "hubo-cli run"
LAYOUT_PATH = Path(__file__).with_name("foxglove_layout.json")
# ROS's std_msgs/String, the schema Foxglove's 3D panel reads a URDF from
STRING_SCHEMA = {"title": "std_msgs/String", "type": "object",
                 "properties": {"data": {"type": "string"}}}


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
                              (scene.hole_on_face_world_m(), HOLE_RGB,
                               fm.LinePrimitiveLineType.LineList)):
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


def _metrics(series: dict[str, np.ndarray], periods: int) -> list[dict]:
    """One ``/metrics`` message per period with every one of :data:`SERIES` (null where the
    run has no value: not logged, or NaN, which JSON lacks)."""
    names = list(SERIES)
    missing = np.full(periods, np.nan)
    rows = np.column_stack([series.get(n, missing) for n in names]).tolist()
    labels = status_codes()
    out = []
    for row in rows:
        message = {n: (v if math.isfinite(v) else None) for n, v in zip(names, row, strict=True)}
        code = message["status_code"] = None if message["status_code"] is None else int(
            message["status_code"])
        message["status"] = None if code is None else labels.get(code, f"code {code}")
        out.append(message)
    return out


def _metrics_schema() -> dict:
    """``/metrics``' JSON schema: one plain type a field (Foxglove reads no type lists; a
    value may still be null)."""
    properties = {name: {"type": "number"} for name in SERIES}
    properties["status_code"] = {"type": "integer"}
    properties["status"] = {"type": "string"}
    return {"title": "hubo.Metrics", "type": "object", "properties": properties}


def export_mcap(scene: RunScene, out: str | Path) -> McapResult:
    """Write ``scene`` as an MCAP file in Foxglove's schemas at ``out`` (replaced if present).

    Raises:
        MissingOptionalDependency: foxglove-sdk is not installed.
    """
    foxglove = require("foxglove", "the MCAP file")
    import foxglove.messages as fm
    from foxglove.channels import (
        FrameTransformsChannel,
        JointStatesChannel,
        LogChannel,
        SceneUpdateChannel,
    )

    started = time.perf_counter()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t_s = scene.t_s
    t_ns = scene.utc_ns()
    q = scene.log.joints("q")
    dq = np.gradient(q, t_s, axis=0) if len(t_s) > 1 else np.zeros_like(q)
    names = list(scene.log.joint_names)
    columns = [_transform_columns(WORLD_FRAME, "torso", scene.T_world_torso)]
    columns += [_transform_columns(*joint) for joint in joint_transforms(scene)]
    q_list, dq_list = q.tolist(), dq.tolist()
    urdf_path = scene.model.urdf_path(scene.drill)
    urdf = urdf_path.read_text()
    counts = dict.fromkeys(TOPICS, 0)
    context = foxglove.Context()
    first = int(t_ns[0])
    with foxglove.open_mcap(str(out), allow_overwrite=True, context=context) as writer:
        writer.write_metadata(METADATA_NAME, run_metadata(scene))
        writer.attach(log_time=first, create_time=urdf_path.stat().st_mtime_ns,
                      name=urdf_path.name, media_type="application/xml", data=urdf.encode())
        description = foxglove.Channel(TOPICS[0], schema=STRING_SCHEMA, context=context)
        states = JointStatesChannel(TOPICS[1], context=context)
        tf = FrameTransformsChannel(TOPICS[2], context=context)
        scene_channel = SceneUpdateChannel(TOPICS[3], context=context)
        metrics = foxglove.Channel(TOPICS[4], schema=_metrics_schema(), context=context)
        log_channel = LogChannel(TOPICS[5], context=context)
        description.log({"data": urdf}, log_time=first)
        scene_channel.log(_scene_update(fm, scene, _stamp(fm, first)), log_time=first)
        happened = {}
        for k, level, text in events(scene):
            happened.setdefault(k, []).append((level, text))
        levels = {"info": fm.LogLevel.Info, "warning": fm.LogLevel.Warning}
        metric_rows = _metrics(time_series(scene), len(scene))
        for k, (ns, metric) in enumerate(zip(t_ns.tolist(), metric_rows, strict=True)):
            stamp = _stamp(fm, ns)
            states.log(fm.JointStates(timestamp=stamp, joints=[
                fm.JointState(name=n, position=p, velocity=v)
                for n, p, v in zip(names, q_list[k], dq_list[k], strict=True)]), log_time=ns)
            tf.log(fm.FrameTransforms(transforms=[
                _transform(fm, parent, child, p[k], r[k], stamp)
                for parent, child, p, r in columns]), log_time=ns)
            metrics.log(metric, log_time=ns)
            for level, text in happened.get(k, ()):
                log_channel.log(fm.Log(timestamp=stamp, level=levels[level],
                                       message=text, name="hubo-cli"), log_time=ns)
                counts[TOPICS[5]] += 1
        counts[TOPICS[0]] = counts[TOPICS[3]] = 1
        counts[TOPICS[1]] = counts[TOPICS[2]] = counts[TOPICS[4]] = len(t_ns)
    return McapResult(out, counts, time.perf_counter() - started)


def _stamp(fm, ns: int):
    return fm.Timestamp(sec=int(ns // 1_000_000_000), nsec=int(ns % 1_000_000_000))


def read_mcap_summary(path: str | Path) -> dict[str, dict]:
    """Per topic of an MCAP file: schema name, message count and first/last log time (s since
    the epoch), read back with the ``mcap`` reader."""
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
