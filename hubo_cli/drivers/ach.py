"""A ctypes binding to libach, the shared-memory IPC library every hubo-ach client links.

libach (github golems/ach, BSD) is found at the path in the ``HUBO_LIBACH`` environment
variable, else with ``ctypes.util.find_library("ach")`` (a lab's installed libach), else as
``<environment>/lib/libach.so`` (``make`` builds it there from ``third_party/ach``); without
it :func:`load_libach` raises :class:`LibachMissing` (a :class:`~hubo_cli.errors.DeviceError`,
exit 3) saying how to install it. Only the calls a hubo-ach client needs are bound:
``ach_open``, ``ach_put``, ``ach_get``, ``ach_close``, ``ach_result_to_string``, and
``ach_create`` / ``ach_unlink`` for tests and the fake daemon.

Channels live in ``/dev/shm/achshm-<name>``. Timeouts of ``ach_get`` are absolute times on the
channel's condition-variable clock, ``CLOCK_MONOTONIC`` for every channel created with libach's
defaults since ach 1.0 (``ach_create`` and ``ach mk``); this binding creates channels with the
defaults and waits on that clock.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import time
from dataclasses import dataclass

from hubo_cli.errors import DeviceError, quoted

LIBACH_ENV = "HUBO_LIBACH"
INSTALL_HINT = (
    "install libach (github.com/golems/ach: ./configure && make && sudo make install, or build "
    "src/libach*.c into libach.so) and, if it is not on the loader path, set HUBO_LIBACH to "
    "its path (make, in a checkout, builds it into the project's environment)")
DRY_RUN_HINT = "without a robot use --dry-run"  # the hardware driver's way round it

# enum ach_status (ach/generic.h)
ACH_OK = 0
ACH_OVERFLOW = 1
ACH_STALE_FRAMES = 5
ACH_MISSED_FRAME = 6
ACH_TIMEOUT = 7
ACH_EEXIST = 8
ACH_ENOENT = 9
# ach_get options
ACH_O_WAIT = 0x01
ACH_O_LAST = 0x02

# ach_channel_t is 128 bytes in ach 2.0 and smaller before; libach only fills it in, so a larger
# zeroed, 8-byte aligned buffer is valid for every version.
_CHANNEL_WORDS = 128


class LibachMissing(DeviceError):
    """libach cannot be loaded (not installed, or HUBO_LIBACH points nowhere).

    Args:
        tried: what was looked for (a path or the library name).
        reason: why loading failed.
        otherwise: the hint's way to go on without libach, where the caller has one.
    """

    def __init__(self, tried: str, reason: str, otherwise: str = "") -> None:
        super().__init__(f"libach is not available ({tried}: {reason}); the hardware driver "
                         "talks to hubo-ach through it",
                         hint=f"{INSTALL_HINT}; {otherwise}" if otherwise else INSTALL_HINT)
        self.tried = tried
        self.reason = reason


class AchError(DeviceError):
    """An ach call failed.

    Args:
        call: the libach function.
        channel: the channel name.
        status: the ``enum ach_status`` value.
        text: libach's name for it.
        hint: what to do.
    """

    def __init__(self, call: str, channel: str, status: int, text: str, hint: str = "") -> None:
        super().__init__(f"{call}({quoted(channel)}) failed: {text} ({status})", hint=hint)
        self.call = call
        self.channel = channel
        self.status = status


class Timespec(ctypes.Structure):
    """``struct timespec`` (Linux, 64-bit ``time_t`` and ``long``)."""

    _fields_ = [("tv_sec", ctypes.c_int64), ("tv_nsec", ctypes.c_long)]


@dataclass(frozen=True)
class Libach:
    """The loaded library with its prototypes set (from :func:`load_libach`)."""

    cdll: ctypes.CDLL
    path: str

    def result_string(self, status: int) -> str:
        """libach's name for a result (``ach_result_to_string``)."""
        text = self.cdll.ach_result_to_string(int(status))
        return text.decode() if text else f"ach status {status}"

    def create(self, name: str, frame_count: int, frame_size: int) -> None:
        """Create a channel (``ach_create`` with libach's default attributes).

        Raises:
            AchError: e.g. ``ACH_EEXIST`` when the channel exists.
        """
        status = self.cdll.ach_create(name.encode(), frame_count, frame_size, None)
        if status != ACH_OK:
            raise AchError("ach_create", name, status, self.result_string(status),
                           hint="remove the old channel (ach rm NAME) or pick another name")

    def unlink(self, name: str) -> None:
        """Remove a channel (``ach_unlink``); a channel that does not exist is not an error."""
        status = self.cdll.ach_unlink(name.encode())
        if status not in (ACH_OK, ACH_ENOENT):
            raise AchError("ach_unlink", name, status, self.result_string(status))

    def open(self, name: str) -> AchChannel:
        """Open an existing channel (``ach_open``).

        Raises:
            AchError: the channel does not exist (``ACH_ENOENT``) or cannot be mapped.
        """
        return AchChannel(self, name)


