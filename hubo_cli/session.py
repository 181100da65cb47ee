"""One run of the robot: the typed set-up every robot command shares, and the one function
that runs it.

A use case (a task, a teleoperation session, the push-wall or standing experiment) supplies a
:class:`RunSetup` and a :class:`~hubo_cli.control.target.Target`; :func:`run` does the rest the
same way for all of them:

1. checks the pace: a real robot (``Driver.real_time``), a live operator and the GUI run at
   wall-clock speed; ``speed=None`` (as fast as possible) applies to replays on simulated
   drivers only, and a different explicit speed there is refused (InputError, exit 2);
2. makes the run folder, the driver (its run options: files in the run folder, the tools, the
   window) and, at the driver's control period (the one owner of the period), the pipeline
   the :class:`~hubo_cli.control.pipeline.SafetyProfile` decides;
3. starts the robot, hands the target the simulator's world (or None on a real robot) so it
   can place its scene, runs the :class:`~hubo_cli.control.loop.ControlLoop` with the
   per-period log, takes a snapshot where there is a simulator;
4. writes ``summary.json`` with the fields every run has (:func:`common_summary`, the balance
   figures of :func:`~hubo_cli.balance_report.balance_report` computed from the log) and returns
   a :class:`RunResult`; the use case adds its own fields with :meth:`RunResult.save_summary`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Protocol

import numpy as np

from hubo_cli.balance_report import balance_report
from hubo_cli.control.log import (
    LOG_NAME,
    META_NAME,
    PARQUET_NAME,
    ROWS_NAME,
    LogData,
    load_log,
    max_velocity_ratio,
    update_log_metadata,
)
from hubo_cli.control.loop import ControlLoop, LoopResult, PeriodObserver
from hubo_cli.control.module import Module
from hubo_cli.control.operator import OperatorKeys
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.target import Target
from hubo_cli.drivers.base import RunContext
from hubo_cli.drivers.registry import driver_class, make_driver
from hubo_cli.errors import (
    ConfigError,
    DeviceError,
    HuboError,
    InputError,
    InterruptedRunError,
)
from hubo_cli.estimation.build import build_estimator
from hubo_cli.interrupts import loop_starting, run_files
from hubo_cli.model import RobotModel
from hubo_cli.pace import check_speed
from hubo_cli.runs import discard_if_unused, make_run_dir, release_run_dir, write_json
from hubo_cli.scene import SceneActions

SUMMARY_NAME = "summary.json"
SNAPSHOT_NAME = "snapshot.png"


class RunObserver(PeriodObserver, Protocol):
    """A live viewer of a run: :meth:`run_started` once the robot has started (before the
    first period), :meth:`period` every period (:class:`PeriodObserver`), :meth:`run_ended`
    after the last (also when the run failed or was interrupted)."""

    def run_started(self, model: RobotModel, tools: Mapping[str, str], world) -> None:
        """``world``: the simulator's (walls, hole), or None on a robot without one."""

    def run_ended(self) -> None:
        """The run is over: publish what is left."""


@dataclass(frozen=True)
class RunSetup:
    """Everything a run needs to know before the robot starts.

    Attributes:
        command: names the run folder (``runs/<time>-<command>``) and the summary's command.
        model: the robot model; the same object the use case planned with.
        tools: arm -> tool held (``hand``, ``drill``): reaches the simulator and the collision
            detector (the use case's whole-body solver is built from the same mapping).
        driver: ``sim``, ``ideal`` or ``hardware`` (see :mod:`hubo_cli.drivers.registry`).
        driver_options: the driver's own options (e.g. ``armed`` for hardware).
        safety: the pipeline's layers and what ``--no-estop`` removes.
        speed: None = as fast as possible (replays on simulated drivers), 1.0 = real time,
            x = x times real time.
        live_input: the target follows a live operator (runs in real time).
        gui: open the simulator's window (runs in real time).
        out: the run folder (None: ``runs/<time>-<command>``).
        duration_s: loop time after which the run ends (None: until the target is done).
        q_start_rad: the start posture (None: the driver's default, the home posture).
        cutting: the wall material's cutting coefficients for the simulator (or None).
        perturb_seed: draw the simulated robot and world from this seed
            (:mod:`hubo_cli.perturb`; None or 0: nominal); simulators only.
        operator: the operator's keys (space stop, r release, q finish), read by the loop
            every period (None: no operator at a keyboard).
        live: a live viewer's publisher (:class:`RunObserver`, e.g. the Foxglove server of
            ``--live``): told when the robot has started, shown every period, told the end.
    """

    command: str
    model: RobotModel
    tools: Mapping[str, str] = field(default_factory=dict)
    tool_mass_kg: float | None = None  # the drill as weighed (None: the robot file's)
    driver: str = "sim"
    driver_options: Mapping[str, object] = field(default_factory=dict)
    safety: SafetyProfile = field(default_factory=SafetyProfile)
    speed: float | None = None
    live_input: bool = False
    gui: bool = False
    out: str | Path | None = None
    duration_s: float | None = None
    q_start_rad: np.ndarray | None = None
    cutting: Mapping[str, float] | None = None
    perturb_seed: int | None = None
    operator: OperatorKeys | None = None
    live: RunObserver | None = None

    def __post_init__(self) -> None:
        wanted = self.safety.limit_set
        if wanted is not None and wanted != self.model.limits_name:
            raise ConfigError(
                f"the run's safety profile enforces the {wanted!r} joint-limit set but its "
                f"model was loaded with {self.model.limits_name!r}",
                hint=f"load the model with load_model(..., {wanted!r})")

    def real_time_reason(self) -> str | None:
        """Why this run must go at wall-clock pace, or None when it need not."""
        if driver_class(self.driver).real_time:
            return f"the {self.driver} driver moves a real robot"
        if self.live_input:
            return "a live operator drives the robot"
        if self.gui:
            return "the simulator's window is open"
        if self.live is not None:
            return "a live viewer (--live) watches the run"
        return None

    def pace(self) -> float | None:
        """The loop's speed (None = as fast as possible), checked against real-time needs."""
        speed = check_speed(self.speed)
        reason = self.real_time_reason()
        if reason is None:
            return speed
        if self.speed is not None and abs(self.speed - 1.0) > 1e-9:
            raise InputError(f"this run must go in real time ({reason}); --speed "
                             f"{self.speed:g} is refused",
                             hint="leave --speed out: faster-than-real-time is for replays "
                                  "on the sim or ideal drivers")
        return 1.0


