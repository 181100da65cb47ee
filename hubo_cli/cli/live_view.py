"""A robot run's live view on the operator's terminal: it degrades, it never blanks.

A terminal that can redraw (not ``TERM=dumb``), at least :data:`MIN_COLUMNS` wide and
:data:`MIN_LINES` high gets the rich view, redrawn four times a second. Anything else gets
plain lines on stderr, one line per update, never cut (the terminal wraps them): on a dumb,
narrow or short terminal one a second, and at once (at most twice a second) when the safety
state changes; in a pipe or a log one every two seconds and on every safety change.
"""

from __future__ import annotations

from collections.abc import Callable

from rich.console import Console, RenderableType
from rich.live import Live

from hubo_cli.cli.output import ProgressLines, err_console, interactive

MIN_COLUMNS = 60  # narrower, a rich table's cells come out empty and lines are cut
MIN_LINES = 12  # lower, the view's last lines would be cut off
TERMINAL_EVERY_S = 1.0
PIPE_EVERY_S = 2.0
URGENT_GAP_S = 0.5


def rich_view_fits(console: Console) -> bool:
    """The console can show the rich live view: a terminal that redraws, large enough."""
    return (console.is_terminal and not console.is_dumb_terminal
            and console.width >= MIN_COLUMNS and console.height >= MIN_LINES)


class LiveView:
    """The live view of one run, started once the robot has started and stopped at its end.

    Args:
        render: returns the rich view.
        line: returns the view as one plain line.
        urgent: returns what must be shown as soon as it changes (the safety words).
        header: a plain line printed once before the first (e.g. the operator's keys).
        transient: the rich view disappears when stopped.
        console: where it goes (stderr).
    """

    def __init__(self, render: Callable[[], RenderableType], line: Callable[[], str],
                 urgent: Callable[[], object] | None = None, header: str | None = None,
                 transient: bool = False, console: Console = err_console) -> None:
        self.console = console
        self.header = header
        self.rich = interactive() and rich_view_fits(console)
        self._live: Live | None = None
        self._lines: ProgressLines | None = None
        if self.rich:
            self._live = Live(get_renderable=render, refresh_per_second=4, console=console,
                              transient=transient)
        else:
            every_s = TERMINAL_EVERY_S if console.is_terminal else PIPE_EVERY_S
            self._lines = ProgressLines(line, every_s=every_s, urgent=urgent,
                                        gap_s=URGENT_GAP_S)

    def start(self) -> None:
        """Start drawing (the header first, for plain lines)."""
        if self._live is not None:
            self._live.start()
            return
        if self.header:
            self.console.print(self.header, markup=False, highlight=False)
        self._lines.start()

    def stop(self) -> None:
        """Stop drawing (idempotent)."""
        if self._live is not None:
            self._live.stop()
        if self._lines is not None:
            self._lines.stop()
