"""The hardware driver on real ach channels, against the fake hubo-daemon (needs libach).

Skipped with the reason when libach cannot be loaded, and run apart from the other tests
(``realtime_support``).
Every channel is uniquely named and unlinked afterwards.
"""

from __future__ import annotations

import os
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from realtime_support import LIBACH_MARKS

from hubo_cli.drivers.ach import (
    ACH_MISSED_FRAME,
    ACH_OK,
    ACH_STALE_FRAMES,
    ACH_TIMEOUT,
    load_libach,
)
from hubo_cli.drivers.hardware import (
    STALE_AFTER_S,
    STALE_GRACE_S,
    HardwareDriver,
    hubo_ach_vector,
)
from hubo_cli.drivers.hubo_ach import REF_SIZE, STATE_SIZE, HuboRef, encode_ref
from hubo_cli.drivers.hubo_ach_daemon import FakeHuboDaemon
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture

pytestmark = list(LIBACH_MARKS)

MODEL = load_model()
INDEX = MODEL.hubo_ach["index"]
REB = MODEL.joint_names.index("REB")
L = MODEL.hubo_ach["ref_filter_length"]
SHM = Path("/dev/shm")


def _names() -> tuple[str, str]:
    tag = f"hubotest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    return f"{tag}-ref", f"{tag}-state"


def _shm_files(*names: str) -> list[Path]:
    return [SHM / f"achshm-{n}" for n in names if (SHM / f"achshm-{n}").exists()]


@pytest.fixture
def channels():
    names = _names()
    yield names
    lib = load_libach()
    for name in names:  # whatever a failing test left behind
        lib.unlink(name)


@pytest.fixture
def posture():
    """A start posture off home: the right elbow bent further, the neck yawed."""
    q = home_posture(MODEL)
    q[REB] -= 0.3
    pos = hubo_ach_vector(MODEL, q)
    pos[1] = 0.1  # NKY: a joint the model does not drive
    return pos


def test_channel_round_trip_timeout_and_unlink(channels):
    lib = load_libach()
    name = channels[0]
    lib.create(name, 8, REF_SIZE)
    assert _shm_files(name)
    with lib.open(name) as writer, lib.open(name) as reader:
        buffer = HuboRef()
        assert reader.get(buffer) == (ACH_STALE_FRAMES, 0)
        assert reader.get(buffer, wait_s=0.01)[0] == ACH_TIMEOUT
        writer.put(encode_ref(np.arange(42.0), np.ones(42), np.zeros(42)))
        status, size = reader.get(buffer, wait_s=1.0)
        assert status in (ACH_OK, ACH_MISSED_FRAME) and size == REF_SIZE
        assert buffer.ref[41] == 41.0 and buffer.mode[0] == 1
    lib.unlink(name)
    assert not _shm_files(name)


def test_start_from_the_measured_posture_without_references_for_0_8_s(channels, posture):
    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels).start() as daemon:
        with HardwareDriver(MODEL, armed=True, ach_ref=channels[0],
                            ach_state=channels[1]) as driver:
            state = driver.start()  # home_posture is asked for; the measured one wins
            assert daemon.stats.ref_frames == 0
            assert state.time_s == pytest.approx(0.8, abs=0.05)
            assert np.allclose(state.q_rad, posture[[INDEX[n] for n in MODEL.joint_names]])
            driver.step()
            frame = HuboRef()
            with lib.open(channels[0]) as ref:
                assert ref.get(frame)[1] == REF_SIZE
            assert np.allclose(np.array(frame.ref), posture)  # neck included: nothing jumps
        daemon.stop()
        daemon.period()  # read what is still on the channel
    assert daemon.stats.frame_sizes == {REF_SIZE: 2}  # the step's frame and the final hold
    assert not _shm_files(*channels)


