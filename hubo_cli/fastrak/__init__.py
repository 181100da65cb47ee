"""Polhemus FASTRAK input: the serial protocol, recordings, and a device emulator.

- :mod:`.records`: output-list layouts, vectorised record decoding and the record encoder.
- :mod:`.parser`: the resynchronising byte-stream parser shared by live and replayed input.
- :mod:`.reader`: the live pyserial reader (explicit configuration, probe, staleness, reconnect).
- :mod:`.capture`: raw captures and pose logs (CSV), their readers and writers.
- :mod:`.emulator`: a FASTRAK on a pty or serial port, for tests and hardware-free runs.
- :mod:`.source`: :class:`PoseSource`, the one interface the live reader and recordings share
  (the teleoperation reads them as an input device, :mod:`hubo_cli.input.fastrak`).
- :mod:`.opener`: :func:`open_source`, which opens a recording or a live port as a source.
"""

from hubo_cli.fastrak.opener import open_source
from hubo_cli.fastrak.source import PoseSample, PoseSource, SourceStats

__all__ = ["PoseSample", "PoseSource", "SourceStats", "open_source"]
