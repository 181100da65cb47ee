"""Export a run to a Rerun recording (``.rrd``): the URDF animated, the paths, the hole and the
time series on one timeline.

Layout (timeline ``time``, the run's seconds):

* ``robot/...``: the URDF (Rerun's URDF loader, static), moved by one transform per joint
  (``transforms/joints/<joint>``, frame ``<parent link>`` -> ``<child link>``) and the torso
  pose (``transforms/torso``, from the root frame ``tf#/``, the world, to ``torso``);
* ``world/walls``, ``world/hole``, ``world/goal_path``, ``world/actual_path`` (static) and
  ``world/tool`` (the measured tool point each period), in world coordinates;
* ``plots/error_mm``, ``plots/wrist_torque_nm``, ``plots/cp_margin_mm`` (capture point inside its
  support polygon, shrunk by the monitor's margin; negative = outside), ``plots/torso_pitch_deg``,
  ``plots/status_code``, and ``status`` (a text entry at each change of status).

Open it with ``rerun FILE.rrd``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.status import Status
from hubo_cli.viz.deps import require
from hubo_cli.viz.replay import ACTUAL_RGB, GOAL_RGB, HOLE_RGB, WALL_RGBA, quat_xyzw
from hubo_cli.viz.scene import ARM_SUFFIX, RunScene, first_column

APPLICATION_ID = "hubo-cli"
WORLD_FRAME = "tf#/"  # the implicit frame of the recording's root entity: the world


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


def series(scene: RunScene) -> dict[str, np.ndarray]:
    """The time series of a run, by plot name (NaN where not logged)."""
    log = scene.log
    suffix = ARM_SUFFIX[scene.working_arm]
    out: dict[str, np.ndarray] = {}
    error = first_column(log, ("error_m", f"error_m{suffix}"))
    if error is not None:
        out["error_mm"] = error * 1000
    torque = first_column(log, ("task_wrist_torque_nm", "wrist_torque_nm"))
    if torque is not None:
        out["wrist_torque_nm"] = torque
    outside = first_column(log, ("cp_outside_m",))
    if outside is not None:
        out["cp_margin_mm"] = -outside * 1000
    T = scene.T_world_torso
    out["torso_pitch_deg"] = np.degrees(np.arctan2(-T[:, 2, 0], np.hypot(T[:, 0, 0], T[:, 1, 0])))
    out["status_code"] = log["status_code"]
    return out


def _finite_strip(points: np.ndarray) -> np.ndarray:
    return points[np.all(np.isfinite(points), axis=1)]


def export_rrd(scene: RunScene, out: str | Path) -> RrdResult:
    """Write ``scene`` as a Rerun recording at ``out``.

    Raises:
        MissingOptionalDependency: rerun-sdk is not installed.
    """
    rr = require("rerun", "the Rerun recording")
    from rerun.urdf import UrdfTree

    started = time.perf_counter()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=scene.run_dir.name)
    rec.save(str(out))
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
    for name, values in series(scene).items():
        rec.send_columns(f"plots/{name}", times, rr.Scalars.columns(scalars=values))
        names.append(name)
    status = scene.log.status
    changes = np.flatnonzero(np.r_[True, status[1:] != status[:-1]])
    rec.send_columns("status", [rr.TimeColumn("time", duration=t_s[changes])],
                     rr.TextLog.columns(text=[Status(int(s)).label for s in status[changes]]))
    rec.flush()
    rec.disconnect()
    return RrdResult(out, len(scene), animated, names, time.perf_counter() - started)


def _log_world(rr, rec, scene: RunScene, times) -> None:
    if scene.walls:
        rec.log("world/walls", rr.Boxes3D(
            centers=[w["centre_world_m"] for w in scene.walls],
            sizes=[w["size_m"] for w in scene.walls],
            quaternions=[[*w["quat_wxyz"][1:], w["quat_wxyz"][0]] for w in scene.walls],
            colors=[_rgb(WALL_RGBA)] * len(scene.walls), fill_mode="solid"), static=True)
    if len(scene.hole_world_m):
        rec.log("world/hole", rr.Points3D(scene.hole_world_m, radii=0.0015,
                                          colors=_rgb(HOLE_RGB)), static=True)
    for name, points, rgb in (("goal_path", scene.goal_world_m, GOAL_RGB),
                              ("actual_path", scene.tool_world_m, ACTUAL_RGB)):
        strip = _finite_strip(points)
        if len(strip) > 1:
            rec.log(f"world/{name}", rr.LineStrips3D([strip], radii=0.001, colors=_rgb(rgb)),
                    static=True)
    rec.send_columns("world/tool", times,
                     rr.Points3D.columns(positions=np.nan_to_num(scene.tool_world_m)))
