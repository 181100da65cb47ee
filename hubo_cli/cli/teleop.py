"""``hubo teleop``: an operator's stream (replay, live FASTRAK or generated) drives the robot."""

from __future__ import annotations

import contextlib
import math

import click
import numpy as np
from rich.console import Group
from rich.markup import escape
from rich.table import Table

from hubo_cli.cli.checks import check_baud, check_seconds
from hubo_cli.cli.hardware import driver_options, hardware_options
from hubo_cli.cli.options import (
    active_stops,
    balance_option,
    live_server,
    perturb_option,
    robot_run_options,
)
from hubo_cli.cli.output import (
    console,
    err_console,
    print_json,
    print_run_folder,
    report_interrupt_stop,
)
from hubo_cli.drivers.registry import DRIVER_NAMES, driver_class
from hubo_cli.errors import EXIT_INTERRUPTED, EXIT_NOT_COMPLETED, HuboError, InputError, quoted
from hubo_cli.pace import check_speed

KEYS_HELP = "keys: space e-stop, r release, c clutch, b change branch, q quit"
DIRECTIONS = (("fwd", "back"), ("left", "right"), ("up", "down"))  # +/- x, y, z of the stance
MOSTLY_REJECTED = 0.5  # a replay with more than this share of samples rejected has failed
# a hand's position RMS over the time its goal was reachable and followed above this: it never
# followed the operator (exit 1). Over all the time it would count a goal out of reach: a
# stream whose goals leave the reach and come back ended exit 1 with the hands on them
# whenever they could be (generated seed 4242 at 0.6 m/s, 12 s: 150 mm RMS in all, 75 mm over
# the reachable 34 %; review 23's 0.5 m excursion: 240 mm in all, 71 mm reachable)
ABSURD_ERROR_MM = 100.0
# A hand whose position RMS over the time its goal was reachable and the hand meant to follow
# it (summary reach's followed_position_rms_mm: a hand held by design, its input stale or
# waiting for a re-centre or clutched, is not judged) exceeds this did not follow the
# operator. Healthy spread (every figure the same to 5e-12 mm on both code paths, AVX-512 /
# portable): the shipped samples
# 1.3-6.5 mm; the 60 generated streams of tests/test_teleop_streams.py at most 29.1 mm at
# 0.25 m/s and 44.7 mm at 0.6 m/s (faster than the arm's joints follow); the bound is 1.2x the
# latter (docs/history/teleop.md, "Round 18: the verdict over reachable time"). A warning,
# not a failed run: the suite's live tracker emulator, whose goals leave the reach and come
# back again and again, read 56.5 and 68.3 mm over its followed time in two runs (the hand
# chasing a goal back into reach, issue 34's return), so an exit code on this figure would
# fail such operators' sessions by chance until that is mended
FOLLOW_BOUND_MM = 55.0
# The same for the orientation (summary reach's followed_orientation_rms_deg, over the same
# time), also a warning. Healthy spread: the shipped samples 1.1-3.9 deg; the 60 short (1.5 s)
# generated streams at most 6.6 deg; 6 s generated streams (issue 34's orientation lag) median
# 7.8 deg, worst 20.7 deg at 0.25 m/s (seeds 5000-5020) and 17.7 deg at 0.6 m/s (5100-5110):
# the bound is 1.45x that worst. It does not flag review 19's 120 Hz stream (turns to 50 deg:
# 17.3 / 18.9 deg over the 50 / 52 % of the time its hands were followed), whose figures lie
# among ordinary streams' (docs/history/teleop.md, "Round 19: the follow verdict judges the
# orientation too"); it flags a hand that does not turn with the operator at all.
FOLLOW_BOUND_DEG = 30.0
EXIT_BAD_INPUT = 2


def _speed(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--speed {quoted(text)} is not a number or 'max'",
                         hint="use --speed 1 (real time), --speed 2, or --speed max") from None
    return check_speed(value)  # at once, before the set-up's work (the run checks it too)


