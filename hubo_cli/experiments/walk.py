"""The walking experiment: the simulated robot walks to a goal stance through the full
pipeline (trajectory generator, capture-point monitor, emergency stoppers, collision detector,
limiter) and we measure where it arrived, how fast, and where its ZMP was.

The walk acts on the estimate; where it arrived is measured here, after the run, against the
simulator's truth in the log (the torso's true pose and the measured joints), beside where the
estimate put it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.log import LogData
from hubo_cli.control.operator import OperatorKeys
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.stop_choice import ActiveStops
from hubo_cli.control.target import Target, TargetOutput
from hubo_cli.errors import HuboError, InputError, quoted
from hubo_cli.falls import FALL_TILT_DEG
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.scene import SceneActions
from hubo_cli.session import RunObserver, RunSetup, run
from hubo_cli.state import RobotState
from hubo_cli.walking.body import SIDE_LEG, walking_posture
from hubo_cli.walking.footsteps import Stance, stance_of
from hubo_cli.walking.params import DEFAULT_GAIT, WalkingParams, walking_params
from hubo_cli.walking.stabilizer import StabilizerGains
from hubo_cli.walking.support import footstep_of
from hubo_cli.walking.target import WalkTarget
from hubo_cli.walking.toe_heel import ToeHeelParams

MAX_GOAL_M = 10.0
PUSH_S = 0.2  # a push lasts this long (as ``hubo sim --push``)
FINAL_ROWS = 20  # the final stance: the mean over the log's last rows (encoder noise averages)
DEFAULT_GAINS = StabilizerGains()


@dataclass
class WalkResult:
    """What a walk showed.

    Attributes:
        fell: the torso fell (:func:`hubo_cli.falls.has_fallen`, on the estimated torso).
        fell_truth: the simulator's truth: the torso's largest true tilt since the start
            passed :data:`~hubo_cli.falls.FALL_TILT_DEG` (None without a simulator). A report's
            figure: where it disagrees with ``fell`` (a sensor that lied) both are said.
        max_true_tilt_deg: that largest true tilt (deg; None without a simulator).
        touchdowns_early: swings ended where the foot was pushed onto the floor early
            (:meth:`~hubo_cli.walking.target.WalkTarget._touched_early`).
        liftoff_waits: lift-offs the walk's timeline waited at, the soles measured carrying
            too little of the body's weight
            (:meth:`~hubo_cli.walking.target.WalkTarget._unloaded_liftoff`).
        landing_waits: landings whose double support waited, after a push, for the landed
            foot to carry (:meth:`~hubo_cli.walking.target.WalkTarget._unloaded_landing`).
        reaims: the plan's last landings re-aimed from the estimated stance sole at their
            lift-offs (:meth:`~hubo_cli.walking.target.WalkTarget._reaim`).
        final_error_mm, final_error_deg: the final stance (midway between the soles) from the
            goal, as the simulator's truth has it (:func:`true_final_error`; the estimate's
            where the log has no true torso position).
        estimated_final_error_mm, estimated_final_error_deg: the same as the estimate has it
            (what the walk's corrections act on).
        steps: footsteps planned (all taken unless the run ended early).
        gait: the robot file's gait the walk took its parameters from (``custom``: given).
        average_speed_m_s: the goal's distance over the time from the start to the last
            step's end; None for a walk a stop ended short of its goal.
        zmp_inside_fraction: of the periods with a sole in contact, the share whose ZMP lay
            inside the convex hull of the soles in contact by at least 1 mm (the ground cannot
            push outside the hull: a ZMP on its edge means a sole tipping). The ZMP, the soles
            and the contacts are the estimate's (:mod:`hubo_cli.estimation.keys`).
        ended: how the loop ended.
        interrupt_stop: how the walk stopped after Ctrl-C, SIGTERM or a log failure in
            mid-walk (:attr:`~hubo_cli.control.loop.LoopResult.interrupt_stop`: ``stood``, or
            how it fell back to the brake); None without one.
        run_dir: the run folder.
        failure: the error the run ended with (:meth:`~hubo_cli.control.loop.LoopResult.failure`:
            e.g. the robot's state lost, exit 3), None if none.
        files: the files written into the run folder (the summary's ``files``, plots included).
        unplayed: the pushes and stops the walk ended before (their time came after its end).
    """

    fell: bool
    stopped_s: float | None
    stood: bool
    shifts: int
    touchdowns_early: int
    liftoff_waits: int
    landing_waits: int
    reaims: int
    final_error_mm: float
    final_error_deg: float
    estimated_final_error_mm: float
    estimated_final_error_deg: float
    steps: int
    average_speed_m_s: float | None
    zmp_inside_fraction: float
    walking_s: float
    ended: str
    estop_events: int
    footsteps: list[dict]
    gait: str
    run_dir: Path
    failure: HuboError | None = None
    fell_truth: bool | None = None
    max_true_tilt_deg: float | None = None
    files: tuple[str, ...] = ()
    interrupt_stop: str | None = None
    unplayed: tuple[Disturbance, ...] = ()

    def summary(self) -> dict:
        """The walk's own fields of summary.json (those every run has, ``ended`` and
        ``interrupt_stop`` among them, are :func:`~hubo_cli.session.common_summary`'s)."""
        return {"fell": self.fell, "fell_truth": self.fell_truth,
                "max_true_tilt_deg": self.max_true_tilt_deg,
                "stopped_s": self.stopped_s, "stood": self.stood,
                "shifts": self.shifts, "touchdowns_early": self.touchdowns_early,
                "liftoff_waits": self.liftoff_waits, "landing_waits": self.landing_waits,
                "reaims": self.reaims,
                "final_error_mm": self.final_error_mm,
                "final_error_deg": self.final_error_deg,
                "estimated_final_error_mm": self.estimated_final_error_mm,
                "estimated_final_error_deg": self.estimated_final_error_deg,
                "steps": self.steps, "average_speed_m_s": self.average_speed_m_s,
                "zmp_inside_fraction": self.zmp_inside_fraction, "walking_s": self.walking_s,
                "footsteps": self.footsteps, "gait": self.gait}


def check_goal(goal: tuple[float, float, float]) -> None:
    """Raise InputError unless the goal is finite and within MAX_GOAL_M and half a turn."""
    x, y, yaw = goal
    if not all(math.isfinite(v) for v in goal):
        raise InputError(f"the goal must be finite numbers, got {goal}", hint="e.g. --to 1 0 0")
    if math.hypot(x, y) > MAX_GOAL_M or abs(yaw) > math.pi:
        raise InputError(f"the goal must lie within {MAX_GOAL_M:g} m and +-pi rad, got {goal}",
                         hint="walk there in shorter legs")


def check_walk_driver(driver: str) -> None:
    """Raise InputError for the ideal driver: it has no floor. It stands the robot on
    whichever sole is lower in the torso's frame, and a walk's weight shift (the torso leaning
    0.14 rad) makes that the lifting foot at lift-off: every walk on it, 1 mm or 1 m, stopped
    on the capture point at 1.08 s (round 20, docs/history/safety.md)."""
    if driver == "ideal":
        raise InputError("a walk needs a floor: the ideal driver has none (it stands the robot "
                         "on its lower sole, the lifting one once the weight shifts)",
                         hint="walk on the simulator (--driver sim) or the robot "
                              "(--driver hardware)")


@dataclass(frozen=True)
class Disturbance:
    """What happens to a walk at ``at_s`` (loop time, s): a push on the torso of ``push_n``
    (N) along ``direction`` (world, unit) for PUSH_S (the simulator only), and/or the
    operator's stop (``stop``: as the space key)."""

    at_s: float
    push_n: float = 0.0
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    stop: bool = False


class Disturbed(Target):
    """``walk`` with ``disturbances`` played on it (pushes through the scene, stops as the
    operator's requests); everything else is the walk's."""

    def __init__(self, walk: WalkTarget, disturbances: Sequence[Disturbance]) -> None:
        self.walk = walk
        self.pending = sorted(disturbances, key=lambda d: d.at_s)
        self.name, self.log_columns = walk.name, walk.log_columns
        self.reads, self.writes = walk.reads, walk.writes
        self.follows, self.previous = walk.follows, walk.previous
        self.world: SceneActions | None = None

    def attach(self, world: SceneActions | None, modules, store) -> None:
        if world is None and any(d.push_n for d in self.pending):
            raise InputError("a push needs the simulator", hint="leave out the push")
        self.world, self.store = world, store
        self.walk.attach(world, modules, store)

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        q, info = self.walk(t_s, state)
        while self.pending and t_s >= self.pending[0].at_s - 1e-9:
            event = self.pending.pop(0)
            if event.push_n:
                self.world.push_torso(event.push_n * np.asarray(event.direction, dtype=float),
                                      PUSH_S)
            if event.stop:
                info = info | {"estop": "operator"}
        return q, info


def check_disturbances(push_n: float, direction: tuple[float, float, float], push_at_s: float,
                       stop_at_s: float | None, driver: str) -> list[Disturbance]:
    """``hubo walk --push/--push-at/--stop-at`` as disturbances; InputError for a force
    outside 0..MAX_PUSH_N, a time that is not a finite number >= 0, or a push on another
    driver than the simulator."""
    from hubo_cli.experiments.standing import MAX_PUSH_N

    if not (math.isfinite(push_n) and 0.0 <= push_n <= MAX_PUSH_N):
        raise InputError(f"--push must be a force of 0 to {MAX_PUSH_N:g} N, got {push_n}",
                         hint="e.g. --push 100")
    for name, value in (("--push-at", push_at_s), ("--stop-at", stop_at_s)):
        if value is not None and not (math.isfinite(value) and 0.0 <= value <= 3600.0):
            raise InputError(f"{name} must be a time of 0 to 3600 s, got {value}",
                             hint=f"e.g. {name} 2.5")
    if push_n and driver != "sim":
        raise InputError(f"--push needs the simulator; the {driver} driver's robot is pushed "
                         "by whatever pushes it", hint="leave out --push")
    events = [Disturbance(push_at_s, push_n, direction)] if push_n else []
    if stop_at_s is not None:
        events.append(Disturbance(stop_at_s, stop=True))
    return events


def walk(model: RobotModel, goal: tuple[float, float, float], *,
         params: WalkingParams | None = None, gui: bool = False,
         out: str | Path | None = None, stops: ActiveStops | None = None,
         perturb_seed: int | None = None, corrections: int = 1,
         balance: str = "off", operator: OperatorKeys | None = None,
         live: RunObserver | None = None,
         stabilizer: StabilizerGains | None = DEFAULT_GAINS, toe_heel: bool = False,
         lip_feedback: bool = False, driver: str = "sim",
         driver_options: dict | None = None,
         disturbances: Sequence[Disturbance] = (), gait: str = DEFAULT_GAIT) -> WalkResult:
    """Walk the robot to ``goal`` = (forward m, left m, turn rad) from its stance.

    Args:
        model: the robot model; its ``walking`` limit set is used for the run.
        goal: where the stance (midway between the soles) should end, relative to the start.
        params: walking parameters (default the robot file's).
        gui, out, perturb_seed: as for every run (:class:`~hubo_cli.session.RunSetup`).
        stops: the stop sources the run keeps (None: every soft source; see
            :mod:`hubo_cli.control.stop_choice`).
        corrections: how many times to plan again from where the feet stand when the walk
            ended off the goal (the feet slip a little on every step).
        balance: the standing balancer, ``default``, ``paper`` or ``off`` (``--balance``; its
            reference assumes both feet down and the CoM over them, which walking breaks: off
            by default).
        operator: the operator's keys (space stop, r release, q finish), if any.
        live: the live viewer's publisher (``--live``), if any.
        stabilizer: the walking stabilizer's gains (:mod:`hubo_cli.walking.stabilizer`);
            None walks the pattern open loop.
        toe_heel: walk on toe and heel (the robot file's ``[toe_heel]``,
            :mod:`hubo_cli.walking.gait`); False lands every sole flat.
        lip_feedback: the stabilizer's CoM feedback is the multi-layer paper's (eq. 7-14:
            :class:`~hubo_cli.walking.stabilizer.LipStabilizer`) instead of the TPCC torso
            offset.
        driver, driver_options: the robot's back end and its options (the hardware driver's
            robot must stand in the walking posture: the walk refuses it otherwise, exit 4;
            its log has no truth, so the final error is the estimate's).
        disturbances: pushes and stops played on the walk (:class:`Disturbance`).
        gait: the robot file's gait the walk takes its parameters from when ``params`` is None
            (:func:`~hubo_cli.walking.params.gait_names`: ``normal``, ``fast``).
    """
    check_goal(goal)
    walking_model = model.with_limits("walking")
    if params is not None and gait != DEFAULT_GAIT:
        raise InputError(f"the gait {quoted(gait)} and given parameters: one or the other",
                         hint="pass the gait's parameters changed with params.with_changes")
    gait = gait if params is None else "custom"
    params = params or walking_params(walking_model, gait)
    q_start, T_world_neck = walking_posture(walking_model, params.step_width_m, params.crouch_m)
    if not 0 <= corrections <= 5:
        raise InputError(f"corrections must be 0 to 5, got {corrections}", hint="e.g. 1")
    target = WalkTarget(walking_model, params, goal, q_start, T_world_neck, corrections,
                        stabilizer=stabilizer,
                        toe_heel=ToeHeelParams.from_model(walking_model) if toe_heel else None,
                        lip_feedback=lip_feedback)
    setup = RunSetup(command="walk", model=walking_model, driver=driver,
                     driver_options=driver_options or {}, gui=gui, out=out,
                     safety=SafetyProfile().with_stops(stops).with_balance(balance),
                     q_start_rad=q_start, perturb_seed=perturb_seed, operator=operator,
                     live=live)
    disturbed = Disturbed(target, disturbances)
    done = run(setup, disturbed if disturbances else target)
    estimated_m, estimated_rad = target.final_error()
    true = true_final_error(done.log, walking_model, goal) if target.final_feet else None
    error_m, error_rad = (estimated_m, estimated_rad) if true is None else true
    distance = math.hypot(goal[0], goal[1])
    walking_s = target.walking_s
    true_tilt = done.summary.get("max_torso_tilt_deg")  # the simulator's (None on a robot)
    result = WalkResult(
        fell=target.fell, stopped_s=target.stopped_s,
        stood=target.phase == "stood" and not target.stop_failed,  # failed: braked in place
        shifts=target.shifts, touchdowns_early=target.touchdowns_early,
        liftoff_waits=target.liftoff_waits, landing_waits=target.landing_waits,
        reaims=target.reaims,
        final_error_mm=1000 * error_m,
        final_error_deg=math.degrees(error_rad),
        estimated_final_error_mm=1000 * estimated_m,
        estimated_final_error_deg=math.degrees(estimated_rad), steps=len(target.steps),
        average_speed_m_s=(None if target.stopped_s is not None
                           else distance / walking_s if walking_s > 0 else 0.0),
        zmp_inside_fraction=(target.zmp_inside_periods / target.zmp_periods
                             if target.zmp_periods else 0.0),
        walking_s=walking_s, ended=done.loop.ended,
        estop_events=sum(e["kind"] == "stop" for e in done.summary["estop_events"]),
        footsteps=[s.to_json() for s in target.steps], gait=gait, run_dir=done.run_dir,
        failure=done.loop.failure(done.run_dir),
        interrupt_stop=done.loop.interrupt_stop or None, unplayed=tuple(disturbed.pending),
        fell_truth=None if true_tilt is None else true_tilt > FALL_TILT_DEG,
        max_true_tilt_deg=true_tilt)
    done.save_summary(result.summary())
    plot_footprints(done, target, walking_model)
    if target.toe_heel is not None:
        plot_fig4(done, target)
    result.files = tuple(done.summary["files"])
    return result


def true_final_error(log: LogData, model: RobotModel, goal: tuple[float, float, float],
                     rows: int = FINAL_ROWS) -> tuple[float, float] | None:
    """How far the walk ended from ``goal`` (forward, left, turn from the start stance) as the
    simulator's truth has it: the stances at the start and at the end, each from the torso's
    true pose in the log and the legs' kinematics of the measured joints averaged over
    ``rows`` rows, the end seen from the start (a report's figure: nothing acts on it).
    Distance (m) and heading error (rad); None where the log has no true torso position."""
    T_world_torso = log.poses("torso")
    if len(T_world_torso) < rows or not np.all(np.isfinite(T_world_torso[[0, -1]])):
        return None
    q = log.joints("q")
    start, end = (_true_stance(model, T_world_torso[part], q[part])
                  for part in (slice(0, rows), slice(-rows, None)))
    return arrival_error(start, end, goal)


def arrival_error(start: Stance, end: Stance, goal: tuple[float, float, float]
                  ) -> tuple[float, float]:
    """How far ``end`` is from ``goal`` (forward, left, turn) seen from ``start``: distance (m)
    and heading error (rad)."""
    c, s = math.cos(start.yaw_rad), math.sin(start.yaw_rad)
    forward, left, turn = goal
    aimed = Stance(start.x_m + c * forward - s * left, start.y_m + s * forward + c * left,
                   start.yaw_rad + turn)
    return (math.hypot(end.x_m - aimed.x_m, end.y_m - aimed.y_m),
            abs(math.remainder(end.yaw_rad - aimed.yaw_rad, math.tau)))


def _true_stance(model: RobotModel, T_world_torso: np.ndarray, q: np.ndarray) -> Stance:
    """The stance of the soles that the torso poses and joints (rows) put them in, averaged."""
    feet = {}
    for side, leg in SIDE_LEG.items():
        limb, part = Limb(model, leg), model.limb_slice(leg)
        poses = np.array([T @ limb.fk(q_k[part]) for T, q_k in zip(T_world_torso, q,
                                                                   strict=True)])
        feet[side] = footstep_of(side, poses.mean(axis=0))  # rotations differ by noise only
    return stance_of(feet["right"], feet["left"])


PLOT_NAME = "walk.png"
FIG4_NAME = "toe_heel.png"


def plot_fig4(done, target: WalkTarget) -> None:
    """The multi-layer paper's Fig. 4 for this walk (``toe_heel.png`` in the run folder):
    the soles' CoPs and angles, planned and measured, the ZMP and the CoM along x."""
    from hubo_cli.plots.toe_heel import plot_toe_heel

    log = done.log
    names = [f"walk.{side}_{what}" for side in ("right", "left")
             for what in ("cop_ref_m", "cop_m", "angle_ref_rad", "angle_rad")]
    names += ["walk.zmp_ref_x_m", "walk.zmp_x_m", "walk.com_ref_x_m", "com_x_m"]
    phases = ", ".join(f"{t:g}" for t in target.toe_heel.scaled_to(
        target.params.step_s).phase_s)
    plot_toe_heel(np.asarray(log["t_s"], dtype=float),
                  {name: np.asarray(log[name], dtype=float) for name in names},
                  done.run_dir / FIG4_NAME,
                  title=f"walk to {target.goal_relative}: toe-heel phases (i)-(v) {phases} s")
    done.add_file(FIG4_NAME)
    done.save_summary({})


def plot_footprints(done, target: WalkTarget, model: RobotModel, rows=None) -> None:
    """Footprints with the CoM and ZMP paths (``walk.png`` in the run folder).

    Args:
        done: the finished run.
        target: the walk.
        model: the robot model (its soles).
        rows: the log's rows of the walk (a boolean mask; None: all).
    """
    import numpy as np

    from hubo_cli.plots.walk import plot_walk

    log = done.log

    def columns(x: str, y: str) -> np.ndarray:
        xy = np.column_stack([np.asarray(log[x], dtype=float),
                              np.asarray(log[y], dtype=float)])
        return xy if rows is None else xy[rows]

    footprints = [s.to_json() for s in target.start_feet] + [s.to_json() for s in target.steps]
    plot_walk(footprints, model.feet.sole_corners_m(),
              columns("walk.com_ref_x_m", "walk.com_ref_y_m"), columns("com_x_m", "com_y_m"),
              columns("walk.zmp_ref_x_m", "walk.zmp_ref_y_m"),
              columns("walk.zmp_x_m", "walk.zmp_y_m"), done.run_dir / PLOT_NAME,
              title=f"walk to {target.goal_relative}: footprints, CoM and ZMP")
    done.add_file(PLOT_NAME)
    done.save_summary({})
