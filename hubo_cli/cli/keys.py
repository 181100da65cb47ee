"""Single-key operator input on a terminal (cbreak mode, a reader thread); no-op otherwise.

:func:`operator_keys` gives every robot command the same keys (space e-stop, r release, q
finish; :mod:`hubo_cli.control.operator`), and a command its own on top (teleop's c, b).
"""

from __future__ import annotations

import contextlib
import os
import select
import sys
import threading
from collections.abc import Callable, Iterator

from hubo_cli.cli.output import err_console
from hubo_cli.control.operator import KEYS_HELP, OperatorKeys


def keyboard_fd() -> int | None:
    """stdin's descriptor when it is a terminal this process may read keys from (it is in the
    terminal's foreground: a background job setting cbreak would be stopped); else None."""
    try:
        fd = sys.stdin.fileno()
        if os.isatty(fd) and os.tcgetpgrp(fd) == os.getpgrp():
            return fd
    except (OSError, ValueError, AttributeError):  # closed, replaced or detached stdin
        pass
    return None


@contextlib.contextmanager
def operator_keys(other: Callable[[str], None] | None = None
                  ) -> Iterator[OperatorKeys | None]:
    """The operator's keys while the block runs, read from the terminal; None (no keys, nothing
    changed on the terminal) when stdin is not a terminal in the foreground (pipes, CI).

    Args:
        other: called with any other key (a command's own keys).
    """
    if keyboard_fd() is None:
        yield None
        return
    keys = OperatorKeys()

    def on_key(char: str) -> None:
        if not keys.press(char) and other is not None:
            other(char)

    with KeyReader(on_key):
        yield keys


def announce_keys(keys: OperatorKeys | None, quiet: bool = False) -> None:
    """One line on stderr naming the operator's keys, when there are (a command without a live
    view; ``quiet``: ``--json``)."""
    if keys is not None and not quiet:
        err_console.print(f"keys: {KEYS_HELP}", markup=False)


class KeyReader:
    """Calls ``on_key(char)`` for every key pressed while active. Restores the terminal on exit.

    Does nothing when stdin is not a terminal in the foreground (pipes, tests, CI).
    """

    def __init__(self, on_key: Callable[[str], None]) -> None:
        self.on_key = on_key
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._saved = None

    def __enter__(self) -> KeyReader:
        fd = keyboard_fd()
        if fd is None:
            return self
        import termios
        import tty

        try:
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        except termios.error:  # not a terminal after all: no keys
            self._saved = None
            return self
        self._thread = threading.Thread(target=self._run, args=(fd,), daemon=True)
        self._thread.start()
        return self

    def _run(self, fd: int) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([fd], [], [], 0.1)
                data = os.read(fd, 1) if ready else None
            except OSError:  # the terminal went away: no more keys
                return
            if data == b"":  # end of input (hung up)
                return
            char = (data or b"").decode(errors="ignore")
            if char:
                self.on_key(char)

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._saved is not None:
            import termios

            with contextlib.suppress(OSError, ValueError, termios.error):
                termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self._saved)
