"""Seeing a run: the log holds what a replay needs, the kinematic replay reproduces the logged
tool and torso, a video decodes to the asked frames, and the Rerun and MCAP exports read back."""

import dataclasses
import json
import math
import os
import re
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from click.testing import CliRunner

import hubo_cli
from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log, pose_columns
from hubo_cli.control.target import Target
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.scene import WallPlacement, WallSize
from hubo_cli.session import RunSetup, run
from hubo_cli.viz.camera import DEFAULT_PRESET, PRESETS, camera_for
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

    def attach(self, world, modules, store) -> None:
        self.world = world

    def __call__(self, t_s: float, state):
        ramp = min(t_s / 0.8, 1.0)
        q = self.q0 + (self.raised - self.q0) * (0.5 - 0.5 * np.cos(np.pi * ramp))
        if t_s >= 0.8:
            if not self.walled:  # the wall through the bit, once the arm is up
                self.world.place_wall(WallPlacement("right_drill_bit", -0.005,
                                                    WallSize(1.4, 1.2, 0.01)))
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
    # the torso leans: its pitch is logged and changes over the run. The wall put through the
    # bit latches the wrist-torque stop at 0.805 s, which brakes and backs the bit out, so the
    # body barely moves: 0.57 mrad of pitch (22 mrad when the stop reverted the raise); a
    # logged pitch that did not change (constant, zeros) fails the 0.1 mrad bound
    pitch = log["torso_pitch_rad"]
    assert np.all(np.isfinite(pitch)) and np.ptp(pitch) > 1e-4


def test_log_says_when_and_by_what_it_was_written_and_parquet_keeps_integers(run_dir):
    pq = pytest.importorskip("pyarrow.parquet")
    sidecar = json.loads((run_dir / "log.json").read_text())
    summary = json.loads((run_dir / "summary.json").read_text())
    started = datetime.fromisoformat(sidecar["started_utc"])
    assert sidecar["started_utc"].endswith("Z") and started.tzinfo is not None
    assert abs(started.timestamp() - (run_dir / "log.json").stat().st_mtime) < 600
    assert sidecar["hubo_cli_version"] == hubo_cli.__version__
    assert summary["started_utc"] == sidecar["started_utc"]
    assert summary["hubo_cli_version"] == hubo_cli.__version__
    schema = pq.read_schema(run_dir / "log.parquet")
    kinds = {name: str(schema.field(name).type) for name in schema.names}
    assert kinds["period_count"] == kinds["status_code"] == "int64"
    assert kinds["limiter_clamped_count"] == kinds["estop_mode_code"] == "int64"
    assert kinds["right_foot_contact_flag"] == "int8" and kinds["q_RSY_rad"] == "double"
    metadata = {k.decode(): v.decode() for k, v in pq.read_metadata(
        run_dir / "log.parquet").metadata.items()}
    assert metadata["started_utc"] == sidecar["started_utc"]
    assert metadata["hubo_cli_version"] == hubo_cli.__version__
    assert metadata["units"] == sidecar["units"]
    assert json.loads(metadata["joint_names"]) == sidecar["joint_names"]
    assert json.loads(metadata["status_codes"]) == sidecar["status_codes"]
    units = json.loads(metadata["column_units"])
    assert (units["t_s"], units["compute_us"], units["q_RSY_rad"], units["torso_x_m"]) == (
        "s", "us", "rad", "m")
    # the values are the CSV's (integers where whole, null where the CSV has NaN)
    csv = pl.read_csv(run_dir / "log.csv")
    parquet = pl.read_parquet(run_dir / "log.parquet")
    for name in ("period_count", "status_code", "limiter_clamped_count", "estop_mode_code"):
        assert np.array_equal(parquet[name].cast(pl.Float64).fill_null(np.nan).to_numpy(),
                              csv[name].cast(pl.Float64).to_numpy(), equal_nan=True)


def test_pandas_reads_the_counters_as_integers(run_dir):
    pd = pytest.importorskip("pandas")
    table = pd.read_parquet(run_dir / "log.parquet")
    for name in ("period_count", "status_code", "limiter_clamped_count", "estop_mode_code",
                 "right_foot_contact_flag"):
        assert pd.api.types.is_integer_dtype(table[name]), (name, table[name].dtype)
    assert table["estop_mode_code"].isna().any()  # missing values stay missing, not NaN floats
    assert pd.api.types.is_float_dtype(table["q_RSY_rad"])


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

    from hubo_cli.viz.legend import bar_height_px
    from hubo_cli.viz.video import Overlay, render_video

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
    changed = np.sum(np.abs(last - no_robot), axis=2) > 60
    inset = Overlay(scene, camera).inset  # the overlay's drawings do not count
    changed[inset.top:inset.top + inset.size + 1, inset.left:inset.left + inset.size + 1] = False
    bar = bar_height_px(240)
    assert changed[bar:-bar].mean() > 0.05  # between the caption and the legend bars
    assert np.mean(np.abs(frames[0].astype(float) - last)) > 1  # and it moves


