"""From a task's steps to a timed plan of tool poses and joint targets, checked before anything
moves (pre-flight).

The stance puts the wall frame W in the stance frame S (see :mod:`hubo_cli.tasks.spec`); each
step becomes Cartesian segments of the tool pose (bit orthogonal to the wall, along S's x):
moves, plunges and retracts with minimum-jerk timing, cuts at constant speed between short
acceleration ramps at each corner. The whole
timeline is then solved period by period exactly as it will run -- the whole-body solver with
the same lift filter, each solution seeded with the previous one -- so the joint targets are
known before the robot starts and pre-flight checks every period's pose, not a sample of them.
A pose whose arm solution is not exact makes pre-flight refuse the task, naming the step and
how far the pose lies beyond the arm's reach.

Steps with a ``thrust_n`` give each period a reference thrust (:attr:`Plan.thrust_n`, ramped
over ``FORCE_RAMP_S`` at each change): the force the tool presses into the wall with, along
S's x. The waist's CoM shift plans for it (the multi-layer paper's eq. 6: the wall pushes the
hand back with the task's largest thrust).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hubo_cli.errors import ConfigError
from hubo_cli.kinematics.interpolate import PoseSegment, segment_duration, trapezoid_timing
from hubo_cli.kinematics.wholebody import LiftFilter, WholeBody
from hubo_cli.model import RobotModel
from hubo_cli.motion.limits import JointLimits
from hubo_cli.posture import home_posture
from hubo_cli.tasks.cut_lag import CutLag, lagging_cuts
from hubo_cli.tasks.moves import check_moves, in_wall
from hubo_cli.tasks.spec import Step, TaskSpec
from hubo_cli.tasks.too_fast import TooFast, too_fast_steps
from hubo_cli.tasks.tool import tool_front_m

EDGE_NONE, EDGE_HORIZONTAL, EDGE_VERTICAL = 0, 1, 2
EDGE_NAMES = {EDGE_HORIZONTAL: "horizontal", EDGE_VERTICAL: "vertical"}


@dataclass(frozen=True)
class Placement:
    """Where the work is.

    Attributes:
        wall_distance_m: neck (home) to wall face along x (m).
        centre_m: (y, z) of the wall frame's origin in S (m).
        working_height_m: the tool height in the neck frame the legs keep (m): they crouch
            for what lies lower (paper III-A).
        auto: the placement came from the workspace search.
        room_m: auto: how far the whole task could shift sideways and stay reachable (m);
            None when the search found no placement (pre-flight then says what misses).
        shift_m: the waist's shift forward over the feet for the whole task (m, CoM control;
            the auto wall distance includes it, so the arm meets the work where the map found
            it reachable).
        shift_per_force_m_n: how far that shift moves per newton of hand force along S's x
            (m/N, eq. 6 at the task's middle height; 0 without CoM control): the run leans
            into the force the hand really meets (:mod:`hubo_cli.control.reference_force`).
    """

    wall_distance_m: float
    centre_m: tuple[float, float]
    working_height_m: float
    auto: bool = False
    room_m: float | None = None
    shift_m: float = 0.0
    shift_per_force_m_n: float = 0.0

    def T_S_W(self) -> np.ndarray:
        """The wall frame in the stance frame (4x4, m): a translation."""
        T = np.eye(4)
        T[:3, 3] = (self.wall_distance_m, *self.centre_m)
        return T

    def to_json(self) -> dict:
        return {"wall_distance_mm": self.wall_distance_m * 1000,
                "centre_mm": [v * 1000 for v in self.centre_m],
                "working_height_mm": self.working_height_m * 1000, "auto": self.auto,
                "room_mm": None if self.room_m is None else self.room_m * 1000,
                "com_shift_mm": self.shift_m * 1000}


@dataclass(frozen=True)
class Miss:
    """A pose pre-flight could not reach.

    Attributes:
        step: the step it belongs to.
        t_s: its time in the plan (s).
        point_W_m: the tool position in the wall frame (m).
        miss_m: how far it lies beyond the reach along the line from the work centre (m);
            None when the work centre itself is out of reach.
        status: the arm's IK status there.
        legs_lag: the pose is reachable, but the legs cannot get the body there in time.
    """

    step: Step
    t_s: float
    point_W_m: np.ndarray
    miss_m: float | None
    status: str
    legs_lag: bool = False

    def message(self) -> str:
        y, z, depth = self.point_W_m[1] * 1000, self.point_W_m[2] * 1000, self.point_W_m[0] * 1000
        where = f"y {y:+.0f} mm, z {z:+.0f} mm, depth {depth:+.1f} mm"
        if self.legs_lag:
            return (f"{self.step.label} ({self.step.kind}): at {where} the legs cannot lower or "
                    f"raise the body fast enough (at most {LEGS_SPEED_M_S * 1000:.0f} mm/s, "
                    f"accelerating at {LEGS_ACCEL_M_S2 * 1000:.0f} mm/s^2, "
                    f"{FORCE_LEGS_ACCEL_M_S2 * 1000:.0f} mm/s^2 in a task that presses)")
        if self.miss_m is None:
            return (f"{self.step.label} ({self.step.kind}): the tool pose at {where} is out of "
                    f"reach, and so is the work centre")
        return (f"{self.step.label} ({self.step.kind}): the tool pose at {where} is out of "
                f"reach by {self.miss_m * 1000:.0f} mm")


@dataclass(frozen=True)
class UnguidedPress:
    """A drill that presses with no depth guide on its bit: its largest thrust and how far the
    hand yields (the most the thrust can drive the bit past the plan)."""

    thrust_n: float
    yield_m: float

    def message(self) -> str:
        return (f"the drill presses with {self.thrust_n:g} N (thrust_n) but its bit has no "
                "depth guide (scene.cutting.guide_depth_m) to rest on the face: the thrust "
                f"drives it through the wall, up to {self.yield_m * 1000:g} mm past the plan, "
                "and the cut may miss the wall")


@dataclass
class Preflight:
    """Pre-flight's verdict: ``ok`` when every pose of every step is exactly reachable and the
    arm follows every cut (``lagging``: the cuts it would lag behind by more than a cut may
    miss, :mod:`hubo_cli.tasks.cut_lag`).

    ``too_fast`` names the steps whose joint targets move faster or accelerate harder than the
    joints' limits (:mod:`hubo_cli.tasks.too_fast`): the pipeline keeps the robot within them,
    so it lags behind the path there (``warnings``), but nothing unsafe is commanded.

    ``unguided`` (a warning too): a drill that presses (``thrust_n``) with no depth guide on
    its bit (``scene.cutting.guide_depth_m``) to rest on the face, so the thrust drives the
    bit through the wall as far as the hand yields.
    """

    misses: list[Miss]
    checked_poses: int
    too_fast: list[TooFast] = field(default_factory=list)
    lagging: list[CutLag] = field(default_factory=list)
    unguided: UnguidedPress | None = None

    @property
    def ok(self) -> bool:
        return not self.misses and not self.lagging

    @property
    def warnings(self) -> list[str]:
        """The steps that ask more than the joints' limits, and a drill pressed with no depth
        guide, one line each."""
        lines = [f"{t.message()}: the robot will lag behind the path there"
                 for t in self.too_fast]
        if self.unguided is not None:
            lines.append(self.unguided.message())
        return lines

    def worst_per_step(self) -> list[Miss]:
        """One miss per failing step: the farthest out."""
        worst: dict[int, Miss] = {}
        for miss in self.misses:
            best = worst.get(miss.step.number)
            if best is None or (miss.miss_m or np.inf) > (best.miss_m or np.inf):
                worst[miss.step.number] = miss
        return [worst[k] for k in sorted(worst)]


@dataclass
class Plan:
    """The timed plan (after the first, joint-space move), one row per control period.

    Attributes:
        spec: the task.
        placement: the wall and work frame.
        dt_s: the period (s).
        q_first_rad: joint target of the first move (reached in joint space from the start).
        T_first_S: the tool pose it reaches (4x4, in S, m).
        t_s: (N,) plan time (s) from the end of the first move.
        step_index: (N,) the step each period belongs to (index into spec.steps).
        goal_S_m: (N, 3) the commanded tool position in S (m).
        q_rad: (N, n_joints) the joint targets.
        cutting: (N,) the tool is cutting (a follow step, bit in the wall).
        edge: (N,) EDGE_HORIZONTAL / EDGE_VERTICAL while cutting, else EDGE_NONE.
        step_times_s: per step (start, end) plan time (s); the first step's is (0, 0).
        preflight: the reachability verdict.
        body: the whole-body solver (and so the model and tool) the plan was made with; the
            run uses the same one.
        thrust_n: (N,) the reference thrust: the force the tool presses into the wall with,
            along S's x (N; 0: position control).
    """

    spec: TaskSpec
    placement: Placement
    dt_s: float
    q_first_rad: np.ndarray
    T_first_S: np.ndarray
    t_s: np.ndarray
    step_index: np.ndarray
    goal_S_m: np.ndarray
    q_rad: np.ndarray
    cutting: np.ndarray
    edge: np.ndarray
    step_times_s: list[tuple[float, float]]
    preflight: Preflight
    body: WholeBody
    thrust_n: np.ndarray | None = None

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1]) if len(self.t_s) else 0.0

    @property
    def has_force(self) -> bool:
        """Some step presses with a thrust (the run needs force control)."""
        return self.thrust_n is not None and bool(np.any(self.thrust_n > 0))

    def hand_force_S_n(self, k: int) -> np.ndarray:
        """The force (N, in S) the wall should exert on the tool at plan row ``k``."""
        return np.array([-float(self.thrust_n[k]), 0.0, 0.0])


PLAN_MAX_S = 1800.0  # a task's whole timeline (s): longer is a typo (and would not fit memory)


def _seconds(t_s: float) -> str:
    """A duration in a message: ``12,345`` s, or ``1.5e+12`` beyond a million seconds."""
    return f"{t_s:,.0f}" if t_s < 1e6 else f"{t_s:.3g}"
LEGS_SPEED_M_S = 0.06  # the lift's speed limit in tasks (m/s): the knees stay within theirs
LEGS_ACCEL_M_S2 = 0.05  # and its acceleration limit (m/s^2), within the knees' 0.6 rad/s^2
CUT_ACCEL_M_S2 = 0.05  # the bit's acceleration at the ends of each cut edge (joints in limits)
LEGS_TIME_CONSTANT_S = 0.05
# ... and under force control the lift's acceleration limit (m/s^2): a lift that ends gently. The
# trajectory generator lags the legs as they lift (not in their own proportions: the torso
# pitches ~2 mrad); when the lift stops that lag goes and the torso swings ~4 mrad, as fast as
# the lift decelerates: at 0.05 m/s^2 26 mrad/s, faster than the arm's correction follows, and
# the bit pressed at 3 N came off the face at the cut's top-right corner (0 N, then 5.6 N). At
# 0.01 m/s^2 the lift stops within 1 s and 10 mm/s lags its goal by 5.4 mm (the arm takes it,
# LIFT_MARGIN_M; cut-rectangle-force still plans at 30 mm/s, not at 40, where main's limit
# plans at 60). Position-only plans keep the brisker limit (docs/history/impedance.md)
FORCE_LEGS_ACCEL_M_S2 = 0.01
LIFT_MARGIN_M = 0.01  # the arm's vertical room kept around the working height (legs lag)
# the legs keep the CoM over the soles' centre (WholeBody's CoM control). With the torso
# correction holding the bit in the world it costs the hole little and buys the capture point
# 20 mm: default cut, support margin 101 vs 81 mm, hole RMS 1.36 vs 1.29 mm, tilt 0.26 vs 0.25 deg
COM_CONTROL = True
FORCE_RAMP_S = 0.5  # a step's thrust is reached (or let go) linearly over this time (s)
# the auto placement keeps a pressing step's poses reachable this much deeper and shallower:
# force control moves the tool along the bit to where the wall really is
FORCE_REACH_M = 0.025


def place(spec: TaskSpec, model: RobotModel) -> Placement:
    """Resolve the stance's ``auto`` parts with the workspace map (tool orthogonal to the wall).

    The legs keep the tool at the working height in the neck frame and crouch for everything
    lower, so the task's highest point is cut standing tall and the arm sees every pose at the
    working height. The search runs over the map's masks: for each wall distance and working
    height, the lateral positions where every sampled pose of the task (cut, approach and
    retract, each within ``LIFT_MARGIN_M`` vertically) is reachable; it keeps the one with the
    most room sideways and centres the task in that room.
    """
    from hubo_cli.workspace.maps import compute_map

    stance = spec.stance
    T_first, pieces = _pieces(spec, np.eye(4), tool_front_m(stance.tool, model))
    samples = _sample_positions(T_first, pieces)  # in W: (depth, y, z)
    if presses(spec):  # force control may go find the wall
        pressed = _sample_positions(T_first, [p for p in pieces
                                              if spec.steps[p.step].thrust_n > 0])
        samples = np.vstack([samples] + [pressed + (d, 0.0, 0.0)
                                         for d in (-FORCE_REACH_M, FORCE_REACH_M)])
    top_W = float(samples[:, 2].max())
    if stance.wall_distance_m is not None and stance.centre_m is not None:
        return Placement(stance.wall_distance_m, stance.centre_m, stance.centre_m[1] + top_W)
    wmap = compute_map(stance.arm, stance.tool, "wall", refine=False, cache=True)
    g = wmap.grid
    reach = wmap.masks != 0                     # (nx, nz, ny), any branch
    res = g.resolution_m
    di = np.round(samples[:, 0] / res).astype(int)
    dj = np.round(samples[:, 1] / res).astype(int)
    offsets = np.unique(np.stack([di, dj], 1), axis=0)
    m = int(round(LIFT_MARGIN_M / res))
    nx, nz, ny = reach.shape
    # a band of rows around each working height, all reachable
    band = np.ones((nx, nz, ny), dtype=bool)
    for dk in range(-m, m + 1):
        band[:, max(0, -dk):nz - max(0, dk)] &= reach[:, max(0, dk):nz + min(0, dk)]
    band[:, :m] = band[:, nz - m:] = False
    xs = range(nx) if stance.wall_distance_m is None else [
        int(np.argmin(np.abs(g.x_m - stance.wall_distance_m)))]
    best = None
    for i in xs:
        ok = np.ones((nz, ny), dtype=bool)
        for a, b in offsets:
            if not 0 <= i + a < nx:
                ok[:] = False
                break
            shifted = np.zeros((nz, ny), dtype=bool)
            lo, hi = max(0, -b), min(ny, ny - b)
            if lo >= hi:  # the task is wider than the map: no lateral position fits
                ok[:] = False
                break
            shifted[:, lo:hi] = band[i + a, :, lo + b:hi + b]
            ok &= shifted
        if stance.centre_m is not None:  # only the given centre's row and column
            keep = np.zeros_like(ok)
            k = int(np.argmin(np.abs(g.z_m - (stance.centre_m[1] + top_W))))
            j = int(np.argmin(np.abs(g.y_m - stance.centre_m[0])))
            keep[k, j] = ok[k, j]
            ok = keep
        for k in np.nonzero(ok.any(axis=1))[0]:
            start, length = _longest_run(ok[k])
            if best is None or length > best[0]:
                best = (length, i, k, start)
    if best is None:
        return _fallback(spec, wmap, top_W)
    length, i, k, start = best
    y_c = float(g.y_m[start] + (length - 1) * res / 2)
    if stance.centre_m is not None:
        y_c = stance.centre_m[0]
    height = float(g.z_m[k])
    found = Placement(float(g.x_m[i]), (y_c, height - top_W), height, True, (length - 1) * res)
    return _with_com_shift(spec, model, found) if stance.wall_distance_m is None else found


def _with_com_shift(spec: TaskSpec, model: RobotModel, placement: Placement) -> Placement:
    """The placement with the waist's CoM shift (WholeBody's CoM control) for the whole task,
    and the wall moved along x by it, so the arm meets the work where the map (in the neck
    frame) found it reachable.

    The steady shift changes with the legs' crouch (about 30 mm over a 10 cm tall cut), more
    than the arm's depth of reach allows, so the task keeps one shift: the middle of the steady
    shifts at its highest and lowest poses. The balance point then stays within half that range
    of the soles' centre instead of ahead of it by the arm's whole moment."""
    if not COM_CONTROL:
        return placement
    limb = spec.stance.limb
    body = WholeBody(model, {limb: spec.stance.tool}, placement.working_height_m,
                     com_control=True)
    T_first, pieces = _pieces(spec, placement.T_S_W(),
                              tool_front_m(spec.stance.tool, model))
    samples = _sample_positions(T_first, pieces)
    thrust = max(step.thrust_n for step in spec.steps)
    forces = {limb: np.array([-thrust, 0.0, 0.0])} if thrust > 0 else None  # eq. 6
    shifts = []
    for z in (samples[:, 2].max(), samples[:, 2].min()):
        T = T_first.copy()
        T[2, 3] = z
        shifts.append(body.solve({limb: T}, home_posture(model),
                                 lift_m=body.lift_for({limb: T}), hand_forces_n=forces).shift_m)
    shift = float(np.mean(shifts))
    per_force = 0.0
    if forces is not None:  # the slope of eq. 6's shift at the middle height, +-1 N
        T = T_first.copy()
        T[2, 3] = 0.5 * (samples[:, 2].max() + samples[:, 2].min())
        lift = body.lift_for({limb: T})
        ends = [body.solve({limb: T}, home_posture(model), lift_m=lift,
                           hand_forces_n={limb: forces[limb] + (f, 0.0, 0.0)}).shift_m
                for f in (-1.0, 1.0)]
        per_force = 0.5 * (ends[1] - ends[0])
    return Placement(placement.wall_distance_m + shift, placement.centre_m,
                     placement.working_height_m, True, placement.room_m, shift, per_force)


def _fallback(spec: TaskSpec, wmap, top_W: float) -> Placement:
    """No placement reaches everything: the map's largest rectangle, for pre-flight to judge."""
    rect = wmap.best_rectangle
    distance = spec.stance.wall_distance_m or rect.wall_distance_m
    y_c, z_c = 0.5 * (rect.y_min_m + rect.y_max_m), 0.5 * (rect.z_min_m + rect.z_max_m)
    return Placement(float(distance), (y_c, z_c - top_W), z_c, True, None)


