"""Recordings: raw captures and pose logs, their writers, replay through open_source, errors."""

import json

import numpy as np
import pytest

from hubo_cli.errors import InputError
from hubo_cli.fastrak.capture import (
    CHUNK_HEAD,
    MAGIC,
    capture_bytes,
    load_recording,
    parse_capture,
    poses_to_capture,
    read_pose_log,
    samples_batch,
    synthesize_chunks,
    write_capture,
    write_pose_log,
)
from hubo_cli.fastrak.opener import open_source
from hubo_cli.fastrak.source import PoseSample, ReplaySource
from hubo_cli.fastrak.track import PoseTrack
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.resources import data_file


def two_hand_tracks(duration_s=2.0):
    t = np.linspace(0.0, duration_s, 41)
    right = np.c_[0.4 + 0.05 * np.sin(t), 0.2 + 0.05 * np.cos(t), 0.1 + 0 * t]
    left = np.c_[0.4 + 0 * t, -0.2 + 0.02 * t, 0.1 + 0.01 * t]
    yaw = 0.3 * t
    q_right = np.c_[np.cos(yaw / 2), 0 * t, 0 * t, np.sin(yaw / 2)]
    q_left = np.tile([1.0, 0, 0, 0], (t.size, 1))
    return {1: PoseTrack(t, right, q_right), 2: PoseTrack(t, left, q_left)}


@pytest.mark.parametrize("fmt,output_list,units", [
    ("binary", "2,11,1", "cm"), ("binary", "52,61,50", "cm"), ("ascii", "2,4,1", "in"),
    ("ascii", "2,11,1", "cm")])
def test_capture_replays_the_written_poses_at_120_hz(tmp_path, fmt, output_list, units):
    tracks = two_hand_tracks()
    path = write_capture(tmp_path / "hands.fastrak", tracks, fmt=fmt, output_list=output_list,
                         units=units)
    with open_source(replay=path) as src:
        assert isinstance(src, ReplaySource)
        samples = src.read_until(1e9)
        assert src.done and src.stats.bad_bytes == 0
    assert len(samples) == 241  # 2 s at 120 records/s, both stations sharing them
    stations = [s.station for s in samples]
    assert stations[:4] == [1, 2, 1, 2]
    t = np.array([s.t_s for s in samples])
    np.testing.assert_allclose(np.diff(t), 1 / 120, atol=1e-9)
    tol = 1.5e-4 if fmt == "ascii" else 1e-6  # ASCII keeps 0.01 in (0.254 mm) steps
    for s in samples[::17]:
        p, q = tracks[s.station].at(s.t_s - t[0])
        np.testing.assert_allclose(s.position_m, p[0], atol=tol)
        np.testing.assert_allclose(s.T_tracker_sensor[:3, :3], quat_wxyz_to_matrix(q)[0],
                                   atol=5e-4 if fmt == "ascii" else 1e-6)


def test_read_until_releases_samples_by_receive_time(tmp_path):
    path = write_capture(tmp_path / "c.fastrak", two_hand_tracks(1.0))
    src = open_source(replay=path)
    first = src.read_until(src.start_s + 0.1)
    assert first and all(s.t_s <= src.start_s + 0.1 for s in first)
    assert src.read_until(src.start_s + 0.1) == []  # nothing twice
    rest = src.read_until(src.end_s)
    assert len(first) + len(rest) == src.stats.good_records and src.done
    assert src.last_seen_s(1) == max(s.t_s for s in rest if s.station == 1)
    assert src.last_seen_s(3) is None and src.is_stale(3, src.end_s)
    assert not src.is_stale(1, src.end_s) and src.is_stale(1, src.end_s + 0.3)
    assert src.is_stale(1, src.end_s + 0.06, timeout_s=0.05)
    src.rewind()
    assert len(src.read_until(src.end_s)) == src.stats.good_records


