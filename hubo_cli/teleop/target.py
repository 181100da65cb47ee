"""The teleoperation target source: operator hand poses -> hand goals -> whole-body joint targets.

It is called by the control loop once per period (``target(t_s, state)``) and goes through
three phases (explicit states, :mod:`hubo_cli.teleop.phases`, run one at a time by a
:class:`~hubo_cli.control.phase.Phases` machine):

1. *approach*: a joint-space move to the first pose of each hand's approach path (drill mode:
   the bit a few centimetres before the wall), then the Cartesian paths (straight into the
   wall), then a wait until the robot is still;
2. *operate*: the operator drives the hands. The input device (:mod:`hubo_cli.input`) delivers
   hand poses stamped with their sample time: a recording or a generated stream those whose
   time has come on the loop's clock (so ``--speed max`` and real time give the same path), a
   live device what has arrived. The first pose of each hand calibrates it (the robot's hand
   stays); a stale hand holds (flag ``stale-input``). When a lost hand comes back, it keeps
   holding: live, until the operator re-centres (``c``, flag ``holding`` meanwhile), so the
   robot's hand never jumps to wherever the operator's hand went while the input was lost; a
   replay re-centres on the first pose after the gap. While the operator holds the device's
   clutch (poses not ``engaged``) the hand holds, and re-centres on release;
3. *settle*: a replay has ended; the hands hold their last goals until the robot is still.

While operating, each arm stays on the IK branch it started on and a goal out of its reach sends
it to the nearest reachable pose on that branch, position first (:mod:`hubo_cli.kinematics.
arm_reach`; ``reach="paper"`` restores the paper's 5 cm rule). The branch changes only on the
operator's request (key ``b``) or, with ``allow_branch_change``, when the hand rests at its reach
limit and another branch reaches the goal: a slow joint-space move, announced in the live view.
Near singular configurations the arm's joint speeds are scaled down
(:mod:`hubo_cli.kinematics.conditioning`). Postures within the collision detector's band count
as out of reach too: an arm target keeps ``collision_room_m`` from the body, measured by the
detector's own geometry, and goes to the clear pose nearest to the goal, position first (the
hand turns to pass the upper arm outside the torso; :mod:`hubo_cli.teleop.room`), so a goal
in front of the chest is reached and one brushing past the torso does not trip a collision
hold.
While operating, each arm's joints are timed by the trajectory generator's own tracker for that
arm (the session builds ``otg`` with a tracker per limb), so a hand does not wait for the legs.
Each period the arm's joints go unsynchronised (each joint time-optimal: the hand keeps up
best) unless that way to the current target would carry the hand more than ``SWING_M`` off the
straight line from its commanded position to the target's (the ruckig trajectory, previewed
and put through the arm's forward kinematics); then they keep the straight joint-space line
(phase synchronisation).

Goals live in the stance frame S (the home neck frame, fixed to the ground). The actual
end-effector pose is what the robot measures, as on the paper's robot: FK of the measured arm
joints, lifted by the FK of the measured legs (feet flat on the ground). The tool's position
through the estimated torso pose (the store's T_WORLD_TORSO in S) is tracked as well: it
also contains the whole body's sway and lean (the ankle controller of eq. 11-12 complies
with the ankle moments, so the robot leans when its centre of mass moves forward).

With ``correction`` (drill mode), the measured torso pose (the estimate's,
:mod:`hubo_cli.kinematics.torso`) corrects the corrected arms' joint targets every period: the
goal in S is solved in the measured neck frame, low-passed and bounded, so the sway moves the
arm and not the bit in the wall. Those arms' measured pose then goes through the measured torso
pose too (without it the body's lean would not show in their error).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from hubo_cli.control.keys import ARM_SYNC, ARM_TARGET_VELOCITY, TRACKER_STATES
from hubo_cli.control.phase import Phases
from hubo_cli.control.target import Target
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import QUAT_WORLD_TORSO, T_WORLD_SOLES, T_WORLD_TORSO
from hubo_cli.input.device import InputDevice
from hubo_cli.kinematics.arm_reach import ArmReach, BranchMove, ReachSettings
from hubo_cli.kinematics.choice import STATUS_NAMES
from hubo_cli.kinematics.conditioning import SingularityScale, condition_number
from hubo_cli.kinematics.dh import invert4, kernel_array, mul4, pose_error
from hubo_cli.kinematics.interpolate import PosePath
from hubo_cli.kinematics.reach import branch_of
from hubo_cli.kinematics.torso import CorrectionSettings, MeasuredTorso, TorsoCorrection
from hubo_cli.kinematics.wholebody import LiftFilter, WholeBody
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.scene import SceneActions, WallPlacement
from hubo_cli.teleop.hand_report import hand_report
from hubo_cli.teleop.lead import DECAY_S, GoalVelocity, tracking_target
from hubo_cli.teleop.mapping import HandMapper
from hubo_cli.teleop.phases import PHASES, Approach, Operate, Settle
from hubo_cli.teleop.reach_lead import (
    AHEAD_S,
    LEAD_BEYOND_M,
    LEAD_SCALE_SHARE,
    MIN_SPEED_M_S,
    RETURN_BEHIND_M,
    RETURN_DECAY_S,
    ReachLead,
)
from hubo_cli.teleop.target_kernels import (
    free_goal,
    hand_errors,
    max_abs_difference,
    operator_pose_plausible,
    path_swing_m,
    tilt_rad,
)
from hubo_cli.teleop.trade import traded_goal

SHORT = {"right-arm": "r", "left-arm": "l"}
_STATUS_CODE = {name: code for code, name in enumerate(STATUS_NAMES)}  # the log's ik_code
_EYE4 = np.eye(4)  # read only
REST_RADIUS_M = 0.005  # a goal that stays within this for REST_S is at rest
REST_S = 0.5
# while operating, each arm joint of the trajectory generator tracks its target on its own
# (ruckig without synchronisation: on the two-hand sample 6.8 / 6.9 mm RMS against 8.0 / 8.2 mm
# with phase-synchronised arms), unless the hand would swing more than SWING_M off the straight
# line to the target on the way there: then the joints keep the straight line in joint space
# (phase), as they do in the approach's joint-space moves. Unsynchronised across a large gap the
# joints arrive one by one and the hand swings off (84 mm beyond the goal's distance to the
# reachable set where a stretched arm comes back, 23 mm with the rule; drill mode's first move
# would swing the drill into the torso), and a lagging hand whose goal speeds up dips below the
# goal's path (two-hand-free.fastrak: 15.5 mm max excursion with a rule on the joints' lag
# alone, phase beyond 0.15 rad; 12.7 mm with this one).
OPERATE_SYNCHRONIZATION = "none"
SWING_M = 0.003
SWING_SAMPLES = 8  # points of the previewed way the swing is measured at (ends included)
# a goal is reachable when the reach search's nearest pose on the arm's branch is this close
# to it (the search stops within a fraction of a millimetre of a reachable goal)
REACHABLE_POSITION_M = 0.002
REACHABLE_ROTATION_RAD = np.radians(1.0)


@dataclass
class HandTrack:
    """Per-arm bookkeeping for metrics and the live view (positions in S, m)."""

    goal_m: np.ndarray | None = None
    actual_m: np.ndarray | None = None
    ik_status: str = "-"
    ik_counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(STATUS_NAMES, 0))
    stale: bool = False
    lost: bool = False          # went stale after calibration: re-centre before moving again
    needs_clutch: bool = False  # live: input is back, waiting for the operator's re-centre
    clutched: bool = False      # the operator holds the device's clutch: re-centre on release
    reachable: bool = True      # the reach search's nearest pose is the goal (within tolerance)
    position_error_m: float = float("nan")
    rotation_error_rad: float = float("nan")
    missing_m: np.ndarray | None = None  # goal minus the reachable pose's position, at the limit
    speed_scale: float = 1.0
    branch_move: BranchMove | None = None
    notice: str = ""
    branch_changes: int = 0
    at_limit_periods: int = 0
    rest_anchor_m: np.ndarray | None = None
    rest_since_s: float = 0.0
    last_branch: int | None = None
    beyond_m: float = 0.0  # the goal's largest distance beyond the reach, this time out of it
    leading: bool = False  # the target leads the goal (reach_lead) this period
    returning: bool = False  # the goal came back into reach from LEAD_BEYOND_M or more beyond
    # it and still moves (reach_lead.ReachLead.back_lead_m)
    passed: bool = False  # since then, the goal has passed the hand along its velocity
    behind_m: float = 0.0  # while returning: how far the hand is behind the goal along its
    # velocity (m; last period's positions), 0 when not known
    operated_periods: int = 0  # periods recorded following the goal in the world (_record)
    reachable_periods: int = 0  # ... of them with the goal reachable, and over those the sums
    reachable_sq_position_m2: float = 0.0  # of the squared position error (m^2)
    reachable_sq_rotation_rad2: float = 0.0  # and of the squared rotation error (rad^2)

    @property
    def at_limit(self) -> bool:
        """The goal is out of reach: the hand is held at the nearest reachable pose."""
        return self.missing_m is not None

    def reachable_so_far(self) -> tuple[float, float, float] | None:
        """The share of the recorded periods whose goal was reachable and the position (mm)
        and orientation (deg) RMS over them, so far (what the live view shows; the run's
        report computes the same from the whole record); None before any reachable period."""
        n = self.reachable_periods
        if not n:
            return None
        return (n / self.operated_periods, math.sqrt(self.reachable_sq_position_m2 / n) * 1000,
                math.degrees(math.sqrt(self.reachable_sq_rotation_rad2 / n)))

    @property
    def held(self) -> bool:
        """The hand holds by design: its input stale, waiting for the operator's re-centre,
        or clutched (its distance to the goal is then no miss)."""
        return self.stale or self.lost or self.needs_clutch or self.clutched


@dataclass
class Keys:
    """Operator requests gathered since the last period (set by the key reader / CLI)."""

    estop: bool = False
    release: bool = False
    clutch: bool = False
    quit: bool = False
    branch: bool = False

    def take(self) -> Keys:
        """Return the pending requests and clear them."""
        pending = Keys(self.estop, self.release, self.clutch, self.quit, self.branch)
        self.estop = self.release = self.clutch = self.quit = self.branch = False
        return pending


class TeleopTarget(Target):
    """Target source for :class:`hubo_cli.control.loop.ControlLoop`.

    Args:
        model: the robot model.
        source: the input device (a recording, a generated stream, a live device).
        mapper: calibration and mapping of tracker poses onto hand goals.
        body: the whole-body solver (its arms' tools are the end effectors).
        approach: arm -> the Cartesian path (goals in S) each hand follows before the operator
            takes over; its end is the hand's start pose.
        q_start_rad: the posture the loop starts from.
        live: the input is a live device (its clock is the wall clock).
        stale_timeout_s: a hand silent this long (by its poses' own times) is stale.
        settle_s: after a replay ends, how long the robot may take to come to rest.
        approach_timeout_s: each approach step waits at most this long for the robot to settle.
        clutch_at_s: replay times (s) at which to re-centre (as if ``c`` was pressed).
        wall: placed once the robot is still at the approach's first pose (drill mode: the
            robot raises its tool away from the wall, as an operator would bring it up to the
            wall with the tool ready); in a simulator only.
        reach: how the arms behave at the edge of their reach (branch, nearest pose, paper);
            None: the mapping mode's defaults (:meth:`ReachSettings.for_mode`).
        singularity: the speed scale near singular configurations (``reach="nearest"`` only);
            None: the reach settings' one.
        correction: correct these arms' goals by the measured torso pose (see the module
            docstring); empty: none.
        correction_settings: its filter and bounds (None: the defaults).
        lift: the legs' lift filter (None: :class:`LiftFilter`'s defaults).
    """

    reads = (QUAT_WORLD_TORSO, T_WORLD_TORSO, T_WORLD_SOLES)
    writes = (ARM_SYNC, ARM_TARGET_VELOCITY)  # each arm's synchronization and its goal's
    # velocity, for otg (groups limbs)
    previous = (TRACKER_STATES,)  # otg's trackers after last period

    def __init__(self, model: RobotModel, source: InputDevice, mapper: HandMapper,
                 body: WholeBody, approach: dict[str, PosePath], q_start_rad: np.ndarray,
                 *, live: bool = False, stale_timeout_s: float = 0.25, settle_s: float = 1.0,
                 approach_timeout_s: float = 5.0, clutch_at_s: tuple[float, ...] = (),
                 wall: WallPlacement | None = None, reach: ReachSettings | None = None,
                 singularity: SingularityScale | None = None, correction: tuple[str, ...] = (),
                 correction_settings: CorrectionSettings | None = None,
                 lift: LiftFilter | None = None) -> None:
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
        self.arms = sorted(set(mapper.config.hand_arm.values()) & set(ARMS))
        self.slices = {arm: model.limb_slice(arm) for arm in ARMS}
        self.q_target = np.array(q_start_rad, dtype=float)
        self.q_out = self.q_target.copy()  # q_target corrected by the measured torso pose
        self._q_out_of = self.q_target.copy()  # the q_target that q_out corrects
        self.torso = MeasuredTorso(body)  # the estimate's torso pose, in S
        self.correction = (TorsoCorrection(body, correction, model.control_period_s,
                                           correction_settings)
                           if correction else None)
        self.lift = lift or LiftFilter()
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
        self.world: SceneActions | None = None
        self.scene: dict = {}
        self.goals: dict[str, np.ndarray] = dict(firsts)
        self.hands = {arm: HandTrack() for arm in self.arms}
        self.reach_settings = reach or ReachSettings.for_mode(mapper.config.mode)
        self.reach = {arm: ArmReach(body.arms[arm], self.reach_settings) for arm in approach}
        self.leads = {arm: ReachLead() for arm in self.arms}  # at the reach limit
        self.singularity = singularity or self.reach_settings.singularity
        self.room = None  # arm targets keep out of the collision detector's band
        # once operating, where the trajectory generator has a tracker per arm: a copy of each
        # (its limits, set each period to its state) to preview the arm's way with
        self._trackers: dict[str, JointTracker] | None = None
        self._goal_velocity: dict[str, GoalVelocity] = {}  # and the goals' velocities
        self._decay_s: dict[str, np.ndarray] = {}  # and DECAY_S per joint, for tracking_target
        self._conditions: dict[str, tuple] = {}  # arm -> the last (joints' bytes, condition
        # number)s
        if self.reach_settings.mode == "nearest" and self.reach_settings.collision_room_m > 0:
            from hubo_cli.teleop.room import CollisionRoom

            self.room = CollisionRoom(model, drill=body.tools.get("right-arm") == "drill",
                                      room_m=self.reach_settings.collision_room_m,
                                      arms=tuple(self.arms))
        self._compile_kernels()
        self.rotation_errors_rad: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self.path_times_s: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self._t_solved_s: dict[str, float] = {}
        self._q_measured = self.q_target.copy()
        self.phases = Phases([Approach(self), Operate(self), Settle(self)])
        self.info: dict = {}  # this period's, which the phases add to
        self.keys_now = Keys()  # the operator's keys taken this period
        self.t_operate_s: float | None = None
        self.t_settle_s: float | None = None
        self.latencies_s: list[float] = []
        self.operate_call_s: list[float] = []  # this target's own time per operating period
        self.operate_cpu_s: list[float] = []  # and its thread's CPU time
        self.samples_used = 0
        # hand -> the sample time of its newest usable pose (followed, or held by the clutch)
        self.last_sample_s: dict[str, float] = {}
        self.errors_m: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self.reachable: dict[str, list[bool]] = {arm: [] for arm in self.arms}
        # per period: the hand meant to follow its goal (input live, not held for a re-centre,
        # clutch released); a held hand's distance to the goal is no miss
        self.meant_to_follow: dict[str, list[bool]] = {arm: [] for arm in self.arms}
        self.world_errors_m: dict[str, list[float]] = {arm: [] for arm in self.arms}
        self.max_tilt_rad = 0.0
        self.paths: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {a: [] for a in self.arms}
        self._info_names = {arm: tuple(f"{c}_{SHORT[arm]}" for c in (
            "actual_x_m", "actual_y_m", "actual_z_m", "ik_code", "reach_limit_m", "speed_scale",
            "goal_x_m", "goal_y_m", "goal_z_m", "error_m", "rot_error_rad")) for arm in self.arms}
        self._hand_of: dict[str, str] = {}  # arm -> the operator's hand that drives it
        for hand_name, arm in mapper.config.hand_arm.items():
            self._hand_of.setdefault(arm, hand_name)
        self._right_leg = model.limb_slice("right-leg")  # lift_of reads it
        self._chains = {arm: limb.fk_chain for arm, limb in body.arms.items()}
        self._lifts: dict[bytes, float] = {}  # _lift_of's memory
        self._T_S_N_now: np.ndarray | None = None  # _T_S_N's, this period
        self.log_columns = tuple(
            f"{c}_{SHORT[a]}" for a in self.arms
            for c in ("goal_x_m", "goal_y_m", "goal_z_m", "actual_x_m", "actual_y_m",
                      "actual_z_m", "error_m", "ik_code", "rot_error_rad", "reach_limit_m",
                      "speed_scale")) + ("phase_code", "lift_m", "latency_s")

    def _compile_kernels(self) -> None:
        """Call each compiled per-period kernel once: compiled (or loaded from numba's cache)
        here, before the loop runs, and not in its first operating period (a kernel's first
        load takes milliseconds: a period's budget is 5 ms)."""
        zeros = np.zeros(6)
        limits = JointLimits(zeros - 1.0, zeros + 1.0, zeros + 1.0, zeros + 1.0, zeros + 1.0)
        goal_velocity = GoalVelocity(limits, self.dt_guard_s)
        for _ in range(goal_velocity.samples):
            goal_velocity.update(zeros, True)
        tracking_target(zeros + 0.1, zeros, zeros, zeros, limits)
        operator_pose_plausible(_EYE4, 1.0)
        tilt_rad(np.array([1.0, 0.0, 0.0, 0.0]))
        max_abs_difference(zeros, zeros)
        free_goal(_EYE4, _EYE4, _EYE4, _EYE4, 1.0, 1.0, 0.5, np.empty((4, 4)))
        pose_error(_EYE4, _EYE4)  # a moved arm's clear pose
        invert4(_EYE4, np.empty((4, 4)))  # the measured torso's stance, placed once
        mul4(_EYE4, _EYE4, np.empty((4, 4)))  # the legs' goals (WholeBody.legs_at)
        for reach in self.reach.values():
            limb = reach.limb
            condition_number(limb, zeros)
            smoothing = ArmReach(limb, reach.settings)  # a throwaway: the arm's own untouched
            smoothing.smoothed(_EYE4, 0.0)  # the first goal starts it, the second is smoothed
            smoothing.smoothed(_EYE4, 0.0)
            smoothing.start(zeros)  # the branch, then the solve on it
            smoothing.solve_into(_EYE4, zeros, np.empty(6))
            path_swing_m(np.zeros((3, 6)), *limb.fk_chain)
            traded_goal(zeros + 0.1, zeros + 0.1, zeros, zeros, limits, limb.fk_chain)
            hand_errors(zeros, *limb.fk_chain, False, 0.0, _EYE4, _EYE4, True, np.empty((4, 4)))

    def attach(self, world: SceneActions | None, modules, store: Store) -> None:
        self.world, self.store = world, store

    # ------------------------------------------------------------------ measurement
    def _T_S_N(self) -> np.ndarray:
        """The measured neck frame in S (4x4, m): the estimate's torso pose (computed once a
        period, when first asked)."""
        if self._T_S_N_now is None:
            self._T_S_N_now = self.torso(self.store[T_WORLD_TORSO], self.store[T_WORLD_SOLES])
        return self._T_S_N_now

    def hand_pose_commanded(self, arm: str) -> np.ndarray:
        """T_S_E of an arm's tool for the current joint target (4x4, m)."""
        goal = self.goals.get(arm)
        return goal if goal is not None else self.body.arms[arm].fk(
            self.q_target[self.slices[arm]])

    def _record_ik(self, solved) -> None:
        for arm, result in solved.arms.items():
            if arm in self.hands:
                hand = self.hands[arm]
                hand.ik_status = result.status
                hand.ik_counts[result.status] += 1
                if self.phase == "operate":  # the paper's rule: count the branch switches
                    branch = int(branch_of(result.q_rad))
                    if hand.last_branch is not None and branch != hand.last_branch:
                        hand.branch_changes += 1
                    hand.last_branch = branch

    @property
    def phase(self) -> str:
        """The phase in force (one of :data:`~hubo_cli.teleop.phases.PHASES`)."""
        return self.phases.current.name

    @property
    def q_measured_rad(self) -> np.ndarray:
        """The joints as measured this period (24, rad; read-only view)."""
        view = self._q_measured.view()
        view.flags.writeable = False
        return view

    # ------------------------------------------------------------------ the loop's call
    def __call__(self, t_s: float, state) -> tuple[np.ndarray | None, dict]:
        # the CPU clock read first: it is not the target's work and costs about 2 us (a system
        # call on cold caches), and the wall clock is read last at the end
        cpu0, t0 = time.thread_time(), time.perf_counter()
        self.info = info = {}
        self.keys_now = keys = self.keys.take()
        self._q_measured = state.q_rad
        self._T_S_N_now = None
        if keys.estop:
            info["estop"] = "operator"
        if keys.release:
            info["release"] = True
        if keys.quit:
            info["done"] = True
        self.phases(t_s, state)
        self.q_out = (self.q_target if self.correction is None
                      else self.correction(self.q_target, self._T_S_N()))
        self._q_out_of = self.q_target
        self._pace_arms()
        self._measure(t_s, state, info)
        self._T_S_N_now = None  # outside a period, asked anew
        if self.phase == "operate":
            self.operate_call_s.append(time.perf_counter() - t0)
            self.operate_cpu_s.append(time.thread_time() - cpu0)
        return self.q_out, info

    def _pace_arms(self) -> None:
        """Each arm's tracker: while the hand follows its goal, led to where it meets the
        goal's prediction and arriving with its velocity (:func:`hubo_cli.teleop.lead.
        tracking_target`), unsynchronised unless that way to the target swings the hand more
        than ``SWING_M`` off the straight line to it, phase synchronised then."""
        if self._trackers is None:
            return
        states, synchronization, velocity = self.store[TRACKER_STATES], {}, {}
        for arm in self.arms:
            tracker, now = self._trackers[arm], states[arm]
            tracker.reset(now.q_rad, now.v_rad_s, now.a_rad_s2)
            target = self.q_out[self.slices[arm]]
            following = self._following(arm)
            v_goal = self._goal_velocity[arm].update(target, following)
            hand = self.hands.get(arm)
            decay = self._decay_s[arm]  # DECAY_S; a returning hand far behind: the goal's own
            # decay (reach_lead)
            if hand is not None and hand.returning and hand.behind_m >= RETURN_BEHIND_M:
                decay = self._goal_velocity[arm].decay_s(DECAY_S, RETURN_DECAY_S)
            traded = 0
            if following:  # joints that can follow make up for those that cannot
                goal, traded = traded_goal(target, v_goal, now.q_rad, now.v_rad_s,
                                           now.limits, self._chains[arm])
            led, velocity[arm], share = tracking_target(
                v_goal, goal if traded else target, now.q_rad, now.v_rad_s, now.limits, decay)
            if traded and not self._traded_clear(arm, led):  # the room holds: untraded
                traded = 0
                led, velocity[arm], share = tracking_target(v_goal, target, now.q_rad,
                                                            now.v_rad_s, now.limits, decay)
            if share > 0.0 or traded:  # the generator's target leads or trades (a copy)
                if self.q_out is self.q_target:
                    self.q_out = self.q_target.copy()
                self.q_out[self.slices[arm]] = target = led
            sync = OPERATE_SYNCHRONIZATION
            # an arm the room moves goes straight to its target, a short way from its
            # command (room.LEAD_RAD), clear of the body
            if ((self.room is not None and arm in self.room.moved)
                    or self.swing_m(arm, tracker, target, velocity[arm]) > SWING_M):
                sync = "phase"
            synchronization[arm] = sync
        self.store[ARM_SYNC] = synchronization
        self.store[ARM_TARGET_VELOCITY] = velocity

    def _traded_clear(self, arm: str, q_arm_rad: np.ndarray) -> bool:
        """The arm's traded target keeps the collision room (checked as the room checks the
        untraded one: the trade moves every joint of the arm after the room's search)."""
        if self.room is None:
            return True
        q = self.q_out.copy()
        q[self.slices[arm]] = q_arm_rad
        return self.room.clears(q)

    def _following(self, arm: str) -> bool:
        """The arm's target follows its goal freely this period (operating, the goal within
        reach and clear of the body, the hand neither held nor slowed nor changing branch; a
        hand returning into reach is followed while slowed: its goal moves inward, away from
        the straight elbow)."""
        hand = self.hands[arm]
        return (self.phase == "operate" and hand.reachable and not hand.at_limit
                and not hand.held
                and hand.branch_move is None and (hand.speed_scale >= 1.0 or hand.returning)
                and (self.room is None or arm not in self.room.moved))

    def swing_m(self, arm: str, tracker: JointTracker, target_rad: np.ndarray,
                target_v_rad_s: np.ndarray | None = None) -> float:
        """How far (m) the hand strays from the straight line between its commanded position and
        the target's on the tracker's unsynchronised way to ``target_rad`` (arm joints, rad),
        arriving with ``target_v_rad_s`` (default 0)."""
        if max_abs_difference(target_rad, tracker.q) < 1e-6:
            return 0.0
        path = tracker.preview(target_rad, OPERATE_SYNCHRONIZATION, SWING_SAMPLES,
                               target_v_rad_s)
        if len(path) < 3:
            return 0.0
        return path_swing_m(path, *self._chains[arm])

    def _settled(self, state) -> bool:
        # against the output; a target set this period has none yet: against the target
        q = self.q_out if np.array_equal(self._q_out_of, self.q_target) else self.q_target
        return bool(np.max(np.abs(state.q_rad - q)) < 0.01
                    and np.max(np.abs(state.dq_rad_s)) < 0.05)

    def approach_step(self, t_s: float, state) -> bool:
        """One period of the approach; True once it has ended (the robot still at the paths'
        ends, or the approach's timeout)."""
        if self.t_path_s is None:  # step 1: joint-space move to the pre-pose, then settle
            self.q_target = self.q_pre
            if self._settled(state) or t_s >= self.approach_timeout_s:
                self.t_path_s = t_s
                if self.world is not None and self.wall is not None:
                    self.scene = self.wall.place(self.world)
            return False
        t_path = t_s - self.t_path_s
        if t_path <= self.approach_s + self.dt_guard_s:  # step 2: the Cartesian paths
            self.goals = {arm: path.at(t_path) for arm, path in self.approach.items()}
            solved = self.body.solve(self.goals, self.q_target, lift_m=self.lift.lift_m)
            self.q_target = solved.q_rad
            self._record_ik(solved)
            return False
        return self._settled(state) or t_path >= self.approach_s + self.approach_timeout_s

    def start_operating(self, t_s: float) -> None:
        """The operator takes over at ``t_s``: each arm's tracker copied from otg's (the
        store's TRACKER_STATES) with its goal-velocity estimate, each reach search started
        from the arm's joint target."""
        self.t_operate_s = t_s
        if self.live:
            # a live device queued every pose since it opened (the start-up, the approach, a
            # walk): the operator's motion before he took over is no command. Dropped here, so
            # the first pose after the take-over calibrates (review 23: the oldest queued pose
            # calibrated and the rest were followed in the first period, the goals stepping
            # some 100 mm in one period on the emulator's circling hands)
            self.source.read_until(self._source_time(t_s))
        states = self.store.get(TRACKER_STATES)  # the arms' trackers, with their own
        if states is not None and all(arm in states for arm in self.arms):
            self._trackers = {arm: JointTracker(states[arm].limits, states[arm].dt_s)
                              for arm in self.arms}
            self._goal_velocity = {arm: GoalVelocity(states[arm].limits, states[arm].dt_s)
                                   for arm in self.arms}
            self._decay_s = {arm: np.full(states[arm].limits.size, DECAY_S)  # (read only)
                             for arm in self.arms}
        for arm, reach in self.reach.items():
            reach.start(self.q_target[self.slices[arm]])

    def _source_time(self, t_s: float) -> float:
        return self.source.now_s() if self.live else t_s - self.t_operate_s

    def operate_step(self, t_s: float, clutch: bool, branch_key: bool = False) -> list[str]:
        """One period of the operator's control (``clutch``: re-centre; ``branch_key``: the
        operator asks for another IK branch); returns the period's status flags."""
        t_src = self._source_time(t_s)
        while self.clutch_at_s and t_src >= self.clutch_at_s[0]:
            self.clutch_at_s.pop(0)
            clutch = True
        if clutch:
            self.mapper.forget()  # the next pose of each hand re-centres it
            for arm, hand in self.hands.items():
                hand.lost = hand.needs_clutch = False
                self._recentre(arm)
        samples = self.source.read_until(t_src)
        changed = False
        for sample in samples:
            if not sample.reliable:
                continue
            arm = self.mapper.config.hand_arm.get(sample.hand)
            if arm not in self.hands:
                continue
            hand = self.hands[arm]
            if not sample.engaged:  # the operator holds the clutch: hold, re-centre on release
                hand.clutched = True
                self.last_sample_s[sample.hand] = sample.t_s
                continue
            if hand.clutched:
                hand.clutched = False
                self.mapper.forget(sample.hand)
                self._recentre(arm)
            if hand.lost:
                if self.live:  # hold until the operator re-centres
                    hand.needs_clutch = True
                    continue
                hand.lost = False  # a replay re-centres by itself after a gap
                self.mapper.forget(sample.hand)
                self._recentre(arm)
            goal = self.mapper.goal(sample.hand, sample.T_operator_hand, sample.t_s,
                                    self.hand_pose_commanded(arm))
            if goal is None:
                continue
            self.goals[arm] = goal.T_S_goal
            self.last_sample_s[sample.hand] = sample.t_s
            self.samples_used += 1
            changed = True
        if samples:
            newest = max(s.t_s for s in samples)
            self.latencies_s.append(max(0.0, self._source_time(t_s) - newest))
        flags = []
        for hand_name, arm in self.mapper.config.hand_arm.items():
            if arm in self.hands:
                hand = self.hands[arm]
                stale = (self.source.is_stale(hand_name, t_src, self.stale_timeout_s)
                         or (not hand.needs_clutch and self._unusable(hand_name)))
                hand.stale = stale and self.mapper.is_calibrated(hand_name)
                if hand.stale:
                    hand.lost = True
                    flags.append("stale-input")
                elif hand.needs_clutch:
                    flags.append("holding")
        lift = self.lift.step(self.body.lift_for(self.goals), self.dt_guard_s)
        if changed or self._converging() or branch_key or lift != self._lift_of(self.q_target):
            if self.reach_settings.mode == "paper":
                solved = self.body.solve(self.goals, self.q_target, lift_m=lift)
                self.q_target = solved.q_rad
                self._record_ik(solved)
                for arm, result in solved.arms.items():
                    if arm in self.hands:
                        self.hands[arm].reachable = result.status == "exact"
            else:
                self._solve_on_branches(t_s, lift, branch_key)
        return flags

    def _unusable(self, hand_name: str) -> bool:
        """Poses of ``hand_name`` keep coming but none was usable (each unreliable, or a jump
        the mapper rejects) for longer than the stale timeout, by their own times: a tracker
        that lies from some moment on (a hemisphere flip, a knocked sensor) is as stale as a
        silent one, and not a hand that holds its goal without a word."""
        seen_s = self.source.last_seen_s(hand_name)
        used_s = self.last_sample_s.get(hand_name)
        return seen_s is not None and used_s is not None and seen_s - used_s > \
            self.stale_timeout_s

    def settle_step(self, t_s: float, state) -> bool:
        """One period of the settling after a replay; True once the robot is still at its
        goals (after at least ``settle_s``) or four times that has passed."""
        if self.reach_settings.mode == "nearest" and self._converging():
            self._solve_on_branches(t_s, self.body.lift_of(self.q_target), False)
        moving = np.max(np.abs(state.dq_rad_s)) if len(state.dq_rad_s) else 0.0
        at_goal = np.max(np.abs(state.q_rad - self.q_out)) < 0.02
        return bool((t_s - self.t_settle_s >= self.settle_s and moving < 0.02 and at_goal)
                    or t_s - self.t_settle_s >= 4 * self.settle_s)

    def _converging(self) -> bool:
        """An arm target is still on its way (nearest-pose search, slowed step, branch move)."""
        return any(h.branch_move is not None or h.at_limit or h.speed_scale < 1.0
                   for h in self.hands.values())

    def _solve_on_branches(self, t_s: float, lift_m: float, branch_key: bool) -> None:
        """Legs to the lift, each arm on its branch (nearest pose, branch moves, speed scale)."""
        q, lift_m = self.body.legs_at(self.q_target, lift_m)
        solved = {}  # arm -> (its reach, its goal in N) for the collision room's search
        for arm, T_S_goal in self.goals.items():
            sl = self.slices[arm]
            q_now = self.q_target[sl]
            reach = self.reach[arm]
            hand = self.hands.get(arm)  # as the last period left it
            T_N_goal = reach.smoothed(T_S_goal, t_s - self._t_solved_s.get(arm, t_s),
                                      hand is not None and not hand.at_limit
                                      and (self.room is None or arm not in self.room.moved))
            self._t_solved_s[arm] = t_s
            T_N_goal[2, 3] -= lift_m
            solved[arm] = (reach, T_N_goal)
            q_arm = np.empty(6)
            code, position_error_m, rotation_error_rad = reach.solve_into(T_N_goal, q_now, q_arm)
            if hand is not None:
                hand.ik_status = status = STATUS_NAMES[code]
                hand.ik_counts[status] += 1
                hand.position_error_m = position_error_m
                hand.rotation_error_rad = rotation_error_rad
                hand.missing_m = None
                hand.reachable = (position_error_m <= REACHABLE_POSITION_M
                                  and rotation_error_rad <= REACHABLE_ROTATION_RAD)
                lead = self.leads[arm]
                lead.push(t_s, T_N_goal[:3, 3])
                hand.leading = False
                if status == "nearest":
                    T_near = reach.limb.fk(q_arm)
                    hand.missing_m = T_N_goal[:3, 3] - T_near[:3, 3]
                    hand.at_limit_periods += 1
                    hand.beyond_m = max(hand.beyond_m, math.sqrt(hand.missing_m.dot(
                        hand.missing_m)))
                    if hand.beyond_m >= LEAD_BEYOND_M:
                        q_arm, hand.leading = self._led(reach, lead, T_N_goal, T_near, q_now,
                                                        q_arm)
                    hand.returning = False
                else:
                    if hand.beyond_m >= LEAD_BEYOND_M:  # back in reach from beyond it
                        hand.returning, hand.passed = True, False
                    hand.beyond_m = 0.0
                    if hand.returning:
                        q_arm, hand.leading = self._led_back(reach, hand, lead, T_N_goal,
                                                             q_now, q_arm)
                q_arm = self._branch_policy(t_s, arm, hand, T_N_goal, q_now, q_arm, branch_key)
            q[sl] = self._speed_scaled(arm, q_now, q_arm, hand)
        if self.room is not None:
            moving = {a: g for a, g in solved.items()
                      if a not in self.hands or self.hands[a].branch_move is None}
            states = self.store.get(TRACKER_STATES) if self._trackers is not None else None
            commanded = None if states is None else {
                a: states[a].q_rad for a in moving if a in states}
            q = self.room.keep(self.q_target, q, moving, commanded)
            for arm in self.room.moved & set(self.hands):  # the clear pose is what is reached
                reach, T_N_goal = solved[arm]
                hand = self.hands[arm]
                # (the searched pose: a target led from the command is on its way there)
                T_clear = reach.limb.fk(self.room.searched.get(arm, q[self.slices[arm]]))
                pos, rot = pose_error(T_clear, T_N_goal)
                hand.position_error_m, hand.rotation_error_rad = float(pos), float(rot)
                hand.reachable = (pos <= REACHABLE_POSITION_M
                                  and rot <= REACHABLE_ROTATION_RAD)
                hand.missing_m = None if hand.reachable else T_N_goal[:3, 3] - T_clear[:3, 3]
        self.q_target = q

    def _recentre(self, arm: str) -> None:
        """A re-centred hand's goal starts anew (re-anchored where the hand is): its lead
        forgets the goal's positions before and how far it went out of reach."""
        self.leads[arm].clear()
        hand = self.hands[arm]
        hand.beyond_m = 0.0
        hand.returning = False

    @staticmethod
    def _led(reach: ArmReach, lead: ReachLead, T_goal: np.ndarray, T_near: np.ndarray,
             q_now: np.ndarray, q_near: np.ndarray) -> tuple[np.ndarray, bool]:
        """The arm's joints for a goal ``T_goal`` beyond its reach, led toward it as it heads
        back (:mod:`hubo_cli.teleop.reach_lead`): the nearest reachable pose (``T_near``,
        joints ``q_near``) moved toward the nearest reachable pose of where the goal will be
        ``AHEAD_S`` later, by at most ``lead.lead_m_of`` its speed times the run-up share; on
        the branch, within the limits and margins; and whether it is led (False: ``q_near``
        as it is)."""
        v = lead.velocity_m_s()
        if v is None:
            return q_near, False
        speed = math.sqrt(v.dot(v))
        cap = lead.lead_m_of(speed) * lead.run_up_share(v, T_goal[:3, 3] - T_near[:3, 3])
        if not cap > 0.0:  # also a NaN
            return q_near, False
        T_ahead = T_goal.copy()
        T_ahead[:3, 3] += v * AHEAD_S
        offset = reach.limb.fk(reach.solve(T_ahead, q_now).q_rad)[:3, 3] - T_near[:3, 3]
        length = math.sqrt(offset.dot(offset))
        if length > cap:
            offset *= cap / length
        T_lead = T_near.copy()
        T_lead[:3, 3] += offset
        q_led = reach.solve(T_lead, q_now).q_rad
        moved = reach.limb.fk(q_led)[:3, 3] - T_near[:3, 3]
        if math.sqrt(moved.dot(moved)) > cap + 1e-4:
            return q_near, False
        return q_led, True

    @staticmethod
    def _led_back(reach: ArmReach, hand: HandTrack, lead: ReachLead, T_goal: np.ndarray,
                  q_now: np.ndarray, q_goal: np.ndarray) -> tuple[np.ndarray, bool]:
        """The arm's joints for a goal ``T_goal`` back in reach from beyond it (``q_goal``: its
        own): the goal moved along its velocity by :meth:`ReachLead.back_lead_m`, the hand's
        lag behind it from the last period's measured positions; and whether it is led. The
        return is over once the goal has no velocity, moves slower than ``MIN_SPEED_M_S`` or
        no longer closes in on the shoulder (toward the straight elbow, where the arm is slowed
        and not followed again: :meth:`_following`)."""
        v = lead.velocity_m_s()
        speed = 0.0 if v is None else math.sqrt(v.dot(v))
        if v is None or speed < MIN_SPEED_M_S \
                or not float(v @ (T_goal[:3, 3] - reach.limb.T_N_base[:3, 3])) < 0.0:
            hand.returning = False
            return q_goal, False
        behind_m = (0.0 if hand.goal_m is None or hand.actual_m is None
                    else float((hand.goal_m - hand.actual_m) @ v) / speed)
        if not math.isfinite(behind_m):  # a position not finite: no lag known
            behind_m = 0.0
        hand.behind_m = behind_m
        hand.passed = hand.passed or behind_m > 0.0
        lead_m = lead.back_lead_m(speed, behind_m, hand.passed)
        if not lead_m > 0.0:
            return q_goal, False
        T_lead = T_goal.copy()
        T_lead[:3, 3] += v * (lead_m / speed)
        return reach.solve(T_lead, q_now).q_rad, True

    def _branch_policy(self, t_s, arm, hand: HandTrack, T_N_goal, q_now, q_arm,
                       branch_key: bool) -> np.ndarray:
        """Start, follow or finish a slow branch change; returns the arm's joints."""
        reach = self.reach[arm]
        goal_m = T_N_goal[:3, 3]
        moved = None if hand.rest_anchor_m is None else goal_m - hand.rest_anchor_m
        if moved is None or math.sqrt(moved.dot(moved)) > REST_RADIUS_M:  # np.linalg.norm
            hand.rest_anchor_m, hand.rest_since_s = goal_m.copy(), t_s
        at_rest = t_s - hand.rest_since_s >= REST_S
        if hand.branch_move is None and hand.at_limit and (
                branch_key or (self.reach_settings.allow_branch_change and at_rest)):
            q_to = reach.other_branch(T_N_goal, q_now)
            if q_to is not None:
                hand.branch_move = reach.plan_branch_move(q_now, q_to, t_s)
                hand.notice = (f"branch change {reach.branch} -> {hand.branch_move.branch_to} "
                               f"({hand.branch_move.duration_s:.1f} s)")
            elif branch_key:
                hand.notice = "no other branch reaches the goal"
        if hand.branch_move is None:
            return q_arm
        q_move, finished = hand.branch_move.at(t_s)
        if finished:
            reach.branch = hand.branch_move.branch_to
            hand.branch_move = None
            hand.branch_changes += 1
            hand.notice = f"on branch {reach.branch}"
        return q_move

    def _speed_scaled(self, arm: str, q_now, q_next, hand: HandTrack | None) -> np.ndarray:
        """Slow the arm near a singular configuration: its target moves at most ``scale`` times
        the speed limits (uniformly, direction kept) and leads the measured joints by at most
        the distance in which the jerk-limited trajectory generator stops from that speed, so
        the joints themselves stay near it."""
        limb = self.reach[arm].limb
        kappa_now, kappa_next = self._condition(arm, q_now), self._condition(arm, q_next)
        scale = self.singularity.scale(kappa_now, kappa_next)
        if hand is not None and hand.leading:  # as an approach's band, times the share
            scale = LEAD_SCALE_SHARE * self.singularity.scale(kappa_now,
                                                              max(kappa_now, kappa_next))
        if hand is not None:
            hand.speed_scale = scale
        if scale >= 1.0:
            return q_next
        spec = limb.spec
        step = q_next - q_now
        biggest = np.max(np.abs(step) / (scale * spec.velocity_rad_s * self.dt_guard_s))
        q = q_now + step / biggest if biggest > 1.0 else q_next
        q_measured = self._q_measured[self.slices[arm]]
        speed = scale * spec.velocity_rad_s  # the generator stops from it within the lead:
        lead = (speed**2 / (2 * spec.acceleration_rad_s2)
                + speed * spec.acceleration_rad_s2 / (2 * spec.jerk_rad_s3))
        return np.clip(q, q_measured - lead, q_measured + lead)

    def _condition(self, arm: str, q_rad: np.ndarray) -> float:
        """:func:`condition_number` of the arm at ``q_rad``, remembered for the last joints
        asked of each arm (the next period's ``q_now`` is mostly this period's ``q_next``)."""
        key = q_rad.tobytes()
        cached = self._conditions.get(arm)
        for q_known, kappa in cached or ():
            if q_known == key:
                return kappa
        kappa = condition_number(self.reach[arm].limb, q_rad)
        self._conditions[arm] = ((key, kappa), *(cached or ())[:1])
        return kappa

    def reach_report(self) -> dict[str, dict]:
        """Per hand, while operating, :func:`~hubo_cli.teleop.hand_report.hand_report` of its
        record: the errors over the whole time, the reachable, followed and steady time, the
        excursions, the time at the reach limit, the branch changes and the time its target
        was kept out of the collision band."""
        return {arm: hand_report(
            self.path_times_s[arm], self.paths[arm], self.errors_m[arm],
            self.rotation_errors_rad[arm], self.reachable[arm], self.meant_to_follow[arm],
            at_limit_s=hand.at_limit_periods * self.dt_guard_s,
            branch_changes=hand.branch_changes,
            collision_room_s=0.0 if self.room is None
            else self.room.pushed_periods.get(arm, 0) * self.dt_guard_s)
            for arm, hand in self.hands.items()}

    def _measure(self, t_s: float, state, info: dict) -> None:
        phase = self.phase
        info["phase_code"] = PHASES.index(phase)
        info["lift_m"] = self._lift_of(self.q_target)
        info["latency_s"] = self.latencies_s[-1] if self.latencies_s else 0.0
        operating = phase == "operate"
        lift_measured_m = None  # the measured legs' lift, computed once when first needed
        q_measured = state.q_rad
        for arm, hand in self.hands.items():
            names = self._info_names[arm]
            goal = self.goals.get(arm)
            corrected = self.correction is not None and arm in self.correction.arms
            world = (goal is not None and operating
                     and self.mapper.is_calibrated(self._hand_of[arm]))
            T_S_N = self._T_S_N() if corrected or world else _EYE4
            if not corrected and lift_measured_m is None:
                lift_measured_m = self._lift_of(q_measured)
            base, offset, alpha, a, d, end = self._chains[arm]
            T_actual = np.empty((4, 4))
            error, rot_error, world_error = hand_errors(
                kernel_array(q_measured[self.slices[arm]]), base, offset, alpha, a, d, end,
                corrected, 0.0 if corrected else lift_measured_m, T_S_N,
                _EYE4 if goal is None else kernel_array(goal), world, T_actual)
            actual = T_actual[:3, 3]
            hand.actual_m = actual
            missing = hand.missing_m
            info[names[0]], info[names[1]], info[names[2]] = actual.tolist()
            info[names[3]] = _STATUS_CODE.get(hand.ik_status, -1)
            info[names[4]] = (0.0 if missing is None
                              else math.sqrt(missing.dot(missing)))  # np.linalg.norm's
            info[names[5]] = hand.speed_scale
            if goal is None:
                continue
            hand.goal_m = goal_m = goal[:3, 3]
            info[names[6]], info[names[7]], info[names[8]] = goal_m.tolist()
            info[names[9]], info[names[10]] = error, rot_error
            if world:
                self._record(arm, t_s, hand, goal_m, actual, error, rot_error, world_error)
        self.max_tilt_rad = max(self.max_tilt_rad, tilt_rad(kernel_array(
            self.store[QUAT_WORLD_TORSO])))

    def _record(self, arm: str, t_s: float, hand, goal_m: np.ndarray, actual_m: np.ndarray,
                error_m: float, rotation_error_rad: float, world_error_m: float) -> None:
        """Record one period of ``arm`` following its goal in the world (what the reach and
        tracking reports read): its errors, whether the goal was reachable and whether the
        hand was meant to follow it, the time and the goal and actual positions (m)."""
        self.errors_m[arm].append(error_m)
        self.reachable[arm].append(hand.reachable)
        self.meant_to_follow[arm].append(not hand.held)
        self.rotation_errors_rad[arm].append(rotation_error_rad)
        self.path_times_s[arm].append(t_s)
        self.paths[arm].append((goal_m.copy(), actual_m.copy()))
        self.world_errors_m[arm].append(world_error_m)
        hand.operated_periods += 1
        if hand.reachable:
            hand.reachable_periods += 1
            hand.reachable_sq_position_m2 += error_m * error_m
            hand.reachable_sq_rotation_rad2 += rotation_error_rad * rotation_error_rad

    def _lift_of(self, q_rad: np.ndarray) -> float:
        """:meth:`WholeBody.lift_of` of a joint vector, remembered for the last few leg
        postures asked (the joint target and the measured joints are asked every period)."""
        key = q_rad[self._right_leg].tobytes()
        lift = self._lifts.get(key)
        if lift is None:
            if len(self._lifts) >= 4:
                self._lifts.clear()
            lift = self._lifts[key] = float(self.body.lift_of(q_rad))
        return lift

    def hand_of(self, arm: str) -> str:
        """The operator's hand that drives ``arm``."""
        return self._hand_of[arm]
