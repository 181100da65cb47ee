"""A stdout whose reader has gone (``hubo ... | head -1``, ``| true``) changes nothing: the
command goes on to its own end and exit code, and prints no error (round 16; main: exit 1 with
no message from click, or "error: Broken pipe" exit 2, whatever the run had done)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

HUBO = Path(sys.executable).with_name("hubo")


@pytest.mark.skipif(sys.platform == "win32", reason="a closed pipe as on POSIX")
def test_a_closed_stdout_keeps_the_exit_code_and_says_nothing():
    process = subprocess.Popen([str(HUBO), "fk", "right-arm", "0", "0", "0", "0", "0", "0",
                                "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()  # the reader is gone before anything is written
    err = process.stderr.read()
    process.wait(timeout=120)
    assert (process.returncode, err) == (0, b"")


def test_the_quiet_stdout_drops_writes_once_the_pipe_is_closed():
    import os

    from hubo_cli.cli.main import _Stdout

    read_fd, write_fd = os.pipe()
    os.close(read_fd)
    try:
        raw = _Stdout(write_fd)
        assert raw.write(b"x" * 100) == 100 and raw.gone  # dropped, no BrokenPipeError
        assert raw.write(b"more") == 4
    finally:
        os.close(write_fd)
