"""The control loop: pacing without drift (fake clock), the log written as it goes, smooth
stops on Ctrl-C and on module errors."""

from __future__ import annotations

import errno
import os
import signal
import sys

import numpy as np
import pytest
from control_support import assert_within_limits, ideal

from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.log import FLAGS_NAME, LOG_NAME, ROWS_NAME, load_log, read_rows
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Module
from hubo_cli.control.phase import PHASE_STOP, PhaseStop
from hubo_cli.control.pipeline import build_pipeline
from hubo_cli.control.status import Status
from hubo_cli.control.target import Target
from hubo_cli.errors import InputError, Terminated
from hubo_cli.interrupts import run_files
from hubo_cli.pace import MIN_SPEED, check_speed

DT = 0.005


class FakeClock:
    """Time that only moves when slept or when work is simulated."""

    def __init__(self, start_s: float = 100.0) -> None:
        self.now_s = start_s
        self.sleeps = 0

    def __call__(self) -> float:
        return self.now_s

    def sleep(self, seconds: float) -> None:
        self.sleeps += 1
        self.now_s += seconds


class PassThrough(Module):
    name = "pass"

    def update(self, q_rad, state, cycle):
        return np.where(np.isfinite(q_rad), q_rad, state.q_rad)


def _moving_target(q0, joint=0, amplitude=0.3, period_s=4.0):
    def target(t_s, state):
        q = q0.copy()
        q[joint] += amplitude * np.sin(2 * np.pi * t_s / period_s)
        return q, {}
    return target


@pytest.mark.parametrize("speed", [1.0, 2.5])
def test_paced_loop_does_not_drift(model, speed):
    clock = FakeClock()
    rng = np.random.default_rng(3)
    robot = ideal(model)
    starts = []

    def target(t_s, state):
        starts.append(clock())
        clock.now_s += rng.uniform(0.0, 0.9) * DT / speed  # work of varying length
        return None, {}

    n = 3000
    loop = ControlLoop(robot, [PassThrough()], target, speed=speed, clock=clock,
                       sleep=clock.sleep)
    result = loop.run(duration_s=n * DT)
    assert result.periods == n and result.overruns == 0
    expected = starts[0] + np.arange(n) * DT / speed
    assert np.max(np.abs(np.array(starts) - expected)) < 1e-9


def test_late_periods_catch_up_then_reanchor(model):
    clock = FakeClock()
    robot = ideal(model)
    starts = []

    def target(t_s, state):
        starts.append(clock())
        k = len(starts)
        if k == 10:
            clock.now_s += 3 * DT      # one slow period: the next ones run back to back
        if k == 100:
            clock.now_s += 1.0         # a stall far beyond max_lag_periods: re-anchor
        return None, {}

    result = ControlLoop(robot, [PassThrough()], target, speed=1.0, clock=clock,
                         sleep=clock.sleep).run(duration_s=200 * DT)
    starts = np.array(starts) - starts[0]
    schedule = np.arange(len(starts)) * DT
    assert np.allclose(starts[:10], schedule[:10], atol=1e-9)
    assert np.all(starts[10:12] > schedule[10:12])                  # late, run back to back
    assert np.allclose(starts[12:100], schedule[12:100], atol=1e-9)  # back on schedule
    assert result.overruns == 1
    assert abs(result.skipped_s - (1.0 - DT)) < 1e-9  # the stall, less the period it was due in
    assert np.allclose(np.diff(starts[100:]), DT, atol=1e-9)


def test_unpaced_loop_never_sleeps(model):
    clock = FakeClock()
    robot = ideal(model)
    ControlLoop(robot, [PassThrough()], lambda t, s: (None, {}), speed=None, clock=clock,
                sleep=clock.sleep).run(duration_s=0.5)
    assert clock.sleeps == 0