def _station_map(pairs: tuple[str, ...]) -> dict[int, str] | None:
    from hubo_cli.input.fastrak import parse_station_map

    return parse_station_map(pairs) if pairs else None


def hand_safety(target) -> list:
    """Per driven hand: stale input, waiting for a re-centre, reach (for the safety view)."""
    from hubo_cli.cli.safety_view import HandSafety

    out = []
    for arm, hand in target.hands.items():
        out.append(HandSafety(arm, stale=hand.stale, needs_clutch=hand.needs_clutch,
                              calibrating=target.phase == "operate"
                              and not target.mapper.is_calibrated(target.hand_of(arm)),
                              ik_status=hand.ik_status))
    return out


def _direction(v) -> str:
    """Words for a direction in the stance frame, e.g. ``fwd-down`` (components over 35 %)."""
    unit = np.asarray(v, dtype=float) / max(float(np.linalg.norm(v)), 1e-12)
    words = [DIRECTIONS[i][0 if unit[i] > 0 else 1] for i in range(3) if abs(unit[i]) > 0.35]
    return "-".join(words)


def _reach_cell(hand) -> str:
    """The reach column: branch moves, the reach limit (missing part), slowing near singular."""
    if hand.branch_move is not None or hand.notice.startswith("no other"):
        return f"[cyan]{hand.notice}[/]"
    if hand.at_limit:
        missing = hand.missing_m
        return (f"[yellow]at reach limit: {np.linalg.norm(missing) * 1000:.0f} mm "
                f"{_direction(missing)}[/]")
    if hand.speed_scale < 1.0:
        return f"[yellow]near singular: {hand.speed_scale:.0%} speed[/]"
    return "ok"


def _reachable_cell(hand) -> str:
    """The share of the time so far that the goal was reachable and the errors over it."""
    so_far = hand.reachable_so_far()
    if so_far is None:
        return "-"
    share, position_mm, rotation_deg = so_far
    return f"{share:.0%}  {position_mm:.1f} mm  {rotation_deg:.1f} deg"


def _view(target, panel) -> Group:
    """The live view: the safety state; per hand goal, actual, position and orientation errors,
    IK status, reach (limit and direction of the missing part, branch changes, slowing), the
    share of the time so far the goal was reachable with the RMS errors over it; input and
    latency."""
    safety = panel()
    from hubo_cli.cli.safety_view import STOPPED_HOW
    phase = "E-STOPPED" if panel.last.estop in STOPPED_HOW else target.phase
    table = Table(title=f"hubo teleop — {phase}   ({KEYS_HELP})", title_justify="left")
    for column in ("hand", "goal (mm)", "actual (mm)", "pos err (mm)", "rot err (deg)", "IK",
                   "reach", "reachable: share, rms", "input"):
        table.add_column(column)

    def mm(p):
        return "-" if p is None else " ".join(f"{v * 1000:+7.1f}" for v in p)

    for arm, hand in target.hands.items():
        error = (np.linalg.norm(hand.goal_m - hand.actual_m) * 1000
                 if hand.goal_m is not None and hand.actual_m is not None else float("nan"))
        table.add_row(arm, mm(hand.goal_m), mm(hand.actual_m), f"{error:.1f}",
                      f"{np.degrees(hand.rotation_error_rad):.1f}", hand.ik_status,
                      _reach_cell(hand), _reachable_cell(hand), "[red]stale[/]" if hand.stale
                      else "[yellow]back: press c[/]" if hand.needs_clutch else "ok")
    latency = target.latencies_s[-1] * 1000 if target.latencies_s else float("nan")
    table.caption = (f"samples {target.samples_used}  rejected {target.mapper.rejected}  "
                     f"latency {latency:.1f} ms")
    return Group(safety, table)


@click.command()
@click.option("--replay", type=click.Path(dir_okay=False), default=None,
              help="Replay a raw FASTRAK capture or a pose log.")
