"""Interrupts after a run's control loop has ended: held back until the run's files are whole.

Once the robot has stopped, the run's summary, plots and (on the command line) its text summary
are quick to finish, and an interrupt in the middle would leave them half written: a first-draft
``summary.json`` contradicting the exit code. So a run is wrapped in :func:`run_files`, and the
control loop calls :func:`loop_ended` once it has stopped the robot; from then until the
*outermost* :func:`run_files` exits (or the next run starts, :func:`loop_starting`), Ctrl-C and
SIGTERM (SIGHUP, SIGQUIT) are recorded, not raised. Scopes nest (the command line, the task
runner and the run scaffold each open one); only the outermost one acts on a recorded
interrupt:

- ``deliver=True`` (the library's default): it raises the interrupt (``KeyboardInterrupt``, or
  :class:`~hubo_cli.errors.Terminated` for SIGTERM) once the files are complete.
- ``deliver=False`` (the command line): it does not raise; the run finishes normally, exits with
  its own code, and the caller reads :attr:`LateInterrupt.cause` to say on stderr that the signal
  came after the run ended. The files, stdout and the exit code then all describe the run as it
  happened: the robot had already stopped, so the signal changed nothing.

Only the main thread can handle signals; elsewhere the scopes do nothing.

An interrupt is also *noted* (:func:`interrupt_pending`), not only raised: the command line
(:func:`catching_interrupts`) and the control loop (:func:`loop_taking`) install a handler that
records the cause before it raises. A ``KeyboardInterrupt`` raised where Python cannot pass it on
(inside a ctypes callback: numba's first compile of a cold cache prints "Exception ignored ...")
is lost, but the note stays: the control loop looks at it before the robot's first command and
every period, and ends the run as interrupted. Within :func:`catching_interrupts` Python's
"Exception ignored" traceback for such a noted interrupt is not printed (``sys.unraisablehook``;
any other exception a callback loses still is). Inside the loop the first interrupt is only noted
(the loop acts on it at its next period, from a whole period: a walk finishes its step, see
:mod:`hubo_cli.control.loop`); a second Ctrl-C raises at once (the operator insists: the brake
where the robot is), while a second signal of another kind is only noted
(:func:`loop_given_back` returns it) and the stop under way goes on within its bound: a
SIGTERM from ``timeout`` or systemd, or a SIGHUP from the dropped terminal, after the
operator's Ctrl-C is nobody insisting, and braking mid-step leaves a foot in the air.

The interrupts are Ctrl-C (SIGINT) and the signals whose default would end the process
mid-motion: SIGTERM, SIGHUP (the ssh session dropped, the terminal closed) and SIGQUIT
(Ctrl-\\), each taken only where Python's default is in place (``nohup``'s ignored SIGHUP
stays ignored). While a control loop runs, SIGTSTP (Ctrl-Z, which would freeze the loop
mid-step while the robot holds its last reference) is refused: ignored, and said through the
``say`` given to :func:`catching_interrupts` (the command line's stderr).
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from hubo_cli.errors import Terminated

# Ctrl-C first; the others end the process by default (absent on Windows: skipped)
_BY_NAME = {s.name: s for s in signal.Signals}
INTERRUPT_SIGNALS = tuple(_BY_NAME[name] for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
                          if name in _BY_NAME)
_SIGTSTP = _BY_NAME.get("SIGTSTP")
REFUSED_STOP = ("Ctrl-Z ignored: the control loop must not freeze while the robot moves; "
                "Ctrl-C stops the run")


@dataclass
class LateInterrupt:
    """What the outermost scope learnt: ``cause`` is ``Ctrl-C``, the signal's name
    (``SIGTERM``, ``SIGHUP``, ``SIGQUIT``) or None."""

    cause: str | None = None


@dataclass
class _State:
    depth: int = 0
    late: LateInterrupt | None = None  # the outermost scope's
    previous: dict | None = None  # the handlers in place before loop_ended(), while deferring


_state = _State()


@dataclass
class _Noted:
    pending: str | None = None  # an interrupt no control loop has acted on yet
    deferring: bool = False  # a loop takes the first interrupt itself: note it, do not raise
    looping: bool = False  # a loop runs: after the first, only Ctrl-C raises
    meanwhile: list[str] = field(default_factory=list)  # later signals only noted
    say: Callable[[str], None] | None = None  # where a refused Ctrl-Z is said


_noted = _Noted()


def _cause(signum: int) -> str:
    return "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name


def _raise(cause: str) -> None:
    raise KeyboardInterrupt if cause == "Ctrl-C" else Terminated(cause)


def _interrupt(signum, frame) -> None:
    """Note the interrupt; raise it unless a control loop takes the first one itself, or
    (after the first) it is not Ctrl-C while a loop runs: only noted then."""
    cause = _cause(signum)
    if _noted.deferring and _noted.pending is None:
        _noted.pending = cause
        return
    if _noted.looping and signum != signal.SIGINT:
        _noted.meanwhile.append(cause)
        return
    _noted.pending = cause
    _raise(cause)


def _refuse_stop(signum, frame) -> None:
    """Ctrl-Z while a loop runs: ignored, and said where the command line asked."""
    if _noted.say is not None:
        _noted.say(REFUSED_STOP)


def interrupt_pending() -> str | None:
    """The cause (``Ctrl-C``, ``SIGTERM``, ``SIGHUP``, ``SIGQUIT``) of an interrupt no control
    loop has acted on yet (one only noted, or one raised but swallowed), or None; always None
    off the main thread (a loop there is not the one the signal was for)."""
    return _noted.pending if _in_main_thread() else None


def take_interrupt() -> str | None:
    """The loop acts on the pending interrupt (returned, then cleared); every further one
    raises at once."""
    cause, _noted.pending, _noted.deferring = _noted.pending, None, False
    return cause


def _taken(sigterm: bool) -> dict:
    """The signals whose handler is still Python's default (Ctrl-C's; SIGTERM's, SIGHUP's and
    SIGQUIT's, ending the process, if ``sigterm``), each to :func:`_interrupt`."""
    wanted = {}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        wanted[signal.SIGINT] = _interrupt
    for s in INTERRUPT_SIGNALS[1:] if sigterm else ():
        if signal.getsignal(s) is signal.SIG_DFL:
            wanted[s] = _interrupt
    return wanted


