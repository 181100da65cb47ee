"""Which stop sources a run keeps: decided in one place, weakened only on the command line.

The soft emergency stopper (:mod:`hubo_cli.control.estop`) acts on the sources it is given,
some of :data:`SOFT_SOURCES`. Every
command starts from its baseline: a task's is :data:`TASK_SOURCES` (its file may add
``stale-input``), the other robot commands' every soft source. A task file and ``--set`` may
only tighten that (more sources, a lower wrist-torque limit than the robot file's; the task
loader refuses anything else, exit 2). Only an explicit command-line option removes a source:
``--no-estop`` (all of them) or ``--estop-sources LIST``. On the hardware driver that is
refused (exit 4) unless :data:`CONFIRM_OPTION` confirms it as well. A walk keeps the
operator's stop whatever is chosen (:func:`check_walk_stops`).
"""

from __future__ import annotations

from dataclasses import dataclass

from hubo_cli.errors import InputError, SafetyError, quoted

SOFT_SOURCES = ("operator", "capture-point", "wrist-torque", "stale-input")
TASK_SOURCES = ("operator", "capture-point", "wrist-torque")  # a scripted task has no input
CONFIRM_OPTION = "--accept-reduced-safety"
STOP_SOURCE = "operator"  # the stop Ctrl-C, SIGTERM and a full disk ask of the stopper
NONE_WORD = "none"


def parse_sources(text: str) -> tuple[str, ...]:
    """``--estop-sources``: a comma-separated list of soft sources, or ``none`` (no soft
    stopper); returned in :data:`SOFT_SOURCES`' order."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == [NONE_WORD]:
        return ()
    unknown = [n for n in names if n not in SOFT_SOURCES]
    if unknown or not names:
        what = f"unknown stop source {quoted(unknown[0])}" if unknown else "no stop source given"
        raise InputError(f"--estop-sources: {what}",
                         hint=f"a comma-separated list of {', '.join(SOFT_SOURCES)}, or "
                              f"{NONE_WORD}")
    return tuple(s for s in SOFT_SOURCES if s in names)


def stops_words(sources) -> str:
    """``operator stop``, ``operator and wrist-torque stops``: sources in words."""
    sources = list(sources)
    names = ", ".join(sources[:-1]) + (" and " if len(sources) > 1 else "") + sources[-1]
    return f"{names} stop{'s' if len(sources) > 1 else ''}"


@dataclass(frozen=True)
class StopChoice:
    """What the command line says about the soft stop sources.

    Attributes:
        no_estop: ``--no-estop``: no soft emergency stopper.
        sources: ``--estop-sources``: exactly these sources (None: not given).
        accept_reduced: :data:`CONFIRM_OPTION`: a reduced set is meant, also on the hardware.
    """

    no_estop: bool = False
    sources: tuple[str, ...] | None = None
    accept_reduced: bool = False

    @classmethod
    def from_options(cls, no_estop: bool, estop_sources: str | None,
                     accept_reduced: bool) -> StopChoice:
        if no_estop and estop_sources is not None:
            raise InputError("--no-estop and --estop-sources both choose the stop sources",
                             hint="give one of them")
        return cls(no_estop, None if estop_sources is None else parse_sources(estop_sources),
                   accept_reduced)

    @property
    def option(self) -> str:
        """The option as given (for messages), "" when neither was."""
        if self.no_estop:
            return "--no-estop"
        if self.sources is not None:
            return f"--estop-sources {','.join(self.sources) or NONE_WORD}"
        return ""


@dataclass(frozen=True)
class ActiveStops:
    """The stop sources a run keeps.

    Attributes:
        sources: what the soft stopper acts on (empty: no soft stopper in the pipeline).
        removed: requested sources the command line removed.
        by: the option that removed them ("" when nothing was removed).
    """

    sources: tuple[str, ...]
    removed: tuple[str, ...] = ()
    by: str = ""

    def words(self) -> str:
        """One line for the start of a run."""
        active = ", ".join(self.sources) or "none (no soft emergency stop)"
        line = f"e-stop sources: {active}"
        if self.removed:
            line += f"; REMOVED by {self.by}: {', '.join(self.removed)}"
        return line


def decide_stops(requested: tuple[str, ...], choice: StopChoice, driver: str) -> ActiveStops:
    """The sources a run keeps: ``requested`` (the baseline, tightened by a task file) unless
    the command line chose otherwise.

    Raises:
        SafetyError: the command line removes a source on the hardware driver without
            :data:`CONFIRM_OPTION` (exit 4, nothing moved).
    """
    if choice.no_estop:
        active: tuple[str, ...] = ()
    elif choice.sources is not None:
        active = choice.sources
    else:
        active = tuple(requested)
    removed = tuple(s for s in requested if s not in active)
    if removed and driver == "hardware" and not choice.accept_reduced:
        raise SafetyError(f"{choice.option} removes the {stops_words(removed)} on the real "
                          "robot: refused, nothing moved",
                          hint=f"add {CONFIRM_OPTION} to confirm the reduced safety, or leave "
                               f"out {choice.option.split()[0]}")
    return ActiveStops(active, removed, choice.option if removed else "")


def check_walk_stops(stops: ActiveStops, what: str) -> None:
    """Refuse a walk (``what``: the command's words) whose stopper does not take the operator's
    stop: Ctrl-C, SIGTERM and a full disk finish the step into a stance through it (the
    control loop asks the stopper for :data:`STOP_SOURCE`); without it they brake the joints
    where they are, a foot in the air. ``--estop-sources operator`` keeps only that stop.

    Raises:
        SafetyError: the operator's stop is removed (exit 4, nothing moved).
    """
    if STOP_SOURCE not in stops.sources:
        raise SafetyError(f"{what} needs the {STOP_SOURCE} stop, which {stops.by or 'the task'}"
                          " removes: without it Ctrl-C brakes the joints where they are, a "
                          "foot in the air; refused, nothing moved",
                          hint=f"keep it: --estop-sources {','.join((STOP_SOURCE, *stops.sources))}"
                               f", or leave out {(stops.by or '--no-estop').split()[0]}")
