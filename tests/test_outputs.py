"""No file is ever destroyed (issue 32, case 4).

A task file's ``name`` cannot lead a run folder out of ``runs/`` (traversal in many spellings,
absolute paths, control and bidi characters, very long names, empty names, names of dots: all
generated here). Every output option (``fastrak decode --out``, ``ik --batch --out``,
``record --out/--csv``, ``export --rrd/--mcap``, ``replay --video``) refuses an existing file
without ``--force`` and, even with it, its input and a run's own files in any spelling (other
paths, symlinks, hard links): exit 2, one error line, no traceback, the file byte-identical. An
output is written under a temporary name and renamed, so a failed write leaves the old file.
"""

import errno
import os
import stat
import unicodedata
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.errors import InputError
from hubo_cli.outputs import RUN_FOLDER_FILES, OutputFile, replacing
from hubo_cli.resources import data_file
from hubo_cli.runs import MARKER, folder_name, make_run_dir
from hubo_cli.tasks.spec import load_task

CAPTURE = data_file("trajectories", "two-hand-free.fastrak")
RUN_FILES = ("summary.json", "log.json", "log.csv", "log.parquet", MARKER)

# -- run-folder names from task files --------------------------------------------------------

TRAVERSALS = ["../victim", "../../victim", "x/../../victim", "x/../../../tmp/victim",
              "..\\..\\victim", "x\\..\\..\\victim", "./../victim", "..././victim", ".../victim",
              "x//..//..//victim", "x/./.././../victim", "%2e%2e%2fvictim", "..%2f..%2fvictim",
              "\uff0e\uff0e\uff0fvictim", "\u2024\u2024/victim", "victim/..", "~/victim",
              "/victim", "//victim", "/tmp/victim", "/etc/passwd", "..", "../", "x/..",
              "..\u202e/victim", "\u202e../../victim"]
FORMAT_CHARACTERS = "\u00ad\u061c\u200b\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067" \
                    "\u2068\u2069\ufeff"
ONLY_DOTS = ["", ".", "..", "...", "." * 300, ". .", "._.", "-", "_", "/", "\\"]


def _hostile_names(rng, absolute_victim: Path) -> list[str]:
    names = list(TRAVERSALS) + list(ONLY_DOTS)
    names += [str(absolute_victim), str(absolute_victim) + "/", f"x/../..{absolute_victim}"]
    names += [f"cut{chr(c)}slot" for c in [*range(0x20), 0x7F, *range(0x80, 0xA0)]]
    names += [f"cut{c}slot" for c in FORMAT_CHARACTERS]
    names += ["a" * 300, "\u00e9" * 400, "\u65e5" * 1000, "x/" * 200 + "victim",
              "e\u0301" * 300, "\U0001f600" * 100, "a" * 100_000]
    pool = list("./\\ ~%_-x") + [chr(c) for c in range(0x20)] + list(FORMAT_CHARACTERS)
    for _ in range(60):  # random mixes of the pieces above
        names.append("".join(rng.choice(pool, size=int(rng.integers(1, 400)))))
    return names


def _toml_string(text: str) -> str:
    """``text`` as a TOML basic string, every non-printable-ASCII character escaped."""
    out = []
    for c in text:
        if c in '"\\':
            out.append("\\" + c)
        elif " " <= c <= "~":
            out.append(c)
        else:
            out.append(f"\\U{ord(c):08X}")
    return '"' + "".join(out) + '"'


def _task_file(path: Path, name: str) -> Path:
    path.write_text(f"name = {_toml_string(name)}\n" + """
[stance]
wall_distance_mm = 470.0
centre_mm = [0.0, 0.0]
[[steps]]
kind = "move"
to_mm = [0.0, 0.0]
depth_mm = -50.0
duration_s = 0.5
""")
    return path


def _snapshot(root: Path) -> dict[Path, bytes | None]:
    return {p: (p.read_bytes() if p.is_file() else None) for p in root.rglob("*")}


