"""The operator always sees the safety state: the live view rendered in-process, the real
terminal (tmux) after pressing space, plain lines on a dumb and narrow terminal, the loop's
overruns as they happen, and stale input judged from the input's own timestamps."""

import io
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from control_support import ideal
from pty_support import HUBO, run_in_pty
from rich.console import Console
from test_control_loop import DT, FakeClock

from hubo_cli.cli.live_view import (
    MIN_COLUMNS,
    MIN_LINES,
    TERMINAL_EVERY_S,
    URGENT_GAP_S,
    rich_view_fits,
)
from hubo_cli.cli.output import ProgressLines
from hubo_cli.cli.safety_view import HandSafety, SafetyPanel, SafetyState, read_safety, safety_text
from hubo_cli.cli.teleop import KEYS_HELP, _view, hand_safety
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.fastrak.opener import open_source
from hubo_cli.resources import data_file
from hubo_cli.teleop.session import TeleopSettings, run_teleop

FREE_CSV = data_file("trajectories", "two-hand-free.csv")
DEADLINE_S = 60.0
SCREEN_COPY = os.environ.get("HUBO_SCREEN_COPY")  # keep the captured pane (for the README)


def _text(renderable) -> str:
    console = Console(width=160, record=True, force_terminal=False, color_system=None)
    console.print(renderable)
    return console.export_text()


def _wait(condition) -> bool:
    deadline = time.monotonic() + DEADLINE_S
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.005)
    return condition()


def test_every_stopper_mode_has_words_and_a_stopped_one_says_so():
    from hubo_cli.cli.safety_view import ESTOP_WORDS, STOPPED_HOW
    from hubo_cli.control.estop import MODES
    assert set(ESTOP_WORDS) == set(MODES) - {"release"}
    for mode in ("stop", "finish", "hold"):
        state = SafetyState(estop=ESTOP_WORDS[mode], estop_sources=("operator",), stops=1)
        text = safety_text(state).plain
        assert f"E-STOP (operator) — press r to release ({STOPPED_HOW[ESTOP_WORDS[mode]]})" \
            in text, text


def test_safety_text_in_words():
    state = SafetyState(estop="held", estop_sources=("operator",), stops=1, collision="holding",
                        collision_pair=("REB_link_0", "torso_0"), collision_distance_m=0.004,
                        hands=[HandSafety("right-arm", needs_clutch=True),
                               HandSafety("left-arm", stale=True, ik_status="capped")])
    text = safety_text(state).plain
    assert "E-STOP (operator) — press r to release (held)" in text
    assert "COLLISION HOLD: REB_link / torso at +4 mm" in text
    assert "right-arm: INPUT BACK — press c to re-centre" in text
    assert "left-arm: STALE INPUT — holding, at its reach limit (capped)" in text
    assert "stops 1" in text


def test_live_view_shows_the_operator_stop_and_counts_it_once(tmp_path):
    """Space, then r, on a replay: the view says E-STOP (operator) and how to release it; the
    bell rings once; one stop and one release count as one stop."""
    captured: dict = {}
    bells: list[float] = []

    def operator(target, loop, panel):
        def stopper_mode():  # what the loop's record says, as the view reads it
            return loop.module_status["estop"].mode

        if not _wait(lambda: target.phase == "operate"):
            return
        target.keys.estop = True
        if _wait(lambda: stopper_mode() == "hold"):
            captured["held"] = _text(_view(target, panel))
        target.keys.release = True
        if _wait(lambda: stopper_mode() == "recover"):
            captured["released"] = _text(_view(target, panel))
        target.keys.quit = True

    def on_ready(target, loop):
        loop.watch_status()
        panel = SafetyPanel(lambda: read_safety(loop, hand_safety(target)),
                            bell=lambda: bells.append(time.monotonic()))
        captured["first"] = _text(_view(target, panel))
        threading.Thread(target=operator, args=(target, loop, panel), daemon=True).start()

    run = run_teleop(TeleopSettings(replay=FREE_CSV, driver="ideal", speed=1.0,
                                    out=tmp_path / "run"), on_ready=on_ready)
    assert "e-stop ready" in captured["first"]
    held = captured["held"]
    assert "E-STOP (operator) — press r to release (held)" in held, held
    assert "collision" in held and "right-arm" in held and "left-arm" in held
    assert "e-stop (operator) released — blending back" in captured["released"]
    assert len(bells) == 1
    kinds = [e["kind"] for e in run.summary["estop_events"]]
    assert kinds == ["stop", "release"]
    assert read_safety().stops == 0


