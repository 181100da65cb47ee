"""Options that several robot commands share."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import click

from hubo_cli.cli.output import NO_ESTOP_HELP, err_console
from hubo_cli.control.stop_choice import (
    CONFIRM_OPTION,
    SOFT_SOURCES,
    ActiveStops,
    StopChoice,
    decide_stops,
)

force_option = click.option(
    "--force", is_flag=True,
    help="Write over an existing output file (never over an input or a run folder's file).")

perturb_option = click.option(
    "--perturb", "perturb_seed", type=click.IntRange(min=0), default=None, metavar="SEED",
    help="Simulate a robot and world drawn from SEED (masses, centres of mass, foot friction, "
         "sensor noise, command delay, floor tilt; 0 = nominal); the draws go into "
         "summary.json. Same seed, same run.")

BALANCE_HELP = ("Balance controllers: default (the ankle balancer's common and differential "
                "damping and what the balance pipeline adds), paper (eq. 11-12 as published, to "
                "study its lean) or off. Recorded in summary.json.")


def balance_option_with(default: str, note: str = ""):
    """``--balance {default,paper,off}`` with its own default (``note`` says why)."""
    return click.option("--balance", "balance", type=click.Choice(["default", "paper", "off"]),
                        default=default, show_default=True,
                        help=BALANCE_HELP + (f" {note}" if note else ""))


balance_option = balance_option_with("default")


def robot_run_options(run_name: str):
    """``--no-estop``, ``--estop-sources``, ``--accept-reduced-safety``, ``--gui``, ``--json``
    and ``--out`` of a command that runs the robot.

    Args:
        run_name: the run folder's default name after the time (``sim``, ``task-<name>``).
    """
    options = [
        click.option("--no-estop", is_flag=True, help=NO_ESTOP_HELP),
        click.option("--estop-sources", "estop_sources", default=None, metavar="LIST",
                     help=f"The soft emergency stopper's sources, exactly: a comma-separated "
                          f"list of {', '.join(SOFT_SOURCES)}, or none. The only way besides "
                          "--no-estop to remove one (task files and --set may only add)."),
        click.option(CONFIRM_OPTION, "accept_reduced_safety", is_flag=True,
                     help="Confirm --no-estop or --estop-sources removing a stop source on the "
                          "hardware driver (refused without it, exit 4)."),
        click.option("--gui", is_flag=True, help="Open the PyBullet window (runs in real time)."),
        click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON."),
        click.option("--out", type=click.Path(file_okay=False), default=None,
                     help=f"Run folder (default runs/<time>-{run_name})."),
        click.option("--live", is_flag=True,
                     help="Serve the run to Foxglove as it runs (open connection "
                          "ws://localhost:8765; runs in real time; see docs/live-view.md)."),
        click.option("--live-host", default=None, metavar="HOST",
                     help="Address --live binds (default 127.0.0.1: this machine only)."),
        click.option("--live-port", type=int, default=None, metavar="PORT",
                     help="TCP port of --live (default 8765; 0: any free port, printed)."),
    ]

    def decorate(function):
        for option in reversed(options):
            function = option(function)
        return function
    return decorate


@contextlib.contextmanager
def live_server(live: bool, host: str | None, port: int | None,
                quiet: bool = False) -> Iterator[object | None]:
    """The Foxglove server of ``--live`` (None without it), bound now, before the robot
    moves, and stopped when the block ends (Ctrl-C included); its address is announced on
    stderr unless ``quiet``.

    Raises:
        InputError: ``--live-host``/``--live-port`` without ``--live``, a bad port or one in
            use.
    """
    from hubo_cli.errors import InputError

    if not live:
        if host is not None or port is not None:
            raise InputError("--live-host and --live-port apply to --live",
                             hint="add --live, or leave them out")
        yield None
        return
    from hubo_cli.viz.foxglove_messages import LAYOUT_PATH
    from hubo_cli.viz.live import DEFAULT_HOST, DEFAULT_PORT, LiveServer

    server = LiveServer(DEFAULT_HOST if host is None else host,
                        DEFAULT_PORT if port is None else port)
    try:
        if not quiet:
            err_console.print(f"live: Foxglove, open connection {server.url} "
                              f"(layout: {LAYOUT_PATH})", markup=False, highlight=False)
        yield server
    finally:
        server.close()
    if server.error and not quiet:
        err_console.print(f"live: publishing stopped early: {server.error}", style="yellow",
                          markup=False)


def active_stops(requested: tuple[str, ...], driver: str, *, no_estop: bool,
                 estop_sources: str | None, accept_reduced_safety: bool,
                 quiet: bool = False) -> ActiveStops:
    """The stop sources a run keeps (:func:`~hubo_cli.control.stop_choice.decide_stops` on the
    command line's choice), announced on stderr on one line unless ``quiet`` (``--json``)."""
    choice = StopChoice.from_options(no_estop, estop_sources, accept_reduced_safety)
    stops = decide_stops(requested, choice, driver)
    if not quiet:
        style = "bold yellow" if stops.removed or not stops.sources else "green"
        err_console.print(f"safety: {stops.words()}", style=style, markup=False)
    return stops
