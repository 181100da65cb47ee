"""Shared output helpers for the command line: JSON to stdout, rich tables, numbers."""

from __future__ import annotations

import contextlib
import json
import sys

import click
import numpy as np
from rich.console import Console

from hubo_cli.runs import _jsonable

NO_ESTOP_HELP = ("Turn the soft emergency stopper off (operator key, capture point, wrist "
                 "torque, stale input); the hard stopper, collision detector and limiter stay. "
                 "Refused for a walk (Ctrl-C's stance stop is the operator's): "
                 "--estop-sources operator keeps only that one.")

console = Console(highlight=False, soft_wrap=True)
err_console = Console(stderr=True, highlight=False, soft_wrap=True)


JSON_WANTED, JSON_PRINTED = "hubo.json_wanted", "hubo.json_printed"  # keys of click's ctx.meta


def print_json(data: dict) -> None:
    """Print one JSON object on stdout (numpy values converted, non-finite as null); the
    command's context notes it, so an error after it prints no second document."""
    click.echo(json.dumps(_jsonable(data), indent=2))
    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        ctx.meta[JSON_PRINTED] = True


def note_json(ctx: click.Context, param: click.Parameter, value: bool) -> bool:
    """``--json``'s callback: notes in the context's meta (shared by the group and its
    subcommands) that the command was asked for JSON, so that an error ending it prints its
    JSON document too (:func:`print_json_error`)."""
    if value:
        ctx.meta[JSON_WANTED] = True
    return value


def print_json_error(ctx: click.Context, message: str, exit_code: int, hint: str = "") -> None:
    """The one JSON document of a command asked for ``--json`` that ends in an error before it
    printed one (the error's line and hint still go to stderr)."""
    if ctx.meta.get(JSON_WANTED) and not ctx.meta.get(JSON_PRINTED):
        print_json({"error": message, "hint": hint, "exit_code": exit_code})


def exit_if_interrupted(summary: dict, failure: Exception | None = None) -> None:
    """Exit 130 after a run that Ctrl-C or SIGTERM ended (its summary already printed); one
    line on stderr when a walk's stop after it fell back to the brake, and, when a sensor
    fault or another error came during its stance stop (``failure``'s ``events``), one line
    each for the interrupt and what came after it, in order."""
    report_interrupt_stop(summary)
    if summary.get("ended") == "interrupted":
        events = getattr(failure, "events", ())
        for i, event in enumerate(events):
            err_console.print(event if i == 0 else f"then: {event}", soft_wrap=True,
                              markup=False, highlight=False)
        raise SystemExit(130)


def report_interrupt_stop(summary: dict) -> None:
    """One line on stderr when the stop a walk was asked for after an interrupt or a log
    failure (the summary's ``interrupt_stop``) did not end standing."""
    how = summary.get("interrupt_stop")
    if how and how != "stood":
        err_console.print(f"warning: the walk did not finish its step into a stance after the "
                          f"interrupt: {how}", soft_wrap=True)


def print_run_folder(run_dir, files, width: int = 18, indent: str = "") -> None:
    """The run folder and, below it, the files the run wrote there (the summary's ``files``,
    which every file is added to as it is written), the label padded to ``width``."""
    console.print(f"{indent}{'run folder':<{width}}{run_dir}", soft_wrap=True)
    console.print(f"{indent}{'':<{width}}{', '.join(files)}", soft_wrap=True)


def fmt_q(q_rad) -> str:
    """Joint vector as space-separated radians with 4 decimals."""
    return " ".join(f"{v:+.4f}" for v in np.asarray(q_rad, dtype=float))


@contextlib.contextmanager
def busy(what: str, quiet: bool = False):
    """Around a step that takes more than a second: a spinner saying ``what`` on a terminal's
    stderr, else (unless ``quiet``: --json) the words as one line on stderr when it starts."""
    if err_console.is_terminal and not err_console.is_dumb_terminal:
        with err_console.status(what):
            yield
    else:
        if not quiet:
            err_console.print(f"{what} ...", soft_wrap=True)
        yield


def warn(message: str) -> None:
    """A one-line warning on stderr."""
    err_console.print(f"[yellow]warning:[/] {message}")


def report_log_warnings(log, report: dict, as_json: bool) -> None:
    """What is wrong in a log that was still read: cut short (fewer periods than its log.json
    says the run logged: ``periods_expected``) and values the robot cannot have logged
    (``log_suspect``, one line each naming the rows); warning lines on stderr and fields in
    the JSON report, nothing for a sound log."""
    if log.cut_short:
        report["periods_expected"] = log.periods_expected
    if log.suspect:
        report["log_suspect"] = list(log.suspect)
    if not as_json:
        for line in ([log.cut_short] if log.cut_short else []) + log.suspect:
            warn(line)


def interactive() -> bool:
    """True when stdout is a terminal (progress bars and live views are shown)."""
    return sys.stdout.isatty()


class ProgressLines:
    """While a run goes on, print one progress line to stderr every ``every_s`` seconds, and at
    once (but at most every ``gap_s``) when ``urgent()`` changes (for output that is not a
    terminal, or a terminal too dumb or narrow for a live view: progress without redrawing).

    Args:
        line: returns the line to print.
        every_s: seconds between lines.
        urgent: returns what must be shown as soon as it changes (e.g. the safety state's
            words); None: lines on the clock only.
        gap_s: the shortest time between two lines.
    """

    def __init__(self, line, every_s: float = 2.0, urgent=None, gap_s: float = 0.5) -> None:
        import threading

        self.line = line
        self.every_s = every_s
        self.urgent = urgent
        self.gap_s = min(gap_s, every_s)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="progress-lines", daemon=True)

    def _run(self) -> None:
        import time

        printed_s, shown = time.monotonic(), self._urgent()
        while not self._stop.wait(self.gap_s):
            now, urgent = time.monotonic(), self._urgent()
            if urgent != shown or now - printed_s >= self.every_s - 1e-3:
                click.echo(self.line(), err=True)
                printed_s, shown = now, urgent

    def _urgent(self):
        return None if self.urgent is None else self.urgent()

    def start(self) -> None:
        """Start printing."""
        self._thread.start()

    def stop(self) -> None:
        """Stop printing (idempotent)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
