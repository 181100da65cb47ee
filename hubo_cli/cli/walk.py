"""``hubo walk``: walk the robot (simulated or through hubo-ach) to a goal stance."""

from __future__ import annotations

import math

import click

from hubo_cli.cli.hardware import driver_options, hardware_options
from hubo_cli.cli.options import (
    active_stops,
    balance_option_with,
    live_server,
    perturb_option,
    robot_run_options,
)
from hubo_cli.cli.output import (
    console,
    exit_if_interrupted,
    print_json,
    print_run_folder,
    warn,
)
from hubo_cli.drivers.registry import DRIVER_NAMES


@click.command("walk")
@click.option("--to", "goal", type=float, nargs=3, required=True, metavar="X Y YAW",
              help="Goal stance relative to the start: forward (m), left (m), turn (rad, "
                   "counter-clockwise).")
@click.option("--corrections", type=click.IntRange(0, 5), default=1, show_default=True,
              help="Walk again from where the feet stand when they slipped more than 8 mm or "
                   "1.5 deg off the goal, up to this many times.")
@click.option("--push", "push_n", type=float, default=0.0, show_default=True,
              help="Push the torso with this force (N) for 0.2 s at --push-at (the simulator "
                   "only): the capture point moves the next footsteps, and its monitor stops "
                   "the walk into a stance if they cannot catch it.")
@click.option("--push-direction", type=click.Choice(["forward", "backward", "left", "right"]),
              default="left", show_default=True, help="Which way the push acts.")
@click.option("--push-at", "push_at_s", type=float, default=2.5, show_default=True,
              help="When the push starts (s into the walk).")
@click.option("--stop-at", "stop_at_s", type=float, default=None,
              help="Stop the walk as the operator's space key would, this far into it (s): "
                   "the step in the air lands, the robot stands in double support and holds.")
@click.option("--driver", type=click.Choice(DRIVER_NAMES), default=DRIVER_NAMES[0],
              show_default=True, help="Robot back end.")
@click.option("--arm", "armed", is_flag=True, help="Arm the hardware driver (required by it).")
@click.option("--toe-heel/--flat-feet", "toe_heel", default=None,
              help="Roll the soles on toe and heel (the multi-layer paper's eq. 4, Fig. 4; the "
                   "robot file's [toe_heel]) or land them flat (the default: see "
                   "docs/stabilizer.md).")
@click.option("--gait", default="normal", show_default=True, metavar="NAME",
              help="The robot file's gait: normal, or fast (2 m in 12 steps at about 0.2 m/s; "
                   "see docs/walking.md).")
@click.option("--lip-feedback", is_flag=True,
              help="The stabilizer's soles track the multi-layer paper's LIP state feedback "
                   "(eq. 7-8) split between the feet by its QP (eq. 9-14).")
@robot_run_options("walk")
@perturb_option
@balance_option_with("off", "Walking: off by default (the standing balancers' reference "
                            "assumes both feet down).")
