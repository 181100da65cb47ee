"""The ``hubo`` command group: each subcommand lives in its own module, imported on use."""

from __future__ import annotations

import importlib
import sys

import click

from hubo_cli import __version__
from hubo_cli.errors import HuboError

# command name -> "module:attribute" (modules are imported only when the command runs)
COMMANDS = {
    "fk": "hubo_cli.cli.kinematics:fk",
    "ik": "hubo_cli.cli.kinematics:ik",
    "fastrak": "hubo_cli.cli.fastrak:fastrak",
    "record": "hubo_cli.cli.fastrak:record",
    "workspace-map": "hubo_cli.cli.workspace:workspace_map",
    "sim": "hubo_cli.cli.sim:sim",
    "task": "hubo_cli.cli.task:task",
    "teleop": "hubo_cli.cli.teleop:teleop",
    "hardware": "hubo_cli.cli.hardware:hardware",
    "replay": "hubo_cli.cli.replay:replay",
    "export": "hubo_cli.cli.export:export",
}


class LazyGroup(click.Group):
    """A click group whose subcommands are imported when used (fast ``--help``)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        target = COMMANDS.get(name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except HuboError as exc:
            click.secho(f"error: {exc}", fg="red", err=True)
            if exc.hint:
                click.echo(f"hint: {exc.hint}", err=True)
            ctx.exit(exc.exit_code)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            ctx.exit(130)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="hubo")
def main() -> None:
    """Teleoperation and task execution for the HUBO 2+ humanoid.

    Runs on the simulated Hubo by default (no hardware needed).
    """


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
