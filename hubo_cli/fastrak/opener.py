"""Opening a pose source: a recording or a live FASTRAK, behind one :class:`PoseSource`.

Kept apart from :mod:`hubo_cli.fastrak.source` (the interface), which the recording reader
(:mod:`.capture`) and the live reader (:mod:`.reader`) both implement, so that neither imports
the module that imports it.
"""

from __future__ import annotations

from pathlib import Path

from hubo_cli.errors import InputError
from hubo_cli.fastrak.source import PoseSource

LIVE_ONLY_OPTIONS = frozenset({
    "baud", "fmt", "output_list", "units", "capture", "reconnect", "settle_s", "probe_timeout_s",
    "first_record_timeout_s", "silence_timeout_s", "reconnect_timeout_s", "read_timeout_s",
    "command_gap_s"})
"""Options of the live reader that a replay ignores."""


def open_source(replay: str | Path | None = None, port: str | None = None,
                **options) -> PoseSource:
    """Open a pose source: a recording (``replay``) or a live FASTRAK on a serial ``port``.

    Args:
        replay: a raw capture (decoded through the same parser as the live path) or a pose-log
            CSV; the kind is recognised from the file's first bytes.
        port: serial device of a live FASTRAK (or an emulator's pty).
        **options: for a replay, ``stations`` (keep only these) and ``plausibility`` (the
            live-port options below are accepted and ignored); for a port, the
            :class:`hubo_cli.fastrak.reader.FastrakReader` options (``baud``, ``fmt``,
            ``output_list``, ``units``, ``stations``, ``capture``, ``reconnect``, ...).

    Raises:
        InputError: neither or both of replay/port, a missing or garbled recording.
        DeviceError: the port is absent, closed or the tracker does not answer.
    """
    if (replay is None) == (port is None):
        raise InputError("give exactly one pose source: a recording or a serial port",
                         hint="use --replay FILE or --port DEV")
    if replay is not None:
        from hubo_cli.fastrak.capture import open_replay

        # a recording's header says its format and units; the live-port settings do not apply
        replay_options = {k: v for k, v in options.items() if k not in LIVE_ONLY_OPTIONS}
        return open_replay(replay, **replay_options)
    from hubo_cli.fastrak.reader import FastrakReader

    return FastrakReader(port, **options)
