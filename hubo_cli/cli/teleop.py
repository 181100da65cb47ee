"""``hubo teleop``: an operator's stream (replay or live FASTRAK) drives the robot."""

from __future__ import annotations

import click
import numpy as np
from rich.live import Live
from rich.table import Table

from hubo_cli.cli.hardware import driver_options, hardware_options
from hubo_cli.cli.output import NO_ESTOP_HELP, console, err_console, interactive, print_json
from hubo_cli.drivers.registry import DRIVER_NAMES, driver_class
from hubo_cli.errors import InputError

KEYS_HELP = "keys: space e-stop, r release, c re-centre (clutch), q quit"


def _speed(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--speed {text!r} is not a number or 'max'",
                         hint="use --speed 1 (real time), --speed 2, or --speed max") from None
    if not value > 0:
        raise InputError("--speed must be positive", hint="use --speed 1 or --speed max")
    return value


def _station_map(pairs: tuple[str, ...]) -> dict[int, str] | None:
    if not pairs:
        return None
    out = {}
    for pair in pairs:
        station, _, arm = pair.partition("=")
        if not station.isdigit() or arm not in ("right-arm", "left-arm"):
            raise InputError(f"--map {pair!r} is not STATION=ARM",
                             hint="e.g. --map 1=right-arm --map 2=left-arm")
        out[int(station)] = arm
    return out


def _view(target) -> Table:
    """The live view: per hand goal, actual, error, IK status; phase, input and latency."""
    table = Table(title=f"hubo teleop — {target.phase}   ({KEYS_HELP})", title_justify="left")
    for column in ("hand", "goal (mm)", "actual (mm)", "error (mm)", "IK", "input"):
        table.add_column(column)

    def mm(p):
        return "-" if p is None else " ".join(f"{v * 1000:+7.1f}" for v in p)

    for arm, hand in target.hands.items():
        error = (np.linalg.norm(hand.goal_m - hand.actual_m) * 1000
                 if hand.goal_m is not None and hand.actual_m is not None else float("nan"))
        table.add_row(arm, mm(hand.goal_m), mm(hand.actual_m), f"{error:.1f}", hand.ik_status,
                      "[red]stale[/]" if hand.stale else "ok")
    latency = target.latencies_s[-1] * 1000 if target.latencies_s else float("nan")
    table.caption = (f"samples {target.samples_used}  rejected {target.mapper.rejected}  "
                     f"latency {latency:.1f} ms")
    return table


@click.command()
@click.option("--replay", type=click.Path(dir_okay=False), default=None,
              help="Replay a raw FASTRAK capture or a pose log.")
@click.option("--port", default=None, help="Read a live FASTRAK on this serial port.")
@click.option("--baud", type=int, default=115200, show_default=True, help="Live port baud rate.")
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
              help="Stop after this long (live mode; default: until q or Ctrl-C).")
@click.option("--no-estop", is_flag=True, help=NO_ESTOP_HELP)
@click.option("--gui", is_flag=True, help="Open the PyBullet window.")
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="Run folder (default runs/<time>-teleop).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--video", is_flag=True,
              help="After the run, render video.mp4 from its log (needs hubo-cli[viz]).")
@hardware_options
def teleop(replay, port, baud, driver, armed, mode, speed, scale, station_map, wall_distance,
           clutch_at, duration, no_estop, gui, out, as_json, video, **hardware) -> None:
    """Drive the robot's hands from an operator's FASTRAK stream.

    Exactly one of --replay FILE or --port DEV. The first sample of each station calibrates it:
    later motion is relative. Writes a run folder with the per-period log, summary.json and the
    commanded-vs-actual path plot.

    Examples: hubo teleop --replay trajectories/drill-rectangle.fastrak --mode drill
              hubo teleop --port /dev/ttyUSB0
    """
    from hubo_cli.cli.keys import KeyReader
    from hubo_cli.cli.replay import add_run_video, check_video_support
    from hubo_cli.teleop.session import TeleopSettings, run_teleop

    if video:
        check_video_support()

    if (replay is None) == (port is None):
        raise InputError("give exactly one of --replay FILE or --port DEV",
                         hint="e.g. hubo teleop --replay trajectories/drill-rectangle.fastrak")
    explicit = click.get_current_context().get_parameter_source("speed")
    if speed == "max" and explicit is click.core.ParameterSource.COMMANDLINE and (
            port is not None or gui or driver_class(driver).real_time):
        raise InputError("--speed max is for replays on the sim or ideal drivers",
                         hint="live input, the hardware driver and --gui run in real time; "
                              "leave --speed out")
    settings = TeleopSettings(
        replay=replay, port=port, driver=driver, mode=mode, speed=_speed(speed), scale=scale,
        station_arm=_station_map(station_map),
        wall_distance_m=None if wall_distance is None else wall_distance / 1000.0,
        duration_s=duration, clutch_at_s=tuple(clutch_at), out=out, gui=gui, baud=baud,
        estop=not no_estop, driver_options=driver_options(driver, armed, **hardware))
    state = {"live": None, "keys": None}

    def on_key(char: str) -> None:
        target = state["target"]
        if char == " ":
            target.keys.estop = True
        elif char == "r":
            target.keys.release = True
        elif char == "c":
            target.keys.clutch = True
        elif char in ("q", "\x1b"):
            target.keys.quit = True

    def on_ready(target) -> None:
        state["target"] = target
        if interactive() and not as_json:
            live = Live(get_renderable=lambda: _view(target), refresh_per_second=4,
                        console=err_console)
            live.start()
            state["live"] = live
            keys = KeyReader(on_key)
            keys.__enter__()
            state["keys"] = keys

    try:
        run = run_teleop(settings, on_ready=on_ready)
    finally:
        if state["keys"] is not None:
            state["keys"].__exit__(None, None, None)
        if state["live"] is not None:
            state["live"].stop()
    summary = run.summary
    if video:
        add_run_video(run.run_dir, summary)
    if as_json:
        print_json({"run_dir": str(run.run_dir), **summary})
    else:
        errors = ", ".join(f"{arm} {v:.1f} mm rms / {summary['max_error_mm'][arm]:.1f} max"
                           for arm, v in summary["rms_error_mm"].items()) or "no operator input"
        console.print(f"teleop {summary['ended']} after {summary['duration_s']:.1f} s "
                      f"({summary['periods']} periods): {errors}")
        console.print(f"  e-stops {len(summary['estop_events'])}, statuses "
                      f"{summary['status_counts']}, max velocity "
                      f"{summary['max_joint_velocity_ratio']:.0%} of limit")
        console.print(f"  run folder: {run.run_dir}")
        if video:
            console.print(f"  video: {summary['video']['file']}")
        if summary["error"]:
            err_console.print(f"[yellow]{summary['error']}[/]")
    if not run.loop.ok:
        raise SystemExit(130 if run.loop.ended == "interrupted" else 1)
