"""Single-key operator input on a terminal (cbreak mode, a reader thread); no-op otherwise."""

from __future__ import annotations

import os
import select
import sys
import threading
from collections.abc import Callable


class KeyReader:
    """Calls ``on_key(char)`` for every key pressed while active. Restores the terminal on exit.

    Does nothing when stdin is not a terminal (pipes, tests, CI).
    """

    def __init__(self, on_key: Callable[[str], None]) -> None:
        self.on_key = on_key
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._saved = None

    def __enter__(self) -> KeyReader:
        if not sys.stdin.isatty():
            return self
        import termios
        import tty

        fd = sys.stdin.fileno()
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd)
        self._thread = threading.Thread(target=self._run, args=(fd,), daemon=True)
        self._thread.start()
        return self

    def _run(self, fd: int) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready:
                char = os.read(fd, 1).decode(errors="ignore")
                if char:
                    self.on_key(char)

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._saved is not None:
            import termios

            termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self._saved)