def _rerun_cli() -> Path:
    """The rerun binary beside the interpreter (it comes with rerun-sdk), or skip."""
    rerun = Path(sys.executable).with_name("rerun")
    if not rerun.exists():
        pytest.skip(f"no rerun command at {rerun} (install hubo-cli[viz])")
    return rerun


def _rrd_print(rerun: Path, rrd: Path) -> str:
    verified = subprocess.run([str(rerun), "rrd", "verify", str(rrd)], capture_output=True,
                              text=True, timeout=120)
    assert verified.returncode == 0, verified.stderr
    return subprocess.run([str(rerun), "rrd", "print", "-vvv", str(rrd)], capture_output=True,
                          text=True, timeout=120).stdout


JSON_TYPES = {"number": (int, float), "integer": (int,), "string": (str,), "boolean": (bool,),
              "object": (dict,), "array": (list,), "null": (type(None),)}


def _schema_problems(value, schema: dict, where: str = "") -> list[str]:
    """Where ``value`` breaks ``schema`` (the JSON schema keywords the exports use: type, a
    type list, properties, required, items); empty when it holds. jsonschema is not a
    dependency of the project."""
    kinds = schema.get("type")
    kinds = [kinds] if isinstance(kinds, str) else kinds
    if kinds is not None and not any(
            isinstance(value, JSON_TYPES[k]) and not (isinstance(value, bool) and k != "boolean")
            and not (k == "integer" and isinstance(value, float)) for k in kinds):
        return [f"{where or 'message'}: {value!r} is not {kinds}"]
    problems = []
    if isinstance(value, dict):
        problems += [f"{where}.{k} missing" for k in schema.get("required", ()) if k not in value]
        for key, sub in schema.get("properties", {}).items():
            if key in value:
                problems += _schema_problems(value[key], sub, f"{where}.{key}")
    if isinstance(value, list) and "items" in schema:
        for i, item in enumerate(value):
            problems += _schema_problems(item, schema["items"], f"{where}[{i}]")
    return problems


def test_the_schema_check_finds_a_null_number():
    """The check the export test uses: a null against "number" is a problem, a missing field
    or a value of a listed type is not."""
    schema = {"type": "object", "properties": {"a": {"type": "number"},
                                               "b": {"type": ["number", "null"]}}}
    assert _schema_problems({"a": None}, schema) == [".a: None is not ['number']"]
    assert _schema_problems({"b": None}, schema) == _schema_problems({"a": 1}, schema) == []
    assert _schema_problems({"a": True}, schema) != []


def _read_mcap(path: Path) -> dict:
    """Everything the ``mcap`` reader gives back: channels by topic (schema name, message
    encoding, log times, raw messages), attachments and metadata records."""
    from mcap.reader import make_reader

    out = {"topics": {}, "attachments": {}, "metadata": {}, "schemas": {}}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            if schema.encoding == "jsonschema":
                out["schemas"][channel.topic] = schema.data
            entry = out["topics"].setdefault(channel.topic, {
                "schema": schema.name, "encoding": channel.message_encoding, "times": [],
                "data": []})
            entry["times"].append(message.log_time)
            entry["data"].append(message.data)
        for attachment in reader.iter_attachments():
            out["attachments"][attachment.name] = (attachment.media_type, attachment.data)
        for record in reader.iter_metadata():
            out["metadata"][record.name] = record.metadata
    return out


