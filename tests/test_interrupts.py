"""Interrupts after a run's loop ended wait for the outermost scope (hubo_cli/interrupts.py)."""

from __future__ import annotations

import os
import signal
import time

import pytest

from hubo_cli.errors import Terminated
from hubo_cli.interrupts import loop_ended, loop_starting, run_files


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