def _prototype(lib: ctypes.CDLL) -> None:
    c_chan = ctypes.c_void_p
    lib.ach_open.argtypes = [c_chan, ctypes.c_char_p, ctypes.c_void_p]
    lib.ach_open.restype = ctypes.c_int
    lib.ach_close.argtypes = [c_chan]
    lib.ach_close.restype = ctypes.c_int
    lib.ach_put.argtypes = [c_chan, ctypes.c_void_p, ctypes.c_size_t]
    lib.ach_put.restype = ctypes.c_int
    lib.ach_get.argtypes = [c_chan, ctypes.c_void_p, ctypes.c_size_t,
                            ctypes.POINTER(ctypes.c_size_t), ctypes.POINTER(Timespec),
                            ctypes.c_int]
    lib.ach_get.restype = ctypes.c_int
    lib.ach_result_to_string.argtypes = [ctypes.c_int]
    lib.ach_result_to_string.restype = ctypes.c_char_p
    lib.ach_create.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_size_t,
                               ctypes.c_void_p]
    lib.ach_create.restype = ctypes.c_int
    lib.ach_unlink.argtypes = [ctypes.c_char_p]
    lib.ach_unlink.restype = ctypes.c_int


_LOADED: dict[str, Libach] = {}


def load_libach(otherwise: str = "") -> Libach:
    """Load libach (``HUBO_LIBACH`` if set, else the system's ``libach``, else the one ``make``
    built into this environment: :func:`_libach_path`), once per path.

    Args:
        otherwise: how the caller goes on without libach, added to the hint (the hardware
            driver: :data:`DRY_RUN_HINT`; the stand-in daemons have no way round it).

    Raises:
        LibachMissing: no library, or one without libach's functions.
    """
    path = _libach_path()
    if not path:
        raise LibachMissing("libach", "not found on the loader path nor in this environment "
                            "and HUBO_LIBACH is unset", otherwise)
    if path in _LOADED:
        return _LOADED[path]
    try:
        cdll = ctypes.CDLL(path)
        _prototype(cdll)
    except OSError as exc:
        raise LibachMissing(path, str(exc), otherwise) from None
    except AttributeError as exc:  # a library without ach_* symbols
        raise LibachMissing(path, f"not libach: {exc}", otherwise) from None
    _LOADED[path] = Libach(cdll, path)
    return _LOADED[path]


def _libach_path() -> str | None:
    """Where libach is: ``HUBO_LIBACH``, the loader path's, or the environment's own copy
    (``make`` builds the vendored source into ``<sys.prefix>/lib``); None if nowhere."""
    own = os.path.join(sys.prefix, "lib", "libach.so")
    return (os.environ.get(LIBACH_ENV) or ctypes.util.find_library("ach")
            or (own if os.path.isfile(own) else None))


def libach_status() -> tuple[bool, str]:
    """(available, what): whether libach loads, and its path or the reason it does not."""
    try:
        return True, load_libach().path
    except LibachMissing as exc:
        return False, exc.message