def test_pose_log_round_trip_and_same_samples_as_capture(tmp_path):
    path = write_capture(tmp_path / "c.fastrak", two_hand_tracks(0.5))
    from_capture = open_source(replay=path).read_until(1e9)
    log = write_pose_log(tmp_path / "c.csv", from_capture)
    header = log.read_text().splitlines()[0]
    assert header == "t_s,station,x_m,y_m,z_m,qw,qx,qy,qz,status"
    with open_source(replay=log) as src:
        from_log = src.read_until(1e9)
        assert src.info["kind"] == "pose-log"
    assert len(from_log) == len(from_capture)
    for a, b in zip(from_capture, from_log, strict=True):
        assert a.station == b.station and a.status == b.status
        assert abs(a.t_s - b.t_s) < 1e-6
        np.testing.assert_allclose(a.T_tracker_sensor, b.T_tracker_sensor, atol=2e-6)


def test_status_letters_survive_capture_and_pose_log(tmp_path):
    chunks = synthesize_chunks(two_hand_tracks(0.2), status="x")
    blob = poses_to_capture(two_hand_tracks(0.2))
    cap = parse_capture(blob)
    # same header, records with status 'x'
    from hubo_cli.fastrak.capture import capture_bytes
    path = tmp_path / "x.fastrak"
    path.write_bytes(capture_bytes(cap.header, chunks))
    rec = load_recording(path)
    assert rec.stats.status_letters == {"x": len(chunks)}
    samples = open_source(replay=path).read_until(1e9)
    assert {s.status for s in samples} == {"x"} and all(s.suspect for s in samples)
    log = write_pose_log(tmp_path / "x.csv", samples)
    assert {s.status for s in open_source(replay=log).read_until(1e9)} == {"x"}


def test_writer_accepts_pose_samples_and_tuples(tmp_path):
    T = np.eye(4)
    T[:3, 3] = [0.3, 0.1, 0.0]
    samples = [PoseSample(1, T, " ", 0.0), PoseSample(1, T, " ", 1.0)]
    blob_a = poses_to_capture(samples)
    blob_b = poses_to_capture([(0.0, 1, T), (1.0, 1, T)])
    assert blob_a == blob_b
    batch, bad = parse_capture(blob_a).decode()
    assert len(batch) == 121 and bad == 0
    np.testing.assert_allclose(batch.position_m, np.tile([0.3, 0.1, 0.0], (121, 1)), atol=1e-7)
    assert len(samples_batch(samples)) == 2


def test_truncated_capture_keeps_what_is_there(tmp_path):
    blob = poses_to_capture(two_hand_tracks(1.0))
    path = tmp_path / "cut.fastrak"
    path.write_bytes(blob[:-50])
    rec = load_recording(path)
    assert rec.info["truncated"] and 0 < rec.stats.good_records < 121


def test_capture_with_garbage_between_chunks_resynchronises(tmp_path):
    cap = parse_capture(poses_to_capture(two_hand_tracks(0.5)))
    chunks = []
    ends = [0, *cap.chunk_ends.tolist()]
    for i, (a, b) in enumerate(zip(ends[:-1], ends[1:], strict=True)):
        data = cap.data[a:b]
        if i % 10 == 3:
            data = b"\x00\xffgarbage0" + data[:-5]  # noise plus a record cut short
        chunks.append((float(cap.chunk_times[i]), data))
    from hubo_cli.fastrak.capture import capture_bytes

    path = tmp_path / "noisy.fastrak"
    path.write_bytes(capture_bytes(cap.header, chunks))
    rec = load_recording(path)
    lost = sum(1 for i in range(len(chunks)) if i % 10 == 3)
    assert rec.stats.good_records == len(chunks) - lost
    assert rec.stats.bad_bytes > 0