def test_a_video_ffmpeg_could_not_finish_is_refused_and_the_old_file_stays(scene, tmp_path,
                                                                           monkeypatch):
    """ffmpeg that fails at its end (the index, on a full disk) exits with an error imageio's
    writer does not raise: the finished file is checked (it was renamed over the user's file,
    exit 0, unplayable). A full disk is ENOSPC naming the user's file (exit 3), otherwise one
    line naming it (ffmpeg's own lines silenced); the old file stays, no temporary file is
    left."""
    import errno
    import shutil

    import imageio_ffmpeg

    from hubo_cli.errors import HuboError
    from hubo_cli.outputs import replacing, writer_failure
    from hubo_cli.viz.video import check_mp4, render_video

    write_frames = imageio_ffmpeg.write_frames
    log_levels = []

    class CutShort:  # ffmpeg's writer, the file then cut as a full disk leaves it
        def __init__(self, path, *args, **kwargs):
            self.path, self.writer = path, write_frames(path, *args, **kwargs)
            log_levels.append(kwargs.get("ffmpeg_log_level"))

        def send(self, frame):
            return self.writer.send(frame)

        def close(self):
            self.writer.close()
            check_mp4(self.path)  # whole until here
            os.truncate(self.path, os.path.getsize(self.path) - 100)

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", CutShort)
    old = tmp_path / "old.mp4"
    old.write_text("OLD")
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=1000))
    with pytest.raises(OSError) as full, replacing(old) as temporary:
        render_video(scene, temporary, speed=1.0, width=64, height=48, start_s=0.0, end_s=0.1)
    assert (full.value.errno, full.value.filename) == (errno.ENOSPC, str(old))
    assert log_levels == ["quiet"]  # ffmpeg's own lines ("Error writing trailer") not printed
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=10**10))
    with pytest.raises(HuboError) as stopped, replacing(old) as temporary:
        raise writer_failure(temporary, "ffmpeg", OSError("the MP4 is incomplete"))
    assert str(stopped.value) == f"cannot write {old}: ffmpeg stopped (the MP4 is incomplete)"
    assert old.read_text() == "OLD" and [p.name for p in tmp_path.iterdir()] == ["old.mp4"]
    with pytest.raises(OSError, match="no index"):
        check_mp4(old)