@hardware_options
def walk(goal: tuple[float, float, float], corrections: int, toe_heel: bool | None,
         gait: str, lip_feedback: bool, push_n: float, push_direction: str, push_at_s: float,
         stop_at_s: float | None, driver: str, armed: bool,
         no_estop: bool, estop_sources: str | None, accept_reduced_safety: bool, gui: bool,
         as_json: bool, out: str | None, live: bool, live_host: str | None,
         live_port: int | None, perturb_seed: int | None, balance: str, **hardware) -> None:
    """Walk the HUBO 2+ to a goal stance (ZMP preview control, footsteps, leg IK).

    The robot starts standing in its walking posture (feet 0.26 m apart, 5 cm crouched) and
    walks through the full pipeline: trajectory generator, capture-point monitor (on the
    planned support), emergency stoppers, collision detector, limiter (the robot file's
    `walking` limit set). An emergency stop (the space key, --stop-at, the capture point)
    finishes the step in the air into a double-support stance and holds there. Exit code 1
    when it fell or was stopped short of the goal. On the hardware driver the robot must
    stand in the walking posture (refused otherwise, exit 4) and the final error is the
    estimate's (the robot has no truth; the simulated daemon's --truth-log does).

    \b
    Examples:
      hubo walk --to 1.0 0 0
      hubo walk --to 2.0 0 0 --gait fast
      hubo walk --to 1.0 0 0 --push 100 --push-direction backward --push-at 4.8
      hubo walk --to 1.0 0 0 --stop-at 2.2
      hubo walk --to 1.0 0 0 --driver hardware --arm   (against hubo hardware sim-daemon
        --posture walking, or a real robot standing so)
    """
    from hubo_cli.cli.keys import announce_keys, operator_keys
    from hubo_cli.control.stop_choice import SOFT_SOURCES, check_walk_stops
    from hubo_cli.experiments.standing import PUSH_DIRECTIONS
    from hubo_cli.experiments.walk import check_disturbances, check_goal, check_walk_driver
    from hubo_cli.experiments.walk import walk as walk_to
    from hubo_cli.model import load_model
    from hubo_cli.runs import reserved_run_dir

    check_goal(goal)
    check_walk_driver(driver)
    disturbances = check_disturbances(push_n, PUSH_DIRECTIONS[push_direction], push_at_s,
                                      stop_at_s, driver)
    options = driver_options(driver, armed, **hardware, quiet=as_json)
    stops = active_stops(SOFT_SOURCES, driver, no_estop=no_estop, estop_sources=estop_sources,
                         accept_reduced_safety=accept_reduced_safety, quiet=as_json)
    check_walk_stops(stops, "a walk")
    with (reserved_run_dir("walk", out) as run_dir,  # a bad --out fails before anything runs
          live_server(live, live_host, live_port, quiet=as_json) as server,
          operator_keys() as keys):
        announce_keys(keys, quiet=as_json)
        result = walk_to(load_model(), goal, gui=gui, out=run_dir, stops=stops,
                         perturb_seed=perturb_seed, corrections=corrections,
                         balance=balance, operator=keys, live=server, driver=driver,
                         driver_options=options, disturbances=disturbances,
                         lip_feedback=lip_feedback, gait=gait,
                         **({} if toe_heel is None else {"toe_heel": toe_heel}))
    fields = result.summary() | {"ended": result.ended, "estop_events": result.estop_events,
                                 "interrupt_stop": result.interrupt_stop,
                                 "run_dir": str(result.run_dir)}
    if as_json:
        print_json(fields)
    else:
        console.print(f"goal              {goal[0]:g} m forward, {goal[1]:g} m left, "
                      f"{math.degrees(goal[2]):.1f} deg")
        if result.stopped_s is not None:
            console.print(f"stopped           at {result.stopped_s:.2f} s: "
                          f"{'standing in double support' if result.stood else 'did not stand'}"
                          f", {result.shifts} footstep changes after the capture point")
        elif result.shifts:
            console.print(f"capture point     moved the footsteps {result.shifts} times")
        if result.touchdowns_early:
            console.print(f"pushed down       {result.touchdowns_early} swing(s) ended where "
                          "the foot touched the floor early")
        ended = _interrupted_words(result)
        if ended is not None:
            console.print(f"ended             {ended}")
        truth = ("" if result.fell_truth is None or result.fell_truth == result.fell
                 else f" (the simulator's truth: {'YES' if result.fell_truth else 'no'}, "
                      f"largest torso tilt {result.max_true_tilt_deg:.0f} deg)")
        console.print(f"fell              {'YES' if result.fell else 'no'}{truth}")
        speed = result.average_speed_m_s
        if result.ended == "interrupted" and result.interrupt_stop != "stood":  # cut short
            console.print(f"steps             {result.steps} planned, the run ended before "
                          "the walk did")  # the plan's steps, not those taken
        else:
            console.print(f"steps             {result.steps} in {result.walking_s:.2f} s"
                          + ("" if speed is None else f" ({speed:.3f} m/s)"))
        console.print(f"final error       {result.final_error_mm:.1f} mm, "
                      f"{result.final_error_deg:.2f} deg (estimated "
                      f"{result.estimated_final_error_mm:.1f} mm, "
                      f"{result.estimated_final_error_deg:.2f} deg)")
        console.print(f"ZMP inside        {100 * result.zmp_inside_fraction:.1f} % of periods")
        console.print(f"e-stop events     {result.estop_events}")
        print_run_folder(result.run_dir, result.files)
    for event in result.unplayed:  # e.g. --push-at 3600 on an 8 s walk
        warn(f"the walk ended before {event.at_s:g} s: its {'push' if event.push_n else 'stop'}"
             f" there never came (use --{'push' if event.push_n else 'stop'}-at within the "
             f"walk's {result.walking_s:.1f} s)")
    exit_if_interrupted(fields, result.failure)
    if result.failure is not None:  # e.g. the robot's state lost: exit 3, the robot braked
        raise result.failure
    if result.fell or result.fell_truth or result.stopped_s is not None:  # fell, or stopped
        raise SystemExit(1)


def _interrupted_words(result) -> str | None:
    """How an interrupted walk ended, for the report's ``ended`` line (None: it was not):
    its step finished into a stance (also after a log failure), never started (no plan), or
    braked short of the goal (with the stance stop's outcome, if one was asked)."""
    if result.interrupt_stop == "stood":  # Ctrl-C's stance stop, or a sensor fault's
        why = "a device fault" if result.ended == "device" else "interrupted"
        return f"{why}: the step finished, standing in double support"
    if result.ended != "interrupted":
        return None
    if not result.steps:
        return "interrupted before the walk started"
    return ("interrupted: braked to a stop before the goal"
            + (f" ({result.interrupt_stop})" if result.interrupt_stop else ""))