@pytest.mark.parametrize("content,message", [
    (b"", "is empty"),
    (b"\x00\x01\x02\xff" * 10, "neither a raw capture"),
    ("t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n".encode("utf-16"), "UTF-16 text"),
    (MAGIC + b"{not json\n", "not valid JSON"),
    (MAGIC + b'{"format": "binary"}\n', "header lacks units"),
    (MAGIC + b'{"format": "binary", "output_list": [2, 11], "units": "cm", '
             b'"stations": [1]}\n', "terminator"),
    (MAGIC + b'{"format": "binary", "output_list": [2, 11, 1], "units": "mm", '
             b'"stations": [1]}\n', "units"),
    (MAGIC + b'{"format": "binary", "output_list": [2, 11, 1], "units": "cm", '
             b'"stations": [1]}\n' + CHUNK_HEAD.pack(0.0, 7) + b"garbage",
     "no valid FASTRAK records"),
    (MAGIC + b'{"format": "binary", "output_list": [2, 11, 1], "units": "cm", '
             b'"stations": [1]}\n' + b"\x00" * 12 + b"garbage", "claims 0 bytes"),
    (b"t_s,station,x_m\n1,2,3\n", "missing column"),
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz,status\n0,1,0,0,0,1,0,0,0,\n0.1,1,a,0,0,1,0,0,0,\n",
     "line 3"),
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz,status\n0,1,0,0,0,1,0,0,0,\n0.1,1,0,0,0,1,0,0,0,\x00\n",
     "line 3: status '.x00' is not a FASTRAK status"),  # (main: used as a healthy record)
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n0,7,0,0,0,1,0,0,0\n", "station"),
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n0,1,0,0,0,0,0,0,0\n", "zero quaternion"),
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n0,1,0,0,0,1,0,0,0\n0.1,1,0,0,0,0.2,0,0,0\n",
     "line 3: the quaternion's norm is 0.2, not 1"),  # review 19: normalised without a word
    (b"t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n", "no rows"),
    (MAGIC + b"[" * 5000 + b"]" * 5000 + b"\n", "nested too deeply"),  # was RecursionError
])
def test_garbled_recordings_are_input_errors(tmp_path, content, message):
    path = tmp_path / "bad.rec"
    path.write_bytes(content)
    with pytest.raises(InputError, match=message) as info:
        open_source(replay=path)
    assert info.value.hint


def test_missing_recording_and_bad_arguments(tmp_path):
    with pytest.raises(InputError, match="no such recording") as info:
        open_source(replay=tmp_path / "nope.fastrak")
    assert "trajectories" in info.value.hint
    with pytest.raises(InputError, match="folder"):
        open_source(replay=tmp_path)
    with pytest.raises(InputError, match="no recording given"):  # was ". is a folder"
        open_source(replay="")
    with pytest.raises(InputError, match="exactly one"):
        open_source()
    with pytest.raises(InputError, match="exactly one"):
        open_source(replay="a", port="b")


def test_station_filter(tmp_path):
    path = write_capture(tmp_path / "c.fastrak", two_hand_tracks(0.5))
    samples = open_source(replay=path, stations=[2]).read_until(1e9)
    assert {s.station for s in samples} == {2}
    with pytest.raises(InputError, match="no records for station"):
        open_source(replay=path, stations=[4])


def test_capture_header_is_one_json_line(tmp_path):
    blob = poses_to_capture(two_hand_tracks(0.1), fmt="ascii", output_list="2,4,1", units="in")
    lines = blob.split(b"\n", 2)
    assert lines[0] + b"\n" == MAGIC
    header = json.loads(lines[1])
    assert header["format"] == "ascii" and header["output_list"] == [2, 4, 1]
    assert header["units"] == "in" and header["stations"] == [1, 2] and header["baud"] == 115200


def test_pose_log_reader_accepts_comments_and_no_status(tmp_path):
    path = tmp_path / "hand.csv"
    path.write_text("# a hand-made log\nt_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n"
                    "0.0,1,0.1,0.2,0.3,1.04,0,0,0\n0.5,1,0.1,0.2,0.4,1,0,0,0\n")
    batch = read_pose_log(path)  # a norm within QUAT_NORM_TOL of 1 is a rounded quaternion
    assert len(batch) == 2 and batch.status.tolist() == [32, 32]
    assert batch.t_s.tolist() == [0.0, 0.5]
    np.testing.assert_allclose(batch.quat_wxyz[0], [1, 0, 0, 0])
    np.testing.assert_allclose(batch.position_m[0], [0.1, 0.2, 0.3])


