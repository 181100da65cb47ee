"""Walking to the working stance first: a target that walks from a start stance to the
stance a task (or an operator) works from, rises into that session's start posture, and then
hands the loop over to the session's own target.

Phases (``approach.phase_code`` in the log):

0. ``walk``: a :class:`~hubo_cli.walking.target.WalkTarget` to the working stance, its last
   two steps closing the feet to the session posture's width; the capture-point monitor
   watches the planned support (as in ``hubo walk``), an emergency stop finishes the step in
   progress and the run ends in that stance (no rise, no session), and the standing balancers rest
   (:data:`~hubo_cli.control.phase.BALANCERS_REST`: their reference assumes both feet down
   and the CoM over them, which walking breaks);
1. ``rise``: both feet down, from the walk's last posture (crouched) to the session's start
   posture in ``RISE_S`` (:func:`rise_rows`: each sole's pose in the neck frame moves along a
   quintic and the legs' closed-form IK follows it, so the feet keep their distance; the arms
   move in joint space), through the whole pipeline (the trajectory generator and the limiter
   keep the limits); the monitor watches the estimated soles again and the balancers act; then
   a wait until the robot is still (at most ``STILL_TIMEOUT_S``);
2. ``then``: the session's target, called with its own clock (zero at the hand-over) as if the
   run had started there; the loop ends when it says so.

Each phase is a :class:`~hubo_cli.control.phase.Phase` (start, run, stop) of one
:class:`~hubo_cli.control.phase.Phases` machine; what the phase that made a period's command
asks of the pipeline (:data:`PHASE_REST`, the planned support) the target writes to the store
every period, so no module is reset or reprogrammed by the target.

The simulated wall of a task or a drill session is placed by the session's target as it is
without a walk (once the tool is ready, ahead of it); while walking the robot is kept clear of
the plane the wall will stand in: the footsteps are refused if a sole would come within
``WALL_MARGIN_M`` of it (:func:`wall_clearance_m`), and the run measures how close the
robot's foremost points (soles' toes, hands, the tool) came (``wall_clearance_mm``, from the
estimated torso pose and the measured joints).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from hubo_cli.control.module import Module
from hubo_cli.control.phase import BALANCERS_REST, PHASE_STOP, SUPPORT_PLAN, Phase, Phases
from hubo_cli.control.target import Target, TargetOutput
from hubo_cli.dataflow import Store
from hubo_cli.errors import InputError
from hubo_cli.estimation.keys import T_WORLD_TORSO
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture
from hubo_cli.scene import SceneActions
from hubo_cli.session import RunSetup
from hubo_cli.state import RobotState
from hubo_cli.urdf import DRILL_FRAME
from hubo_cli.walking.body import walking_posture
from hubo_cli.walking.footsteps import Footstep, Stance, closing_steps, plan_footsteps
from hubo_cli.walking.gait import smoothstep5
from hubo_cli.walking.params import WalkingParams, walking_params
from hubo_cli.walking.target import WalkTarget

PHASES = ("walk", "rise", "then")
PHASE_REST = {"walk": True, "rise": False, "then": False}  # the standing balancers rest
RISE_S = 4.0            # walking crouch -> the session's posture (5 cm up)
STILL_TIMEOUT_S = 2.0   # after the rise, wait at most this long for the robot to be still
STILL_RAD_S = 0.05      # every joint slower than this counts as still
WALL_MARGIN_M = 0.05    # no sole within this of the wall's plane on the way
HANDS = ("right_hand", "left_hand")


def stance_width_m(model: RobotModel, q_rad: np.ndarray) -> float:
    """How far apart the soles stand (centre lines, m) in the posture ``q_rad``."""
    y = [float(Limb(model, leg).fk(q_rad[model.limb_slice(leg)])[1, 3]) for leg in LEGS]
    return abs(y[0] - y[1])


def rise_rows(model: RobotModel, q_from_rad: np.ndarray, q_to_rad: np.ndarray,
              n: int) -> np.ndarray:
    """Joint rows (n, joints) from ``q_from_rad`` to ``q_to_rad`` with both feet down: each
    sole's pose in the neck frame moves from its place in one posture to its place in the other
    along a quintic in time (position straight, rotation by the shortest arc) and the legs'
    IK follows; the other joints move in joint space along the same quintic. Two postures
    with the feet as far apart keep them so all the way (the difference of two straight-line
    paths between the same offsets)."""
    from scipy.spatial.transform import Rotation, Slerp

    q_from, q_to = (np.asarray(q, dtype=float) for q in (q_from_rad, q_to_rad))
    s = smoothstep5((np.arange(n) + 1.0) / n)
    rows = q_from + s[:, None] * (q_to - q_from)
    for leg in LEGS:
        limb, part = Limb(model, leg), model.limb_slice(leg)
        T_a, T_b = limb.fk(q_from[part]), limb.fk(q_to[part])
        turn = Slerp([0.0, 1.0], Rotation.from_matrix([T_a[:3, :3], T_b[:3, :3]]))(s)
        q = q_from[part]
        for k in range(n):
            T = np.eye(4)
            T[:3, :3] = turn[k].as_matrix()
            T[:3, 3] = T_a[:3, 3] + s[k] * (T_b[:3, 3] - T_a[:3, 3])
            result = limb.solve(T, q)
            if not result.exact:
                raise InputError(f"the {leg} cannot rise into the session's posture "
                                 f"({result.status} at {k / n:.0%})",
                                 hint="the walk ended too far from the working stance")
            q = rows[k, part] = result.q_rad
        # the IK's last solution and the posture differ by its rounding: spread it over the
        # rise (the last row is the posture, no jump)
        rows[:, part] += s[:, None] * (q_to[part] - rows[-1, part])
    return rows


def wall_clearance_m(feet: Sequence[Footstep], wall_x_m: float, toe_m: float) -> float:
    """How far the foremost toe of ``feet`` stays behind the plane x = ``wall_x_m`` (m;
    negative: past it). ``toe_m``: the sole's front edge ahead of its frame."""
    return min(wall_x_m - (f.x_m + math.cos(f.yaw_rad) * toe_m) for f in feet)