@click.option("--port", default=None, help="Read a live FASTRAK on this serial port.")
@click.option("--generate", "generate_seed", type=click.IntRange(0, 2**32 - 1), default=None,
              metavar="SEED", help="Replay the generated operator stream of this seed (both "
                                   "hands; --duration sets its length, default 30 s).")
@click.option("--max-speed", "max_speed", type=float, default=None, metavar="M/S",
              help="--generate: the hands' speed cap (default 0.25; 0.6 for a swing test).")
@click.option("--reconnect-timeout", "reconnect_timeout", type=float, default=10.0,
              show_default=True, metavar="SECONDS",
              help="Live: a lost tracker ends the run after this long without reconnecting.")
@click.option("--baud", type=int, default=115200, show_default=True, callback=check_baud,
              help="Live port baud rate.")
@click.option("--driver", type=click.Choice(DRIVER_NAMES), default=DRIVER_NAMES[0],
              show_default=True, help="Robot back end.")
@click.option("--arm", "armed", is_flag=True, help="Arm the hardware driver (required by it).")
@click.option("--mode", type=click.Choice(["free", "drill"]), default="free", show_default=True,
              help="free: follow each hand's pose; drill: bit orthogonal to the wall, y and z.")
@click.option("--speed", default="max", show_default=True,
              help="Replay pace: 1 = real time, X = X times, max = as fast as possible. Live "
                   "input, the hardware driver and --gui always run in real time.")
@click.option("--scale", type=float, default=1.0, show_default=True,
              help="Robot metres per operator metre.")
@click.option("--map", "station_map", multiple=True, metavar="STATION=ARM",
              help="Which station drives which arm (default 1=right-arm, 2=left-arm).")
@click.option("--wall-distance", type=float, default=None, metavar="MM",
              help="Drill mode: wall distance from the neck (default: the workspace map's).")
@click.option("--clutch", "clutch_at", type=float, multiple=True, metavar="SECONDS",
              help="Re-centre at these replay times (as the c key does live).")
@click.option("--duration", type=float, default=None, metavar="SECONDS",
              help="Stop after this long (live mode; default: until q or Ctrl-C); with "
                   "--generate, the stream's length.")
@click.option("--reach", "reach_mode", type=click.Choice(["nearest", "paper"]), default="nearest",
              show_default=True,
              help="Out of reach: nearest = stay on the IK branch, go to the nearest reachable "
                   "pose (position first); paper = the paper's 5 cm rule (may switch branch).")
@click.option("--orientation-weight", type=float, default=0.87, show_default=True,
              metavar="MM_PER_DEG",
              help="Nearest pose: millimetres of position error one degree of orientation "
                   "error is worth (small = position first).")
@click.option("--allow-branch-change", is_flag=True,
              help="Change IK branch by itself (slowly, announced) when a hand rests at its "
                   "reach limit and another branch reaches the goal; otherwise only on key b.")
@click.option("--walk-from", "walk_from", type=float, nargs=2, default=None, metavar="X Y",
              help="Start this far (m, x forward, y left) from the working stance and walk "
                   "there before the operator takes over (on the estimate; the simulator or the "
                   "robot: the ideal driver has no floor).")
@robot_run_options("teleop")
@click.option("--video", is_flag=True,
              help="After the run, render video.mp4 from its log (needs hubo-cli[viz]).")
