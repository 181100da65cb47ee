"""The one root error type of hubo-cli and its specific children.

Every error carries the data that explains it and a ``hint`` that says what to do next. The
command line prints ``str(error)`` on one line (plus the hint) and exits with ``exit_code``.
Expected outcomes (an unreachable goal, a capped solution, a held joint) are *results*, not
errors: see :class:`hubo_cli.kinematics.choice.IKResult`.
"""

from __future__ import annotations


class HuboError(Exception):
    """Root of every error hubo-cli raises on purpose.

    Args:
        message: one line saying what went wrong.
        hint: one line saying how to fix it (may be empty).
    """

    exit_code = 1

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint

    def __str__(self) -> str:
        return self.message


class ConfigError(HuboError):
    """A robot, task or parameter file is missing, malformed or inconsistent."""

    exit_code = 2

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None,
                 field: str | None = None, hint: str = "") -> None:
        where = ""
        if path:
            where = f"{path}"
            if line is not None:
                where += f":{line}"
            where += ": "
        if field:
            where += f"[{field}] "
        super().__init__(where + message, hint)
        self.path = path
        self.line = line
        self.field = field


class InputError(HuboError):
    """Bad user input: a malformed file, a bad command-line value, a stream that cannot be read."""

    exit_code = 2


class DeviceError(HuboError):
    """A device (serial port, tracker, robot bridge) is absent, closed or misbehaving."""

    exit_code = 3


class SafetyError(HuboError):
    """A safety rule refused an action before anything moved (e.g. the hardware is not armed)."""

    exit_code = 4


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C raises KeyboardInterrupt: a run ends the same way (its
    smooth stop, its summary, exit 130)."""


def interrupt_cause(exc: BaseException) -> str:
    """What interrupted a run: ``SIGTERM`` or ``Ctrl-C``."""
    return "SIGTERM" if isinstance(exc, Terminated) else "Ctrl-C"