class _Walk(Phase[TargetOutput]):
    """Walk to the working stance; on arrival hand over to the rise (the walk's last command
    stands this period), on a fall end the run."""

    name = "walk"

    def __init__(self, owner: WalkFirst) -> None:
        self.owner = owner

    def run(self, t_s: float, state: RobotState) -> tuple[TargetOutput, str | None]:
        owner = self.owner
        q, info = owner.walk(t_s, state)
        owner.measure_clearance(state)
        if info.pop("done", False):
            if owner.walk.fell or owner.walk.phase != "walk":  # fell, or stopped: held there
                info["done"] = True
            else:
                owner.q_walked = q
                return (q, info), "rise"
        return (q, info), None


class _Rise(Phase[TargetOutput]):
    """Both feet down, from the walk's last command into the session's posture, then a wait
    until the robot is still."""

    name = "rise"
    runs_at_start = False  # the walk's last command stands in the period it ends

    def __init__(self, owner: WalkFirst) -> None:
        self.owner = owner
        self.t_start_s = 0.0
        self.rows: np.ndarray | None = None  # the rise's joint rows, one per period

    def start(self, t_s: float, state: RobotState) -> None:
        walk = self.owner.walk
        self.t_start_s = t_s
        self.rows = rise_rows(walk.model, self.owner.q_walked, self.owner.q_then,
                              int(round(RISE_S / walk.gait.period_s)))

    def run(self, t_s: float, state: RobotState) -> tuple[TargetOutput, str | None]:
        k = int(round((t_s - self.t_start_s) / self.owner.walk.gait.period_s))
        q = self.rows[min(k, len(self.rows) - 1)]
        still = float(np.max(np.abs(state.dq_rad_s))) < STILL_RAD_S
        if k >= len(self.rows) and (still or t_s - self.t_start_s >= RISE_S + STILL_TIMEOUT_S):
            return (q, {}), "then"
        return (q, {}), None


class _Then(Phase[TargetOutput]):
    """The session's target, with its own clock from the hand-over (it runs in that period)."""

    name = "then"

    def __init__(self, owner: WalkFirst) -> None:
        self.owner = owner

    def start(self, t_s: float, state: RobotState) -> None:
        owner = self.owner
        owner.handover_s = t_s
        owner.then.attach(owner.world, owner.modules, owner.store)

    def run(self, t_s: float, state: RobotState) -> tuple[TargetOutput, str | None]:
        return self.owner.then(t_s - self.owner.handover_s, state), None


