"""A Polhemus FASTRAK as an input device: live on a serial port, or replayed from a recording.

Everything FASTRAK stays here: stations 1-4 and which hand each one is, the status letters
(a suspect record becomes an unreliable pose), the transmitter's axes (x forward, y right,
z down), the record counters. The teleoperation sees hands and poses in the operator's frame O
(x forward, y left, z up): with R = R_operator_tracker (a half turn about x by default),

    T_O_hand = [R R_K_sensor R^T, R p_K_sensor],

i.e. the hand's frame is the sensor's re-expressed with O's axes, so a relative motion of the
sensor maps onto the same relative motion of the hand in O.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hubo_cli.errors import DeviceError, InputError, quoted
from hubo_cli.fastrak.source import PoseSample, PoseSource
from hubo_cli.input.device import HAND_OF_ARM, HandPose, InputDevice
from hubo_cli.model import ARMS

R_OPERATOR_TRACKER = np.diag([1.0, -1.0, -1.0])  # FASTRAK x forward, y right, z down -> O
STATIONS = (1, 2, 3, 4)
DEFAULT_STATION_ARM = {1: "right-arm", 2: "left-arm"}


def check_station_map(station_arm: dict[int, str]) -> dict[int, str]:
    """A station -> arm map must name FASTRAK stations 1..4 and drive each arm from one station.

    Raises:
        InputError: an unknown station or arm, or two stations on one arm.
    """
    seen: dict[str, int] = {}
    for station, arm in station_arm.items():
        if station not in STATIONS:
            raise InputError(f"station {station} does not exist: a FASTRAK has stations 1-4",
                             hint="e.g. --map 1=right-arm --map 2=left-arm")
        if arm not in ARMS:
            raise InputError(f"station {station}: unknown arm {quoted(arm)}",
                             hint=f"use one of {', '.join(ARMS)}")
        if arm in seen:
            raise InputError(f"stations {seen[arm]} and {station} both drive the {arm}",
                             hint="map one station per arm")
        seen[arm] = station
    return station_arm


def parse_station_map(pairs) -> dict[int, str]:
    """``STATION=ARM`` texts (``--map 1=right-arm``) as a checked station -> arm map."""
    out: dict[int, str] = {}
    for pair in pairs:
        station, _, arm = str(pair).partition("=")
        station = station.strip()
        if not station.isdigit() or arm.strip() not in ARMS:
            raise InputError(f"--map {quoted(pair)} is not STATION=ARM",
                             hint="e.g. --map 1=right-arm --map 2=left-arm")
        if int(station) in out:
            raise InputError(f"station {station} is mapped twice", hint="map it once")
        out[int(station)] = arm.strip()
    return check_station_map(out)


def check_stations_present(station_arm: dict[int, str], available, where: str) -> None:
    """Every mapped station must be in the input (a recording's or a tracker's stations).

    Raises:
        InputError: naming the missing station and those the input has.
    """
    have = sorted(int(s) for s in available)
    missing = [s for s in sorted(station_arm) if s not in have]
    if missing:
        raise InputError(f"{where} has no station {missing[0]} (mapped to the "
                         f"{station_arm[missing[0]]}); it has station(s) "
                         f"{', '.join(map(str, have)) or 'none'}",
                         hint="map a station the input has, e.g. --map "
                              f"{have[0] if have else 1}={station_arm[missing[0]]}")


def check_live_stations(station_arm: dict[int, str], active, port) -> None:
    """Every mapped station must be one the live tracker reports active (the reader enables
    those and takes records of no other): an arm mapped to a station without a receiver would
    never move, the run ending without a word (review 23; a recording is refused the same way
    by :func:`check_stations_present`).

    Raises:
        DeviceError: naming the missing station and the stations the tracker has.
    """
    have = sorted(int(s) for s in active)
    missing = [s for s in sorted(station_arm) if s not in have]
    if missing:
        s = missing[0]
        raise DeviceError(f"the FASTRAK on {port} reports no receiver at station {s} (mapped "
                          f"to the {station_arm[s]}); its active station(s): "
                          f"{', '.join(map(str, have)) or 'none'}",
                          hint=f"plug a receiver into station {s}, or map the stations it has, "
                               f"e.g. --map {have[0] if have else 1}={station_arm[s]}")


def operator_pose(T_K_sensor: np.ndarray, R_operator_tracker: np.ndarray = R_OPERATOR_TRACKER
                  ) -> np.ndarray:
    """The hand's pose in O for a sensor pose in the tracker frame (see the module docstring)."""
    R = R_operator_tracker
    T = np.eye(4)
    T[:3, :3] = R @ T_K_sensor[:3, :3] @ R.T
    T[:3, 3] = R @ T_K_sensor[:3, 3]
    return T


