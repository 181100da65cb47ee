"""Seeing a run: the log holds what a replay needs, the kinematic replay reproduces the logged
tool and torso, a video decodes to the asked frames, and the Rerun and MCAP exports read back."""

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log, pose_columns
from hubo_cli.control.target import Target
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.session import RunSetup, run
from hubo_cli.viz.camera import DEFAULT_PRESET, camera_for
from hubo_cli.viz.replay import KinematicReplay
from hubo_cli.viz.scene import load_scene

pytestmark = pytest.mark.xdist_group("viz")  # module-scoped runs: one worker


class SwayTarget(Target):
    """The right (drill) arm raised, a wall put through the bit, then one sideways sway of the
    shoulder yaw, at rest again by 1.8 s."""

    def __init__(self, model) -> None:
        self.q0 = home_posture(model)
        self.arm = model.limb_slice("right-arm")
        self.raised = self.q0.copy()
        self.raised[self.arm] = [-0.9, 0.0, 0.0, -0.9, 0.0, -0.3]  # bit forward at chest height
        self.world = None
        self.walled = False

    def attach(self, world, modules) -> None:
        self.world = world

    def __call__(self, t_s: float, state):
        ramp = min(t_s / 0.8, 1.0)
        q = self.q0 + (self.raised - self.q0) * (0.5 - 0.5 * np.cos(np.pi * ramp))
        if t_s >= 0.8:
            if not self.walled:  # the wall through the bit, once the arm is up
                bit_x = self.world.frame_pose("right_drill_bit")[0, 3]
                self.world.add_wall(bit_x - 0.005, 1.4, 1.2, 0.01)
                self.walled = True
            phase = min((t_s - 0.8) / 1.0, 1.0)
            q[self.arm.start + 2] = 0.25 * (0.5 - 0.5 * np.cos(2 * np.pi * phase))
        return q, {}


def record_sway_run(run_dir: Path, duration_s: float = 2.0) -> Path:
    """A short simulated run through the run scaffold (log, scene metadata, snapshot)."""
    model = load_model()
    setup = RunSetup("sway", model, tools={"right-arm": "drill"}, out=run_dir,
                     duration_s=duration_s)
    return run(setup, SwayTarget(model)).run_dir


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    return record_sway_run(tmp_path_factory.mktemp("viz") / "sway", duration_s=2.0)


@pytest.fixture(scope="module")
def scene(run_dir):
    return load_scene(run_dir)


def test_log_is_plain_csv_with_sidecar_and_parquet(run_dir):
    table = pl.read_csv(run_dir / "log.csv")  # no options
    assert [c for c, kind in table.schema.items() if not kind.is_numeric()] == ["flags"]
    sidecar = json.loads((run_dir / "log.json").read_text())
    assert table.columns == sidecar["columns"] and table.height == sidecar["rows"] > 400
    assert set(pose_columns("torso") + pose_columns("right_hand")) <= set(table.columns)
    parquet = pl.read_parquet(run_dir / "log.parquet")
    assert parquet.columns == table.columns and parquet.height == table.height
    assert np.array_equal(parquet["q_RSY_rad"].to_numpy(), table["q_RSY_rad"].to_numpy())
    scene = sidecar["metadata"]["scene"]
    assert scene["tools"]["right-arm"] == "drill" and len(scene["walls"]) == 1
    assert len(scene["hole_world_m"]) == len(scene["hole_t_s"]) > 0
    log = load_log(run_dir)
    assert len(log) == table.height and log.metadata["scene"]["walls"] == scene["walls"]
    # the torso leans: its pitch is logged and changes over the run
    pitch = log["torso_pitch_rad"]
    assert np.all(np.isfinite(pitch)) and np.ptp(pitch) > 1e-3


