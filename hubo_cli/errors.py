"""The one root error type of hubo-cli and its specific children.

Every error carries the data that explains it and a ``hint`` that says what to do next. The
command line prints ``str(error)`` on one line (plus the hint) and exits with ``exit_code``.
Expected outcomes (an unreachable goal, a capped solution, a held joint) are *results*, not
errors: see :class:`hubo_cli.kinematics.choice.IKResult`.
"""

from __future__ import annotations

# the most an error message quotes of a value it read (a file's field, a command-line value):
# enough to recognise it, never a 100,000-item list echoed whole
QUOTED_CHARS = 60


# The exit codes of a run that raised no error (the errors' own are their ``exit_code``):
# it ended without completing (a fall, a stop, a goal not met), or Ctrl-C / SIGTERM ended it
EXIT_NOT_COMPLETED = 1
EXIT_INTERRUPTED = 130


class HuboError(Exception):
    """Root of every error hubo-cli raises on purpose.

    Args:
        message: one line saying what went wrong.
        hint: one line saying how to fix it (may be empty).

    Attributes:
        events: when the run this error ended also saw others (Ctrl-C during a sensor fault's
            stance stop), every message in the order it happened, this error's among them;
            () otherwise.
    """

    exit_code = 1
    events: tuple[str, ...] = ()

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
    """A safety rule refused an action before anything moved: the hardware is not armed, or
    what was asked leaves the robot's reach where it stands (a task's path in pre-flight, a
    wall the drill cannot reach). A value beyond physical sense (a wall 5 m away) is an
    :class:`InputError` or :class:`ConfigError` instead, read before any reach is worked out."""

    exit_code = 4


class InterruptedRunError(HuboError):
    """Ctrl-C or SIGTERM ended a run and something failed during its stop (a full disk while
    a walk finished its step): the message says both; the exit is the interrupt's, which came
    first."""

    exit_code = EXIT_INTERRUPTED


def quoted(value: object) -> str:
    """``repr(value)`` for an error message, cut to :data:`QUOTED_CHARS` characters with what
    was left out said: ``[2, 2, 2, ...] (100,000 items)``, ``'xxxx...' (5,000,000
    characters)``. Every message that quotes what the user gave goes through here."""
    try:
        text = repr(value)
    except ValueError:  # an integer of more than 4300 digits (Python's limit for its text)
        return "an integer too long to print"
    if len(text) <= QUOTED_CHARS:
        return text
    try:
        size = f"{len(value):,} {'characters' if isinstance(value, str | bytes) else 'items'}"
    except TypeError:  # a number or an object without a length
        size = f"{len(text):,} characters"
    return f"{text[:QUOTED_CHARS]}... ({size})"


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP: the terminal gone; SIGQUIT: Ctrl-\\), raised where Ctrl-C raises
    KeyboardInterrupt: a run ends the same way (its smooth stop, its summary, exit 130).
    ``Terminated("SIGHUP")`` names the signal; without one it is SIGTERM."""

    @property
    def cause(self) -> str:
        """The signal's name (``SIGTERM``, ``SIGHUP``, ``SIGQUIT``)."""
        return str(self.args[0]) if self.args else "SIGTERM"


def interrupt_cause(exc: BaseException) -> str:
    """What interrupted a run: ``Ctrl-C`` or the signal's name (``SIGTERM``, ...)."""
    return exc.cause if isinstance(exc, Terminated) else "Ctrl-C"