@hardware_options
@perturb_option
@balance_option
def teleop(replay, port, generate_seed, max_speed, reconnect_timeout, baud, driver, armed, mode,
           speed, scale, station_map,
           wall_distance, clutch_at, duration, reach_mode, orientation_weight, allow_branch_change,
           walk_from, no_estop, estop_sources, accept_reduced_safety, gui, out, as_json, live,
           live_host, live_port, video, perturb_seed, balance, **hardware) -> None:
    """Drive the robot's hands from an operator's FASTRAK stream.

    Exactly one of --replay FILE, --port DEV or --generate SEED. The first pose of each hand
    calibrates it:
    later motion is relative. Writes a run folder with the per-period log, summary.json and the
    commanded-vs-actual path plot.

    \b
    Keys in the live view (a terminal):
      space   emergency stop: revert 0.5 s of motion and hold
      r       release the emergency stop (blends back over 2.5 s)
      c       re-centre (clutch): the hands stay, the tracker's pose becomes the new reference;
              needed after the tracker was lost, before the hands move again
      q, Esc  finish the run (smooth stop, summary written); Ctrl-C and SIGTERM do the same

    \b
    Examples: hubo teleop --replay trajectories/drill-rectangle.fastrak --mode drill
              hubo teleop --port /dev/ttyUSB0
    """
    from hubo_cli.cli.replay import check_video_support
    from hubo_cli.control.stop_choice import SOFT_SOURCES, check_walk_stops
    from hubo_cli.kinematics.arm_reach import ReachSettings
    from hubo_cli.runs import reserved_run_dir
    from hubo_cli.teleop.session import TeleopSettings

    if video:
        check_video_support()

    if sum(x is not None for x in (replay, port, generate_seed)) != 1:
        raise InputError("give exactly one of --replay FILE, --port DEV or --generate SEED",
                         hint="e.g. hubo teleop --replay trajectories/drill-rectangle.fastrak")
    if max_speed is not None and generate_seed is None:
        raise InputError("--max-speed applies to --generate", hint="add --generate SEED")
    stream = None
    if generate_seed is not None:
        from hubo_cli.input.operator_stream import StreamSettings

        stream = StreamSettings(duration_s=30.0 if duration is None else duration,
                                max_speed_m_s=0.25 if max_speed is None else max_speed)
        duration = None  # the stream's length ends the run
    explicit = click.get_current_context().get_parameter_source("speed")
    if speed == "max" and explicit is click.core.ParameterSource.COMMANDLINE and (
            port is not None or gui or live or driver_class(driver).real_time):
        raise InputError("--speed max is for replays on the sim or ideal drivers",
                         hint="live input, the hardware driver, --gui and --live run in real "
                              "time; leave --speed out")
    speed_x = _speed(speed)
    check_seconds("--duration", duration)
    check_seconds("--reconnect-timeout", reconnect_timeout, 3600)
    for t in clutch_at:
        if not (math.isfinite(t) and t >= 0):
            raise InputError(f"--clutch {t:g} is not a time in the replay",
                             hint="give seconds from the replay's start, e.g. --clutch 12.5")
    if clutch_at and port is not None:
        raise InputError("--clutch times apply to replays", hint="live, press c to re-centre")
    given = click.get_current_context().get_parameter_source
    for option, name in (("--reconnect-timeout", "reconnect_timeout"), ("--baud", "baud")):
        if port is None and given(name) is click.core.ParameterSource.COMMANDLINE:
            # review 22: a replay's --baud was taken and ignored without a word
            raise InputError(f"{option} applies to a live tracker (--port)",
                             hint="leave it out for a replay or a generated stream")
    if not (math.isfinite(scale) and 0 < scale <= 10):
        raise InputError(f"--scale {scale:g} must be in (0, 10]", hint="e.g. --scale 1")
    if wall_distance is not None and mode != "drill":
        raise InputError("--wall-distance applies to --mode drill", hint="add --mode drill")
    if wall_distance is not None:
        _check_wall_distance(wall_distance)
    if walk_from is not None and not all(math.isfinite(v) and abs(v) <= 10 for v in walk_from):
        raise InputError(f"--walk-from {walk_from[0]:g} {walk_from[1]:g} must be metres within "
                         "10 m of the working stance", hint="e.g. --walk-from -1 0 (1 m behind)")
    stations = _station_map(station_map)
    stops = active_stops(SOFT_SOURCES, driver, no_estop=no_estop, estop_sources=estop_sources,
                         accept_reduced_safety=accept_reduced_safety, quiet=as_json)
    if walk_from is not None:
        from hubo_cli.experiments.walk import check_walk_driver

        check_walk_driver(driver)  # review 23: it walked one step on the ideal driver
        check_walk_stops(stops, "--walk-from (a walk)")
    settings = TeleopSettings(
        replay=replay, port=port, generate_seed=generate_seed, stream=stream, driver=driver,
        mode=mode, speed=speed_x, scale=scale,
        station_arm=stations,
        wall_distance_m=None if wall_distance is None else wall_distance / 1000.0,
        duration_s=duration, clutch_at_s=tuple(clutch_at), out=out, gui=gui, baud=baud,
        reconnect_timeout_s=reconnect_timeout,
        stops=stops, driver_options=driver_options(driver, armed, **hardware, quiet=as_json),
        perturb_seed=perturb_seed, balance=balance, walk_from_m=walk_from,
        reach=ReachSettings.for_mode(
            mode, mode=reach_mode, allow_branch_change=allow_branch_change,
            orientation_weight_m_per_rad=orientation_weight / 1000 * 180 / np.pi))
    with _opened_recording(settings) as recording:  # its stations checked before anything
        _check_clutch_times(clutch_at, recording)
        if wall_distance is not None:
            _check_wall_reach(settings)
        with (reserved_run_dir("teleop", out) as run_dir,
              live_server(live, live_host, live_port, quiet=as_json) as server):
            settings.out, settings.live = run_dir, server
            run = _run(settings, as_json, recording)
    _report(run, as_json, video)