class WalkFirst(Target):
    """Walk to the working stance, rise into ``q_then_rad``, then run ``then`` (see the module
    docstring).

    Args:
        walk: the walk (its goal: the working stance relative to the start).
        q_then_rad: the posture ``then`` starts from (its run set-up's start posture).
        then: the session's target.
        wall_x_m: the plane the session's wall will stand in, world x (m; None: no wall).
        frames: the robot's foremost frames whose clearance to it is measured (the soles'
            toes, and the hands or the tool).
    """

    def __init__(self, walk: WalkTarget, q_then_rad: np.ndarray, then: Target,
                 wall_x_m: float | None = None, frames: Sequence[str] = HANDS) -> None:
        self.walk = walk
        self.then = then
        self.q_then = np.asarray(q_then_rad, dtype=float)
        self.wall_x_m = wall_x_m
        toe = walk.model.feet.forward_m + walk.model.feet.length_m / 2
        # frame -> the point of it that comes nearest the wall (homogeneous, frame axes)
        self.points = {"right_sole": np.array([toe, 0.0, 0.0, 1.0]),
                       "left_sole": np.array([toe, 0.0, 0.0, 1.0])}
        self.points.update((f, np.array([0.0, 0.0, 0.0, 1.0])) for f in frames)
        self.log_columns = tuple(dict.fromkeys(
            (*walk.log_columns, "approach.phase_code", *then.log_columns)))
        self.reads = tuple(dict.fromkeys((*walk.reads, T_WORLD_TORSO, *then.reads)))
        self.writes = tuple(dict.fromkeys((*walk.writes, BALANCERS_REST, *then.writes)))
        self.follows = tuple(dict.fromkeys((*walk.follows, *then.follows)))
        self.previous = tuple(dict.fromkeys((*walk.previous, *then.previous)))
        self.phases = Phases([_Walk(self), _Rise(self), _Then(self)])
        self.world: SceneActions | None = None
        self.modules: list[Module] = []
        self.store: Store | None = None
        self.q_walked: np.ndarray | None = None  # the walk's last command
        self.handover_s: float | None = None
        self.wall_clearance_m = math.inf

    name = "walk-first"

    def attach(self, world: SceneActions | None, modules: Sequence[Module],
               store: Store) -> None:
        self.world, self.store = world, store
        self.modules = list(modules)
        self.walk.attach(world, modules, store)
        model = self.walk.model
        self._robot = load_pin_robot(model, floating=True,
                                     urdf_path=model.urdf_path(DRILL_FRAME in self.points))
        self._data = self._robot.model.createData()
        self._frames = [(self._robot.frame_id(f), p) for f, p in self.points.items()]

    @property
    def phase(self) -> str:
        """The phase in force: ``walk``, ``rise`` or ``then``."""
        return self.phases.current.name

    @property
    def then_origin_s(self) -> float:
        """The run's time at which the target handed over to starts its own clock (it sees
        ``t_s - then_origin_s``; 0 before the handover): its summary's times are put on the
        run's clock with it."""
        return self.handover_s or 0.0

    @property
    def inner(self) -> Target:
        """The target driving the robot now."""
        return self.then if self.phase == "then" else self.walk

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        q, info = self.phases(t_s, state)
        phase = self.phases.ran.name
        # what the phase that made this period's command asks of the pipeline
        self.store[BALANCERS_REST] = PHASE_REST[phase]
        if phase != "walk":
            self.store[SUPPORT_PLAN] = None  # both feet down: the estimated soles
            self.store[PHASE_STOP] = None  # a stop reverts the motion again
        return q, info | {"approach.phase_code": float(PHASES.index(phase))}

    def measure_clearance(self, state: RobotState) -> None:
        """The foremost point's distance to the wall's plane: the estimated torso pose, the
        measured joints."""
        if self.wall_x_m is None:
            return
        robot, data = self._robot, self._data
        q = robot.configuration(state.q_rad, self.store[T_WORLD_TORSO])
        pin.framesForwardKinematics(robot.model, data, q)
        foremost = max(float((data.oMf[fid].homogeneous @ p)[0]) for fid, p in self._frames)
        self.wall_clearance_m = min(self.wall_clearance_m, self.wall_x_m - foremost)

    def summary(self) -> dict:
        """The walk's figures for the session's summary (``walk``)."""
        walk = self.walk
        error_m, error_rad = walk.final_error() if walk.final_feet else (math.nan, math.nan)
        distance = math.hypot(*walk.goal_relative[:2])
        walking_s = walk.walking_s
        return {
            "fell": walk.fell, "arrived": self.phase == "then",
            "final_error_mm": 1000 * error_m, "final_error_deg": math.degrees(error_rad),
            "steps": len(walk.steps),
            "average_speed_m_s": distance / walking_s if walking_s > 0 else 0.0,
            "zmp_inside_fraction": (walk.zmp_inside_periods / walk.zmp_periods
                                    if walk.zmp_periods else 0.0),
            "walking_s": walking_s, "handover_s": self.handover_s,
            "wall_clearance_mm": (1000 * self.wall_clearance_m
                                  if math.isfinite(self.wall_clearance_m) else None),
            "start_feet": [f.to_json() for f in walk.start_feet],
            "footsteps": [s.to_json() for s in walk.steps]}


