"""The hardware driver on its dry-run sink (file/FIFO, state echoed through hubo-daemon's
reference filter): arming, start-up delay, frames, safety latches, faults, and a state that
stops (its source silenced, a clock of one period a step). The same driver on real ach
channels: tests/test_hardware_ach.py."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hubo_cli.drivers.hardware import (
    MODE_DIRECT,
    MODE_FILTERED,
    STALE_AFTER_S,
    STALE_GRACE_S,
    HardwareDriver,
    read_ref_frames,
)
from hubo_cli.drivers.hubo_ach import JOINT_COUNT, REF_SIZE
from hubo_cli.errors import ConfigError, DeviceError, SafetyError
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

MODEL = load_model()
PERIOD = MODEL.control_period_s
INDEX = MODEL.hubo_ach["index"]
REB = MODEL.joint_names.index("REB")


@pytest.fixture
def hw(tmp_path):
    driver = HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin")
    yield driver
    driver.close()


def _ramp(driver, joint: int, step_rad: float, periods: int):
    q = driver.read().q_rad.copy()
    for _ in range(periods):
        q[joint] += step_rad
        driver.send(q)
        state = driver.step()
    return q, state


def test_the_imus_a_z_is_no_heading(hw):
    """hubo-ach's a_z is not a heading (docs/hardware.md): whatever it carries, the attitude the
    driver reports has the tilt a_x, a_y and yaw 0."""
    from hubo_cli.geometry import quat_wxyz_to_matrix, roll_pitch_of_quat_wxyz

    q = hw.start().q_rad
    advance = hw.source.advance
    rng = np.random.default_rng(41)
    tilt = np.zeros(3)

    def tilted(ref_rad, mode):
        frame = advance(ref_rad, mode)
        frame.imu_tilt_rad = tilt.copy()
        return frame

    hw.source.advance = tilted
    for a_z in (0.0, 1.3, -3.0, np.pi, *rng.uniform(-10.0, 10.0, 20)):
        tilt[:] = *rng.uniform(-0.3, 0.3, 2), a_z
        hw.send(q)
        quat = hw.step().imu_quat_wxyz
        R = quat_wxyz_to_matrix(quat)
        assert np.arctan2(R[1, 0], R[0, 0]) == pytest.approx(0.0, abs=1e-12)
        assert np.allclose(roll_pitch_of_quat_wxyz(quat), tilt[:2], atol=1e-12)


@pytest.mark.parametrize("sink", ["ach", "file", "fifo"])
def test_refuses_to_start_unless_armed(tmp_path, sink):
    driver = HardwareDriver(MODEL, sink=sink, sink_path=tmp_path / "hubo-ref.bin")
    with pytest.raises(SafetyError, match="not armed") as info:
        driver.start()
    assert "--arm" in info.value.hint
    assert not (tmp_path / "hubo-ref.bin").exists()


def test_no_reference_in_the_first_0_8_s_then_one_frame_per_period(hw):
    state = hw.start()
    assert state.time_s == pytest.approx(MODEL.hubo_ach["startup_ref_delay_s"])
    assert hw.sink_path.stat().st_size == 0
    for _ in range(10):
        hw.step()
    frames = read_ref_frames(hw.sink_path)
    assert len(frames) == 10
    assert hw.log_values()["hw_ref_seq"] == 10
    assert hw.read().time_s == pytest.approx(0.8 + 10 * PERIOD)
    assert hw.sink_path.stat().st_size == 10 * REF_SIZE == 10 * 462


def test_frames_carry_references_in_hubo_ach_order(hw):
    hw.start()
    q = home_posture(MODEL)
    q[REB] -= 0.003
    hw.send(q)
    hw.step()
    frame = read_ref_frames(hw.sink_path)[-1]
    assert frame.ref_rad.shape == (JOINT_COUNT,)
    for i, name in enumerate(MODEL.joint_names):
        assert frame.ref_rad[INDEX[name]] == pytest.approx(q[i])
    unused = sorted(set(range(JOINT_COUNT)) - {INDEX[n] for n in MODEL.joint_names})
    assert np.all(frame.ref_rad[unused] == 0.0)
    assert np.all(frame.mode == MODE_DIRECT) and np.all(frame.comply == 0)  # direct: default


@pytest.mark.parametrize("mode", [MODE_FILTERED, MODE_DIRECT])
def test_echo_follows_through_the_mode_chosen(tmp_path, mode):
    with HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin",
                        ref_mode=mode) as hw:
        start = hw.start()
        q = start.q_rad.copy()
        q[REB] -= 0.004  # a small step, within the velocity limit
        hw.send(q)
        state = hw.step()
        assert np.all(read_ref_frames(hw.sink_path)[-1].mode == mode)
        assert hw.log_values()["hw_ref_mode"] == mode
    L = MODEL.hubo_ach["ref_filter_length"] if mode == MODE_FILTERED else 1
    assert state.q_rad[REB] - start.q_rad[REB] == pytest.approx(-0.004 / L)
    assert state.dq_rad_s[REB] == pytest.approx(-0.004 / L / PERIOD)


def test_nan_freezes_the_joint_until_released(hw):
    start = hw.start()
    q = start.q_rad.copy()
    q[REB] = np.nan
    applied = hw.send(q)
    assert applied[REB] == start.q_rad[REB]
    assert "REB" in hw.frozen_joints
    q[REB] = start.q_rad[REB] - 0.002
    assert hw.send(q)[REB] == start.q_rad[REB]  # still frozen
    assert "nan-ref" in hw.step().flags
    hw.release_joints()
    assert hw.send(q)[REB] == pytest.approx(q[REB])
    assert "nan-ref" not in hw.step().flags


def test_too_fast_reference_is_refused_and_latches_servo_off(hw):
    start = hw.start()
    limit = MODEL.velocity_rad_s[REB]
    q = start.q_rad.copy()
    q[REB] -= 0.9 * limit * PERIOD  # just under the limit: accepted
    assert hw.send(q)[REB] == pytest.approx(q[REB])
    jump = q.copy()
    jump[REB] -= 1.5 * limit * PERIOD
    held = hw.send(jump)
    assert held[REB] == pytest.approx(q[REB])
    assert hw.servo_off
    state = hw.step()
    assert "servo-off" in state.flags
    assert read_ref_frames(hw.sink_path)[-1].ref_rad[INDEX["REB"]] == pytest.approx(q[REB])
    assert hw.send(q)[REB] == pytest.approx(q[REB])  # latched: nothing new is accepted
    q2 = q.copy()
    q2[REB] -= 0.001
    assert hw.send(q2)[REB] == pytest.approx(q[REB])
    hw.reset_servo()
    assert hw.send(q2)[REB] == pytest.approx(q2[REB])


def test_an_exception_inside_ends_in_a_hold_not_a_crash(hw):
    start = hw.start()
    _ramp(hw, REB, -0.001, 5)

    os.close(hw.sink._fd)  # the sink's file goes away underneath the driver
    state = hw.step()  # no exception
    assert "fault" in state.flags
    assert "Bad file descriptor" in hw.fault_message
    q = state.q_rad.copy()
    q[REB] -= 0.001
    held = hw.send(q)
    assert held[REB] == pytest.approx(start.q_rad[REB] - 0.005)
    assert "fault" in hw.step().flags
    hw.stop()  # never raises
    hw.sink._fd = -1


def test_stop_writes_a_hold_frame(hw):
    hw.start()
    _ramp(hw, REB, -0.001, 3)
    hw.stop()
    frames = read_ref_frames(hw.sink_path)
    assert len(frames) == 4
    assert np.array_equal(frames[-1].ref_rad, frames[-2].ref_rad)
    assert "stopped" in hw.step().flags


def test_named_pipe_sink_works_without_a_reader(tmp_path):
    with HardwareDriver(MODEL, armed=True, sink="fifo",
                        sink_path=tmp_path / "hubo-ref.fifo") as driver:
        driver.start()
        flags = set()
        for _ in range(300):  # more than a pipe buffer holds
            flags |= set(driver.step().flags)
        assert "sink-full" in flags
        assert "fault" not in flags
        reader = os.open(driver.sink_path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            assert len(os.read(reader, REF_SIZE)) == REF_SIZE
        finally:
            os.close(reader)


def test_bad_options_are_refused(tmp_path):
    path = tmp_path / "hubo-ref.bin"
    with pytest.raises(ConfigError, match="unknown sink"):
        HardwareDriver(MODEL, armed=True, sink="socket", sink_path=path)
    with pytest.raises(ConfigError, match="needs sink_path"):
        HardwareDriver(MODEL, armed=True, sink="file")
    with pytest.raises(ConfigError, match="mode"):
        HardwareDriver(MODEL, armed=True, sink="file", sink_path=path, ref_mode=2)
    with pytest.raises(ConfigError, match="channel name"):
        HardwareDriver(MODEL, armed=True, ach_ref="a/b")


def test_the_run_folder_holds_the_file_sink(tmp_path):
    from hubo_cli.drivers.base import RunContext

    options = HardwareDriver.run_options(RunContext(tmp_path, {"right": "drill"}))
    assert options == {"sink_path": tmp_path / "hubo-ref.bin"}


def test_without_libach_the_ach_sink_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setenv("HUBO_LIBACH", str(tmp_path / "no-libach.so"))
    driver = HardwareDriver(MODEL, armed=True)
    with pytest.raises(DeviceError, match="libach is not available") as info:
        driver.start()
    assert info.value.exit_code == 3
    assert "golems/ach" in info.value.hint and "HUBO_LIBACH" in info.value.hint
    driver.close()


def test_a_library_that_is_not_libach_is_refused(monkeypatch):
    import ctypes.util

    libm = ctypes.util.find_library("m")
    if libm is None:
        pytest.skip("no libm to stand for a wrong library")
    monkeypatch.setenv("HUBO_LIBACH", libm)
    from hubo_cli.drivers.ach import LibachMissing, load_libach

    with pytest.raises(LibachMissing, match="not libach"):
        load_libach()


def test_libach_is_taken_from_the_variable_then_the_loader_then_the_environment(
        tmp_path, monkeypatch):
    """``HUBO_LIBACH`` first, a lab's libach on the loader path next, the copy ``make`` builds
    into the environment (``<sys.prefix>/lib/libach.so``) last; none of them: missing, with a
    hint that names the way to build it."""
    import ctypes.util
    import sys

    from hubo_cli.drivers import ach

    own = tmp_path / "env" / "lib" / "libach.so"
    monkeypatch.setattr(sys, "prefix", str(tmp_path / "env"))
    monkeypatch.delenv("HUBO_LIBACH", raising=False)
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    with pytest.raises(ach.LibachMissing, match="nor in this environment") as info:
        ach.load_libach()
    assert "make" in info.value.hint
    own.parent.mkdir(parents=True)
    own.write_bytes(b"")
    assert ach._libach_path() == str(own)
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: "/lab/libach.so")
    assert ach._libach_path() == "/lab/libach.so"
    monkeypatch.setenv("HUBO_LIBACH", "/mine/libach.so")
    assert ach._libach_path() == "/mine/libach.so"


class _Clock:
    """Wall time advancing one control period per driver step (the daemon's 200 Hz)."""

    def __init__(self) -> None:
        self.t_s = 100.0

    def __call__(self) -> float:
        return self.t_s


def _silence(driver, clock, *, after: int, back_after: int | None = None):
    """The state source goes quiet after ``after`` more periods (a dead daemon), and speaks
    again after ``back_after`` periods of silence if given; the clock runs one period a step."""
    advance = driver.source.advance
    count = {"n": 0}

    def quiet(ref_rad, mode):
        clock.t_s += PERIOD
        count["n"] += 1
        silent = count["n"] > after and (back_after is None or count["n"] <= after + back_after)
        frame = advance(ref_rad, mode)
        return None if silent else frame

    driver.source.advance = quiet


def _cruise(driver, periods: int, step_rad: float):
    """Move REB at a constant rate; returns the commands."""
    q = driver.read().q_rad.copy()
    for _ in range(periods):
        q[REB] += step_rad
        driver.send(q)
        driver.step()
    return q


@pytest.fixture
def stale_hw(tmp_path):
    clock = _Clock()
    driver = HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin",
                            clock=clock)
    driver.start()
    yield driver, clock
    driver.close()


