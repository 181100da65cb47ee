"""The hardware driver: arming, start-up delay, frame format, echo, safety latches, faults."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hubo_cli.drivers.hardware import (
    FLAG_HOLD,
    FLAG_SERVO_OFF,
    JOINT_COUNT,
    REF_FRAME,
    HardwareDriver,
    encode_state_frame,
    read_ref_frames,
)
from hubo_cli.errors import ConfigError, SafetyError
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

MODEL = load_model()
PERIOD = MODEL.control_period_s
INDEX = MODEL.hubo_ach["index"]
REB = MODEL.joint_names.index("REB")


@pytest.fixture
def hw(tmp_path):
    driver = HardwareDriver(MODEL, armed=True, run_dir=tmp_path)
    yield driver
    driver.close()


def _ramp(driver, joint: int, step_rad: float, periods: int):
    q = driver.read().q_rad.copy()
    for _ in range(periods):
        q[joint] += step_rad
        driver.send(q)
        state = driver.step()
    return q, state


def test_refuses_to_start_unless_armed(tmp_path):
    driver = HardwareDriver(MODEL, run_dir=tmp_path)
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
    assert frames[0].time_s == pytest.approx(0.8 + PERIOD)
    assert [f.seq for f in frames] == list(range(10))
    assert hw.sink_path.stat().st_size == 10 * REF_FRAME.size == 10 * 490


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
    assert np.all(frame.mode == 0) and frame.flags == 0


def test_echo_follows_with_the_hubo_ach_filter(hw):
    start = hw.start()
    q = start.q_rad.copy()
    q[REB] -= 0.004  # a small step, within the velocity limit
    hw.send(q)
    state = hw.step()
    L = MODEL.hubo_ach["ref_filter_length"]
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
    assert read_ref_frames(hw.sink_path)[-1].flags & FLAG_SERVO_OFF
    assert hw.send(q)[REB] == pytest.approx(q[REB])  # latched: nothing new is accepted
    q2 = q.copy()
    q2[REB] -= 0.001
    assert hw.send(q2)[REB] == pytest.approx(q[REB])
    hw.reset_servo()
    assert hw.send(q2)[REB] == pytest.approx(q2[REB])


def test_an_exception_inside_ends_in_a_hold_not_a_crash(hw, monkeypatch):
    start = hw.start()
    _ramp(hw, REB, -0.001, 5)

    def broken(*args):
        raise OSError("bridge went away")

    monkeypatch.setattr(hw.source, "feed", broken)
    state = hw.step()  # no exception
    assert "fault" in state.flags
    assert "bridge went away" in hw.fault_message
    q = state.q_rad.copy()
    q[REB] -= 0.001
    held = hw.send(q)
    assert held[REB] == pytest.approx(start.q_rad[REB] - 0.005)
    hw.stop()
    assert read_ref_frames(hw.sink_path)[-1].flags & FLAG_HOLD


def test_stop_writes_a_hold_frame(hw):
    hw.start()
    _ramp(hw, REB, -0.001, 3)
    hw.stop()
    frames = read_ref_frames(hw.sink_path)
    assert frames[-1].flags & FLAG_HOLD
    assert frames[-1].ref_rad[INDEX["REB"]] == pytest.approx(frames[-2].ref_rad[INDEX["REB"]])


def test_named_pipe_sink_works_without_a_reader(tmp_path):
    with HardwareDriver(MODEL, armed=True, run_dir=tmp_path, sink="fifo") as driver:
        driver.start()
        flags = set()
        for _ in range(300):  # more than a pipe buffer holds
            flags |= set(driver.step().flags)
        assert "sink-full" in flags
        assert "fault" not in flags
        reader = os.open(driver.sink_path, os.O_RDONLY | os.O_NONBLOCK)
        try:
            assert os.read(reader, REF_FRAME.size)[:4] == b"HREF"
        finally:
            os.close(reader)


def test_state_from_a_bridge_stream(tmp_path):
    source = tmp_path / "hubo-state.bin"
    pos = np.zeros(JOINT_COUNT)
    for i, name in enumerate(MODEL.joint_names):
        pos[INDEX[name]] = home_posture(MODEL)[i]
    ft = np.array([[0.1, 0.2, 1.0], [0.0, 0.0, 0.0], [1.5, -2.5, 190.0], [0.0, 0.0, 185.0]])
    quat = [np.cos(0.01), np.sin(0.01), 0.0, 0.0]
    source.write_bytes(encode_state_frame(0, 0.0, quat, [0.0, 0.1, 0.0], ft, pos))
    with HardwareDriver(MODEL, armed=True, run_dir=tmp_path, state_source=source,
                        stale_periods=5) as driver:
        state = driver.start()
        assert np.allclose(state.q_rad, home_posture(MODEL))
        assert np.allclose(state.ft["right-ankle"], [0, 0, 190.0, 1.5, -2.5, 0])
        assert state.tilt_rad()[0] == pytest.approx(0.02)
        assert "stale-state" in driver.step().flags  # the bridge wrote only one frame
        pos[INDEX["REB"]] -= 0.01
        with open(source, "ab") as stream:
            stream.write(encode_state_frame(1, 0.81, quat, [0, 0, 0], ft, pos))
        state = driver.step()
        assert "stale-state" not in state.flags
        assert state.q_rad[REB] == pytest.approx(home_posture(MODEL)[REB] - 0.01)


def test_bad_options_are_refused(tmp_path):
    with pytest.raises(ConfigError):
        HardwareDriver(MODEL, armed=True, run_dir=tmp_path, sink="socket")
    with pytest.raises(ConfigError):
        HardwareDriver(MODEL, armed=True, run_dir=tmp_path, ref_mode=2)
