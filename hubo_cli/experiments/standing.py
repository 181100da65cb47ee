"""The standing experiment: the simulated robot holds its home posture through the full
pipeline (the ankle balancer of paper III-C unless turned off), optionally pushed once on the
torso, and we watch tilt, feet and falls. It runs on the shared run scaffold
(:mod:`hubo_cli.session`) like every other robot command."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from hubo_cli.control.operator import OperatorKeys
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.stop_choice import ActiveStops
from hubo_cli.control.target import Target
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError, HuboError, InputError, quoted
from hubo_cli.estimation.keys import CONTACT, T_WORLD_SOLES, T_WORLD_TORSO, WRENCHES
from hubo_cli.falls import has_fallen
from hubo_cli.geometry import tilt_rad_of_matrix
from hubo_cli.model import RobotModel, load_model
from hubo_cli.posture import check_stands_in, home_posture
from hubo_cli.scene import SceneActions
from hubo_cli.session import RunObserver, RunResult, RunSetup, run

FLAT_TOLERANCE_DEG = 1.0  # a sole tilted more than this (or without contact) is not flat
# ``hubo sim --push-direction``: the push's world direction by name (x forward, y left)
PUSH_DIRECTIONS = {"forward": (1.0, 0.0, 0.0), "backward": (-1.0, 0.0, 0.0),
                   "left": (0.0, 1.0, 0.0), "right": (0.0, -1.0, 0.0)}


@dataclass
class StandingResult:
    """What a standing run showed (angles in degrees, times in seconds).

    Attributes:
        max_tilt_deg: largest torso tilt from upright (IMU) over the run.
        feet_flat: both soles flat on the floor (within FLAT_TOLERANCE_DEG, in contact) in
            every period.
        fell: the torso fell (:func:`hubo_cli.falls.has_fallen`; the run then ends).
        realtime_factor: simulated seconds per wall-clock second of the loop.
        max_sole_tilt_deg: largest tilt of either sole.
        final_tilt_deg: torso tilt at the end.
        physics_share: fraction of the loop's wall time spent in PyBullet's stepSimulation.
        max_feet_moment_difference_nm: largest |M_right - M_left| of the ankle moments (x, y),
            how unevenly the two feet are loaded (the balancer's compliance evens them out).
        push_direction: world direction of the push (unit vector, x forward, y left).
        max_foot_shift_mm: largest horizontal distance of either sole from where it stood at
            the start (mm), as the estimate has the soles: a foot that stepped (a sole rocking
            on its heel or toe moves it a few mm; a slide is not seen, as on the robot).
        times_s, tilts_deg, feet_moment_difference_nm: traces, one sample per control period.
        failure: the error the run ended with (e.g. the robot's state lost, exit 3), if any.
    """

    duration_s: float
    push_n: float
    balance: bool
    max_tilt_deg: float
    feet_flat: bool
    fell: bool
    realtime_factor: float
    max_sole_tilt_deg: float
    final_tilt_deg: float
    physics_share: float
    simulated_s: float
    max_feet_moment_difference_nm: float = 0.0
    max_foot_shift_mm: float = 0.0
    push_direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    snapshot: Path | None = None
    run_dir: Path | None = None
    times_s: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    tilts_deg: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    feet_moment_difference_nm: np.ndarray = field(default_factory=lambda: np.zeros(0),
                                                  repr=False)
    failure: HuboError | None = None

    def summary(self) -> dict:
        """The headline numbers as a plain dict (for JSON; the run's common summary says which
        balancer ran, ``balance``, and the time it ran, ``duration_s``; the time asked for is
        ``requested_duration_s``)."""
        return {"max_tilt_deg": self.max_tilt_deg, "feet_flat": self.feet_flat,
                "fell": self.fell, "realtime_factor": self.realtime_factor,
                "requested_duration_s": self.duration_s, "simulated_s": self.simulated_s,
                "push_n": self.push_n, "push_direction": list(self.push_direction),
                "max_sole_tilt_deg": self.max_sole_tilt_deg,
                "final_tilt_deg": self.final_tilt_deg, "physics_share": self.physics_share,
                "max_feet_moment_difference_nm": self.max_feet_moment_difference_nm,
                "max_foot_shift_mm": self.max_foot_shift_mm,
                "snapshot": str(self.snapshot) if self.snapshot else None}


# the hip strategy's stance: the legs crouch this much below the standing posture (the CoM
# 0.556 m above the soles instead of 0.628). A push's capture point lies v/omega beyond the
# CoM, v/omega ~ sqrt(height): 6 % less. 90 N pushes forward and backward on perturbation
# seeds 1-10, 5 of which fell standing taller, were all held, and the nominal robot's rocking
# settles faster (docs/history/balance.md)
BRACE_LIFT_M = -0.10


def standing_posture(model: RobotModel, lift_m: float = 0.0) -> np.ndarray:
    """The home posture with the waist moved over the feet so that the model's centre of mass
    (pinocchio, empty hands) sits over the centre of the soles, as the tasks' CoM control
    (:class:`~hubo_cli.kinematics.wholebody.WholeBody`, hrpsys AutoBalancer) places it: the
    crouched home posture has it about 4 mm ahead of the centre, which leaves the toes less
    room than the heels (a forward push held 84 N, a backward one 90 N). ``lift_m`` raises
    the waist (m, < 0 crouches; :data:`BRACE_LIFT_M` is the braced stance). Torso upright,
    soles flat (rad)."""
    from hubo_cli.kinematics.wholebody import WholeBody

    return WholeBody(model, com_control=True).solve({}, lift_m=lift_m).q_rad


def posture_of(model: RobotModel, name: str) -> np.ndarray:
    """A standing run's posture by name (rad): ``standing`` (:func:`standing_posture`),
    ``braced`` (the same, crouched by :data:`BRACE_LIFT_M`: the hip strategy's) or ``home``.

    Raises:
        ConfigError: another name.
    """
    if name == "braced":
        return standing_posture(model, BRACE_LIFT_M)
    if name == "standing":
        return standing_posture(model)
    if name == "home":
        return home_posture(model)
    raise ConfigError(f"unknown standing posture {quoted(name)}",
                      hint="use standing, braced or home")


MAX_PUSH_N = 10_000.0  # N; 0.2 s of far less throws the robot, more is a typing error
PUSH_AT_S, PUSH_DURATION_S = 1.0, 0.2  # hubo sim's push: 1 s into the stand, for 0.2 s


def check_standing_args(duration_s: float, push_n: float, model: RobotModel, *,
                        push_at_s: float = PUSH_AT_S,
                        push_duration_s: float = PUSH_DURATION_S) -> None:
    """Raise InputError unless one of ``model``'s control periods <= duration_s <= 3600 (s; a
    shorter stand rounds to no period at all, which review 20's ``--duration 1e-300`` made an
    internal error), 0 <= push_n <= MAX_PUSH_N, and a push ends within the stand (review 22:
    ``hubo sim --duration 0.5 --push 100`` reported the push and "fell no", exit 0, though the
    stand ended before it). ``model``: the robot the stand runs on."""
    period_s = model.control_period_s
    if not (math.isfinite(duration_s) and period_s <= duration_s <= 3600):
        raise InputError(f"duration must be in [{period_s:g}, 3600] s (one control period to "
                         f"an hour), got {duration_s:g}", hint="e.g. --duration 5")
    if not (math.isfinite(push_n) and 0 <= push_n <= MAX_PUSH_N):
        raise InputError(f"push must be a force of 0 to {MAX_PUSH_N:g} N, got {push_n}",
                         hint="e.g. --push 30")
    push_end_s = push_at_s + push_duration_s
    if push_n > 0 and duration_s < push_end_s:
        raise InputError(f"duration {duration_s:g} s ends before the push does ({push_n:g} N "
                         f"from {push_at_s:g} s for {push_duration_s:g} s): the stand would "
                         "be reported as standing a push it never felt",
                         hint=f"stand at least {push_end_s:g} s, e.g. --duration 5, or leave "
                              "out the push")


class StandTarget(Target):
    """Hold the home posture; push the torso once; watch tilt, soles and falls each period
    (the estimate's torso, soles and contact; the simulator only pushes)."""

    name = "stand"
    reads = (T_WORLD_TORSO, T_WORLD_SOLES, CONTACT, WRENCHES)
    log_columns = ("tilt_deg", "feet_moment_difference_nm", "max_sole_tilt_deg")

    def __init__(self, q_home_rad: np.ndarray, n_periods: int, push_world_n: np.ndarray,
                 push_at_s: float, push_duration_s: float, model: RobotModel | None = None,
                 posture: str = "home") -> None:
        self.q_home_rad = q_home_rad
        self.model, self.posture = model, posture  # what a robot without a world must stand in
        self.push_world_n = push_world_n
        self._pushes = bool(np.any(push_world_n))
        self.push_at_s = push_at_s
        self.push_duration_s = push_duration_s
        self.world: SceneActions | None = None
        self.store: Store | None = None
        self.times_s = np.zeros(n_periods)
        self.tilts_deg = np.zeros(n_periods)
        self.differences_nm = np.zeros(n_periods)
        self.k = 0
        self.feet_flat, self.fell, self.max_sole_deg = True, False, 0.0
        self.soles_start_m: dict[str, tuple[float, float]] = {}  # x, y (m)
        self.max_foot_shift_m = 0.0
        self.torso_z0_m: float | None = None
        self.wall_start_s = self.wall_end_s = 0.0
        self.physics_start_s = 0.0

    def attach(self, world: SceneActions | None, modules, store: Store) -> None:
        if world is None and self._pushes:
            raise ConfigError("the standing experiment's push needs the simulator (it pushes "
                              "the torso)", hint="run it with the sim driver, or push the "
                                                 "robot yourself (the simulated daemon: hubo "
                                                 "hardware sim-daemon --push)")
        self.world, self.store = world, store
        self.physics_start_s = world.physics_wall_s if world is not None else 0.0
        self.wall_start_s = time.perf_counter()

    def __call__(self, t_s: float, state) -> tuple[np.ndarray, dict]:
        world, store, k = self.world, self.store, self.k
        if k == 0 and world is None and self.model is not None:  # not placed by a simulator
            check_stands_in(self.model, state.q_rad, self.q_home_rad, self.posture)
        if self._pushes and abs(t_s - self.push_at_s) < 0.0025:
            world.push_torso(self.push_world_n, self.push_duration_s)
        T_world_torso = store[T_WORLD_TORSO]
        tilt = math.degrees(tilt_rad_of_matrix(T_world_torso[:3, :3]))
        torso_z_m = float(T_world_torso[2, 3])
        if self.torso_z0_m is None:
            self.torso_z0_m = torso_z_m
        wrenches = store[WRENCHES]
        (_, _, _, rx, ry, _), (_, _, _, lx, ly, _) = (wrenches["right-ankle"].tolist(),
                                                      wrenches["left-ankle"].tolist())
        if k < len(self.times_s):
            self.times_s[k], self.tilts_deg[k] = state.time_s, tilt
            self.differences_nm[k] = math.hypot(rx - lx, ry - ly)
            self.k += 1
        for sole, T_world_sole, touching in zip(("right_sole", "left_sole"),
                                                store[T_WORLD_SOLES], store[CONTACT],
                                                strict=True):
            sole_tilt = math.degrees(tilt_rad_of_matrix(T_world_sole[:3, :3]))
            x, y = T_world_sole[:2, 3].tolist()
            x0, y0 = self.soles_start_m.setdefault(sole, (x, y))
            self.max_foot_shift_m = max(self.max_foot_shift_m, math.hypot(x - x0, y - y0))
            self.max_sole_deg = max(self.max_sole_deg, sole_tilt)
            self.feet_flat &= bool(touching) and sole_tilt <= FLAT_TOLERANCE_DEG
        if has_fallen(tilt, self.torso_z0_m - torso_z_m):
            self.fell = True
        self.wall_end_s = time.perf_counter()
        return self.q_home_rad, {"tilt_deg": tilt, "feet_moment_difference_nm":
                                 self.differences_nm[k - 1] if k else 0.0,
                                 "max_sole_tilt_deg": self.max_sole_deg, "done": self.fell}


WALKING_LIMITS = "walking"  # the robot file's limit set whose legs step and bow the trunk


@dataclass(frozen=True)
class StandingOptions:
    """One standing run's options, decided once by :func:`standing_options` and passed through
    unchanged (the CLI builds them, loads the model with ``safety.limit_set`` and calls
    :func:`run_standing`).

    Attributes:
        duration_s, push_n, push_direction, push_at_s, push_duration_s, step, perturb_seed:
            as :func:`stand` takes them (``push_direction`` normalised).
        safety: the run's safety profile: balancer and its mode, hip strategy, stop sources
            and the legs' joint-limit set (``limit_set``, never None here).
        limit_set_reason: why the run has its limit set (for the summary).
        posture: what the robot stands in (:func:`posture_of`): ``braced`` with the hip
            strategy, ``standing`` otherwise with the default balancer, else ``home``.
        driver, driver_options: the robot's back end and its options; only the simulator
            pushes (``push_n`` must be 0 on another: the hardware driver's robot is pushed by
            whatever pushes it, the simulated daemon's ``--push``), and the robot must stand
            in the posture the run holds (``posture``; the simulated daemon's ``--posture``).
    """

    duration_s: float
    push_n: float
    push_direction: tuple[float, float, float]
    push_at_s: float
    push_duration_s: float
    step: bool
    perturb_seed: int | None
    safety: SafetyProfile
    limit_set_reason: str
    posture: str = "standing"
    driver: str = "sim"
    driver_options: Mapping[str, object] = field(default_factory=dict)


def standing_options(duration_s: float = 5.0, push_n: float = 0.0, *,
                     balance: str = "default", step: bool = False, hip_strategy: bool = True,
                     limit_set: str | None = None, default_limit_set: str = "table4",
                     stops: ActiveStops | None = None, push_direction=(1.0, 0.0, 0.0),
                     push_at_s: float = PUSH_AT_S, push_duration_s: float = PUSH_DURATION_S,
                     perturb_seed: int | None = None, driver: str = "sim",
                     driver_options: Mapping[str, object] | None = None) -> StandingOptions:
    """The standing run's options, every choice made here once.

    ``balance`` is ``--balance``'s choice (``default``, ``paper`` or ``off``). The hip strategy
    runs only with the default balancer and not with ``step``. Stepping and the hip strategy
    need the robot file's ``walking`` limit set (legs fast enough to step and to bow the
    trunk); otherwise the run stands on ``default_limit_set`` (Table IV's, as published).
    ``limit_set`` names the set explicitly (``--limits``); one those options cannot run on is
    a ConfigError. The duration and the push are not checked here: the robot the run stands
    on judges them (:func:`check_standing_args`, which the CLI and :func:`stand` call first)."""
    direction = np.asarray(push_direction, dtype=float)
    if direction.shape != (3,) or not np.all(np.isfinite(direction)) or not direction.any():
        raise InputError(f"the push direction must be a non-zero 3-vector, got {push_direction}",
                         hint="e.g. (1, 0, 0), forward")
    direction = direction / np.linalg.norm(direction)
    safety = SafetyProfile().with_balance(balance)
    default = safety.balance and safety.balance_mode == "default"
    hip = hip_strategy and not step and default
    needs = "stepping (--step)" if step else "the hip strategy" if hip else None
    if limit_set is not None:
        load_model(limits=limit_set)  # an unknown set is named as such, with the known ones
    if needs is None:
        chosen = limit_set or default_limit_set
        reason = ("named by --limits" if limit_set
                  else "neither stepping nor the hip strategy runs")
    elif limit_set not in (None, WALKING_LIMITS):
        raise ConfigError(f"{needs} needs the {quoted(WALKING_LIMITS)} joint-limit set, not "
                          f"{quoted(limit_set)}",
                          hint="leave --limits out" + ("" if step else ", or add --no-hip"))
    else:
        chosen, reason = WALKING_LIMITS, f"{needs} needs its legs' speed"
    safety = replace(safety, hip_strategy=hip, limit_set=chosen).with_stops(stops)
    return StandingOptions(duration_s=float(duration_s), push_n=float(push_n),
                           push_direction=tuple(float(v) for v in direction),
                           push_at_s=float(push_at_s), push_duration_s=float(push_duration_s),
                           step=step, perturb_seed=perturb_seed, safety=safety,
                           limit_set_reason=reason,
                           posture="braced" if hip else "standing" if default else "home",
                           driver=driver,
                           driver_options=dict(driver_options or {}))


def stand(model: RobotModel, duration_s: float = 5.0, push_n: float = 0.0,
          balance: bool = True, *, push_at_s: float = PUSH_AT_S,
          push_duration_s: float = PUSH_DURATION_S,
          push_direction=(1.0, 0.0, 0.0), gui: bool = False, out: str | Path | None = None,
          stops: ActiveStops | None = None, perturb_seed: int | None = None,
          balance_mode: str = "default", step: bool = False,
          hip_strategy: bool = True, operator: OperatorKeys | None = None,
          live: RunObserver | None = None, driver: str = "sim",
          driver_options: dict | None = None) -> StandingResult:
    """Stand the robot for ``duration_s`` and measure how it copes (the library's form of
    ``hubo sim``: :func:`standing_options` then :func:`run_standing`, with ``model`` loaded
    again for the limit set the options need).

    With the default balancer the robot stands in :func:`standing_posture` (the home posture
    with the model's CoM over the soles' centre), crouched by :data:`BRACE_LIFT_M` when the hip
    strategy runs; with the paper's or none, in the home posture.

    Args:
        model: robot model.
        duration_s: simulated time (s).
        push_n: force (N) of one push on the torso's centre of mass, 0 for none (the
            simulator's torso body, torso, pelvis and neck in one, has it 0.93 m above the
            floor in the home posture).
        balance: run the ankle balancer in the pipeline.
        push_at_s, push_duration_s: when the push starts and how long it lasts (s).
        push_direction: world direction of the push (normalised; default forward, +x;
            PUSH_DIRECTIONS names four).
        gui: open the PyBullet window (real time).
        out: the run folder (default ``runs/<time>-sim``); it gets the log, the snapshot and
            ``summary.json``.
        stops: the stop sources the run keeps (None: every soft source; see
            :mod:`hubo_cli.control.stop_choice`).
        perturb_seed: a perturbed simulated robot and world (:mod:`hubo_cli.perturb`).
        balance_mode: ``default`` or ``paper`` (eq. 11-12 as published), when balance is on.
        step: catch a push the ankles cannot hold by stepping
            (:class:`~hubo_cli.walking.capture_step.CaptureStepper`; the robot file's
            ``walking`` limit set, whose legs are fast enough to step); the summary gets
            ``capture_step``.
        hip_strategy: bow the trunk when the capture point nears the soles' toe or heel edge
            (:class:`~hubo_cli.control.hip_strategy.HipStrategy`, after the balancer; the
            robot file's ``walking`` limit set, whose legs are fast enough for it); only with
            the default balancer (the paper's mode and no balancer stand on Table IV's limits,
            as published), and not with ``step``, which answers such a push by stepping.
        operator: the operator's keys (space stop, r release, q finish), if any.
        live: the live viewer's publisher (``--live``), if any.
        driver, driver_options: the robot's back end and its options; only the simulator
            pushes (``push_n`` must be 0 on another: the hardware driver's robot is pushed by
            whatever pushes it, the simulated daemon's ``--push``), and the robot must stand
            in the posture the run holds (``posture``; the simulated daemon's ``--posture``).
    """
    check_standing_args(duration_s, push_n, model, push_at_s=push_at_s,
                        push_duration_s=push_duration_s)
    options = standing_options(duration_s, push_n, balance=balance_mode if balance else "off",
                               step=step, hip_strategy=hip_strategy,
                               default_limit_set=model.limits_name, stops=stops,
                               push_direction=push_direction, push_at_s=push_at_s,
                               push_duration_s=push_duration_s, perturb_seed=perturb_seed,
                               driver=driver, driver_options=driver_options)
    if model.limits_name != options.safety.limit_set:
        model = model.with_limits(options.safety.limit_set)
    return run_standing(model, options, gui=gui, out=out, operator=operator, live=live)


def run_standing(model: RobotModel, options: StandingOptions, *, gui: bool = False,
                 out: str | Path | None = None, operator: OperatorKeys | None = None,
                 live: RunObserver | None = None) -> StandingResult:
    """Run the standing experiment ``options`` describe on ``model``, which must carry the
    options' limit set (:class:`~hubo_cli.session.RunSetup` refuses another) and whose
    control period the options' duration was checked against (:func:`check_standing_args`)."""
    safety = options.safety
    posture = options.posture
    q_home = posture_of(model, posture)
    n_periods = int(round(options.duration_s / model.control_period_s))
    direction = np.asarray(options.push_direction)
    target = stepper = StandTarget(q_home, n_periods, options.push_n * direction,
                                   options.push_at_s, options.push_duration_s, model, posture)
    if options.step:
        from hubo_cli.walking.capture_step import CaptureStepper
        from hubo_cli.walking.params import walking_params

        stepper = CaptureStepper(target, model, walking_params(model), q_home)
    setup = RunSetup(command="sim", model=model, driver=options.driver,
                     driver_options=dict(options.driver_options), gui=gui, out=out,
                     safety=safety,
                     duration_s=n_periods * model.control_period_s, q_start_rad=q_home,
                     perturb_seed=options.perturb_seed, operator=operator, live=live)
    done = run(setup, stepper)
    result = _result(target, done, options.duration_s, options.push_n, safety.balance,
                     model.control_period_s)
    result.failure = done.loop.failure(done.run_dir)
    result.push_direction = options.push_direction
    done.save_summary(result.summary() | {"limit_set_reason": options.limit_set_reason,
                                          "posture": posture})
    if options.step:
        done.save_summary({"capture_step": stepper.summary()})
    if "hip" in done.loop.module_status:  # how far the trunk bowed, and that it stands up
        bow = done.log["hip_bow_rad"]  # the hip strategy's output (NaN in the smooth stop)
        bow = bow[np.isfinite(bow)]
        done.save_summary({"hip_strategy": {
            "max_bow_rad": float(np.max(np.abs(bow), initial=0.0)),
            "final_bow_rad": float(bow[-1]) if len(bow) else 0.0}})
    return result


def _result(target: StandTarget, done: RunResult, duration_s: float, push_n: float,
            balance: bool, period_s: float) -> StandingResult:
    n = max(target.k, 1)
    wall = target.wall_end_s - target.wall_start_s
    simulated = target.k * period_s
    # a robot through hubo-ach has no physics here (its own runs in its own time)
    physics = (0.0 if target.world is None else
               target.world.physics_wall_s - target.physics_start_s)
    return StandingResult(
        duration_s=duration_s, push_n=push_n, balance=balance,
        max_tilt_deg=float(target.tilts_deg[:n].max()),
        feet_flat=bool(target.feet_flat and not target.fell), fell=target.fell,
        realtime_factor=simulated / wall if wall > 0 else float("inf"),
        max_sole_tilt_deg=target.max_sole_deg, final_tilt_deg=float(target.tilts_deg[n - 1]),
        physics_share=min(1.0, physics / wall) if wall > 0 else 0.0, simulated_s=simulated,
        max_feet_moment_difference_nm=float(target.differences_nm[:n].max()),
        max_foot_shift_mm=target.max_foot_shift_m * 1000,
        snapshot=done.run_dir / "snapshot.png", run_dir=done.run_dir,
        times_s=target.times_s[:n], tilts_deg=target.tilts_deg[:n],
        feet_moment_difference_nm=target.differences_nm[:n])