def walk_first(model: RobotModel, then: Target, start_m: tuple[float, float],
               q_then_rad: np.ndarray, wall_distance_m: float | None = None,
               corrections: int = 1, params: WalkingParams | None = None,
               frames: Sequence[str] = HANDS
               ) -> tuple[WalkFirst, RobotModel, np.ndarray, float]:
    """A session that starts ``start_m`` = (x, y) from its working stance (in that stance's
    frame, m) and walks there first.

    Args:
        model: the session's model (its parameter set is kept).
        then: the session's target.
        start_m: where the robot starts, relative to the working stance (m).
        q_then_rad: the session's start posture (its feet set the closing width).
        wall_distance_m: the session's wall, ahead of the working stance's neck (m; None:
            no wall).
        corrections: as for ``hubo walk``.
        params: walking parameters (default the robot file's).
        frames: the hands' or tools' frames whose clearance to the wall is measured.

    Returns:
        (target, the run's model (the robot file's ``walking`` limit set), the start posture,
        a time budget for the walk and the rise (s), to add to the session's).

    Raises:
        InputError: a start too far away, or a walk that would bring a sole within
            WALL_MARGIN_M of the wall's plane.
    """
    x, y = (float(v) for v in start_m)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"the start must be finite numbers, got {start_m}",
                         hint="e.g. 1 m behind the working stance: [-1000, 0] mm")
    walking_model = model.with_limits("walking")
    params = params or walking_params(walking_model)
    q_start, T_world_neck = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    width = stance_width_m(model, q_then_rad)
    goal = Stance(-x, -y, 0.0)  # the working stance, seen from the start (the world's origin)
    here = Stance(0.0, 0.0, 0.0)
    right, left = here.foot("right", params.step_width_m), here.foot("left", params.step_width_m)
    steps = plan_footsteps(right, left, goal, params)
    ends = {s.side: s for s in steps}
    first = "left" if steps and steps[-1].side == "right" else "right"
    steps += closing_steps(ends.get("right", right), ends.get("left", left), goal, width, first)
    wall_x = None if wall_distance_m is None else goal.x_m + wall_distance_m
    if wall_x is not None:
        toe = walking_model.feet.forward_m + walking_model.feet.length_m / 2
        clearance = wall_clearance_m([right, left, *steps], wall_x, toe)
        if clearance < WALL_MARGIN_M:
            raise InputError(
                f"walking from {x * 1000:.0f}, {y * 1000:.0f} mm a sole would come "
                f"{clearance * 1000:.0f} mm from the wall's plane ({WALL_MARGIN_M * 1000:.0f} "
                "mm at least)", hint="start behind the working stance, e.g. [-1000, 0] mm")
    walk = WalkTarget(walking_model, params, (-x, -y, 0.0), q_start, T_world_neck,
                      corrections, end_width_m=width)
    budget = ((1 + corrections) * (params.start_s + params.double_support_s + params.settle_s
                                   + (len(steps) + 4) * params.step_s)
              + RISE_S + STILL_TIMEOUT_S)
    return (WalkFirst(walk, q_then_rad, then, wall_x, frames), walking_model, q_start,
            budget)


def walk_first_setup(setup: RunSetup, then: Target, start_m: tuple[float, float],
                     wall_distance_m: float | None = None, frames: Sequence[str] = HANDS,
                     ) -> tuple[WalkFirst, RunSetup]:
    """A session's run set-up and target with the walk to its working stance first
    (:func:`walk_first`): the target to run, and ``setup`` with the walking limit set, the
    walking start posture and the walk's time added to its duration (if it has one)."""
    target, model, q_start, walk_s = walk_first(setup.model, then, start_m, setup.q_start_rad
                                                if setup.q_start_rad is not None
                                                else home_posture(setup.model),
                                                wall_distance_m, frames=frames)
    duration = None if setup.duration_s is None else setup.duration_s + walk_s
    return target, replace(setup, model=model, q_start_rad=q_start, duration_s=duration)
