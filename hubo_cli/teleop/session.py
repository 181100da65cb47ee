"""One teleoperation run: input device -> mapping -> whole body -> pipeline -> driver -> run
folder."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hubo_cli.control.loop import LoopResult
from hubo_cli.control.operator import OperatorKeys
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.stop_choice import ActiveStops
from hubo_cli.errors import SafetyError
from hubo_cli.input.device import HAND_OF_ARM, InputDevice
from hubo_cli.input.opener import open_input
from hubo_cli.input.operator_stream import StreamSettings
from hubo_cli.kinematics.arm_reach import ReachSettings
from hubo_cli.kinematics.interpolate import PosePath, PoseSegment, segment_duration
from hubo_cli.kinematics.wholebody import LiftFilter, WholeBody
from hubo_cli.model import RobotModel, load_model
from hubo_cli.plots.paths import plot_path_comparison
from hubo_cli.posture import home_posture
from hubo_cli.scene import WallPlacement, WallSize
from hubo_cli.session import RunObserver, RunResult, RunSetup, run
from hubo_cli.teleop.mapping import HandMapper, MappingConfig
from hubo_cli.teleop.target import TeleopTarget
from hubo_cli.urdf import DRILL_FRAME, tool_frame

PAPER_HOLE_M = (0.150, 0.100)  # the paper's cut (V): drill mode starts at its upper-left corner
APPROACH_SPEED_M_S = 0.05      # mean speed of the bit's move into the wall
# drill mode: the bit stops this far before the wall, then goes in along its axis. The flutes
# reach 20 mm either side of the bit's middle (the robot file's bit_half_length_m), so they
# stand 7.5 mm clear of the cardboard's face. At 50 mm the paper hole's upper-left corner of
# the default stance has no such pose within the arm's reach (the wrist at its limits): the
# joint-space move ended 39 mm and 8.5 deg short of it, the straight move in started from
# there, and the bit went into the cardboard sweeping 34-54 mm/s sideways (0.8-1.3 N m on the
# wrist at once, against the 1.21 N m stop).
STANDOFF_M = 0.03
# drill mode: the legs follow the goal's height at most this fast, speeding up and slowing down
# at most this (the bit is in the cardboard: the legs' default 20 mm/s, started and stopped at
# once, swayed the body and moved the bit across the wall and along it by up to 20 mm/s more
# than the goal)
DRILL_LIFT_SPEED_M_S = 0.008
DRILL_LIFT_ACCEL_M_S2 = 0.02
ENTRY_STEP_M = 0.002           # the search for a way in goes down the hole's edge in these steps
ROUTE_SPEED_M_S = 0.008        # mean speed of the bit in the wall from where it went in up to
#                                the start point (the cardboard drags it across: 80 N s/m)
# free mode: forearms forward, hands 30 cm in front of the chest, 23 cm below the shoulders:
# 92-94 % of an 8 cm cube around it is reachable at the same hand orientation
FREE_READY_ARM_RAD = {"right-arm": (0.0, -0.15, 0.0, -1.4, 0.0, 0.0),
                      "left-arm": (0.0, 0.15, 0.0, -1.4, 0.0, 0.0)}
WALL = WallSize(height_m=2.0, width_m=1.2, thickness_m=0.005)  # the simulated cardboard
# The robot's limit set per mode. Free mode: the arms' jerk limit raised (40 rad/s^3, the robot
# file says why) and a trajectory-generator tracker per arm, so each hand keeps up with the
# operator. Drill mode: the robot's own limits and one tracker for the whole body, so the arm
# moves the bit through the cardboard in step with the legs (faster, it drags the bit harder
# and the wrist-torque stop fires sooner).
MODE_LIMITS = {"free": "teleop", "drill": "table4"}


@dataclass
class TeleopSettings:
    """What to run (see ``hubo teleop --help`` for the user's view).

    Attributes:
        replay: a raw capture or pose log to replay (or None with ``port``/``generate_seed``).
        port: a serial port with a live FASTRAK.
        generate_seed: replay the generated operator stream of this seed
            (:mod:`hubo_cli.input.operator_stream`).
        stream: the generated stream's settings (None: the defaults, 30 s at 0.25 m/s).
        driver: ``sim``, ``hardware`` or ``ideal``.
        mode: ``free`` or ``drill``.
        speed: None = as fast as possible, 1.0 = real time.
        scale: robot metres per operator metre.
        station_arm: tracker station -> arm (None: 1 -> right, 2 -> left; drill: 1 -> right).
        wall_distance_m: drill mode wall distance (None: the workspace map's best stance).
        duration_s: stop after this long (live mode; None = until q / Ctrl-C).
        clutch_at_s: replay times at which to re-centre.
        out: run folder (None: runs/<time>-teleop).
        reach: how the arms behave at the edge of their reach (None: the mode's defaults).
        gui, baud, driver_options: passed on.
        stops: the stop sources the run keeps (None: every soft source; see
            :mod:`hubo_cli.control.stop_choice`).
        operator: the operator's keys (space stop, r release, q finish), if any.
        live: the live viewer's publisher (``--live``), if any.
        reconnect_timeout_s: live: a lost tracker ends the run after this long without
            reconnecting (``--reconnect-timeout``).
        perturb_seed: a perturbed simulated robot and world (:mod:`hubo_cli.perturb`).
        balance: the balancer, ``default``, ``paper`` or ``off`` (``--balance``).
        walk_from_m: start this far (x, y; m) from the working stance and walk there before
            the operator takes over (:mod:`hubo_cli.walking.approach`; None: start on it).
    """

    replay: str | Path | None = None
    port: str | None = None
    generate_seed: int | None = None
    stream: StreamSettings | None = None
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
    reconnect_timeout_s: float = 10.0
    stops: ActiveStops | None = None
    operator: OperatorKeys | None = None
    live: RunObserver | None = None
    driver_options: dict = field(default_factory=dict)
    perturb_seed: int | None = None
    reach: ReachSettings | None = None
    balance: str = "default"
    walk_from_m: tuple[float, float] | None = None


@dataclass
class TeleopRun:
    """A finished run: its folder, summary and how the loop ended."""

    run_dir: Path
    summary: dict
    loop: LoopResult


def drill_stance(wall_distance_m: float | None = None) -> tuple[float, np.ndarray, float]:
    """Where to stand and start for a drill cut of the paper's size (paper IV, III-A).

    Without a distance, the stance is the workspace map's largest one-branch rectangle of the
    wall for the drill held orthogonal to it, so the arm has vertical room around its working
    height; the legs take the rest of the height (the widest single segment, the paper's
    criterion, is a ridge a few millimetres tall: any lag of the legs would leave the arm out
    of reach). With ``wall_distance_m`` the hole goes into the reachable rectangle of that
    distance's slice. Returns (wall distance m, the upper-left corner of a paper-size hole
    centred in that rectangle (m, in S), the rectangle's mid height m = the working height).

    Raises:
        SafetyError: nothing of the wall is reachable at ``wall_distance_m`` (exit 4, as a
            task whose path leaves the arm's reach is refused in pre-flight).
    """
    from hubo_cli.workspace.stance import best_stance

    if wall_distance_m is None:
        stance = best_stance(tool="drill", arm="right", vertical="arm")
        wall, rect = stance.wall_distance_m, stance.rectangle
    else:
        stance = best_stance(tool="drill", arm="right", vertical="arm", size_m=PAPER_HOLE_M,
                             wall_distance_m=wall_distance_m)
        wall, rect = wall_distance_m, stance.rectangle
        if rect.y_max_m <= rect.y_min_m:
            raise SafetyError(f"the drill reaches nothing of a wall {wall_distance_m * 1000:.0f}"
                              " mm from the neck; nothing moved",
                              hint="leave --wall-distance out (the workspace map's best stance)"
                                   " or see hubo workspace-map")
    y_mid, z_mid = (rect.y_min_m + rect.y_max_m) / 2, (rect.z_min_m + rect.z_max_m) / 2
    corner = np.array([wall, y_mid + PAPER_HOLE_M[0] / 2, z_mid + PAPER_HOLE_M[1] / 2])
    return wall, corner, z_mid


def station_map(settings: TeleopSettings) -> dict[int, str]:
    """Tracker station -> arm: the settings' map, or the mode's default."""
    if settings.station_arm is not None:
        return dict(settings.station_arm)
    return {1: "right-arm"} if settings.mode == "drill" else {1: "right-arm", 2: "left-arm"}


def prepare(settings: TeleopSettings, model: RobotModel | None = None):
    """Build everything before the robot starts (errors surface before anything moves).

    Returns (model, whole-body solver, mapping, scene). The legs' working height is where the
    hands start (free mode: the legs follow only the operator's height changes) or the middle
    of the reachable rectangle (drill mode).
    """
    model = model or load_model(limits=MODE_LIMITS.get(settings.mode, "table4"))
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
    mapping = MappingConfig(hand_arm={HAND_OF_ARM[arm]: arm for arm in stations.values()},
                            scale=settings.scale, mode=settings.mode,
                            wall_distance_m=scene.get("wall_distance_m", 0.484))
    return model, body, mapping, scene


def teleop_setup(settings: TeleopSettings, body: WholeBody, duration_s: float | None
                 ) -> RunSetup:
    """The session's run set-up: the solver's model and tools, live input in real time."""
    return RunSetup(
        command="teleop", model=body.model, tools=dict(body.tools), driver=settings.driver,
        driver_options=dict(settings.driver_options),
        safety=SafetyProfile(tracker_groups="limbs" if settings.mode == "free" else "body"
                             ).with_stops(settings.stops).with_balance(settings.balance),
        speed=settings.speed, live_input=settings.port is not None, gui=settings.gui,
        out=settings.out, duration_s=duration_s, q_start_rad=home_posture(body.model),
        perturb_seed=settings.perturb_seed, operator=settings.operator, live=settings.live)


def open_operator_input(settings: TeleopSettings) -> InputDevice:
    """The session's operator input, opened: a recording is read (once) and its stations
    checked against the map; a port configures the tracker.

    Raises:
        InputError / DeviceError: a bad recording or station map, a missing port.
    """
    return open_input(replay=settings.replay, port=settings.port,
                      generate_seed=settings.generate_seed, stream=settings.stream,
                      station_arm=station_map(settings), baud=settings.baud,
                      reconnect_timeout_s=settings.reconnect_timeout_s)


def run_teleop(settings: TeleopSettings, on_ready=None,
               device: InputDevice | None = None) -> TeleopRun:
    """Run one teleoperation session and write its run folder.

    Args:
        settings: what to run.
        on_ready: called with the :class:`TeleopTarget` and the control loop once the robot
            has started (the CLI attaches its live view and key reader there).
        device: the input, opened by the caller with :func:`open_operator_input` (who closes
            it); None: opened here once the pace is checked.

    Raises:
        InputError / DeviceError: a bad recording, a missing port (before anything moves).
    """
    model, body, mapping, scene = prepare(settings)
    q_start = home_posture(model)
    approach = approach_paths(body, mapping.hand_arm.values(), scene)
    wall = drill_wall(scene) if settings.mode == "drill" else None
    teleop_setup(settings, body, None).pace()  # refuse a bad pace before opening the port
    with (open_operator_input(settings) if device is None
          else contextlib.nullcontext(device)) as source:
        target = TeleopTarget(model, source, HandMapper(mapping), body, approach, q_start,
                              live=source.live, clutch_at_s=settings.clutch_at_s, wall=wall,
                              reach=settings.reach,
                              correction=("right-arm",) if settings.mode == "drill" else (),
                              lift=LiftFilter(DRILL_LIFT_SPEED_M_S,
                                              max_accel_m_s2=DRILL_LIFT_ACCEL_M_S2)
                              if settings.mode == "drill" else None)
        duration = settings.duration_s
        if duration is None and source.recorded_s is not None:
            duration = source.recorded_s + target.approach_timeout_s + 30.0
        setup, runs = teleop_setup(settings, body, duration), target
        if settings.walk_from_m is not None:  # the operator takes over at the stance
            from hubo_cli.walking.approach import walk_first_setup

            runs, setup = walk_first_setup(setup, target, settings.walk_from_m,
                                           scene.get("wall_distance_m"),
                                           frames=[tool_frame(a, t) for a, t in body.tools.items()])
        done = run(setup, runs, on_start=None if on_ready is None
                   else lambda _, loop: on_ready(target, loop))
    t_origin_s = 0.0 if runs is target else runs.then_origin_s  # (its own clock's)
    summary = done.save_summary(summarise(settings, target, done, source, scene, t_origin_s))
    if runs is not target:
        from hubo_cli.experiments.walk import plot_footprints

        summary = done.save_summary({"walk": runs.summary()})
        plot_footprints(done, runs.walk, setup.model,
                        rows=np.asarray(done.log["approach.phase_code"]) == 0)
    return TeleopRun(done.run_dir, summary, done.loop)


def drill_wall(scene: dict) -> WallPlacement:
    """Drill mode's wall, placed at the bit as a task places its wall: once the robot holds
    the bit ``STANDOFF_M`` before the start point (the approach's first pose), the wall's
    mid-plane goes ``STANDOFF_M`` ahead of the bit, where the mapping keeps the bit's middle
    (x = the wall distance in S). So the flutes sit in the cardboard by half their length
    either way whatever the body's lean at that moment."""
    return WallPlacement(DRILL_FRAME, STANDOFF_M - WALL.thickness_m / 2, WALL)


def approach_paths(body: WholeBody, arms, scene: dict) -> dict[str, PosePath]:
    """Each driven hand's approach path (goals in S); its first pose is reached in joint space.

    Free mode: the hands' ready pose (forearms forward). Drill mode: :func:`drill_approach`.
    """
    paths = {}
    for arm in arms:
        T_ready = body.arms[arm].fk(np.array(FREE_READY_ARM_RAD[arm]))
        if scene and arm == "right-arm":
            paths[arm] = drill_approach(body, scene["start_m"])
        else:
            paths[arm] = PosePath([PoseSegment(T_ready, T_ready, 0.0)])
    return paths


def drill_approach(body: WholeBody, start_m) -> PosePath:
    """The bit's way to the start point (S, m), orthogonal to the wall: from ``STANDOFF_M``
    before the wall straight in along the bit, at the start point or, where the arm does not
    reach that straight way exactly, at the highest point below it on the hole's edge where it
    does, then up the edge to the start point at ``ROUTE_SPEED_M_S``. So the pose the robot
    holds while the wall is placed is the path's own, and the bit never sweeps sideways through
    the cardboard to catch up with it.

    Raises:
        SafetyError: no way in within the hole's height (the stance's rectangle leaves none).
    """
    T_start = np.eye(4)
    T_start[:3, 3] = start_m
    for k in range(int(round(PAPER_HOLE_M[1] / ENTRY_STEP_M)) + 1):
        T_in = T_start.copy()
        T_in[2, 3] -= k * ENTRY_STEP_M
        T_off = T_in.copy()
        T_off[0, 3] -= STANDOFF_M
        segments = [PoseSegment(T_off, T_in, segment_duration(T_off, T_in, APPROACH_SPEED_M_S))]
        if k:
            segments.append(PoseSegment(T_in, T_start, segment_duration(T_in, T_start,
                                                                        ROUTE_SPEED_M_S)))
        path = PosePath(segments)
        if _reached_exactly(body, path):
            return path
    raise SafetyError(f"the drill cannot reach the wall there along its bit: no way in within "
                      f"{PAPER_HOLE_M[1] * 1000:.0f} mm below the hole's corner "
                      f"({start_m[0] * 1000:.0f}, {start_m[1] * 1000:.0f}, "
                      f"{start_m[2] * 1000:.0f}) mm in S; nothing moved",
                      hint="leave out --wall-distance (the workspace map's best stance) or "
                           "choose another")


def _reached_exactly(body: WholeBody, path: PosePath, samples: int = 12) -> bool:
    """Every pose of ``path`` (``samples`` along each segment) has an exact arm solution at
    the legs' lift for its first pose, as the approach solves them."""
    first = {"right-arm": path.at(0.0)}
    lift_m, q = body.lift_for(first), None
    for k, segment in enumerate(path.segments):
        for t in np.linspace(0.0, segment.duration_s, samples):
            solved = body.solve({"right-arm": path.at(path.starts_s[k] + t)}, q, lift_m=lift_m)
            if solved.arms["right-arm"].status != "exact":
                return False
            q = solved.q_rad
    return True


def stale_spans(log, t_origin_s: float = 0.0, timeout_s: float = 0.0) -> dict | None:
    """How long a driven hand's input was stale (flag ``stale-input``: nothing usable came,
    a silent or garbled tracker, poses that each jump away, a gap in a recording) while the
    hands held: the total, the spans and the longest one, on the target's clock (the run's
    less ``t_origin_s``; s); None when it never was. The flag rises ``timeout_s`` (the stale
    timeout) after the hand's last usable pose, and the hand held its goal from that pose on:
    each span starts that much earlier (not before the log's start or the span before it), so
    that it is the time the hand was held, not the time beyond the timeout."""
    stale = np.array(["stale-input" in f for f in log.flags], dtype=bool)
    if not stale.any():
        return None
    t_s = np.asarray(log["t_s"], dtype=float) - t_origin_s
    dt_s = float(np.median(np.diff(t_s))) if len(t_s) > 1 else 0.0
    edges = np.diff(np.concatenate([[0], stale.astype(np.int8), [0]]))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    earliest = np.concatenate([[0], ends[:-1]])  # the log's start, else the span before's end
    starts_s = np.maximum(t_s[starts] - timeout_s, t_s[earliest])
    lengths_s = (ends - starts) * dt_s + (t_s[starts] - starts_s)
    longest = int(np.argmax(lengths_s))
    return {"total_s": float(lengths_s.sum()), "spans": len(starts),
            "longest_s": float(lengths_s[longest]), "longest_from_s": float(starts_s[longest])}


def summarise(settings: TeleopSettings, target: TeleopTarget, done: RunResult,
              source: InputDevice, scene: dict, t_origin_s: float = 0.0) -> dict:
    """The session's own summary fields; also draws the path plots into the run folder.
    ``t_origin_s``: the run's time at which the target's own clock starts (a walk to the
    stance hands over then)."""
    rms, peak = {}, {}
    for arm, errors in target.errors_m.items():
        if errors:
            e = np.asarray(errors)
            rms[arm] = float(np.sqrt(np.mean(e**2)) * 1000)
            peak[arm] = float(np.max(e) * 1000)
            goals = np.array([g for g, _ in target.paths[arm]])
            actual = np.array([a for _, a in target.paths[arm]])
            name = f"path_{arm}.png"
            plot_path_comparison(goals, actual, done.run_dir / name, plane="yz",
                                 title=f"{arm}: operator's goal vs actual "
                                       f"({'drill bit' if settings.mode == 'drill' else 'hand'})",
                                 rms_error_mm=rms[arm])
            done.add_file(name)
    latencies = np.asarray(target.latencies_s) * 1000
    result = done.loop
    summary = {
        "input": str(settings.replay or settings.port or f"generated:{settings.generate_seed}"),
        "input_kind": ("port" if settings.port else "replay" if settings.replay
                       else "generated"),
        "mode": settings.mode,
        "operate_s": None if target.t_operate_s is None
        else result.t_end_s - t_origin_s - target.t_operate_s,
        "rms_error_mm": rms, "max_error_mm": peak,
        "world_rms_error_mm": {arm: float(np.sqrt(np.mean(np.square(e))) * 1000)
                               for arm, e in target.world_errors_m.items() if e},
        "max_torso_tilt_deg": float(np.degrees(target.max_tilt_rad)),
        "ik_status_counts": {arm: h.ik_counts for arm, h in target.hands.items()},
        "reach": target.reach_report(),
        "latency_ms": {"median": float(np.median(latencies)) if len(latencies) else None,
                       "p99": float(np.percentile(latencies, 99)) if len(latencies) else None},
        "target_us": {"median": float(np.median(target.operate_call_s) * 1e6),
                      "p99": float(np.percentile(target.operate_call_s, 99) * 1e6),
                      "cpu_median": float(np.median(target.operate_cpu_s) * 1e6)}
        if target.operate_call_s else {"median": None, "p99": None, "cpu_median": None},
        "samples_used": target.samples_used,
        "samples_rejected": target.mapper.rejected,
        # driven arms whose hand's poses came and not one was usable (each with a status
        # letter, or each a jump): they never moved
        "arms_without_usable_input": [
            arm for hand, arm in target.mapper.config.hand_arm.items()
            if arm in target.hands and source.last_seen_s(hand) is not None
            and hand not in target.last_sample_s],
        "input_stats": source.stats(),
        "stale_input": stale_spans(done.log, t_origin_s, target.stale_timeout_s),
        "input_info": source.info,
        "scene": target.scene,
    }
    if scene:
        summary["wall_distance_mm"] = scene["wall_distance_m"] * 1000
        summary["start_mm"] = np.asarray(scene["start_m"]) * 1000
    return summary
