"""Reading a file the user names that may be a FIFO or a device: opened without waiting for a
writer, each chunk waited for at most :data:`STREAM_WAIT_S` (a stream nobody writes is refused,
never waited on for ever: a blocking ``open`` or ``read`` of a FIFO holds the main thread where
Ctrl-C cannot reach it)."""

from __future__ import annotations

import os
import select
from pathlib import Path
from stat import S_ISREG

from hubo_cli.errors import InputError

STREAM_WAIT_S = 5.0  # a FIFO or device silent this long is refused


def open_nonblocking(path: str | Path) -> int:
    """A read-only file descriptor of ``path`` (a FIFO's open does not wait for a writer).

    Raises:
        OSError: as ``os.open`` (missing, a folder, no permission).
    """
    return os.open(path, os.O_RDONLY | os.O_NONBLOCK)


def reader_of(fd: int, path: str | Path):
    """``read(size)`` for the open ``fd``: a regular file is read as usual, a FIFO or device
    through :func:`read_stream`."""
    if S_ISREG(os.fstat(fd).st_mode):
        os.set_blocking(fd, True)
        return lambda size: os.read(fd, size)
    return lambda size: read_stream(fd, size, Path(path))


def refuse_special_files(*paths: str | Path) -> None:
    """Refuse a FIFO, device or folder where a run folder holds its own files (a log, its
    sidecar, a summary): a blocking read of one would hold the command where neither Ctrl-C
    nor SIGTERM reaches it (review 28: a FIFO as log.parquet held hubo export for ever). A
    path that does not exist is left to the caller.

    Raises:
        InputError: the first such path.
    """
    for path in paths:
        try:
            mode = os.stat(path).st_mode
        except OSError:
            continue
        if not S_ISREG(mode):
            raise InputError(f"{path} is not a plain file (a FIFO, device or folder)",
                             hint="a run folder's files are the ones hubo wrote: give the "
                                  "folder as it was written")


def read_stream(fd: int, size: int, path: Path) -> bytes:
    """Up to ``size`` bytes of a FIFO or device (fewer only at its end), waiting at most
    :data:`STREAM_WAIT_S` for each chunk.

    Raises:
        InputError: nothing arrived for :data:`STREAM_WAIT_S`.
    """
    chunks, got = [], 0
    while got < size:
        ready, _, _ = select.select([fd], [], [], STREAM_WAIT_S)
        if not ready:
            raise InputError(f"nothing arrived from {path} in {STREAM_WAIT_S:g} s",
                             hint="start the program writing to it first, or give a file")
        try:
            chunk = os.read(fd, size - got)
        except BlockingIOError:  # taken by another reader meanwhile
            continue
        if not chunk:  # its writer closed it
            break
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)