def _longest_run(row: np.ndarray) -> tuple[int, int]:
    """(start, length) of the longest run of True."""
    best_start, best_len, start = 0, 0, None
    for j, v in enumerate(np.append(row, False)):
        if v and start is None:
            start = j
        elif not v and start is not None:
            if j - start > best_len:
                best_start, best_len = start, j - start
            start = None
    return best_start, best_len


def _sample_positions(T_first: np.ndarray, pieces: list[_Piece], step_m: float = 0.0025
                      ) -> np.ndarray:
    """Tool positions along the plan (every ``step_m``), in the frame the pieces were made in."""
    points = [T_first[:3, 3]]
    for piece in pieces:
        a, b = piece.segment.T_start[:3, 3], piece.segment.T_end[:3, 3]
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step_m)))
        points += [a + (b - a) * s for s in np.linspace(0.0, 1.0, n + 1)]
    return np.array(points)


def tool_pose(T_S_W: np.ndarray, y_m: float, z_m: float, depth_m: float) -> np.ndarray:
    """T_S_E for the tool at (y, z) of the wall plane, ``depth_m`` past the face, bit along x."""
    T = np.eye(4)
    T[:3, 3] = T_S_W[:3, 3] + (depth_m, y_m, z_m)
    return T


@dataclass(frozen=True)
class _Piece:
    segment: PoseSegment
    step: int
    cutting: bool
    edge: int


