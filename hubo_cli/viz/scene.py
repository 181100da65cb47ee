"""What a replay shows, read from a run folder: body poses, tool paths, walls, the hole, captions.

All positions are in the world frame (m). The world pose of the torso comes from the log; where
its position is unknown (hardware) it is estimated by standing the lower sole on the floor under
the torso, with the logged (IMU) orientation. The measured tool path is the logged hand frame
carried to the tool's point; the goal path is the commanded tool position (logged in the task's
stance frame S) carried into the world by the offset between the measured tool in the world and
in S at the first period where both are known (the way a task places its wall).

The run's start in UTC (for exports' absolute times) is the log's ``started_utc``; a log written
before that was recorded gets its file's modification time, and :attr:`RunScene.start_source`
says so.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from hubo_cli import __version__
from hubo_cli.control.log import LogData, load_log, status_codes
from hubo_cli.control.status import Status
from hubo_cli.errors import InputError, quoted
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import ARMS, LEGS, RobotModel, load_model

ARM_SUFFIX = {"right-arm": "_r", "left-arm": "_l"}
# the run's scalar series (time_series), in the order exports show them
SERIES = ("error_mm", "wrist_torque_nm", "cp_margin_mm", "torso_pitch_deg", "status_code")
# statuses whose start is an ``info`` event, not a ``warning``: the pipeline at work
QUIET_STATUSES = frozenset({Status.OK, Status.SLOWING, Status.HOLDING, Status.JOINT_LIMIT})
HOLE_FACE_OFFSET_M = 0.001  # the hole drawn this far in front of the wall's face
START_FROM_LOG = "log"  # RunScene.start_source when the log says when the run started
LATEST_START_NS = 2 ** 62  # a start time after this (year 2116) is not believed
HAND_FRAME = {"right-arm": "right_hand", "left-arm": "left_hand"}


def _columns(log: LogData, stem: str, suffix: str) -> np.ndarray | None:
    names = [f"{stem}_{axis}_m{suffix}" for axis in "xyz"]
    if not all(n in log.columns for n in names):
        return None
    return np.column_stack([log[n] for n in names])


def first_column(log: LogData, names) -> np.ndarray | None:
    """The first of ``names`` that the log has, or None."""
    for name in names:
        if name in log.columns:
            return log[name]
    return None


@dataclass
class RunScene:
    """A run, ready to replay.

    Attributes:
        run_dir: the run folder.
        log: the loaded log.
        model: the robot model.
        T_world_torso: torso poses (N x 4 x 4, m), estimated where the log has no position.
        torso_estimated: True where the torso position was estimated (N,).
        tools: arm -> tool (``drill``, ``hand``, ``none``).
        working_arm: the arm whose tool the paths follow.
        tool_world_m: the measured tool point per period (N x 3).
        goal_world_m: the commanded tool point per period (N x 3), NaN where none was logged.
        walls: walls as placed (``centre_world_m``, ``quat_wxyz``, ``size_m``).
        hole_world_m: where the bit crossed a wall (M x 3).
        start_utc_ns: when the run started (UTC, ns since the epoch).
        start_source: where that comes from: ``"log"`` (the log's ``started_utc``) or a
            sentence naming the file whose modification time stands in for it.
    """

    run_dir: Path
    log: LogData
    model: RobotModel
    T_world_torso: np.ndarray
    torso_estimated: np.ndarray
    tools: dict[str, str]
    working_arm: str
    tool_world_m: np.ndarray
    goal_world_m: np.ndarray
    walls: list[dict] = field(default_factory=list)
    hole_world_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    start_utc_ns: int = 0
    start_source: str = START_FROM_LOG

    @property
    def t_s(self) -> np.ndarray:
        return self.log["t_s"]

    def __len__(self) -> int:
        return len(self.log)

    @property
    def drill(self) -> bool:
        """Whether the robot holds the drill (the URDF with the drill is replayed)."""
        return self.tools.get("right-arm") == "drill"

    def index_at(self, t_s: float) -> int:
        """The last period at or before time ``t_s``."""
        return int(np.clip(np.searchsorted(self.t_s, t_s + 1e-9, side="right") - 1, 0,
                           len(self) - 1))

    def focus_world_m(self) -> np.ndarray:
        """The point a camera should look at: the hole's centre, else the tool's mean path,
        else a point in front of the torso."""
        for points in (self.hole_world_m, self.goal_world_m, self.tool_world_m):
            finite = points[np.all(np.isfinite(points), axis=1)] if len(points) else points
            if len(finite):
                return 0.5 * (finite.min(axis=0) + finite.max(axis=0))
        return self.T_world_torso[0, :3, 3] + np.array([0.35, 0.0, -0.1])

    def utc_ns(self) -> np.ndarray:
        """Each period's time as UTC nanoseconds since the epoch (int64)."""
        return self.start_utc_ns + np.round(self.t_s * 1e9).astype(np.int64)

    def hole_on_face_world_m(self) -> np.ndarray:
        """The hole's points on the face of their wall on the robot's side
        (:func:`hole_on_face`)."""
        return hole_on_face(self.hole_world_m, self.walls, self.T_world_torso[0, :3, 3])

    def caption(self, k: int, step_names=()) -> str:
        """One line describing period ``k``: time, step (``step 3/5 cut`` with the task's
        ``step_names``), error, wrist torque, lean, status."""
        log = self.log
        parts = [f"t {log['t_s'][k]:6.2f} s"]
        step = first_column(log, ("step_code",))
        if step is not None and np.isfinite(step[k]):
            i = int(step[k])
            parts.append(f"step {i + 1}/{len(step_names)} {step_names[i]}"
                         if 0 <= i < len(step_names) else f"step {i + 1}")
        suffix = ARM_SUFFIX[self.working_arm]
        error = first_column(log, ("error_m", f"error_m{suffix}"))
        if error is not None and np.isfinite(error[k]):
            parts.append(f"error {error[k] * 1000:5.1f} mm")
        torque = first_column(log, ("task_wrist_torque_nm", "wrist_torque_nm"))
        if torque is not None and np.isfinite(torque[k]):
            parts.append(f"wrist {torque[k]:4.2f} N m")
        lean = np.degrees(np.arctan2(-self.T_world_torso[k, 2, 0], self.T_world_torso[k, 2, 2]))
        parts.append(f"lean {lean:+4.1f} deg")
        parts.append(f"status {Status(int(log['status_code'][k])).label}")
        return "   ".join(parts)


def hole_on_face(hole_world_m: np.ndarray, walls: list[dict],
                 robot_world_m: np.ndarray) -> np.ndarray:
    """The hole's points moved onto the face of their wall on the robot's side (at
    ``robot_world_m``), plus :data:`HOLE_FACE_OFFSET_M`, where a viewer sees them; the points as
    cut lie inside the wall. A point in no wall stays where it is."""
    points = np.array(hole_world_m, dtype=float).reshape(-1, 3)
    for wall in walls:
        centre, size = np.asarray(wall["centre_world_m"]), np.asarray(wall["size_m"])
        R = quat_wxyz_to_matrix(wall["quat_wxyz"])
        local = (points - centre) @ R  # rows: R.T @ (p - c)
        inside = np.all(np.abs(local) <= size / 2 + 0.005, axis=1)
        thin = int(np.argmin(size))
        side = (np.sign(((robot_world_m - centre) @ R)[thin])
                if np.all(np.isfinite(robot_world_m)) else -1)
        local[inside, thin] = (side or -1) * (size[thin] / 2 + HOLE_FACE_OFFSET_M)
        points[inside] = centre + local[inside] @ R.T
    return points


def series_values(column, working_arm: str, T_world_torso: np.ndarray) -> dict:
    """The scalar series (:data:`SERIES`) by name from a run's columns, for every period of a
    log or one live period: ``column(name)`` gives a log column's values (an array or a number)
    or None; ``T_world_torso``: the torso poses (... x 4 x 4). A series without its column is
    left out; see :func:`time_series`."""
    def first(*names):
        return next((v for v in map(column, names) if v is not None), None)

    suffix = ARM_SUFFIX[working_arm]
    out = {}
    error = first("error_m", f"error_m{suffix}")
    if error is not None:
        out["error_mm"] = error * 1000
    torque = first("task_wrist_torque_nm", "wrist_torque_nm")
    if torque is not None:
        out["wrist_torque_nm"] = torque
    outside = first("cp_outside_m")
    if outside is not None:
        out["cp_margin_mm"] = -outside * 1000
    T = T_world_torso
    out["torso_pitch_deg"] = np.degrees(np.arctan2(-T[..., 2, 0],
                                                   np.hypot(T[..., 0, 0], T[..., 1, 0])))
    out["status_code"] = first("status_code")
    return out


def time_series(scene: RunScene) -> dict[str, np.ndarray]:
    """The run's scalar time series by name (NaN where not logged): ``error_mm`` (tracking
    error of the tool), ``wrist_torque_nm``, ``cp_margin_mm`` (the capture point inside its
    support polygon shrunk by the monitor's margin; negative = outside), ``torso_pitch_deg``
    and ``status_code`` (:data:`SERIES`); a series the log lacks is left out."""
    log = scene.log
    return series_values(lambda name: log[name] if name in log.columns else None,
                         scene.working_arm, scene.T_world_torso)


def estop_event(latched: bool) -> tuple[str, str]:
    """(level, text) of the e-stop latching or releasing."""
    return ("warning", "e-stop latched") if latched else ("info", "e-stop released")


def status_event(code: int, labels: dict[int, str]) -> tuple[str, str]:
    """(level, text) of a change to status ``code`` (``warning`` outside
    :data:`QUIET_STATUSES`)."""
    return ("info" if code in QUIET_STATUSES else "warning",
            f"status: {labels.get(code, f'code {code}')}")


def events(scene: RunScene) -> list[tuple[int, str, str]]:
    """What happened, in order, as (period, level, text): the e-stop latching (``warning``)
    and releasing (``info``), read from the log's ``estop`` flag, and each change of status
    (``info``, or ``warning`` for a status outside :data:`QUIET_STATUSES`)."""
    out = []
    estopped = np.array(["estop" in f for f in scene.log.flags], dtype=bool)
    for k in np.flatnonzero(np.diff(estopped.astype(np.int8), prepend=0)).tolist():
        out.append((k, *estop_event(bool(estopped[k]))))
    status, labels = scene.log.status, status_codes()
    for k in np.flatnonzero(np.r_[True, status[1:] != status[:-1]]).tolist():
        out.append((k, *status_event(int(status[k]), labels)))
    return sorted(out, key=lambda e: e[0])


def run_metadata(scene: RunScene) -> dict[str, str]:
    """What an export says about the run it holds (strings): the hubo-cli that made the run
    and the one that exported it, when it started (UTC ISO 8601) and where that comes from, the
    command, driver and perturbation seed (from ``summary.json`` where the run folder has a
    readable one), the periods, the duration, the URDF and the run folder."""
    log = scene.log
    path = scene.run_dir / "summary.json"
    try:  # only a plain file is read (a FIFO there would hold the export for ever)
        summary = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    except (OSError, UnicodeDecodeError, ValueError):
        summary = {}
    if not isinstance(summary, dict):
        summary = {}
    perturbation = summary.get("perturbation")
    seed = perturbation.get("seed") if isinstance(perturbation, dict) else None
    start_s, start_ns = divmod(scene.start_utc_ns, 1_000_000_000)
    started = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(start_s)) + f".{start_ns:09d}Z"
    values = {"hubo_cli_version": log.hubo_cli_version, "exported_by": f"hubo-cli {__version__}",
              "started_utc": started, "start_time_source": scene.start_source,
              "command": log.metadata.get("command", summary.get("command")),
              "driver": summary.get("driver"), "seed": seed, "periods": len(scene),
              "duration_s": float(scene.t_s[-1] - scene.t_s[0]),
              "urdf": scene.model.urdf_path(scene.drill).name, "run_dir": str(scene.run_dir)}
    return {k: "" if v is None else str(v) for k, v in values.items()}


