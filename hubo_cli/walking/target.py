"""The walking target: plans the walk from where the estimate puts the feet in its first
period, then sends the pattern's joints one period at a time and measures what the robot did.

It acts on the estimation layer's keys (:mod:`hubo_cli.estimation.keys`: the soles' and the
torso's poses, contact, compensated wrenches, CoM, ZMP, capture point), never on the
simulator's frames, so it walks on any driver; it tells the capture-point monitor the support it
plans (:data:`~hubo_cli.control.phase.SUPPORT_PLAN`) through the store.

Its phases (``walk.phase_code``, :data:`WALK_PHASES`):

* ``walk``: the pattern. While a foot swings (up to CP_WINDOW of its single support), the
  estimated capture point's error from the pattern's (as it was before that swing's moves)
  beyond a margin, as it will have grown by the landing (exp(omega t), at most CP_GAIN_MAX),
  moves that landing further (never back, in that swing) and every later footstep
  (:func:`~hubo_cli.walking.replan.shifted_landing`: hrpsys AutoBalancer's footstep
  modification, within step limits, never across the stance leg); the pattern is re-planned
  (:func:`~hubo_cli.walking.replan.pattern_from`) from the period it is decided in, its first
  rows solved then and the rest a slice a period while they play (REPLAN_ROWS_PER_PERIOD; too
  late for this landing (CP_BLEND_PERIODS before it): not moved); a later re-plan replaces a
  rest being computed. After a push from the front that stopped the walk (the capture-point
  monitor), early in a swing (CP_ABANDON_FRACTION), a swing foot still behind the landing
  that would capture the body (the capture point predicted at touchdown by the linear
  inverted pendulum) is put down where it is instead (:meth:`WalkTarget._abandoned`). A
  swing foot pushed onto the floor (the estimate's sole in contact and loaded, past
  TOUCH_FRACTION of its swing, TOUCH_MIN_HEIGHT_M or more above its landing in the pattern)
  ends its swing there: the step lands where that sole stands and, the capture point off the
  pattern's (a push), the timeline from the landing on plays at once, else the foot stays
  down until the planned landing (:meth:`WalkTarget._touched_early`); lifted again under the
  robot's weight, it fell. A swing leg is pitched at its hip against the
  estimated torso's pitch from the planned one (beyond LEVEL_DEAD_RAD), so that a foot carried
  by a body tipped by a push lands flat (:meth:`WalkTarget._level_swing`); against the
  torso's roll toward the stance side (a side push rolling the body over the stance sole's
  outer edge) the swing leg's sole goal is turned back about that edge, so the foot keeps its
  planned place over the floor and lands as the body rolls back, and a walk so tipped stops
  once that foot has landed (:mod:`~hubo_cli.walking.floor_reach`,
  :meth:`WalkTarget._caught`); a push that would take the capture point over that edge
  within 0.2 s abducts the hip rolls, the swing one then the stance one, moving the
  centroidal moment pivot beyond the edge (:mod:`~hubo_cli.walking.momentum`; the floor reach
  holds meanwhile). From the last
  step's landing on (the pattern's settle) the stabilizer's torso offset holds, as in
  ``stopping``: integrating there, it wound up and kept the soles' loads chattering until the
  next plan's start (docs/history/walking.md, "The walk's own settle"). A foot lifts off only
  while the ankles' sensors read the soles carrying the body (LIFTOFF_MIN_LOAD); a landing
  that bounced the robot into the air makes the timeline wait at the lift-off
  (:meth:`WalkTarget._unloaded_liftoff`), at most LIFTOFF_WAIT_MAX_S. At the lift-off of
  each of the plan's last REAIM_STEPS steps the landings still to come move by the stance
  sole's drift from its place in the pattern, as the estimate sees it
  (:meth:`WalkTarget._reaim`): the feet end where the plan put them without the correction
  walked after the pattern, which stays for the walks that still end off.
* ``stopping``: entered when the soft stopper has latched (its mode, the previous period's
  :data:`~hubo_cli.control.keys.STOP_MODE`, is no longer ``release``), or when a foot the floor
  reach turned has landed (:meth:`WalkTarget._caught`), or when a landed foot bounced off the
  floor with the estimated capture point LANDING_WALK_PUSHED_M or more off the pattern's
  (:meth:`WalkTarget._unloaded_landing`), or when a lift-off would leave the body on a foot
  reading unloaded with the capture point off the pattern's
  (:meth:`WalkTarget._unloaded_liftoff`): the step in progress is finished
  (the swing foot lands; before the first step, none is taken) into a double-support stance, the
  CoM comes to rest between the feet over ``settle_s``; after a push, a landing's weight
  transfer waits in the periods its landed foot reads unloaded, bounced off the floor
  (:meth:`WalkTarget._unloaded_landing`). Every period the walk tells the stopper that it stops
  itself so (:data:`~hubo_cli.control.phase.PHASE_STOP`), and the stopper passes this motion
  through instead of reverting it. The stabilizer's torso offset holds from the latch on (the
  soles' damping goes on): its CoM feedback integrates the CoM's error, so in a stance rocking
  on its sole edges it shifts the torso in phase with the rocking's speed, its weight feeding
  the rocking until the held stance tipped over its toes (docs/history/walking.md, "The rocking
  after a stop").
* ``stood``: the stance is reached; the stopper holds it; the run ends STOOD_S later. A
  release does not resume the walk.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace

import numba as nb
import numpy as np
import pinocchio as pin

from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.lip_feedback import LipFeedback
from hubo_cli.control.phase import PHASE_STOP, SUPPORT_PLAN, PhaseStop, SupportPlan
from hubo_cli.control.target import Target, TargetOutput
from hubo_cli.control.wrench_distribution import WrenchDistributor
from hubo_cli.dataflow import Store
from hubo_cli.errors import DeviceError, InputError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
    ZMP_WORLD,
)
from hubo_cli.falls import has_fallen
from hubo_cli.geometry import pose_laid_flat, rigid_inverse, tilt_rad_of_z_axis
from hubo_cli.kinematics.choice import CAPPED, EXACT, solve_limb
from hubo_cli.kinematics.dh import JIT, TRUE
from hubo_cli.model import RobotModel
from hubo_cli.posture import check_stands_in
from hubo_cli.scene import SceneActions
from hubo_cli.state import ANKLE_SENSORS, GRAVITY_M_S2, RobotState
from hubo_cli.walking.body import (
    SIDE_LEG,
    JointPlan,
    WalkingBody,
    poses_of_rows,
    run_slices,
    unsolved_plan,
)
from hubo_cli.walking.floor_reach import FloorReach
from hubo_cli.walking.footsteps import (
    Footstep,
    Stance,
    closing_steps,
    plan_footsteps,
    stance_of,
    within_limits,
)
from hubo_cli.walking.gait import Gait, make_gait
from hubo_cli.walking.lead_in import blend_from_held, levelled, torso_lead
from hubo_cli.walking.momentum import MomentumStrategy
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.replan import (
    CP_MARGIN_M,
    TOUCH_BLEND_ROWS,
    Fix,
    continued_fix,
    gait_rows,
    pattern_from,
    prefix_rows,
    rest_of,
    shift_steps,
    shifted_landing,
    with_fix,
)
from hubo_cli.walking.stabilizer import (
    LipStabilizer,
    SoleDamper,
    StabilizerGains,
    TorsoOffset,
    Touchdown,
)
from hubo_cli.walking.support import (
    SIDES,
    ankle_wrenches,
    estimated_feet,
    footstep_of,
    planned_contacts,
    planned_support,
    zmp_outside_m,
)
from hubo_cli.walking.toe_heel import ToeHeelParams, ankle_offset

ARRIVED_M = 0.008                  # closer than this to the goal stance needs no correction
ARRIVED_RAD = math.radians(1.5)
ZMP_INSIDE_MARGIN_M = 0.001  # a ZMP closer than this to the hull's edge counts as on it (a sole
                             # tipping about that edge: the physics keeps the ZMP on the hull)
LEG_STEP_RAD = 0.005  # the stabilizer's correction of a leg's joints (torso offset, touchdown
                     # hold) changes by at most this much a period: an IK solution further from
                     # the last one (another branch, or off the goal) keeps the last correction
LEG_CAPPED_M = 1e-4  # an IK solution capped to the joint limits this close to the sole's goal
LEG_CAPPED_RAD = 1e-3  # reaches it: each hip yaw stands at its limit, 0, while the feet point
                       # ahead, and feet toed in by microradians (as the simulator reads them
                       # after a few steps) cap it; taking only exact solutions, the correction
                       # stayed zero from the first capped period on while the offset grew
# each sole's Fig. 4 log columns (:meth:`WalkTarget._toe_heel_info`), right then left
_TOE_HEEL_COLUMNS = tuple((f"walk.{side}_cop_ref_m", f"walk.{side}_angle_ref_rad",
                           f"walk.{side}_cop_m", f"walk.{side}_angle_rad") for side in SIDES)
WALK_PHASES = ("walk", "stopping", "stood")
STOOD_S = 1.0          # [chosen] a stopped walk holds its stance this long, then ends
WALK_STOP_SPARE_S = 1.0  # [chosen] the stopper's deadline: the stop's pattern at its longest
# (:meth:`WalkTarget.stop_within_s`) and this much for its landing's wait (LANDING_WAIT_MAX_S;
# the planted step lifts no foot)
CP_WINDOW = 0.75       # [chosen] a landing moves only over this first part of its swing
CP_REPLAN_M = 0.02     # [chosen] a landing moves again once its goal changed by this much
CP_BLEND_PERIODS = 20  # [chosen] a moved landing's pattern is played at least this long before
                       # the foot lands (its swing moves onto the new path by then)
PREFIX_ROWS_PER_PERIOD = 8  # [chosen] a re-plan's first rows solved a period (the legs twice
                            # each): the row played is always solved
REPLAN_ROWS_PER_PERIOD = 60  # [chosen] a re-plan's work per control period, in pattern rows
                             # of one of its passes (the legs solved, the multi-body ZMP, the
                             # legs solved again): <= 30 us a row on the dev machine, so
                             # <= 2 ms of the 5 ms period
TOUCH_FRACTION = 1 / 3  # [chosen] a swing foot loaded beyond estimation.swing_touchdown_n past
                        # this part of its single support has touched down early ...
TOUCH_MIN_HEIGHT_M = 0.006  # [chosen] ... while the pattern still has it this high: lower, the
                            # stabilizer's Touchdown (its touchdown_height_m) holds it. Normal
                            # landings of perturbed robots 1, 4, 8 loaded their soles at most
                            # 1.2 mm up, 0.06 s early; soles pushed down mid-swing: 15-20 mm up.
                            # 2 mm: seed 8's 3.4 mm touchdown was caught, seed 17's lost
LEVEL_DEAD_RAD = math.radians(1.0)  # [chosen] a swing leg is pitched against the estimated
                        # torso's pitch from the planned one beyond this (below: walking's own
                        # sway; the pattern plays unchanged)
LEVEL_RATE_RAD_S = 0.6  # [chosen] ... that pitch changing at most this fast
LEVEL_MAX_RAD = 0.2     # [chosen] ... and at most this large (11.5 deg): 1.2x the largest turn
                        # of the 20 pushed walks (0.169 rad, docs/history/walking.md), so that
                        # a torso estimate gone wrong cannot swing a leg further than that
LEVEL_RETURN_RAD_S = 0.1  # [chosen] with both soles loaded a turn goes back at this rate
                        # (held, it holds the torso at the very pitch it reacts to: the other
                        # sole stood 7.6 deg toe-up on its heel to the end). Given back at
                        # 0.6 rad/s at the touchdown the landed foot was unloaded and the robot
                        # fell backward (seed 11); at 0.05 a stop's stance (1.9 s loaded
                        # before the stopper holds its posture) left 0.065 of 0.16 rad
LIFTOFF_WINDOW_S = 0.1  # [chosen] a foot lifts off only while the ankles' F/T sensors read, as
LIFTOFF_MIN_LOAD = 0.2  # the median of their F_z together over this window, at least this part
                        # of the body's weight (380 N); else the timeline waits at the lift-off
                        # (the body is in the air: a bounce after a landing). Of 969 lift-offs
                        # of round 6's pushed, stopped and fast walks (both CPU paths) the least
                        # such median came before pushed seed 20's 3.54 s lift-off (33-37 N; it
                        # fell: 0.2 is 2x over it), the next 122 N. Perturbed robots' 1 m walks
                        # bounce too: it waited at 2 of their 322 lift-offs (5-15 ms; both
                        # arrived; docs/history/walking.md, round 7). Without the sensors
                        # (NaN) it never waits
LANDING_WAIT_MAX_S = 0.5  # [chosen] after a push, a landing's double support waits at most this
                          # long in all for its landed foot to carry (WalkTarget._unloaded_landing)
LANDING_WALK_PUSHED_M = 0.1  # [chosen] ... and while the walk goes on, once the estimated capture
# point is this far off the pattern's (unpushed walks: 57 mm at most, round 10; a 70 N push's
# bounce, seed 2: 121-195 mm; docs/history/walking.md, round 14)
LANDING_CARRIED_S = 0.08  # [chosen] ... and none once that foot has carried this long in a row
                          # (the landing is made: pushed seed 13's landed foot bounced, loaded
                          # at most 0.035 s in a row; seed 8's carried 0.21 s, then the body
                          # rocked onto the other foot and waiting there, it fell); one pushed
                          # down early still waits at a hop while the walk goes on
LIFTOFF_WAIT_MAX_S = 1.0  # [chosen] ... and at one lift-off at most this long: then the sensors
                        # read wrong (zero) or the robot is held in the air, and the walk ends
                        # there (a DeviceError: the loop's smooth stop, both feet planned down)
CP_CAPTURE_MARGIN_M = 0.04  # [chosen] after a push from the front, the landing that captures
                            # the body has its heel this far behind the capture point predicted
                            # at touchdown (WalkTarget._capture_landing) ...
CP_ZMP_MARGIN_M = 0.02  # [chosen] ... predicted with the ZMP at most this close to the stance
                        # sole's heel or toe (on the edge, a sole tips: seed 11's pushed walk
                        # stood with its capture point on the heel's edge within a few mm)
CP_ABANDON_FRACTION = 0.5  # [chosen] ... a swing is abandoned for it only this early (later
                           # the foot is far up and ahead: pushed seed 4's, put down 0.1 s
                           # before its landing, hung in the air 0.2 s more and it fell)
REAIM_STEPS = 4        # [chosen] the plan's last this many steps are re-aimed at their lift-offs
                       # from the estimated stance foot (:meth:`WalkTarget._reaim`)
REAIM_STEP_M = 0.015   # [chosen] a re-aim changes a swing's travel by at most this much
REAIM_MOVED_STEPS = 2  # [chosen] in a plan whose landings the capture point moved (the fast
                       # gait's), only the last this many steps are re-aimed, and at the goal
REAIM_LAST_M = 0.06    # [chosen] the fast gait's last step (beside the stance foot: half the
                       # other steps' travel) changes its travel by up to this much at a re-aim
REAIM_LAST_FLOOR_M = ARRIVED_M / 2  # [chosen] ... and is re-aimed for a stance that would end
                       # this far off (its landing misses by a few mm of its own: AVX-512 seed
                       # 10, predicted 5.6 mm, ended 8.0 mm off and walked a correction)
CP_GAIN_MAX = 1.0      # [chosen] the error's growth by the landing counted at most this much
                       # (exp(omega t) is 17 at a swing's start: a 1 cm error of the estimate's
                       # capture point moved the landing by 17 cm; 3x stepped too far back
                       # after a backward push, and the robot fell forward). The error is the
                       # one against the pattern before the swing's moves, and a move is not
                       # turned back in its swing (round 32): measured against the re-planned
                       # pattern, whose capture point the move itself carries toward the
                       # robot's, the error shrank and turned, and so did the moves (portable
                       # robot 21's fast walk, one swing: +11, -13, -35 mm; it fell)


# no landing moved yet: (step, shift applied, steps before it) and (step, its first row on the
# plan's timeline, the pattern's capture point moved by its landing's moves from there; m)
_NO_SHIFT = (-1, np.zeros(2), None)
_NO_REF_MOVE = (-1, 0, np.zeros((1, 2)))  # (neither array is written into: both are replaced)


def _not_turned_back(wanted_m: np.ndarray, applied_m: np.ndarray) -> np.ndarray:
    """A landing's shift as the capture point asks for it now (``wanted_m``), kept on each
    axis (world x, y; m) the swing's earlier moves (``applied_m``) shifted it along from
    shrinking back or turning: only moved further that way."""
    direction = np.sign(applied_m)
    return np.where(direction != 0.0,
                    direction * np.maximum(direction * wanted_m, np.abs(applied_m)), wanted_m)


@nb.njit(**JIT)
def _correct_legs(T_neck_soles, R_neck_world, offset_x, offset_y, lift_right, lift_left, q,
                  deltas, right, left, step_rad, turns):
    """The stabilizer's correction of both legs, compiled (one call a period): each planned
    sole goal in the torso's frame (``T_neck_soles``: right, left) moved by the torso offset
    (world x, y) and the sole's lift (world z), both turned into the torso's frame by
    ``R_neck_world``, then by ``turns`` (2 x 4 x 4, in the torso's frame: the swing foot kept
    over the floor, :class:`~hubo_cli.walking.floor_reach.FloorReach`; identities when
    neither leg is turned), then
    :func:`_correct_leg` with the leg's ``(chain, lengths, is_arm, lower, upper, hold_m,
    start)`` and its row of ``deltas`` (2 x 6)."""
    goal = np.empty((4, 4))
    moved = np.empty((4, 4))
    for side in range(2):
        lift = lift_right if side == 0 else lift_left
        for r in range(4):  # a loop, not goal[:, :] = ...: see choice._copy6
            for c in range(4):
                goal[r, c] = T_neck_soles[side, r, c]
        for r in range(3):
            goal[r, 3] += (R_neck_world[r, 0] * -offset_x + R_neck_world[r, 1] * -offset_y
                           + R_neck_world[r, 2] * lift)
        for r in range(4):
            for c in range(4):
                total = 0.0
                for i in range(4):
                    total += turns[side, r, i] * goal[i, c]
                moved[r, c] = total
        for r in range(4):
            for c in range(4):
                goal[r, c] = moved[r, c]
        _correct_leg(goal, right if side == 0 else left, q, deltas[side], step_rad)


@nb.njit(**JIT)
def _correct_leg(T_neck_goal, leg, q, delta, step_rad):
    """One leg's correction: the leg's joints ``q[start:start + 6]`` (the pattern's) solved
    for the goal sole ``T_neck_goal`` (:func:`~hubo_cli.kinematics.choice.solve_limb` from
    those joints); an exact solution, or one capped to the joint limits within LEG_CAPPED_M
    and LEG_CAPPED_RAD of the goal, whose difference to them changes no joint by more than
    ``step_rad`` from the last correction ``delta`` becomes the new correction (written to
    ``delta``); the correction is added to the leg's joints of ``q`` in place."""
    chain, lengths, is_arm, lower, upper, hold_m, start = leg
    part = q[start:start + 6]
    solved = np.empty(6)
    status, position_m, rotation_rad = solve_limb(T_neck_goal, chain, lengths, is_arm, lower,
                                                  upper, part, TRUE[0], hold_m, TRUE[0], solved)
    if status == EXACT or (status == CAPPED and position_m <= LEG_CAPPED_M
                           and rotation_rad <= LEG_CAPPED_RAD):
        within = True
        for j in range(6):
            within = within and abs(solved[j] - part[j] - delta[j]) <= step_rad
        if within:
            for j in range(6):
                delta[j] = solved[j] - part[j]
    for j in range(6):
        part[j] += delta[j]


class WalkTarget(Target):
    """Walk to ``goal`` (forward, left, turn relative to the stance at the start).

    Its first period plans the walk from the estimate's soles and torso; each period sends the
    pattern's joints, writes the planned support for the capture-point monitor and logs the
    reference and estimated ZMP and CoM. When the pattern has ended (its last ``settle_s``
    standing) and the estimated feet, which slip a little on every step, stand further than
    ARRIVED_M / ARRIVED_RAD from the goal, it plans again from where they stand, up to
    ``corrections`` times. The run ends then, or on a fall.

    ``end_width_m`` (None: the walking width) ends every walk with the feet this far apart
    (:func:`~hubo_cli.walking.footsteps.closing_steps`): the stance a task starts from.
    """

    name = "walk"
    reads = (T_WORLD_SOLES, T_WORLD_TORSO, CONTACT, WRENCHES, COM_WORLD, COM_VELOCITY_WORLD,
             ZMP_WORLD, CAPTURE_POINT_WORLD)
    writes = (SUPPORT_PLAN, PHASE_STOP)
    previous = (STOP_MODE,)
    log_columns = ("walk.zmp_ref_x_m", "walk.zmp_ref_y_m", "walk.com_ref_x_m",
                   "walk.com_ref_y_m", "walk.zmp_x_m", "walk.zmp_y_m",
                   "walk.contact_zmp_outside_m", "walk.step", "walk.tilt_deg",
                   "planned_right_foot_contact_flag", "planned_left_foot_contact_flag",
                   "walk.right_cop_ref_m", "walk.left_cop_ref_m", "walk.right_cop_m",
                   "walk.left_cop_m", "walk.right_angle_ref_rad", "walk.left_angle_ref_rad",
                   "walk.right_angle_rad", "walk.left_angle_rad",
                   "walk.zmp_command_x_m", "walk.zmp_command_y_m",
                   "walk.phase_code", "walk.soles_fz_n", "walk.liftoff_wait", "walk.landing_wait",
                   "walk.cp_error_x_m", "walk.cp_error_y_m",
                   "walk.cp_shift_x_m", "walk.cp_shift_y_m")
    stabilizer_columns = ("walk.offset_x_m", "walk.offset_y_m", "walk.right_lift_m",
                          "walk.left_lift_m", "walk.right_sole_roll_rad",
                          "walk.right_sole_pitch_rad", "walk.left_sole_roll_rad",
                          "walk.left_sole_pitch_rad", "walk.right_level_rad",
                          "walk.left_level_rad", "walk.pitch_error_rad", "walk.right_reach_rad",
                          "walk.left_reach_rad", "walk.right_momentum_rad",
                          "walk.left_momentum_rad")  # (:meth:`_stabilizer_info`'s)
    log_columns += stabilizer_columns

    def __init__(self, model: RobotModel, params: WalkingParams, goal: tuple[float, float, float],
                 q_start_rad: np.ndarray, T_world_neck_start: np.ndarray,
                 corrections: int = 1, end_width_m: float | None = None,
                 stabilizer: StabilizerGains | None = None,
                 toe_heel: ToeHeelParams | None = None, lip_feedback: bool = False) -> None:
        self.model = model
        # the push responses (:meth:`_unloaded_landing`, :meth:`_reach_floor`, :meth:`_momentum`)
        # by the gait's step (WalkingParams.answers_pushes), except the landing wait once the
        # walk stops, on for every flat-foot gait (:meth:`_waits`); the floor reach and the
        # momentum strategy not in toe-heel walks (not measured with them)
        self.landing_wait = params.answers_pushes or toe_heel is None
        self.landing_wait_walking = params.answers_pushes
        self.floor_reach = params.answers_pushes and toe_heel is None
        self.momentum = params.answers_pushes and toe_heel is None
        # the capture-point monitor's planned support where the estimated soles stand
        # (:meth:`_support_in_estimate`) for the gaits that do not answer pushes (the fast
        # gait, whose stance soles slip round); the pushed gaits' where the pattern put it
        self.support_where_standing = not params.answers_pushes
        # the same gaits' plans the capture point moved are re-aimed at the goal in their last
        # steps (:meth:`_reaim`); a pushed gait's move answers a push, left to the correction
        self.reaim_moved = not params.answers_pushes
        self.toe_heel = toe_heel
        self.lip_feedback = lip_feedback and stabilizer is not None
        self.lip: LipStabilizer | None = None
        self.end_width_m = end_width_m
        self.params = params
        self.goal_relative = goal
        self.q_start = np.asarray(q_start_rad, dtype=float)
        self._sent_q = self.q_start  # the joints last sent (a correction starts from them)
        self.T_world_neck_start = T_world_neck_start
        self.store: Store | None = None
        self.placed = True
        self.gait: Gait | None = None
        self.plan: JointPlan | None = None
        self.start: Stance | None = None
        self.goal: Stance | None = None
        self.corners = np.ascontiguousarray(model.feet.sole_corners_m()[:, :3])
        self.k = 0
        self.fell = False
        self.zmp_periods = 0
        self.zmp_inside_periods = 0
        self.torso_z0_m: float | None = None
        self.final_feet: dict[str, np.ndarray] = {}
        self.steps: list[Footstep] = []
        self.start_feet: list[Footstep] = []
        self.corrections_left = int(corrections)
        self.plan_start_s = 0.0
        self.last_step_end_s = 0.0
        self.body: WalkingBody | None = None
        self.stabilizer = stabilizer
        self.phase = "walk"
        self.stopped_s: float | None = None  # when the walk began to stop (loop time, s)
        self.stop_failed = False  # the stop's pattern could not be made: the stopper brakes
        self.shifts = 0  # landings moved after the capture point
        self.touchdowns_early = 0  # swings ended where the foot touched down early
        self.reaims = 0  # landings re-aimed from the estimated stance foot (:meth:`_reaim`)
        self._reaimed = -1  # the plan's step last re-aimed
        self._reaimed_m = {side: np.zeros(2) for side in SIDES}  # each foot's last landing
                                                # moved so far by re-aims (world x, y; m)
        self._moves_before = 0  # landings moved by the capture point or a push before the plan
        self._shift = _NO_SHIFT  # the capture point's landing moves (_NO_SHIFT's comment)
        self._ref_moved = _NO_REF_MOVE
        self._cp_error = np.full(2, math.nan)
        self._pending = None  # a re-plan's rest being computed (_replan)
        self._prefix = None  # a re-plan's first rows being solved (_replan)
        self._omega = 1.0
        dt = model.control_period_s
        self._loads_n = np.full((max(1, round(LIFTOFF_WINDOW_S / dt)), 2), np.inf)  # the
        self._load_i = 0              # soles' measured F_z (right, left), the last periods
        self._waiting = False  # the timeline waited at a lift-off last period
        self._waited_s = 0.0  # ... this long
        self._weight_n = math.inf  # the body's weight (N; from the first plan's model)
        self._bounced = False  # a pushed landing's foot bounced off the floor: the walk stops
        self.liftoff_waits = 0  # lift-offs the timeline waited at
        self.landing_waits = 0  # landings whose double support waited for the landed foot
        self._landed: int | None = None  # the last landing's foot (its support column)
        self._played_support: tuple[bool, bool] | None = None  # the row played last period
        self._landing_waited_s = 0.0  # ... its double support waited this long in all
        self._landing_carried_s = 0.0  # ... its foot has carried this long in a row
        self._landing_made = False  # ... that long: made (no more waits)
        self._pushed_down = False  # the swing ending was pushed onto the floor early
        self._landing_pushed_down = False  # ... the last landing was: watched till lift-off
        self._put_down = False  # a swing abandoned: its foot put down from the air
        self._landing_put_down = False  # ... the last landing was: it never waits
        xs, ys = self.corners[:, 0], self.corners[:, 1]
        box = (float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max()))
        if stabilizer is not None:
            self.dampers = {side: SoleDamper(stabilizer, box, dt,
                                             model.estimation.sole_damping_min_fz_n)
                            for side in SIDES}
            self.torso_offset = TorsoOffset(stabilizer, dt)
            self.touchdowns = {side: Touchdown(stabilizer, dt) for side in SIDES}
            self._leg_delta = np.zeros((2, 6))  # the legs' corrections: right, left
            self._level_rad = np.zeros(2)  # each swing leg's pitch against the torso's (rad)
            self._pitch_error_rad = 0.0  # the estimated torso's pitch from the planned one
            self._half_width_m = float(self.corners[:, 1].max())  # the soles' (m)
            self.reach = FloorReach(self._half_width_m, dt)
            self._no_turns = np.array((np.eye(4), np.eye(4)))  # (_correct_legs's turns)
            self._hip_roll = tuple(model.joint_names.index(n) for n in ("RHR", "LHR"))
            self.hips = MomentumStrategy(
                tuple(float(model.lower_rad[j]) for j in self._hip_roll),
                tuple(float(model.upper_rad[j]) for j in self._hip_roll), dt)
        names = list(model.joint_names)
        self._ankle = {"right": (names.index("RAR"), names.index("RAP")),
                       "left": (names.index("LAR"), names.index("LAP"))}
        self._hip_pitch = (names.index("RHP"), names.index("LHP"))  # (right, left)

    def attach(self, world: SceneActions | None, modules: Sequence, store: Store) -> None:
        self.store = store
        self.placed = world is not None  # a simulator starts the robot in the posture

    def _start(self, t_s: float, q_rad: np.ndarray) -> None:
        """The walk's first period: the measured joints ``q_rad`` checked against the walking
        posture (a robot through hubo-ach stands where it was left), the goal from the
        estimated stance, the first plan.

        Raises:
            SafetyError: a joint more than :data:`~hubo_cli.posture.START_TOLERANCE_RAD` from
                the walking posture.
        """
        if not self.placed:
            check_stands_in(self.model, q_rad, self.q_start, "walking")
        feet = estimated_feet(self.store)
        self.start_feet = [feet["right"], feet["left"]]
        self.start = stance_of(feet["right"], feet["left"])
        forward, left, turn = self.goal_relative
        c, s = math.cos(self.start.yaw_rad), math.sin(self.start.yaw_rad)
        self.goal = Stance(self.start.x_m + c * forward - s * left,
                           self.start.y_m + s * forward + c * left, self.start.yaw_rad + turn)
        self._plan(self.q_start, t_s)
        self._weight_n = self.body.robot.weight_n

    def _plan(self, q_rad: np.ndarray, t_s: float) -> None:
        """Plan the walk from where the estimate puts the feet now (the stance frame moves
        with them), starting at loop time ``t_s`` from the commanded joints ``q_rad``; the
        stabilizer's torso offset and the legs' correction start again from zero."""
        store = self.store
        feet = estimated_feet(store)
        steps = plan_footsteps(feet["right"], feet["left"], self.goal, self.params)
        if self.end_width_m is not None:
            placed = {step.side: step for step in steps}
            first = "left" if steps and steps[-1].side == "right" else "right"
            steps = steps + closing_steps(placed.get("right", feet["right"]),
                                          placed.get("left", feet["left"]), self.goal,
                                          self.end_width_m, first)
        T_world_neck = np.array(store[T_WORLD_TORSO], dtype=float)
        T_world_neck[2, 3] = self.T_world_neck_start[2, 3] if self.gait is None \
            else self.plan.T_world_neck[-1, 2, 3]
        body = WalkingBody(self.model, q_rad, T_world_neck, self.params.lean_rad_per_m)
        goals = None
        if self.gait is not None and self.toe_heel is None:  # a correction (held, below)
            # the soles where the joints last sent hold them (the stabilizer's corrections
            # in): rebuilt as the pattern's soles moved by the torso offset and the lifts,
            # they missed what the legs' correction had reached (it lags, LEG_STEP_RAD)
            goals = np.stack([body.legs[SIDE_LEG[side]].fk(
                self._sent_q[body.slices[SIDE_LEG[side]]]) for side in SIDES])
            T_world_neck[:3, :3] = levelled(T_world_neck[:3, :3], goals[:, :3, :3])
        sole_z = float(store[T_WORLD_SOLES][0, 2, 3])
        com = body.com_in_neck(q_rad)
        com_world = T_world_neck[:3, :3] @ com + T_world_neck[:3, 3]
        gait = make_gait(feet["right"], feet["left"], steps, self.params,
                         self.model.control_period_s, float(com_world[2]) - sole_z, sole_z,
                         self.model.feet.forward_m, com_start_m=com_world[:2],
                         toe_heel=self.toe_heel, sole=self.model.feet)
        held = goals is not None and gait.toe_heel is None
        if held:  # a correction: its lead-in moves the soles from where the legs hold them
            lead = blend_from_held(gait, T_world_neck @ goals)
            gait = replace(gait, torso_lead_rad=torso_lead(
                gait, lead, T_world_neck[:3, :3], self.params.lean_rad_per_m))
        self._reaimed = -1
        self._reaimed_m = {side: np.zeros(2) for side in SIDES}
        # a new plan (a correction's) counts its steps from 0 again: the last plan's landing
        # moves (their steps, shifts and record) are not its own
        self._shift, self._ref_moved = _NO_SHIFT, _NO_REF_MOVE
        self._moves_before = self.shifts + self.touchdowns_early  # (:meth:`_reaim`)
        self._aims = {side: _final_place(steps, feet[side], side) for side in SIDES}
        # what the plan was made from, for re-planning it in motion (:meth:`_replan`)
        self._basis = ((feet["right"], feet["left"]), list(steps), sole_z, com_world[:2].copy())
        self._row0 = 0  # the pattern's first period on the plan's timeline
        self._steps_before = len(self.steps)
        self._omega = math.sqrt(GRAVITY_M_S2 / gait.com_height_m)
        self._adopt(gait, body, t_s)
        if held:  # the swings' clearance above the estimated soles, not the held ones
            for side in SIDES:
                z0 = self._sole_z0[side] = float(gait.feet[side][min(lead, gait.n - 1), 2])
                self._clearance[side] = (gait.feet[side][:, 2] - z0).tolist()
        if self.stabilizer is not None:
            # the estimated torso the plan starts from already carries the torso offset as the
            # legs' correction held it: kept, that correction moved the torso by it a second
            # time in one period (a correction walk's start; pushed seed 17: 28 mm back, and
            # the capture-point stop's stance tipped over its heels; docs/history/walking.md)
            self.torso_offset.reset()
            self._leg_delta[:] = 0.0
            self.reach.reset()
        self.steps.extend(steps)

    def _adopt(self, gait: Gait, body: WalkingBody, t_s: float, fix_start=None) -> None:
        """Play ``gait`` from loop time ``t_s`` on: its joints (``body``, the multi-body
        correction from ``fix_start``: see :meth:`WalkingBody.solve_corrected`) and rows.

        Raises:
            InputError: a sole the legs cannot reach.
        """
        self._install(run_slices(self._adoption(gait, body, fix_start, gait.n)), t_s)

    def _adoption(self, gait: Gait, body: WalkingBody, fix_start, rows_per_slice: int
                  ) -> Iterator[None]:
        """What :meth:`_adopt` computes, ``rows_per_slice`` rows at a time (yields between
        slices); returns the attributes :meth:`_install` sets."""
        params = self.params
        corrected, plan = yield from body.solve_corrected_slices(
            gait, self._basis[2], params.preview_s, params.zmp_weight, params.jerk_weight,
            fix_start, rows_per_slice)
        yield
        com, cart = corrected.com, gait.com
        fix = (com.com_m - cart.com_m, com.com_velocity_m_s - cart.com_velocity_m_s,
               com.com_acceleration_m_s2 - cart.com_acceleration_m_s2)
        return self._playing(gait, corrected, plan, body, fix)

    def _playing(self, cart: Gait, gait: Gait, plan: JointPlan, body: WalkingBody, fix: Fix,
                 whole: Gait | None = None) -> dict:
        """The attributes :meth:`_install` sets to play ``gait`` (the multi-body corrected
        pattern) with the joints ``plan``: ``cart`` the cart-table pattern and ``fix`` the
        correction (each continued by a re-plan), per-period rows for the loop. ``whole``: the
        pattern ``gait`` is the first rows of (a re-plan's, :meth:`_replan`), whose landings
        and planned support they take."""
        whole = gait if whole is None else whole
        new = {"_cart": cart, "gait": gait, "plan": plan, "body": body, "_fix": fix}
        if self.lip_feedback:
            new["_contacts"] = planned_contacts(gait)
        # each leg's IK data as :func:`_correct_legs` takes them (right, left)
        new["_leg_kernel"] = tuple(
            (leg.chain, leg.lengths_m, leg.spec.is_arm, leg.lower_rad, leg.upper_rad, leg.hold_m,
             body.slices[name].start)
            for leg, name in ((body.legs[SIDE_LEG[side]], SIDE_LEG[side]) for side in SIDES))
        n = gait.n
        new["_support_poses"] = planned_support(whole, self._basis[2])[:n]
        new["_whole_support"] = whole.support  # the lift-off guard's next row past a prefix
        # per-period rows as plain floats and bools for the loop (cheaper than numpy scalars)
        new["_rows"] = {"support": gait.support.tolist(), "zmp_ref": gait.zmp_ref_m.tolist(),
                        "com_ref": gait.com.com_m.tolist(), "plan_com": plan.com_m.tolist(),
                        "com_velocity_ref": gait.com.com_velocity_m_s.tolist(),
                        "step": gait.step_index.tolist(),
                        **{side: gait.feet[side].tolist() for side in SIDES}}
        sole_z0 = new["_sole_z0"] = {side: float(gait.feet[side][0, 2]) for side in SIDES}
        # each sole's lowest point above its landing height (a rolled sole's origin is raised)
        clearance = new["_clearance"] = {side: (gait.feet[side][:, 2] - sole_z0[side]).tolist()
                                         for side in SIDES}
        if gait.toe_heel is not None:
            for column, side in enumerate(SIDES):
                _, dz = ankle_offset(gait.toe_heel.foot_angle_rad[:, column],
                                     gait.toe_heel.pivot_m[:, column])
                clearance[side] = (gait.feet[side][:, 2] - sole_z0[side] - dz).tolist()
        # the soles' goals in the planned torso's frame, per period: the stabilizer only moves
        # them by its torso offset and a touchdown's lift (:meth:`_stabilized`)
        T_neck_world = rigid_inverse(plan.T_world_neck)
        new["_R_neck_world"] = T_neck_world[:, :3, :3].copy()
        new["_T_neck_soles"] = np.stack([T_neck_world @ poses_of_rows(
            gait.feet[side], None if gait.toe_heel is None
            else gait.toe_heel.foot_angle_rad[:, column])
            for column, side in enumerate(SIDES)], axis=1)  # n x 2 x 4 x 4
        index = np.arange(whole.n)
        # per period: the next period with both feet down (a swing's landing)
        both = np.where(whole.support.all(axis=1), index, whole.n)
        new["_landing"] = np.minimum.accumulate(both[::-1])[::-1][:n].tolist()
        moving = np.nonzero(whole.step_index >= 0)[0]
        new["_settle_k"] = int(moving[-1]) + 1 if len(moving) else 0  # the pattern's settle
        return new

    def _install(self, new: dict, t_s: float) -> None:
        """Play the pattern :meth:`_adoption` made from loop time ``t_s`` on (a re-plan being
        computed is dropped)."""
        self._pending = self._prefix = None
        for name, value in new.items():
            setattr(self, name, value)
        if self.lip_feedback:
            self.lip = LipStabilizer(LipFeedback.from_model(self.model, self.gait.com_height_m),
                                     WrenchDistributor.from_model(self.model),
                                     pin.computeTotalMass(self.body.robot.model))
        self.plan_start_s = t_s
        self.k = 0

    def _replan(self, steps: list[Footstep], t_s: float, planted: int | None = None,
                failed: Callable[[], None] | None = None,
                done: Callable[[], None] | None = None, skip: int = 0,
                held: int | None = None) -> None:
        """Play the plan's pattern with ``steps`` (changed from the step in progress on;
        ``planted``: :func:`~hubo_cli.walking.replan.pattern_from`, a step onto its foot's own
        place ending a stop; ``held``: a step down early, its foot held down as a planted
        one's and the step kept) from this period on, then
        ``done`` (see :mod:`hubo_cli.walking.replan`): its first rows
        (:func:`~hubo_cli.walking.replan.prefix_rows`) are solved PREFIX_ROWS_PER_PERIOD a
        period from this one on (:meth:`_advance_prefix`), the rest a slice a period while
        they play (:meth:`_advance_replan`); ``skip`` rows of the plan's timeline left out from
        this period (a swing ended early). It replaces a re-plan still being computed. A sole
        the legs cannot reach by the swing's landing keeps the pattern playing and calls
        ``failed``; later, the step in progress is finished into a stance
        (:meth:`_finish_step`)."""
        k = min(self.k, self.gait.n - 1)
        start, _, sole_z, com_start = self._basis
        # the legs' solutions playing seed the new ones (those solved: see _advance_prefix)
        solved = len(self.plan.q_rad) if self._prefix is None else self._prefix[1]
        old = self.plan.q_rad[:solved], self.plan.T_world_neck[:solved]
        try:
            cart = pattern_from(self._cart, k, self._row0 + k + skip, start, steps, self.params,
                                sole_z, self.model.feet.forward_m, com_start,
                                planted if held is None else held,
                                REPLAN_ROWS_PER_PERIOD)
            fix = continued_fix(self._fix, k, cart.n)
            m = prefix_rows(cart.n, REPLAN_ROWS_PER_PERIOD)
            first = with_fix(gait_rows(cart, 0, m), tuple(part[:m] for part in fix))
            body = self.body.seeded(old[0][k], old[1][k])
            landing = int(np.argmax(np.append(first.support.all(axis=1), True)))
            if PREFIX_ROWS_PER_PERIOD <= landing < m:  # the swing's landing reached (else: later)
                j = min(k + landing, len(old[0]) - 1)
                body.seeded(old[0][j], old[1][j]).solve(gait_rows(first, landing, landing + 1))
            plan = unsolved_plan(m, len(self.q_start))
            slices = body.solve_slices(first, PREFIX_ROWS_PER_PERIOD, plan)
            next(slices, None)  # the first rows now
        except InputError:
            if failed is not None:
                failed()
            return
        new = self._playing(cart, first, plan, body, fix, whole=cart)
        row0 = new["_row0"] = self._row0 + k + skip if steps else 0
        basis = new["_basis"] = (start, list(steps), sole_z, com_start)
        kept = new["steps"] = [*self.steps[:self._steps_before],
                               *(steps if planted is None else steps[:planted])]
        self._install(new, t_s)
        self._prefix = (slices, 0)
        self._solved(min(PREFIX_ROWS_PER_PERIOD, m))
        if done is not None:
            done()
        if m < cart.n:
            j = min(k + m, len(old[0]) - 1)
            self._pending = (m, self._rest(cart, m, self.body.seeded(old[0][j], old[1][j]),
                                           tuple(part[m] for part in fix),
                                           {"_row0": row0 + m, "_basis": basis, "steps": kept}),
                             None)

    def _solved(self, rows: int) -> None:
        """The playing re-plan's first ``rows`` are solved (:meth:`_advance_prefix`): their
        per-period rows that come from the joints."""
        slices, done = self._prefix
        plan, gait = self.plan, self.gait
        rows = min(rows, gait.n)
        part = slice(done, rows)
        T_neck_world = rigid_inverse(plan.T_world_neck[part])
        self._R_neck_world[part] = T_neck_world[:, :3, :3]
        self._T_neck_soles[part] = np.stack([T_neck_world @ poses_of_rows(gait.feet[side][part])
                                             for side in SIDES], axis=1)
        self._rows["plan_com"][part] = plan.com_m[part].tolist()
        self._prefix = None if rows >= gait.n else (slices, rows)

    def _advance_prefix(self, t_s: float) -> None:
        """The next PREFIX_ROWS_PER_PERIOD rows of the playing re-plan's first rows (always
        ahead of the row played: it started with as many). A row the legs cannot reach: the
        rows after the last solved one hold it, and the step in progress is finished into a
        stance (:meth:`_finish_step`)."""
        slices, done = self._prefix
        try:
            next(slices)
            self._solved(done + PREFIX_ROWS_PER_PERIOD)
        except StopIteration:
            self._solved(self.gait.n)
        except InputError:
            plan = self.plan
            for part in (plan.q_rad, plan.T_world_neck, plan.com_m):
                part[done:] = part[done - 1]
            self._solved(self.gait.n)
            self._pending = None
            self._finish_step(t_s)

    def _rest(self, cart: Gait, first: int, body: WalkingBody, fix_start: tuple, keep: dict
              ) -> Iterator[None]:
        """A re-plan's rows from ``first`` on (:meth:`_replan`): the CoM path, then its
        multi-body correction continued from ``fix_start``, REPLAN_ROWS_PER_PERIOD rows at a
        time; returns what :meth:`_install` sets (and ``keep``)."""
        rest = rest_of(cart, first, self.params)
        yield
        new = yield from self._adoption(rest, body, fix_start, REPLAN_ROWS_PER_PERIOD)
        return {**new, **keep}

    def _advance_replan(self, t_s: float) -> None:
        """One period's slice of a re-plan's rest; played once its first rows have (its rest
        computed then, should the slices not have sufficed). Its legs out of reach: the step
        in progress is finished into a stance (:meth:`_finish_step`)."""
        at_k, slices, new = self._pending
        try:
            if new is None and self.k < at_k:
                try:
                    next(slices)
                except StopIteration as finished:
                    self._pending = (at_k, slices, finished.value)
                return
            if new is None:
                new = run_slices(slices)
        except InputError:
            self._pending = None
            self._finish_step(t_s)
            return
        if self.k >= at_k:
            self._install(new, t_s)

    def _stop(self, t_s: float) -> None:
        """The stopper latched: finish the step in progress into a double-support stance (none
        before the first step; nothing changes once the last one is down)."""
        self.phase, self.stopped_s, self.corrections_left = "stopping", t_s, 0
        if self.toe_heel is not None:
            # a re-plan makes a flat-foot pattern (walking/replan.py): a rolled sole would be
            # turned flat at once, so a toe-heel walk's stop is the stopper's brake and hold
            self.stop_failed = True
            return
        self._finish_step(t_s)

    def stop_within_s(self) -> float:
        """How long a stop latched now may take to stand (s; the stopper's deadline): the stop's
        pattern at its longest, two steps' time (a swing just begun finished, then the next
        step planted where the other foot stands: :meth:`_finish_step`, the CoM over the
        landed foot for a single support's time), the settle, and ``WALK_STOP_SPARE_S`` for
        the landing's wait. Counted with one step (before round 25), a SIGHUP 0.1 s into a
        swing whose stop waited 0.19 s at its landings stood 0.08 s after the deadline and the
        stopper held it where it was (``interrupt_stop`` ``held``; docs/history/walking.md,
        round 25)."""
        return 2 * self.params.step_s + self.params.settle_s + WALK_STOP_SPARE_S

    def _finish_step(self, t_s: float) -> None:
        """Finish the step in progress into a double-support stance from this period on (none
        before the first step; nothing changes once the last one is down); its legs out of
        reach: :attr:`stop_failed` (the stopper brakes and holds instead)."""
        k = min(self.k, self.gait.n - 1)
        step = self._rows["step"][k]
        steps = self._basis[1]
        shifted_step, applied, base = self._shift
        # a landing the capture point moved keeps its shift (and the steps it shifted from)
        self._shift = ((step, applied, base[:step + 1]) if shifted_step == step >= 0
                       else _NO_SHIFT)
        self._ref_moved = _NO_REF_MOVE  # (the stop's pattern is the reference)
        planted = None
        if step >= 0:
            kept = steps[:step + 1]
            if step + 1 < len(steps) and (all(self._rows["support"][k])
                                          or not self._pushed(k)):
                # the step has landed and the weight moves onto it, or (no push) the foot is
                # still in the air and will land where planned: the CoM turns back over that
                # foot as walking would (a single support's time, the other foot down), then
                # comes to rest between the feet. Turned at once, it tipped the robot over the
                # new stance foot's outer edge; turned in mid-swing, the CoM reversed over the
                # stance sole's inner edge and the swing sole struck the floor early (a
                # portable 2 m walk's stop, seed 20, tilted 20 deg). A pushed walk's stop keeps
                # the capture point's landing (docs/walking.md)
                other = steps[step + 1].side
                x, y, _, yaw = self._rows[other][k]
                kept = [*kept, Footstep(other, x, y, yaw)]
                planted = step + 1
        elif any(i >= 0 for i in self._rows["step"][k:]):
            kept = []  # the lead-in: no step yet
        else:
            return  # the last step is down: the pattern settles between the feet already
        if len(kept) == len(steps) and planted is None:
            return

        def failed() -> None:
            self.stop_failed = True

        self._replan(kept, t_s, planted, failed)

    def _follow_capture_point(self, t_s: float) -> None:
        """While a foot swings (the first CP_WINDOW of it): move its landing, and every later
        footstep, by the estimated capture point's error from the pattern's beyond
        CP_MARGIN_M, as it will have grown by the landing (see the module docstring)."""
        k, rows, gait = self.k, self._rows, self.gait
        if k >= gait.n or self.toe_heel is not None:  # no flat re-plan of a toe-heel walk
            return
        step, support = rows["step"][k], rows["support"][k]
        if self._touched_early(k, step, support, t_s):
            return
        self._cp_error = self._capture_point_error(k)
        error_x, error_y = self._cp_error.tolist()
        if step < 0 or (support[0] and support[1]) or not (math.isfinite(error_x)
                                                          and math.isfinite(error_y)):
            return  # (no estimate of the capture point: nothing moves)
        period = gait.period_s
        remaining_s = (self._landing[k] - k) * period
        if remaining_s < (1.0 - CP_WINDOW) * self.params.single_support_s:
            return
        shifted_step, applied, base = self._shift
        if shifted_step != step:
            shifted_step, applied, base = step, np.zeros(2), list(self._basis[1])
        # the error against the pattern before this landing's moves, from whose steps
        # ``applied`` is measured (see CP_GAIN_MAX)
        error = self._cp_error + self._ref_moved_at(step, k)
        excess = np.sign(error) * np.maximum(np.abs(error) - CP_MARGIN_M, 0.0)
        wanted = _not_turned_back(excess * min(math.exp(self._omega * remaining_s),
                                               CP_GAIN_MAX), applied)
        stance_side = "right" if support[0] else "left"
        x, y, _, yaw = rows[stance_side][k]
        stance = Footstep(stance_side, x, y, yaw)
        self._shift = (shifted_step, applied, base)
        if self._abandoned(k, step, stance, base, remaining_s, t_s):
            return
        wanted = self._back_to_capture(k, stance, base[step], remaining_s, wanted)
        if (not np.any(excess) and not np.any(applied)) or \
                float(np.hypot(*(wanted - applied))) < CP_REPLAN_M:
            return
        if k + CP_BLEND_PERIODS > self._landing[k]:
            return  # too late to move this landing
        moved = shifted_landing(stance, base[step], wanted,
                                self.model.feet.width_m, self.params.step_width_m)
        # the landing as the step's limits let it move: where they hold it where it already
        # is, a capture point beyond them re-plans nothing (not a re-plan every period)
        if float(np.hypot(moved.x_m - base[step].x_m - applied[0],
                          moved.y_m - base[step].y_m - applied[1])) < CP_REPLAN_M:
            return

        self._move_landing(step, moved, base, t_s)

    def _capture_landing(self, k: int, stance: Footstep, remaining_s: float
                         ) -> tuple[float, float]:
        """After a push from the front (the capture point's error along the stance sole
        behind it by more than CP_MARGIN_M): the landing (its origin along the stance sole,
        m) whose heel lies CP_CAPTURE_MARGIN_M behind the capture point predicted at
        touchdown, ``remaining_s`` from now (the linear inverted pendulum from the estimated
        capture point, its ZMP the estimated one held CP_ZMP_MARGIN_M or more inside the
        stance sole's heel and toe), and the capture point so predicted for a landing
        TOUCH_BLEND_ROWS from now; NaN, NaN when no landing behind the stance heel's margin
        is needed. Only :meth:`_abandoned` uses them: the landing moved so far back
        (:meth:`_follow_capture_point`) made pushed seed 4's foot come down 0.141 m back
        and bounce, and the robot fell backward, where the error's 0.107 m stands
        (docs/history/walking.md, round 9)."""
        c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        if c * float(self._cp_error[0]) + s * float(self._cp_error[1]) > -CP_MARGIN_M:
            return math.nan, math.nan
        wrenches = ankle_wrenches(self.store)
        points = [self._in_pattern(k, wrenches, self.store[key])
                  for key in (CAPTURE_POINT_WORLD, ZMP_WORLD)]
        if not np.all(np.isfinite(points)):
            return math.nan, math.nan
        cp_x, zmp_x = (c * (px - stance.x_m) + s * (py - stance.y_m) for px, py in points)
        heel_m, toe_m = float(self.corners[:, 0].min()), float(self.corners[:, 0].max())
        zmp_x = min(max(zmp_x, heel_m + CP_ZMP_MARGIN_M), toe_m - CP_ZMP_MARGIN_M)
        landing_cp_x = zmp_x + (cp_x - zmp_x) * math.exp(self._omega * remaining_s)
        if landing_cp_x >= heel_m + CP_CAPTURE_MARGIN_M:
            return math.nan, math.nan
        now_s = TOUCH_BLEND_ROWS * self.gait.period_s
        return (landing_cp_x - CP_CAPTURE_MARGIN_M - heel_m,
                zmp_x + (cp_x - zmp_x) * math.exp(self._omega * now_s))

    def _back_to_capture(self, k: int, stance: Footstep, planned: Footstep, remaining_s: float,
                         wanted: np.ndarray) -> np.ndarray:
        """The landing's move ``wanted`` (world x, y from ``planned``, m), taken back along the
        stance sole's heading as far as the landing that captures the body
        (:meth:`_capture_landing`) once the walk is stopping after a push from the front: the
        stop's stance is the last, so its polygon has to hold the capture point, which the
        error's move (hrpsys's rule, made for a walk that steps on) does not place. A swing
        past CP_ABANDON_FRACTION that lands where that rule put it left the capture point
        56-66 mm behind both heels, and the robot tipped over backward a second later (2 m
        walks pushed 100 N, seeds 50, 53 and 59; docs/history/walking.md, round 36).
        Unchanged while walking, or without such a push."""
        if self.phase != "stopping":
            return wanted
        landing_x, _ = self._capture_landing(k, stance, remaining_s)
        if not math.isfinite(landing_x):
            return wanted
        heading = np.array((math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)))
        planned_x = float(heading @ np.array((planned.x_m - stance.x_m,
                                              planned.y_m - stance.y_m)))
        back = landing_x - planned_x - float(heading @ wanted)
        return wanted + min(back, 0.0) * heading

    def _abandoned(self, k: int, step: int, stance: Footstep, base: list[Footstep],
                   remaining_s: float, t_s: float) -> bool:
        """Once the walk is stopping (the capture-point monitor's stop, or the
        operator's), after a push from the front, the landing that captures the body
        (:meth:`_capture_landing`) lies behind where the swing foot is now along the stance
        sole, and the foot put down under its command now (at most CP_MAX_SHIFT_M from its
        planned landing, within the step's limits: :func:`~hubo_cli.walking.replan.
        shifted_landing`; the timeline from its landing on played at once, as a swing down
        early: :meth:`_touched_early`) has its heel CP_CAPTURE_MARGIN_M behind the capture
        point predicted then: the swing is abandoned there, within the first
        CP_ABANDON_FRACTION of its single support. Swinging on (main before round 9), seed
        11's walk pushed at 1.900 s put that foot down 0.57 s after the push and fell; the foot
        put back down, it touched 0.475 s after the push and stood (docs/history/walking.md).
        A walk still walking is not abandoned: the fast gait's own lag of the capture point
        (slips, no push) passed the same test in perturbed robots 8 and 11's 2 m walks, 20-22
        mm behind with the monitor silent, and the feet put down short fell; a push abandoned
        its swing 20-55 ms after the monitor's stop, 106-108 mm behind. Returns whether it
        re-planned."""
        if self.phase != "stopping" or \
                remaining_s < (1.0 - CP_ABANDON_FRACTION) * self.params.single_support_s:
            return False
        landing_x, now_cp_x = self._capture_landing(k, stance, remaining_s)
        side = base[step].side
        x, y, _, yaw = self._rows[side][k]
        c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        here_x = c * (x - stance.x_m) + s * (y - stance.y_m)
        heel_m = float(self.corners[:, 0].min())
        if not (landing_x < here_x and here_x + heel_m <= now_cp_x - CP_CAPTURE_MARGIN_M):
            return False  # (NaN: no capture landing needed)
        here = shifted_landing(stance, base[step], np.array((x - base[step].x_m,
                                                             y - base[step].y_m)),
                               self.model.feet.width_m, self.params.step_width_m)
        here = Footstep(side, here.x_m, here.y_m, yaw)

        self._put_down = True  # (till its landing is played: _unloaded_landing)
        self._move_landing(step, here, base, t_s, skip=self._landing[k] - k)
        return True

    def _move_landing(self, step: int, landing: Footstep, base: list[Footstep], t_s: float,
                      touched: bool = False, **replan) -> None:
        """Re-plan ``base`` with step ``step`` landing at ``landing`` (:meth:`_replan`, with
        ``replan``'s options); once installed (out of the legs' reach it is not: the pattern
        playing stands) it counts as a landing moved by the capture point, or as a swing ended
        where the foot ``touched`` down early, and the move is kept for the step's later
        moves (``_shift``)."""
        old_cart, old_k, old_row = self._cart, self.k, self._row0 + self.k

        def done() -> None:
            if touched:
                self.touchdowns_early += 1
            else:
                self.shifts += 1
                self._record_ref_move(step, old_cart, old_k, old_row)
            self._shift = (step, np.array([landing.x_m - base[step].x_m,
                                           landing.y_m - base[step].y_m]), base)

        self._replan(shift_steps(base, step, landing), t_s, done=done, **replan)

    def _record_ref_move(self, step: int, old_cart: Gait, old_k: int, old_row: int) -> None:
        """Add how far the re-plan just installed moved the pattern's capture point (its
        cart-table CoM plus velocity over omega, the new less ``old_cart``, whose row
        ``old_k`` was the plan's row ``old_row``; the multi-body correction is continued
        alike, :func:`~hubo_cli.walking.replan.continued_fix`) to step ``step``'s record, up to
        its landing."""
        new, old, omega = self._cart.com, old_cart.com, self._omega
        first_old = old_k + self._row0 - old_row  # (a swing abandoned skips rows)
        # (a re-plan's cart has its CoM path only over its first rows: held from the last)
        n = min(self._landing[0] + 1, len(new.com_m), len(old.com_m) - first_old)
        if n <= 0:
            return
        moved = ((new.com_m[:n] + new.com_velocity_m_s[:n] / omega)
                 - (old.com_m[first_old:first_old + n]
                    + old.com_velocity_m_s[first_old:first_old + n] / omega))
        recorded, first, total = self._ref_moved
        if recorded != step:
            first, total = self._row0, np.zeros((1, 2))
        start = self._row0 - first
        total = np.vstack([total, np.repeat(total[-1:], max(start + n - len(total), 0), axis=0)])
        total[start:start + n] += moved
        total[start + n:] += moved[-1]
        self._ref_moved = (step, first, total)

    def _ref_moved_at(self, step: int, k: int) -> np.ndarray:
        """How far step ``step``'s landing moves have moved the pattern's capture point at
        period ``k`` (world x, y; m; :meth:`_record_ref_move`)."""
        recorded, first, moved = self._ref_moved
        if recorded != step:
            return np.zeros(2)
        return moved[min(max(self._row0 + k - first, 0), len(moved) - 1)]

    def _reaim(self, t_s: float) -> None:
        """At the lift-off of each of the plan's last REAIM_STEPS steps (both soles down, the
        next row lifting one), move the plan's landings still to come by the stance sole's
        drift: where the pattern put it less where the estimate puts it. The legs place a
        landing relative to the stance sole, so a stance sole standing off its place in the
        pattern (the soles' slips as the estimate sees them, the legs' tracking) carries every
        later landing with it; moved so, the feet end where the plan put them in the
        estimate's world, and the correction walked after the pattern (:meth:`__call__`) is
        needed only when they did not.

        Each foot's last landing moves by the drift less what earlier re-aims already moved it
        (a landing the capture point moved keeps that move), its landings before it by a share
        growing to 1 there; once the stance foot has made its last landing, the plan's last
        one also takes back that foot's miss (the stance, midway between them, on the goal).
        Only where the stance would end ARRIVED_M or more off (the drift less both feet's
        mean re-aim so far; less: the walk ends where no correction walks. Re-aimed at every
        drift, the normal gait's 1 m walks, which arrive without a correction, ended further
        off by the truth: median 1.75 -> 4.3 mm, seed 6 15.3 mm, seed 12 stopped by the
        capture-point monitor). A swing's travel changes by at most REAIM_STEP_M a re-aim;
        the steps stay within the gait's limits (else the change along the walk is halved,
        twice at most, or left out), and a plan whose steps are not within them (an
        approach's closing steps to a stance narrower than the gait's) is not re-aimed.
        Not while the capture point is off the pattern's by what moves a landing (CP_MARGIN_M
        and CP_REPLAN_M; but see the fast gait's last step below): the correction after the
        pattern acts then.

        A plan whose landings the capture point or a push has moved: in a gait that answers
        pushes it is not re-aimed (a push's answer is not pulled back; round 9: seed 11 of the
        fast 2 m walks fell after 2 re-aims among 23 such moves, re-aimed at each of the last 4
        lift-offs); in the fast gait (:attr:`reaim_moved`), whose moves follow its own
        capture point's lag, only its last REAIM_MOVED_STEPS steps are, at the goal: each
        foot's final place off the plan's first (:meth:`_off_aim`) stands for what re-aims
        moved it. There the last step (beside the stance foot) moves by up to REAIM_LAST_M,
        for a stance that would end REAIM_LAST_FLOOR_M off, whatever the capture point's
        error (the capture point still moves its landing as it swings: at the fast gait's
        last lift-off the estimated one ran 44-51 mm ahead of the pattern's in AVX-512 walks
        1 and 15 and portable 12, whose plans ended 15-27 mm short and walked a correction,
        docs/history/walking.md, round 20). Re-planned as the capture
        point's moves are (:meth:`_replan`): the swing foot moves onto its new path by its
        landing, the CoM continues."""
        k, cart = self.k, self._cart
        if self.toe_heel is not None or k + 1 >= cart.n or not all(cart.support[k].tolist()) \
                or all(cart.support[k + 1].tolist()):
            return
        step, steps = int(cart.step_index[k + 1]), self._basis[1]
        moved_plan = self.shifts + self.touchdowns_early > self._moves_before
        if moved_plan and not self.reaim_moved:
            return
        last = REAIM_MOVED_STEPS if moved_plan else REAIM_STEPS
        last_step = self.reaim_moved and step == len(steps) - 1
        if step < max(len(steps) - last, 0) or step == self._reaimed or not (last_step or np.all(
                np.abs(self._capture_point_error(k)) <= CP_MARGIN_M + CP_REPLAN_M)):
            return
        self._reaimed = step
        column = 0 if cart.support[k + 1, 0] else 1
        side = SIDES[column]
        x, y, _, yaw = cart.feet[side][k].tolist()
        stance = footstep_of(side, self.store[T_WORLD_SOLES][column])
        drift = np.array([x - stance.x_m, y - stance.y_m])  # the pattern's sole less the
        # estimate's; each foot's final place off the goal's in the plan (moved: the capture
        # point's moves too, taken back)
        reaimed = self._off_aim(steps) if moved_plan else self._reaimed_m
        ending_m = float(np.hypot(*(drift - (reaimed["right"] + reaimed["left"]) / 2)))
        if not ending_m >= (REAIM_LAST_FLOOR_M if last_step else ARRIVED_M):  # (NaN: no sole)
            return  # the stance would end where no correction walks
        finals = {}
        for foot in SIDES:
            mine = [j for j in range(step, len(steps)) if steps[j].side == foot]
            if mine:
                finals[foot] = (mine, drift - reaimed[foot])
        if len(finals) == 1:  # the stance foot has made its last landing: its miss too
            foot = steps[-1].side
            mine, d = finals[foot]
            finals[foot] = (mine, d + drift - reaimed[side])
        changes = {}
        for mine, d in finals.values():
            n = len(mine)
            most_m = REAIM_LAST_M if last_step else REAIM_STEP_M * n
            d = d * min(1.0, most_m / max(float(np.hypot(*d)), 1e-12))
            changes.update({j: d * (i + 1) / n for i, j in enumerate(mine)})
        feet = [Footstep(foot, *cart.feet[foot][k][[0, 1, 3]].tolist()) for foot in SIDES]
        if not within_limits(steps[step:], *feet, self.params):
            return  # (an approach's closing steps to the working stance, narrower than the
            # gait's lateral bound: unchecked, a re-aim put the soles 0.147 m apart)
        ahead = np.array([math.cos(yaw), math.sin(yaw)])  # the walk's forward here
        for share in (1.0, 0.5, 0.25, 0.0):  # of the change along it (a step's reach)
            moved = []
            for j, old in enumerate(steps):
                if j not in changes:
                    moved.append(old)
                    continue
                d = changes[j] - (1.0 - share) * float(changes[j] @ ahead) * ahead
                moved.append(Footstep(old.side, old.x_m + d[0], old.y_m + d[1], old.yaw_rad))
            if within_limits(moved[step:], *feet, self.params):
                break
        else:
            return

        def done() -> None:
            self.reaims += 1
            for foot, (mine, _) in finals.items():
                reaimed[foot] += np.array([moved[mine[-1]].x_m - steps[mine[-1]].x_m,
                                           moved[mine[-1]].y_m - steps[mine[-1]].y_m])

        self._replan(moved, t_s, done=done)

    def _off_aim(self, steps: list[Footstep]) -> dict[str, np.ndarray]:
        """Each foot's final place in ``steps`` (its last landing, else where the plan
        started it) less its final place in the plan as made (:meth:`_plan`): world x, y (m)."""
        return {side: _final_place(steps, self._basis[0][column], side) - self._aims[side]
                for column, side in enumerate(SIDES)}

    def _touched_early(self, k: int, step: int, support: list[bool], t_s: float) -> bool:
        """A swing foot down early (pushed onto the floor): the estimate has its sole in
        contact and carrying more than ``estimation.swing_touchdown_n`` past TOUCH_FRACTION
        of its single support, the pattern's sole still TOUCH_MIN_HEIGHT_M or more above its
        landing (lower, the stabilizer's :class:`Touchdown` holds it). The swing ends there:
        the step lands where the estimate's sole stands (seen from the stance sole, in the
        pattern's frame); pushed (:meth:`_pushed`), the rest of the timeline from that
        landing on is played from now (the double support, the next step, whose landing the
        capture point moves as it swings), else the foot stays down where it stands and the
        ZMP on the stance foot until the planned landing. Returns whether it re-planned."""
        if step < 0 or support[0] == support[1]:
            return False
        column = 0 if not support[0] else 1
        period, single_s = self.gait.period_s, self.params.single_support_s
        remaining = self._landing[k] - k
        # (above the floor the plan stands on: a re-plan's ``_clearance`` counts from its
        # first row, in the air when it began in a swing)
        if self._rows[SIDES[column]][k][2] - self._basis[2] < TOUCH_MIN_HEIGHT_M or \
                (single_s - remaining * period) < TOUCH_FRACTION * single_s:
            return False
        if not (self.store[CONTACT][column] and ankle_wrenches(self.store)[column, 2]
                > self.model.estimation.swing_touchdown_n):
            return False
        side, stance_side = SIDES[column], SIDES[1 - column]
        poses = self.store[T_WORLD_SOLES]
        touched = footstep_of(side, poses[column])
        stance = footstep_of(stance_side, poses[1 - column])
        x, y, _, yaw = self._rows[stance_side][k]
        c, s = math.cos(yaw - stance.yaw_rad), math.sin(yaw - stance.yaw_rad)
        dx, dy = touched.x_m - stance.x_m, touched.y_m - stance.y_m
        shifted_step, _, base = self._shift
        if shifted_step != step:
            base = list(self._basis[1])
        landed = Footstep(side, x + c * dx - s * dy, y + s * dx + c * dy,
                          yaw + touched.yaw_rad - stance.yaw_rad)

        pushed = self._pushed(k)
        self._pushed_down = pushed  # (till its landing is played: _unloaded_landing)
        self._move_landing(step, landed, base, t_s, touched=True,
                           skip=remaining if pushed else 0, held=None if pushed else step)
        return True

    def _pushed(self, k: int) -> bool:
        """The estimated capture point is off the pattern's by more than CP_MARGIN_M on an
        axis (either way), or not finite: a swing ended early at period ``k`` skips the rest of its
        timeline to the landing (:meth:`_touched_early`). Skipping to the landing in a walk
        the robot follows put the pattern's CoM that much time behind its ZMP reference:
        fast-gait feet down 0.13 s early (perturbed robots 8 and 12, the capture point within
        15 mm of the pattern's) drove the pattern's CoM at 0.8 m/s (the walk's 0.25), its
        capture point 0.22-0.23 m from the robot's, and the landings moved after it, then the
        stop, tipped the robot over. Skipping only to the row whose planned capture point lies
        nearest the estimated one let a side push's foot (seed 2 of
        tools/walk_disturbances.py) be held with the ZMP on the stance foot: it fell
        (docs/history/walking.md)."""
        return not np.all(np.abs(self._capture_point_error(k)) <= CP_MARGIN_M)

    def _capture_point_error(self, k: int) -> np.ndarray:
        """The estimated capture point (seen from the more loaded planned support sole
        standing where the pattern put it, as :meth:`_in_pattern`) less the pattern's
        (its CoM plus velocity over omega): world x, y (m)."""
        com = self.gait.com
        planned = (np.asarray(com.com_m[k]) + np.asarray(com.com_velocity_m_s[k]) / self._omega)
        return np.asarray(self._in_pattern(k, ankle_wrenches(self.store),
                                           self.store[CAPTURE_POINT_WORLD])) - planned

    @property
    def walking_s(self) -> float:
        """From the start to the end of the last step's double support (s)."""
        gait = self.gait
        if gait is None:
            return 0.0
        moving = np.nonzero(gait.step_index >= 0)[0]
        if not len(moving):
            return self.last_step_end_s
        return self.plan_start_s + float((moving[-1] + 1) * gait.period_s)

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        store = self.store
        if self._pending is not None and self.k >= self._pending[0]:
            self._advance_replan(t_s)  # a re-plan's rest is due: played from this period
        work = self._prefix, self._pending
        if self.gait is None:
            self._start(t_s, state.q_rad)
        elif self.phase == "walk" and (store.get(STOP_MODE, "release") != "release"
                                       or self._caught(self.k) or self._bounced):
            self._stop(t_s)
        elif self.phase == "walk" and self.k >= self.gait.n and not self.fell \
                and self._pending is None and self.corrections_left > 0 and not self.arrived():
            self.corrections_left -= 1
            self.last_step_end_s = self.walking_s
            # from the joints last sent: the CoM where the legs hold it (the plan's last
            # row missed the stabilizer's correction: portable seed 1's soles jumped 6 mm)
            self._plan(self._sent_q, t_s)
        elif self.phase in ("walk", "stopping"):  # a stop's last step follows it too
            if self.phase == "walk":
                self._reaim(t_s)
            self._follow_capture_point(t_s)
        if self._prefix is work[0] and self._pending is work[1]:  # (a re-plan decided now
            if self._prefix is not None:                           # has done its share)
                self._advance_prefix(t_s)
            if self._pending is not None:
                self._advance_replan(t_s)
        if self.phase == "stopping" and self.k >= self.gait.n and self._pending is None:
            self.phase = "stood"
        # how this phase stops: finishing the step (settled once it stands), or by the
        # stopper's own brake when the stop's pattern could not be made
        store[PHASE_STOP] = None if self.stop_failed else PhaseStop(
            self.phase == "stood", self.stop_within_s())
        gait, plan = self.gait, self.plan
        k = min(self.k, gait.n - 1)
        right_fz_n, left_fz_n = (float(state.ft[sensor][2]) if sensor in state.ft else math.nan
                                 for sensor in ANKLE_SENSORS)  # as read (the log's *_foot_fz_n)
        soles_fz = right_fz_n + left_fz_n
        self._loads_n[self._load_i] = right_fz_n, left_fz_n
        self._load_i = (self._load_i + 1) % len(self._loads_n)
        landing_wait = self._unloaded_landing(k, (right_fz_n, left_fz_n))
        if landing_wait:
            self.landing_waits += self._landing_waited_s == 0.0
            self._landing_waited_s += gait.period_s
        liftoff_wait = not landing_wait and self._unloaded_liftoff(k)
        self._waited_s = self._waited_s + gait.period_s if liftoff_wait else 0.0
        if self._waited_s > LIFTOFF_WAIT_MAX_S:
            weight_n = LIFTOFF_MIN_LOAD * self._weight_n
            raise DeviceError(
                f"the ankle force sensors read {np.median(self._loads_n.sum(axis=1)):.0f} N "
                f"together (under {weight_n:.0f} N, {LIFTOFF_MIN_LOAD:g} of the robot's "
                f"weight), or the foot to stay down under "
                f"{self.model.estimation.swing_touchdown_n:g} N, for "
                f"{LIFTOFF_WAIT_MAX_S:g} s before a step: the walk stopped in double support",
                hint="check the ankle F/T sensors (zero offsets, cables), or put the robot "
                     "down on its feet")
        if landing_wait or liftoff_wait:
            self.liftoff_waits += liftoff_wait and not self._waiting
            self.plan_start_s += gait.period_s  # the timeline waits: row k plays again
        else:
            self.k += 1
        self._waiting = liftoff_wait
        (_, _, r02, _), (_, _, r12, _), (_, _, r22, torso_z) = store[T_WORLD_TORSO][:3].tolist()
        tilt_deg = math.degrees(tilt_rad_of_z_axis(r02, r12, r22))
        if self.torso_z0_m is None:
            self.torso_z0_m = torso_z
        if has_fallen(tilt_deg, self.torso_z0_m - torso_z):
            self.fell = True
        poses = store[T_WORLD_SOLES]
        zmp = np.asarray(store[ZMP_WORLD], dtype=float)
        outside = zmp_outside_m(zmp, poses, self.corners, store[CONTACT])
        if math.isfinite(outside):
            self.zmp_periods += 1
            self.zmp_inside_periods += outside <= -ZMP_INSIDE_MARGIN_M
        self.final_feet = {"right": poses[0].copy(), "left": poses[1].copy()}
        right_down, left_down = self._rows["support"][k]
        store[SUPPORT_PLAN] = SupportPlan(self._support_in_estimate(k)
                                          if self.support_where_standing
                                          else self._support_poses[k], None,
                                          (not right_down, not left_down))
        q = plan.q_rad[k]
        if self.stabilizer is not None:
            q = self._stabilized(k, q.copy(), zmp if math.isfinite(outside) else None)
        self._sent_q = q
        rows = self._rows
        zmp_x, zmp_y = zmp[:2].tolist()
        support = rows["support"][k]
        self._played_support = (bool(support[0]), bool(support[1]))
        (zmp_ref_x, zmp_ref_y), (com_ref_x, com_ref_y) = rows["zmp_ref"][k], rows["com_ref"][k]
        info = {"walk.zmp_ref_x_m": zmp_ref_x, "walk.zmp_ref_y_m": zmp_ref_y,
                "walk.com_ref_x_m": com_ref_x, "walk.com_ref_y_m": com_ref_y,
                "walk.zmp_x_m": zmp_x, "walk.zmp_y_m": zmp_y,
                "walk.contact_zmp_outside_m": outside if math.isfinite(outside) else math.nan,
                "walk.step": float(rows["step"][k]), "walk.tilt_deg": tilt_deg,
                "planned_right_foot_contact_flag": float(support[0]),
                "planned_left_foot_contact_flag": float(support[1]),
                "walk.phase_code": float(WALK_PHASES.index(self.phase)),
                "walk.soles_fz_n": soles_fz,
                "walk.liftoff_wait": float(liftoff_wait),
                "walk.landing_wait": float(landing_wait),
                "walk.cp_error_x_m": float(self._cp_error[0]),
                "walk.cp_error_y_m": float(self._cp_error[1]),
                "walk.cp_shift_x_m": float(self._shift[1][0]),
                "walk.cp_shift_y_m": float(self._shift[1][1]),
                **self._stabilizer_info(), **self._toe_heel_info(k, poses),
                "done": self.fell or self._done(t_s)}
        return q, info

    def _waits(self) -> bool:
        """The landing wait acts this period (``landing_wait``; while the walk goes on, only
        ``landing_wait_walking``). The fast gait's landings wait only once it stops: waiting
        while it walked stopped 14 of 20 unpushed perturbed 2 m walks after 2-11 steps; once
        stopped, the 100 N pushes' falls went 10 -> 9 of 20 (AVX-512) and 11 -> 10 (portable),
        no walk fared worse, the unpushed walks the same to the digit
        (docs/history/walking.md, round 24)."""
        return self.landing_wait and (self.landing_wait_walking or self.phase != "walk")

    def _unloaded_liftoff(self, k: int) -> bool:
        """Row ``k`` has both soles down and the next lifts one, while the soles measured
        carried less than LIFTOFF_MIN_LOAD of the body's weight (their median over the last
        LIFTOFF_WINDOW_S): the robot bounces, and the foot lifted would be its only support;
        or while the foot to stay down measured under ``estimation.swing_touchdown_n`` (its
        median over the same window) with the estimated capture point off the pattern's
        (:meth:`_pushed`): a push the estimate sees, the landed foot in the air, and the body
        would come down on it from the foot lifted (pushed seed 40 at 80 N: that foot read
        -10 N, the capture point 37 mm off, the left foot lifted and the robot fell). While
        the walk goes on, that wait also stops it (``_bounced``, the operator's stop next
        period). Off while walking (:meth:`_waits`) for a gait of short steps, as the fast
        gait: its landings bounce and its capture point lags the pattern's beyond CP_MARGIN_M
        unpushed; waiting there, perturbed robot 11's fast 2 m walk fell (portable path,
        round 17). Unpushed, perturbed robots lift off onto a landed foot
        reading -12 to +52 N at 56 of 160 lift-offs (8 of 20 walks), the capture point then
        within 15.5 mm of the pattern's: the foot reading alone stopped 8 of those walks after
        their first step (docs/history/walking.md, rounds 16 and 17)."""
        support = self._whole_support  # a re-plan's prefix ends mid-pattern: the next row
        if k + 1 >= len(support) or not support[k].all() or support[k + 1].all():  # is here
            return False
        together_n = self._loads_n.sum(axis=1)
        together_n = together_n[~np.isnan(together_n)]  # one garbled reading: not ignored
        if len(together_n) and np.median(together_n) < LIFTOFF_MIN_LOAD * self._weight_n:
            return True
        staying_n = self._loads_n[:, int(np.argmax(support[k + 1]))]
        staying_n = staying_n[~np.isnan(staying_n)]
        unloaded = bool(self._waits() and len(staying_n)
                        and np.median(staying_n) < self.model.estimation.swing_touchdown_n
                        and self._pushed(k))
        if unloaded and self.phase == "walk":
            self._bounced = True  # the walk stops (the operator's stop, next period)
        return unloaded

    def _unloaded_landing(self, k: int, soles_fz_n: tuple[float, float]) -> bool:
        """Row ``k`` is in the double support after a landing, the landed foot's ankle F/T
        sensor (``soles_fz_n``: right, left, N, as read) reads under
        ``estimation.swing_touchdown_n`` this period, the walk is stopping
        (the capture-point monitor's stop or the operator's) and the estimated capture point
        is off the pattern's (:meth:`_pushed`): the timeline waits at row ``k``,
        the pattern's weight transfer held, until that foot carries again, at most
        LANDING_WAIT_MAX_S in all over that double support (then it plays on), and no more
        once the foot has carried LANDING_CARRIED_S in a row. A push just
        before a landing tips the body back onto the other sole and the landed foot leaves
        the floor again, bouncing between the feet; played on, the transfer moved the ZMP
        reference onto the foot in the air, the body rolled onto it and over its outer edge
        (pushed seed 13, docs/history/walking.md, round 10). A re-plan (a stop) begun in that
        double support keeps the landing; without the sensor (NaN) it never waits. Only once
        the walk stops: waiting while it walked, perturbed robots' unpushed 1 m walks (their
        capture point 20-57 mm off the pattern's, landed feet reading under 60 N now and
        then) waited 0.3-3 s, one fell and 14 of 20 ended over 10 mm off. Off while walking
        (:meth:`_waits`) for a gait of short steps (``WalkingParams.answers_pushes``), as
        the fast gait: its own landings bounce and its capture point lags the pattern's by
        more than CP_MARGIN_M without a push; waiting at 4-12 of its landings, 3 of 10 of its
        2 m walks fell (docs/history/walking.md, round 10). While the walk goes on, the
        same landing with the capture point LANDING_WALK_PUSHED_M or more off the pattern's
        waits too, and the walk stops (``_bounced``: the stop latches next period, as the
        operator's): 60-70 N side pushes toward the swing foot (seeds 2, 5 and 19 of
        tools/walk_disturbances.py) landed, bounced between the soles, the walk played on,
        lifted the other foot with the body rolling over that sole's outer edge, and fell
        (docs/history/walking.md, round 14). A landing pushed onto the floor early
        (:meth:`_touched_early`, pushed) is watched till its lift-off, also once made: while
        the walk goes on, its foot read unloaded again with the capture point off the
        pattern's (:meth:`_pushed`) waits (within LANDING_WAIT_MAX_S), and the walk goes on
        once it carries. Pushed toward the swing foot (seed 20 at 70-90 N), that foot carried
        0.1 s, then the other one, trailing and lengthened by the pattern's weight transfer,
        struck the floor and the robot hopped off both soles; played on, the transfer went on
        in the air, the next lift-off came 20 ms after the body came down, rolling over the
        landed sole's outer edge, and it fell (docs/history/walking.md, round 15). The
        landing of a swing abandoned in the air (:meth:`_abandoned`) never waits: its foot has
        not reached the floor, and the timeline held at that landing's first row held the foot
        in the air while the body tipped back over the stance heel (the 2 m walk's seed 1 of
        tools/walk_disturbances.py, pushed from the front 36 ms after a lift-off, fell;
        docs/history/walking.md, round 22)."""
        if not self._waits() or not all(self._rows["support"][k]):
            self._landed = None  # (a single support: the landing is past)
            return False
        played = self._played_support
        if played is not None and not all(played):
            # a landing: last period played one sole down, this row has both, whatever
            # pattern it is in (a stop's rest, an early touchdown or an abandoned swing starts
            # its pattern at the landing's row 0)
            self._landed = 0 if not played[0] else 1
            self._landing_waited_s = self._landing_carried_s = 0.0
            self._landing_made, self._landing_pushed_down = False, self._pushed_down
            self._landing_put_down = self._put_down
            self._pushed_down = self._put_down = False
        if self._landed is None or self._landing_waited_s >= LANDING_WAIT_MAX_S \
                or self._landing_put_down:
            return False
        if not soles_fz_n[self._landed] < self.model.estimation.swing_touchdown_n:
            self._landing_carried_s += self.gait.period_s
            if self._landing_carried_s >= LANDING_CARRIED_S - 1e-9:
                self._landing_made = True
                if not self._landing_pushed_down:
                    self._landed = None  # the landing is made
            return False
        self._landing_carried_s = 0.0
        if self.phase == "stopping":
            return not self._landing_made and self._pushed(k)
        if self._landing_made:
            # a landing pushed down early, made, whose foot leaves the floor again: the robot
            # hops off its soles; the weight transfer waits, the walk goes on after it
            # (docs/history/walking.md, round 15)
            return self._pushed(k)
        error = self._capture_point_error(k)
        self._bounced = not np.all(np.abs(error) <= LANDING_WALK_PUSHED_M)
        return self._bounced

    def _done(self, t_s: float) -> bool:
        """The walk has ended: the pattern played (and no correction is due), or a stop's
        stance held STOOD_S."""
        if self._pending is not None:
            return False
        if self.phase == "walk":
            return self.k >= self.gait.n and (self.corrections_left == 0 or self.arrived())
        return self.phase == "stood" and self.k >= self.gait.n + round(STOOD_S
                                                                       / self.gait.period_s)

    def _toe_heel_info(self, k: int, poses: np.ndarray) -> dict[str, float]:
        """Fig. 4's quantities for the log: each sole's planned CoP along it (x from its
        origin, m) and its angle (rad, > 0 on the toe), NaN walking flat; the measured ones
        (the compensated ankle wrench's CoP while loaded, the estimated sole's pitch); the
        LIP feedback's ZMP command (NaN without it)."""
        info = {}
        wrenches = ankle_wrenches(self.store)
        plan = self.gait.toe_heel
        for column, (cop_ref, angle_ref, cop, angle) in enumerate(_TOE_HEEL_COLUMNS):
            fz, my = float(wrenches[column, 2]), float(wrenches[column, 4])
            info[cop_ref] = math.nan if plan is None else float(plan.cop_offset_m[k, column])
            info[angle_ref] = (math.nan if plan is None
                               else float(plan.foot_angle_rad[k, column]))
            info[cop] = -my / fz if fz > self.model.estimation.sole_damping_min_fz_n else math.nan
            info[angle] = math.asin(max(-1.0, min(1.0, -float(poses[column][2, 0]))))
        command = self.lip.zmp_command_m if self.lip is not None else (math.nan, math.nan)
        info["walk.zmp_command_x_m"], info["walk.zmp_command_y_m"] = (float(v) for v in command)
        return info

    def _stabilizer_info(self) -> dict[str, float]:
        """The stabilizer's corrections for the log (NaN without a stabilizer)."""
        if self.stabilizer is None:
            return dict.fromkeys(self.stabilizer_columns, math.nan)
        right, left = self.dampers["right"].delta_rad, self.dampers["left"].delta_rad
        offset = self.torso_offset.offset_m
        return {"walk.offset_x_m": float(offset[0]), "walk.offset_y_m": float(offset[1]),
                "walk.right_lift_m": self.touchdowns["right"].lift_m,
                "walk.left_lift_m": self.touchdowns["left"].lift_m,
                "walk.right_sole_roll_rad": float(right[0]),
                "walk.right_sole_pitch_rad": float(right[1]),
                "walk.left_sole_roll_rad": float(left[0]),
                "walk.left_sole_pitch_rad": float(left[1]),
                "walk.right_level_rad": float(self._level_rad[0]),
                "walk.left_level_rad": float(self._level_rad[1]),
                "walk.pitch_error_rad": self._pitch_error_rad,
                "walk.right_reach_rad": float(self.reach.angle_rad[0]),
                "walk.left_reach_rad": float(self.reach.angle_rad[1]),
                "walk.right_momentum_rad": float(self.hips.offset_rad[0]),
                "walk.left_momentum_rad": float(self.hips.offset_rad[1])}

    def _pattern_frame(self, k: int, wrenches: np.ndarray) -> tuple[float, ...]:
        """Where the pattern's frame stands in the estimate's: the more loaded planned support
        sole's planned place (x, y), its estimated place (x, y), and the cosine and sine of its
        planned heading less its estimated one (see :meth:`_in_pattern`)."""
        right_down, left_down = self._rows["support"][k]
        column = 1 if (left_down, float(wrenches[1, 2])) > (right_down, float(wrenches[0, 2])) \
            else 0
        sole = self.store[T_WORLD_SOLES][column]
        planned_x, planned_y, _, planned_yaw = self._rows[SIDES[column]][k]  # (floats)
        turn = planned_yaw - math.atan2(float(sole[1, 0]), float(sole[0, 0]))
        return (planned_x, planned_y, float(sole[0, 3]), float(sole[1, 3]), math.cos(turn),
                math.sin(turn))

    def _in_pattern(self, k: int, wrenches: np.ndarray, point_m: np.ndarray
                    ) -> tuple[float, float]:
        """An estimated point (world x, y) seen from the more loaded planned support sole
        standing where the pattern put it: its offset from that sole's estimated place, in
        that sole's frame, from the sole's planned place and heading (the pattern's frame,
        which a sole's slip or twist does not move: the estimate sees a stance sole's twist,
        by the gyro, and the CoM ahead of a sole turned 4 deg read as 10 mm sideways off the
        pattern, which moved landings and stopped walks; docs/history/walking.md)."""
        planned_x, planned_y, sole_x, sole_y, c, s = self._pattern_frame(k, wrenches)
        dx, dy = float(point_m[0]) - sole_x, float(point_m[1]) - sole_y
        return planned_x + c * dx - s * dy, planned_y + s * dx + c * dy

    def _support_in_estimate(self, k: int) -> np.ndarray:
        """Row ``k``'s planned support (:func:`~hubo_cli.walking.support.planned_support`)
        placed in the estimate's frame as :meth:`_in_pattern` reads the pattern's (its
        inverse): the capture-point monitor judges the estimated capture point against the
        soles where the robot stands (with ``support_where_standing``; else where the pattern
        put them). Laid where the pattern put them, fast walks whose stance soles had slipped
        round by degrees (seen by the gyro) and walked on turned had their capture points
        judged against soles off their own: seed 12's was 13 mm outside while its error in the
        pattern's frame was 12 mm, and the monitor stopped it. Off for the normal gait: two 100
        N pushes' stops came 55-435 ms later (the support moved with the pushed stance sole)
        and those walks fell (docs/history/walking.md, round 13). The soles the row has down
        are laid where the estimate has them (flat, on the plan's floor), the swing foot's
        landing place from the pattern's frame: a frame laid from the more loaded sole alone
        moved the whole hull when the other sole took the load (87 mm at a fast walk's last
        landing, the capture point past its front line, a false stop; round 19)."""
        planned_x, planned_y, sole_x, sole_y, c, s = self._pattern_frame(
            k, ankle_wrenches(self.store))
        M = np.eye(4)
        M[:2, :2] = ((c, s), (-s, c))  # the turn back: estimated heading less planned
        M[0, 3] = sole_x - (c * planned_x + s * planned_y)
        M[1, 3] = sole_y - (-s * planned_x + c * planned_y)
        laid = M @ self._support_poses[k]
        sensed = self.store[T_WORLD_SOLES]
        for column, down in enumerate(self._rows["support"][k]):
            if down:
                laid[column] = pose_laid_flat(sensed[column], float(laid[column, 2, 3]))
        return laid

    def _stabilized(self, k: int, q: np.ndarray, zmp: np.ndarray | None) -> np.ndarray:
        """The pattern's joints ``q`` with the stabilizer's corrections (see
        :mod:`hubo_cli.walking.stabilizer`)."""
        rows = self._rows
        wrenches = ankle_wrenches(self.store)
        com = self._in_pattern(k, wrenches, self.store[COM_WORLD])
        if self.phase == "walk" and k < self._settle_k:  # settling, stopping: it holds (see
            # the module docstring)
            self.torso_offset.update(zmp, rows["zmp_ref"][k], com, rows["plan_com"][k])
        offset_x, offset_y = self.torso_offset.offset_m.tolist()
        cop_refs = [None, None]
        if self.lip is not None:  # eq. 8 and 9-14: the soles' reference CoPs for their dampers
            zmp_pattern = (math.nan, math.nan) if zmp is None \
                else self._in_pattern(k, wrenches, zmp)
            cop_refs = self.lip.cop_references(
                rows["plan_com"][k], rows["com_velocity_ref"][k], rows["zmp_ref"][k], com,
                self.store[COM_VELOCITY_WORLD][:2], zmp_pattern, self._contacts[k])
        lifts = [self.touchdowns[side].update(not down, self._clearance[side][k],
                                              float(wrenches[column, 2]))
                 for column, (side, down) in enumerate(zip(SIDES, rows["support"][k],
                                                           strict=True))]
        torso_error = self._torso_error_rad(k)
        self._reach_floor(k, float(torso_error[0]))
        turns = self.reach.turns(self._T_neck_soles[k])
        _correct_legs(self._T_neck_soles[k], self._R_neck_world[k], offset_x, offset_y, *lifts,
                      q, self._leg_delta, *self._leg_kernel, LEG_STEP_RAD,
                      self._no_turns if turns is None else turns)
        for column, side in enumerate(SIDES):
            delta = self.dampers[side].update(wrenches[column], cop_refs[column])
            roll, pitch = self._ankle[side]
            q[roll] += delta[0]
            q[pitch] += delta[1]
        self._level_swing(rows["support"][k], q, float(torso_error[1]))
        self._momentum(k, q)
        return q

    def _caught(self, k: int) -> bool:
        """A swing foot turned beyond REACH_STOP_RAD against the body's roll over the stance
        sole's edge has landed (row ``k`` has both soles down): the walk stops there
        (:mod:`hubo_cli.walking.floor_reach`; never in a toe-heel walk, whose reach is off)."""
        return (self.stabilizer is not None and self.reach.tipped
                and k < self.gait.n and all(self._rows["support"][k]))

    def _torso_error_rad(self, k: int) -> np.ndarray:
        """The estimated torso's attitude from the planned one at row ``k``, as a rotation
        vector in the torso's frame (rad: x its roll, y its pitch)."""
        R_plan = self.plan.T_world_neck[k, :3, :3]
        return pin.log3(R_plan.T @ np.asarray(self.store[T_WORLD_TORSO], dtype=float)[:3, :3])

    def _reach_floor(self, k: int, roll_error_rad: float) -> None:
        """The swing foot kept over the floor against the estimated torso's roll from the
        planned one toward the stance side (``roll_error_rad``,
        :mod:`hubo_cli.walking.floor_reach`). Off
        (``floor_reach``) for a gait of short steps (``WalkingParams.answers_pushes``), as
        the fast gait: its own slips and hops roll the torso beyond REACH_DEAD_RAD without a
        push (perturbed robots 8, 11 and 12's 2 m walks, turns of 0.013-0.033 rad): robot
        12's walk stopped itself (without the reach it arrives 23 mm off), robot 11's 0.175 s
        before the monitor's stop (docs/history/walking.md, round 11)."""
        if not self.floor_reach or (self.momentum and self.hips.acting):
            return
        support = self._rows["support"][k]
        contact = self.store[CONTACT]
        self.reach.update(roll_error_rad, (bool(support[0]), bool(support[1])),
                          (bool(contact[0]), bool(contact[1])))

    def _momentum(self, k: int, q: np.ndarray) -> None:
        """The hip rolls' momentum strategy against a side push toward the stance foot
        (:mod:`hubo_cli.walking.momentum`), added in place to ``q`` within the walking set's
        limits. Off (``momentum``) for a gait of short steps (the fast gait) and toe-heel walks."""
        if not self.momentum:
            return
        support = self._rows["support"][k]
        contact = self.store[CONTACT]
        past_m = math.nan  # the estimated capture point past the stance sole's outer edge
        if support[0] != support[1]:
            stance = 0 if support[0] else 1
            T = self.store[T_WORLD_SOLES][stance]
            cp = np.asarray(self.store[CAPTURE_POINT_WORLD], dtype=float)
            outward = 1.0 if stance == 1 else -1.0  # the sole's outer side along its y axis
            past_m = (outward * float((cp[0] - T[0, 3]) * T[0, 1] + (cp[1] - T[1, 3]) * T[1, 1])
                      - self._half_width_m)
        offsets = self.hips.update(float(self._cp_error[1]), past_m,
                                   (bool(support[0]), bool(support[1])),
                                   (bool(contact[0]), bool(contact[1])),
                                   (float(q[self._hip_roll[0]]), float(q[self._hip_roll[1]])))
        for column, j in enumerate(self._hip_roll):
            if offsets[column]:
                q[j] = min(max(q[j] + offsets[column], self.hips.lower_rad[column]),
                           self.hips.upper_rad[column])

    def _level_swing(self, support: list[bool], q: np.ndarray, pitch_error_rad: float
                     ) -> None:
        """Pitch each swing leg at its hip against the estimated torso's pitch from the planned one
        (``pitch_error_rad``; beyond LEVEL_DEAD_RAD, at most LEVEL_MAX_RAD; changing at most
        LEVEL_RATE_RAD_S), in place in ``q``: a body tipped by a push carries a swing foot
        fixed in its frame with it and lands it early on an edge (pushed from the front, the
        body tipped back and the heel came down 7 deg toe-up, 0.05 m short of its moved
        landing, and bounced). Turned so, the leg keeps its planned pitch in the world and
        the sole lands flat. A leg on the floor (planned down, or in the estimate's contact)
        keeps its turn while the other one swings (turned back under the weight, the landed
        foot was lifted at its toe or heel); with both soles planned down and in contact,
        the turns go back to the pattern at LEVEL_RETURN_RAD_S, the torso righting itself
        over the flat soles. The turn is about the hip's pitch axis, not the torso's: with
        the hip yawed by psi it leaves sin(psi) of the torso's pitch as the sole's roll (2.7
        deg of 9 at 0.3 rad)."""
        error = pitch_error_rad
        self._pitch_error_rad = error  # about the torso's y axis
        tilt_rad = min(max(abs(error) - LEVEL_DEAD_RAD, 0.0), LEVEL_MAX_RAD)
        tilt_rad = math.copysign(tilt_rad, error)
        step = LEVEL_RATE_RAD_S * self.model.control_period_s
        contact = self.store[CONTACT]
        loaded = all(support) and all(contact)
        back = LEVEL_RETURN_RAD_S * self.model.control_period_s
        for column, down in enumerate(support):
            level = self._level_rad[column]
            if loaded:
                self._level_rad[column] = level - min(max(level, -back), back)
            # (on the floor, one leg swinging: it holds; no estimate of the torso: it holds)
            elif not (down or contact[column]) and math.isfinite(tilt_rad):
                self._level_rad[column] = level + min(max(tilt_rad - level, -step), step)
            q[self._hip_pitch[column]] -= self._level_rad[column]

    def arrived(self) -> bool:
        """The estimated feet stand within ARRIVED_M and ARRIVED_RAD of the goal stance."""
        if not self.final_feet:
            return False
        error_m, error_rad = self.final_error()
        return error_m <= ARRIVED_M and error_rad <= ARRIVED_RAD

    def final_error(self) -> tuple[float, float]:
        """The estimated final stance's distance (m) and heading error (rad) from the goal;
        NaN when the walk ended (Ctrl-C, SIGTERM, an error) before its last step came down."""
        if not self.final_feet:
            return math.nan, math.nan
        return stance_error(self.final_feet, self.goal)


def _final_place(steps: list[Footstep], start: Footstep, side: str) -> np.ndarray:
    """Where ``side``'s foot ends in ``steps`` (world x, y; m): its last landing, else
    ``start``."""
    place = next((step for step in reversed(steps) if step.side == side), start)
    return np.array([place.x_m, place.y_m])


def stance_error(T_world_soles: dict[str, np.ndarray], goal: Stance) -> tuple[float, float]:
    """The distance (m) and heading error (rad) of the stance the soles (``right``, ``left``:
    4x4 world poses) stand in from ``goal``."""
    feet = {side: footstep_of(side, T) for side, T in T_world_soles.items()}
    reached = stance_of(feet["right"], feet["left"])
    return (math.hypot(reached.x_m - goal.x_m, reached.y_m - goal.y_m),
            abs(math.atan2(math.sin(reached.yaw_rad - goal.yaw_rad),
                           math.cos(reached.yaw_rad - goal.yaw_rad))))