def _pieces(spec: TaskSpec, T_S_W: np.ndarray, front_m: float
            ) -> tuple[np.ndarray, list[_Piece]]:
    """The first move's end pose and the Cartesian pieces of the following steps. A follow
    cuts when the tool's front (``front_m`` past its depth reference) is past the wall face, or
    when it presses with a thrust (the hand yields along the bit until the tool meets the
    face): review 28's slot planned with the bit's middle 10 mm before the face cut the wall
    with its flutes and ran without a cut's checks."""
    steps = spec.steps
    pieces: list[_Piece] = []

    def next_path_start(k: int) -> tuple[float, float]:
        for later in steps[k + 1:]:
            if later.kind == "follow":
                return later.points_m[0]
        return (0.0, 0.0)

    first = steps[0]
    yz = first.to_m if first.to_m is not None else next_path_start(0)
    depth = first.depth_m
    T_first = tool_pose(T_S_W, *yz, depth)
    T_now = T_first
    for k, step in enumerate(steps[1:], start=1):
        if step.kind == "wait":
            pieces.append(_Piece(PoseSegment(T_now, T_now, step.duration_s), k, False, EDGE_NONE))
            continue
        if step.kind == "follow":
            cutting = in_wall(depth, front_m) or step.thrust_n > 0
            for a, b in zip(step.points_m[:-1], step.points_m[1:], strict=True):
                T_a, T_b = tool_pose(T_S_W, *a, depth), tool_pose(T_S_W, *b, depth)
                if np.linalg.norm(T_now[:3, 3] - T_a[:3, 3]) > 1e-9:  # join the path's start
                    pieces.append(_line(T_now, T_a, step, k, cutting))
                pieces.append(_line(T_a, T_b, step, k, cutting))
                T_now = T_b
            yz = step.points_m[-1]
            continue
        if step.kind == "move":
            yz = step.to_m if step.to_m is not None else next_path_start(k)
        depth = step.depth_m
        T_end = tool_pose(T_S_W, *yz, depth)
        speed = step.speed_m_s if step.speed_m_s is not None else None
        duration = (step.duration_s if speed is None
                    else segment_duration(T_now, T_end, speed))
        pieces.append(_Piece(PoseSegment(T_now, T_end, duration), k, False, EDGE_NONE))
        T_now = T_end
    return T_first, pieces


