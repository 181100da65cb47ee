"""From operator hand poses to hand goals (paper III-D and IV).

Frames:
- operator frame O: the input device's frame with the robot's axes (x forward, y left, z up;
  each device turns its own axes into it, see :mod:`hubo_cli.input.device`);
- stance frame S: the robot's neck frame at its home posture, fixed to the ground (hand goals
  live here; the whole-body solver turns them into joints, see kinematics.wholebody).

Calibration: the first valid pose of a hand (or a clutch press) records the operator's hand pose
T_O_ref and the robot hand pose T_S_hand0 at that moment. Later poses move the robot's hand by
the operator's motion relative to that reference:

    p_goal = p_hand0 + scale * (p_now - p_ref)
    R_goal = (R_now R_ref^T) R_hand0

Modes: ``free`` follows position and orientation; ``drill`` (paper IV) keeps the bit on the
wall plane x = wall_distance_m and orthogonal to it (identity orientation in S) and follows only
the operator's y and z, at most ``wall_speed_m_s`` fast: the goal follows the operator's hand
at that speed while the hand moves faster, and catches up once it slows.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.errors import ConfigError, quoted
from hubo_cli.input.device import ARM_OF_HAND
from hubo_cli.model import ARMS
from hubo_cli.teleop.target_kernels import free_goal, operator_pose_plausible

MODES = ("free", "drill")
MAX_OPERATOR_RANGE_M = 100.0  # a tracker reads a few metres; far beyond is garbage
# drill mode: the speed-bounded goal follows the operator's path through points at least
# PATH_STEP_M apart (a corner is cut by at most about that), at most MAX_PENDING of them ahead
# (1 m of path at least, 40 s at 25 mm/s; beyond, the oldest is dropped: a chord across two
# points). The step is over the hand's tremor and the tracker's noise (0.7 mm in the shipped
# drill recording): points 2 mm apart drew them as a zigzag that the goal traced at the bound
# (docs/history/teleop.md, round 20)
PATH_STEP_M = 0.005
MAX_PENDING = 200


@dataclass
class MappingConfig:
    """How operator motion maps onto the robot's hands.

    Attributes:
        hand_arm: operator hand -> the arm it drives (default right -> right-arm, left ->
            left-arm).
        scale: robot metres per operator metre.
        mode: ``free`` or ``drill``.
        wall_distance_m: drill mode: the wall plane's x in the stance frame.
        max_step_m: a sample that moves the goal further than this from the previous goal is
            implausible (tracker glitch) and ignored.
        max_turn_rad: free mode: a sample that turns the goal further than this from the
            previous goal's orientation is implausible too, and ignored. 60 deg between two
            poses of one station: a hand turning 3,600 deg/s at the FASTRAK's 60 Hz a station
            (two stations), still 480 deg/s for a tracker sending 8 a second; the shipped
            recordings turn at most 0.38 deg between poses (23 deg/s), the generated streams
            0.46 deg (review 23: a station turned 180 deg in one record and kept so was followed,
            the wrist turning as fast as its limits let it, exit 0 without a word).
        wall_speed_m_s: drill mode: the goal's largest speed across the wall (by the samples'
            times). The cardboard drags the bit across (80 N s/m and 0.5 N in the default
            cutting model) about 0.2 m from the wrist sensor: the drill replay's wrist moment
            rose about 0.018 N m per mm/s of the bit's speed across the wall, to 0.93-1.22 N m
            at its fastest stroke (55-65 mm/s), at the 1.21 N m wrist-torque stop.
    """

    hand_arm: dict[str, str] = field(default_factory=lambda: dict(ARM_OF_HAND))
    scale: float = 1.0
    mode: str = "free"
    wall_distance_m: float = 0.484
    max_step_m: float = 0.15
    max_turn_rad: float = math.pi / 3
    wall_speed_m_s: float = 0.025

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"unknown teleop mode {quoted(self.mode)}", hint="use free or drill")
        if not (np.isfinite(self.scale) and 0 < self.scale <= 10):
            raise ConfigError(f"scale {self.scale} is not in (0, 10]", hint="use e.g. --scale 1")
        if not (np.isfinite(self.max_turn_rad) and 0 < self.max_turn_rad < math.pi):
            raise ConfigError(f"the largest turn between two poses {self.max_turn_rad} rad is "
                              "not in (0, pi)", hint="use e.g. pi / 3 (60 deg)")
        if not (np.isfinite(self.wall_speed_m_s) and self.wall_speed_m_s > 0):
            raise ConfigError(f"the drill's speed across the wall {self.wall_speed_m_s} m/s is "
                              "not a positive number", hint="use e.g. 0.025")
        arms = list(self.hand_arm.values())
        unknown = [h for h, a in self.hand_arm.items() if h not in ARM_OF_HAND or a not in ARMS]
        if unknown or len(set(arms)) != len(arms):
            raise ConfigError(f"hand -> arm map {self.hand_arm} is not one hand per arm",
                             hint="e.g. right -> right-arm, left -> left-arm")


@dataclass
class _Reference:
    T_O_ref: np.ndarray
    T_S_hand0: np.ndarray
    last_goal: np.ndarray   # the last goal given (drill mode: speed-bounded)
    last_mapped: np.ndarray  # the last sample's mapped pose (what the glitch check compares)
    last_t_s: float | None = None
    # drill mode: the operator's points on the wall (y, z in S, m) the goal has yet to pass
    pending: deque = field(default_factory=lambda: deque(maxlen=MAX_PENDING))


@dataclass(frozen=True)
class HandGoal:
    """A goal for one arm: the tool pose in the stance frame (4x4, m) and the sample time (s)."""

    arm: str
    T_S_goal: np.ndarray
    t_s: float
    calibrated_now: bool = False


class HandMapper:
    """Calibrates each hand and maps its poses onto hand goals.

    Args:
        config: the mapping settings.
    """

    def __init__(self, config: MappingConfig) -> None:
        self.config = config
        self._refs: dict[str, _Reference] = {}
        self.rejected = 0

    def is_calibrated(self, hand: str) -> bool:
        return hand in self._refs

    def recenter(self, hand: str, T_O_hand: np.ndarray, T_S_hand_now: np.ndarray) -> None:
        """Clutch: make the operator's current hand pose correspond to the robot's hand pose."""
        T_S_hand = np.array(T_S_hand_now, dtype=float)
        if self.config.mode == "drill":
            T_S_hand[:3, :3] = np.eye(3)
            T_S_hand[0, 3] = self.config.wall_distance_m
        self._refs[hand] = _Reference(np.array(T_O_hand, dtype=float), T_S_hand,
                                      T_S_hand.copy(), T_S_hand.copy())

    def forget(self, hand: str | None = None) -> None:
        """Drop the calibration of ``hand`` (None: of every hand); its next pose calibrates
        again."""
        if hand is None:
            self._refs.clear()
        else:
            self._refs.pop(hand, None)

    def goal(self, hand: str, T_O_hand: np.ndarray, t_s: float,
             T_S_hand_now: np.ndarray) -> HandGoal | None:
        """The robot hand's goal for one operator pose, or None if the hand drives no arm or the
        pose is implausible (non-finite, beyond ``MAX_OPERATOR_RANGE_M``, or a jump larger than
        ``max_step_m``; in free mode also a turn larger than ``max_turn_rad``).

        Args:
            hand: ``right`` or ``left``.
            T_O_hand: the operator's hand pose in the operator frame (4x4, m).
            t_s: the pose's sample time (s).
            T_S_hand_now: the arm's current tool pose in the stance frame, used to calibrate.
        """
        arm = self.config.hand_arm.get(hand)
        if arm is None:
            return None
        T_O = np.ascontiguousarray(T_O_hand, dtype=float)
        # non-finite, or beyond any tracker's range (and large enough to overflow in the maths)
        if T_O.shape != (4, 4) or not operator_pose_plausible(T_O, MAX_OPERATOR_RANGE_M):
            self.rejected += 1
            return None
        if hand not in self._refs:
            self.recenter(hand, T_O, T_S_hand_now)
            ref = self._refs[hand]
            ref.last_t_s = t_s
            return HandGoal(arm, ref.T_S_hand0.copy(), t_s, calibrated_now=True)
        ref = self._refs[hand]
        if self.config.mode != "drill":  # one compiled call: the same arithmetic as below
            T_goal = np.empty((4, 4))
            if not free_goal(T_O, ref.T_O_ref, ref.T_S_hand0, ref.last_mapped,
                             self.config.scale, self.config.max_step_m,
                             math.cos(self.config.max_turn_rad), T_goal):
                self.rejected += 1
                return None
            ref.last_mapped = T_goal.copy()
            if math.isfinite(t_s) and (ref.last_t_s is None or t_s > ref.last_t_s):
                ref.last_t_s = t_s
            ref.last_goal = T_goal
            return HandGoal(arm, T_goal, t_s)
        T_goal = np.eye(4)
        delta_S = self.config.scale * (T_O[:3, 3] - ref.T_O_ref[:3, 3])
        if self.config.mode == "drill":
            T_goal[:3, :3] = np.eye(3)
            T_goal[0, 3] = self.config.wall_distance_m
            T_goal[1:3, 3] = ref.T_S_hand0[1:3, 3] + delta_S[1:3]
        else:
            T_goal[:3, :3] = T_O[:3, :3] @ ref.T_O_ref[:3, :3].T @ ref.T_S_hand0[:3, :3]
            T_goal[:3, 3] = ref.T_S_hand0[:3, 3] + delta_S
        step = T_goal[:3, 3] - ref.last_mapped[:3, 3]
        if math.sqrt(step.dot(step)) > self.config.max_step_m:  # np.linalg.norm's arithmetic
            self.rejected += 1
            return None
        ref.last_mapped = T_goal.copy()
        if self.config.mode == "drill":
            elapsed_s = t_s - ref.last_t_s if np.isfinite(t_s) and ref.last_t_s is not None \
                else 0.0
            here = T_goal[1:3, 3].copy()
            behind = ref.pending[-1] if ref.pending else ref.last_goal[1:3, 3]
            if np.linalg.norm(here - behind) >= PATH_STEP_M:
                ref.pending.append(here)
            T_goal[1:3, 3] = _along(ref.pending, here, ref.last_goal[1:3, 3],
                                    self.config.wall_speed_m_s * max(elapsed_s, 0.0))
        if np.isfinite(t_s) and (ref.last_t_s is None or t_s > ref.last_t_s):
            ref.last_t_s = t_s
        ref.last_goal = T_goal
        return HandGoal(arm, T_goal, t_s)


def _along(pending: deque, latest: np.ndarray, start: np.ndarray, room_m: float) -> np.ndarray:
    """The point ``room_m`` further from ``start`` along the operator's path: the ``pending``
    points still ahead, in order (those passed are removed), then his hand's ``latest`` point.
    A goal slower than the operator's hand follows the path drawn; it does not cut across its
    corners."""
    at = np.array(start, dtype=float)
    while room_m > 0.0:
        ahead = (pending[0] if pending else latest) - at
        length = float(np.linalg.norm(ahead))
        if length <= room_m:
            at = at + ahead
            room_m -= length
            if not pending:
                return at
            pending.popleft()
        else:
            return at + ahead * (room_m / length)
    return at