@dataclass
class RunResult:
    """A finished run.

    Attributes:
        run_dir: the run folder.
        loop: how the control loop ended (with what its modules published at the end,
            ``loop.module_status``: a use case reads that, never a module).
        summary: the summary as written to ``summary.json``.
    """

    run_dir: Path
    loop: LoopResult
    summary: dict

    @cached_property
    def log(self) -> LogData:
        """The per-period log (read once)."""
        return load_log(self.run_dir)

    def add_file(self, name: str) -> None:
        """List a file the use case wrote into the run folder in the summary."""
        if name not in self.summary["files"]:
            self.summary["files"].append(name)

    def save_summary(self, fields: Mapping[str, object]) -> dict:
        """Add the use case's own fields to the summary and write it again; returns it."""
        self.summary.update(fields)
        write_json(self.run_dir / SUMMARY_NAME, self.summary)
        return self.summary


def run(setup: RunSetup, target: Target,
        on_start: Callable[[Target, ControlLoop], None] | None = None) -> RunResult:
    """Run ``target`` on the robot as ``setup`` says and write the run folder.

    Args:
        setup: the run's set-up.
        target: where the joint targets come from.
        on_start: called with the target and the control loop once the robot has started,
            before the first period (live views, keys; the loop's overruns and skipped time).

    Raises:
        HuboError: a bad set-up, or a driver that cannot start (nothing moved; an empty run
            folder is removed again).
        KeyboardInterrupt: Ctrl-C or SIGTERM after the loop ended, raised once the run folder
            is written (unless an outer :func:`hubo_cli.interrupts.run_files` holds it longer).
    """
    loop_starting()
    speed = setup.pace()
    run_dir = make_run_dir(setup.command, setup.out)  # locked until the run is written
    try:
        with run_files():  # an interrupt once the loop ended waits for the files
            return _run_in(setup, target, on_start, speed, run_dir)
    finally:
        release_run_dir(run_dir)


def _run_in(setup: RunSetup, target: Target, on_start, speed: float | None,
            run_dir: Path) -> RunResult:
    """:func:`run` in its locked run folder."""
    try:
        cls = driver_class(setup.driver)
        context = RunContext(run_dir, dict(setup.tools), setup.gui, setup.cutting,
                             setup.perturb_seed)
        options = {**setup.driver_options, **cls.run_options(context)}
        with make_driver(setup.driver, setup.model, **options) as driver:
            if setup.perturb_seed and driver.world is None:
                raise InputError(f"--perturb needs the simulator, not the {setup.driver} driver",
                                 hint="leave out --perturb or --driver")
            modules = setup.safety.build(setup.model, driver.period_s, setup.tools)
            driver.start(setup.q_start_rad)
            world = driver.world
            loop = ControlLoop(driver, modules, target, speed=speed, log_path=run_dir,
                               operator=setup.operator, observer=setup.live,
                               estimator=build_estimator(setup.model, setup.tools,
                                                         driver.period_s,
                                                         driver.accel_measured,
                                                         driver.sensors_measured,
                                                         setup.tool_mass_kg))
            # the target may act on the scene, never read it (issue 33)
            target.attach(None if world is None else SceneActions(world), modules,
                          loop.target_store)
            if on_start is not None:
                on_start(target, loop)
            result = _run_loop(loop, setup, world)
            driver_summary = driver.summary_values()
            if result.log_error:  # a full disk: no snapshot, no log read back
                _end_without_log(setup, speed, result, modules, run_dir)
            metadata = {}
            if world is not None:
                world.snapshot_png(run_dir / SNAPSHOT_NAME)
                metadata["scene"] = world.scene()
    except HuboError:
        discard_if_unused(run_dir)  # nothing moved: leave no empty run folder behind
        raise
    metadata |= {"command": setup.command, "balance": setup.safety.balance_choice,
                 "limit_set": setup.model.limits_name}
    update_log_metadata(run_dir, metadata)
    summary = common_summary(setup, speed, result, modules, run_dir) | driver_summary
    done = RunResult(run_dir, result, summary)
    summary["started_utc"] = done.log.started_utc  # the log's, the one home of the fact
    summary["hubo_cli_version"] = done.log.hubo_cli_version
    summary["max_joint_velocity_ratio"] = max_velocity_ratio(setup.model, done.log)
    summary.update(balance_report(done.log, setup.model,
                                  drill=setup.tools.get("right-arm") == "drill"))
    if world is not None:  # the simulator's draws and ground truth
        summary["perturbation"] = world.perturbation.to_json()
        summary["max_torso_tilt_deg"] = world.max_tilt_deg
    write_json(run_dir / SUMMARY_NAME, summary)
    return done


