"""Shared output helpers for the command line: JSON to stdout, rich tables, numbers."""

from __future__ import annotations

import json
import sys

import click
import numpy as np
from rich.console import Console

from hubo_cli.runs import _jsonable

NO_ESTOP_HELP = ("Turn the soft emergency stopper off (operator key, capture point, wrist "
                 "torque, stale input); the hard stopper, collision detector and limiter stay.")

console = Console(highlight=False, soft_wrap=True)
err_console = Console(stderr=True, highlight=False, soft_wrap=True)


def print_json(data: dict) -> None:
    """Print one JSON object on stdout (numpy values converted, non-finite as null)."""
    click.echo(json.dumps(_jsonable(data), indent=2))


def fmt_q(q_rad) -> str:
    """Joint vector as space-separated radians with 4 decimals."""
    return " ".join(f"{v:+.4f}" for v in np.asarray(q_rad, dtype=float))


def warn(message: str) -> None:
    """A one-line warning on stderr."""
    err_console.print(f"[yellow]warning:[/] {message}")


def interactive() -> bool:
    """True when stdout is a terminal (progress bars and live views are shown)."""
    return sys.stdout.isatty()
