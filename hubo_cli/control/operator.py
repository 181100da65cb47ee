"""The operator's keys every robot command shares: space stops, r releases, q finishes.

A key reader (the command line's, :mod:`hubo_cli.cli.keys`) presses them from its thread; the
control loop takes what was pressed once per period and acts on it as on a target's ``info``:
an ``operator`` stop request, a release of every stopper, the end of the run (smooth stop,
summary written).
"""

from __future__ import annotations

import threading

KEYS = {" ": "estop", "r": "release", "q": "quit", "\x1b": "quit"}
KEYS_HELP = "space e-stop, r release, q finish"


class OperatorKeys:
    """Requests pressed since the loop last took them (safe to press from another thread)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: set[str] = set()
        self.finished = False  # q was taken: the operator ended the run

    def press(self, char: str) -> bool:
        """Record the request of key ``char``; False when it is not one of :data:`KEYS`."""
        request = KEYS.get(char)
        if request is None:
            return False
        with self._lock:
            self._pending.add(request)
        return True

    def take(self) -> dict:
        """The pending requests as a target's ``info`` entries (``estop``, ``release``,
        ``done``; see :mod:`hubo_cli.control.loop`), cleared."""
        with self._lock:
            pending, self._pending = self._pending, set()
        info: dict = {}
        if "estop" in pending:
            info["estop"] = "operator"
        if "release" in pending:
            info["release"] = True
        if "quit" in pending:
            info["done"] = True
            self.finished = True
        return info