def _run_loop(loop: ControlLoop, setup: RunSetup, world) -> LoopResult:
    """Run the loop, with the live viewer (if any) told of its start and end."""
    if setup.live is None:
        return loop.run(setup.duration_s)
    setup.live.run_started(setup.model, setup.tools, world)
    try:
        return loop.run(setup.duration_s)
    finally:
        setup.live.run_ended()


def _end_without_log(setup: RunSetup, speed: float | None, loop: LoopResult,
                     modules: list[Module], run_dir: Path) -> None:
    """A run whose log could not be written (a full disk) was braked to a stop (a walk: its
    step finished into a stance): write what summary the disk still takes and raise
    DeviceError (exit 3) saying so, or InterruptedRunError (exit 130) when Ctrl-C or SIGTERM
    came first and the log failed during the stop it asked for (the message says both)."""
    summary = common_summary(setup, speed, loop, modules, run_dir)
    with contextlib.suppress(InputError):  # a summary whole or none (write_json)
        write_json(run_dir / SUMMARY_NAME, summary)
    kept = ("its records are kept in log.rows: `hubo replay` writes log.csv from them once "
            "there is space" if (run_dir / ROWS_NAME).exists() else "")
    how = ("the walk finished its step and stood" if loop.interrupt_stop == "stood"
           else "the run was braked to a stop")
    dropped = (f" ({loop.log_periods_dropped} periods after the failure not logged)"
               if loop.log_periods_dropped else "")
    error = InterruptedRunError if loop.ended == "interrupted" else DeviceError
    raise error(f"{loop.error}; {how} after {loop.t_end_s:.2f} s{dropped}",
                hint="free space on that disk or choose another --out"
                     + (f" ({kept})" if kept else ""))


def common_summary(setup: RunSetup, speed: float | None, loop: LoopResult,
                   modules: list[Module], run_dir: Path) -> dict:
    """The summary fields every run has (see docs/runs.md, "The run folder")."""
    files = [name for name in (LOG_NAME, META_NAME, PARQUET_NAME, SNAPSHOT_NAME)
             if (run_dir / name).exists()] + [SUMMARY_NAME]
    return {
        "command": setup.command,
        "driver": setup.driver,
        "speed": "max" if speed is None else speed,
        "tools": dict(setup.tools),
        "pipeline": [m.name for m in modules],
        "estop_enabled": bool(setup.safety.active_sources),
        "estop_sources": list(setup.safety.active_sources),
        "estop_removed": {"sources": list(setup.safety.removed),
                          "by": setup.safety.removed_by} if setup.safety.removed else None,
        "balance": setup.safety.balance_choice,
        "limit_set": setup.model.limits_name,
        "ended": loop.ended,
        "finished_by_operator": setup.operator is not None and setup.operator.finished,
        "error": loop.error,
        "duration_s": loop.t_end_s,
        "periods": loop.periods,
        "smooth_stop_s": loop.smooth_stop_s,
        "interrupt_stop": loop.interrupt_stop or None,
        "interrupt_stop_s": loop.interrupt_stop_s if loop.interrupt_stop else None,
        "log_periods_dropped": loop.log_periods_dropped,
        "status_counts": loop.status_counts,
        "collision_periods": loop.flag_counts.get("collision", 0),
        "collision_holds": [{"t_s": t, "pair": list(pair)}
                            for _, t, kind, pair in loop.safety_events if kind == "collision"],
        "estop_events": [{"module": m, "t_s": t, "kind": k, "sources": list(s)}
                         for m, t, k, s in loop.safety_events
                         if k in ("stop", "release", "finish", "finish-deadline")],
        "overruns": loop.overruns,
        "overrun_skipped_s": loop.skipped_s,
        "stale_state_periods": loop.flag_counts.get("stale-state", 0),
        "files": files,
    }
