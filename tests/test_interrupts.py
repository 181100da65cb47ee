"""Interrupts after a run's loop ended wait for the outermost scope (hubo_cli/interrupts.py)."""

from __future__ import annotations

import os
import signal
import sys
import time

import pytest

from hubo_cli import interrupts
from hubo_cli.errors import Terminated, interrupt_cause
from hubo_cli.interrupts import (
    catching_interrupts,
    loop_ended,
    loop_given_back,
    loop_starting,
    loop_taking,
    run_files,
    take_interrupt,
)

posix_only = pytest.mark.skipif(sys.platform == "win32", reason="SIGHUP, SIGQUIT, SIGTSTP")


def test_a_late_sigterm_waits_for_the_outermost_scope_then_is_raised():
    steps = []
    with pytest.raises(Terminated):
        with run_files():  # the task runner's
            with run_files():  # the run scaffold's
                loop_ended()
                os.kill(os.getpid(), signal.SIGTERM)
                steps.append("summary")
            os.kill(os.getpid(), signal.SIGINT)  # a second signal changes nothing
            steps.append("plots")
    assert steps == ["summary", "plots"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_the_command_line_scope_reports_instead_and_a_next_run_raises_it():
    with run_files(deliver=False) as late:
        with run_files():
            loop_ended()
            os.kill(os.getpid(), signal.SIGINT)
        assert late.cause == "Ctrl-C"
    assert late.cause == "Ctrl-C"
    with pytest.raises(KeyboardInterrupt), run_files(deliver=False):  # a sweep's next run
        with run_files():
            loop_ended()
            os.kill(os.getpid(), signal.SIGINT)
        loop_starting()  # raised before anything moves
    with run_files():  # before the loop ends, interrupts are raised at once
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)


def test_a_shutdown_under_way_drops_a_second_interrupt_and_restores_the_handlers():
    """Inside `stopping()` (a sweep ending its workers after a Ctrl-C) a second SIGINT or
    SIGTERM is dropped, not raised; after it the handlers are the ones before (round 12's
    review: a second Ctrl-C cut the cluster's shutdown short and the exit waited for ever on
    a worker left alive)."""
    from hubo_cli.interrupts import stopping

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    with stopping():
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)  # (delivered to the main thread at its next bytecode)
    assert {s: signal.getsignal(s) for s in before} == before


@pytest.fixture
def default_actions():
    """SIGTERM, SIGHUP, SIGQUIT and SIGTSTP at their default actions (as in a shell), restored
    after."""
    signals = [getattr(signal, n) for n in ("SIGTERM", "SIGHUP", "SIGQUIT", "SIGTSTP")
               if hasattr(signal, n)]
    before = {s: signal.signal(s, signal.SIG_DFL) for s in signals}
    yield
    for s, handler in before.items():
        signal.signal(s, handler)


def _send(signum: int) -> None:
    os.kill(os.getpid(), signum)
    time.sleep(0.02)  # (delivered to the main thread at its next bytecode)


@posix_only
@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP", "SIGQUIT"])
def test_the_signals_that_would_end_the_process_are_named_interrupts(default_actions, name):
    """SIGHUP (the ssh session dropped, the terminal closed) and SIGQUIT (Ctrl-\\) end a run
    as SIGTERM does: raised as Terminated naming the signal (round 16; main left their default
    actions: the process died mid-walk with a foot in the air, no stop, no summary)."""
    signum = getattr(signal, name)
    with catching_interrupts():
        assert signal.getsignal(signum) is interrupts._interrupt  # (main: SIG_DFL, not sent)
        with pytest.raises(Terminated) as raised:
            _send(signum)
    assert interrupt_cause(raised.value) == name
    assert signal.getsignal(signum) is signal.SIG_DFL  # given back


@posix_only
def test_an_ignored_hangup_stays_ignored(default_actions):
    """``nohup hubo ...``: SIGHUP ignored before the command stays ignored."""
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    with catching_interrupts(), run_files():
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        loop_ended()
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN


@posix_only
def test_in_a_loop_only_a_second_ctrl_c_raises_other_signals_are_noted(default_actions):
    """While a control loop runs, the first interrupt of any kind is noted (the loop stops
    from a whole period: a walk finishes its step); after it only Ctrl-C, the operator
    insisting, raises (the brake where the robot is); SIGTERM from ``timeout`` or systemd, a
    SIGHUP or SIGQUIT are noted and given back when the loop ends (its stop goes on)."""
    with catching_interrupts():
        handlers = loop_taking()
        try:
            assert signal.getsignal(signal.SIGHUP) is interrupts._interrupt  # (main: SIG_DFL)
            _send(signal.SIGHUP)
            assert interrupts.interrupt_pending() == "SIGHUP"
            _send(signal.SIGTERM)  # before the loop took the first: noted as well
            assert take_interrupt() == "SIGHUP"
            _send(signal.SIGQUIT)
            _send(signal.SIGTERM)
            with pytest.raises(KeyboardInterrupt):
                _send(signal.SIGINT)
        finally:
            meanwhile = loop_given_back(handlers)
        assert meanwhile == ("SIGTERM", "SIGQUIT")
        with pytest.raises(Terminated):  # no loop: raised at once again
            _send(signal.SIGTERM)


@posix_only
def test_ctrl_z_is_refused_while_a_loop_runs(default_actions):
    """SIGTSTP (Ctrl-Z) would freeze the loop mid-step (the hardware daemon holding the last
    reference, a foot in the air): while a loop runs it is ignored and the command line is
    given one line saying so; outside the loop its default is back."""
    said = []
    with catching_interrupts(say=said.append):
        handlers = loop_taking()
        try:
            assert signal.getsignal(signal.SIGTSTP) is not signal.SIG_DFL  # (main: it is)
            _send(signal.SIGTSTP)
        finally:
            loop_given_back(handlers)
        assert signal.getsignal(signal.SIGTSTP) is signal.SIG_DFL
    assert said == [interrupts.REFUSED_STOP]


@pytest.mark.parametrize("argv", [["sim", "--json", "--duration", "1"],
                                  ["task", "cut-rectangle", "--json"]])
def test_an_interrupt_while_the_command_loads_still_gives_the_json_document(monkeypatch, argv):
    """Review 21: SIGTERM 3.1 s and 7.1 s into `hubo sim --duration 3 --json` on a loaded
    machine (the command's module still importing, its --json not yet parsed) ended exit 130
    with "interrupted (SIGTERM)" on stderr and nothing on stdout; a script reading the one
    JSON document got none."""
    import importlib
    import json

    from click.testing import CliRunner

    from hubo_cli.cli import main as cli_main

    real = importlib.import_module

    def interrupted(name, *args, **kwargs):
        if name.startswith("hubo_cli.cli.") and name != "hubo_cli.cli.output":
            raise Terminated("SIGTERM")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(cli_main.importlib, "import_module", interrupted)
    result = CliRunner().invoke(cli_main.main, argv)
    assert result.exit_code == 130
    assert json.loads(result.stdout) == {"error": "interrupted (SIGTERM)", "hint": "",
                                         "exit_code": 130}