def test_pose_log_with_a_byte_order_mark_and_huge_quaternions(tmp_path):
    """A spreadsheet's "CSV UTF-8" starts with a byte-order mark (it was 'missing column(s)
    t_s'); a quaternion of components 1e300 (its squares overflowed: a zero quaternion, then a
    division by zero, an internal error) is refused by its norm (review 19: norms of 0.2 to 5
    were normalised without a word), an input error, exit 2."""
    path = tmp_path / "sheet.csv"
    path.write_bytes(b"\xef\xbb\xbft_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n"
                     b"0.0,1,0.1,0.2,0.3,1,0,0,0\n0.5,1,0.1,0.2,0.4,0.5,-0.5,0.5,0.5\n")
    batch = read_pose_log(path)
    np.testing.assert_allclose(quat_wxyz_to_matrix(batch.quat_wxyz[0]), np.eye(3))
    path.write_bytes(b"\xef\xbb\xbft_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n"
                     b"0.0,1,0.1,0.2,0.3,1e300,0,0,0\n0.5,1,0.1,0.2,0.4,1e308,-1e308,0,0\n")
    with pytest.raises(InputError, match="line 2: the quaternion's norm is inf, not 1"):
        read_pose_log(path)
    track = PoseTrack([0.0, 1.0], np.zeros((2, 3)), [[1e300, 0, 0, 0], [0, 0, 0, 2]])
    np.testing.assert_allclose(track.quat_wxyz, [[1, 0, 0, 0], [0, 0, 0, 1]])



@pytest.mark.parametrize("scale, unit", [(100, "cm"), (1000, "mm")])
def test_a_pose_log_in_centimetres_or_millimetres_is_refused_naming_the_units(tmp_path, scale,
                                                                              unit):
    """Review 21: the shipped sample's first 3 s written in centimetres drove both arms to
    their reach limits for 8 s (ideal driver) and ended "202 of 360 samples were rejected",
    exit 2; in millimetres "no operator input". A pose beyond the FASTRAK's 3 m (the live
    reader drops such a record as garbled) is refused at load, the line and the units named;
    the shipped samples reach 0.65 m, generated streams (seeds 0-12345 at 2 m/s) 0.65 m. A
    far pose among sound ones (x = 1e6 m from 1 s: main replayed it, re-centred on it) too."""
    sample = read_pose_log(data_file("trajectories", "two-hand-free.csv"))
    rows = "".join(f"{float(t)!r},{st},{x * scale!r},{y * scale!r},{z * scale!r},1,0,0,0\n"
                   for t, st, (x, y, z) in zip(sample.t_s[:40], sample.station[:40].tolist(),
                                               sample.position_m[:40].tolist(), strict=True))
    path = tmp_path / f"{unit}.csv"
    path.write_text("t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n" + rows)
    with pytest.raises(InputError, match=r"line 2: a pose at \[.*\] m, beyond a FASTRAK's 3 m; "
                                         r"40 of the 40 rows") as refused:
        read_pose_log(path)
    assert "centimetres or millimetres" in refused.value.hint
    path.write_text("t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n0,1,0.3,0,0,1,0,0,0\n"
                    "0.01,1,2.99,0,-3,1,0,0,0\n0.02,1,1e6,0,0,1,0,0,0\n")
    with pytest.raises(InputError, match=r"line 4: a pose at \[1000000.0, 0.0, 0.0\] m.* 1 of "
                                         r"the 3 rows"):
        read_pose_log(path)

def test_replay_ignores_live_port_options(tmp_path):
    path = write_capture(tmp_path / "c.fastrak", two_hand_tracks(0.2))
    with open_source(replay=path, port=None, baud=9600, fmt="ascii", units="in") as src:
        assert src.info["format"] == "binary" and src.info["units"] == "cm"
        assert len(src.read_until(1e9)) == src.stats.good_records


def _timed_pose_log(path, times):
    rows = "".join(f"{float(t)!r},1,0.1,0.2,0.3,1,0,0,0\n" for t in times)
    path.write_text("t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n" + rows)
    return path


