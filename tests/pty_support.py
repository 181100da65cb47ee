"""Run a command on a pseudo-terminal of a given width and TERM, as an operator's terminal."""

from __future__ import annotations

import fcntl
import os
import pty
import select
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Callable
from pathlib import Path

HUBO = str(Path(sys.executable).with_name("hubo"))


def run_in_pty(argv: list[str], *, columns: int = 80, term: str = "xterm-256color",
               timeout_s: float = 60.0,
               on_output: Callable[[str, Callable[[bytes], None]], None] | None = None,
               ) -> tuple[int, str]:
    """Run ``argv`` with stdin, stdout and stderr on one pty of ``columns`` columns; returns
    (exit code, everything it wrote). ``on_output(text_so_far, send)`` is called after each
    read and may type into the terminal with ``send``."""
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 40, columns, 0, 0))
    env = dict(os.environ, TERM=term, COLUMNS=str(columns), LINES="40")
    # a session of its own with the pty as its controlling terminal, in the foreground (as in
    # an operator's terminal): the commands read keys only from such a terminal
    process = subprocess.Popen(argv, stdin=follower, stdout=follower, stderr=follower, env=env,
                               start_new_session=True,
                               preexec_fn=lambda: fcntl.ioctl(0, termios.TIOCSCTTY, 0))
    os.close(follower)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([leader], [], [], 0.1)
            if ready:
                try:
                    data = os.read(leader, 65536)
                except OSError:  # the command closed the terminal (it ended)
                    break
                if not data:
                    break
                chunks.append(data)
                if on_output is not None:
                    on_output(b"".join(chunks).decode(errors="replace"),
                              lambda keys: os.write(leader, keys))
            elif process.poll() is not None:
                break
        return process.wait(timeout=max(1.0, deadline - time.monotonic())), \
            b"".join(chunks).decode(errors="replace")
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        os.close(leader)