def _start_utc(log: LogData, log_file: Path) -> tuple[int, str]:
    """(UTC ns since the epoch, source) of the run's start; see the module docstring."""
    text = log.started_utc
    try:
        moment = datetime.fromisoformat(text)
        if moment.tzinfo is None:
            moment = moment.replace(tzinfo=UTC)
        ns = round(moment.timestamp() * 1e6) * 1000
        if 0 <= ns < LATEST_START_NS:
            return ns, START_FROM_LOG
    except (TypeError, ValueError, OverflowError, OSError):
        pass
    stamp = log_file.stat().st_mtime_ns
    why = "no start time" if text is None else f"an unusable start time ({quoted(str(text))})"
    return stamp, (f"the modification time of {log_file.name} (the log has {why}; that is "
                   "when the log was last written, at or after the run's end)")


def _tools(scene_meta: dict) -> dict[str, str]:
    tools = {arm: "hand" for arm in ARMS}
    tools.update(scene_meta.get("tools", {}))
    return tools


def _checked_scene(log: LogData, run_dir: Path) -> dict:
    """The log's scene metadata (walls, tools, hole), checked so that a replay can place it.

    Raises:
        InputError: something in it is not what a run writes.
    """
    scene = log.metadata.get("scene", {})
    problem = _scene_problem(scene)
    if problem is not None:
        raise InputError(f"the scene in {run_dir / 'log.json'} {problem}",
                         hint="give a run folder as hubo wrote it (or remove the scene from "
                              "log.json's metadata to replay without walls)")
    return scene