def test_a_task_files_name_never_leads_the_run_folder_out_of_runs(tmp_path, monkeypatch):
    """The run folder of ``hubo task`` is ``runs/<time>-task-<name>`` made from the task file's
    ``name`` (cli/task.py and tasks/runner.py: ``f"task-{spec.name}"``): for every hostile
    name it is one new folder directly inside runs/, its name a single safe component, and
    nothing outside runs/ is created or changed."""
    work = tmp_path / "work"
    (work / "victim").mkdir(parents=True)
    victims = [work / "victim", tmp_path / "victim", tmp_path / "abs-victim"]
    for victim in victims:
        victim.mkdir(exist_ok=True)
        for name in RUN_FILES:
            (victim / name).write_text(f"the user's own {name}\n")
    tasks = tmp_path / "tasks"
    tasks.mkdir()
    names = _hostile_names(np.random.default_rng(32), tmp_path / "abs-victim")
    files = [_task_file(tasks / f"t{k}.toml", name) for k, name in enumerate(names)]
    monkeypatch.chdir(work)
    before = _snapshot(tmp_path)
    made = set()
    for name, file in zip(names, files, strict=True):
        spec = load_task(file)
        assert spec.name == name  # the task keeps its name; only the folder's is made safe
        run_dir = make_run_dir(f"task-{spec.name}")
        assert run_dir.resolve().parent == (work / "runs").resolve(), (name, run_dir)
        assert run_dir.is_dir() and run_dir not in made
        made.add(run_dir)
        component = run_dir.name
        assert "/" not in component and "\\" not in component and ".." not in component
        assert not any(unicodedata.category(c) in ("Cc", "Cf", "Zs", "Zl", "Zp")
                       for c in component), repr(component)
        assert len(component.encode()) <= 128 and not component.startswith(".")
    after = _snapshot(tmp_path)
    assert {p: v for p, v in after.items() if (work / "runs") not in p.parents
            and p != work / "runs"} == before


def test_hubo_task_reserves_its_run_folder_inside_runs(tmp_path, monkeypatch):
    """Through the command line: ``hubo task run`` reserves its run folder from the task's
    name before pre-flight; with a hostile name it is inside runs/, and the task (out of
    reach: refused in pre-flight, exit 4, in about a second) leaves every other file as it
    was."""
    import hubo_cli.runs as runs

    made = []

    def spy(command, out=None):
        made.append(make_run_dir(command, out))
        return made[-1]

    monkeypatch.setattr(runs, "make_run_dir", spy)
    (tmp_path / "victim").mkdir()
    (tmp_path / "victim" / "log.csv").write_text("the user's own log\n")
    monkeypatch.chdir(tmp_path)
    names = ["x/../../victim", "../victim", str(tmp_path / "victim"), "..\u202e/victim",
             "...", "", "x/" * 200 + "victim"]
    for k, name in enumerate(names):
        task = _task_file(tmp_path / f"t{k}.toml", name)
        task.write_text(task.read_text().replace("to_mm = [0.0, 0.0]", "to_mm = [900.0, 0.0]"))
        before = _snapshot(tmp_path)
        _invoke(["task", "run", str(task), "--driver", "ideal"], 4, "refused in pre-flight",
                [])
        assert made[-1].resolve().parent == (tmp_path / "runs").resolve(), (name, made[-1])
        after = _snapshot(tmp_path)
        before.pop(tmp_path / "runs", None)
        assert {p: v for p, v in after.items() if p != tmp_path / "runs"} == before
    assert len(made) == len(names) and not any((tmp_path / "runs").iterdir())


def test_folder_name_keeps_ordinary_names_and_marks_the_folder(tmp_path, monkeypatch):
    for name in ("task-cut-rectangle", "sim", "push-wall-left-estop", "task-cut_slot.v2",
                 "task-\u65e5\u672c"):
        assert folder_name(name) == name
    monkeypatch.chdir(tmp_path)
    run_dir = make_run_dir("task-x/../../victim")
    assert (run_dir / MARKER).read_text().strip() == "task-x_victim" == run_dir.name[16:]
    assert make_run_dir("task-x/../../victim", run_dir) == run_dir  # --out again: reused


def test_a_symlink_in_runs_is_never_followed(tmp_path, monkeypatch):
    """A link planted where the next run folder would go (to a user's folder, or dangling) is
    passed over; and a name that still resolved outside runs/ would be refused."""
    import hubo_cli.runs as runs

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runs.time, "strftime", lambda *a: "20260101-000000")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "log.csv").write_text("mine\n")
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "20260101-000000-task-a").symlink_to(tmp_path / "mine")
    (tmp_path / "runs" / "20260101-000000-task-a-2").symlink_to(tmp_path / "elsewhere")
    run_dir = make_run_dir("task-a")
    assert run_dir == Path("runs/20260101-000000-task-a-3") and run_dir.is_dir()
    assert sorted(p.name for p in (tmp_path / "mine").iterdir()) == ["log.csv"]
    assert not (tmp_path / "elsewhere").exists()
    monkeypatch.setattr(runs, "folder_name", lambda command: "x/../../escape")
    with pytest.raises(InputError, match="outside runs/"):
        make_run_dir("task-a")
    assert not (tmp_path / "escape").exists()


