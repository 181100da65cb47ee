"""The input device contract, run against every device: a FASTRAK recording (raw capture and
pose log), a live FASTRAK (the emulator on a pty), and generated operator streams.

Every device delivers hand poses (``right``/``left``, 4x4 in the operator's frame) stamped with
their own sample time, oldest first and each once; judges staleness by those times; and is a
context manager. The generator's own promises (reproducible, speed cap, turn limit, clutch,
reach) are checked over seeds drawn here, and its pose log replays as the stream itself.
"""

import time

import numpy as np
import pytest

from hubo_cli.errors import InputError
from hubo_cli.fastrak.capture import write_capture
from hubo_cli.fastrak.emulator import make_emulator
from hubo_cli.input import HANDS, HandPose, InputDevice
from hubo_cli.input.fastrak import open_fastrak, tracker_pose
from hubo_cli.input.generated import generated_input, write_stream_pose_log
from hubo_cli.input.opener import open_input
from hubo_cli.input.operator_stream import START_M, StreamSettings, operator_stream
from hubo_cli.resources import data_file

FAST = {"settle_s": 0.05, "command_gap_s": 0.0}
SEEDS = np.random.default_rng(34).integers(0, 2**31, 4).tolist()  # drawn, not picked


def _capture_of_stream(path, seed):
    """A raw FASTRAK capture of the generated stream of ``seed`` (stations 1 right, 2 left)."""
    poses = [(float(t), 1 if s.hand == "right" else 2, tracker_pose(T))
             for s in operator_stream(seed, StreamSettings(duration_s=4.0))
             for t, T in zip(s.t_s, s.T_operator_hand, strict=True)]
    return write_capture(path, poses)


def _recorded_devices(tmp_path):
    yield "shipped capture", open_fastrak(replay=data_file("trajectories", "two-hand-free.fastrak"))
    yield "shipped pose log", open_fastrak(replay=data_file("trajectories", "two-hand-free.csv"))
    yield "generated capture", open_fastrak(replay=_capture_of_stream(tmp_path / "g.fastrak",
                                                                      SEEDS[0]))
    yield "generated pose log", open_fastrak(replay=write_stream_pose_log(
        tmp_path / "g.csv", SEEDS[1], StreamSettings(duration_s=4.0)))
    yield "generated", generated_input(SEEDS[2], StreamSettings(duration_s=4.0))
    yield "generated (opener)", open_input(generate_seed=SEEDS[3],
                                           stream=StreamSettings(duration_s=4.0))


def _check_poses(poses, hands, until_s=None):
    for p in poses:
        assert isinstance(p, HandPose) and p.hand in hands
        T = p.T_operator_hand
        assert T.shape == (4, 4) and np.isfinite(T).all()
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6)
        assert np.allclose(T[3], [0, 0, 0, 1])
        if until_s is not None:
            assert p.t_s <= until_s + 1e-12


def _behaves(device: InputDevice, step_s: float, reads: int, live: bool) -> None:
    """The contract's behaviour over ``reads`` reads ``step_s`` apart on the caller's clock."""
    with device as d:
        assert d is device and set(d.hands) <= set(HANDS) and d.hands
        assert isinstance(d.info, dict) and "kind" in d.info and isinstance(d.stats(), dict)
        assert all(d.is_stale(h, 0.0) for h in d.hands)  # nothing delivered yet
        newest: dict[str, float] = {}
        t = 0.0 if live else getattr(d, "start_s", 0.0)
        for _ in range(reads):
            t += step_s
            if live:
                time.sleep(step_s)
            poses = d.read_until(t)
            _check_poses(poses, d.hands, None if live else t)
            for p in poses:  # oldest first, each once: times never go back per hand
                assert p.t_s >= newest.get(p.hand, -np.inf)
                newest[p.hand] = p.t_s
        assert set(newest) == set(d.hands), "every hand delivered a pose"
        now = d.now_s() if live else t
        for hand, last in newest.items():
            assert d.last_seen_s(hand) == last
            # judged by the poses' own times: fresh now, stale once the timeout has passed
            assert not d.is_stale(hand, last + 0.1, timeout_s=0.25)
            if not live:  # live: judged up to the reader's last look at its port (it has
                # read nothing newer), tested with a silent unit in test_fastrak_pty
                assert d.is_stale(hand, last + 0.3, timeout_s=0.25)
            assert last <= now + 1e-9
    device.close()  # idempotent


def test_recorded_and_generated_devices_keep_the_contract(tmp_path):
    for name, device in _recorded_devices(tmp_path):
        try:
            _behaves(device, step_s=0.05, reads=40, live=False)
        except AssertionError as exc:
            raise AssertionError(f"{name}: {exc}") from exc
        # a recording ends: everything delivered once, then nothing
        with device as d:
            pass
    with generated_input(SEEDS[0], StreamSettings(duration_s=2.0)) as d:
        everything = d.read_until(1e9)
        assert d.done and d.recorded_s == pytest.approx(2.0) and not d.read_until(1e9)
        assert len(everything) == 2 * (int(2.0 * 120) + 1)