def _scene_problem(scene) -> str | None:
    """What is wrong with a scene's metadata, or None."""
    if not isinstance(scene, dict):
        return "is not a mapping"
    tools = scene.get("tools", {})
    if not (isinstance(tools, dict)
            and all(isinstance(a, str) and isinstance(t, str) for a, t in tools.items())):
        return "has tools that are not arm -> tool names"
    walls = scene.get("walls", [])
    for k, wall in enumerate(walls if isinstance(walls, list) else [None]):
        if not _wall_ok(wall):
            return (f"has a malformed wall ({k + 1}): each needs centre_world_m and size_m "
                    "(3 finite numbers, the sizes positive) and quat_wxyz (4, not all 0)")
    try:
        hole = np.asarray(scene.get("hole_world_m", []), dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        hole = None
    if hole is None or not np.all(np.isfinite(hole)):
        return "has a hole_world_m that is not a list of finite x, y, z points"
    return None


def _wall_ok(wall) -> bool:
    if not isinstance(wall, dict):
        return False
    try:
        centre = np.asarray(wall["centre_world_m"], dtype=float)
        size = np.asarray(wall["size_m"], dtype=float)
        quat = np.asarray(wall["quat_wxyz"], dtype=float)
    except (KeyError, TypeError, ValueError):
        return False
    return (centre.shape == size.shape == (3,) and quat.shape == (4,)
            and bool(np.all(np.isfinite([*centre, *size, *quat])) and np.all(size > 0)
                     and np.linalg.norm(quat) > 1e-9))


def working_arm(tools: dict[str, str], columns) -> str:
    """The arm whose tool a replay follows: the drill's, else the first whose goals are
    logged (``columns``: the log's column names), else the right."""
    for arm in ARMS:
        if tools.get(arm) == "drill":
            return arm
    for arm in ARMS:
        if all(f"goal_{axis}_m{ARM_SUFFIX[arm]}" in columns for axis in "xyz"):
            return arm
    return "right-arm"


def hand_to_tool(model: RobotModel, tool: str) -> np.ndarray:
    """T_hand_tool: the tool's point seen from the hand frame (4x4, m)."""
    return np.linalg.inv(model.tool_transform("hand")) @ model.tool_transform(tool)


def leg_limbs(model: RobotModel) -> list[tuple[Limb, slice]]:
    """The legs' kinematics and joint slices, for :func:`torso_on_floor`."""
    return [(Limb(model, leg), model.limb_slice(leg)) for leg in LEGS]


def torso_on_floor(legs: list[tuple[Limb, slice]], R_world_torso: np.ndarray,
                   q_rad: np.ndarray) -> np.ndarray:
    """The torso's world position (m) when its lower sole stands on the floor under it, with
    the torso's orientation ``R_world_torso`` and the joint positions ``q_rad``."""
    soles_z = [(R_world_torso @ limb.fk(q_rad[index])[:3, 3])[2] for limb, index in legs]
    return np.array([0.0, 0.0, -min(soles_z)])


def _estimate_torso(model: RobotModel, log: LogData, T: np.ndarray) -> np.ndarray:
    """Fill unknown torso positions: lower sole on the floor, under the torso."""
    unknown = ~np.all(np.isfinite(T[:, :3, 3]), axis=1)
    if not unknown.any():
        return unknown
    q = log.joints("q")
    legs = leg_limbs(model)
    for k in np.flatnonzero(unknown):
        R = T[k, :3, :3] if np.all(np.isfinite(T[k, :3, :3])) else np.eye(3)
        T[k, :3, :3] = R
        T[k, :3, 3] = torso_on_floor(legs, R, q[k])
    return unknown


def _tool_world(model: RobotModel, log: LogData, T_world_torso: np.ndarray, arm: str,
                tool: str) -> np.ndarray:
    T_hand_tool = hand_to_tool(model, tool)
    frame = HAND_FRAME[arm]
    if log.has_pose(frame):
        T_world_hand = log.poses(frame)
    else:
        T_world_hand = np.full((len(log), 4, 4), np.nan)
    # not logged (a log of the first format, or an unknown torso position): forward kinematics
    # of the measured arm through the (estimated) torso pose
    missing = np.flatnonzero(~np.all(np.isfinite(T_world_hand[:, :3, 3]), axis=1))
    if len(missing):
        limb, index = Limb(model, arm, "hand"), model.limb_slice(arm)
        q = log.joints("q")[:, index]
        for k in missing:
            T_world_hand[k] = T_world_torso[k] @ limb.fk(q[k])
    return (T_world_hand @ T_hand_tool)[:, :3, 3]


def _goal_world(log: LogData, arm: str, tool_world_m: np.ndarray) -> np.ndarray:
    suffix = ARM_SUFFIX[arm]
    goal, actual = _columns(log, "goal", suffix), _columns(log, "actual", suffix)
    if goal is None:
        goal, actual = _columns(log, "goal", ""), _columns(log, "actual", "")
    if goal is None or actual is None:
        return np.full_like(tool_world_m, np.nan)
    known = np.all(np.isfinite(np.hstack([goal, actual, tool_world_m])), axis=1)
    if not known.any():
        return np.full_like(tool_world_m, np.nan)
    k = int(np.argmax(known))
    return goal + (tool_world_m[k] - actual[k])


def load_scene(run: str | Path, model: RobotModel | None = None) -> RunScene:
    """Read a run folder (or its log file) into a :class:`RunScene`.

    Raises:
        InputError: no log there, an empty one, one that cannot be read, times that are not
            finite, no measured joint columns, or a scene in its metadata that cannot be placed.
    """
    path = Path(run)
    run_dir = path if path.is_dir() else path.parent
    if not any((run_dir / name).exists() for name in ("log.csv", "log.parquet", "log.rows")):
        raise InputError(f"{path} is not a run folder: {run_dir} has no period log (log.csv)",
                         hint="give a run folder written by hubo task, teleop or push-wall")
    log = load_log(path)
    if len(log) == 0:
        raise InputError(f"the log in {run_dir} has no periods", hint="replay a run that ran")
    model = model or load_model()
    if tuple(log.joint_names) != tuple(model.joint_names):
        raise InputError(f"the log's joints ({len(log.joint_names)}) are not the model's",
                         hint="replay a run of the HUBO 2+ model")
    missing = [f"q_{j}_rad" for j in log.joint_names if f"q_{j}_rad" not in log.columns]
    if missing:
        raise InputError(f"the log in {run_dir} lacks the measured joints' columns "
                         f"({', '.join(missing[:3])}{', ...' if len(missing) > 3 else ''})",
                         hint="give a run folder as hubo wrote it")
    if log.has_pose("torso"):
        T = log.poses("torso")
    else:
        T = np.tile(np.eye(4), (len(log), 1, 1))
        T[:, :3, 3] = np.nan
    estimated = _estimate_torso(model, log, T)
    scene_meta = _checked_scene(log, run_dir)
    tools = _tools(scene_meta)
    arm = working_arm(tools, log.columns)
    tool_world = _tool_world(model, log, T, arm, tools[arm])
    hole = np.asarray(scene_meta.get("hole_world_m", []), dtype=float).reshape(-1, 3)
    log_file = next(f for f in (run_dir / "log.parquet", run_dir / "log.csv",
                                run_dir / "log.rows", path) if f.is_file())
    start_ns, start_source = _start_utc(log, log_file)
    return RunScene(run_dir, log, model, T, estimated, tools, arm, tool_world,
                    _goal_world(log, arm, tool_world), list(scene_meta.get("walls", [])), hole,
                    start_ns, start_source)