def tracker_pose(T_O_hand: np.ndarray, R_operator_tracker: np.ndarray = R_OPERATOR_TRACKER
                 ) -> np.ndarray:
    """The inverse of :func:`operator_pose`: the sensor pose in the tracker frame."""
    return operator_pose(T_O_hand, np.asarray(R_operator_tracker).T)


class FastrakInput(InputDevice):
    """A FASTRAK (live reader or replayed recording) delivering hands.

    Args:
        source: the FASTRAK pose source (:func:`hubo_cli.fastrak.opener.open_source`); closed
            with the device.
        station_arm: station -> arm it drives (``right-arm`` / ``left-arm``); the stations must
            be in a recording (checked here).
        R_operator_tracker: the tracker's axes into the operator's frame.

    Raises:
        InputError: a mapped station is not in the recording.
    """

    def __init__(self, source: PoseSource, station_arm: dict[int, str] | None = None,
                 R_operator_tracker: np.ndarray = R_OPERATOR_TRACKER) -> None:
        super().__init__()
        self.source = source
        station_arm = check_station_map(dict(station_arm or DEFAULT_STATION_ARM))
        try:
            if not source.live:
                where = source.info.get("path", "the recording")
                check_stations_present(station_arm, source.stations, str(where))
            else:
                check_live_stations(station_arm, source.stations, source.info.get("port"))
        except (InputError, DeviceError):
            source.close()
            raise
        self.station_hand = {s: HAND_OF_ARM[arm] for s, arm in station_arm.items()}
        self.hands = tuple(h for h in ("right", "left") if h in self.station_hand.values())
        self.R_operator_tracker = np.asarray(R_operator_tracker, dtype=float)
        self.live = source.live
        self.info = dict(source.info, stations={str(s): h for s, h in self.station_hand.items()})

    def _hand_pose(self, sample: PoseSample) -> HandPose:
        return HandPose(self.station_hand[sample.station],
                        operator_pose(sample.T_tracker_sensor, self.R_operator_tracker),
                        sample.t_s, reliable=not sample.suspect)

    def _read(self, t_s: float) -> list[HandPose]:
        return [self._hand_pose(s) for s in self.source.read_until(t_s)
                if s.station in self.station_hand]

    def now_s(self) -> float:
        return self.source.now_s()

    def looked_s(self) -> float:
        return self.source.looked_s()

    @property
    def done(self) -> bool:
        return self.source.done

    @property
    def recorded_s(self) -> float | None:
        return self.source.recorded_s

    def stats(self) -> dict:
        return self.source.stats.as_dict()

    def close(self) -> None:
        self.source.close()


def open_fastrak(replay: str | Path | None = None, port: str | None = None,
                 station_arm: dict[int, str] | None = None, **options) -> FastrakInput:
    """A FASTRAK device: a recording (``replay``, a raw capture or a pose-log CSV) or a live
    unit on a serial ``port``; ``options`` go to :func:`hubo_cli.fastrak.opener.open_source`.

    Raises:
        InputError: neither or both of replay/port, a bad recording, a missing station.
        DeviceError: the port is absent or the tracker does not answer.
    """
    from hubo_cli.fastrak.opener import open_source

    return FastrakInput(open_source(replay=replay, port=port, **options), station_arm)
