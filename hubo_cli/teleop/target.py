"""The teleoperation target source: tracker samples -> hand goals -> whole-body joint targets.

It is called by the control loop once per period (``target(t_s, state)``) and goes through
three phases:

1. *approach*: a joint-space move to the first pose of each hand's approach path (drill mode:
   the bit a few centimetres before the wall), then the Cartesian paths (straight into the
   wall), then a wait until the robot is still;
2. *operate*: the operator drives the hands. Replays deliver the samples whose receive time has
   come on the loop's clock (so ``--speed max`` and real time give the same path); a live tracker
   delivers what has arrived. The first sample of each station calibrates it (the hand stays);
   a stale station holds its hand (flag ``stale-input``);
3. *settle*: a replay has ended; the hands hold their last goals until the robot is still.

Goals live in the stance frame S (the home neck frame, fixed to the ground). The actual
end-effector pose is what the robot measures, as on the paper's robot: FK of the measured arm
joints, lifted by the FK of the measured legs (feet flat on the ground). Where the driver knows
the torso's pose in the world (the simulation), the tool's world position is tracked as well:
it also contains the whole body's sway and lean (the ankle controller of eq. 11-12 complies
with the ankle moments, so the robot leans when its centre of mass moves forward).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubo_cli.control.target import Target
from hubo_cli.drivers.base import SimulatedWorld
from hubo_cli.fastrak.source import PoseSource
from hubo_cli.geometry import tilt_rad_of_quat_wxyz
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.interpolate import PosePath
from hubo_cli.kinematics.wholebody import LiftFilter, WholeBody
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.scene import WallPlacement
from hubo_cli.teleop.mapping import HandMapper

PHASES = ("approach", "operate", "settle")
SHORT = {"right-arm": "r", "left-arm": "l"}


@dataclass
class HandTrack:
    """Per-arm bookkeeping for metrics and the live view (positions in S, m)."""

    goal_m: np.ndarray | None = None
    actual_m: np.ndarray | None = None
    ik_status: str = "-"
    ik_counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STATUS_NAMES, 0))
    stale: bool = False


@dataclass
class Keys:
    """Operator requests gathered since the last period (set by the key reader / CLI)."""

    estop: bool = False
    release: bool = False
    clutch: bool = False
    quit: bool = False

    def take(self) -> Keys:
        """Return the pending requests and clear them."""
        pending = Keys(self.estop, self.release, self.clutch, self.quit)
        self.estop = self.release = self.clutch = self.quit = False
        return pending


class TeleopTarget(Target):
    """Target source for :class:`hubo_cli.control.loop.ControlLoop`.

    Args:
        model: the robot model.
        source: the pose source (replay or live).
        mapper: calibration and mapping of tracker poses onto hand goals.
        body: the whole-body solver (its arms' tools are the end effectors).
        approach: arm -> the Cartesian path (goals in S) each hand follows before the operator
            takes over; its end is the hand's start pose.
        q_start_rad: the posture the loop starts from.
        live: the source is a live tracker (its clock is the wall clock).
        stale_timeout_s: a station silent this long is stale.
        settle_s: after a replay ends, how long the robot may take to come to rest.
        approach_timeout_s: each approach step waits at most this long for the robot to settle.
        clutch_at_s: replay times (s) at which to re-centre (as if ``c`` was pressed).
        wall: placed once the robot is still at the approach's first pose (drill mode: the
            robot raises its tool away from the wall, as an operator would bring it up to the
            wall with the tool ready); in a simulator only.
    """

    def __init__(self, model: RobotModel, source: PoseSource, mapper: HandMapper,
                 body: WholeBody, approach: dict[str, PosePath], q_start_rad: np.ndarray,
                 *, live: bool = False, stale_timeout_s: float = 0.25, settle_s: float = 1.0,
                 approach_timeout_s: float = 5.0, clutch_at_s: tuple[float, ...] = (),
                 wall: WallPlacement | None = None) -> None:
        self.model = model
        self.source = source
        self.mapper = mapper
        self.body = body
        self.live = live
        self.stale_timeout_s = stale_timeout_s
        self.settle_s = settle_s
        self.approach_timeout_s = approach_timeout_s
        self.clutch_at_s = sorted(clutch_at_s)
        self.dt_guard_s = model.control_period_s
        self.keys = Keys()
        self.arms = sorted(set(mapper.config.station_arm.values()) & set(ARMS))
        self.slices = {arm: model.limb_slice(arm) for arm in ARMS}
        self.q_target = np.array(q_start_rad, dtype=float)
        self.lift = LiftFilter()
        # approach step 1: joint space to the paths' first poses (legs straight to their lift)
        firsts = {a: p.at(0.0) for a, p in approach.items()}
        self.lift.reset(body.lift_for(firsts))
        first = body.solve(firsts, self.q_target, lift_m=self.lift.lift_m)
        self.q_pre = first.q_rad
        self.approach_ok = all(r.status == "exact" for r in first.arms.values())
        # approach step 2: the Cartesian paths (e.g. straight into the wall)
        self.approach = approach
        self.approach_s = max((p.duration_s for p in approach.values()), default=0.0)
        self.t_path_s: float | None = None
        self.wall = wall
        self.world: SimulatedWorld | None = None
        self.scene: dict = {}
        self.goals: dict[str, np.ndarray] = dict(firsts)
        self.hands = {arm: HandTrack() for arm in self.arms}
        self.phase = "approach"
        self.t_operate_s: float | None = None
        self.t_settle_s: float | None = None
        self.T_world_S: np.ndarray | None = None
        self.latencies_s: list[float] = []
        self.samples_used = 0
        self.last_sample_s: dict[int, float] = {}
        self.errors_m: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self.world_errors_m: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self.max_tilt_rad = 0.0
        self.paths: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {a: [] for a in self.arms}
        self.log_columns = tuple(
            f"{c}_{SHORT[a]}" for a in self.arms
            for c in ("goal_x_m", "goal_y_m", "goal_z_m", "actual_x_m", "actual_y_m",
                      "actual_z_m", "error_m", "ik_code")) + ("phase_code", "lift_m",
                                                             "latency_s")

    def attach(self, world: SimulatedWorld | None, modules) -> None:
        self.world = world

    # ------------------------------------------------------------------ measurement
    def hand_pose_measured(self, arm: str, state) -> np.ndarray:
        """T_S_E of an arm's tool from the measured joints (4x4, m): arm FK lifted by leg FK."""
        lifted = self.body.arms[arm].fk(state.q_rad[self.slices[arm]])
        lifted[2, 3] += self.body.lift_of(state.q_rad)
        return lifted

    def hand_position_world(self, arm: str, state) -> np.ndarray | None:
        """The tool's position in S through the measured torso pose (m), or None if unknown."""
        if state.T_world_torso is None:
            return None
        if self.T_world_S is None:
            self.T_world_S = np.array(state.T_world_torso, dtype=float)
        T_N_E = self.body.arms[arm].fk(state.q_rad[self.slices[arm]])
        return (np.linalg.solve(self.T_world_S, state.T_world_torso) @ T_N_E)[:3, 3]

    def hand_pose_commanded(self, arm: str) -> np.ndarray:
        """T_S_E of an arm's tool for the current joint target (4x4, m)."""
        return self.goals.get(arm, self.body.arms[arm].fk(self.q_target[self.slices[arm]]))

    def _record_ik(self, solved) -> None:
        for arm, result in solved.arms.items():
            if arm in self.hands:
                self.hands[arm].ik_status = result.status
                self.hands[arm].ik_counts[result.status] += 1

    # ------------------------------------------------------------------ the loop's call
    def __call__(self, t_s: float, state) -> tuple[np.ndarray | None, dict]:
        info: dict = {}
        flags: list[str] = []
        keys = self.keys.take()
        if keys.estop:
            info["estop"] = "operator"
        if keys.release:
            info["release"] = True
        if keys.quit:
            info["done"] = True
        if self.phase == "approach":
            self._approach(t_s, state)
        elif self.phase == "operate":
            flags += self._operate(t_s, keys.clutch)
        if self.phase == "settle":
            moving = np.max(np.abs(state.dq_rad_s)) if len(state.dq_rad_s) else 0.0
            at_goal = np.max(np.abs(state.q_rad - self.q_target)) < 0.02
            if (t_s - self.t_settle_s >= self.settle_s and moving < 0.02 and at_goal) or (
                    t_s - self.t_settle_s >= 4 * self.settle_s):
                info["done"] = True
        self._measure(t_s, state, info)
        if flags:
            info["flags"] = flags
        return self.q_target, info

    def _settled(self, state) -> bool:
        return bool(np.max(np.abs(state.q_rad - self.q_target)) < 0.01
                    and np.max(np.abs(state.dq_rad_s)) < 0.05)

    def _approach(self, t_s: float, state) -> None:
        if self.t_path_s is None:  # step 1: joint-space move to the pre-pose, then settle
            self.q_target = self.q_pre
            if self._settled(state) or t_s >= self.approach_timeout_s:
                self.t_path_s = t_s
                if self.world is not None and self.wall is not None:
                    self.scene = self.wall.place(self.world)
            return
        t_path = t_s - self.t_path_s
        if t_path <= self.approach_s + self.dt_guard_s:  # step 2: the Cartesian paths
            self.goals = {arm: path.at(t_path) for arm, path in self.approach.items()}
            solved = self.body.solve(self.goals, self.q_target, lift_m=self.lift.lift_m)
            self.q_target = solved.q_rad
            self._record_ik(solved)
            return
        if self._settled(state) or t_path >= self.approach_s + self.approach_timeout_s:
            self.phase = "operate"
            self.t_operate_s = t_s

    def _source_time(self, t_s: float) -> float:
        return self.source.now_s() if self.live else t_s - self.t_operate_s

    def _operate(self, t_s: float, clutch: bool) -> list[str]:
        t_src = self._source_time(t_s)
        while self.clutch_at_s and t_src >= self.clutch_at_s[0]:
            self.clutch_at_s.pop(0)
            clutch = True
        if clutch:
            self.mapper.forget()  # the next sample of each station re-centres on the hand
        samples = self.source.read_until(t_src)
        changed = False
        for sample in samples:
            if sample.suspect:
                continue
            arm = self.mapper.config.station_arm.get(sample.station)
            if arm not in self.hands:
                continue
            goal = self.mapper.goal(sample.station, sample.T_tracker_sensor, sample.t_s,
                                    self.hand_pose_commanded(arm))
            if goal is None:
                continue
            self.goals[arm] = goal.T_S_goal
            self.last_sample_s[sample.station] = sample.t_s
            self.samples_used += 1
            changed = True
        if samples:
            newest = max(s.t_s for s in samples)
            self.latencies_s.append(max(0.0, self._source_time(t_s) - newest))
        flags = []
        for station, arm in self.mapper.config.station_arm.items():
            if arm in self.hands:
                stale = self.source.is_stale(station, t_src, self.stale_timeout_s)
                self.hands[arm].stale = stale and self.mapper.is_calibrated(station)
                if self.hands[arm].stale:
                    flags.append("stale-input")
        lift = self.lift.step(self.body.lift_for(self.goals), self.dt_guard_s)
        if changed or lift != self.body.lift_of(self.q_target):
            solved = self.body.solve(self.goals, self.q_target, lift_m=lift)
            self.q_target = solved.q_rad
            self._record_ik(solved)
        if self.source.done:
            self.phase = "settle"
            self.t_settle_s = t_s
        return flags

    def _measure(self, t_s: float, state, info: dict) -> None:
        info["phase_code"] = PHASES.index(self.phase)
        if state.T_world_torso is not None and self.T_world_S is None:
            self.T_world_S = np.array(state.T_world_torso, dtype=float)
        info["lift_m"] = float(self.body.lift_of(self.q_target))
        info["latency_s"] = self.latencies_s[-1] if self.latencies_s else 0.0
        for arm, hand in self.hands.items():
            key = SHORT[arm]
            actual = self.hand_pose_measured(arm, state)[:3, 3]
            goal = self.goals.get(arm)
            hand.actual_m = actual
            if goal is not None:
                hand.goal_m = goal[:3, 3]
            info.update({f"actual_x_m_{key}": actual[0], f"actual_y_m_{key}": actual[1],
                         f"actual_z_m_{key}": actual[2],
                         f"ik_code_{key}": STATUS_NAMES.index(hand.ik_status)
                         if hand.ik_status in STATUS_NAMES else -1})
            if hand.goal_m is not None:
                error = float(np.linalg.norm(hand.goal_m - actual))
                info.update({f"goal_x_m_{key}": hand.goal_m[0], f"goal_y_m_{key}": hand.goal_m[1],
                             f"goal_z_m_{key}": hand.goal_m[2], f"error_m_{key}": error})
                if self.phase == "operate" and self.mapper.is_calibrated(
                        self._station_of(arm)):
                    self.errors_m[arm].append(error)
                    self.paths[arm].append((hand.goal_m.copy(), actual.copy()))
                    world = self.hand_position_world(arm, state)
                    if world is not None:
                        self.world_errors_m[arm].append(float(np.linalg.norm(hand.goal_m
                                                                             - world)))
        self.max_tilt_rad = max(self.max_tilt_rad,
                                float(tilt_rad_of_quat_wxyz(state.imu_quat_wxyz)))

    def _station_of(self, arm: str) -> int:
        return next(s for s, a in self.mapper.config.station_arm.items() if a == arm)
