"""Output files of the commands (``--video``, ``--rrd``, ``--mcap``, ``--out``, ``--csv``): no
command ever destroys a file.

:class:`OutputFile` checks an output path before any work: an existing file is refused unless
``--force``, and even with ``--force`` the path may not be one of the command's inputs (or
another of its outputs) nor a file of a run folder. "The same file" is judged by device and
inode, so a hard link or a symlink to an input is caught like the input itself.
:meth:`OutputFile.writing` (and :func:`replacing` for a run's own files) hands the writer a
temporary name beside the file and renames it into place only when the writer has finished: a
failed or interrupted write leaves the old file (or none), never a half one.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from hubo_cli.errors import HuboError, InputError

# A folder holding one of these is a run folder: runs.MARKER, session.SUMMARY_NAME and
# control.log.META_NAME (named here to keep this module light; tests/test_outputs.py checks them)
RUN_FOLDER_FILES = (".hubo-run", "summary.json", "log.json")

# a writer that fails with less than this free beside its file ran out of space
NEARLY_FULL_BYTES = 4 * 1024 * 1024
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)  # the disk is the device in trouble (exit 3)

_UMASK = os.umask(0o022)
os.umask(_UMASK)


def _stat(path: Path) -> os.stat_result | None:
    try:
        return os.stat(path)
    except (OSError, ValueError):
        return None


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether ``a`` and ``b`` name the same file: the same absolute path, or (both existing)
    the same device and inode (a hard link, a symlink, another spelling of the path)."""
    if os.path.abspath(a) == os.path.abspath(b):
        return True
    sa, sb = _stat(Path(a)), _stat(Path(b))
    return sa is not None and sb is not None and (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


def is_run_folder(folder: str | Path) -> bool:
    """Whether ``folder`` holds a run (its marker, summary.json or log.json)."""
    return any(os.path.lexists(Path(folder) / name) for name in RUN_FOLDER_FILES)


def _files_in(folder: Path) -> list[Path]:
    try:
        return [p for p in folder.iterdir() if p.is_file()]
    except OSError:
        return []


def _folders_of(path: Path) -> list[Path]:
    """The folder of ``path`` and, if it is a symlink, the folder of its target."""
    try:
        return [path.parent, path.resolve().parent]
    except (OSError, RuntimeError):  # a symlink loop
        return [path.parent]


class OutputFile:
    """The path of an output option, checked at once (see :meth:`check`).

    Args:
        path: the file to write.
        option: the option's name, for messages (``--out``, ``--video``).
        inputs: files (and folders: every file in them) the command reads.
        others: the command's other output files (this one must not be one of them).
        force: write over an existing file (never over an input or a run's file).

    Raises:
        InputError: the path is refused; nothing was written.
    """

    def __init__(self, path: str | Path, *, option: str = "--out",
                 inputs: tuple[str | Path, ...] = (), others: tuple[str | Path | None, ...] = (),
                 force: bool = False) -> None:
        self.path = Path(path)
        self.option = option
        self.inputs = tuple(Path(p) for p in inputs)
        self.others = tuple(Path(p) for p in others if p is not None)
        self.force = force
        self.check()

    def _refuse(self, why: str, hint: str) -> InputError:
        return InputError(f"{self.option} {self.path} {why}; nothing was written", hint=hint)

    def check(self) -> None:
        """Refuse the path: a folder, one of the inputs (by name, device and inode), a file of
        a run folder, a device or pipe, an existing file without ``force``, or a folder that is
        missing or not writable.

        Raises:
            InputError: what is wrong and how to fix it.
        """
        path = self.path
        if not path.name or path.name in (".", ".."):
            raise self._refuse("is not a file name", "give a file name, e.g. out.csv")
        try:
            os.lstat(path)
        except FileNotFoundError:
            pass
        except OSError as exc:  # a name too long, a file where a folder should be, ...
            raise self._refuse(f"cannot be written: {exc.strerror or exc}",
                               "choose another path") from None
        if path.is_dir():
            raise self._refuse("is a folder, not a file", "give a file name inside it")
        for source in self.inputs:
            for other in (source, *(_files_in(source) if source.is_dir() else ())):
                if same_file(path, other):
                    how = "" if os.path.abspath(path) == os.path.abspath(other) else (
                        f" {other} (the same file by device and inode)")
                    raise self._refuse(f"is the input file{how}",
                                       "write the output to another file")
        for other in self.others:
            if same_file(path, other):
                raise self._refuse(f"is also the file of another output ({other})",
                                   "give each output its own file")
        exists = os.path.lexists(path)
        if exists and any(is_run_folder(folder) for folder in _folders_of(path)):
            raise self._refuse("is a file of a run folder (never written over, not even with "
                               "--force)", "write the output to a file outside the run folder")
        if exists and path.exists() and not path.is_file():
            raise self._refuse("is not a regular file (a device, pipe or socket)",
                               "give the path of a file")
        if exists and not self.force:
            raise self._refuse("exists", "choose another name, delete the file, or add --force")
        parent = path.parent
        if not parent.is_dir():
            raise self._refuse(f"cannot be written: the folder {parent} does not exist",
                               "create the folder first or choose another path")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise self._refuse(f"cannot be written: the folder {parent} is not writable",
                               "choose a writable path")

    def writing(self, *, keep_partial: bool = False) -> contextlib.AbstractContextManager[Path]:
        """A temporary path to write; renamed to :attr:`path` at the end of the ``with`` after
        the checks pass again (a file that appeared meanwhile is not written over without
        ``force``). See :func:`replacing`."""
        return replacing(self.path, check=self.check, clobber=self.force,
                         keep_partial=keep_partial)


@contextlib.contextmanager
def replacing(path: str | Path, *, check: Callable[[], None] | None = None,
              clobber: bool = True, keep_partial: bool = False) -> Iterator[Path]:
    """Yield a new temporary file beside ``path`` (same suffix, so writers that go by the
    suffix work) for the caller to write; rename it to ``path`` when the ``with`` block ends.

    Args:
        path: the file to (re)place.
        check: called just before the rename (it may refuse).
        clobber: replace an existing ``path``; else an existing one is refused.
        keep_partial: when the block fails and nothing is at ``path``, keep what was written
            there (a recording cut short is still data), and when the rename is refused keep
            the temporary file (named in the error); otherwise a failure leaves no trace.

    Raises:
        InputError: the temporary file cannot be made, or the rename is refused or fails.
    """
    path = Path(path)
    stem = path.stem.encode()[:64].decode(errors="ignore")  # the name stays short enough
    suffix = path.suffix if len(path.suffix.encode()) <= 16 else ""
    try:
        fd, name = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".part{suffix}", dir=path.parent)
    except OSError as exc:
        raise InputError(f"cannot write in {path.parent}: {exc.strerror or exc}",
                         hint="choose a writable path") from None
    os.close(fd)
    temporary = Path(name)
    try:
        yield temporary
    except BaseException as exc:
        with contextlib.suppress(OSError, InputError):
            if keep_partial and temporary.stat().st_size and not os.path.lexists(path):
                _rename(temporary, path, clobber=False)
        with contextlib.suppress(OSError):
            temporary.unlink()
        if isinstance(exc, OSError) and exc.errno is not None and exc.filename is not None \
                and os.fspath(exc.filename) == str(temporary):
            # the user's file is what could not be written (a full disk), not a name they
            # never gave (the temporary one is gone)
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        if isinstance(exc, HuboError) and str(temporary) in exc.message:  # a writer's failure
            exc.message = exc.message.replace(str(temporary), str(path))
            exc.args = (str(exc),)
        raise
    try:
        if check is not None:
            check()
        _rename(temporary, path, clobber=clobber)
    except InputError as exc:
        if keep_partial:  # refused at the end: the recording stays, under its temporary name
            raise InputError(f"{exc.message} (what was written is kept in {temporary})",
                             hint=exc.hint) from None
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise
    with contextlib.suppress(OSError):
        temporary.unlink()  # the hard link made without ``clobber``