def _two_station_log(path, t1_s, t2_s):
    """A pose log of stations 1 and 2, each row's x its station's row number (mm), written
    row by row in the order of the two lists zipped (station 1's row, then station 2's)."""
    rows = "".join(f"{float(t)!r},{s},{k / 1000!r},0.2,0.3,1,0,0,0\n"
                   for k, pair in enumerate(zip(t1_s, t2_s, strict=True))
                   for s, t in ((1, pair[0]), (2, pair[1])))
    path.write_text("t_s,station,x_m,y_m,z_m,qw,qx,qy,qz\n" + rows)
    return path


def test_stations_stamped_each_by_itself_are_merged_by_time(tmp_path):
    """Two stations of a 120 Hz tracker whose rows a recorder stamped each by itself: station
    2's times up to 6 ms earlier than station 1's row before it (refused as a time going back
    until round 26). Read merged by time, each station's rows in their own order; a station
    whose own time goes back, or stations more than 0.05 s apart, are still refused."""
    rng = np.random.default_rng(26)
    t1 = ROWS + rng.uniform(0.0, 0.002, len(ROWS))
    t2 = ROWS + rng.uniform(-0.006, 0.002, len(ROWS))
    assert (t2 < t1).any()
    batch = read_pose_log(_two_station_log(tmp_path / "jitter.csv", t1, t2))
    assert np.all(np.diff(batch.t_s) >= 0.0)
    shift_s = batch.t_s[0] - min(t1[0], t2[0])  # counted from the first row if before 0
    for s, times in ((1, t1), (2, t2)):
        mine = batch.station == s
        assert batch.t_s[mine] == pytest.approx(times + shift_s, abs=1e-12)
        assert np.array_equal(batch.position_m[mine, 0], np.arange(len(ROWS)) / 1000)
    back = t2.copy()
    back[60] = back[58]  # station 2's row 60 earlier than its row 59
    with pytest.raises(InputError, match=r"line 123: t_s .* earlier than station 2's row "
                                         r"before it") as info:
        read_pose_log(_two_station_log(tmp_path / "back.csv", ROWS, np.r_[ROWS[:1] - 0.004,
                                                                          back[1:]]))
    assert "0.05 s of each other" in info.value.hint
    with pytest.raises(InputError, match=r"line 3: t_s -0.056 s is earlier than the row before "
                                         r"it \(0.004 s\)"):
        read_pose_log(_two_station_log(tmp_path / "apart.csv", ROWS, ROWS - 0.06))


def _timed_capture(path, retime):
    """A 3 s capture of two stations (9 kB) with its chunk times changed by
    ``retime(k, t_s)``."""
    cap = parse_capture(poses_to_capture(two_hand_tracks(3.0)))
    starts = np.r_[0, cap.chunk_ends[:-1]]
    chunks = [(retime(k, t), cap.data[a:b]) for k, (t, a, b) in
              enumerate(zip(cap.chunk_times, starts, cap.chunk_ends, strict=True))]
    path.write_bytes(capture_bytes(cap.header, chunks))
    return path


ROWS = 0.004 + np.arange(120) / 120.0  # 1 s of a station at 120 Hz, as recorded