def test_the_view_reads_the_loops_record_not_the_modules(model):
    """The safety view reads what the loop recorded of the pipeline: the record taken when the
    loop is built (the stopper ready), refreshed every period once a viewer watches (the
    operator's stop seen in the period after it latched), and the last one in the result."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    seen: dict[int, str] = {}
    loop_ref: list[ControlLoop] = []

    def target(t_s, state):
        k = round(t_s / DT)
        if k in (5, 21, 60):
            seen[k] = read_safety(loop_ref[0]).estop
        info = {"done": k >= 80}
        if k == 20:
            info["estop"] = "operator"
        if k == 40:
            info["release"] = True
        return q0, info

    loop = ControlLoop(robot, build_pipeline(model), target)
    loop_ref.append(loop)
    before = read_safety(loop)
    assert before.soft_estop and before.estop == "off" and before.stops == 0
    assert "operator" in before.active_sources and before.balance.balancer
    loop.watch_status()
    result = loop.run()
    assert seen == {5: "off", 21: "stopping", 60: "releasing"}, seen
    assert result.module_status["estop"].stops == 1
    assert result.module_status["estop"].last_stop_sources == ("operator",)
    assert result.module_status["otg"] is None  # a module with nothing to show


@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")
def test_terminal_shows_estop_after_space(tmp_path):
    """The real terminal: hubo teleop in tmux, space pressed, the pane captured."""
    session = f"hubo-test-{time.monotonic_ns()}"
    hubo = Path(sys.executable).with_name("hubo")
    command = (f"{hubo} teleop --replay {FREE_CSV} --driver ideal --speed 1 "
               f"--out {tmp_path / 'run'}; sleep 30")
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "160", "-y", "30",
                    command], check=True)

    def pane() -> str:
        return subprocess.run(["tmux", "capture-pane", "-p", "-t", session],
                              capture_output=True, text=True).stdout

    try:
        assert _wait(lambda: "hubo teleop — operate" in pane()), pane()
        subprocess.run(["tmux", "send-keys", "-t", session, "Space"], check=True)
        assert _wait(lambda: "E-STOP (operator)" in pane() and "held" in pane()), pane()
        screen = pane()
        assert "E-STOP (operator) — press r to release (held)" in screen
        assert "hubo teleop — E-STOPPED" in screen
        if SCREEN_COPY:
            Path(SCREEN_COPY).write_text(screen)
        subprocess.run(["tmux", "send-keys", "-t", session, "r"], check=True)
        assert _wait(lambda: "released" in pane()), pane()
        subprocess.run(["tmux", "send-keys", "-t", session, "q"], check=True)
        assert _wait(lambda: "e-stops 1 (released 1)" in pane()), pane()
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)


def test_the_loop_falling_behind_shows_as_it_happens(model):
    """A real control loop on a clock that stalls twice: the view says so from the next period
    on, with the overruns and the wall time skipped so far."""
    clock = FakeClock()
    seen: dict[int, str] = {}
    loop_ref: list[ControlLoop] = []

    def target(t_s, state):
        k = round(t_s / DT)
        if k in (40, 60, 150):
            seen[k] = SafetyPanel(lambda: read_safety(loop_ref[0])).words()
        if k in (50, 120):
            clock.now_s += {50: 1.0, 120: 0.5}[k]  # a stall far beyond the loop's lag limit
        return None, {}

    loop = ControlLoop(ideal(model), [], target, speed=1.0, clock=clock, sleep=clock.sleep)
    loop_ref.append(loop)
    loop.run(duration_s=200 * DT)
    assert "LOOP LATE" not in seen[40]
    assert "LOOP LATE: 1 overrun, 1.0 s of wall time skipped" in seen[60], seen[60]
    assert "LOOP LATE: 2 overruns, 1.5 s of wall time skipped" in seen[150], seen[150]


def test_only_a_terminal_that_redraws_and_is_wide_enough_gets_the_rich_view():
    def console(width, term, height=40):
        return Console(file=io.StringIO(), force_terminal=True, width=width, height=height,
                       _environ={"TERM": term})

    assert rich_view_fits(console(80, "xterm-256color"))
    assert not rich_view_fits(console(MIN_COLUMNS - 1, "xterm-256color"))
    assert not rich_view_fits(console(80, "xterm-256color", height=MIN_LINES - 1))
    assert not rich_view_fits(console(200, "dumb"))
    assert not rich_view_fits(Console(file=io.StringIO(), width=200))  # not a terminal


def test_plain_lines_come_at_most_twice_a_second(capsys):
    """Even when the safety state changes at every look, plain lines are rate-limited."""
    calls = iter(range(10**6))
    lines = ProgressLines(lambda: "line", every_s=TERMINAL_EVERY_S,
                          urgent=lambda: next(calls), gap_s=URGENT_GAP_S)
    lines.start()
    time.sleep(1.6)
    lines.stop()
    printed = capsys.readouterr().err.splitlines()
    assert 1 <= len(printed) <= 1.6 / URGENT_GAP_S + 1, printed


def test_a_dumb_narrow_terminal_gets_plain_lines_with_the_release_key(tmp_path):
    """hubo teleop on a pty with TERM=dumb and 20 columns: the keys once, then one plain line
    per update (never cut: the terminal wraps them, no cursor movement), the e-stop with its
    release key after space, and q ends the run."""
    keys = {"space": False, "q": False}

    def operator(text, send):
        if "teleop operate" in text and not keys["space"]:
            keys["space"] = True
            send(b" ")
        if "E-STOP (operator)" in text and not keys["q"]:
            keys["q"] = True
            send(b"q")

    code, output = run_in_pty([HUBO, "teleop", "--replay", str(FREE_CSV), "--driver", "ideal",
                               "--speed", "1", "--out", str(tmp_path / "run")],
                              columns=20, term="dumb", on_output=operator, timeout_s=180)
    assert code == 0, output
    lines = output.replace("\r", "").splitlines()
    assert KEYS_HELP in lines  # whole, on its own line
    progress = [line for line in lines if line.startswith("teleop ")
                and ": samples " in line]
    assert len(progress) >= 2, output
    assert any("E-STOP (operator) — press r to release" in line for line in progress), output
    assert all("collision" in line and "right-arm" in line for line in progress)
    assert "\x1b[" not in output  # a dumb terminal: no colour, no cursor movement
    assert "e-stops 1" in output


def _emulator() -> tuple[subprocess.Popen, str]:
    """``hubo fastrak emulate --pty`` in its own process (it streams while this one stalls)."""
    process = subprocess.Popen([HUBO, "fastrak", "emulate", "--pty", "--stations", "2",
                                "--duration", "60"], stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL, text=True)
    return process, process.stdout.readline().strip()


def test_a_late_loop_does_not_make_fresh_input_stale():
    """The reader's thread starved while the caller runs late (it holds the interpreter, as a
    long period does): the input is not stale, as the unit streamed all along. A unit that
    really stops is stale soon after the 0.25 s timeout."""
    emulator, port = _emulator()
    try:
        assert port.startswith("/dev/"), port
        with open_source(port=port) as source:
            deadline = time.monotonic() + DEADLINE_S
            while time.monotonic() < deadline and source.last_seen_s(1) is None:
                source.read_until(0.0)
                time.sleep(0.01)
            judged = []
            for _ in range(3):  # the reader may slip in once at the start of a stall: retry
                judged.append(_stalled_judgement(source))
                if judged[-1][0] > 0.5:
                    break
            late_s, stale = judged[-1]
            # the newest sample is over 0.5 s old by the loop's clock, which would call it stale
            assert late_s > 0.5 and not stale, judged
            emulator.send_signal(signal.SIGSTOP)  # the unit goes silent; the reader reads on
            try:
                def silent() -> bool:
                    source.read_until(0.0)
                    return source.is_stale(1, source.now_s())

                stopped_s = time.monotonic()
                assert _wait(silent)
                # 0.25 s of silence, read by a reader polling every 50 ms (or, starved for a
                # second, judged by the caller's clock): well within 2 s on a busy machine
                assert time.monotonic() - stopped_s < 2.0
            finally:
                emulator.send_signal(signal.SIGCONT)
    finally:
        emulator.kill()
        emulator.wait()


def _stalled_judgement(source) -> tuple[float, bool]:
    """Hold the interpreter for 0.6 s (the reader thread waits for its turn), then judge station
    1 as the loop does: (its newest sample's age by the loop's clock, stale)."""
    switch = sys.getswitchinterval()
    sys.setswitchinterval(10.0)
    try:
        busy_until = time.monotonic() + 0.6
        while time.monotonic() < busy_until:
            pass
        source.read_until(0.0)
        now_s = source.now_s()
        return now_s - source.last_seen_s(1), source.is_stale(1, now_s)
    finally:
        sys.setswitchinterval(switch)