def _line(T_a: np.ndarray, T_b: np.ndarray, step: Step, k: int, cutting: bool) -> _Piece:
    """One straight edge of a path at the step's speed, speeding up and slowing down at the
    step's acceleration (default ``CUT_ACCEL_M_S2``) at its ends (the bit stops at each corner,
    turns, and goes on)."""
    d = T_b[:3, 3] - T_a[:3, 3]
    duration, ramp = trapezoid_timing(float(np.linalg.norm(d)), step.speed_m_s,
                                      step.accel_m_s2 or CUT_ACCEL_M_S2)
    edge = EDGE_HORIZONTAL if abs(d[1]) >= abs(d[2]) else EDGE_VERTICAL
    return _Piece(PoseSegment(T_a, T_b, duration, profile="trapezoid", ramp_s=ramp), k,
                  cutting, edge if cutting else EDGE_NONE)


def presses(spec: TaskSpec) -> bool:
    """Some step of the task presses with a thrust (its plan runs under force control)."""
    return any(step.thrust_n > 0 for step in spec.steps)


def lift_filter(spec: TaskSpec) -> LiftFilter:
    """The plan's lift filter (not yet reset): it ends gently under force control."""
    return LiftFilter(LEGS_SPEED_M_S, LEGS_TIME_CONSTANT_S,
                      FORCE_LEGS_ACCEL_M_S2 if presses(spec) else LEGS_ACCEL_M_S2)