# -- output options ---------------------------------------------------------------------------


def _fake_run(folder: Path) -> Path:
    """A run folder's files (the refusals come before anything is read)."""
    folder.mkdir()
    for name in RUN_FILES:
        (folder / name).write_text(f"the run's {name}\n")
    return folder


def _batch_csv(path: Path) -> Path:
    from hubo_cli.kinematics import get_limb
    from hubo_cli.kinematics.batch_csv import POSE_COLUMNS

    limb = get_limb("right-arm", "hand")
    T = limb.fk_batch(limb.random_q(np.random.default_rng(4), 3)).reshape(-1, 16)
    path.write_text(",".join(POSE_COLUMNS) + "\n"
                    + "".join(",".join(map(repr, row.tolist())) + "\n" for row in T))
    return path


def _invoke(argv: list[str], code: int, text: str, watched: list[Path]):
    """Run ``hubo argv``: exit ``code``, one ``error:`` line holding ``text`` (when code is not
    0), no traceback, every watched file byte-identical."""
    before = {p: p.read_bytes() for p in watched}
    result = CliRunner().invoke(main, argv)
    output = result.output
    assert "Traceback" not in output and "internal error" not in output, output
    assert result.exit_code == code, (argv, output)
    if code:
        errors = [line for line in output.splitlines() if line.lower().startswith("error:")]
        assert len(errors) == 1 and text in errors[0], (argv, output)
    for path, data in before.items():
        assert path.read_bytes() == data, path
    return result


# command -> (argv for an output path, the command's input file or run folder)
COMMANDS = {
    "fastrak-decode": lambda d, out: (["fastrak", "decode", str(d / "cap.fastrak"), "--out", out],
                                      d / "cap.fastrak"),
    "ik-batch": lambda d, out: (["ik", "right-arm", "--batch", str(d / "in.csv"), "--out", out],
                                d / "in.csv"),
    "record": lambda d, out: (["record", "--port", "/dev/null", "--out", out], None),
    "record-csv": lambda d, out: (["record", "--port", "/dev/null", "--out",
                                   str(d / "new.fastrak"), "--csv", out], None),
    "export-rrd": lambda d, out: (["export", str(d / "run"), "--rrd", out], d / "run"),
    "export-mcap": lambda d, out: (["export", str(d / "run"), "--mcap", out], d / "run"),
    "replay-video": lambda d, out: (["replay", str(d / "run"), "--video", out], d / "run"),
    "input-generate": lambda d, out: (["input", "generate", "3", "--duration", "2", "--out",
                                       out], None),
}


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    """A folder with a capture, a batch CSV, a run and a user's file; the cwd."""
    import shutil

    shutil.copy(CAPTURE, tmp_path / "cap.fastrak")
    _batch_csv(tmp_path / "in.csv")
    _fake_run(tmp_path / "run")
    (tmp_path / "mine.out").write_text("the user's own file\n")
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _hostile_targets(d: Path, source: Path | None) -> list[tuple[str, bool, str]]:
    """(output path, --force, expected text) that every command refuses with exit 2."""
    run = d / "run"
    targets = [(str(d / "mine.out"), False, "exists"),
               (str(d), True, ""),  # click's own check (Error: ... is a directory)
               (str(d / "no-such-folder" / "x.out"), True, "does not exist"),
               (str(d / ("a" * 300 + ".out")), True, "File name too long"),
               (str(d / "mine.out" / "x.out"), True, "Not a directory")]
    os.mkfifo(d / "fifo")
    targets.append((str(d / "fifo"), True, "not a regular file"))
    for name in RUN_FILES:  # a run's own files, even with --force
        targets.append((str(run / name), True, ""))
    (d / "link-to-summary").symlink_to(run / "summary.json")
    targets.append((str(d / "link-to-summary"), True, ""))
    if source is not None and source.is_file():
        (d / "hard-link").hardlink_to(source)
        (d / "sym-link").symlink_to(source)
        (d / "sub" / "chain").symlink_to(d / "sym-link")
        targets += [(str(p), True, "input file") for p in (
            source, d / "." / source.name, d / "sub" / ".." / source.name, Path(source.name),
            d / "hard-link", d / "sym-link", d / "sub" / "chain")]
    if source is not None and source.is_dir():  # a run: a hard link to one of its files too
        (d / "hard-link").hardlink_to(run / "log.parquet")
        targets.append((str(d / "hard-link"), True, "input file"))
    return targets