def test_stale_state_brakes_then_holds_then_ends_the_run(stale_hw):
    """No fresh state for 0.1 s: the pipeline's commands are ignored, the reference brakes
    within the joint limits from its cruise, holds, and STALE_GRACE_S later the run ends
    (exit 3)."""
    from hubo_cli.drivers.stale_state import StateLost

    driver, clock = stale_hw
    # a third of the joint's speed limit: the brake is done well within the grace (from half
    # of it the brake takes 0.825 s, longer than the 0.8 s grace: the end waits for it)
    step = -MODEL.velocity_rad_s[REB] * PERIOD / 3
    _silence(driver, clock, after=10)
    q = _cruise(driver, 10, step)
    flags, lost = [], None
    for _ in range(400):
        q[REB] += step  # the pipeline would go on moving
        driver.send(q)
        try:
            flags.append(driver.step().flags)
        except StateLost as exc:
            lost = exc
            break
    assert lost is not None and lost.exit_code == 3 and not lost.back
    assert "braked" in lost.message and "hubo-state" in lost.message
    onset = next(i for i, f in enumerate(flags) if "stale-state" in f)
    assert onset in (19, 20)  # 0.1 s of 5 ms periods without a fresh state (+ rounding)
    # ends STALE_GRACE_S after the brake began (the brake is done by then), within a period
    assert len(flags) - onset == pytest.approx(STALE_GRACE_S / PERIOD, abs=1)
    assert all("stale-state" in f for f in flags[onset:])
    assert lost.stale_s == pytest.approx(STALE_AFTER_S + STALE_GRACE_S, abs=2 * PERIOD)

    ref = np.array([f.ref_rad[INDEX["REB"]] for f in read_ref_frames(driver.sink_path)])
    v = np.diff(ref) / PERIOD
    a = np.diff(v) / PERIOD
    cruise = 10 + onset + 1  # frames put before the brake's first
    assert np.allclose(v[:cruise - 1], step / PERIOD)  # the pipeline's commands until then
    brake = v[cruise - 1:]
    assert np.all(np.abs(np.diff(np.abs(brake))) <= 1e-9 + MODEL.acceleration_rad_s2[REB]
                  * PERIOD)  # decelerating only, within the acceleration limit
    assert np.max(np.abs(a)) <= MODEL.acceleration_rad_s2[REB] * 1.001
    assert np.all(brake * np.sign(step) >= -1e-12)  # never back, never a jump
    rest = np.flatnonzero(np.abs(brake) < 1e-12)[0]
    v0, a_max, j_max = (abs(step) / PERIOD, MODEL.acceleration_rad_s2[REB],
                        MODEL.jerk_rad_s3[REB])
    assert rest * PERIOD <= v0 / a_max + a_max / j_max + 2 * PERIOD < STALE_GRACE_S
    assert np.all(brake[rest:] == 0.0)  # then held, whatever the pipeline sends
    travel = abs(ref[-1] - ref[cruise - 1])
    assert travel <= v0**2 / a_max  # twice v²/2a: the jerk limit's ramps add less than that

    driver.stop()
    assert read_ref_frames(driver.sink_path)[-1].ref_rad[INDEX["REB"]] == ref[-1]


