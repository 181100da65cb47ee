"""One teleoperation run: source -> mapping -> whole body -> pipeline -> driver -> run folder."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.control.log import load_log, max_velocity_ratio
from hubo_cli.control.loop import ControlLoop, LoopResult
from hubo_cli.control.pipeline import DEFAULT_ORDER, build_pipeline
from hubo_cli.drivers.base import make_driver
from hubo_cli.fastrak.source import open_source
from hubo_cli.kinematics.interpolate import PosePath, PoseSegment, segment_duration
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import load_model
from hubo_cli.plots.paths import plot_path_comparison
from hubo_cli.posture import home_posture
from hubo_cli.runs import make_run_dir, write_json
from hubo_cli.teleop.mapping import HandMapper, MappingConfig
from hubo_cli.teleop.target import TeleopTarget

PAPER_HOLE_M = (0.150, 0.100)  # the paper's cut (V): drill mode starts at its upper-left corner
APPROACH_SPEED_M_S = 0.05      # mean speed of the bit's move into the wall
STANDOFF_M = 0.05              # drill mode: the bit stops this far before the wall, then goes in
# free mode: forearms forward, hands 30 cm in front of the chest, 23 cm below the shoulders:
# 92-94 % of an 8 cm cube around it is reachable at the same hand orientation
FREE_READY_ARM_RAD = {"right-arm": (0.0, -0.15, 0.0, -1.4, 0.0, 0.0),
                      "left-arm": (0.0, 0.15, 0.0, -1.4, 0.0, 0.0)}
WALL_SIZE_M = (1.2, 2.0)       # width, height of the simulated cardboard wall
WALL_THICKNESS_M = 0.005


@dataclass
class TeleopSettings:
    """What to run (see ``hubo teleop --help`` for the user's view).

    Attributes:
        replay: a raw capture or pose log to replay (or None with ``port``).
        port: a serial port with a live FASTRAK.
        driver: ``sim``, ``hardware`` or ``ideal``.
        mode: ``free`` or ``drill``.
        speed: None = as fast as possible, 1.0 = real time.
        scale: robot metres per operator metre.
        station_arm: tracker station -> arm (None: 1 -> right, 2 -> left; drill: 1 -> right).
        wall_distance_m: drill mode wall distance (None: the workspace map's best stance).
        duration_s: stop after this long (live mode; None = until q / Ctrl-C).
        clutch_at_s: replay times at which to re-centre.
        out: run folder (None: runs/<time>-teleop).
        gui, baud, estop, driver_options: passed on.
    """

    replay: str | Path | None = None
    port: str | None = None
    driver: str = "sim"
    mode: str = "free"
    speed: float | None = None
    scale: float = 1.0
    station_arm: dict[int, str] | None = None
    wall_distance_m: float | None = None
    duration_s: float | None = None
    clutch_at_s: tuple[float, ...] = ()
    out: str | Path | None = None
    gui: bool = False
    baud: int = 115200
    estop: bool = True
    driver_options: dict = field(default_factory=dict)


@dataclass
class TeleopRun:
    """A finished run: its folder, summary and how the loop ended."""

    run_dir: Path
    summary: dict
    loop: LoopResult


def drill_stance(wall_distance_m: float | None = None) -> tuple[float, np.ndarray, float]:
    """Where to stand and start for a drill cut of the paper's size (paper IV, III-A).

    The stance is the workspace map's largest one-branch rectangle of the wall for the drill
    held orthogonal to it, so the arm has vertical room around its working height; the legs
    take the rest of the height (the widest single segment, the paper's criterion, is a ridge
    a few millimetres tall: any lag of the legs would leave the arm out of reach). Returns
    (wall distance m, the upper-left corner of a paper-size hole centred in that rectangle
    (m, in S), the rectangle's mid height m = the working height).
    """
    from hubo_cli.workspace.stance import best_stance

    stance = best_stance(tool="drill", arm="right", vertical="arm")
    rect = stance.rectangle
    wall = stance.wall_distance_m if wall_distance_m is None else wall_distance_m
    y_mid, z_mid = (rect.y_min_m + rect.y_max_m) / 2, (rect.z_min_m + rect.z_max_m) / 2
    corner = np.array([wall, y_mid + PAPER_HOLE_M[0] / 2, z_mid + PAPER_HOLE_M[1] / 2])
    return wall, corner, z_mid


def station_map(settings: TeleopSettings) -> dict[int, str]:
    """Tracker station -> arm: the settings' map, or the mode's default."""
    if settings.station_arm is not None:
        return dict(settings.station_arm)
    return {1: "right-arm"} if settings.mode == "drill" else {1: "right-arm", 2: "left-arm"}


def prepare(settings: TeleopSettings):
    """Build everything before the robot starts (errors surface before anything moves).

    Returns (model, whole-body solver, mapping, scene). The legs' working height is where the
    hands start (free mode: the legs follow only the operator's height changes) or the middle
    of the reachable rectangle (drill mode).
    """
    model = load_model()
    stations = station_map(settings)
    tools = {arm: "hand" for arm in stations.values()}
    scene: dict = {}
    if settings.mode == "drill":
        tools["right-arm"] = "drill"
        wall, start, height = drill_stance(settings.wall_distance_m)
        scene = {"wall_distance_m": wall, "start_m": start, "working_height_m": height}
        body = WholeBody(model, tools, height)
    else:
        body = WholeBody(model, tools)
        heights = [body.arms[a].fk(np.array(FREE_READY_ARM_RAD[a]))[2, 3] for a in tools]
        body.working_height_m = float(np.mean(heights))
    mapping = MappingConfig(station_arm=stations, scale=settings.scale, mode=settings.mode,
                            wall_distance_m=scene.get("wall_distance_m", 0.484))
    return model, body, mapping, scene


def run_teleop(settings: TeleopSettings, on_ready=None) -> TeleopRun:
    """Run one teleoperation session and write its run folder.

    Args:
        settings: what to run.
        on_ready: called with the :class:`TeleopTarget` and the pipeline's modules once the
            robot has started (the CLI attaches its live view and key reader there).

    Raises:
        InputError / DeviceError: a bad recording, a missing port (before anything moves).
    """
    model, body, mapping, scene = prepare(settings)
    q_start = home_posture(model)
    approach = approach_paths(body, mapping.station_arm.values(), scene)
    live = settings.port is not None
    source = open_source(replay=settings.replay, port=settings.port, baud=settings.baud)
    run_dir = make_run_dir("teleop", settings.out)
    options = dict(settings.driver_options)
    if settings.driver == "sim":
        options.update(gui=settings.gui, drill=settings.mode == "drill")
    order = DEFAULT_ORDER if settings.estop else tuple(
        n for n in DEFAULT_ORDER if n not in ("estop", "hard-estop", "capture-point"))
    with source, make_driver(settings.driver, model, **options) as driver:
        driver.start(q_start)

        def place_wall() -> None:
            if settings.mode == "drill" and hasattr(driver, "add_wall"):
                driver.add_wall(scene["wall_distance_m"], WALL_SIZE_M[1], WALL_SIZE_M[0],
                                WALL_THICKNESS_M)

        target = TeleopTarget(model, source, HandMapper(mapping), body, approach, q_start,
                              live=live, clutch_at_s=settings.clutch_at_s,
                              on_pre_pose=place_wall)
        modules = build_pipeline(model, order)
        if on_ready is not None:
            on_ready(target, modules)
        loop = ControlLoop(driver, modules, target, speed=settings.speed, log_path=run_dir)
        duration = settings.duration_s
        if duration is None and not live:
            duration = (source.end_s - source.start_s) + target.approach_timeout_s + 30.0
        result = loop.run(duration)
        if hasattr(driver, "snapshot_png"):
            driver.snapshot_png(run_dir / "snapshot.png")
    summary = summarise(settings, model, target, result, run_dir, source, scene)
    write_json(run_dir / "summary.json", summary)
    return TeleopRun(run_dir, summary, result)


def approach_paths(body: WholeBody, arms, scene: dict) -> dict[str, PosePath]:
    """Each driven hand's approach path (goals in S); its first pose is reached in joint space.

    Free mode: the hands' ready pose (forearms forward). Drill mode: from ``STANDOFF_M`` before
    the wall, orthogonal to it, straight in to the start point.
    """
    paths = {}
    for arm in arms:
        T_ready = body.arms[arm].fk(np.array(FREE_READY_ARM_RAD[arm]))
        if scene and arm == "right-arm":
            T_wall = np.eye(4)
            T_wall[:3, 3] = scene["start_m"]
            T_off = T_wall.copy()
            T_off[0, 3] -= STANDOFF_M
            paths[arm] = PosePath([PoseSegment(T_off, T_wall, segment_duration(
                T_off, T_wall, APPROACH_SPEED_M_S))])
        else:
            paths[arm] = PosePath([PoseSegment(T_ready, T_ready, 0.0)])
    return paths


def summarise(settings, model, target: TeleopTarget, result: LoopResult, run_dir: Path,
              source, scene: dict) -> dict:
    """The run's summary.json content; also draws the path plots into the run folder."""
    rms, peak, files = {}, {}, ["log.csv", "summary.json"]
    for arm, errors in target.errors_m.items():
        if errors:
            e = np.asarray(errors)
            rms[arm] = float(np.sqrt(np.mean(e**2)) * 1000)
            peak[arm] = float(np.max(e) * 1000)
            goals = np.array([g for g, _ in target.paths[arm]])
            actual = np.array([a for _, a in target.paths[arm]])
            name = f"path_{arm}.png"
            plot_path_comparison(goals, actual, run_dir / name, plane="yz",
                                 title=f"{arm}: operator's goal vs actual "
                                       f"({'drill bit' if settings.mode == 'drill' else 'hand'})",
                                 rms_error_mm=rms[arm])
            files.append(name)
    latencies = np.asarray(target.latencies_s) * 1000
    if (run_dir / "snapshot.png").exists():
        files.append("snapshot.png")
    summary = {
        "command": "teleop",
        "input": str(settings.replay or settings.port),
        "input_kind": "port" if settings.port else "replay",
        "mode": settings.mode, "driver": settings.driver,
        "speed": "max" if settings.speed is None else settings.speed,
        "ended": result.ended, "error": result.error,
        "duration_s": result.t_end_s, "periods": result.periods,
        "operate_s": None if target.t_operate_s is None else result.t_end_s - target.t_operate_s,
        "rms_error_mm": rms, "max_error_mm": peak,
        "world_rms_error_mm": {arm: float(np.sqrt(np.mean(np.square(e))) * 1000)
                               for arm, e in target.world_errors_m.items() if e},
        "max_torso_tilt_deg": float(np.degrees(target.max_tilt_rad)),
        "ik_status_counts": {arm: h.ik_counts for arm, h in target.hands.items()},
        "estop_events": [{"module": m, "t_s": t, "kind": k, "sources": list(s)}
                         for m, t, k, s in result.safety_events if k in ("stop", "release")],
        "status_counts": result.status_counts,
        "max_joint_velocity_ratio": max_velocity_ratio(model, load_log(run_dir)),
        "latency_ms": {"median": float(np.median(latencies)) if len(latencies) else None,
                       "p99": float(np.percentile(latencies, 99)) if len(latencies) else None},
        "samples_used": target.samples_used,
        "samples_rejected": target.mapper.rejected,
        "input_stats": source.stats.as_dict(),
        "overruns": result.overruns,
        "files": files,
    }
    if scene:
        summary["wall_distance_mm"] = scene["wall_distance_m"] * 1000
        summary["start_mm"] = np.asarray(scene["start_m"]) * 1000
    return summary