def check_duration(spec: TaskSpec) -> float:
    """The task's timeline (s), refused beyond :data:`PLAN_MAX_S`; worked out from the steps'
    lengths and speeds alone (a placement moves every pose alike), so it costs no pre-flight:
    ``hubo sweep`` checks it for every combination of values before any run.

    Raises:
        ConfigError: too long; the message names the longest step (exit 2).
    """
    _, pieces = _pieces(spec, np.eye(4), front_m=0.0)  # durations: no cutting flags read
    total_s = float(sum(p.segment.duration_s for p in pieces))
    if not total_s <= PLAN_MAX_S:
        step_s = np.zeros(len(spec.steps))  # a step's pieces (a rectangle's four sides) summed
        np.add.at(step_s, [p.step for p in pieces], [p.segment.duration_s for p in pieces])
        slowest = int(np.argmax(step_s))
        raise ConfigError(f"the task would take {_seconds(total_s)} s ("
                          f"{spec.steps[slowest].label} alone "
                          f"{_seconds(step_s[slowest])} s); the limit is "
                          f"{PLAN_MAX_S:g} s", path=str(spec.path),
                          hint="raise the speeds or shorten the waits")
    return total_s


def make_plan(spec: TaskSpec, model: RobotModel, placement: Placement | None = None) -> Plan:
    """Lay out the task in time and solve every period (see the module docstring).

    Args:
        spec: a task with steps.
        model: the robot model.
        placement: where the work is (default: resolved from the task's stance).
    """
    check_duration(spec)  # before the placement: no workspace map for a typo
    check_moves(spec, model)
    placement = placement or place(spec, model)
    T_S_W = placement.T_S_W()
    limb = spec.stance.limb
    body = WholeBody(model, {limb: spec.stance.tool}, placement.working_height_m)
    shift = placement.shift_m
    dt = model.control_period_s
    T_first, pieces = _pieces(spec, T_S_W, tool_front_m(spec.stance.tool, model))

    misses: list[Miss] = []
    lift = lift_filter(spec)
    lift.reset(body.lift_for({limb: T_first}))
    first = body.solve({limb: T_first}, home_posture(model), lift_m=lift.lift_m, shift_m=shift)
    if first.arms[limb].status != "exact":
        misses.append(_miss(body, limb, spec.steps[0], 0.0, T_first, T_S_W, lift.lift_m,
                            first.arms[limb].status, shift))

    starts = np.cumsum([0.0] + [p.segment.duration_s for p in pieces])
    n = int(np.floor(starts[-1] / dt + 1e-9)) + 1
    t = np.arange(n) * dt
    piece_of = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, max(len(pieces) - 1, 0))
    q = np.empty((n, len(model.joint_names)))
    goal = np.empty((n, 3))
    step_index = np.zeros(n, dtype=np.int64)
    cutting = np.zeros(n, dtype=bool)
    edge = np.zeros(n, dtype=np.int8)
    q_prev = first.q_rad
    failed_steps: set[int] = set()
    for i in range(n):
        piece = pieces[piece_of[i]] if pieces else None
        T = T_first if piece is None else piece.segment.at(t[i] - starts[piece_of[i]])
        lift_m = lift.step(body.lift_for({limb: T}), dt)
        solved = body.solve({limb: T}, q_prev, lift_m=lift_m, shift_m=shift)
        status = solved.arms[limb].status
        if status != "exact" and piece is not None:
            step = spec.steps[piece.step]
            # keep the list short: every 0.1 s of a failing stretch, the rest are alike
            if piece.step not in failed_steps or i % 20 == 0:
                misses.append(_miss(body, limb, step, float(t[i]), T, T_S_W, lift_m, status,
                                    shift))
                failed_steps.add(piece.step)
        q_prev = solved.q_rad
        q[i] = solved.q_rad
        goal[i] = T[:3, 3]
        if piece is not None:
            step_index[i] = piece.step
            cutting[i] = piece.cutting
            edge[i] = piece.edge
    too_fast = too_fast_steps(spec, model, q, step_index, goal, dt, CUT_ACCEL_M_S2)
    arm = model.limb_slice(limb)
    lagging = lagging_cuts(spec.steps, body.arms[limb],
                           JointLimits.from_model(model).subset(np.arange(arm.start, arm.stop)),
                           q[:, arm], goal, step_index, dt, CUT_ACCEL_M_S2)
    thrust = _ramped(np.array([spec.steps[k].thrust_n for k in step_index]),
                     int(round(FORCE_RAMP_S / dt)))
    pressed_n = max(step.thrust_n for step in spec.steps)
    guided = spec.scene.cutting.guide_depth_m > 0.0
    unguided = (UnguidedPress(pressed_n, model.impedance_max_offset_m)
                if spec.stance.tool == "drill" and pressed_n > 0.0 and not guided else None)
    step_times = [(0.0, 0.0)]
    for k in range(1, len(spec.steps)):
        mine = [j for j, p in enumerate(pieces) if p.step == k]
        step_times.append((float(starts[mine[0]]), float(starts[mine[-1] + 1])) if mine
                          else (step_times[-1][1],) * 2)
    return Plan(spec, placement, dt, first.q_rad, T_first, t, step_index, goal, q, cutting, edge,
                step_times, Preflight(misses, n + 1, too_fast, lagging, unguided), body, thrust)