def test_log_is_written_as_it_goes(model, tmp_path):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    seen = []

    def target(t_s, state):
        k = int(round(t_s / DT))
        if k in (1, 50, 120):  # the periods so far are stored (the CSV comes at close)
            _, rows, flags = read_rows(tmp_path / ROWS_NAME, tmp_path / FLAGS_NAME)
            seen.append((k, len(rows), len(flags)))
        return _moving_target(q0)(t_s, state)

    result = ControlLoop(robot, build_pipeline(model), target,
                         log_path=tmp_path).run(duration_s=1.0)
    assert seen == [(1, 1, 1), (50, 50, 50), (120, 120, 120)]
    assert not (tmp_path / ROWS_NAME).exists() and not (tmp_path / FLAGS_NAME).exists()
    log = load_log(tmp_path)
    assert len(log) == result.periods
    assert log.joints("cmd").shape == (result.periods, 24)
    header = (tmp_path / LOG_NAME).read_text().splitlines()[0].split(",")
    units = ("_s", "_us", "_rad", "_m", "_n", "_nm", "_count", "_code", "_flag")
    assert all(name == "flags" or name.endswith(units) for name in header), header
    running = np.array(["smooth-stop" not in f for f in log.flags])
    assert np.all(np.isfinite(log["com_z_m"][running]))
    assert np.allclose(log["t_s"], np.arange(len(log)) * DT)


def _assert_smooth_end(model, robot, q0):
    commands = robot.commands(q0)
    assert_within_limits(model, commands, DT)
    v_end = (commands[-1] - commands[-2]) / DT
    assert np.max(np.abs(v_end)) < 1e-9
    assert robot.stops >= 1


def test_ctrl_c_ends_in_a_smooth_stop(model, tmp_path):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    moving = _moving_target(q0, amplitude=0.5, period_s=3.0)

    def target(t_s, state):
        if t_s >= 0.75:
            raise KeyboardInterrupt
        return moving(t_s, state)

    result = ControlLoop(robot, build_pipeline(model), target, log_path=tmp_path).run(5.0)
    assert result.ended == "interrupted" and not result.ok
    assert result.stop_periods > 10          # it was moving, so the brake took a while
    _assert_smooth_end(model, robot, q0)
    log = load_log(tmp_path)
    assert len(log) == result.periods
    assert "smooth-stop" in log.flags[-1]
    assert log.status[-1] == Status.SLOWING


@pytest.mark.parametrize("interrupts_s", [(0.75,), (0.75, 0.78)], ids=["once", "twice"])
def test_ctrl_c_after_a_periods_record_counts_that_period(model, tmp_path, interrupts_s):
    """SIGTERM / Ctrl-C arrive between any two bytecodes: one that lands after a period's record
    was written (here in the viewer's call) counts that period, in the run and in its smooth
    stop (a second Ctrl-C), so the summary's ``periods`` is the log's length (main: one short,
    seen once in the suite on a loaded machine) and ``stop_periods`` counts the stop's."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()

    class Interrupting:
        left = list(interrupts_s)

        def period(self, t_s, status, flags, state, extras):
            if self.left and t_s >= self.left[0]:
                self.left.pop(0)
                raise KeyboardInterrupt

    moving = _moving_target(q0, amplitude=0.5, period_s=3.0)
    result = ControlLoop(robot, build_pipeline(model), moving, log_path=tmp_path,
                         observer=Interrupting()).run(5.0)
    assert result.ended == "interrupted", result.error
    log = load_log(tmp_path)
    assert len(log) == result.periods
    stopping = np.array(["smooth-stop" in f for f in log.flags])
    assert result.stop_periods == stopping.sum() > 0


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_interrupts_while_the_loop_cleans_up_wait_for_the_run_files(model, tmp_path, signum):
    """A Ctrl-C, then two more signals while the loop stops the driver and writes its log (the
    fuzz review's second Ctrl-C 0.15-0.4 s after the first: main left log.csv header-only and no
    summary): the log is whole, and the signals wait for the run's scope (raised at its end)."""
    robot = ideal(model)
    moving = _moving_target(robot.read().q_rad.copy(), amplitude=0.5, period_s=3.0)
    stop = robot.stop

    def stop_while_signalled():
        os.kill(os.getpid(), signum)
        os.kill(os.getpid(), signal.SIGINT)
        stop()

    robot.stop = stop_while_signalled
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        with pytest.raises(KeyboardInterrupt), run_files():
            result = ControlLoop(robot, build_pipeline(model), moving, log_path=tmp_path).run(0.5)
            assert result.ended == "finished", result.error
            assert len(load_log(tmp_path)) == result.periods
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert not (tmp_path / ROWS_NAME).exists()  # the rows were turned into the CSV


