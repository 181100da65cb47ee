"""The resynchronising FASTRAK byte-stream parser, shared by the live reader and replays.

Bytes are fed as they arrive, each chunk with its receive time. A record is decided only when all
its bytes are present; an offset that does not start a valid record costs exactly one byte (good
data is never flushed), and a partial record at the end of a chunk waits for the next chunk.
Feeding a stream in any chunking gives the same records as decoding it in one piece
(:func:`decode_stream`), which is what replays use.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.fastrak.records import (
    DEFAULT_PLAUSIBILITY,
    Plausibility,
    RecordBatch,
    RecordLayout,
    scan,
    station_table,
)


class StreamParser:
    """Incremental parser for one FASTRAK stream.

    Args:
        layout: the record layout the device was configured with.
        units: ``cm`` or ``in``.
        stations: stations whose records are accepted (others count as bad bytes).
        plausibility: limits a record must meet.

    Attributes:
        good_records, bad_bytes, bytes_fed: running totals.
    """

    def __init__(self, layout: RecordLayout, units: str, stations=(1, 2, 3, 4),
                 plausibility: Plausibility = DEFAULT_PLAUSIBILITY) -> None:
        self.layout = layout
        self.units = units
        self.plausibility = plausibility
        self._station_ok = station_table(stations)
        self._pending = b""
        self._offset = 0  # stream offset of self._pending[0]
        self.good_records = 0
        self.bad_bytes = 0
        self.bytes_fed = 0
        self._last_t = 0.0

    @property
    def pending_bytes(self) -> int:
        """Bytes held back because they may start a record that is not complete yet."""
        return len(self._pending)

    def feed(self, data: bytes, t_s: float) -> tuple[RecordBatch, int]:
        """Add bytes received at ``t_s`` (seconds); return (new records, bytes skipped).

        Each new record is stamped with ``t_s``, the time its last byte arrived, and its stream
        offset.
        """
        self.bytes_fed += len(data)
        self._last_t = float(t_s)
        buf = self._pending + data if self._pending else bytes(data)
        result = scan(buf, self.layout, self.units, final=False, plaus=self.plausibility,
                      station_ok=self._station_ok)
        batch = result.batch
        if len(batch):
            batch.t_s = np.full(len(batch), float(t_s))
            batch.offset += self._offset
        self._pending = buf[result.consumed:]
        self._offset += result.consumed
        self.good_records += len(batch)
        self.bad_bytes += result.bad_bytes
        return batch, result.bad_bytes

    def finish(self) -> tuple[RecordBatch, int]:
        """End of stream: decide the held-back bytes; return (records among them, bytes skipped).

        Records found here are stamped with the time of the last feed.
        """
        buf, self._pending = self._pending, b""
        result = scan(buf, self.layout, self.units, final=True, plaus=self.plausibility,
                      station_ok=self._station_ok)
        batch = result.batch
        if len(batch):
            batch.t_s = np.full(len(batch), self._last_t)
            batch.offset += self._offset
        self._offset += len(buf)
        self.good_records += len(batch)
        self.bad_bytes += result.bad_bytes
        return batch, result.bad_bytes

    def reset(self) -> int:
        """Drop held-back bytes (after a reconnect); return how many were dropped."""
        dropped = len(self._pending)
        self._pending = b""
        self._offset += dropped
        self.bad_bytes += dropped
        return dropped


def decode_stream(data: bytes, chunk_ends: np.ndarray, chunk_times: np.ndarray,
                  layout: RecordLayout, units: str, stations=(1, 2, 3, 4),
                  plausibility: Plausibility = DEFAULT_PLAUSIBILITY) -> tuple[RecordBatch, int]:
    """Decode a whole recorded stream at once, exactly as chunk-by-chunk feeding would.

    Args:
        data: the concatenated bytes of every chunk.
        chunk_ends: (K,) exclusive end offset of each chunk in ``data`` (increasing).
        chunk_times: (K,) receive time of each chunk, seconds.
        layout, units, stations, plausibility: as for :class:`StreamParser`.

    Returns:
        The records (stamped with the receive time of the chunk holding their last byte) and
        the number of bytes skipped, a trailing partial record included.
    """
    result = scan(data, layout, units, stations, final=True, plaus=plausibility)
    batch = result.batch
    if len(batch):
        last_byte = batch.offset + layout.length - 1
        idx = np.searchsorted(np.asarray(chunk_ends), last_byte, side="right")
        idx = np.minimum(idx, len(chunk_times) - 1)
        batch.t_s = np.asarray(chunk_times, dtype=np.float64)[idx]
    return batch, result.bad_bytes
