"""End-to-end teleoperation: replays on the simulated and ideal robots, input trouble, live pty."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log
from hubo_cli.fastrak.capture import capture_bytes, parse_capture, read_recording_bytes
from hubo_cli.model import load_model
from hubo_cli.resources import data_file
from hubo_cli.teleop.session import TeleopSettings, run_teleop, stale_spans

RECTANGLE = data_file("trajectories", "drill-rectangle.fastrak")


def _chunks(path):
    cap = parse_capture(read_recording_bytes(path))
    starts = np.concatenate([[0], cap.chunk_ends[:-1]])
    return cap.header, [(float(t), cap.data[a:b]) for t, a, b in
                        zip(cap.chunk_times, starts, cap.chunk_ends, strict=True)]


def _first_seconds(path, tmp_path, seconds):
    """The first ``seconds`` of a capture, as a capture file (a shorter replay)."""
    header, chunks = _chunks(path)
    out = tmp_path / f"first-{seconds:g}s-{path.name}"
    out.write_bytes(capture_bytes(header, [(t, d) for t, d in chunks if t < seconds]))
    return out


def _max_step_ratio(run_dir):
    """Largest per-period command change as a fraction of the velocity limit (no jumps)."""
    model = load_model()
    log = load_log(run_dir)
    index = [model.joint_names.index(j) for j in log.joint_names]
    steps = np.abs(np.diff(log.joints("cmd"), axis=0)) / model.control_period_s
    return float(np.max(steps / model.velocity_rad_s[index]))


@pytest.fixture(scope="module")
def drill_rectangle_run(tmp_path_factory):
    """The whole drill recording on the simulated robot (about 50 simulated s), run once for
    the module, and its session target (the hand's errors in the world, period by period)."""
    targets = []
    run = run_teleop(TeleopSettings(replay=RECTANGLE, mode="drill",
                                    out=tmp_path_factory.mktemp("drill-rectangle") / "run"),
                     on_ready=lambda target, loop: targets.append(target))
    return run, targets[0]


@pytest.mark.physical
@pytest.mark.slow
def test_drill_rectangle_on_the_simulated_robot(drill_rectangle_run):
    run, _ = drill_rectangle_run
    s = run.summary
    assert s["ended"] == "done" and not s["estop_events"]
    # through the measured torso pose (encoders + IMU), which the drill-mode correction holds
    # on the goal: 3.53 / 3.51 mm on the AVX-512 / portable code paths in round 20 (4.47 /
    # 4.44 while the drill goal traced the hand's tremor, 9946bec); it was 5.1 mm on most
    # runs, but 7.4 mm after a 1e-12 change of one time constant (the feet slip sideways on
    # some runs, which no measurement on the robot sees, and the torso estimate assumes they
    # stand still). The test below asserts the world error of the operation's first 2 s to
    # 6 mm; this bound leaves room for that chaos (11.5 mm is 1.55x the 7.4 mm).
    assert s["rms_error_mm"]["right-arm"] < 11.5
    # the wrist's bending moment, the drill's weight removed (what the 1.21 N m stop reads):
    # the bit goes in along its axis, crosses the cardboard no faster than the drill mode's
    # bound and the legs move calmly meanwhile: 0.707 / 0.702 N m at the peak (11.8 s) on the
    # AVX-512 / portable code paths in round 20 (0.93 / 1.216 before, at the stop's limit;
    # 0.912 at 48.9 s while the goal traced the hand's tremor, docs/history/teleop.md): 1.07
    # N m is 1.5x
    wrist_nm = load_log(run.run_dir)["wrist_torque_nm"]
    assert np.nanmax(wrist_nm) < 1.07
    assert s["scene"]["placed_from"] == "right_drill_bit"
    assert s["max_joint_velocity_ratio"] <= 1.0 + 1e-9  # the log keeps 15 digits
    assert s["ik_status_counts"]["right-arm"]["held"] == 0
    for name in ("log.csv", "summary.json", "path_right-arm.png", "snapshot.png"):
        assert (run.run_dir / name).exists()


@pytest.mark.parametrize("wall_distance_m", [None, 0.38, 0.44, 0.53, 0.55])
def test_the_drill_goes_into_the_wall_along_its_bit_from_a_pose_within_reach(wall_distance_m):
    """The pose the robot holds while the wall is placed is the approach's own (exact IK, not
    the capped pose 39 mm and 8.5 deg short of it that the default stance had with a 50 mm
    standoff), its flutes clear of the cardboard; the bit then moves along its axis only while
    it goes in, and across the wall only inside the hole, up its edge to the start point."""
    from hubo_cli.errors import SafetyError
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.session import (
        PAPER_HOLE_M,
        STANDOFF_M,
        WALL,
        TeleopSettings,
        approach_paths,
        prepare,
    )

    model, body, _, scene = prepare(TeleopSettings(mode="drill", wall_distance_m=wall_distance_m))
    try:
        path = approach_paths(body, ["right-arm"], scene)["right-arm"]
    except SafetyError as err:  # no way in near the corner: refused before anything moves
        assert "--wall-distance" in err.hint and "nothing moved" in str(err)
        return
    start = np.asarray(scene["start_m"])
    plunge, *route = path.segments
    assert np.allclose(plunge.T_end[:3, 3] - plunge.T_start[:3, 3], [STANDOFF_M, 0.0, 0.0])
    assert np.allclose(plunge.T_start[:3, :3], np.eye(3)) and plunge.T_end[0, 3] == start[0]
    assert STANDOFF_M - model.drill.bit_tip_m - WALL.thickness_m / 2 >= 0.005  # flutes clear
    for segment in route:  # up the hole's left edge, in the wall plane
        assert segment.T_start[0, 3] == segment.T_end[0, 3] == start[0]
        assert segment.T_start[1, 3] == segment.T_end[1, 3] == start[1]
        assert start[2] - PAPER_HOLE_M[1] - 1e-9 <= segment.T_start[2, 3] <= start[2]
    assert np.allclose(path.at(path.duration_s)[:3, 3], start)
    first = {"right-arm": path.at(0.0)}
    solved = body.solve(first, home_posture(model), lift_m=body.lift_for(first))
    assert solved.arms["right-arm"].status == "exact"


# The two-hand session through the CLI (`hubo teleop --replay <capture> --json`): the shipped
# two-hand capture's whole run, in test_teleop_reach.py
# (test_the_two_hand_sample_keeps_up_with_the_operator; its first 5 s were run here again until
# round 18).


# Not marked physical: on the ideal driver this run is the same on both code paths to the last
# bit (AVX-512 / portable, round 18: the 2950 logged periods equal in every column but the
# wall-clock compute time; 153 stale periods and a largest velocity ratio of 1.000000000000023
# on both), so make test-portable would only repeat it (2.3 s of CPU).
@pytest.mark.slow
def test_a_one_second_gap_holds_smoothly(tmp_path):
    header, chunks = _chunks(RECTANGLE)
    # the first 7 s, without 4-5 s (a short stream: the gap, not the whole cut, is tested)
    src = tmp_path / "gap.fastrak"
    src.write_bytes(capture_bytes(header, [(t, d) for t, d in chunks
                                           if t < 7.0 and not 4.0 <= t < 5.0]))
    run = run_teleop(TeleopSettings(replay=src, mode="drill", driver="ideal",
                                    out=tmp_path / "run"))
    assert run.summary["ended"] == "done"
    # ~1 s flagged stale: 153 periods on both code paths (AVX-512 / portable), 1.5x the bound
    assert run.summary["status_counts"].get("stale input", 0) > 100
    # review 20: the reported span is the time the hand held, the 1 s gap (the flag's 0.765 s
    # and the 0.25 s timeout before it: 1.015 s; main said 0.77 s)
    stale = run.summary["stale_input"]
    assert stale["spans"] == 1 and 0.95 <= stale["longest_s"] == stale["total_s"] <= 1.05
    assert _max_step_ratio(run.run_dir) <= 1.0 + 1e-9
    assert run.summary["max_joint_velocity_ratio"] <= 1.0 + 1e-9


def test_a_stale_span_counts_the_hold_before_its_flag():
    """Review 20: the flag rises the stale timeout after the hand's last usable pose, so a
    span of flags understated the hold by the timeout ("input stale for 0.01 s" after a
    tracker jumped away). Spans start the timeout earlier, never before the log or the end of
    the span before."""
    class Log:
        def __init__(self, stale_rows):
            self.flags = [["stale-input"] if k in stale_rows else [] for k in range(200)]
            self.t = np.arange(200) * 0.005 + 2.0

        def __getitem__(self, name):
            return self.t

    # flagged from row 10 (0.05 s after the log's start: clamped there) for 20 rows, and from
    # row 100 for 2 rows (0.25 s before it the hand held)
    spans = stale_spans(Log(set(range(10, 30)) | {100, 101}), t_origin_s=1.0, timeout_s=0.25)
    assert spans["spans"] == 2 and spans["longest_s"] == pytest.approx(0.26)
    assert spans["longest_from_s"] == pytest.approx(1.25)  # row 50 on the target's clock
    assert spans["total_s"] == pytest.approx(0.26 + 0.15)
    # a span that starts just after another: from the end of the one before
    spans = stale_spans(Log(set(range(10, 30)) | {35}), timeout_s=0.25)
    assert spans["total_s"] == pytest.approx(0.15 + 0.03)
    assert spans["longest_s"] == pytest.approx(0.15) and spans["longest_from_s"] == 2.0


# Not marked physical: the ideal driver, as the gap's test above.
@pytest.mark.slow
def test_a_tracker_that_jumps_and_stays_there_is_stale_input(tmp_path):
    # review 20: the right hand's station reads 0.2 m further forward from 1 s on (a hemisphere
    # flip, a knocked sensor). Each such pose is a jump the mapper rejects; on main the hand
    # held its last goal for the rest of the replay, every later pose rejected, and the run
    # ended exit 0 without a word ("followed" 100 %, 2.4 mm RMS). Now poses that keep coming
    # unusable for the stale timeout are stale input: said, then the replay re-centres
    text = data_file("trajectories", "two-hand-free.csv").read_text().splitlines()
    rows = [text[0]]
    for line in text[1:]:
        f = line.split(",")
        if float(f[0]) > 3.0:
            break
        if f[1] == "1" and float(f[0]) >= 1.0:
            f[2] = f"{float(f[2]) + 0.2:.6f}"
        rows.append(",".join(f))
    src = tmp_path / "jump.csv"
    src.write_text("\n".join(rows) + "\n")
    run = run_teleop(TeleopSettings(replay=src, driver="ideal", out=tmp_path / "run"))
    stale = run.summary["stale_input"]
    assert run.summary["ended"] == "done" and stale is not None
    # flagged once the poses were unusable for the 0.25 s timeout (as a silent tracker is),
    # until the next pose re-centres: a span of a few periods, 1.25 s into the stream (the
    # approach takes the first 2.09 s of the target's clock on the ideal driver)
    # the span is the time the hand held: from its last usable pose (the 0.25 s timeout
    # before the flag) to the re-centre (main said 0.01 s from 3.34 s)
    assert stale["spans"] == 1 and 0.25 <= stale["longest_s"] < 0.30
    assert 3.05 <= stale["longest_from_s"] <= 3.15
    # then re-centred: only the station's 16 poses of the timeout (60 Hz) were rejected, the
    # rest used (on main every one of its 120 poses after the jump would be)
    assert run.summary["samples_rejected"] <= 20
    assert run.summary["arms_without_usable_input"] == []  # it had some before the jump
    assert _max_step_ratio(run.run_dir) <= 1.0 + 1e-9


@pytest.mark.slow
def test_garbage_bytes_give_the_same_path(tmp_path):
    clean_src = _first_seconds(RECTANGLE, tmp_path, 3.0)  # 360 chunks: 9 bursts of noise
    header, chunks = _chunks(clean_src)
    rng = np.random.default_rng(5)
    noisy = []
    for k, (t, data) in enumerate(chunks):
        noisy.append((t, data))
        if k % 40 == 7:  # bursts of line noise between records
            noisy.append((t, bytes(rng.integers(0, 256, rng.integers(1, 30), dtype=np.uint8))))
    src = tmp_path / "noisy.fastrak"
    src.write_bytes(capture_bytes(header, noisy))
    clean = run_teleop(TeleopSettings(replay=clean_src, mode="drill", driver="ideal",
                                      out=tmp_path / "clean"))
    dirty = run_teleop(TeleopSettings(replay=src, mode="drill", driver="ideal",
                                      out=tmp_path / "dirty"))
    assert dirty.summary["input_stats"]["bad_bytes_skipped"] > 0
    assert (dirty.summary["input_stats"]["good_records"]
            == clean.summary["input_stats"]["good_records"])
    a, b = load_log(clean.run_dir).joints("cmd"), load_log(dirty.run_dir).joints("cmd")
    assert a.shape == b.shape and np.allclose(a, b, atol=1e-12)


@pytest.mark.slow
def test_pose_log_replays_like_the_capture(tmp_path):
    lines = data_file("trajectories", "drill-rectangle.csv").read_text().splitlines()
    csv = tmp_path / "first-4s.csv"  # the header and 4 s of poses (2 stations at 60 Hz)
    csv.write_text("\n".join(lines[:481]) + "\n")
    run = run_teleop(TeleopSettings(replay=csv, mode="drill", driver="ideal",
                                    out=tmp_path / "run"))
    # the drilling hand's 240 poses, nearly all used
    assert run.summary["ended"] == "done" and run.summary["samples_used"] > 200


def test_live_tracker_through_the_emulators_pty(tmp_path):
    from hubo_cli.fastrak.emulator import make_emulator

    emu = make_emulator(stations=2).start()
    try:
        run = run_teleop(TeleopSettings(port=emu.port_name, driver="ideal", speed=1.0,
                                        duration_s=2.5, out=tmp_path / "run"))
    finally:
        emu.close()
    s = run.summary
    assert s["input_kind"] == "port" and s["ended"] == "finished"
    # about 50 in the 0.4 s after the take-over at 2.09 s (2 stations at 60 Hz; the poses
    # queued during the approach are not followed: review 23)
    assert s["samples_used"] > 20
    assert s["latency_ms"]["median"] is not None


def test_bad_inputs_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.fastrak"
    bad.write_bytes(b"not a capture at all \x00\xff")
    for args in (["teleop", "--replay", str(bad)], ["teleop"],
                 ["teleop", "--replay", str(RECTANGLE), "--speed", "fast"],
                 ["teleop", "--port", str(tmp_path / "no-such-port"), "--driver", "ideal"]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code in (2, 3), (args, result.output)
        assert "Traceback" not in result.output and "error:" in result.output


@pytest.mark.physical
@pytest.mark.slow
def test_drill_mode_places_the_wall_at_the_bit_and_holds_the_flutes_in_it(drill_rectangle_run):
    """The first 2 s of the operation (the whole run's feet slip a little on some runs, see
    above; these 2 s are the part before that chaos: 1.8 mm in the world)."""
    from hubo_cli.control.log import load_log as load
    from hubo_cli.teleop.session import STANDOFF_M, WALL
    from hubo_cli.urdf import DRILL_FRAME

    run, target = drill_rectangle_run
    s = run.summary
    assert s["ended"] == "done" and not s["estop_events"]
    assert s["scene"]["placed_from"] == DRILL_FRAME
    assert s["scene"]["gap_m"] == pytest.approx(STANDOFF_M - WALL.thickness_m / 2)
    # every period of the operation's first 2 s has the flutes in the cardboard (the
    # simulator's record)
    log = load(run.run_dir)
    operating = np.round(log["t_s"][log["phase_code"] == 1], 6)
    operating = operating[operating <= operating[0] + 2.0]
    holes = np.round(log.metadata["scene"]["hole_t_s"], 6)
    assert len(operating) > 300 and np.isin(operating, holes).all()
    # the hand's error in the world (the summary's world_rms_error_mm) over the same 2 s
    t_s = np.asarray(target.path_times_s["right-arm"])
    world_m = np.asarray(target.world_errors_m["right-arm"])
    assert len(world_m) == len(t_s) and len(world_m) > 300
    first = world_m[t_s <= t_s[0] + 2.0]
    # 0.93 / 0.93 mm on the AVX-512 / portable code paths (1.81 / 1.85 before the bit went
    # in along its axis): 6.4x
    assert len(first) > 300 and np.sqrt(np.mean(np.square(first))) * 1000 < 6.0
    assert s["world_rms_error_mm"]["right-arm"] == pytest.approx(
        np.sqrt(np.mean(np.square(world_m))) * 1000)


def _verdict(reach: dict[str, tuple[float, float]], overall_mm: float = 96.0,
             without_input: tuple[str, ...] = ()):
    """``hubo teleop``'s verdict (its exit code, its line on stderr) on a finished run whose
    hands had these (share of the time reachable and followed live, position RMS over that
    time in mm, optionally the orientation RMS over it in deg); ``without_input``: the arms
    none of whose poses was usable."""
    from types import SimpleNamespace

    from hubo_cli.cli.teleop import _report

    summary = {"estop_events": [], "error": "", "samples_used": 1920, "samples_rejected": 0,
               "arms_without_usable_input": list(without_input),
               "rms_error_mm": dict.fromkeys(reach, overall_mm), "stale_input": None,
               "interrupt_stop": None,
               "reach": {arm: {"followed_share": figures[0],
                               "followed_position_rms_mm": figures[1],
                               "followed_orientation_rms_deg": (figures[2:] or (None,))[0]}
                         for arm, figures in reach.items()}}
    run = SimpleNamespace(summary=summary, run_dir=Path("runs/x"),
                          loop=SimpleNamespace(exception=None, ok=True, ended="done"))
    try:
        _report(run, as_json=True)
    except SystemExit as exc:
        return exc.code
    return 0


def test_an_arm_whose_poses_were_none_usable_is_bad_input(capsys):
    # review 20's status_x_right_all.csv: station 1 reported out of its envelope ('x') in every
    # pose of a 4 s two-hand stream; the right arm never moved, the left followed, and main
    # ended exit 0 without a word (the "no operator input" check counts both hands together)
    assert _verdict({"left-arm": (1.0, 7.9)}, 7.9, without_input=("right-arm",)) == 2
    err = capsys.readouterr().err
    assert "the right-arm never moved: its station's poses came and not one was usable" in err
    assert _verdict({"left-arm": (1.0, 7.9), "right-arm": (1.0, 7.9)}, 7.9) == 0


def test_hands_that_did_not_follow_their_reachable_goals_are_said(capsys):
    """The review's both-hands stream (60 deg turns, 25 cm reach; 96 / 98 mm RMS overall, under
    the 100 mm that says the robot never moved, and 46 / 60 mm over the 33 / 30 % of the time
    the goals were reachable): one warning line naming the right hand and its figure (main: no
    line; exit 0 stays, FOLLOW_BOUND_MM says why). A hand at the healthy streams' worst (44.7
    mm, 0.6 m/s) and the shipped samples' (7 mm) has no line."""
    assert _verdict({"left-arm": (0.327, 46.1), "right-arm": (0.304, 59.9)}) == 0
    err = capsys.readouterr().err
    assert "right-arm hand missed" in err and "60 mm RMS" in err and "30%" in err
    assert _verdict({"left-arm": (1.0, 44.7), "right-arm": (0.9, 7.1)}, overall_mm=44.7) == 0
    assert "missed" not in capsys.readouterr().err
    assert _verdict({"left-arm": (0.0, None)}, overall_mm=50.0) == 0  # never reachable


def test_goals_out_of_reach_are_no_failure_to_follow_but_a_hand_off_its_reachable_ones_is(
        capsys):
    """Generated seed 4242 at 0.6 m/s for 6 s (ideal driver): 124 / 13 mm RMS in all, 36 / 12
    mm over the 42 / 39 % of the time the goals were reachable and followed; main ended it exit
    1, "the robot did not follow", on the all-time figure. Now exit 0 without a word; a hand
    120 mm off its reachable goals is still a run that did not complete."""
    assert _verdict({"left-arm": (0.42, 35.6), "right-arm": (0.39, 11.6)},
                    overall_mm=123.9) == 0
    assert "missed" not in capsys.readouterr().err
    assert _verdict({"left-arm": (0.42, 120.0), "right-arm": (0.39, 11.6)},
                    overall_mm=123.9) == 1
    assert ("the left-arm hand missed the operator's goals by 120 mm RMS over the time they "
            "were reachable" in capsys.readouterr().err)


def test_the_command_line_judges_a_stream_leaving_the_reach_by_its_reachable_time(tmp_path):
    result = CliRunner().invoke(main, ["teleop", "--generate", "4242", "--max-speed", "0.6",
                                       "--duration", "6", "--driver", "ideal", "--json",
                                       "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output  # main: 1
    reach = json.loads(result.stdout)["reach"]
    assert max(r["position_rms_mm"] for r in reach.values()) > 100.0  # the case still
    assert max(r["followed_position_rms_mm"] for r in reach.values()) < 55.0


def test_hands_that_did_not_turn_with_their_reachable_goals_are_said(capsys):
    """A hand that does not turn with the operator (45 deg RMS off its goals' orientation over
    the 52 % of the time it was followed; main: no word, the verdict judged the position only):
    one warning line naming it, exit 0 (as the position's); with the position line too when
    both miss. The healthy worst (6 s generated streams, 20.7 deg) has no line, nor has review
    19's 120 Hz stream (17.3 / 18.9 deg), whose figures lie among ordinary streams'."""
    assert _verdict({"left-arm": (0.503, 30.0, 17.3), "right-arm": (0.520, 30.0, 45.0)},
                    overall_mm=64.0) == 0
    err = capsys.readouterr().err
    assert "right-arm hand missed the operator's turn of the hand by 45 deg RMS" in err
    assert "52%" in err and "goals" not in err
    assert _verdict({"left-arm": (0.503, 59.6, 17.3), "right-arm": (0.520, 52.8, 45.0)},
                    overall_mm=68.0) == 0
    err = capsys.readouterr().err
    assert "left-arm hand missed the operator's goals by 60 mm" in err
    assert "right-arm hand missed the operator's turn of the hand by 45 deg" in err
    assert _verdict({"left-arm": (1.0, 29.1, 20.7), "right-arm": (0.52, 52.8, 18.9)},
                    overall_mm=30.0) == 0
    assert "missed" not in capsys.readouterr().err


def test_the_followed_orientation_is_over_the_followed_periods_only(model):
    """summary reach's followed_orientation_rms_deg: the orientation error's RMS over the
    periods the goal was reachable and the hand meant to follow (none: None), as a teleop
    target's reach report gives it from the periods it recorded."""
    from hubo_cli.input.device import HandPose, RecordedInput
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.mapping import HandMapper
    from hubo_cli.teleop.session import approach_paths, prepare
    from hubo_cli.teleop.target import TeleopTarget

    _, body, mapping, scene = prepare(TeleopSettings(generate_seed=0), model)
    poses = [HandPose(hand, np.eye(4), 0.0) for hand in ("left", "right")]
    with RecordedInput(poses, {"kind": "test"}) as device:
        target = TeleopTarget(model, device, HandMapper(mapping), body,
                              approach_paths(body, mapping.hand_arm.values(), scene),
                              home_posture(model))
    periods = {  # arm: (orientation error deg, goal reachable, clutch held) per period
        "right-arm": [(3.0, True, False), (4.0, True, False), (50.0, False, False),
                      (60.0, True, True)],
        "left-arm": [(5.7, False, False)]}
    for arm, records in periods.items():
        hand = target.hands[arm]
        for i, (error_deg, reachable, clutched) in enumerate(records):
            hand.reachable, hand.clutched = reachable, clutched
            target._record(arm, 0.005 * i, hand, np.zeros(3), np.zeros(3), 0.0,
                           np.radians(error_deg), 0.0)
    report = target.reach_report()
    assert report["right-arm"]["followed_orientation_rms_deg"] == pytest.approx(
        np.sqrt((9 + 16) / 2))
    assert report["right-arm"]["reachable_orientation_rms_deg"] == pytest.approx(
        np.sqrt((9 + 16 + 3600) / 3))  # the clutched period counts there, not here
    assert report["left-arm"]["followed_orientation_rms_deg"] is None


def test_a_live_operator_s_motion_before_the_take_over_is_not_followed(model):
    """Review 23: a live device queues every pose from when it opens; the first operating
    period took the oldest as the calibration and followed the rest at once, so the goal
    stepped by the operator's whole motion since the port opened (about 100 mm in one period
    on the emulator's circling hands). Now the poses before the take-over are dropped and the
    first one after it calibrates: the hand starts where it is."""
    from hubo_cli.input.device import HandPose, InputDevice
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.mapping import HandMapper
    from hubo_cli.teleop.session import approach_paths, prepare
    from hubo_cli.teleop.target import TeleopTarget

    class LiveQueue(InputDevice):
        live = True
        hands = ("right",)
        info = {"kind": "test"}

        def __init__(self):
            super().__init__()
            self.queue, self.clock = [], 0.0

        def _read(self, t_s):
            out, self.queue = self.queue, []
            return out

        def now_s(self):
            return self.clock

    def pose(x_m, t_s):
        T = np.eye(4)
        T[:3, 3] = [0.3 + x_m, -0.2, 0.0]
        return HandPose("right", T, t_s)

    _, body, mapping, scene = prepare(TeleopSettings(generate_seed=0,
                                                     station_arm={1: "right-arm"}), model)
    device = LiveQueue()
    target = TeleopTarget(model, device, HandMapper(mapping), body,
                          approach_paths(body, mapping.hand_arm.values(), scene),
                          home_posture(model), live=True)
    from hubo_cli.dataflow import Store

    target.store = Store()
    T_hand0 = target.hand_pose_commanded("right-arm").copy()
    # the operator moves 0.3 m forward while the robot approaches (1 cm a record), then holds
    device.queue = [pose(0.01 * k, 0.02 * k) for k in range(31)]
    device.clock = 0.61
    target.start_operating(5.0)
    device.queue.append(pose(0.30, 0.62))  # the first pose after the take-over
    target.operate_step(5.005, False)
    assert np.linalg.norm(target.goals["right-arm"][:3, 3] - T_hand0[:3, 3]) < 1e-9
    device.queue.append(pose(0.31, 0.63))  # then 1 cm more is followed: 1 cm
    target.operate_step(5.01, False)
    assert np.linalg.norm(target.goals["right-arm"][:3, 3] - T_hand0[:3, 3]) == pytest.approx(
        0.01, abs=1e-9)