@pytest.mark.parametrize("command", list(COMMANDS))
def test_output_options_refuse_hostile_targets(command, workspace):
    d = workspace
    _, source = COMMANDS[command](d, "x")
    watched = [p for p in d.rglob("*") if p.is_file() and not p.is_symlink()]
    for out, force, text in _hostile_targets(d, source):
        argv, _ = COMMANDS[command](d, out)
        _invoke(argv + ["--force"] * force, 2, text, watched)
    names = sorted(p.name for p in d.rglob("*"))
    assert not [n for n in names if ".part" in n]  # no temporary file left


def test_two_outputs_of_one_command_are_not_the_same_file(workspace):
    d = workspace
    _invoke(["export", "run", "--rrd", "x.out", "--mcap", "./x.out"], 2, "another output", [])
    _invoke(["record", "--port", "/dev/null", "--out", "mine.out", "--csv", "mine.out",
             "--force"], 2, "another output", [d / "mine.out"])
    assert not (d / "x.out").exists()


@pytest.mark.parametrize("command", ["fastrak-decode", "ik-batch"])
def test_force_replaces_a_file_whole_keeping_its_mode(command, workspace):
    d = workspace
    target = d / "mine.out"
    os.chmod(target, 0o640)
    hard_link_to_run = d / "run-log-link.out"  # not this command's input: replaced, the run's
    hard_link_to_run.hardlink_to(d / "run" / "log.csv")  # file itself stays as it was
    run_before = _snapshot(d / "run")
    for out in (target, hard_link_to_run):
        argv, _ = COMMANDS[command](d, str(out))
        _invoke(argv, 2, "exists", [out])
        _invoke(argv + ["--force"], 0, "", [])
        assert out.read_bytes() != b"the user's own file\n" and out.stat().st_nlink == 1
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert _snapshot(d / "run") == run_before
    new = d / "new.out"
    _invoke(COMMANDS[command](d, str(new))[0], 0, "", [])
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(new.stat().st_mode) == 0o666 & ~umask
    assert not [p for p in d.iterdir() if ".part" in p.name]


def test_a_failed_write_leaves_the_old_file_and_no_half_file(workspace, monkeypatch):
    """The pose-log writer writes half its file and then fails (a full disk): exit 2, the old
    file is whole, no temporary file is left."""
    import hubo_cli.fastrak.capture as capture

    def half_then_full(path, batch):
        Path(path).write_text("t_s,station,x\n0.0,1,")
        raise InputError(f"cannot write {path}: No space left on device", hint="free space")

    monkeypatch.setattr(capture, "write_pose_log", half_then_full)
    _invoke(["fastrak", "decode", "cap.fastrak", "--out", "mine.out", "--force"], 2,
            "No space left", [workspace / "mine.out"])
    assert not [p for p in workspace.iterdir() if ".part" in p.name]


# -- the library: a checked path and a writer that renames at the end --------------------------


def test_replacing_keeps_the_old_file_when_the_writer_fails_or_is_interrupted(tmp_path):
    old = tmp_path / "a.mp4"
    old.write_bytes(b"good")
    for failure in (OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()):
        with pytest.raises(type(failure)), replacing(old) as temporary:
            assert temporary.parent == tmp_path and temporary.suffix == ".mp4"
            temporary.write_bytes(b"ha")
            raise failure
        assert old.read_bytes() == b"good"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4"]
    with replacing(old) as temporary:
        temporary.write_bytes(b"new")
    assert old.read_bytes() == b"new" and sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4"]
    for name in ("\u65e5" * 80 + ".csv", "x." + "y" * 250):  # 244 and 252 bytes: allowed names
        with replacing(tmp_path / name) as temporary:
            temporary.write_bytes(b"long")
        assert (tmp_path / name).read_bytes() == b"long"