def test_state_back_within_the_grace_does_not_resume_the_motion(stale_hw):
    from hubo_cli.drivers.stale_state import StateLost

    driver, clock = stale_hw
    _silence(driver, clock, after=5, back_after=60)  # 0.3 s without a state, then back
    q = _cruise(driver, 5, -0.001)
    held = []  # the reference while the state is back
    with pytest.raises(StateLost) as info:
        for _ in range(400):
            q[REB] -= 0.001
            applied = driver.send(q)
            if "stale-hold" in driver.step().flags:
                held.append(applied[REB])
    assert info.value.back and info.value.exit_code == 3
    assert info.value.stale_s == pytest.approx(0.3, abs=2 * PERIOD)
    assert "came back" in info.value.message and "not resumed" in info.value.message
    # fresh state for the rest of the grace, yet the brake goes on to rest and holds there
    speed = np.abs(np.diff(held))
    assert len(held) > 100 and np.all(np.diff(speed) <= 1e-12)
    assert np.all(speed[-50:] == 0.0)
    assert abs(held[-1] - q[REB]) > 0.1  # the pipeline moved on; the robot did not follow


def test_a_state_whose_clock_stands_still_is_not_fresh(stale_hw):
    driver, clock = stale_hw
    advance = driver.source.advance
    frozen = {}

    def repeat(ref_rad, mode):  # a daemon stuck republishing the same state
        clock.t_s += PERIOD
        frozen.setdefault("frame", advance(ref_rad, mode))
        return frozen["frame"]

    driver.source.advance = repeat
    flags = [driver.step().flags for _ in range(25)]
    assert "stale-state" in flags[-1] and "stale-state" not in flags[10]
    assert driver.log_values()["hw_state_age_periods"] >= 20


