"""Export a run to a Rerun recording (``.rrd``): the URDF animated, the paths, the hole and the
time series on one timeline.

Layout (timeline ``time``, the run's seconds; the recording's start time is the run's, from its
log, so the viewer shows when it happened; the property ``hubo_cli_run`` holds
:func:`~hubo_cli.viz.scene.run_metadata`: versions, start, command, driver, seed):

* ``robot/...``: the URDF (Rerun's URDF loader, static), moved by one transform per joint
  (``transforms/joints/<joint>``, frame ``<parent link>`` -> ``<child link>``) and the torso
  pose (``transforms/torso``, from the root frame ``tf#/``, the world, to ``torso``);
* ``world/walls``, ``world/hole`` (the points as cut, drawn on the wall's face on the robot's
  side, where they can be seen), ``world/goal_path``, ``world/actual_path`` (static) and
  ``world/tool`` (the measured tool point each period), in world coordinates;
* ``plots/<series>`` (:func:`~hubo_cli.viz.scene.time_series`: ``error_mm``,
  ``wrist_torque_nm``, ``cp_margin_mm``, ``torso_pitch_deg``, ``status_code``), and ``events``
  (a text entry, with its level, at each e-stop latch or release and each change of status).

The file carries its blueprint (the viewer's layout): the 3-D view beside three plots, each
grouping series of one unit, and the event log. Open it with ``rerun FILE.rrd``.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.outputs import require_room, writer_failure
from hubo_cli.viz.camera import DEFAULT_PRESET, camera_for
from hubo_cli.viz.deps import require
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, WALL_RGBA, quat_xyzw
from hubo_cli.viz.scene import RunScene, events, run_metadata, time_series

APPLICATION_ID = "hubo-cli"
WORLD_FRAME = "tf#/"  # the implicit frame of the recording's root entity: the world
PROPERTY_NAME = "hubo_cli_run"  # the recording's property holding scene.run_metadata
TEXT_LOG_LEVEL = {"info": "INFO", "warning": "WARN"}  # events' levels in Rerun's words
# the blueprint's plots: title -> the series it groups
PLOT_GROUPS = {"Tracking error and support margin (mm)": ("error_mm", "cp_margin_mm"),
               "Wrist torque (N m) and torso pitch (deg)": ("wrist_torque_nm", "torso_pitch_deg"),
               "Status code": ("status_code",)}


@dataclass
class RrdResult:
    """What :func:`export_rrd` wrote: the file, periods, joints animated and wall time (s)."""

    path: Path
    periods: int
    joints: int
    series: list[str]
    wall_s: float


def _rgb(rgb) -> list[int]:
    return [int(round(255 * c)) for c in rgb[:3]]


def _finite_strip(points: np.ndarray) -> np.ndarray:
    return points[np.all(np.isfinite(points), axis=1)]


def export_rrd(scene: RunScene, out: str | Path) -> RrdResult:
    """Write ``scene`` as a Rerun recording at ``out``.

    Raises:
        MissingOptionalDependency: rerun-sdk is not installed.
        OSError: ENOSPC, the disk is full, before the SDK starts (its save hung at times on a
            full disk) or while it writes (see :func:`hubo_cli.outputs.writer_failure`).
        HuboError: the SDK's writer stopped otherwise.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    require_room(out)
    rr = require("rerun", "the Rerun recording")
    # its name and start time are the run's (not the export's, which the SDK would send)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=scene.run_dir.name,
                             send_properties=False)
    try:
        return _write_rrd(rr, rec, scene, out)
    except RuntimeError as exc:  # the SDK's file writer stopped (a full disk, say)
        raise writer_failure(out, "the Rerun writer", exc) from None
    finally:
        # the stream lets go of its file before the caller removes it (review 22: after a
        # failed write the SDK's sink, flushed again at the interpreter's exit, made the
        # removed temporary file again, empty)
        with contextlib.suppress(Exception):
            rec.disconnect()


