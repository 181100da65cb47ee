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


def exit_if_interrupted(summary: dict) -> None:
    """Exit 130 after a run that Ctrl-C or SIGTERM ended (its summary already printed)."""
    if summary.get("ended") == "interrupted":
        raise SystemExit(130)


def fmt_q(q_rad) -> str:
    """Joint vector as space-separated radians with 4 decimals."""
    return " ".join(f"{v:+.4f}" for v in np.asarray(q_rad, dtype=float))


def warn(message: str) -> None:
    """A one-line warning on stderr."""
    err_console.print(f"[yellow]warning:[/] {message}")


def interactive() -> bool:
    """True when stdout is a terminal (progress bars and live views are shown)."""
    return sys.stdout.isatty()


class ProgressLines:
    """While a run goes on, print one progress line to stderr every ``every_s`` seconds (for
    output that is not a terminal: pipes and logs get progress too, without a live view).

    Args:
        line: returns the line to print.
        every_s: seconds between lines.
    """

    def __init__(self, line, every_s: float = 2.0) -> None:
        import threading

        self.line = line
        self.every_s = every_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="progress-lines", daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            click.echo(self.line(), err=True)

    def start(self) -> None:
        """Start printing."""
        self._thread.start()

    def stop(self) -> None:
        """Stop printing (idempotent)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