def test_a_run_whose_robot_state_stops_ends_device_with_its_periods_counted(tmp_path):
    """The loop on the dry-run driver whose state stops: ``ended: device``, the driver's
    error, its stale periods counted, no smooth stop of the loop's own after the brake."""
    from hubo_cli.control.loop import ControlLoop

    clock = _Clock()
    with HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin",
                        clock=clock) as driver:
        state = driver.start()
        _silence(driver, clock, after=40)
        q0 = state.q_rad.copy()

        def target(t_s, state):
            q = q0.copy()
            q[REB] -= 0.2 * t_s  # 0.2 rad/s, on and on
            return q, {}

        loop = ControlLoop(driver, [], target, speed=None)
        result = loop.run(5.0)
    assert result.ended == "device" and result.exception.exit_code == 3
    assert "robot state lost" in result.error
    stale = result.flag_counts["stale-state"]
    # the grace, or the brake from 0.2 rad/s if longer (161 periods measured)
    assert STALE_GRACE_S / PERIOD - 2 <= stale <= 1.0 / PERIOD
    assert result.stop_periods == 0
    assert 40 + 20 + STALE_GRACE_S / PERIOD - 3 <= result.periods <= 40 + 20 + 1.0 / PERIOD


def test_the_view_and_the_status_say_state_stale():
    from hubo_cli.cli.safety_view import read_safety, safety_text
    from hubo_cli.control.status import Status, status_from_flags

    assert status_from_flags({"servo-off", "stale-state", "estop"}) == Status.STATE_STALE
    assert Status.STATE_STALE.label == "state stale"
    assert status_from_flags({"stale-hold", "holding"}) == Status.STATE_STALE
    for flags, words in ((("stale-state", "ref-wait"), "no fresh robot state"),
                         (("stale-hold",), "robot state back")):
        text = safety_text(read_safety(robot_flags=flags)).plain
        assert text.startswith("STATE STALE") and words in text and "the run ends" in text
    assert "STATE STALE" not in safety_text(read_safety(robot_flags=("ref-wait",))).plain