@pytest.mark.parametrize("mode", ["filtered", "direct"])
def test_the_loop_closes_through_the_channels_within_the_filter_lag(channels, posture, mode):
    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels).start() as daemon:
        with HardwareDriver(MODEL, armed=True, ach_ref=channels[0],
                            ach_state=channels[1], ref_mode=mode) as driver:
            start = driver.start()
            q = start.q_rad.copy()
            commanded, measured = [], []
            for k in range(300):  # 0.5 s ramp at 0.4 rad/s, then 1 s of hold
                if k < 100:
                    q[REB] -= 0.002
                commanded.append(driver.send(q)[REB])
                state = driver.step()
                measured.append(state.q_rad[REB])
                assert state.flags == (), state.flags
            values = driver.log_values()
        daemon.stop()
        daemon.period()  # read what is still on the channel
    stats = daemon.stats
    assert stats.error == "" and stats.frame_sizes == {REF_SIZE: 301}  # and the final hold
    assert stats.missed_ref_frames == 0
    commanded, measured = np.array(commanded), np.array(measured)
    step = np.max(np.abs(np.diff(commanded)))
    assert step == pytest.approx(0.002)
    # a first-order filter lags a reference moving by at most `step` per period by at most
    # (L - 1) steps; allow 3 periods of transport between the processes' clocks
    lag = np.abs(measured - commanded)
    filter_lag = L - 1 if mode == "filtered" else 0  # direct: no filter
    assert np.max(lag) <= (filter_lag + 3) * step
    if mode == "filtered":
        assert np.max(lag) >= 0.5 * (L - 1) * step  # it does lag: the filter is applied
    assert abs(measured[-1] - commanded[-1]) < 0.02 * 0.2  # settled after 1 s of hold
    assert values["hw_ref_seq"] == 300 and values["hw_state_age_periods"] == 0
    assert not _shm_files(*channels)


def test_safety_latches_hold_on_the_channels(channels, posture):
    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels).start() as daemon:
        with HardwareDriver(MODEL, armed=True, ach_ref=channels[0],
                            ach_state=channels[1]) as driver:
            start = driver.start()
            q = start.q_rad.copy()
            q[REB] = np.nan  # NaN freezes the joint
            assert driver.send(q)[REB] == start.q_rad[REB]
            assert "nan-ref" in driver.step().flags
            driver.release_joints()
            jump = start.q_rad.copy()
            jump[REB] -= 0.05  # 10 rad/s: over-speed latches servo-off and holds
            assert driver.send(jump)[REB] == start.q_rad[REB]
            assert "servo-off" in driver.step().flags
            assert daemon.joints_rad[INDEX["REB"]] == pytest.approx(start.q_rad[REB])
            driver.reset_servo()

            driver.sink.channel.close()  # the channel goes away underneath: a hold, no crash
            assert "fault" in driver.step().flags
            assert "ach channel" in driver.fault_message
    assert not _shm_files(*channels)


def test_no_daemon_is_a_device_error_naming_it(channels):
    lib = load_libach()
    for name, size in zip(channels, (REF_SIZE, STATE_SIZE), strict=True):
        lib.create(name, 4, size)
    driver = HardwareDriver(MODEL, armed=True, ach_ref=channels[0], ach_state=channels[1],
                            start_timeout_s=0.05)
    with pytest.raises(Exception, match="no .* frame within") as info:
        driver.start()
    assert info.value.exit_code == 3 and "hubo-daemon" in info.value.hint
    driver.close()
    missing = HardwareDriver(MODEL, armed=True, ach_ref="hubotest-none-ref")
    with pytest.raises(Exception, match="ACH_ENOENT") as info:
        missing.start()
    assert info.value.exit_code == 3
    missing.close()


def test_the_fake_daemon_stops_on_a_frame_of_the_wrong_size(channels, posture):
    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels) as daemon, lib.open(channels[0]) as ref:
        ref.put(bytes(490))  # the old private frame
        daemon.period()
        assert "490 bytes" in daemon.stats.error


