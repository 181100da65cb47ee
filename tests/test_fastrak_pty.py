"""The live reader against the emulator through a real pseudo-terminal (pyserial on the slave).

Waits are bounded by generous deadlines that only matter when something is broken; no assertion
depends on how fast the machine is.
"""

import os
import select
import termios
import time
import tty

import numpy as np
import pytest

from hubo_cli.errors import DeviceError, InputError
from hubo_cli.fastrak.capture import write_capture
from hubo_cli.fastrak.emulator import EmulatedFastrak, make_emulator
from hubo_cli.fastrak.opener import open_source
from hubo_cli.fastrak.reader import FastrakReader
from hubo_cli.fastrak.records import make_layout, scan
from hubo_cli.fastrak.track import PoseTrack

FAST = {"settle_s": 0.05, "command_gap_s": 0.0}
DEADLINE_S = 10.0


def collect(src, n):
    got = []
    deadline = time.monotonic() + DEADLINE_S
    while len(got) < n and time.monotonic() < deadline:
        got += src.read_until(0.0)
        time.sleep(0.005)
    return got


def wait_for(condition):
    deadline = time.monotonic() + DEADLINE_S
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.01)
    return condition()


def assert_matches_played(got, played, pos_tol, rot_tol):
    assert len(played) >= len(got) > 0
    for sample, (_, station, p, q) in zip(got, played, strict=False):
        assert sample.station == station
        np.testing.assert_allclose(sample.position_m, p, atol=pos_tol)
        from hubo_cli.geometry import quat_wxyz_to_matrix

        np.testing.assert_allclose(sample.T_tracker_sensor[:3, :3],
                                   quat_wxyz_to_matrix(q[None])[0], atol=rot_tol)


@pytest.mark.parametrize("stations,fmt,output_list,units,streaming", [
    (1, "binary", "2,11,1", "cm", False),
    (4, "binary", "2,11,1", "cm", False),
    (4, "ascii", "2,4,1", "in", False),
    (2, "binary", "52,61,50", "cm", True),
])
def test_reader_gets_the_poses_the_emulator_played(stations, fmt, output_list, units, streaming):
    emu = make_emulator(stations=stations, keep_played=10_000, streaming=streaming).start()
    try:
        with open_source(port=emu.port_name, fmt=fmt, output_list=output_list, units=units,
                         **FAST) as src:
            got = collect(src, 12 * stations)
            assert src.stations == tuple(range(1, stations + 1))
            assert src.stats.bad_bytes == 0
        played = emu.device.played_snapshot()
    finally:
        emu.close()
    assert len(got) >= 12 * stations
    order = [s.station for s in got]  # round robin over the stations, 120 records/s shared
    assert all(b == a % stations + 1 for a, b in zip(order, order[1:], strict=False))
    ascii_in = fmt == "ascii"
    assert_matches_played(got, played, 1.5e-4 if ascii_in else 1e-6, 2e-3 if ascii_in else 1e-6)
    times = [s.t_s for s in got]
    assert times == sorted(times)


def test_reader_reconfigures_a_unit_saved_in_streaming_mode():
    emu = make_emulator(stations=2, streaming=True).start()
    try:
        with open_source(port=emu.port_name, fmt="ascii", output_list="2,11,1", units="in",
                         **FAST) as src:
            assert len(collect(src, 10)) >= 10
            # the status reply (after 'c') showed the saved binary cm state; the reader then
            # set everything itself
            assert src.unit_status["binary"] and not src.unit_status["continuous"]
            assert src.unit_status["units"] == "cm"
        device = emu.device
        assert not device.binary and device.units == "in" and device.lists[1] == (2, 11, 1)
        seen = device.commands_seen
        assert seen[0] == "c" and "S" in seen and seen.index("C") > seen.index("F")
    finally:
        emu.close()


def test_status_letters_reach_the_samples():
    emu = make_emulator(stations=1).start()
    emu.device.status = "y"
    try:
        with open_source(port=emu.port_name, **FAST) as src:
            got = collect(src, 5)
            assert {s.status for s in got} == {"y"} and all(s.suspect for s in got)
            assert src.stats.status_letters["y"] >= 5
    finally:
        emu.close()