def test_load_log_reads_the_first_format_and_a_cut_short_row(tmp_path, run_dir):
    lines = (run_dir / "log.csv").read_text().splitlines(keepends=True)
    old = tmp_path / "log.csv"
    old.write_text("# hubo-cli period log v1; units ...\n" + "".join(lines[:11]) + lines[11][:40])
    log = load_log(old)
    assert len(log) == 10 and log.joint_names[0] == "RSP"
    assert log.flags[0] == [] or all(isinstance(w, str) for w in log.flags[0])


def test_replay_reproduces_logged_bit_and_torso_lean(scene):
    assert scene.drill and scene.working_arm == "right-arm"
    bit_error, lean_error = [], []
    with KinematicReplay(scene) as replay:
        for k in range(0, len(scene), 3):
            replay.show(k)
            bit_error.append(np.linalg.norm(replay.frame_pose("right_drill_bit")[:3, 3]
                                            - scene.tool_world_m[k]))
            T = replay.torso_pose()
            lean = np.arctan2(-T[2, 0], np.hypot(T[0, 0], T[1, 0]))
            lean_error.append(abs(lean - scene.log["torso_pitch_rad"][k]))
    assert max(bit_error) < 1e-6
    assert max(lean_error) < 1e-9
    # the bit moved by decimetres over the run (the arm raised), so the check is not trivial
    assert np.linalg.norm(np.ptp(scene.tool_world_m, axis=0)) > 0.1


@pytest.mark.physical
def test_a_hardware_log_without_torso_position_is_stood_on_its_soles(run_dir, tmp_path):
    """A hardware driver knows the torso's orientation (IMU) but not its position: the replay
    stands the robot on its lower sole under the torso, which lands where the sim had it."""
    table = pl.read_parquet(run_dir / "log.parquet")
    unknown = [*pose_columns("right_hand"), *pose_columns("left_hand"), "torso_x_m", "torso_y_m",
               "torso_z_m"]
    table.with_columns([pl.lit(float("nan")).alias(c) for c in unknown]).write_parquet(
        tmp_path / "log.parquet")
    (tmp_path / "log.csv").write_text("")  # a run folder: its CSV and sidecar beside
    (tmp_path / "log.json").write_text((run_dir / "log.json").read_text())
    hardware = load_scene(tmp_path)
    sim = load_scene(run_dir)
    assert hardware.torso_estimated.all() and not sim.torso_estimated.any()
    height_error = np.abs(hardware.T_world_torso[:, 2, 3] - sim.T_world_torso[:, 2, 3])
    # the sim's soles sink into the floor by millimetres: 1.85 mm on both code paths
    # (AVX-512 / portable), 5.4x
    assert height_error.max() < 0.01
    assert np.all(np.isfinite(hardware.tool_world_m))


def test_a_2_s_video_decodes_to_60_frames_of_the_robot(scene, tmp_path):
    import imageio_ffmpeg

    from hubo_cli.viz.video import render_video

    out = tmp_path / "two.mp4"
    result = render_video(scene, out, speed=1.0, width=320, height=240, start_s=0.0, end_s=2.0)
    assert result.frames == 60
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = reader.__next__()
    frames = [np.frombuffer(f, dtype=np.uint8).reshape(240, 320, 3) for f in reader]
    assert meta["size"] == (320, 240) and meta["fps"] == pytest.approx(30)
    assert abs(len(frames) - 60) <= 1
    # the same view with the robot taken 50 m up out of the picture: the robot changes a good
    # part of the frame (so the video shows it, not a blank or empty scene)
    away = scene.T_world_torso.copy()
    away[:, 2, 3] += 50.0
    camera = camera_for(DEFAULT_PRESET, scene.focus_world_m(), scene.working_arm, 320, 240)
    with KinematicReplay(dataclasses.replace(scene, T_world_torso=away)) as empty:
        empty.show(len(scene) - 1)
        no_robot = empty.render(camera).astype(float)
    last = frames[-1].astype(float)
    changed = np.sum(np.abs(last - no_robot), axis=2)[40:] > 60  # below the caption bar
    assert changed.mean() > 0.05
    assert np.mean(np.abs(frames[0].astype(float) - last)) > 1  # and it moves