@pytest.mark.parametrize("seed", range(6))
def test_the_stale_brake_from_any_motion_stays_within_the_limits(tmp_path, seed):
    """Every joint cruising at a random speed up to its limit (away from its nearer position
    limit, with room to stop) when the state stops at a random period: the references slow
    down only, within the velocity and acceleration limits, come to rest and hold, and the run
    ends at the grace or, from a fast motion, when the brake is done."""
    from hubo_cli.drivers.stale_state import StateLost

    rng = np.random.default_rng(seed)
    clock = _Clock()
    with HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin",
                        clock=clock) as driver:
        q = driver.start().q_rad.copy()
        lower, upper = MODEL.lower_rad, MODEL.upper_rad
        direction = np.where(upper - q > q - lower, 1.0, -1.0)
        room = np.maximum(upper - q, q - lower) - 0.05
        v_max = MODEL.velocity_rad_s
        speed = rng.uniform(0.0, 1.0, q.size) * v_max
        speed = np.minimum(speed, np.sqrt(MODEL.acceleration_rad_s2 * room))  # room to stop
        cruise = int(rng.integers(3, 30))
        _silence(driver, clock, after=cruise)
        periods = 0
        with pytest.raises(StateLost) as info:
            for periods in range(1, 2000):  # noqa: B007 (counted for after the loop)
                q = q + direction * speed * PERIOD
                driver.send(q)
                driver.step()
    ref = np.array([f.ref_rad[[INDEX[n] for n in MODEL.joint_names]]
                    for f in read_ref_frames(driver.sink_path)])
    v = np.diff(ref, axis=0) / PERIOD
    assert np.all(np.abs(v) <= v_max * 1.001)
    brake = np.abs(v[cruise + 20:])  # from the brake's first period on
    assert np.all(np.diff(brake, axis=0) <= 1e-9)  # slowing down only
    a = np.diff(v, axis=0) / PERIOD
    assert np.all(np.abs(a) <= MODEL.acceleration_rad_s2 * 1.001)
    assert np.all(np.abs(v[-1]) < 1e-6)  # at rest at the end
    # from the brake's start: the grace, or the time to stop from the fastest joint if longer
    stop_s = np.max(speed / MODEL.acceleration_rad_s2 + MODEL.acceleration_rad_s2
                    / MODEL.jerk_rad_s3)
    held_s = (periods - cruise - 20) * PERIOD
    assert STALE_GRACE_S - 2 * PERIOD <= held_s <= max(STALE_GRACE_S, stop_s) + 3 * PERIOD
    assert not info.value.back


def test_the_summary_says_whether_the_daemons_sensors_were_judged(tmp_path):
    """Review 21: with --json the warning that --echo-sensors (or a dry run) turns the sensor
    checks off and leaves the force stops reading no force is not said; the summary says it,
    for the robot's channels as well as a dry run's file."""
    assert HardwareDriver(MODEL).summary_values()["hw_sensors_checked"] is True
    assert HardwareDriver(MODEL, echo_sensors=True).summary_values()["hw_sensors_checked"] \
        is False
    dry = HardwareDriver(MODEL, armed=True, sink="file", sink_path=tmp_path / "hubo-ref.bin")
    assert dry.summary_values()["hw_sensors_checked"] is False