def test_a_recording_cut_short_is_kept_only_where_no_file_was(tmp_path):
    new, old = tmp_path / "new.fastrak", tmp_path / "old.fastrak"
    old.write_bytes(b"good")
    for path in (new, old):
        with pytest.raises(ConnectionError), \
                OutputFile(path, force=True).writing(keep_partial=True) as temporary:
            temporary.write_bytes(b"partial")
            raise ConnectionError
    assert new.read_bytes() == b"partial" and old.read_bytes() == b"good"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new.fastrak", "old.fastrak"]
    with pytest.raises(InputError, match="exists.*kept in") as refused, \
            OutputFile(tmp_path / "late.fastrak").writing(keep_partial=True) as temporary:
        temporary.write_bytes(b"a whole recording")
        (tmp_path / "late.fastrak").write_bytes(b"appeared meanwhile")
    assert temporary.read_bytes() == b"a whole recording" and str(temporary) in str(refused.value)
    assert (tmp_path / "late.fastrak").read_bytes() == b"appeared meanwhile"


def test_a_file_that_appears_during_the_write_is_not_written_over(tmp_path):
    path = tmp_path / "out.csv"
    out = OutputFile(path)
    with pytest.raises(InputError, match="exists"), out.writing() as temporary:
        temporary.write_text("ours")
        path.write_text("theirs")
    assert path.read_text() == "theirs" and len(list(tmp_path.iterdir())) == 1


def test_the_run_folder_files_are_the_ones_runs_write():
    from hubo_cli.control.log import META_NAME
    from hubo_cli.session import SUMMARY_NAME

    assert set(RUN_FOLDER_FILES) == {MARKER, SUMMARY_NAME, META_NAME}


# -- a real run: export and replay refuse its files, replace a user's file whole ---------------


@pytest.fixture(scope="module")
def real_run(tmp_path_factory) -> Path:
    """A 0.3 s run on the ideal driver (well under a second)."""
    from hubo_cli.control.target import Target
    from hubo_cli.model import load_model
    from hubo_cli.posture import home_posture
    from hubo_cli.session import RunSetup, run

    class Hold(Target):
        def __init__(self, q) -> None:
            self.q = q

        def __call__(self, t_s, state):
            return self.q, {}

    model = load_model()
    setup = RunSetup("hold", model, tools={"right-arm": "drill"}, driver="ideal",
                     out=tmp_path_factory.mktemp("outputs") / "run", duration_s=0.3)
    return run(setup, Hold(home_posture(model))).run_dir


def test_export_and_replay_never_write_over_the_run_and_replace_a_file_whole(real_run,
                                                                             tmp_path):
    from hubo_cli.viz.mcap_export import read_mcap_summary
    from hubo_cli.viz.scene import load_scene

    run_files = [p for p in real_run.iterdir() if p.is_file()]
    for name, option in (("summary.json", "--mcap"), ("log.parquet", "--rrd"),
                         ("log.csv", "--video")):
        command = "replay" if option == "--video" else "export"
        _invoke([command, str(real_run), option, str(real_run / name), "--force"], 2,
                "input file", run_files)
    assert len(load_scene(real_run)) > 0  # the run still replays
    mcap, video = tmp_path / "a.mcap", tmp_path / "a.mp4"
    for path in (mcap, video):
        path.write_text("the user's own file\n")
    _invoke(["export", str(real_run), "--mcap", str(mcap)], 2, "exists", [mcap])
    _invoke(["export", str(real_run), "--mcap", str(mcap), "--force"], 0, "", run_files)
    assert read_mcap_summary(mcap)["/joint_states"]["messages"] == len(load_scene(real_run))
    _invoke(["replay", str(real_run), "--video", str(video), "--size", "64x48"], 2, "exists",
            [video])
    _invoke(["replay", str(real_run), "--video", str(video), "--size", "64x48", "--force"], 0,
            "", run_files)
    assert video.read_bytes()[4:8] == b"ftyp"  # an MP4 now
    # a name ffmpeg cannot take a format from: one line, nothing written (it was 11 lines of
    # ffmpeg's own errors)
    for name in ("a.out", "a", "a.mp4.tmp", "a.MKV"):
        _invoke(["replay", str(real_run), "--video", str(tmp_path / name), "--size", "64x48"],
                2, "must end in .mp4", run_files)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap", "a.mp4"]