def test_live_capture_replays_to_the_same_samples(tmp_path):
    path = tmp_path / "live.fastrak"
    emu = make_emulator(stations=2).start()
    try:
        src = open_source(port=emu.port_name, capture=path, **FAST)
        live = collect(src, 30)
        src.close()
        live += src.read_until(0.0)
    finally:
        emu.close()
    with open_source(replay=path) as replay:
        replayed = replay.read_until(1e9)
        assert replay.info["port"] == emu.port_name
    assert len(replayed) == len(live)
    for a, b in zip(live, replayed, strict=True):
        assert a.station == b.station and a.t_s == b.t_s
        np.testing.assert_array_equal(a.T_tracker_sensor, b.T_tracker_sensor)


def test_closed_port_mid_stream_is_a_clear_error():
    emu = make_emulator(stations=1).start()
    src = open_source(port=emu.port_name, reconnect=False, **FAST)
    try:
        assert collect(src, 3)
        emu.close()  # the "adapter" goes away

        def raises():
            try:
                src.read_until(0.0)
            except DeviceError as exc:
                return exc
            return None

        assert wait_for(lambda: not src.alive)
        error = raises()
        while error is None:  # samples received before the loss come first
            error = raises()
        assert emu.port_name in str(error) and "stopped" in str(error)
        assert error.hint
    finally:
        src.close()


def test_reconnect_gives_up_with_a_clear_error():
    emu = make_emulator(stations=1).start()
    src = open_source(port=emu.port_name, reconnect_timeout_s=0.4, **FAST)
    try:
        assert collect(src, 3)
        emu.close()
        assert wait_for(lambda: not src.alive)
        with pytest.raises(DeviceError, match="reconnecting failed"):
            for _ in range(1000):
                src.read_until(0.0)
    finally:
        src.close()


def test_a_port_failing_while_configuring_is_a_device_error(monkeypatch):
    """pyserial's buffer resets raise termios.error, which is no OSError: a reconnect that
    opens a pty whose other end is just closing is one failed attempt (a DeviceError), not
    the end of the reader."""
    emu = make_emulator(stations=1).start()
    src = open_source(port=emu.port_name, **FAST)
    try:
        assert collect(src, 1)
        src.close()  # the port is free again; the emulator still answers

        def failing_probe(self, ser):
            raise termios.error(5, "Input/output error")

        monkeypatch.setattr(FastrakReader, "_probe", failing_probe)
        with pytest.raises(DeviceError, match="while configuring"):
            src._connect()
    finally:
        src.close()
        emu.close()


def test_silent_unit_is_stale_then_reconfigured():
    emu = make_emulator(stations=2).start()
    try:
        with open_source(port=emu.port_name, silence_timeout_s=0.3, **FAST) as src:
            assert collect(src, 4)
            emu.device.continuous = False  # the unit stops streaming (e.g. a stray 'c')
            assert wait_for(lambda: src.stats.reconnects == 1)
            got = collect(src, 10)
            assert len(got) >= 10
            last = max(s.t_s for s in got if s.station == 1)
            # judged up to when the reader last looked: fresh now, not at a time to come
            assert not src.is_stale(1, last) and not src.is_stale(1, src.now_s())
            assert src.looked_s() >= last
            assert src.is_stale(3, src.now_s())
    finally:
        emu.close()


def test_absent_port_and_silent_port_are_device_errors():
    with pytest.raises(DeviceError, match="no serial port") as info:
        open_source(port="/dev/does-not-exist-fastrak")
    assert "emulate --pty" in info.value.hint
    master, slave = os.openpty()  # a line with nobody answering
    tty.setraw(slave)
    try:
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match="no reply") as info:
            open_source(port=os.ttyname(slave), probe_timeout_s=0.2, **FAST)
        assert "--baud" in info.value.hint
        assert time.monotonic() - t0 < DEADLINE_S
    finally:
        os.close(master)
        os.close(slave)


