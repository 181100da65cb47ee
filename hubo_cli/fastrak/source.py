"""One interface for operator poses, from a live FASTRAK or from a recording.

:func:`hubo_cli.fastrak.opener.open_source` returns a :class:`PoseSource`; its consumer (the
FASTRAK input device, :mod:`hubo_cli.input.fastrak`, which turns stations into hands for the
teleoperation) calls ``read_until(t_s)`` once per control cycle and checks
``is_stale(station, now_s)`` before trusting a station's latest pose.

Replay sources deliver every sample whose receive time is at or before ``t_s``, so a replay runs
as fast as the caller's clock (simulation time) or paced to real time. Live sources deliver
everything received so far and never block for more than a few milliseconds.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.fastrak.records import SUSPECT_STATUS, RecordBatch
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.timeline import OnTimeline, Timeline


@dataclass(frozen=True, eq=False)
class PoseSample:
    """One station's pose from one data record.

    Attributes:
        station: 1..4.
        T_tracker_sensor: (4,4) sensor pose in the tracker's (transmitter) frame, metres.
        status: the record's status character (``" "`` healthy, else the BIT error letter).
        t_s: receive time, seconds since the source started.
        stylus: stylus switch 0/1 when the output list carries item 16, else None.
    """

    station: int
    T_tracker_sensor: np.ndarray
    status: str
    t_s: float
    stylus: int | None = None

    @property
    def position_m(self) -> np.ndarray:
        """Sensor position in the tracker frame, metres."""
        return self.T_tracker_sensor[:3, 3]

    @property
    def suspect(self) -> bool:
        """True if the status letter flags an envelope or signal problem (x, y, j, k)."""
        return self.status in SUSPECT_STATUS


@dataclass
class SourceStats:
    """Counters of what a source has read.

    Attributes:
        good_records: records accepted by the parser.
        bad_bytes: bytes skipped while resynchronising (garbage, partial or implausible records).
        bytes_received: bytes read from the port or the capture.
        per_station: station -> records accepted.
        status_letters: status character -> records carrying it (healthy records not counted).
        reconnects: times a live reader reopened its port.
    """

    good_records: int = 0
    bad_bytes: int = 0
    bytes_received: int = 0
    per_station: dict[int, int] = field(default_factory=dict)
    status_letters: dict[str, int] = field(default_factory=dict)
    reconnects: int = 0

    def add(self, batch: RecordBatch, bad_bytes: int = 0, bytes_received: int = 0) -> None:
        """Count a decoded batch."""
        self.good_records += len(batch)
        self.bad_bytes += bad_bytes
        self.bytes_received += bytes_received
        if len(batch):
            stations, counts = np.unique(batch.station, return_counts=True)
            for s, c in zip(stations.tolist(), counts.tolist(), strict=True):
                self.per_station[s] = self.per_station.get(s, 0) + c
            letters = batch.status[batch.status != 0x20]
            if letters.size:
                codes, counts = np.unique(letters, return_counts=True)
                for code, c in zip(codes.tolist(), counts.tolist(), strict=True):
                    self.status_letters[chr(code)] = self.status_letters.get(chr(code), 0) + c

    def as_dict(self) -> dict:
        """Plain dict for JSON reports."""
        return {"good_records": self.good_records, "bad_bytes_skipped": self.bad_bytes,
                "bytes_received": self.bytes_received,
                "per_station": {str(k): v for k, v in sorted(self.per_station.items())},
                "status_letters": dict(sorted(self.status_letters.items())),
                "reconnects": self.reconnects}


def batch_samples(batch: RecordBatch) -> list[PoseSample]:
    """Turn a decoded batch into :class:`PoseSample` objects (each with its own 4x4 array)."""
    n = len(batch)
    if n == 0:
        return []
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = quat_wxyz_to_matrix(batch.quat_wxyz)
    T[:, :3, 3] = batch.position_m
    T[:, 3, 3] = 1.0
    stations = batch.station.tolist()
    statuses = [chr(c) for c in batch.status.tolist()]
    times = batch.t_s.tolist()
    styli = [None if s < 0 else s for s in batch.stylus.tolist()]
    return [PoseSample(stations[i], T[i], statuses[i], times[i], styli[i]) for i in range(n)]


class PoseSource(ABC):
    """Where operator poses come from; a context manager.

    Attributes:
        stats: :class:`SourceStats` counters.
        info: what the source is (kind, path or port, format, output list, units, stations).
        stations: the stations the source delivers (a recording's, or those the tracker
            reports active).
    """

    stats: SourceStats
    info: dict
    stations: tuple[int, ...]
    live = False  # a live device (its clock is the wall clock) rather than a recording

    def __init__(self) -> None:
        self._last_seen: dict[int, float] = {}

    @property
    def done(self) -> bool:
        """True once a recording has delivered every sample (a live source never is)."""
        return False

    @property
    def recorded_s(self) -> float | None:
        """How long a recording lasts (s); None for a live source."""
        return None

    @abstractmethod
    def read_until(self, t_s: float) -> list[PoseSample]:
        """New samples: up to receive time ``t_s`` (replay) or all received so far (live)."""

    @abstractmethod
    def now_s(self) -> float:
        """The source's clock, seconds since it started (live: wall clock; replay: last t_s)."""

    def _seen(self, samples: list[PoseSample]) -> None:
        for s in samples:
            self._last_seen[s.station] = s.t_s

    def last_seen_s(self, station: int) -> float | None:
        """Receive time of the newest sample delivered for ``station``, or None if never seen."""
        return self._last_seen.get(station)

    def looked_s(self) -> float:
        """Up to when the source has looked at its input, on its own clock: a live reader's
        latest completed read of its port; ``inf`` when that is not what limits it (a replay:
        the caller's clock releases the samples)."""
        return math.inf

    def is_stale(self, station: int, now_s: float, timeout_s: float = 0.25) -> bool:
        """True if ``station`` has delivered nothing within ``timeout_s`` before ``now_s``, or
        before the source last looked at its input if that is earlier: input is judged by its
        own timestamps, so a caller running late while a live reader waits for its turn does
        not make fresh input stale."""
        last = self._last_seen.get(station)
        return last is None or min(now_s, self.looked_s()) - last > timeout_s

    def close(self) -> None:
        """Release the port or file (idempotent)."""

    def __enter__(self) -> PoseSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class ReplaySource(OnTimeline, PoseSource):
    """Samples from a recording, released by the caller's clock.

    Args:
        samples: every sample of the recording in receive-time order.
        info: description of the recording.
        stats: counters of the whole recording (decoded when it was opened).
    """

    def __init__(self, samples: list[PoseSample], info: dict, stats: SourceStats) -> None:
        super().__init__()
        self._timeline = Timeline(samples, lambda sample: sample.t_s)
        self.info = info
        self.stats = stats

    @property
    def stations(self) -> tuple[int, ...]:
        """Stations present in the recording."""
        return tuple(sorted({s.station for s in self._timeline.items}))

    def read_until(self, t_s: float) -> list[PoseSample]:
        """Every not yet delivered sample with receive time <= ``t_s`` (seconds)."""
        out = self._timeline.take_until(t_s)
        if out:
            self._seen(out)
        return out

    def rewind(self) -> None:
        """Start delivering from the first sample again."""
        self._timeline.rewind()
        self._last_seen.clear()