def test_stale_state_on_the_channels_brakes_holds_and_ends_even_if_it_comes_back(channels,
                                                                                 posture):
    """The daemon stops publishing (hung, its channels there): after 0.1 s the driver brakes
    and holds; the daemon comes back within the grace, but the motion does not resume and the
    run ends with :class:`StateLost` (exit 3)."""
    from hubo_cli.drivers.stale_state import StateLost

    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels).start() as daemon:
        with HardwareDriver(MODEL, armed=True, ach_ref=channels[0],
                            ach_state=channels[1]) as driver:
            q = driver.start().q_rad.copy()
            for _ in range(20):  # 0.4 rad/s
                q[REB] -= 0.002
                driver.send(q)
                driver.step()
            daemon.stop()
            stopped = time.monotonic()
            flags, refs = [], []
            with pytest.raises(StateLost) as info:
                for _ in range(1000):
                    q[REB] -= 0.002
                    refs.append(driver.send(q)[REB])
                    flags.append(driver.step().flags)
                    if "stale-state" in flags[-1] and daemon._thread is None:
                        stale_after = time.monotonic() - stopped
                        daemon.start()  # back within the grace
            ended = time.monotonic() - stopped
    assert info.value.back and info.value.exit_code == 3
    # 0.1 s by the wall clock after the last state read (the one in flight when the daemon
    # stopped is read a period later); generous upper bounds for a loaded machine
    assert 0.1 - 2 * MODEL.control_period_s <= stale_after < 0.5
    assert STALE_AFTER_S + STALE_GRACE_S - 2 * MODEL.control_period_s <= ended < 2.5
    assert any("stale-hold" in f for f in flags)
    speed = np.abs(np.diff(refs))
    onset = next(i for i, f in enumerate(flags) if "stale-state" in f)
    assert np.all(np.diff(speed[onset + 1:]) <= 1e-12)  # only slowing down, then held
    # at rest, then held to the end. How many periods are held depends on the machine's
    # timing (the grace is wall-clock time, and periods stretch while the driver waits for
    # the state): 19 or 20 in 9 runs here (round 30), and a clean clone's CI failed when it
    # asked for 20. So it asks for a few of them, not a count
    held = speed[onset + 1:] == 0.0
    assert held.any() and held[int(np.argmax(held)):].all()
    assert len(held) - int(np.argmax(held)) >= 5
    assert abs(refs[-1] - q[REB]) > 0.1  # the commands went on; the robot did not follow
    assert not _shm_files(*channels)


def test_left_over_channels_are_taken_over_and_removed(channels, posture):
    """Channels a killed daemon left (here of the old 504/3,632-byte layout) are replaced and
    removed at the end; channels a live daemon publishes are refused, untouched."""
    from hubo_cli.errors import DeviceError

    lib = load_libach()
    lib.create(channels[0], 4, 504)
    lib.create(channels[1], 4, 3632)
    with FakeHuboDaemon(lib, posture, *channels).start() as daemon:
        assert daemon.replaced == list(channels) and daemon.created == list(channels)
        with lib.open(channels[0]) as ref:
            ref.put(bytes(REF_SIZE))  # the new channel takes hubo_ref_t frames
        with pytest.raises(DeviceError, match="another daemon publishes") as info:
            FakeHuboDaemon(lib, posture, *channels)
        assert info.value.exit_code == 3
        assert _shm_files(*channels) and daemon.stats.error == ""
    assert not _shm_files(*channels)


def test_a_late_period_is_stamped_when_it_was_due_not_when_it_ran(channels, posture):
    """Round 30: a CI run's sim daemon, one period late, ran the next at once to catch up and
    stamped each state when it ran: two states 2 ms apart a whole 5 ms body step apart, which
    the driver read as a joint at 5.4 rad/s ("implausible measurement"). Each state is stamped
    with its period's scheduled start, so no two are closer in time than the body stepped."""
    from hubo_cli.drivers.hubo_ach_daemon import EchoBody

    stamps = []

    class SlowOnce(EchoBody):
        def advance(self, *args):
            super().advance(*args)
            if len(stamps) == 5:
                time.sleep(0.008)  # late by 3 ms of a 5 ms period: the next runs at once

        def state(self, time_s):
            stamps.append(time_s)
            return super().state(time_s)

    lib = load_libach()
    with FakeHuboDaemon(lib, posture, *channels) as daemon:
        daemon.body = SlowOnce(posture)
        stamps.clear()  # (the state published on opening)
        daemon.run(duration_s=0.1)
    steps_s = np.diff(stamps)
    assert len(steps_s) > 10 and steps_s.min() >= daemon.period_s - 1e-9, steps_s