def test_reader_rejects_bad_options_before_touching_the_port():
    with pytest.raises(InputError):
        open_source(port="/dev/null", output_list="2,11")
    with pytest.raises(InputError):
        open_source(port="/dev/null", units="mm")
    with pytest.raises(InputError):
        open_source(port="/dev/null", stations=[5])


def test_emulator_answers_the_reader_commands():
    dev = EmulatedFastrak(stations=(1, 2))
    status = dev.receive(b"S", 0.0)
    assert len(status) == 55 and status.startswith(b"21S3F0") and status.endswith(b"\r\n")
    assert dev.receive(b"l1\r", 0.0) == b"21l1100\r\n"
    assert dev.receive(b"l2,0\rl1\r", 0.0) == b"21l1000\r\n"
    assert dev.receive(b"l2,1\r", 0.0) == b""
    assert dev.receive(b"O1\r", 0.0) == b"21O2,4,1\r\n"
    assert dev.receive(b"O1,2,11,1\r", 0.0) == b""
    assert dev.receive(b"O1", 0.0) == b""  # a command split across reads waits for its CR
    assert dev.receive(b"\r", 0.0) == b"21O2,11,1\r\n"
    assert b"*ERROR*" in dev.receive(b"O1,2,99,1\r", 0.0)
    assert b"*ERROR*" in dev.receive(b"Z", 0.0)
    dev.receive(b"fu", 0.0)
    assert dev.receive(b"S", 0.0)[3:6] == b"3F3"
    polled = dev.receive(b"P", 0.0)  # one record per station, in each station's own list
    res1 = scan(polled, make_layout("binary", "2,11,1"), "cm", stations=(1,), final=True)
    res2 = scan(polled, make_layout("binary", "2,4,1"), "cm", stations=(2,), final=True)
    assert len(res1.batch) == 1 and len(res2.batch) == 1
    assert dev.next_record(0.0) == b""  # not continuous yet
    dev.receive(b"C", 0.0)
    assert dev.next_record(0.0)[:2] == b"01" and dev.next_record(0.0)[:2] == b"02"
    dev.receive(b"\x13", 0.0)  # ^S suspends output
    assert dev.next_record(0.0) == b""


def test_emulator_plays_a_recording(tmp_path):
    t = np.linspace(0, 1, 11)
    track = PoseTrack(t, np.c_[0.3 + 0.1 * t, 0 * t, 0 * t], np.tile([1.0, 0, 0, 0], (11, 1)))
    path = write_capture(tmp_path / "rec.fastrak", {3: track})
    with pytest.raises(InputError, match="no poses for station"):
        make_emulator(stations=2, from_file=path)
    emu = make_emulator(from_file=path, keep_played=1000).start()
    try:
        assert emu.device.plugged == (3,)
        with open_source(port=emu.port_name, **FAST) as src:
            got = collect(src, 10)
        played = emu.device.played_snapshot()
    finally:
        emu.close()
    assert {s.station for s in got} == {3}
    assert_matches_played(got, played, 1e-6, 1e-6)
    # played poses are the recording's, looped over its 1 s span
    start = track.start_s
    for t_s, _, p, _ in played[:10]:
        np.testing.assert_allclose(p, track.at(start + t_s % 1.0)[0][0], atol=1e-6)


def test_emulator_serves_a_serial_port():
    from hubo_cli.fastrak.emulator import FastrakEmulator, SerialEndpoint

    master, slave = os.openpty()  # the emulator opens the slave like a serial port
    tty.setraw(slave)
    emu = FastrakEmulator(EmulatedFastrak(stations=(1, 2)), SerialEndpoint(os.ttyname(slave)))
    emu.start()
    try:
        def read_until(n):
            got = b""
            deadline = time.monotonic() + DEADLINE_S
            while len(got) < n and time.monotonic() < deadline:
                if select.select([master], [], [], 0.1)[0]:  # never block past the deadline
                    got += os.read(master, 4096)
            return got

        os.write(master, b"S")
        assert read_until(55).startswith(b"21S3F0")
        os.write(master, b"C")
        layout = make_layout("ascii", "2,4,1")
        data = read_until(10 * layout.length)
        res = scan(data, layout, "in", final=True)
        assert len(res.batch) >= 9 and set(res.batch.station.tolist()) == {1, 2}
    finally:
        emu.close()
        os.close(master)
        os.close(slave)