@pytest.mark.parametrize("make,start_s,error", [
    # a pose log's times as time.time() writes them, negative, or far out: counted from the
    # first row (they stood 41 s then "no operator input", or ended at once, exit 0)
    (lambda p: _timed_pose_log(p, ROWS), 0.004, None),
    (lambda p: _timed_pose_log(p, 1764500000.0 + ROWS), 0.0, None),
    (lambda p: _timed_pose_log(p, ROWS - 100.0), 0.0, None),
    (lambda p: _timed_pose_log(p, 30.0 + ROWS), 0.0, None),  # rows cut from a recording
    (lambda p: _timed_pose_log(p, 1e12 + ROWS), 0.0, None),
    (lambda p: _timed_pose_log(p, 1e16 + ROWS), None, "too large to tell apart"),
    (lambda p: _timed_pose_log(p, 1.0 + ROWS * 2e-6), None, "120 records within 1.98e-06 s"),
    (lambda p: _timed_pose_log(p, np.r_[ROWS[:60], ROWS[60:] - 0.5]), None,
     r"line 62: t_s 0.004 s is earlier than the row before it \(0.4956"),  # was re-sorted
    (lambda p: _timed_pose_log(p, np.zeros(3)), None, "every row has the same time"),
    # round 18: one station's rows at one time reach the robot as one instant; 30 in a row (a
    # late serial read's burst, as a decoded capture stamps it) replay as recorded, 31 do not
    # (the review's log with 3 s of rows at t = 1.0 s replayed 1 s, exit 0)
    (lambda p: _timed_pose_log(p, np.r_[ROWS[:40], np.full(30, ROWS[40]), ROWS[70:]]), 0.004,
     None),
    (lambda p: _timed_pose_log(p, np.r_[ROWS[:40], np.full(31, ROWS[40]), ROWS[71:]]), None,
     r"lines 42-72: station 1's rows all have t_s 0.3373\d* s \(31 in a row"),
    # a raw capture agrees
    (lambda p: _timed_capture(p, lambda k, t: 1764500000.0 + t), 0.0, None),
    (lambda p: _timed_capture(p, lambda k, t: t - 100.0), 0.0, None),
    (lambda p: _timed_capture(p, lambda k, t: 0.0), None, "every chunk has the same time"),
    (lambda p: _timed_capture(p, lambda k, t: 1e16 + t), None, "too large to tell apart"),
    (lambda p: _timed_capture(p, lambda k, t: 1.0 + t * 1e-6), None, "bytes within"),
])
def test_recording_times_count_from_the_start_or_are_refused(tmp_path, make, start_s, error):
    path = make(tmp_path / "rec")
    if error is not None:
        with pytest.raises(InputError, match=error) as info:
            load_recording(path)
        assert info.value.hint and "\n" not in info.value.message
        return
    t_s = load_recording(path).batch.t_s
    assert t_s[0] == pytest.approx(start_s, abs=1e-9)
    span_s = 3.0 if path.read_bytes().startswith(MAGIC) else 1.0
    assert span_s - 0.02 < t_s[-1] - t_s[0] < span_s + 0.02  # the recording's own, kept


def test_the_emulator_refuses_a_recording_no_tracker_could_send(tmp_path):
    """A position beyond the tracker's range went out as inf in binary records, with numpy's
    overflow warning (round 15)."""
    from hubo_cli.fastrak.emulator import RecordedMotion

    path = _timed_pose_log(tmp_path / "far.csv", ROWS)
    lines = path.read_text().splitlines()
    lines[40] = lines[40].replace("0.1,0.2", "1e300,0.2", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"line 41: a pose at \[1e\+300, 0.2, 0.3\] m, beyond a "
                                         r"FASTRAK's 3 m; 1 of the 120 rows"):
        RecordedMotion.from_file(path)
    assert RecordedMotion.from_file(_timed_pose_log(tmp_path / "ok.csv", ROWS)).stations == (1,)


@pytest.mark.parametrize("separator", ["\u2028", "\x0c", "\x85", "\x1e"])
def test_a_comment_line_stays_a_comment_whatever_unicode_it_holds(tmp_path, separator):
    """Review 23: lines were split with str.splitlines, which also ends a line at a form feed,
    U+0085, U+2028 and others: the rest of a comment line after one was read as a pose row
    (here a pose 0.5 m off among the sample's) and later lines were numbered unlike an
    editor's. Now only CR LF, LF and CR end a line."""
    lines = data_file("trajectories", "two-hand-free.csv").read_text().splitlines()[:41]
    far = lines[20].split(",")
    far[2] = f"{float(far[2]) + 0.5:.6f}"
    text = "\n".join(lines[:20] + ["# a note" + separator + ",".join(far)] + lines[20:]) + "\n"
    path = tmp_path / "comment.csv"
    path.write_text(text, encoding="utf-8")
    batch = read_pose_log(path)
    assert len(batch) == 40
    assert np.abs(batch.position_m[:, 0]).max() < 0.4
    bad = text.replace(lines[30], lines[30].replace(",", ";", 1))
    path.write_text(bad, encoding="utf-8")
    with pytest.raises(InputError, match="line 32: "):  # the editor's line: header 1, rows 2-
        read_pose_log(path)