def test_a_summary_and_a_sweep_table_are_written_whole_or_not_at_all(tmp_path, monkeypatch):
    """A write that fails half way (a full disk) keeps the former file and leaves no part."""
    from hubo_cli.runs import write_json
    from hubo_cli.sweep import write_table

    summary = tmp_path / "summary.json"
    write_json(summary, {"ok": True})
    table = tmp_path / "sweep.csv"
    write_table([], table)
    before = summary.read_text(), table.read_text()

    real_open = open

    def failing_open(path, mode="r", *args, **kwargs):
        f = real_open(path, mode, *args, **kwargs)
        if "w" in mode and ".part" in str(path):
            f.write("{half" if str(path).endswith(".json") else "command,se")
            f.flush()
            raise OSError(errno.ENOSPC, "No space left on device")
        return f

    monkeypatch.setattr("builtins.open", failing_open)
    monkeypatch.setattr(Path, "write_text", lambda self, text, **kw: failing_open(self, "w"))
    with pytest.raises(InputError, match="cannot write .*summary.json: No space left"):
        write_json(summary, {"ok": False})
    with pytest.raises(InputError, match="cannot write .*sweep.csv: No space left"):
        write_table([], table)
    monkeypatch.undo()
    assert (summary.read_text(), table.read_text()) == before
    assert not [p for p in tmp_path.iterdir() if ".part" in p.name]


@pytest.mark.parametrize("exporter", ["mcap_export"])  # rerun_export alike (its import: 1.3 s)
def test_a_writer_that_stops_is_a_full_disk_or_one_line(tmp_path, monkeypatch, exporter):
    """The Rerun and MCAP writers (and ffmpeg) say only that they stopped: on a full disk
    (under 4 MiB free) that is the disk's ENOSPC (exit 3, as a run's log says it), otherwise
    one line naming the file and the writer; it was an internal error (exit 1)."""
    import importlib
    import shutil

    from hubo_cli.errors import HuboError
    from hubo_cli.outputs import writer_failure

    module = importlib.import_module(f"hubo_cli.viz.{exporter}")
    pytest.importorskip("rerun" if exporter == "rerun_export" else "foxglove")
    export = module.export_rrd if exporter == "rerun_export" else module.export_mcap

    import logging

    quiet = []

    def stops(*args):
        quiet.append(logging.getLogger("foxglove.mcap").getEffectiveLevel() > logging.CRITICAL)
        raise RuntimeError("File-writer thread shut down prematurely\nand more")

    monkeypatch.setattr(module, "_write_rrd" if exporter == "rerun_export" else "_write_mcap",
                        stops)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=1000))
    with pytest.raises(OSError) as full:
        export(None, tmp_path / "x.out")
    assert full.value.errno == errno.ENOSPC and full.value.filename == str(tmp_path / "x.out")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=10**9))
    with pytest.raises(HuboError, match=r"^cannot write .*x\.out: the .* writer stopped "
                                        r"\(File-writer thread shut down prematurely\)$"):
        export(None, tmp_path / "x.out")
    assert writer_failure(tmp_path / "v.mp4", "ffmpeg", OSError()).message.endswith(
        "ffmpeg stopped (OSError)")
    # the MCAP SDK's log is quiet while it writes (after a failed write it logged a line per
    # message: 13,830 for a 20 mm cut) and as before afterwards
    assert quiet == [True, True] or exporter == "rerun_export"
    assert logging.getLogger("foxglove").level == logging.NOTSET


def _fill_then_fail(path, *args, **kwargs):
    """A writer on a full disk: part of the file, then ENOSPC (as the OS says it)."""
    with open(path, "wb") as f:
        f.write(b"half a fi")
    raise OSError(errno.ENOSPC, "No space left on device", str(path))