def deadline_after(timeout_s: float) -> Timespec:
    """The absolute ``CLOCK_MONOTONIC`` time ``timeout_s`` from now, as libach waits on it."""
    ns = time.clock_gettime_ns(time.CLOCK_MONOTONIC) + max(0, int(timeout_s * 1e9))
    return Timespec(ns // 1_000_000_000, ns % 1_000_000_000)


class AchChannel:
    """One open channel. Use :meth:`Libach.open`; close with :meth:`close` or ``with``.

    Args:
        lib: the loaded library.
        name: the channel name (``hubo-ref``, ``hubo-state``, ...).
    """

    def __init__(self, lib: Libach, name: str) -> None:
        self.lib = lib
        self.name = name
        self._chan = (ctypes.c_uint64 * _CHANNEL_WORDS)()
        self._open = False
        status = lib.cdll.ach_open(ctypes.byref(self._chan), name.encode(), None)
        if status != ACH_OK:
            hint = ("is hubo-ach's daemon running (it creates the channels)? "
                    f"`ach mk {name}` creates it by hand" if status == ACH_ENOENT else "")
            raise AchError("ach_open", name, status, lib.result_string(status), hint=hint)
        self._open = True

    def put(self, data: bytes | ctypes.Structure) -> None:
        """Write one frame (``ach_put``).

        Raises:
            AchError: e.g. ``ACH_OVERFLOW`` when the frame is larger than the channel's frames.
        """
        self._require_open()
        buffer = bytes(data)
        status = self.lib.cdll.ach_put(ctypes.byref(self._chan), buffer, len(buffer))
        if status != ACH_OK:
            raise AchError("ach_put", self.name, status, self.lib.result_string(status))

    def get(self, buffer: ctypes.Array | ctypes.Structure, *, last: bool = True,
            wait_s: float | None = None) -> tuple[int, int]:
        """Read one frame into ``buffer`` (``ach_get``).

        Args:
            buffer: a writable ctypes object; frames larger than it give ``ACH_OVERFLOW``.
            last: the newest frame (``ACH_O_LAST``); else the next one not yet read.
            wait_s: wait up to this long for a new frame (``ACH_O_WAIT`` with an absolute
                ``CLOCK_MONOTONIC`` deadline); None returns at once.

        Returns:
            (status, frame size in bytes): ``ACH_OK`` or ``ACH_MISSED_FRAME`` with a frame
            copied; ``ACH_STALE_FRAMES`` (nothing new) or ``ACH_TIMEOUT`` with none.

        Raises:
            AchError: any other result (overflow, corrupt channel, ...).
        """
        self._require_open()
        size = ctypes.c_size_t(0)
        options = ACH_O_LAST if last else 0
        deadline = None
        if wait_s is not None:
            options |= ACH_O_WAIT
            deadline = deadline_after(wait_s)
        status = self.lib.cdll.ach_get(ctypes.byref(self._chan), ctypes.byref(buffer),
                                       ctypes.sizeof(buffer), ctypes.byref(size),
                                       None if deadline is None else ctypes.byref(deadline),
                                       options)
        if status in (ACH_OK, ACH_MISSED_FRAME, ACH_STALE_FRAMES, ACH_TIMEOUT):
            return status, size.value
        hint = (f"a frame of {size.value} bytes does not fit {ctypes.sizeof(buffer)}: the writer "
                "uses another struct version" if status == ACH_OVERFLOW else "")
        raise AchError("ach_get", self.name, status, self.lib.result_string(status), hint=hint)

    def close(self) -> None:
        """Close the channel (``ach_close``); safe to call twice."""
        if self._open:
            self._open = False
            self.lib.cdll.ach_close(ctypes.byref(self._chan))

    def _require_open(self) -> None:
        if not self._open:
            raise DeviceError(f"ach channel {quoted(self.name)} is closed",
                              hint="open it again with Libach.open")

    def __enter__(self) -> AchChannel:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
