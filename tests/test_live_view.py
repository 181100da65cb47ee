"""The operator always sees the safety state: the live view rendered in-process, and the real
terminal (tmux) after pressing space."""

import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from rich.console import Console

from hubo_cli.cli.safety_view import HandSafety, SafetyPanel, SafetyState, read_safety, safety_text
from hubo_cli.cli.teleop import _view, hand_safety
from hubo_cli.control.pipeline import find_module
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

    def operator(target, modules, panel):
        estop = find_module(modules, "estop")
        if not _wait(lambda: target.phase == "operate"):
            return
        target.keys.estop = True
        if _wait(lambda: estop.mode == "hold"):
            captured["held"] = _text(_view(target, panel))
        target.keys.release = True
        if _wait(lambda: estop.mode == "recover"):
            captured["released"] = _text(_view(target, panel))
        target.keys.quit = True

    def on_ready(target):
        modules = target.modules
        panel = SafetyPanel(lambda: read_safety(modules, hand_safety(target)),
                            bell=lambda: bells.append(time.monotonic()))
        captured["first"] = _text(_view(target, panel))
        threading.Thread(target=operator, args=(target, modules, panel), daemon=True).start()

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
    assert read_safety([]).stops == 0


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
