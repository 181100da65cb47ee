"""``hubo task``: scripted tasks and experiments, each a subcommand of this group."""

from __future__ import annotations

import click

from hubo_cli.cli.output import console, print_json
from hubo_cli.errors import HuboError

EXIT_INTERRUPTED = 130


@click.group("task")
def task() -> None:
    """Run a scripted task or experiment on the robot (simulated by default)."""


@task.command("push-wall")
@click.option("--direction", type=click.Choice(["forward", "left"]), default="forward",
              show_default=True,
              help="forward: both hands 0.25 m into a wall in 4 s; left: the left hand 0.25 m "
                   "into a block on its left in 2 s.")
@click.option("--no-estop", is_flag=True,
              help="Leave the emergency stopper out of the pipeline (the robot may fall).")
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="Run folder (default runs/<time>-push-wall-<direction>-<estop>).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--interpolator", type=click.Choice(["otg", "hoff-arbib"]), default="otg",
              show_default=True, help="Trajectory generator: ruckig or Hoff-Arbib (eq. 1).")
@click.option("--gui", is_flag=True, help="Open the PyBullet window and run in real time.")
@click.pass_context
def push_wall(ctx: click.Context, direction: str, no_estop: bool, out: str | None,
              as_json: bool, interpolator: str, gui: bool) -> None:
    """The emergency-stop experiment (multi-layer controllers paper, IV-C): push a wall.

    With the emergency stopper the capture-point flag reverts the push and the robot stays
    up; without it the robot tips over. Writes log.csv, summary.json and cp_error.png.

    Example: hubo task push-wall --direction left --no-estop
    """
    from hubo_cli.experiments.push_wall import run_push_wall
    from hubo_cli.model import load_model

    result = run_push_wall(load_model(), direction=direction, estop=not no_estop, out=out,
                           speed=1.0 if gui else None, gui=gui, interpolator=interpolator)
    summary = result.summary | {"run_dir": str(result.run_dir)}
    loop = result.loop
    if loop.ended in ("module-error", "target-error", "driver-error"):
        raise HuboError(f"the run stopped early: {loop.error}",
                        hint=f"the log up to the stop is in {result.run_dir / 'log.csv'}")
    if as_json:
        print_json(summary)
    else:
        _print_summary(summary)
    if loop.ended == "interrupted":
        ctx.exit(EXIT_INTERRUPTED)


def _print_summary(summary: dict) -> None:
    flag = summary["t_emergency_s"]
    cp_flag = summary["t_cp_flag_s"]
    outcome = "FELL" if summary["fell"] else "tipped" if summary["tipped"] else "stayed up"
    console.print(f"push              {summary['direction']}, {summary['push_m']:g} m in "
                  f"{summary['push_s']:g} s")
    console.print(f"emergency stop    {summary['estop']}"
                  + (f" (revert {summary['revert_s']:g} s, stop {summary['stop_s']:g} s)"
                     if summary["estop"] == "on" else ""))
    console.print("capture-point flag "
                  + (f"at {cp_flag:.3f} s" if cp_flag is not None else "never raised"))
    console.print("emergency         "
                  + (f"at {flag:.3f} s ({', '.join(summary['emergency_sources'])})"
                     if flag is not None else "none"))
    console.print(f"robot             {outcome}: max tilt {summary['max_tilt_deg']:.1f} deg, "
                  f"sole lift {summary['max_sole_lift_mm']:.0f} mm")
    console.print(f"max CP error      {summary['max_cp_error_mm']:.1f} mm along "
                  f"{summary['cp_error_axis']}")
    console.print(f"ended             {summary['ended']} after {summary['duration_s']:.2f} s")
    console.print(f"run folder        {summary['run_dir']}", soft_wrap=True)
    console.print("                  log.csv, summary.json, cp_error.png")