def test_export_rrd_verifies_and_mcap_reads_back(scene, run_dir, tmp_path):
    from hubo_cli.viz.mcap_export import read_mcap_summary

    rrd, mcap = tmp_path / "run.rrd", tmp_path / "run.mcap"
    result = CliRunner().invoke(main, ["export", str(run_dir), "--rrd", str(rrd), "--mcap",
                                       str(mcap), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["rrd"]["joints"] == 24
    rerun = Path(sys.executable).with_name("rerun")
    verified = subprocess.run([str(rerun), "rrd", "verify", str(rrd)], capture_output=True,
                              text=True, timeout=120)
    assert verified.returncode == 0, verified.stderr
    stats = subprocess.run([str(rerun), "rrd", "stats", str(rrd)], capture_output=True,
                           text=True, timeout=120).stdout
    for entity in ("/transforms/torso", "/transforms/joints/RSY", "/plots/wrist_torque_nm",
                   "/plots/cp_margin_mm", "/world/hole", "/world/actual_path"):
        assert entity in stats
    topics = read_mcap_summary(mcap)
    t_s = scene.t_s
    for topic, schema in (("/joint_states", "foxglove.JointStates"),
                          ("/tf", "foxglove.FrameTransforms")):
        assert topics[topic]["schema"] == schema
        assert topics[topic]["messages"] == len(scene)
        assert topics[topic]["first_s"] == pytest.approx(t_s[0], abs=1e-9)
        assert topics[topic]["last_s"] == pytest.approx(t_s[-1], abs=1e-9)


def test_without_the_extra_the_commands_say_what_to_install(run_dir, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun now fails
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    result = CliRunner().invoke(main, ["export", str(run_dir), "--rrd", str(tmp_path / "x.rrd")])
    assert result.exit_code == 2
    assert "rerun-sdk" in result.output and "pip install 'hubo-cli[viz]'" in result.output
    result = CliRunner().invoke(main, ["replay", str(run_dir), "--video",
                                       str(tmp_path / "x.mp4")])
    assert result.exit_code == 2 and "imageio-ffmpeg" in result.output
    result = CliRunner().invoke(main, ["task", "cut-rectangle", "--video", "--out",
                                       str(tmp_path / "never")])
    assert result.exit_code == 2 and not (tmp_path / "never").exists()


def test_replay_refuses_bad_input_without_a_traceback(run_dir, tmp_path):
    runner = CliRunner()
    empty = tmp_path / "empty"
    empty.mkdir()
    for args in (["replay", str(empty), "--video", "x.mp4"],
                 ["replay", str(run_dir)],
                 ["replay", str(run_dir), "--video", "x.mp4", "--size", "big"],
                 ["replay", str(run_dir), "--video", "x.mp4", "--speed", "0"],
                 ["replay", str(run_dir), "--video", "x.mp4", "--from", "50"],
                 ["export", str(run_dir)]):
        result = runner.invoke(main, args)
        assert result.exit_code == 2, (args, result.output)
        assert "Traceback" not in result.output and "error" in result.output.lower()


def test_replay_command_writes_the_video_it_reports(run_dir, tmp_path):
    out = tmp_path / "small.mp4"
    result = CliRunner().invoke(main, ["replay", str(run_dir), "--video", str(out), "--size",
                                       "96x64", "--speed", "4", "--camera", "side", "--json"])
    assert result.exit_code == 0, result.output
    video = json.loads(result.output)["video"]
    run_s = len(load_log(run_dir)) * 0.005
    assert video["frames"] == round(run_s * 30 / 4)
    assert (video["width"], video["height"]) == (96, 64)
    assert out.read_bytes()[4:8] == b"ftyp"  # an MP4 container
