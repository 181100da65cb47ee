"""``hubo sim``: stand the simulated robot, optionally push it, and report how it copes."""

from __future__ import annotations

import json

import click

from hubo_cli.cli.hardware import driver_options, hardware_options
from hubo_cli.cli.options import (
    active_stops,
    balance_option,
    live_server,
    perturb_option,
    robot_run_options,
)
from hubo_cli.cli.output import console, exit_if_interrupted, print_json, print_run_folder
from hubo_cli.drivers.registry import DRIVER_NAMES
from hubo_cli.errors import InputError


@click.command("sim")
@click.option("--duration", type=float, default=5.0, show_default=True,
              help="Simulated time to stand (s).")
@click.option("--push", type=float, default=0.0, show_default=True,
              help="Push the torso with this force (N) for 0.2 s, 1 s into the run (at the "
                   "torso's centre of mass, about 0.93 m above the floor).")
@click.option("--push-direction", type=click.Choice(["forward", "backward", "left", "right"]),
              default="forward", show_default=True, help="Which way the push acts.")
@balance_option
@click.option("--no-balance", is_flag=True, help="The same as --balance off.")
@click.option("--step", is_flag=True,
              help="Catch a push the ankles cannot hold by stepping toward the capture point, "
                   "then bring the other foot beside it (the walking limit set).")
@click.option("--no-hip", is_flag=True,
              help="Leave out the hip strategy (the trunk bows when a push brings the capture "
                   "point near the toes or heels; it runs on the robot file's walking limits, "
                   "with the default balancer only) and stand on Table IV's limits.")
@click.option("--limits", "limit_set", default=None, metavar="NAME",
              help="The legs' joint-limit set the limiter enforces (the robot file's "
                   "table4 or a [limit_sets] name). Default: walking with --step or the hip "
                   "strategy (their legs must be fast enough), table4 otherwise; a set they "
                   "cannot run on is refused.")
@click.option("--driver", type=click.Choice(DRIVER_NAMES), default=DRIVER_NAMES[0],
              show_default=True, help="Robot back end (only the simulator pushes: on another, "
                                      "--push is refused).")
@click.option("--arm", "armed", is_flag=True, help="Arm the hardware driver (required by it).")
@robot_run_options("sim")
@perturb_option
@hardware_options
def sim(duration: float, push: float, push_direction: str, balance: str, no_balance: bool,
        step: bool, no_hip: bool, limit_set: str | None, driver: str, armed: bool,
        no_estop: bool, estop_sources: str | None, accept_reduced_safety: bool, gui: bool,
        as_json: bool, out: str | None, live: bool, live_host: str | None,
        live_port: int | None, perturb_seed: int | None, **hardware) -> None:
    """Stand the HUBO 2+ in its home posture and report tilt, feet and falls.

    On the hardware driver the robot must stand in the posture the run holds (with the default
    balancer hubo hardware sim-daemon's --posture braced, with --step or --no-hip --posture
    standing; refused otherwise, exit 4) and
    whatever pushes it is outside (the simulated daemon's --push); the tilt and feet are the
    estimate's.

    \b
    Examples:
      hubo sim --duration 5 --push 30 --push-direction backward
      hubo sim --driver hardware --arm --step --duration 6   (against hubo hardware
        sim-daemon --posture standing --push 120,at=2)
    """
    from hubo_cli.cli.keys import announce_keys, operator_keys
    from hubo_cli.control.stop_choice import SOFT_SOURCES
    from hubo_cli.experiments.standing import (
        PUSH_DIRECTIONS,
        check_standing_args,
        run_standing,
        standing_options,
    )
    from hubo_cli.model import load_model
    from hubo_cli.runs import reserved_run_dir

    # before any notice about the stop sources (the control period is the robot file's)
    check_standing_args(duration, push, load_model())
    driver_settings = driver_options(driver, armed, **hardware, quiet=as_json)
    if push and driver != "sim":
        raise InputError(f"--push needs the simulator; the {driver} driver's robot is pushed "
                         "from outside",
                         hint="leave out --push (the simulated daemon pushes: hubo hardware "
                              "sim-daemon --push N,at=S)")
    stops = active_stops(SOFT_SOURCES, driver, no_estop=no_estop, estop_sources=estop_sources,
                         accept_reduced_safety=accept_reduced_safety, quiet=as_json)
    # the run's one configuration, every option decided here (the limit set among them)
    options = standing_options(duration, push, balance="off" if no_balance else balance,
                               step=step, hip_strategy=not no_hip, limit_set=limit_set,
                               stops=stops, push_direction=PUSH_DIRECTIONS[push_direction],
                               perturb_seed=perturb_seed, driver=driver,
                               driver_options=driver_settings)
    model = load_model(limits=options.safety.limit_set)
    with (reserved_run_dir("sim", out) as run_dir,  # a bad --out fails before anything runs
          live_server(live, live_host, live_port, quiet=as_json) as server,
          operator_keys() as keys):
        announce_keys(keys, quiet=as_json)
        result = run_standing(model, options, gui=gui, out=run_dir, operator=keys,
                              live=server)
    # the run's whole summary (as in summary.json: pipeline, e-stops, perturbation draws ...)
    summary = (json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
               | {"run_dir": str(run_dir)})
    if as_json:
        print_json(summary)
    else:
        _print(summary, result, options, push_direction, run_dir)
    exit_if_interrupted(summary, result.failure)
    if result.failure is not None:  # e.g. the robot's state lost: exit 3, the robot braked
        raise result.failure


def _print(summary: dict, result, options, push_direction: str, run_dir) -> None:
    from hubo_cli.cli.safety_view import balance_summary_line

    profile, push, duration = options.safety, options.push_n, options.duration_s

    balance = {"default": "default (common + differential damping)",
               "paper": "paper (eq. 11-12: K_r 0.009 rad/s/deg, K_c 0.0015 rad/s/N m)",
               "off": "off"}[profile.balance_choice]
    push_text = (f"{push:g} N {push_direction} for 0.2 s at t = 1 s" if push > 0
                 else "none" if summary["driver"] == "sim" else "none from this run (the "
                 "robot is pushed from outside)")
    interrupted = " (interrupted)" if summary["ended"] == "interrupted" else ""
    console.print(f"stood             {result.simulated_s:.2f} s of {duration:g} s{interrupted}")
    console.print(f"balance           {balance}")
    console.print(f"push              {push_text}")
    console.print(f"leg limits        {profile.limit_set} ({options.limit_set_reason})")
    console.print(f"max tilt          {result.max_tilt_deg:.3f} deg "
                  f"(final {result.final_tilt_deg:.3f} deg)")
    console.print(f"feet flat         {'yes' if result.feet_flat else 'no'} "
                  f"(max sole tilt {result.max_sole_tilt_deg:.3f} deg)")
    console.print(f"fell              {'YES' if result.fell else 'no'}")
    if options.step:
        stepped = summary["capture_step"]
        console.print(f"stepped           {stepped['steps']} step(s)" + (
            f" from t = {stepped['trigger_s']:.2f} s" if stepped["stepped"] else "") + (
            f", ended in its stance by the stop at {stepped['stop_s']:.2f} s"
            if stepped["stop_s"] is not None else ""))
    console.print(f"support           {balance_summary_line(summary)}", soft_wrap=True)
    if summary["driver"] == "sim":
        console.print(f"real-time factor  {result.realtime_factor:.2f} "
                      f"({100 * result.physics_share:.0f} % of the time in physics)")
    print_run_folder(run_dir, summary["files"])