def test_capture_write_failure_is_reported(tmp_path, monkeypatch):
    from hubo_cli.fastrak.capture import CaptureWriter

    emu = make_emulator(stations=1).start()
    try:
        src = open_source(port=emu.port_name, capture=tmp_path / "c.fastrak", **FAST)
        assert collect(src, 2)

        def disk_full(self, t_s, data):
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(CaptureWriter, "write", disk_full)
        with pytest.raises(InputError, match="No space left"):
            for _ in range(2000):
                src.read_until(0.0)
                time.sleep(0.005)
        src.close()
    finally:
        emu.close()


def test_a_live_tracker_without_a_mapped_station_is_refused():
    """Review 23: a tracker with a receiver at station 1 only, under the default map (station 2
    drives the left arm), ran with the left arm never moving and exit 0 without a word; a
    recording without a mapped station is refused. Now refused before anything moves, the
    port closed."""
    from hubo_cli.input.fastrak import FastrakInput

    emu = make_emulator(stations=1).start()
    try:
        src = open_source(port=emu.port_name, **FAST)
        with pytest.raises(DeviceError, match="no receiver at station 2") as info:
            FastrakInput(src)
        assert "--map 1=left-arm" in info.value.hint and "left-arm" in str(info.value)
        assert not src.alive
        with open_source(port=emu.port_name, **FAST) as again:
            assert FastrakInput(again, {1: "right-arm"}).hands == ("right",)
    finally:
        emu.close()


@pytest.mark.parametrize("fault", ["no-records", "noise-only"])
def test_a_unit_that_answers_but_sends_no_valid_record_is_lost(fault):
    """Review 23: a unit that answers its commands but streams nothing was "reconnected" after
    each silence (the probe answered) and one that streams only noise never counted as
    silent: the hands held for good and a run never ended (exit 0 at its duration). Now a
    reconnection counts once a record came, and garbage alone is silence: after the reconnect
    timeout the reader's DeviceError ends the run (exit 3)."""
    emu = make_emulator(stations=1).start()
    src = open_source(port=emu.port_name, silence_timeout_s=0.2, reconnect_timeout_s=0.4,
                      probe_timeout_s=0.2, first_record_timeout_s=0.2, **FAST)
    try:
        assert collect(src, 3)
        noise = bytes(range(256)).replace(b"0", b"")  # no record header can start in it
        emu.device.next_record = (lambda t_s: b"") if fault == "no-records" else (
            lambda t_s: noise[:40])
        with pytest.raises(DeviceError, match="reconnecting failed") as info:
            deadline = time.monotonic() + DEADLINE_S
            while time.monotonic() < deadline:
                src.read_until(0.0)
                time.sleep(0.01)
        assert "no valid record" in str(info.value) and src.stats.reconnects == 0
    finally:
        src.close()
        emu.close()


def test_a_unit_without_an_active_station_is_named_with_a_hint_the_command_has(monkeypatch):
    """Review 23: `hubo teleop --port` on a unit reporting no active station said "enable one
    with --stations 1", an option teleop does not have (`hubo record` has it)."""
    def no_station(self, command):
        if command[:1] == b"l" and b"," not in command:
            return b"21l0000\r\n"
        return EmulatedFastrak._terminated(self, command)

    monkeypatch.setattr(EmulatedFastrak, "_terminated", no_station, raising=True)
    emu = make_emulator(stations=1).start()
    try:
        with pytest.raises(DeviceError, match="reports no active station") as info:
            open_source(port=emu.port_name, **FAST)
        assert "hubo record --stations 1" in info.value.hint
        assert "or enable one with --stations" not in info.value.hint
    finally:
        emu.close()