@pytest.mark.parametrize("case", ["ik-batch", "input-generate", "fastrak-decode"])
def test_an_output_on_a_full_disk_is_the_device_exit_3_and_leaves_no_file(tmp_path, monkeypatch,
                                                                          case):
    """Review 21: on a full 2 MB tmpfs, ``hubo ik --batch --out`` said "cannot write ...: None"
    and the pose-log writers (``input generate``, ``fastrak decode``) "choose a writable
    output path", each exit 2 (bad input); a full disk is the device's trouble, exit 3 with
    the disk's hint, as a run, an export and the workspace map say it, and no part is left."""
    import shutil

    import polars as pl

    out = tmp_path / "out.csv"
    if case == "ik-batch":  # polars gives the OS's words and no errno
        batch = tmp_path / "batch.csv"
        batch.write_text("T00,T01,T02,T03,T10,T11,T12,T13,T20,T21,T22,T23,T30,T31,T32,T33\n"
                         "1,0,0,0.3,0,1,0,-0.2,0,0,1,-0.2,0,0,0,1\n")

        def polars_full(self, path, *args, **kwargs):
            Path(path).write_bytes(b"line,q1")
            raise OSError("No space left on device (os error 28)")

        usage = shutil.disk_usage(tmp_path)
        monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=1000))
        monkeypatch.setattr(pl.DataFrame, "write_csv", polars_full)
        argv = ["ik", "right-arm", "--batch", str(batch), "--out", str(out)]
    else:
        monkeypatch.setattr(Path, "write_text", _fill_then_fail)
        argv = (["input", "generate", "3", "--duration", "1", "--out", str(out)]
                if case == "input-generate" else
                ["fastrak", "decode", str(data_file("trajectories", "two-hand-free.fastrak")),
                 "--out", str(out)])
    for json_flag in ([], ["--json"]):
        result = CliRunner().invoke(main, argv + json_flag)
        assert result.exit_code == 3, result.output
        assert f"error: No space left on device ({out})" in result.output
        assert "hint: free space on that disk or write elsewhere" in result.output
        assert "Traceback" not in result.output
        assert sorted(p.name for p in tmp_path.iterdir()) == (["batch.csv"] if case == "ik-batch"
                                                               else [])


def test_a_workspace_map_on_a_full_disk_leaves_no_part_of_its_file(tmp_path, monkeypatch):
    """Review 21: ``hubo workspace-map --out`` on a full tmpfs ended exit 3 and left its run
    folder with an empty workspace.npz; the file is now written through a temporary name."""
    from types import SimpleNamespace

    from hubo_cli.workspace import files

    monkeypatch.setattr(files, "_per_x", lambda m: {})
    monkeypatch.setattr(np, "savez_compressed", _fill_then_fail)
    grid = SimpleNamespace(x_m=np.zeros(1), y_m=np.zeros(1), z_m=np.zeros(1))
    one = SimpleNamespace(arm="right", R_N_E=np.eye(3), grid=grid, masks=np.zeros(1),
                          reachable=np.zeros(1))
    with pytest.raises(OSError) as full:
        files.save_npz([one], tmp_path / "workspace.npz")
    assert full.value.errno == errno.ENOSPC and full.value.filename == str(
        tmp_path / "workspace.npz")
    assert list(tmp_path.iterdir()) == []


def test_a_rerun_recording_is_not_started_on_a_nearly_full_disk(tmp_path, monkeypatch):
    """Review 22: on a full disk Rerun's own save at times never returned (its native code,
    deaf to SIGTERM and Ctrl-C: `hubo export RUN --rrd` hung until SIGKILL) and left its
    temporary file; the disk's ENOSPC is now raised before the SDK is touched."""
    import shutil

    from hubo_cli.viz import rerun_export

    def untouched(*args):
        raise AssertionError("the SDK was started")

    monkeypatch.setattr(rerun_export, "require", untouched)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=4 * 2**20 - 1))
    with pytest.raises(OSError) as full:
        rerun_export.export_rrd(None, tmp_path / "x.rrd")
    assert full.value.errno == errno.ENOSPC and full.value.filename == str(tmp_path / "x.rrd")
    assert list(tmp_path.iterdir()) == []


def test_a_plot_on_a_full_disk_names_its_file(tmp_path):
    """Round 30: ``hubo workspace-map`` on a full 200 kB tmpfs said "No space left on device"
    naming no file (matplotlib's own OSError, injected here as it raised it); every plot is now
    written through ``save_figure``, whose failed write names the plot (a full disk: exit 3's
    OSError) or is one input error."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hubo_cli.plots import save_figure

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    fig = plt.figure()
    fig.savefig = full
    with pytest.raises(OSError) as raised:
        save_figure(fig, tmp_path / "plot.png")
    assert raised.value.errno == errno.ENOSPC
    assert raised.value.filename == str(tmp_path / "plot.png")
    with pytest.raises(InputError, match="cannot write .*no-such-folder/plot.png"):
        save_figure(plt.figure(), tmp_path / "no-such-folder" / "plot.png")
    assert plt.get_fignums() == []  # closed either way