def _opened_recording(settings):
    """A replay's recording opened now, read once (a file or a FIFO alike), checked against
    the station map and handed to the run; a live port or a generated stream is opened by
    the run itself (a port once the pace is checked, just before the robot starts)."""
    from hubo_cli.teleop.session import open_operator_input

    if settings.replay is None:
        return contextlib.nullcontext()
    return open_operator_input(settings)


def _check_clutch_times(clutch_at_s, recording) -> None:
    """Every --clutch time within the replay (one after its end would never fire)."""
    end_s = None if recording is None else recording.recorded_s
    for t in clutch_at_s:
        if end_s is not None and t > end_s:
            raise InputError(f"--clutch {t:g} is after the replay's end ({end_s:.2f} s)",
                             hint="give seconds from the replay's start, e.g. --clutch 12.5")


def _check_wall_distance(wall_distance_mm: float) -> None:
    """A positive distance within a task file's bound on lengths (beyond it a typo: exit 2,
    as in a task); a wall within it that the drill cannot reach is refused for safety (exit 4,
    :func:`_check_wall_reach`), as a task's path out of reach is in pre-flight."""
    from hubo_cli.tasks.spec import LENGTH_MAX_MM

    if not (math.isfinite(wall_distance_mm) and 0 < wall_distance_mm <= LENGTH_MAX_MM):
        raise InputError(f"--wall-distance {wall_distance_mm:g} mm must be a positive distance "
                         f"of at most {LENGTH_MAX_MM:g} mm",
                         hint="e.g. --wall-distance 470 (or leave it out: the workspace map's)")


def _check_wall_reach(settings) -> None:
    """Drill mode with a given wall distance: the bit must have a way into the wall within the
    arm's exact reach there (:func:`~hubo_cli.teleop.session.drill_approach` refuses one
    without, SafetyError), before anything moves."""
    from hubo_cli.teleop.session import approach_paths, prepare

    _, body, mapping, scene = prepare(settings)
    approach_paths(body, mapping.hand_arm.values(), scene)