def test_a_live_fastrak_keeps_the_contract():
    emu = make_emulator(stations=2).start()
    try:
        _behaves(open_fastrak(port=emu.port_name, **FAST), step_s=0.02, reads=15, live=True)
    finally:
        emu.close()


def test_recordings_name_hands_not_stations(tmp_path):
    capture = data_file("trajectories", "two-hand-free.fastrak")
    with open_fastrak(replay=capture, station_arm={2: "right-arm"}) as d:  # station 2 drives
        assert d.hands == ("right",)
        assert {p.hand for p in d.read_until(1.0)} == {"right"}
    with pytest.raises(InputError, match="has no station 3"):
        open_fastrak(replay=capture, station_arm={3: "right-arm"})
    with pytest.raises(InputError, match="exactly one"):
        open_input(replay=capture, generate_seed=1)


def test_the_tracker_frame_becomes_the_operators():
    """A FASTRAK's z points down, y right: a sensor moved down and to the operator's right is a
    hand moved down (-z) and right (-y) in the operator's frame; turns follow the same way."""
    from hubo_cli.geometry import rpy_to_matrix
    from hubo_cli.input.fastrak import operator_pose
    from hubo_cli.kinematics.poses import make_transform

    T = operator_pose(make_transform(rpy_to_matrix(0, 0, 0.3), [0.1, 0.02, 0.05]))
    assert np.allclose(T[:3, 3], [0.1, -0.02, -0.05])
    assert np.allclose(T[:3, :3], rpy_to_matrix(0, 0, -0.3))
    assert np.allclose(tracker_pose(T), make_transform(rpy_to_matrix(0, 0, 0.3),
                                                       [0.1, 0.02, 0.05]))


@pytest.mark.parametrize("max_speed", [0.25, 0.6])
def test_generated_streams_keep_their_promises(max_speed):
    settings = StreamSettings(duration_s=30.0, max_speed_m_s=max_speed)
    clutched, far = 0, 0
    for seed in SEEDS:
        streams = operator_stream(seed, settings)
        again = operator_stream(seed, settings)
        for s, s2 in zip(streams, again, strict=True):
            assert np.array_equal(s.T_operator_hand, s2.T_operator_hand)  # reproducible
            assert np.allclose(np.diff(s.t_s), 1 / 120) and s.t_s[-1] == pytest.approx(30.0)
            assert s.speed_m_s().max() <= max_speed * (1 + 1e-6)
            assert s.speed_m_s().max() >= 0.5 * max_speed  # it does move that fast
            R = s.T_operator_hand[:, :3, :3]
            turn = np.degrees(np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2,
                                                -1, 1)))
            assert turn.max() <= 60.0 + 1e-6
            offset = s.position_m - START_M[s.hand]
            inward = offset[:, 1] * (1 if s.hand == "right" else -1)
            assert inward.max() > 0.03 and inward.min() < -0.03  # inward and outward
            clutched += int((~s.engaged).any())
            far += int(np.linalg.norm(offset, axis=1).max() > 0.25)
    assert clutched >= 1 and far >= 1  # clutch presses and reaches out of reach happen
    assert not np.array_equal(operator_stream(SEEDS[0], settings)[0].T_operator_hand,
                              operator_stream(SEEDS[1], settings)[0].T_operator_hand)


def test_a_streams_pose_log_replays_as_the_stream(tmp_path):
    """Written as a FASTRAK pose log and replayed, a stream gives its own poses back (the
    clutched stretch left out: a replay re-centres after the gap, as the clutch does)."""
    seed = next(s for s in range(100) if any((~h.engaged).any() for h in operator_stream(
        s, StreamSettings(duration_s=10.0))))
    settings = StreamSettings(duration_s=10.0)
    path = write_stream_pose_log(tmp_path / "s.csv", seed, settings)
    with open_fastrak(replay=path) as replayed, generated_input(seed, settings) as generated:
        back = replayed.read_until(1e9)
        engaged = [p for p in generated.read_until(1e9) if p.engaged]
    assert len(back) == len(engaged) < 2 * (10 * 120 + 1)
    for hand in HANDS:
        a = [p for p in back if p.hand == hand]
        b = [p for p in engaged if p.hand == hand]
        assert np.allclose([p.t_s for p in a], [p.t_s for p in b], atol=1e-6)
        # the pose log keeps micrometres and 7 quaternion digits
        assert max(np.abs(x.T_operator_hand - y.T_operator_hand).max()
                   for x, y in zip(a, b, strict=True)) < 1e-5


def test_bad_stream_settings_are_one_line_errors():
    # review 28: 0.001 s made a one-sample stream and an internal error (no speed to cap)
    for kwargs in ({"duration_s": 0}, {"duration_s": float("nan")}, {"duration_s": 0.001},
                   {"duration_s": 0.099}, {"max_speed_m_s": 0}, {"max_speed_m_s": 50},
                   {"max_turn_deg": 200}):
        with pytest.raises(InputError):
            StreamSettings(**kwargs)
    for seed in range(5):  # the shortest allowed stream is one
        for s in operator_stream(seed, StreamSettings(duration_s=0.1, max_speed_m_s=0.01)):
            assert len(s.t_s) == 13 and s.speed_m_s().max() <= 0.01 * (1 + 1e-6)