def test_a_slowed_runs_stop_goes_at_real_time_at_least(model, tmp_path):
    """At the slowest pace (MIN_SPEED) a period lasts 100 times its length, and the smooth stop
    after a Ctrl-C is paced at real time (main: at the run's pace, so at --speed 1e-9 a Ctrl-C
    waited for days); slower than MIN_SPEED is refused (by the run's set-up)."""
    robot = ideal(model)
    moving = _moving_target(robot.read().q_rad.copy(), amplitude=0.5, period_s=3.0)
    now = [0.0]
    sleeps = []

    def sleep(s):
        sleeps.append(s)
        now[0] += s

    class Interrupting:
        def period(self, t_s, status, flags, state, extras):
            if abs(t_s - 0.5) < 1e-9:
                raise KeyboardInterrupt

    loop = ControlLoop(robot, build_pipeline(model), moving, speed=MIN_SPEED, log_path=tmp_path,
                       clock=lambda: now[0], sleep=sleep, observer=Interrupting())
    result = loop.run(5.0)
    assert result.ended == "interrupted" and result.stop_periods > 10
    dt = robot.period_s
    slow = [s for s in sleeps if s > dt + 1e-12]  # all the run's periods but the first
    assert len(slow) == result.periods - result.stop_periods - 1
    assert slow == pytest.approx([dt / MIN_SPEED] * len(slow))
    with pytest.raises(InputError, match="at least"):
        check_speed(MIN_SPEED / 2)


def _raise_terminated(signum, frame):
    raise Terminated


class Exploding(Module):
    name = "exploding"

    def __init__(self, at_s):
        self.at_s = at_s

    def update(self, q_rad, state, cycle):
        if cycle.t_s >= self.at_s:
            raise RuntimeError("module failure")
        return q_rad


def test_module_error_ends_in_a_smooth_stop(model, tmp_path):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    modules = build_pipeline(model)
    modules.insert(1, Exploding(0.6))
    result = ControlLoop(robot, modules, _moving_target(q0, amplitude=0.5, period_s=3.0),
                         log_path=tmp_path).run(5.0)
    assert result.ended == "module-error"
    assert "RuntimeError" in result.error and "module failure" in result.error
    assert result.stop_periods > 10
    _assert_smooth_end(model, robot, q0)
    assert len(load_log(tmp_path)) == result.periods


