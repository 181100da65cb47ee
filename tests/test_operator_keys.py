"""The operator's keys in every robot command (issue 32, part 2): space stops, r releases, q
finishes; read from a terminal, and silently absent without one.

The terminal is a real pseudo-terminal (the command is its session's foreground job, as in a
shell). Waits are bounded by generous deadlines that only matter when something is broken; no
assertion depends on how fast the machine is.
"""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import select
import signal
import struct
import sys
import termios
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from task_files import raise_and_hold

from hubo_cli.cli.keys import keyboard_fd, operator_keys
from hubo_cli.cli.main import main
from hubo_cli.control.estop import RECOVER_S
from hubo_cli.control.log import load_log
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.operator import KEYS_HELP, OperatorKeys
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.drivers.registry import make_driver
from hubo_cli.posture import home_posture

DEADLINE_S = 120.0
ANSI = re.compile(rb"\x1b\[[0-9;?]*[A-Za-z]|\x1b\][^\x07]*\x07|\r")

# raise the drill, then hold it far longer than any test waits: a key must end it
LONG_TASK = raise_and_hold("long-hold", 60)


class Terminal:
    """A command run as the foreground job of a new pseudo-terminal (160 x 40)."""

    def __init__(self, args: list[str]) -> None:
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "TERM": "xterm-256color",
               "COLUMNS": "160", "LINES": "40"}
        self.pid, self.fd = pty.fork()
        if self.pid == 0:  # the child: a session leader with the terminal as its own
            os.execve(sys.executable, [sys.executable, "-m", "hubo_cli.cli.main", *args], env)
        fcntl.ioctl(self.fd, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
        self.output = b""
        self.status: int | None = None

    def read(self, timeout_s: float = 0.1) -> None:
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        if ready:
            try:
                self.output += os.read(self.fd, 65536)
            except OSError:  # the child closed the terminal
                time.sleep(timeout_s)

    def text(self) -> str:
        return ANSI.sub(b"", self.output).decode(errors="replace")

    def wait_for(self, words: str) -> bool:
        deadline = time.monotonic() + DEADLINE_S
        while words not in self.text() and time.monotonic() < deadline and self.poll() is None:
            self.read()
        self.read(0.2)
        return words in self.text()

    def press(self, key: str) -> None:
        os.write(self.fd, key.encode())

    def poll(self) -> int | None:
        if self.status is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.status = os.waitstatus_to_exitcode(status)
        return self.status

    def wait(self) -> int:
        deadline = time.monotonic() + DEADLINE_S
        while self.poll() is None and time.monotonic() < deadline:
            self.read()
        if self.poll() is None:
            os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            pytest.fail(f"the run did not end: {self.text()[-2000:]}")
        self.read(0.2)
        self.lflag = termios.tcgetattr(self.fd)[3]  # the terminal's modes as the run left them
        os.close(self.fd)
        return self.status


@pytest.fixture(scope="module")
def long_task(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("keys") / "long.toml"
    path.write_text(LONG_TASK)
    return path


def _summary(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


def test_space_during_a_task_latches_the_stop(long_task, tmp_path):
    run = tmp_path / "run"
    term = Terminal(["task", "run", str(long_task), "--driver", "ideal", "--out", str(run)])
    assert term.wait_for(f"keys: {KEYS_HELP}"), term.text()[-2000:]
    assert term.wait_for("running"), term.text()[-2000:]  # the view is up: the loop runs
    term.press(" ")
    # with an operator at the keyboard the stop holds (it does not end the run by itself)
    assert term.wait_for("press r to release (held)"), term.text()[-2000:]
    time.sleep(2.0)  # longer than a stop without an operator holds before the run ends
    assert term.poll() is None, term.text()[-2000:]
    term.press("q")
    status = term.wait()
    text = term.text()
    assert status == 1, text  # the task did not complete: stopped, then finished by q
    assert "did not complete (emergency stop)" in text and "e-stop      operator at" in text
    assert "Traceback" not in text and "internal error" not in text
    summary = _summary(run)
    assert summary["estop"]["sources"] == ["operator"] and summary["estop"]["held"]
    assert summary["estop"]["resumed_at_t_s"] == []
    assert [e["kind"] for e in summary["estop_events"]] == ["stop"]
    assert summary["ended"] == "done" and summary["finished_by_operator"]
    assert term.lflag & termios.ICANON and term.lflag & termios.ECHO  # given back cooked


def test_r_after_a_stop_resumes_the_task_where_it_froze(long_task, tmp_path):
    """space stops a task, r releases it: the stopper blends back to the frozen plan and the
    plan goes on from there to its end (completed, exit 0)."""
    task = tmp_path / "short.toml"
    task.write_text(LONG_TASK.replace("duration_s = 60", "duration_s = 30"))
    run = tmp_path / "run"
    term = Terminal(["task", "run", str(task), "--driver", "ideal", "--out", str(run)])
    assert term.wait_for("running"), term.text()[-2000:]
    term.press(" ")
    assert term.wait_for("press r to release (held)"), term.text()[-2000:]
    term.press("r")
    status = term.wait()
    text = term.text()
    assert status == 0, text
    summary = _summary(run)
    assert summary["completed"] and not summary["finished_by_operator"]
    assert [e["kind"] for e in summary["estop_events"]] == ["stop", "release"]
    (resumed,) = summary["estop"]["resumed_at_t_s"]
    release_t_s = summary["estop_events"][1]["t_s"]
    # after the blend back: no sooner than RECOVER_S, at most a few periods later
    assert release_t_s + RECOVER_S - 0.01 < resumed < release_t_s + RECOVER_S + 0.5
    assert all(step["done"] for step in summary["steps"])
    # the whole plan was played, paused from the stop to the resume: at least its 31 s plus
    # the pause (a resume that skipped the rest of the plan ends sooner)
    stop_t_s = summary["estop_events"][0]["t_s"]
    assert summary["duration_s"] >= 31.0 + (resumed - stop_t_s) - 0.1


def test_q_during_a_task_ends_it_cleanly(long_task, tmp_path):
    run = tmp_path / "run"
    term = Terminal(["task", "run", str(long_task), "--driver", "ideal", "--out", str(run)])
    assert term.wait_for("running"), term.text()[-2000:]
    term.press("q")
    status = term.wait()
    text = term.text()
    assert status == 1, text  # ended by the operator before the task completed
    assert "did not complete (finished by the operator: q)" in text
    assert "Traceback" not in text and "internal error" not in text
    summary = _summary(run)
    assert summary["finished_by_operator"] and summary["ended"] == "done"
    assert summary["estop"] is None and summary["duration_s"] < 55  # before the end
    log = load_log(run)
    # the run ended at rest: the last command is still, and everything is in the folder
    q = log.joints("cmd")
    assert np.max(np.abs(q[-1] - q[-2])) < 1e-6
    assert {"log.csv", "summary.json", "task.toml"} <= set(summary["files"])


def test_sim_names_its_keys_and_q_ends_it(tmp_path):
    """``hubo sim`` (and ``hubo walk``: the same helper) has no live view: one line names the
    keys."""
    run = tmp_path / "sim"
    term = Terminal(["sim", "--duration", "60", "--out", str(run)])
    assert term.wait_for(f"keys: {KEYS_HELP}"), term.text()[-2000:]
    term.press("q")
    assert term.wait() == 0, term.text()
    summary = _summary(run)
    assert summary["finished_by_operator"] and summary["periods"] * 0.005 < 60


def test_no_terminal_no_keys(long_task, tmp_path):
    """CliRunner's stdin is no terminal: no keys, no key line, the terminal untouched."""
    assert keyboard_fd() is None
    with operator_keys() as keys:
        assert keys is None
    task = tmp_path / "short.toml"
    task.write_text(LONG_TASK.replace("duration_s = 60", "duration_s = 0.2"))
    result = CliRunner().invoke(main, ["task", "run", str(task), "--driver", "ideal",
                                       "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert "keys:" not in result.output


def test_the_loop_takes_the_keys_each_period(model):
    """space -> an operator stop in that period; r -> released; q -> the run ends (done)."""
    keys = OperatorKeys()
    assert not keys.press("x") and keys.take() == {}
    driver = make_driver("ideal", model)
    modules = SafetyProfile(balance=False).build(model, driver.period_s, {})
    pressed = {10: " ", 400: "r", 800: "q"}

    def target(t_s, state):
        k = int(round(t_s / driver.period_s))
        if k in pressed:
            keys.press(pressed[k])
        return home_posture(model), {}

    with driver:
        driver.start(home_posture(model))
        result = ControlLoop(driver, modules, target, operator=keys).run(10.0)
    events = [(m, round(t / driver.period_s), kind, sources)
              for m, t, kind, sources in result.safety_events]
    assert events[0][0] == "estop" and events[0][2:] == ("stop", ("operator",))
    assert 10 <= events[0][1] <= 11  # the period the key was pressed in, or the next
    assert events[1][2] == "release"
    assert result.ended == "done" and result.periods < 1000 and keys.finished