def _run(settings, as_json: bool, recording=None):
    from hubo_cli.cli.keys import operator_keys
    from hubo_cli.cli.live_view import LiveView
    from hubo_cli.cli.safety_view import SafetyPanel, read_safety
    from hubo_cli.teleop.session import run_teleop

    state: dict = {"target": None}

    def on_key(char: str) -> None:  # teleop's own keys (space, r and q: every command's)
        target = state["target"]
        if target is None:
            return
        if char == "c":
            target.keys.clutch = True
        elif char == "b":
            target.keys.branch = True

    def on_ready(target, loop) -> None:
        state["target"] = target
        if as_json:
            return
        loop.watch_status()
        panel = SafetyPanel(lambda: read_safety(loop, hand_safety(target), loop.driver.world,
                                                target.robot_flags),
                            bell=err_console.bell)
        view = LiveView(lambda: _view(target, panel),
                        lambda: f"teleop {target.phase}: samples {target.samples_used} | "
                                f"{panel.words()}",
                        urgent=panel.alarm,
                        header=KEYS_HELP if settings.operator is not None else None)
        view.start()
        state["view"] = view

    try:
        with operator_keys(on_key) as keys:
            settings.operator = keys
            return run_teleop(settings, on_ready=on_ready, device=recording)
    finally:
        if "view" in state:
            state["view"].stop()


def report_stale_input(summary: dict) -> None:
    """One line on stderr when a hand's input was stale during the run (a tracker silent or
    sending garbage, a gap in a recording): for how long, the longest span and where. The
    hands held meanwhile, as designed, so the run's exit code is not changed by it."""
    stale = summary.get("stale_input")
    if not stale:
        return
    err_console.print(f"[yellow]input stale for {stale['total_s']:.2f} s[/] in "
                      f"{stale['spans']} span{'s' if stale['spans'] > 1 else ''} (the longest "
                      f"{stale['longest_s']:.2f} s from t = {stale['longest_from_s']:.2f} s): "
                      f"nothing usable came from {escape(summary['input'])} then (silent, "
                      "garbled or jumping away) and the hands held", soft_wrap=True)