def test_export_rrd_verifies_with_blueprint_and_mcap_reads_back(scene, run_dir, tmp_path):
    from hubo_cli.viz.mcap_export import LAYOUT_PATH, METADATA_NAME
    from hubo_cli.viz.scene import events, run_metadata

    rerun = _rerun_cli()
    rrd, mcap = tmp_path / "run.rrd", tmp_path / "run.mcap"
    result = CliRunner().invoke(main, ["export", str(run_dir), "--rrd", str(rrd), "--mcap",
                                       str(mcap), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["rrd"]["joints"] == 24 and report["mcap"]["layout"] == str(LAYOUT_PATH)
    printed = _rrd_print(rerun, rrd)
    for entity in ("/transforms/torso", "/transforms/joints/RSY", "/plots/wrist_torque_nm",
                   "/plots/cp_margin_mm", "/world/hole", "/world/actual_path", "/events"):
        assert f" - {entity} - " in printed, entity
    # the blueprint: one 3-D view, three grouped plots (not one per series) and the event log
    views = re.findall(r"┆ \[(\w+)\]\s+┆ \[[^\]]*\]\s+┆ \[/", printed)
    assert sorted(views) == ["3D", "TextLog", "TimeSeries", "TimeSeries", "TimeSeries"]
    # the recording starts when the run did (the log's start), not at the export
    start_ns = scene.start_utc_ns
    assert scene.start_source == "log"
    assert start_ns == round(datetime.fromisoformat(scene.log.started_utc).timestamp() * 1e6) * 1000
    assert printed.count("RecordingInfo:start_time │") == 1 and f"[{start_ns}]" in printed
    # and says what the run was, as the MCAP's metadata record does
    assert " - /__properties/hubo_cli_run - " in printed
    assert f"[{run_metadata(scene)['started_utc']}]" in printed and "[sway]" in printed

    read = _read_mcap(mcap)
    topics = read["topics"]
    t_ns = start_ns + np.round(scene.t_s * 1e9).astype(np.int64)
    for topic, schema in (("/joint_states", "foxglove.JointStates"),
                          ("/tf", "foxglove.FrameTransforms"), ("/metrics", "hubo.Metrics"),
                          ("/safety", "hubo.Safety")):
        assert topics[topic]["schema"] == schema
        assert topics[topic]["times"] == t_ns.tolist()  # UTC: the run's start + its time
    assert datetime(2020, 1, 1, tzinfo=UTC).timestamp() * 1e9 < t_ns[0]  # not 1970
    urdf = scene.model.urdf_path(drill=True)
    assert read["attachments"][urdf.name] == ("application/xml", urdf.read_bytes())
    description = topics["/robot_description"]
    assert description["schema"] == "std_msgs/String" and description["encoding"] == "json"
    assert json.loads(description["data"][0]) == {"data": urdf.read_text()}
    meta = read["metadata"][METADATA_NAME]
    assert meta["started_utc"].startswith(scene.log.started_utc[:26])
    assert meta["start_time_source"] == "log" and meta["command"] == "sway"
    assert meta["hubo_cli_version"] == hubo_cli.__version__ and meta["periods"] == str(len(scene))
    metrics = [json.loads(m) for m in topics["/metrics"]["data"]]
    assert all(isinstance(m["status_code"], int) and m["status"] for m in metrics)
    # every JSON message holds to its channel's declared schema (the run has periods without
    # a value: those fields are left out, never null against "number")
    for topic in ("/robot_description", "/metrics", "/safety"):
        schema = json.loads(read["schemas"][topic])
        for data in topics[topic]["data"]:
            assert _schema_problems(json.loads(data), schema) == [], (topic, data)
    torque = [m.get("wrist_torque_nm", math.nan) for m in metrics]
    assert np.allclose(np.array(torque, dtype=float), scene.log["task_wrist_torque_nm"]
                       if "task_wrist_torque_nm" in scene.log.columns
                       else scene.log["wrist_torque_nm"], equal_nan=True)
    assert topics["/events"]["schema"] == "foxglove.Log"
    happened = events(scene)
    assert topics["/events"]["times"] == [int(t_ns[k]) for k, _, _ in happened]
    assert happened[0][2] == "status: ok"
    # the shipped layout shows what the file holds: each plotted field is a /metrics field
    layout = json.loads(LAYOUT_PATH.read_text())
    panels = layout["configById"]
    plotted = [p["value"] for c in panels.values() for p in c.get("paths", [])]
    assert len(plotted) >= 5 and all(p.split(".")[0] in topics for p in plotted)
    first = {"/metrics": json.loads(read["schemas"]["/metrics"])["properties"],
             "/safety": json.loads(topics["/safety"]["data"][0])}
    assert all(p.split(".", 1)[1] in first[p.split(".")[0]] for p in plotted)
    assert panels["RosOut!hubo-events"]["topicToRender"] in topics
    three_d = panels["3D!hubo"]["topics"]
    assert three_d["/robot_description"]["visible"] and set(three_d) <= set(topics)
    assert set(re.findall(r'"([^"]+![^"]+)"', json.dumps(layout["layout"]))) == set(panels)


def test_an_old_run_without_a_start_time_exports_at_its_files_time(run_dir, tmp_path):
    """A log written before started_utc was recorded (and one with a hostile start time)
    exports with its file's modification time as the start, and the metadata says so."""
    from hubo_cli.viz.mcap_export import METADATA_NAME, export_mcap
    from hubo_cli.viz.rerun_export import export_rrd

    old = tmp_path / "old"
    old.mkdir()
    (old / "log.csv").write_bytes((run_dir / "log.csv").read_bytes())
    # the Parquet copy as first written: every number a float, NaN where missing, no metadata
    pl.read_parquet(run_dir / "log.parquet").with_columns(
        pl.col(pl.Int64, pl.Int8).cast(pl.Float64).fill_null(np.nan)).write_parquet(
        old / "log.parquet")
    sidecar = json.loads((run_dir / "log.json").read_text())
    del sidecar["started_utc"], sidecar["hubo_cli_version"]
    (old / "log.json").write_text(json.dumps(sidecar))
    mtime_ns = 1_600_000_000_123_456_789
    os.utime(old / "log.parquet", ns=(mtime_ns, mtime_ns))
    scene = load_scene(old)
    assert scene.log.started_utc is None and scene.start_utc_ns == mtime_ns
    assert np.array_equal(scene.log["estop_mode_code"], load_log(run_dir)["estop_mode_code"],
                          equal_nan=True)
    assert "modification time of log.parquet" in scene.start_source
    read = _read_mcap(export_mcap(scene, tmp_path / "old.mcap").path)
    assert export_rrd(scene, tmp_path / "old.rrd").periods == len(scene)
    assert read["topics"]["/tf"]["times"][0] == mtime_ns
    meta = read["metadata"][METADATA_NAME]
    assert "modification time" in meta["start_time_source"] and meta["hubo_cli_version"] == ""
    for hostile in ("yesterday", "0001-01-01T00:00:00Z", "9999-12-31T23:59:59Z", 12, None, ""):
        (old / "log.json").write_text(json.dumps(sidecar | {"started_utc": hostile}))
        scene = load_scene(old)
        assert scene.start_utc_ns == mtime_ns and "modification time" in scene.start_source
    (old / "log.json").write_text(json.dumps(sidecar | {"started_utc": "2026-01-02T03:04:05"}))
    assert load_scene(old).start_utc_ns == 1767323045 * 10 ** 9  # no zone given: UTC


def test_events_are_the_estop_latches_and_releases_and_the_status_changes(scene):
    from hubo_cli.viz.scene import events

    n = len(scene)
    flags = [["estop"] if 100 <= k < 150 or k >= n - 3 else ["slowing"] for k in range(n)]
    codes = np.zeros(n)
    codes[100:150] = 6  # e-stopped
    codes[150:160] = 42  # no such status: its number
    codes[n - 3:] = 7  # servo off
    log = dataclasses.replace(scene.log, flags=flags,
                              columns={**scene.log.columns, "status_code": codes})
    got = events(dataclasses.replace(scene, log=log))
    assert got == [(0, "info", "status: ok"), (100, "warning", "e-stop latched"),
                   (100, "warning", "status: e-stopped"), (150, "info", "e-stop released"),
                   (150, "warning", "status: code 42"), (160, "info", "status: ok"),
                   (n - 3, "warning", "e-stop latched"), (n - 3, "warning", "status: servo off")]


def test_the_hole_is_drawn_on_the_walls_face_toward_the_robot(scene):
    hole = scene.hole_world_m
    assert len(hole) > 10
    wall = scene.walls[0]
    near_face_x = wall["centre_world_m"][0] - wall["size_m"][0] / 2
    # as cut, the points are in the wall (the bit's crossing), hidden by the opaque box
    assert np.all(hole[:, 0] > near_face_x - 1e-6)
    shown = scene.hole_on_face_world_m()
    assert np.allclose(shown[:, 0], near_face_x - 0.001)  # 1 mm in front, on the robot's side
    assert np.array_equal(shown[:, 1:], hole[:, 1:])
    assert scene.T_world_torso[0, 0, 3] < near_face_x
    # a wall turned 90 degrees about z (its thin side along y) with the robot on its -y side
    c = np.cos(np.pi / 4)
    turned = dataclasses.replace(scene, walls=[{
        "centre_world_m": [0.0, 0.5, 1.0], "quat_wxyz": [c, 0, 0, c], "size_m": [0.02, 1.0, 2.0]}],
        hole_world_m=np.array([[0.1, 0.505, 1.0], [3.0, 3.0, 3.0]]))
    moved = turned.hole_on_face_world_m()
    assert np.allclose(moved[0], [0.1, 0.5 - 0.01 - 0.001, 1.0])
    assert np.array_equal(moved[1], [3.0, 3.0, 3.0])  # in no wall: left alone


@pytest.mark.parametrize("damage", [
    {"scene": {"walls": [{"centre_world_m": [0.5, 0, 1]}]}},
    {"scene": {"walls": [{"centre_world_m": [None, 0, 1], "quat_wxyz": [0, 0, 0, 0],
                          "size_m": [0.01, 1, 1]}]}},
    {"scene": {"walls": {"a": 1}, "hole_world_m": [[1, 2]]}},
    {"scene": {"hole_world_m": "abc"}},
    {"scene": [], "tools": 3},
    {"scene": {"tools": ["drill"]}},
    "{not json", "[]", '{"metadata": []}', "log.parquet", "t_s",
    # review 20: times that go back, repeat or skip 11 days (no run logs them: one period a
    # row); a sidecar naming other joints than its columns, or counting no number of rows
    "t_s back", "t_s repeat", "t_s gap", ("joint_names", ["XXX"] * 24), ("joint_names", []),
    ("rows", -5), ("rows", "many")])
def test_export_of_a_damaged_run_folder_is_refused_in_one_line(run_dir, tmp_path, damage):
    bad = tmp_path / "bad"
    bad.mkdir()
    for name in ("log.csv", "log.json", "log.parquet"):
        (bad / name).write_bytes((run_dir / name).read_bytes())
    sidecar = json.loads((run_dir / "log.json").read_text())
    t_s = pl.read_parquet(run_dir / "log.parquet")["t_s"].to_numpy().copy()
    if isinstance(damage, dict):
        sidecar["metadata"] |= damage
        (bad / "log.json").write_text(json.dumps(sidecar))
    elif isinstance(damage, tuple):
        (bad / "log.json").write_text(json.dumps(sidecar | dict([damage])))
    elif damage == "log.parquet":
        (bad / "log.parquet").write_bytes(b"PAR1 not a parquet file")
    elif damage.startswith("t_s"):
        n = len(t_s)
        t_s = {"t_s": np.r_[t_s[:-1], 1e300], "t_s back": 10.0 - t_s,
               "t_s repeat": np.r_[t_s[:n // 2], t_s[n // 2 - 1:-1]],
               "t_s gap": t_s + 1e6 * (np.arange(n) > n // 2)}[damage]
        table = pl.read_parquet(run_dir / "log.parquet")
        table.with_columns(pl.Series("t_s", t_s)).write_parquet(bad / "log.parquet")
    else:
        (bad / "log.json").write_text(damage)
    result = CliRunner().invoke(main, ["export", str(bad), "--mcap", str(tmp_path / "x.mcap"),
                                       "--rrd", str(tmp_path / "x.rrd")])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert lines[0].startswith("error: ") and lines[1].startswith("hint: ") and len(lines) == 2
    assert "Traceback" not in result.output and "internal error" not in result.output
    assert not (tmp_path / "x.mcap").exists() and not (tmp_path / "x.rrd").exists()


def test_export_of_values_the_robot_cannot_have_says_their_rows(run_dir, tmp_path):
    """Review 20: a torso logged at 1e308 m or at infinity and a measured joint that is not a
    number were exported without a word. Each is said in one line naming its rows; a position
    the robot cannot be at is shown unknown (the torso estimated from the legs), so the export
    is whole and finite where the log was sound."""
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "log.json").write_bytes((run_dir / "log.json").read_bytes())
    table = pl.read_parquet(run_dir / "log.parquet")
    late = np.arange(table.height) >= 100  # rows 101 to the last
    table.with_columns(pl.Series("torso_x_m", np.where(late, 1e308, table["torso_x_m"])),
                       pl.Series("torso_z_m", np.where(late, np.inf, table["torso_z_m"])),
                       pl.Series("q_REB_rad", np.where(late, np.nan, table["q_REB_rad"]))
                       ).write_parquet(bad / "log.parquet")
    out = tmp_path / "x.mcap"
    result = CliRunner().invoke(main, ["export", str(bad), "--mcap", str(out), "--json"])
    assert result.exit_code == 0, result.output
    rows = f"rows 101-{table.height}"
    suspect = json.loads(result.stdout)["log_suspect"]
    assert len(suspect) == 2 and all(rows in line for line in suspect), suspect
    assert "torso position" in suspect[0] and "REB is not a number" in suspect[1]
    assert out.stat().st_size > 0
    scene = load_scene(bad)
    assert np.all(np.isfinite(scene.T_world_torso)) and scene.torso_estimated[late].all()
    assert np.array_equal(scene.T_world_torso[~late], load_scene(run_dir).T_world_torso[~late])
    result = CliRunner().invoke(main, ["export", str(bad), "--mcap", str(out), "--force"])
    warnings = [line for line in result.output.splitlines() if line.startswith("warning:")]
    assert result.exit_code == 0 and len(warnings) == 2 and rows in warnings[0]


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
                 # review 28: the renderer grew by 300 MB/s, deaf to Ctrl-C
                 ["replay", str(run_dir), "--video", "x.mp4", "--size", "100000x100000"],
                 ["replay", str(run_dir), "--video", "x.mp4", "--size", "7682x480"],
                 ["replay", str(run_dir), "--video", "x.mp4", "--speed", "0"],
                 # as teleop's floor (main: ten million frames a second of the run)
                 ["replay", str(run_dir), "--video", "x.mp4", "--speed", "1e-7"],
                 ["replay", str(run_dir), "--video", "x.mp4", "--from", "50"],
                 ["export", str(run_dir)]):
        result = runner.invoke(main, args)
        assert result.exit_code == 2, (args, result.output)
        assert "Traceback" not in result.output and "error" in result.output.lower()


def test_a_picture_is_even_and_from_16_px_to_8k():
    from hubo_cli.errors import InputError
    from hubo_cli.viz.camera import IMAGE_MAX_PX, check_image_size

    check_image_size(16, 16)
    check_image_size(*IMAGE_MAX_PX)
    for size in ((14, 16), (17, 16), (7682, 480), (640, 4322), (-640, 480)):
        with pytest.raises(InputError, match="is not usable"):
            check_image_size(*size)


def test_replay_command_writes_the_video_it_reports(run_dir, tmp_path):
    out = tmp_path / "small.mp4"
    result = CliRunner().invoke(main, ["replay", str(run_dir), "--video", str(out), "--size",
                                       "96x64", "--speed", "4", "--camera", "side", "--json"])
    assert result.exit_code == 0, result.output
    video = json.loads(result.stdout)["video"]
    run_s = len(load_log(run_dir)) * 0.005
    assert video["frames"] == round(run_s * 30 / 4)
    assert (video["width"], video["height"]) == (96, 64)
    assert out.read_bytes()[4:8] == b"ftyp"  # an MP4 container
    # without --json, off a terminal, it says how far it is: at the start and each quarter
    said = CliRunner().invoke(main, ["replay", str(run_dir), "--video", str(out), "--size",
                                     "96x64", "--to", "0.5", "--force"])
    assert said.exit_code == 0, said.output
    lines = [line for line in said.output.splitlines() if line.startswith("rendering")]
    assert lines[0] == "rendering small.mp4: 1/15 frames"
    assert lines[-1] == "rendering small.mp4: 15/15 frames" and len(lines) == 5


def _corners(lower, upper) -> np.ndarray:
    return np.array([[(lower, upper)[i >> k & 1][k] for k in range(3)] for i in range(8)])


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_video_camera_frames_the_whole_robot_and_the_hole(scene, preset):
    """Every corner of the box round the robot's links over the run and the hole is in the
    picture between the caption and legend bars, and the box fills it (a corner near an edge:
    the camera is not just far away)."""
    from hubo_cli.viz.legend import bar_height_px
    from hubo_cli.viz.video import FRAMING_SAMPLES, framing_camera

    width, height = 320, 240
    bar = bar_height_px(height)
    with KinematicReplay(scene) as replay:
        camera = framing_camera(scene, replay, preset, width, height)
        periods = np.linspace(0, len(scene) - 1, FRAMING_SAMPLES).round().astype(int)
        lower, upper = replay.robot_bounds_m(periods)
    lower = np.minimum(lower, scene.hole_world_m.min(axis=0))
    upper = np.maximum(upper, scene.hole_world_m.max(axis=0))
    px = camera.project(_corners(lower, upper))
    assert np.all(np.isfinite(px))
    assert np.all((px[:, 0] >= 0) & (px[:, 0] <= width) & (px[:, 1] >= bar)
                  & (px[:, 1] <= height - bar))
    gaps = np.r_[px[:, 0], width - px[:, 0], px[:, 1] - bar, height - bar - px[:, 1]]
    assert gaps.min() < 10  # fitted, not merely far away
    # the old framing (the preset's distance from the hole) cut the default view's feet off
    if preset == DEFAULT_PRESET:
        old = camera_for(preset, scene.focus_world_m(), scene.working_arm, width, height)
        assert np.any(old.project(_corners(lower, upper))[:, 1] > height)


def test_the_snapshot_camera_frames_the_robots_links(scene):
    from hubo_cli.drivers.snapshot import snapshot_camera
    from hubo_cli.viz.camera import body_bounds_m
    from hubo_cli.viz.legend import bar_height_px

    with KinematicReplay(scene) as replay:
        replay.show(len(scene) - 1)
        p, cid, robot = replay._p, replay._cid, replay._robot
        meta = {"tools": scene.tools, "hole_world_m": scene.hole_world_m.tolist()}
        camera = snapshot_camera(p, cid, meta, scene.tool_world_m[-1], robot, 640, 480)
        lower, upper = body_bounds_m(p, robot, cid)
    assert upper[2] - lower[2] > 1.0  # head to feet
    px = camera.project(_corners(lower, upper))
    assert np.all((px >= 0) & (px <= [640, 480 - bar_height_px(480)]))


def test_frames_and_snapshots_carry_a_legend_and_the_path_is_kept_only_while_cutting(
        scene, run_dir, tmp_path):
    from PIL import Image

    from hubo_cli.viz.legend import BAR_RGB, bar_height_px
    from hubo_cli.viz.video import Overlay, drawn_periods, legend_entries, render_still

    labels = [e.label for e in legend_entries(trail=True)]
    assert labels == ["goal path", "bit measured", "bit, last 1 s", "hole cut", "bit now"]
    for picture in (np.asarray(Image.open(render_still(scene, tmp_path / "still.png",
                                                       width=320, height=240))),
                    np.asarray(Image.open(run_dir / "snapshot.png"))):
        bar = picture[-bar_height_px(picture.shape[0]) + 2:]
        light = np.all(np.abs(bar.astype(int) - BAR_RGB) <= 3, axis=2)
        assert 0.5 < light.mean() < 0.98  # the bar, with words and samples on it
    assert drawn_periods(scene).all()  # no cutting column: every period
    cutting = np.zeros(len(scene))
    cutting[100:200] = 1
    log = dataclasses.replace(scene.log, columns={**scene.log.columns, "cutting": cutting})
    cut = dataclasses.replace(scene, log=log)
    assert np.array_equal(np.flatnonzero(drawn_periods(cut)), np.arange(100, 200))
    overlay = Overlay(cut, camera_for(DEFAULT_PRESET, scene.focus_world_m(), "right-arm"))
    assert "bit, last 1 s" in [e.label for e in overlay.entries]
    # the inset magnifies the cut: every kept point and the hole inside its square
    inset = overlay.inset
    assert inset.shown and inset.size >= 0.3 * 480
    inside = np.vstack([inset.tool[100:200], inset.hole])
    assert np.all((inside[:, 0] >= inset.left) & (inside[:, 0] <= inset.left + inset.size)
                  & (inside[:, 1] >= inset.top) & (inside[:, 1] <= inset.top + inset.size))
    extent = inside.max(axis=0) - inside.min(axis=0)
    assert extent.max() > 0.5 * inset.size  # magnified to fill it
    assert 0 < inset.bar_px <= inset.size / 2
    # the caption bar is red while e-stopped, dark otherwise
    from hubo_cli.viz.video import ALARM_BAR_RGB

    status = scene.log.status
    assert (status == 6).any() and (status == 0).any()  # the sway's wall trips the wrist stop
    blank = np.zeros((480, 640, 3), dtype=np.uint8)
    for k in (int(np.argmax(status == 6)), int(np.argmax(status == 0))):
        corner = tuple(overlay.draw(blank, k)[2, 636])
        assert (corner == ALARM_BAR_RGB) == (status[k] == 6), (k, status[k], corner)


def test_fit_camera_frames_any_box_and_refuses_an_unknown_one():
    from hubo_cli.errors import InputError
    from hubo_cli.viz.camera import fit_camera

    rng = np.random.default_rng(38)
    for k in range(60):
        size = 10.0 ** rng.uniform(-3, 1.7, 3) * (rng.random(3) > 0.15)  # some sides flat
        lower = rng.uniform(-5, 5, 3)
        preset = sorted(PRESETS)[k % len(PRESETS)]
        w, h = (640, 480) if k % 2 else (96, 64)
        top, bottom = (0, 0) if k % 3 else (12, 12)
        camera = fit_camera(preset, lower, lower + size, "left-arm" if k % 4 else "right-arm",
                            w, h, top_px=top, bottom_px=bottom)
        px = camera.project(_corners(lower, lower + size))
        assert np.all((px[:, 0] >= 0) & (px[:, 0] <= w) & (px[:, 1] >= top)
                      & (px[:, 1] <= h - bottom)), (k, size, preset)
    for bad in ([np.nan, 0, 0], [0, np.inf, 0]):
        with pytest.raises(InputError):
            fit_camera(DEFAULT_PRESET, [0, 0, 0], bad)


def test_the_caption_names_the_tasks_step(scene, tmp_path):
    from hubo_cli.viz.video import step_names

    steps = np.full(len(scene), np.nan)
    steps[10:] = 2
    log = dataclasses.replace(scene.log, columns={**scene.log.columns, "step_code": steps})
    folder = tmp_path / "run"
    folder.mkdir()
    stepped = dataclasses.replace(scene, log=log, run_dir=folder)
    assert step_names(stepped) == []  # no task.toml: the number only
    assert "step 3 " in stepped.caption(20, step_names(stepped))
    for garbage in ("[[steps]]\nname = ", "steps = 3", b"\xff\xfe[[steps]]"):
        (folder / "task.toml").write_bytes(garbage if isinstance(garbage, bytes)
                                           else garbage.encode())
        assert step_names(stepped) == []
    (folder / "task.toml").write_text('[[steps]]\nname = "raise"\n[[steps]]\nname = "in"\n'
                                      '[[steps]]\nname = "cut"\n')
    names = step_names(stepped)
    assert names == ["raise", "in", "cut"]
    assert "step 3/3 cut" in stepped.caption(20, names)
    assert "step" not in stepped.caption(5, names)  # no step logged yet
    assert "step 3 " in stepped.caption(20, names[:2])  # a step the names do not reach