def _rename(temporary: Path, path: Path, *, clobber: bool) -> None:
    """Give ``temporary`` the mode a new file (or the replaced one) has and move it to
    ``path``, atomically; without ``clobber`` an existing ``path`` is never replaced."""
    try:
        old = os.lstat(path)
        mode = old.st_mode & 0o777 if not os.path.islink(path) else 0o666 & ~_UMASK
    except OSError:
        mode = 0o666 & ~_UMASK
    try:
        os.chmod(temporary, mode)
        if clobber:
            os.replace(temporary, path)
            return
        try:
            os.link(temporary, path)  # fails if ``path`` exists: no window to write over it
        except FileExistsError:
            raise InputError(f"{path} appeared while it was written; nothing was written over",
                             hint="choose another name, or add --force") from None
        except OSError:  # a file system without hard links
            if os.path.lexists(path):
                raise InputError(f"{path} appeared while it was written; nothing was written "
                                 "over", hint="choose another name, or add --force") from None
            os.replace(temporary, path)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}",
                         hint="free disk space or choose a writable path") from None


def write_error(path: str | Path, exc: OSError, hint: str) -> Exception:
    """The error to raise when writing ``path`` failed with ``exc``: a full disk stays an
    OSError naming ``path`` (the command line's exit 3, "free space on that disk"; a writer
    that gives no errno, as polars, is judged by the space left there), anything else an
    InputError with the system's reason and ``hint`` (exit 2)."""
    if exc.errno in DISK_FULL:
        return OSError(exc.errno, exc.strerror, str(path))
    if exc.errno is None:
        failure = writer_failure(path, "the writer", exc)
        if isinstance(failure, OSError):
            return failure
    return InputError(f"cannot write {path}: {exc.strerror or exc}", hint=hint)


def nearly_full(folder: str | Path) -> bool:
    """Less than :data:`NEARLY_FULL_BYTES` free in ``folder`` (False when it cannot be told)."""
    try:
        return shutil.disk_usage(folder).free < NEARLY_FULL_BYTES
    except OSError:
        return False


def require_room(path: str | Path) -> None:
    """Raise the disk's ENOSPC for ``path`` before a writer that cannot fail cleanly starts on
    a nearly full disk (review 22: Rerun's ``save`` there hung at times in its native code,
    deaf to SIGTERM and Ctrl-C, and left its temporary file)."""
    if nearly_full(Path(path).parent):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


def writer_failure(path: str | Path, writer: str, exc: BaseException) -> Exception:
    """The error to raise when a library's writer (ffmpeg, Rerun, MCAP) failed writing
    ``path`` with ``exc``, which says only that it stopped (a broken pipe, a writer thread
    gone): a full disk (less than :data:`NEARLY_FULL_BYTES` free there) is an OSError
    ENOSPC, which the command line reports as the device in trouble (exit 3); anything else
    one line naming the file and the writer (exit 1)."""
    if nearly_full(Path(path).parent):
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return HuboError(f"cannot write {path}: {writer} stopped ({reason})",
                     hint="check the folder and try again")
