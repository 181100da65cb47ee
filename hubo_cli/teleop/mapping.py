"""From tracker poses to hand goals (paper III-D and IV).

Frames:
- tracker frame K: the FASTRAK transmitter's axes (x forward, y right, z down by default);
- stance frame S: the robot's neck frame at its home posture, fixed to the ground (hand goals
  live here; the whole-body solver turns them into joints, see kinematics.wholebody).

Calibration: the first valid sample of a station (or a clutch press) records the sensor pose
T_K_ref and the robot hand pose T_S_hand0 at that moment. Later samples move the hand by the
operator's motion relative to that reference, rotated into the robot's frame:

    p_goal = p_hand0 + scale * R_S_K (p_now - p_ref)
    R_goal = (R_S_K R_now R_ref^T R_S_K^T) R_hand0

Modes: ``free`` follows position and orientation; ``drill`` (paper IV) keeps the bit on the
wall plane x = wall_distance_m and orthogonal to it (identity orientation in S) and follows only
the operator's y and z.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubo_cli.errors import ConfigError, InputError

# FASTRAK reference frame is x forward, y right, z down; a half turn about x gives S's axes.
R_STANCE_TRACKER_DEFAULT = np.diag([1.0, -1.0, -1.0])
MODES = ("free", "drill")
MAX_TRACKER_RANGE_M = 100.0  # a FASTRAK reads up to ~3 m from its source; far beyond is garbage
ARMS = ("right-arm", "left-arm")
STATIONS = (1, 2, 3, 4)  # FASTRAK receivers


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
            raise InputError(f"station {station}: unknown arm {arm!r}",
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
            raise InputError(f"--map {pair!r} is not STATION=ARM",
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


@dataclass
class MappingConfig:
    """How operator motion maps onto the robot's hands.

    Attributes:
        station_arm: tracker station -> arm name (default 1 -> right-arm, 2 -> left-arm).
        scale: robot metres per operator metre.
        mode: ``free`` or ``drill``.
        wall_distance_m: drill mode: the wall plane's x in the stance frame.
        R_stance_tracker: rotation of the tracker frame into the stance frame.
        max_step_m: a sample that moves the goal further than this from the previous goal is
            implausible (tracker glitch) and ignored.
    """

    station_arm: dict[int, str] = field(default_factory=lambda: {1: "right-arm", 2: "left-arm"})
    scale: float = 1.0
    mode: str = "free"
    wall_distance_m: float = 0.484
    R_stance_tracker: np.ndarray = field(default_factory=lambda: R_STANCE_TRACKER_DEFAULT.copy())
    max_step_m: float = 0.15

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"unknown teleop mode {self.mode!r}", hint="use free or drill")
        if not (np.isfinite(self.scale) and 0 < self.scale <= 10):
            raise ConfigError(f"scale {self.scale} is not in (0, 10]", hint="use e.g. --scale 1")
        check_station_map(self.station_arm)


@dataclass
class _Reference:
    T_K_ref: np.ndarray
    T_S_hand0: np.ndarray
    last_goal: np.ndarray


@dataclass(frozen=True)
class HandGoal:
    """A goal for one arm: the tool pose in the stance frame (4x4, m) and the sample time (s)."""

    arm: str
    T_S_goal: np.ndarray
    t_s: float
    calibrated_now: bool = False


class HandMapper:
    """Calibrates each station and maps its samples onto hand goals.

    Args:
        config: the mapping settings.
    """

    def __init__(self, config: MappingConfig) -> None:
        self.config = config
        self._refs: dict[int, _Reference] = {}
        self.rejected = 0

    def is_calibrated(self, station: int) -> bool:
        return station in self._refs

    def recenter(self, station: int, T_K_sensor: np.ndarray, T_S_hand_now: np.ndarray) -> None:
        """Clutch: make the current sensor pose correspond to the current hand pose."""
        T_S_hand = np.array(T_S_hand_now, dtype=float)
        if self.config.mode == "drill":
            T_S_hand[:3, :3] = np.eye(3)
            T_S_hand[0, 3] = self.config.wall_distance_m
        self._refs[station] = _Reference(np.array(T_K_sensor, dtype=float), T_S_hand,
                                         T_S_hand.copy())

    def forget(self, station: int | None = None) -> None:
        """Drop the calibration of ``station`` (None: of every station); its next sample
        calibrates again."""
        if station is None:
            self._refs.clear()
        else:
            self._refs.pop(station, None)

    def goal(self, station: int, T_K_sensor: np.ndarray, t_s: float,
             T_S_hand_now: np.ndarray) -> HandGoal | None:
        """The hand goal for one sample, or None if the station drives no arm or the sample is
        implausible (non-finite, beyond ``MAX_TRACKER_RANGE_M``, or a jump larger than
        ``max_step_m``).

        Args:
            station: tracker station of the sample.
            T_K_sensor: the sensor pose in the tracker frame (4x4, m).
            t_s: the sample's receive time (s).
            T_S_hand_now: the arm's current tool pose in the stance frame, used to calibrate.
        """
        arm = self.config.station_arm.get(station)
        if arm is None:
            return None
        T_K = np.asarray(T_K_sensor, dtype=float)
        # non-finite, or beyond any tracker's range (and large enough to overflow in the maths)
        if not np.all(np.isfinite(T_K)) or np.max(np.abs(T_K[:3, 3])) > MAX_TRACKER_RANGE_M:
            self.rejected += 1
            return None
        if station not in self._refs:
            self.recenter(station, T_K, T_S_hand_now)
            ref = self._refs[station]
            return HandGoal(arm, ref.T_S_hand0.copy(), t_s, calibrated_now=True)
        ref = self._refs[station]
        R = self.config.R_stance_tracker
        T_goal = np.eye(4)
        delta_S = self.config.scale * (R @ (T_K[:3, 3] - ref.T_K_ref[:3, 3]))
        if self.config.mode == "drill":
            T_goal[:3, :3] = np.eye(3)
            T_goal[0, 3] = self.config.wall_distance_m
            T_goal[1:3, 3] = ref.T_S_hand0[1:3, 3] + delta_S[1:3]
        else:
            R_rel_K = T_K[:3, :3] @ ref.T_K_ref[:3, :3].T
            T_goal[:3, :3] = R @ R_rel_K @ R.T @ ref.T_S_hand0[:3, :3]
            T_goal[:3, 3] = ref.T_S_hand0[:3, 3] + delta_S
        if np.linalg.norm(T_goal[:3, 3] - ref.last_goal[:3, 3]) > self.config.max_step_m:
            self.rejected += 1
            return None
        ref.last_goal = T_goal
        return HandGoal(arm, T_goal, t_s)