def _install(handlers: dict) -> dict:
    return {s: signal.signal(s, h) for s, h in handlers.items()}


@contextmanager
def catching_interrupts(say: Callable[[str], None] | None = None) -> Iterator[None]:
    """The command line's scope: Ctrl-C (where Python's default handler is in place) and
    SIGTERM, SIGHUP, SIGQUIT (where the default, ending the process, is) raise
    ``KeyboardInterrupt`` / :class:`~hubo_cli.errors.Terminated` and are noted (see the
    module's docstring); ``say`` is given a refused Ctrl-Z's line (it runs in a signal
    handler: it must not take a lock the interrupted code may hold)."""
    if not _in_main_thread():
        yield
        return
    _noted.say = say
    previous = _install(_taken(sigterm=True))
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _quiet_noted_interrupt(previous_hook)
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        for s, handler in previous.items():
            if signal.getsignal(s) is _interrupt:
                signal.signal(s, handler)
        _noted.pending, _noted.deferring, _noted.say = None, False, None


def _quiet_noted_interrupt(previous_hook):
    """``sys.unraisablehook`` that says nothing of an interrupt a ctypes callback swallowed
    once it is noted (the control loop acts on the note), and passes anything else on."""
    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _noted.pending is not None:
            return
        previous_hook(unraisable)
    return hook


def loop_taking() -> dict:
    """A control loop starts: the first interrupt from now is noted, not raised (Ctrl-C's
    handler installed where Python's default is; SIGTERM's only where
    :func:`catching_interrupts` put it). Returns what :func:`loop_given_back` restores."""
    if not _in_main_thread():  # (signals reach the main thread only: nothing to take here)
        return {}
    _noted.deferring, _noted.looping, _noted.meanwhile = True, True, []
    taken = _taken(sigterm=False)
    if _SIGTSTP is not None and signal.getsignal(_SIGTSTP) is signal.SIG_DFL:
        taken[_SIGTSTP] = _refuse_stop
    return _install(taken)


def loop_given_back(previous: dict) -> tuple[str, ...]:
    """The control loop has stopped the robot: interrupts raise again (the handlers
    :func:`loop_taking` replaced are back) and one still pending is dropped (the loop
    acted on it). Returns the signals only noted meanwhile (after the first, not Ctrl-C),
    each once, in order."""
    if not _in_main_thread():
        return ()
    meanwhile = tuple(dict.fromkeys(_noted.meanwhile))
    _noted.pending, _noted.deferring, _noted.looping, _noted.meanwhile = None, False, False, []
    for s, handler in previous.items():
        if signal.getsignal(s) in (_interrupt, _refuse_stop):
            signal.signal(s, handler)
    return meanwhile


def _record(signum, frame) -> None:
    if _state.late is not None and _state.late.cause is None:
        _state.late.cause = _cause(signum)


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def loop_starting() -> None:
    """A new run is about to start (a command may run several): interrupts are raised again,
    and one held back since the previous run's loop ended is raised now, before anything moves."""
    previous, _state.previous = _state.previous, None
    for s, handler in (previous or {}).items():
        signal.signal(s, handler)
    late = _state.late
    if late is not None and late.cause is not None:
        cause, late.cause = late.cause, None
        _raise(cause)


def loop_ended() -> None:
    """The run's loop has ended: hold back interrupts until the outermost scope exits (a no-op
    outside :func:`run_files`, off the main thread, or when already holding back)."""
    if _state.depth == 0 or _state.previous is not None or not _in_main_thread():
        return
    _state.previous = {s: signal.signal(s, _record) for s in INTERRUPT_SIGNALS
                       if signal.getsignal(s) is not signal.SIG_IGN}  # (nohup's SIGHUP)


@contextmanager
def run_files(deliver: bool = True) -> Iterator[LateInterrupt]:
    """A scope inside which, after :func:`loop_ended`, interrupts wait for the scope's end
    (see the module's docstring for ``deliver``); yields the outermost scope's record."""
    outermost = _state.depth == 0
    if outermost:
        _state.late = LateInterrupt()
    late = _state.late
    _state.depth += 1
    try:
        yield late
    finally:
        _state.depth -= 1
        if outermost:
            previous, _state.previous, _state.late = _state.previous, None, None
            for s, handler in (previous or {}).items():
                signal.signal(s, handler)
    if outermost and deliver and late.cause is not None:
        _raise(late.cause)


@contextmanager
def stopping() -> Iterator[None]:
    """A shutdown already under way after an interrupt (a sweep ending its workers and its
    cluster): a second Ctrl-C or SIGTERM (SIGHUP, SIGQUIT) inside is recorded and dropped, not
    raised, so it cannot cut the shutdown short and leave worker processes the interpreter's
    exit then waits on for ever (main thread only; elsewhere nothing changes)."""
    if not _in_main_thread():
        yield
        return
    previous = {s: signal.signal(s, lambda signum, frame: None) for s in INTERRUPT_SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
