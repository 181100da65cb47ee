"""A C locale (file names and file contents ASCII unless told otherwise): a task with a
non-ASCII name runs, its folder name is ASCII, and every file the run reads or writes is UTF-8
whatever the locale (issue 32, cases 4 and 9)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from task_files import raise_and_hold

from hubo_cli import runs

HUBO = Path(sys.executable).with_name("hubo")


def test_a_folder_name_keeps_only_what_the_file_system_encoding_writes(monkeypatch):
    monkeypatch.setattr(runs.sys, "getfilesystemencoding", lambda: "ascii")
    assert runs.folder_name("task-café ☕ ok") == "task-caf_ok"
    assert runs.folder_name("task-日本") == "task"
    monkeypatch.setattr(runs.sys, "getfilesystemencoding", lambda: "utf-8")
    assert runs.folder_name("task-café") == "task-café"


def test_a_task_with_a_non_ascii_name_runs_under_the_c_locale(tmp_path):
    task = tmp_path / "uni.toml"
    task.write_text(raise_and_hold("café ☕ 10° \u202e ok", 0.2), encoding="utf-8")
    env = {k: v for k, v in os.environ.items() if k not in ("LANG", "LC_ALL", "PYTHONUTF8",
                                                            "PYTHONIOENCODING")}
    env |= {"LANG": "C", "LC_ALL": "C", "PYTHONUTF8": "0"}
    done = subprocess.run([str(HUBO), "task", "run", str(task), "--driver", "ideal"],
                          cwd=tmp_path, env=env, capture_output=True, timeout=300)
    err = done.stderr.decode("ascii", "replace")
    assert done.returncode == 0, err
    assert b"Traceback" not in done.stderr and b"internal error" not in done.stderr
    (run,) = (tmp_path / "runs").iterdir()
    assert run.name.isascii() and run.name.endswith("task-caf_10_ok")
    summary = json.loads((run / "summary.json").read_text(encoding="utf-8"))
    assert summary["task"] == "café ☕ 10° \u202e ok" and summary["completed"]
    assert "café ☕" in (run / "task.toml").read_text(encoding="utf-8")