def _write_rrd(rr, rec, scene: RunScene, out: Path) -> RrdResult:
    from rerun.urdf import UrdfTree

    started = time.perf_counter()
    rec.save(str(out), default_blueprint=blueprint(rr, scene))
    rec.send_recording_name(scene.run_dir.name)
    rec.send_recording_start_time_nanos(scene.start_utc_ns)
    rec.send_property(PROPERTY_NAME, rr.AnyValues(**run_metadata(scene)))
    urdf = scene.model.urdf_path(scene.drill)
    tree = UrdfTree.from_file_path(urdf, entity_path_prefix="robot")
    tree.log_urdf_to_recording(rec)
    t_s = scene.t_s
    times = [rr.TimeColumn("time", duration=t_s)]
    q = scene.log.joints("q")
    index = {name: i for i, name in enumerate(scene.log.joint_names)}
    animated = 0
    for joint in tree.joints():
        if joint.name in index:
            rec.send_columns(f"transforms/joints/{joint.name}", times,
                             joint.compute_transform_columns(q[:, index[joint.name]].tolist(),
                                                             clamp=False))
            animated += 1
    T = scene.T_world_torso
    root = tree.root_link().name
    rec.send_columns("transforms/torso", times, rr.Transform3D.columns(
        translation=T[:, :3, 3], quaternion=quat_xyzw(T[:, :3, :3]),
        parent_frame=[WORLD_FRAME] * len(T), child_frame=[root] * len(T)))
    _log_world(rr, rec, scene, times)
    names = []
    for name, values in time_series(scene).items():
        rec.send_columns(f"plots/{name}", times, rr.Scalars.columns(scalars=values))
        names.append(name)
    happened = events(scene)
    rec.send_columns("events", [rr.TimeColumn("time", duration=t_s[[k for k, _, _ in happened]])],
                     rr.TextLog.columns(text=[text for _, _, text in happened],
                                        level=[TEXT_LOG_LEVEL[level] for _, level, _ in happened]))
    rec.flush()
    return RrdResult(out, len(scene), animated, names, time.perf_counter() - started)


def blueprint(rr, scene: RunScene):
    """The viewer's layout: the 3-D view (robot and world, seen from the video's camera:
    behind and above the working shoulder, at the hole) beside the plots of
    :data:`PLOT_GROUPS` above the event log."""
    rrb = rr.blueprint
    camera = camera_for(DEFAULT_PRESET, scene.focus_world_m(), scene.working_arm)
    plots = [rrb.TimeSeriesView(name=title, origin="/plots",
                                contents=[f"+ /plots/{name}" for name in names])
             for title, names in PLOT_GROUPS.items()]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="Robot and wall", origin="/",
                              contents=["+ /robot/**", "+ /world/**", "+ /transforms/**"],
                              eye_controls=rrb.EyeControls3D(
                                  position=camera.eye_m, look_target=camera.target_m,
                                  eye_up=(0.0, 0.0, 1.0))),
            rrb.Vertical(*plots, rrb.TextLogView(name="Events", origin="/events"),
                         row_shares=[3] * len(plots) + [2]),
            column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"))


def _log_world(rr, rec, scene: RunScene, times) -> None:
    if scene.walls:
        rec.log("world/walls", rr.Boxes3D(
            centers=[w["centre_world_m"] for w in scene.walls],
            sizes=[w["size_m"] for w in scene.walls],
            quaternions=[[*w["quat_wxyz"][1:], w["quat_wxyz"][0]] for w in scene.walls],
            colors=[_rgb(WALL_RGBA)] * len(scene.walls), fill_mode="solid"), static=True)
    if len(scene.hole_world_m):
        rec.log("world/hole", rr.Points3D(scene.hole_on_face_world_m(), radii=0.0015,
                                          colors=_rgb(HOLE_RGB)), static=True)
    for name, points, rgb in (("goal_path", scene.goal_world_m, GOAL_RGB),
                              ("actual_path", scene.tool_world_m, ACTUAL_RGB)):
        strip = _finite_strip(points)
        if len(strip) > 1:
            rec.log(f"world/{name}", rr.LineStrips3D([strip], radii=0.001, colors=_rgb(rgb)),
                    static=True)
    rec.send_columns("world/tool", times,
                     rr.Points3D.columns(positions=np.nan_to_num(scene.tool_world_m)))