def _ramped(values: np.ndarray, periods: int) -> np.ndarray:
    """``values`` with each change spread linearly over the following ``periods`` rows (a
    causal moving average; zero before the start: the first move presses on nothing)."""
    if periods <= 1 or not values.any():
        return values.astype(float)
    padded = np.concatenate([np.zeros(periods - 1), values]).astype(float)
    return np.convolve(padded, np.ones(periods) / periods, mode="valid")


def _reachable(body: WholeBody, limb: str, T: np.ndarray, lift_m: float | None = None,
               shift_m: float = 0.0) -> bool:
    """Exactly reachable with this lift (default: the legs at their steady lift for T) and
    the waist's CoM shift."""
    lift = body.lift_for({limb: T}) if lift_m is None else lift_m
    return body.solve({limb: T}, None, lift_m=lift, shift_m=shift_m).arms[limb].status == "exact"


MISS_BISECTIONS = 14  # the miss to 1/16,384 of the centre-to-pose distance: < 0.05 mm


def _miss(body: WholeBody, limb: str, step: Step, t_s: float, T: np.ndarray,
          T_S_W: np.ndarray, lift_m: float, status: str, shift_m: float = 0.0) -> Miss:
    """How far T lies beyond the reach: bisection along the line from the work centre (at the
    same depth) to T, the legs at their steady lift for each probe. A pose that is reachable
    that way but not with the lift of its moment is one the legs are too slow for."""
    point_W = T[:3, 3] - T_S_W[:3, 3]
    if _reachable(body, limb, T, shift_m=shift_m):
        return Miss(step, t_s, point_W, 0.0, status, legs_lag=True)
    centre = T.copy()
    centre[1:3, 3] = T_S_W[1:3, 3]
    if not _reachable(body, limb, centre, shift_m=shift_m):
        return Miss(step, t_s, point_W, None, status)
    inside, outside = 0.0, 1.0
    for _ in range(MISS_BISECTIONS):
        mid = 0.5 * (inside + outside)
        probe = T.copy()
        probe[:3, 3] = centre[:3, 3] + mid * (T[:3, 3] - centre[:3, 3])
        if _reachable(body, limb, probe, shift_m=shift_m):
            inside = mid
        else:
            outside = mid
    return Miss(step, t_s, point_W, float((1 - inside) * np.linalg.norm(T[:3, 3]
                                                                        - centre[:3, 3])), status)