def test_target_done_and_operator_release(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()

    def target(t_s, state):
        info = {"done": t_s >= 0.5}
        if abs(t_s - 0.1) < 1e-9:
            info["estop"] = ["operator"]
        if abs(t_s - 0.2) < 1e-9:
            info["release"] = True
        return q0, info

    result = ControlLoop(robot, build_pipeline(model), target).run()
    assert result.ended == "done" and result.ok
    kinds = [(name, kind) for name, _, kind, _ in result.safety_events]
    assert kinds == [("estop", "stop"), ("estop", "release")]


def test_a_swallowed_interrupt_still_ends_the_run_before_anything_moves(model, tmp_path):
    """Ctrl-C during a cold cache's numba compile raises inside a ctypes callback, which
    swallows the KeyboardInterrupt ("Exception ignored ..."): on main the run then went on to
    its end, exit 0. Noted by the handler, the loop sees it before the robot's first command:
    interrupted, nothing sent."""
    from hubo_cli import interrupts

    robot = ideal(model)
    moving = _moving_target(robot.read().q_rad.copy(), amplitude=0.5, period_s=3.0)
    with interrupts.catching_interrupts():
        try:  # as a ctypes callback does
            interrupts._interrupt(signal.SIGINT, None)
        except KeyboardInterrupt:
            pass
        result = ControlLoop(robot, build_pipeline(model), moving, log_path=tmp_path).run(1.0)
    assert result.ended == "interrupted" and result.error == "interrupted (Ctrl-C)"
    assert robot.sent == [] and result.periods == 0
    assert interrupts.interrupt_pending() is None  # acted on: the next run is not ended by it


def test_a_swallowed_interrupt_is_not_printed_and_other_lost_errors_still_are(monkeypatch):
    """Python prints "Exception ignored on calling ctypes callback function ...
    KeyboardInterrupt" (a traceback) for an interrupt a ctypes callback swallows (numba's
    compile of a cold cache); noted, it is the loop's to act on: the command line's scope
    keeps it off stderr. Any other exception such a callback loses is still reported."""
    import ctypes

    from hubo_cli import interrupts

    reported = []

    def recorded(unraisable):
        reported.append(type(unraisable.exc_value))

    monkeypatch.setattr(sys, "unraisablehook", recorded)
    callback = ctypes.CFUNCTYPE(None)
    interrupted = callback(lambda: interrupts._interrupt(signal.SIGINT, None))
    failing = callback(lambda: 1 / 0)
    with interrupts.catching_interrupts():
        interrupted()
        assert interrupts.interrupt_pending() == "Ctrl-C"
        failing()
    assert reported == [ZeroDivisionError]  # (main: KeyboardInterrupt as well)
    assert sys.unraisablehook is recorded and interrupts.interrupt_pending() is None


def test_an_interrupt_in_the_loop_is_acted_on_between_periods(model, tmp_path):
    """Inside the loop the first interrupt is noted, not raised (it cannot land inside a
    period); the loop brakes from the next period on; a non-walking run brakes as before."""
    robot = ideal(model)
    moving = _moving_target(robot.read().q_rad.copy(), amplitude=0.5, period_s=3.0)
    reached = []

    def target(t_s, state):
        if abs(t_s - 0.75) < DT / 2:
            os.kill(os.getpid(), signal.SIGINT)  # noted by the loop's handler: not raised
            reached.append(t_s)  # (main: never, the interrupt raised above)
        return moving(t_s, state)

    result = ControlLoop(robot, build_pipeline(model), target, log_path=tmp_path).run(5.0)
    assert result.ended == "interrupted" and result.error == "interrupted (Ctrl-C)"
    assert reached == [pytest.approx(0.75)]
    assert result.periods - result.stop_periods == round(0.75 / DT) + 1  # that period ran
    assert result.stop_periods > 10 and result.interrupt_stop == ""


class _Stepping(Target):
    """A phase that stops itself (a walk's contract, without the walk): it moves joint 0 and,
    once the stopper latches, slows to rest over 0.3 s and says it stands (PHASE_STOP) 0.8 s
    after the latch (the trajectory generator ahead of the stopper at rest by then)."""

    writes = (PHASE_STOP,)
    previous = (STOP_MODE,)

    def __init__(self, q0, interrupts_s=(), fail_log_s=None, loop=None):
        self.moving = _moving_target(q0, amplitude=0.2, period_s=3.0)
        self.interrupts_s, self.fail_log_s, self.loop = list(interrupts_s), fail_log_s, loop
        self.stopped_s = None
        self.q = q0

    def __call__(self, t_s, state):
        if self.interrupts_s and t_s >= self.interrupts_s[0] - 1e-9:
            self.interrupts_s.pop(0)
            os.kill(os.getpid(), signal.SIGINT)
        if self.fail_log_s is not None and t_s >= self.fail_log_s and not self.loop.log.error:
            self.loop.log._failed(OSError(errno.ENOSPC, "No space left on device"), "log.rows")
        if self.stopped_s is None and self.store.get(STOP_MODE, "release") != "release":
            self.stopped_s = t_s
        if self.stopped_s is None:
            self.q = self.moving(t_s, state)[0]
            done = 0.0
        else:  # the phase's own stop: slow down (the joint's motion scaled to rest)
            done = min((t_s - self.stopped_s) / 0.3, 1.0)
            previous, self.q = self.q, self.moving(t_s, state)[0]
            self.q = previous + (1.0 - done) * (self.q - previous)
        self.store[PHASE_STOP] = PhaseStop(
            self.stopped_s is not None and t_s - self.stopped_s >= 0.8 - 1e-9, 2.0)
        return self.q, {}


@pytest.mark.skipif(sys.platform == "win32", reason="SIGHUP")
def test_a_hangup_then_sigterm_lets_the_phase_stop_itself(model, tmp_path):
    """SIGHUP (the terminal gone) mid-phase takes the phase's own stop as Ctrl-C does; a
    SIGTERM 0.1 s later (``timeout``, systemd) is said in the error and the stop goes on to
    the stance (round 16; main: SIGHUP's default action ended the process)."""
    from hubo_cli import interrupts

    class Hanging(_Stepping):
        def __call__(self, t_s, state):
            for at_s, signum in ((0.5, signal.SIGHUP), (0.6, signal.SIGTERM)):
                if abs(t_s - at_s) < DT / 2:
                    os.kill(os.getpid(), signum)
            return super().__call__(t_s, state)

    before = {s: signal.signal(s, signal.SIG_DFL) for s in (signal.SIGHUP, signal.SIGTERM)}
    try:
        with interrupts.catching_interrupts():
            assert signal.getsignal(signal.SIGHUP) is interrupts._interrupt  # (main: SIG_DFL)
            robot = ideal(model)
            q0 = robot.read().q_rad.copy()
            target = Hanging(q0)
            loop = ControlLoop(robot, build_pipeline(model, ("estop", "limiter")), target,
                               log_path=tmp_path)
            result = loop.run(5.0)
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
    assert result.ended == "interrupted"
    assert result.error == "interrupted (SIGHUP); SIGTERM during the stop, which went on"
    assert result.interrupt_stop == "stood" and result.stop_periods <= 1
    _assert_smooth_end(model, robot, q0)


@pytest.mark.parametrize("event", ["Ctrl-C", "log failure", "Ctrl-C twice"])
def test_a_phase_that_stops_itself_is_asked_to_after_ctrl_c_or_a_log_failure(model, tmp_path,
                                                                             event):
    """Ctrl-C (or a full disk) while the target's phase stops itself: the loop requests the
    operator's stop and runs on (the log no longer written after a failure) until the stopper
    holds the phase's stance, then 0.5 s; a second Ctrl-C meanwhile falls back to the brake."""
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    target = _Stepping(q0, interrupts_s={"Ctrl-C": (0.5,), "Ctrl-C twice": (0.5, 0.6)}.get(
        event, ()), fail_log_s=0.5 if event == "log failure" else None)
    modules = build_pipeline(model, ("estop", "limiter"))  # the phase's motion unfiltered
    loop = ControlLoop(robot, modules, target, log_path=tmp_path)
    target.loop = loop
    result = loop.run(5.0)
    assert result.ended == ("log-error" if event == "log failure" else "interrupted")
    assert target.stopped_s == pytest.approx(0.51)  # latched at 0.505, seen the next period
    if event == "Ctrl-C twice":
        assert result.interrupt_stop == "braked: a second interrupt (Ctrl-C)"
        assert result.interrupt_stop_s == pytest.approx(0.1, abs=0.011)  # 0.505 to 0.605
        assert result.stop_periods > 0  # the loop's brake
    else:
        assert result.interrupt_stop == "stood"
        assert result.interrupt_stop_s == pytest.approx(0.81, abs=0.011)
        assert result.t_end_s == pytest.approx(target.stopped_s + 0.8 + 0.5, abs=0.011)
        assert result.stop_periods <= 1  # at rest: the loop's brake had nothing to stop
    assert result.log_periods_dropped == (result.periods - round(0.5 / DT)
                                          if event == "log failure" else 0)
    _assert_smooth_end(model, robot, q0)


@pytest.mark.parametrize(("event", "presses"), [("sensor fault", 1), ("log failure", 2)])
def test_ctrl_c_during_a_faults_stance_stop_lets_it_stand_and_twice_brakes(model, tmp_path,
                                                                          event, presses,
                                                                          capsys):
    """The log fails (or a sensor fault is raised) at 0.2 s: the phase stops itself; Ctrl-C
    at 0.3 s: the stop goes on to the stance and the error names both; a second Ctrl-C at 0.4
    s brakes, as during an interrupt's stance (round 18; main braked at the first, mid-step:
    the review's walk left on one foot after a stuck IMU's stance stop and a Ctrl-C)."""
    from hubo_cli.estimation.build import build_estimator
    from hubo_cli.estimation.plausibility import SensorFault

    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    target = _Stepping(q0, interrupts_s=(0.3, 0.4)[:presses],
                       fail_log_s=0.2 if event == "log failure" else None)
    estimator = None
    if event == "sensor fault":  # the estimation layer finds one at 0.2 s
        estimator = build_estimator(model, sensors_measured=False)
        update = estimator.update

        def failing(state):
            update(state)
            if abs(state.time_s - 0.2) < DT / 2:
                raise SensorFault("the IMU read the same values: frozen")
        estimator.update = failing
    loop = ControlLoop(robot, build_pipeline(model, ("estop", "limiter")), target,
                       log_path=tmp_path, estimator=estimator)
    target.loop = loop
    result = loop.run(5.0)
    first = {"log failure": ("log-error", "cannot write the log"),
             "sensor fault": ("device", "the IMU read the same values: frozen")}[event]
    assert result.ended == first[0]  # the first event stays the run's end
    assert result.error.startswith(first[1])
    assert result.error.endswith("; interrupted (Ctrl-C)" if presses == 1
                                 else "; interrupted (Ctrl-C); second interrupt (Ctrl-C)")
    if presses == 1:
        assert result.interrupt_stop == "stood"  # (main: "braked: Ctrl-C while standing up")
        assert result.t_end_s == pytest.approx(target.stopped_s + 0.8 + 0.5, abs=0.011)
    else:
        assert result.interrupt_stop == "braked: a second interrupt (Ctrl-C)"
        assert result.interrupt_stop_s == pytest.approx(0.2, abs=0.011)
    _assert_smooth_end(model, robot, q0)
    if event == "sensor fault":  # stderr names both, in order, one line each (round 19;
        # main: the fault alone)
        from hubo_cli.cli.main import report_error
        from hubo_cli.cli.output import exit_if_interrupted

        assert result.said == (first[1], "interrupted (Ctrl-C)")
        report_error(result.failure(tmp_path))
        lines = capsys.readouterr().err.splitlines()
        assert lines[:2] == [f"error: {first[1]}", "then: interrupted (Ctrl-C)"]
        assert lines[2].startswith("hint: ") and len(lines) == 3
        # the other order (Ctrl-C, then the fault in its stance stop): exit 130, both said
        fault = SensorFault(first[1])
        fault.events = ("interrupted (Ctrl-C)", first[1])
        with pytest.raises(SystemExit, match="130"):
            exit_if_interrupted({"ended": "interrupted", "interrupt_stop": "stood"}, fault)
        assert capsys.readouterr().err.splitlines() == ["interrupted (Ctrl-C)",
                                                        f"then: {first[1]}"]


def test_a_full_disk_during_an_interrupts_stance_says_both_and_exits_as_interrupted(model,
                                                                                   tmp_path):
    """Ctrl-C at 0.1 s, then the log fails at 0.2 s while the phase finishes its stop: the
    run stays ``interrupted`` (the operator's came first: exit 130), the one-line error and
    the summary name the full disk as well, and no snapshot or log read-back is tried on the
    full disk (main went on as after a whole log: on a real full disk the snapshot's write
    failed, a bare OSError, exit 3, no summary)."""
    import json

    from hubo_cli.control.pipeline import SafetyProfile
    from hubo_cli.errors import InterruptedRunError
    from hubo_cli.session import RunSetup, run

    q0 = ideal(model).read().q_rad.copy()
    target = _Stepping(q0, interrupts_s=(0.1,), fail_log_s=0.2)
    setup = RunSetup(command="stepping", model=model, driver="ideal", out=tmp_path / "run",
                     safety=SafetyProfile(balance=False))
    with pytest.raises(InterruptedRunError) as raised:
        run(setup, target, on_start=lambda target, loop: setattr(target, "loop", loop))
    message = str(raised.value)
    assert raised.value.exit_code == 130
    assert message.startswith("interrupted (Ctrl-C); cannot write the log ")
    assert message.count("No space left on device") == 1  # (main said it twice)
    assert "; the walk finished its step and stood after 1.4" in message
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["ended"] == "interrupted" and summary["interrupt_stop"] == "stood"
    assert summary["error"].startswith("interrupted (Ctrl-C); cannot write the log ")
    assert summary["log_periods_dropped"] == summary["periods"] - round(0.2 / DT)
