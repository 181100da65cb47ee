"""Export a run to an MCAP file in Foxglove's schemas, for Foxglove (opens with the robot shown).

Times are UTC: the run's start (the log's ``started_utc``; for an older log, its file's
modification time, which the metadata then says) plus each period's time. The topics are the
live server's (:mod:`hubo_cli.viz.foxglove_messages` builds both):

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
  ``torso_pitch_deg``, ``status_code``; a field is left out of a message where the run has no
  value at that period, as Foxglove reads no nullable type) and ``status`` (its label), for
  Foxglove's plots;
* ``/events`` (``foxglove.Log``): e-stop latched and released, and each change of status;
* ``/safety`` (JSON, ``hubo.Safety``, each period): which stop acts (e-stop, collision, stale
  state or input, servos off, joint limit), from the period's flags.

The file also holds the URDF as an attachment and one metadata record, ``hubo-cli run``
(:func:`~hubo_cli.viz.scene.run_metadata`). The layout :data:`LAYOUT_PATH` (Foxglove: Layouts,
Import from file) shows the 3D panel, the plots and the event log.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.log import status_codes
from hubo_cli.outputs import writer_failure
from hubo_cli.viz import foxglove_messages as msg
from hubo_cli.viz.deps import require
from hubo_cli.viz.foxglove_messages import LAYOUT_PATH, TOPICS, WORLD_FRAME
from hubo_cli.viz.scene import SERIES, RunScene, events, run_metadata, time_series

__all__ = ["LAYOUT_PATH", "METADATA_NAME", "McapResult", "export_mcap", "read_mcap_summary"]
METADATA_NAME = "hubo-cli run"


@dataclass
class McapResult:
    """What :func:`export_mcap` wrote: the file, messages per topic and wall time (s)."""

    path: Path
    messages: dict[str, int]
    wall_s: float


def export_mcap(scene: RunScene, out: str | Path) -> McapResult:
    """Write ``scene`` as an MCAP file in Foxglove's schemas at ``out`` (replaced if present).

    Raises:
        MissingOptionalDependency: foxglove-sdk is not installed.
        OSError: ENOSPC, the disk is full (see :func:`hubo_cli.outputs.writer_failure`).
        HuboError: the SDK's writer stopped otherwise.
    """
    foxglove = require("foxglove", "the MCAP file")
    # after a failed write the SDK logs one line per message it is still given (13,830 lines
    # of "McapError(AttemptedWriteAfterFailure)" for a 20 mm cut on a full disk); the
    # failure is raised once, below
    sdk_log = logging.getLogger("foxglove")
    level = sdk_log.level
    sdk_log.setLevel(logging.CRITICAL + 1)
    try:
        return _write_mcap(foxglove, scene, out)
    except RuntimeError as exc:  # the SDK's writer stopped (FoxgloveError: an I/O error)
        raise writer_failure(out, "the MCAP writer", exc) from None
    finally:
        sdk_log.setLevel(level)


def _write_mcap(foxglove, scene: RunScene, out: str | Path) -> McapResult:
    import foxglove.messages as fm

    started = time.perf_counter()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t_s = scene.t_s
    t_ns = scene.utc_ns()
    q = scene.log.joints("q")
    with np.errstate(over="ignore", invalid="ignore"):  # a damaged log's 1e308: inf, no warning
        dq = np.gradient(q, t_s, axis=0) if len(t_s) > 1 else np.zeros_like(q)
    names = list(scene.log.joint_names)
    columns = [msg.transform_columns(WORLD_FRAME, "torso", scene.T_world_torso)]
    columns += [msg.transform_columns(*joint)
                for joint in msg.JointFrames(scene.model).transforms(q)]
    q_list, dq_list = q.tolist(), dq.tolist()
    urdf_path = scene.model.urdf_path(scene.drill)
    urdf = urdf_path.read_text(encoding="utf-8")
    counts = dict.fromkeys(TOPICS, 0)
    context = foxglove.Context()
    first = int(t_ns[0])
    with foxglove.open_mcap(str(out), allow_overwrite=True, context=context) as writer:
        writer.write_metadata(METADATA_NAME, run_metadata(scene))
        writer.attach(log_time=first, create_time=urdf_path.stat().st_mtime_ns,
                      name=urdf_path.name, media_type="application/xml", data=urdf.encode())
        channels = msg.open_channels(foxglove, context)
        channels.description.log({"data": urdf}, log_time=first)
        channels.scene.log(msg.scene_update(fm, scene.walls, scene.goal_world_m,
                                            scene.tool_world_m, scene.hole_on_face_world_m(),
                                            msg.stamp(fm, first)), log_time=first)
        happened = {}
        for k, level, text in events(scene):
            happened.setdefault(k, []).append((level, text))
        series = time_series(scene)
        missing = np.full(len(scene), np.nan)
        labels = status_codes()
        metric_rows = np.column_stack([series.get(n, missing) for n in SERIES]).tolist()
        flags = scene.log.flags
        for k, (ns, metric) in enumerate(zip(t_ns.tolist(), metric_rows, strict=True)):
            ts = msg.stamp(fm, ns)
            channels.states.log(msg.joint_states(fm, names, q_list[k], dq_list[k], ts),
                                log_time=ns)
            channels.tf.log(msg.frame_transforms(fm, columns, k, ts), log_time=ns)
            channels.metrics.log(msg.metrics_message(metric, labels), log_time=ns)
            channels.safety.log(msg.safety_message(flags[k]), log_time=ns)
            for level, text in happened.get(k, ()):
                channels.events.log(msg.log_message(fm, level, text, ts), log_time=ns)
                counts["/events"] += 1
        counts["/robot_description"] = counts["/scene"] = 1
        for topic in ("/joint_states", "/tf", "/metrics", "/safety"):
            counts[topic] = len(t_ns)
    return McapResult(out, counts, time.perf_counter() - started)


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