def _report(run, as_json: bool, video: bool = False) -> None:
    """Print the summary; a run that failed in substance ends with a warning and exit 1 or 2."""
    from hubo_cli.cli.output import warn
    from hubo_cli.cli.safety_view import balance_summary_line

    summary = run.summary
    if video:
        from hubo_cli.cli.replay import add_run_video

        add_run_video(run.run_dir, summary, quiet=as_json)
    stops = [e for e in summary["estop_events"] if e["kind"] == "stop"]
    if as_json:
        print_json({"run_dir": str(run.run_dir), **summary})
    else:
        errors = ", ".join(f"{arm} {v:.1f} mm rms / {summary['max_error_mm'][arm]:.1f} max"
                           for arm, v in summary["rms_error_mm"].items()) or "no operator input"
        console.print(f"teleop {summary['ended']} after {summary['duration_s']:.1f} s "
                      f"({summary['periods']} periods): {errors}")
        for arm, r in summary["reach"].items():
            if r["position_rms_mm"] is not None:
                console.print(f"  {arm}: position {r['position_rms_mm']:.1f} mm rms, orientation "
                              f"{r['orientation_rms_deg']:.1f} deg rms, at reach limit "
                              f"{r['at_limit_s']:.1f} s, kept out of the collision band "
                              f"{r['collision_room_s']:.1f} s, largest excursion "
                              f"{r['max_excursion_mm']:.0f} mm, branch changes "
                              f"{r['branch_changes']}")
                if r.get("reachable_share") is not None:
                    over = ("" if r["reachable_position_rms_mm"] is None else
                            f": position {r['reachable_position_rms_mm']:.1f} mm rms, "
                            f"orientation {r['reachable_orientation_rms_deg']:.1f} deg rms, "
                            f"largest excursion {r['reachable_max_excursion_mm']:.0f} mm over "
                            "that time")
                    console.print(f"    goal reachable {r['reachable_share']:.0%} of the "
                                  f"time{over}")
                if r.get("steady_position_rms_mm") is not None:
                    from hubo_cli.teleop.hand_report import RETURN_WINDOW_S

                    console.print(f"    steady, {r['steady_share']:.0%} of that time (more than "
                                  f"{RETURN_WINDOW_S:g} s after the goal came back into reach): "
                                  f"position {r['steady_position_rms_mm']:.1f} mm rms, orientation "
                                  f"{r['steady_orientation_rms_deg']:.1f} deg rms")
                if r.get("followed_orientation_rms_deg") is not None:
                    console.print(f"    followed live {r['followed_share']:.0%} of the time: "
                                  f"position {r['followed_position_rms_mm']:.1f} mm rms, "
                                  f"orientation {r['followed_orientation_rms_deg']:.1f} deg "
                                  "rms over that time (the verdict's)")
        releases = sum(e["kind"] == "release" for e in summary["estop_events"])
        console.print(f"  e-stops {len(stops)} (released {releases}), statuses "
                      f"{summary['status_counts']}, max velocity "
                      f"{summary['max_joint_velocity_ratio']:.0%} of limit")
        console.print(f"  balance: {balance_summary_line(summary)}", soft_wrap=True)
        print_run_folder(run.run_dir, summary["files"], width=12, indent="  ")
        if video:
            console.print(f"  video: {summary['video']['file']}")
    exception = run.loop.exception
    if isinstance(exception, HuboError):
        raise exception
    if summary["error"] and not as_json:
        err_console.print(f"[yellow]{summary['error']}[/]")
    report_interrupt_stop(summary)
    report_stale_input(summary)
    if not run.loop.ok:
        raise SystemExit(EXIT_INTERRUPTED if run.loop.ended == "interrupted"
                         else EXIT_NOT_COMPLETED)
    used, rejected = summary["samples_used"], summary["samples_rejected"]
    if used == 0:
        warn("no operator input reached the robot (no pose of a driven hand was usable)")
        raise SystemExit(EXIT_BAD_INPUT)
    if rejected > MOSTLY_REJECTED * (used + rejected):
        warn(f"{rejected} of {used + rejected} samples were rejected (jumps or bad values): "
             "the errors above describe what was left, not the recording")
        raise SystemExit(EXIT_BAD_INPUT)
    for arm in summary["arms_without_usable_input"]:
        warn(f"the {arm} never moved: its station's poses came and not one was usable (each "
             "with a status letter or each a jump)")
    if summary["arms_without_usable_input"]:
        raise SystemExit(EXIT_BAD_INPUT)
    worst, arm, _ = worst_followed(summary, "followed_position_rms_mm")
    if worst is not None and worst > ABSURD_ERROR_MM:
        warn(f"the {arm} hand missed the operator's goals by {worst:.0f} mm RMS over the time "
             "they were reachable: the robot did not follow")
        raise SystemExit(EXIT_NOT_COMPLETED)
    for line in not_followed(summary):  # warnings, not exit 1: see FOLLOW_BOUND_MM
        warn(line)


def worst_followed(summary: dict, key: str) -> tuple:
    """(figure, arm, followed share) of the hand whose summary ``reach`` figure ``key`` is the
    largest; (None, None, None) when no hand has it (none was followed)."""
    return max(((r[key], arm, r["followed_share"])
                for arm, r in summary.get("reach", {}).items() if r.get(key) is not None),
               default=(None, None, None))


def not_followed(summary: dict) -> list[str]:
    """The lines saying which hand did not follow its reachable goals: the worst one by its
    position RMS over that time above :data:`FOLLOW_BOUND_MM`, and the worst one by its
    orientation RMS above :data:`FOLLOW_BOUND_DEG` (none, one or both)."""
    lines = []
    for key, bound, unit, what in (
            ("followed_position_rms_mm", FOLLOW_BOUND_MM, "mm", "the operator's goals"),
            ("followed_orientation_rms_deg", FOLLOW_BOUND_DEG, "deg",
             "the operator's turn of the hand")):
        rms, arm, share = worst_followed(summary, key)
        if rms is not None and rms > bound:
            lines.append(f"the {arm} hand missed {what} by {rms:.0f} {unit} RMS over the "
                         f"{share:.0%} of the time they were reachable and followed live "
                         f"(bound {bound:.0f} {unit}): it did not follow")
    return lines
