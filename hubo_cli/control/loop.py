"""The fixed-rate control loop: read the state, get a target, run the modules, send, step, log.

Each period of ``dt`` (the model's 5 ms):

1. ask the caller's :class:`~hubo_cli.control.target.Target` (or a plain function)
   ``target(t_s, state) -> (q_target_rad | None, info)``;
   ``None`` (or NaN entries) means "no new target"; ``info`` may carry ``"estop"`` (a source
   name or several), ``"flags"`` (status flags of the source, e.g. ``"stale-input"``),
   ``"release"`` (release every emergency stopper), ``"done"`` (finish after
   this period) and numbers for the log's extra columns (declared in ``target.log_columns``);
2. run the ordered modules on the command (a module that requests an emergency stop through
   ``cycle.estop_requests`` must come before the stopper that should see it in that period);
3. send the result to the driver, step it, and write one log row with the period's status;
   an ``observer`` (:class:`PeriodObserver`, e.g. the live view) is shown the period too.

What the modules publish for a viewer (their ``status()`` snapshots) is the loop's
:attr:`ControlLoop.module_status` record: taken when the loop is built and when it ends, and
after every period once a viewer asks for it (:meth:`ControlLoop.watch_status`). A viewer reads
that record, never a module: the record is replaced whole, in the loop's thread.

Pacing uses absolute deadlines (``next += period``), so it does not drift: ``speed=None`` runs as
fast as possible, ``1.0`` in real time, ``x`` at x times real time. A period more than
``max_lag_periods`` late re-anchors the schedule (counted in ``overruns``).

Ctrl-C (or SIGTERM) and any exception raised by the target source or a module end in a
smooth stop: a velocity-interface ruckig brake from the last command, passed through a soft
error limiter, sent period by period until the command is at rest; then ``driver.stop()``. A
second Ctrl-C during the brake stops the driver at once. A failing driver is stopped at once
(one reporting device trouble has braked by itself: ``ended`` is ``device``). A log that cannot
be written (a full disk: :attr:`PeriodLog.error`) ends the run with a brake (``log-error``; the
periods after the failure are not logged).

The first Ctrl-C (or SIGTERM) is only noted (:mod:`hubo_cli.interrupts`); the loop acts on it at
the start of its next period, so it never lands inside a period, and one that Python swallowed
(a ctypes callback) is still seen, before the robot's first command. While the target's phase
stops itself (a walk: the store's :data:`~hubo_cli.control.phase.PHASE_STOP`, followed by the
soft stopper, ``estop``), an interrupt or a log failure does not brake the robot where it is
(a foot in the air): the loop asks for the operator's stop (the stopper latches and the walk
finishes its step into a double-support stance, as the space key does) and runs on, the log
no longer written after a failure, until the stopper holds that stance, within the phase's
``within_s`` plus :data:`STANCE_SPARE_S` (:attr:`LoopResult.interrupt_stop` says how it went).
A second Ctrl-C, the bound running out or a stopper that does not latch falls back to the
brake; a second signal of another kind (SIGTERM, SIGHUP, SIGQUIT: nobody insisting) is said
in ``error`` and the stop goes on. A stance stop that a sensor fault or a log failure began
counts interrupts the same way: the first is said in ``error`` (after the fault, which stays
the run's end) and the stop goes on; the second brakes.
The loop never raises for these; :class:`LoopResult` says how it ended.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from hubo_cli.control.estop import MAX_FINISH_S
from hubo_cli.control.following import check_torso_height, torso_height_bounds_m
from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.limiter import SoftErrorLimiter
from hubo_cli.control.log import LOG_NAME, PeriodLog
from hubo_cli.control.module import Cycle, Module
from hubo_cli.control.operator import OperatorKeys
from hubo_cli.control.phase import PHASE_STOP, PhaseStop
from hubo_cli.control.settled import settled_objects
from hubo_cli.control.status import Status, status_from_flags
from hubo_cli.control.stop_choice import STOP_SOURCE
from hubo_cli.control.target import Target, TargetOutput, as_target
from hubo_cli.dataflow import Store, check_flow
from hubo_cli.drivers.base import Driver
from hubo_cli.errors import ConfigError, DeviceError, HuboError, interrupt_cause
from hubo_cli.estimation.estimator import Estimator
from hubo_cli.estimation.keys import T_WORLD_TORSO
from hubo_cli.estimation.plausibility import SensorFault
from hubo_cli.interrupts import (
    interrupt_pending,
    loop_ended,
    loop_given_back,
    loop_taking,
    take_interrupt,
)
from hubo_cli.motion.limits import JointLimits, all_finite
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.state import RobotState

TargetSource = Target | Callable[[float, RobotState], TargetOutput]


class PeriodObserver(Protocol):
    """Shown every period the loop logs (the smooth stop's included), after the log row is
    written, in the loop's thread: it must be quick (copy what it needs and return) and is
    dropped for the rest of the run if it raises."""

    def period(self, t_s: float, status: Status, flags: set[str], state: RobotState,
               extras: dict | None) -> None:
        """``t_s``: loop time (s); ``status``, ``flags``: the period's; ``state``: the robot's
        after the step; ``extras``: the log's extra columns (None in the smooth stop)."""

LABELS = {status: status.label for status in Status}  # a property's work done once
ENDINGS = ("finished", "done", "interrupted", "module-error", "target-error", "driver-error",
           "device", "log-error", "estimation-error")
MAX_STOP_S = 15.0  # a brake from full speed at the slowest joint's limits takes under 2 s
STANCE_SPARE_S = 1.0  # a phase stopping itself after an interrupt: its within_s (at most the
                      # stopper's MAX_FINISH_S) and this long for the stopper's own brake
STANCE_HOLD_S = 0.5  # ... then held this long (the loop sees a fall meanwhile) before it ends


@dataclass
class LoopResult:
    """How a run ended.

    Attributes:
        ended: ``finished`` (duration reached), ``done`` (the target source said so),
            ``interrupted`` (Ctrl-C or SIGTERM), ``module-error``, ``target-error``,
            ``estimation-error`` (an observer failed: the robot is braked from the last command),
            ``driver-error``, ``device`` (the driver reported device trouble, e.g. the robot's
            state stopped: it has braked and holds by itself; or a module or the estimate
            found it, e.g. a joint that does not follow, a torso estimated metres up:
            :mod:`hubo_cli.control.following`, braked from the last command) or
            ``log-error`` (the log could not be written: a full disk).
        periods: control periods run (the smooth stop included).
        t_end_s: loop time at the end (s).
        error: one line describing the error or interruption, "" otherwise: ``said`` joined
            with ``; ``.
        said: what ended or interrupted the run, in the order it happened (a sensor fault,
            then the Ctrl-C during its stance stop), one message each; () when nothing did.
        stop_periods: periods spent in the final smooth stop.
        status_counts: status label -> number of periods.
        flag_counts: flag -> number of periods it was raised in (e.g. ``collision``).
        safety_events: (module name, time s, kind, sources) for every emergency-stop latch and
            release and every collision hold.
        overruns: periods that ran so late that the schedule was re-anchored.
        skipped_s: wall time the schedule skipped at those re-anchors (s): the periods a
            real-time run did not get to run.
        log_path: the per-period log, if one was written.
        final_command_rad: the last command sent.
        module_status: what each module published at the end (name -> its ``status()``
            snapshot, None for a module with nothing to show).
        interrupt_stop: how a phase that stops itself (a walk) stopped after an interrupt or
            a log failure: ``stood`` (it finished its step and the stopper holds the stance),
            ``held`` (the stopper braked it and holds), ``braked: <why>`` (the loop's brake:
            a second interrupt, no stance within the bound, a stopper that did not latch),
            ``ended: <how>`` (the run ended meanwhile: the target's done, an error); "" when
            no such stop was asked for.
        interrupt_stop_s: loop time from that request to its end (s; NaN without one).
        interrupt_t_s: loop time of that request (s; NaN without one): the stopper's
            ``operator`` latches from then on are the interrupt's, not the operator's key.
        log_periods_dropped: periods run after the log failed, not in it.
        log_error: the log's failure (a full disk), "" when it was written whole; also said
            in ``error``, whether it ended the run (``log-error``) or came during an
            interrupt's stop (``interrupted``).
    """

    ended: str
    periods: int
    t_end_s: float
    error: str = ""
    said: tuple[str, ...] = ()
    stop_periods: int = 0
    status_counts: dict[str, int] = field(default_factory=dict)
    flag_counts: dict[str, int] = field(default_factory=dict)
    safety_events: list[tuple[str, float, str, tuple[str, ...]]] = field(default_factory=list)
    overruns: int = 0
    skipped_s: float = 0.0
    log_path: Path | None = None
    final_command_rad: np.ndarray | None = None
    exception: BaseException | None = None
    module_status: dict[str, object] = field(default_factory=dict)
    interrupt_stop: str = ""
    interrupt_stop_s: float = float("nan")
    interrupt_t_s: float = float("nan")
    log_periods_dropped: int = 0
    log_error: str = ""

    @property
    def smooth_stop_s(self) -> float:
        """Loop time spent in the final smooth stop (s)."""
        return self.t_end_s * self.stop_periods / self.periods if self.periods else 0.0

    @property
    def ok(self) -> bool:
        """True when the run ended as planned (duration reached or the source finished)."""
        return self.ended in ("finished", "done")

    def failure(self, run_dir: Path) -> HuboError | None:
        """The error a command ends with after this run (its summary written): the driver's or
        a module's own (a lost robot state is a DeviceError, exit 3), with its ``events``
        when something else came too (:attr:`said`: e.g. Ctrl-C during a sensor fault's
        stance stop), or one line for a part that failed inside; None when the run ended
        without one (done, finished, interrupted)."""
        if isinstance(self.exception, HuboError):
            return self.exception
        if self.ended in ("module-error", "target-error", "estimation-error", "driver-error"):
            return HuboError(f"the run stopped early: {self.error}",
                             hint=f"the log up to the stop is in {Path(run_dir) / LOG_NAME}")
        return None


def _as_requests(value) -> Iterable[str]:
    if not value:
        return ()
    if isinstance(value, str):
        return (value,)
    return tuple(str(v) for v in value)


def _merge_info(info: dict, pressed: dict) -> dict:
    """A target's ``info`` with the operator's requests added (stop requests of both kept)."""
    if not pressed:
        return info
    merged = {**info, **pressed}
    if "estop" in info and "estop" in pressed:
        merged["estop"] = (*_as_requests(info["estop"]), *_as_requests(pressed["estop"]))
    return merged


@dataclass
class _StanceStop:
    """A phase stopping itself (a walk finishing its step) after an interrupt or a log
    failure, asked at ``t_start_s``, given ``bound_s`` to stand (loop time); once it stands,
    held STANCE_HOLD_S before the loop ends."""

    t_start_s: float
    bound_s: float
    outcome: str = ""
    t_end_s: float | None = None
    asked: bool = False  # the stop was requested in a period (the stopper could answer)

    def over(self, store: Store, t_s: float) -> bool:
        """After a period ending at ``t_s``: the stopper holds (``stood`` when the phase
        says it stands, ``held`` when the stopper braked it), it did not latch, or the bound
        ran out (both ``braked: ...``); sets :attr:`outcome` when it is over."""
        if not self.asked:  # (begun after this period's modules ran: a log failure)
            return False
        if self.t_end_s is not None:  # standing: held STANCE_HOLD_S, a fall seen meanwhile
            return t_s - self.t_end_s >= STANCE_HOLD_S - 1e-9
        mode = store.get(STOP_MODE)
        if mode == "hold":
            phase_stop = store.get(PHASE_STOP)
            settled = isinstance(phase_stop, PhaseStop) and phase_stop.settled
            self.outcome = "stood" if settled else "held"
        elif mode not in ("finish", "stop"):
            self.outcome = f"braked: the stopper did not take the {STOP_SOURCE} stop"
        elif t_s - self.t_start_s > self.bound_s + 1e-9:
            self.outcome = f"braked: no stance within {self.bound_s:.2f} s"
        if self.outcome:
            self.t_end_s = t_s
        return self.outcome.startswith("braked")

    def end(self, outcome: str, t_s: float) -> None:
        """It ended otherwise at ``t_s``: a second interrupt, the target's end, an error."""
        self.outcome, self.t_end_s = outcome, t_s

    def took_s(self, t_now_s: float) -> float:
        """From the request to its end (s; to the stance, not to the end of its hold)."""
        return (self.t_end_s if self.t_end_s is not None else t_now_s) - self.t_start_s


class ControlLoop:
    """Runs modules at a fixed rate between a target source and a driver.

    Args:
        driver: a started driver (``driver.start()`` already called). Its period is the
            loop's: a module built for another period is refused (ConfigError).
        modules: the ordered pipeline (see :func:`hubo_cli.control.pipeline.build_pipeline`).
        target: the target source (see the module docstring).
        speed: None = as fast as possible, 1.0 = real time, x = x times real time (at least
            :data:`hubo_cli.pace.MIN_SPEED`: the run's set-up checks it).
        log_path: write the per-period CSV here (a folder gets ``log.csv``); None = no log.
        clock, sleep: time functions (s); injectable for tests.
        max_lag_periods: lateness (in periods) that re-anchors the schedule.
        operator: the operator's keys (:class:`~hubo_cli.control.operator.OperatorKeys`):
            what was pressed is taken each period and merged into the target's ``info``.
        observer: shown every period (:class:`PeriodObserver`); ``observer_error`` says why
            it was dropped, if it was.
        estimator: the estimation layer, run on every state the driver returns, before the
            target and the modules (None: the robot's own,
            :func:`~hubo_cli.estimation.build.build_estimator` of the driver's model without a
            tool, where the target or a module reads a key; else none, an empty store). The
            flow of keys from it through the target and the modules is checked now.
    """

    def __init__(self, driver: Driver, modules: list[Module], target: TargetSource, *,
                 speed: float | None = None, log_path: str | Path | None = None,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep,
                 max_lag_periods: int = 20, operator: OperatorKeys | None = None,
                 observer: PeriodObserver | None = None,
                 estimator: Estimator | None = None) -> None:
        self.driver = driver
        self.modules = list(modules)
        self.target = as_target(target)
        self.operator = operator
        self.observer = observer
        self.observer_error = ""
        self.speed = speed
        self.dt_s = driver.period_s
        for m in self.modules:
            if m.dt_s is not None and abs(m.dt_s - self.dt_s) > 1e-12:
                raise ConfigError(
                    f"the {m.name} module was built for a {m.dt_s * 1000:g} ms period but the "
                    f"{driver.name} driver runs at {self.dt_s * 1000:g} ms",
                    hint="build the pipeline with the driver's period (driver.period_s)")
        if estimator is None and (self.target.reads or any(m.reads for m in self.modules)):
            from hubo_cli.estimation.build import build_estimator

            estimator = build_estimator(driver.model, period_s=self.dt_s,
                                        accel_measured=driver.accel_measured,
                                        sensors_measured=driver.sensors_measured)
        self.estimator = estimator
        self.store = estimator.store if estimator is not None else Store()
        # an estimated torso beyond these heights is device trouble (following.py)
        self._torso_bounds_m = (torso_height_bounds_m(driver.model) if estimator is not None
                                and T_WORLD_TORSO in estimator.writes else None)
        check_flow([self.target, *self.modules],
                   provided=estimator.writes if estimator is not None else ())
        # each stage sees the store through its view: an undeclared key is a FlowError
        self.target_store = self.target.store = self.store.view(self.target)
        self._views = [self.store.view(m) for m in self.modules]
        self._watching_status = False
        self.module_status = self._published()
        self.clock = clock
        self.sleep = sleep
        self.max_lag_periods = max_lag_periods
        self.limits = JointLimits.from_model(driver.model)
        self.log_path = None
        if log_path is not None:
            path = Path(log_path)
            self.log_path = path / LOG_NAME if path.is_dir() else path
        self.log: PeriodLog | None = None
        self.period = 0
        self.overruns = 0
        self.skipped_s = 0.0
        self._deadline = 0.0
        self._statuses: Counter[str] = Counter()
        self._flags: Counter[str] = Counter()
        n = len(driver.joint_names)
        self._nan = np.full(n, np.nan)
        all_finite(self._nan)  # numba compiles it now, not in the first period
        self._cmd = np.zeros(n)
        self._cmd_prev = np.zeros(n)
        self._cmd_prev2 = np.zeros(n)

    # ------------------------------------------------------------------ helpers
    def _extra_columns(self) -> list[str]:
        columns = [c for m in self.modules for c in m.log_columns]
        columns += self.target.log_columns
        columns += self.driver.log_columns
        if self.estimator is not None:
            columns += self.estimator.log_columns
        return list(dict.fromkeys(columns))

    def _published(self) -> dict[str, object]:
        return {m.name: m.status() for m in self.modules}

    def watch_status(self) -> None:
        """Refresh :attr:`module_status` after every period from now on (a viewer watches;
        about 20 us a period, so runs without one take it only at the start and the end)."""
        self._watching_status = True

    def _pace(self, min_speed: float = 0.0) -> float:
        """Wait for this period's deadline, the loop running at ``self.speed`` but not slower
        than ``min_speed``; return the lateness after waiting (s)."""
        if self.speed is None:
            return 0.0
        wall_period = self.dt_s / max(self.speed, min_speed)
        now = self.clock()
        if self.period == 0 and self._deadline == 0.0:
            self._deadline = now
        wait = self._deadline - now
        if wait > 0:
            self.sleep(wait)
            now = self.clock()
        elif -wait > self.max_lag_periods * wall_period:
            self.overruns += 1
            self.skipped_s += -wait
            self._deadline = now
        late = now - self._deadline
        self._deadline += wall_period
        return late

    def _remember(self, q: np.ndarray) -> None:
        self._cmd_prev2 = self._cmd_prev
        self._cmd_prev = self._cmd
        self._cmd = q

    def _write(self, t_s, flags, compute_s, late_s, target, cmd, state, extras) -> None:
        status = status_from_flags(flags)
        self._statuses[LABELS[status]] += 1
        if flags:  # (Counter.update checks for a Mapping first: most periods have none)
            self._flags.update(flags)
        if self.log is not None:
            self.log.write(self.period, t_s, status, compute_s * 1e6, late_s * 1e6, flags,
                           target, cmd, state.q_rad, extras, state=state)
        if self.observer is not None:
            try:
                self.observer.period(t_s, status, flags, state, extras)
            except Exception as err:  # noqa: BLE001 (a viewer never stops the robot)
                self.observer, self.observer_error = None, f"{type(err).__name__}: {err}"

    # ------------------------------------------------------------------ run
    def run(self, duration_s: float | None = None) -> LoopResult:
        """Run until ``duration_s`` (loop time, s), the source's ``done``, Ctrl-C or an error.

        Returns a :class:`LoopResult`; the per-period log is closed when it returns.
        """
        handlers = loop_taking()  # the first interrupt is noted, acted on between periods
        try:
            with settled_objects():  # no full collection's scan of them stalls a period
                return self._run(duration_s, handlers)
        finally:
            loop_given_back(handlers)

    def _stance_stop(self, t_s: float) -> _StanceStop | None:
        """The stop an interrupt or a log failure asks of a phase that stops itself (a walk
        in mid-step), or None: no such phase, or no soft stopper following it."""
        phase_stop, mode = self.store.get(PHASE_STOP), self.store.get(STOP_MODE)
        if not isinstance(phase_stop, PhaseStop) or mode not in ("release", "finish"):
            return None
        return _StanceStop(t_s, min(max(float(phase_stop.within_s), 0.0), MAX_FINISH_S)
                           + STANCE_SPARE_S)

    def _run(self, duration_s: float | None, handlers: dict) -> LoopResult:
        driver = self.driver
        if self.log_path is not None:
            self.log = PeriodLog(self.log_path, driver.joint_names, self._extra_columns(),
                                 model=driver.model)
        ended, exc = "finished", None
        said: list[str] = []  # what ended or interrupted the run, in order (``error``)
        t_s = 0.0
        stance: _StanceStop | None = None  # a phase stopping itself after an interrupt
        # (or a sensor fault, a log failure): the first interrupt lets it go on, the second
        # brakes (raised as KeyboardInterrupt, or noted where a callback swallowed it)
        interrupted = False
        log_failed = False
        held = False  # the driver failed: it stopped (or holds) by itself, no brake of ours
        try:
            state = driver.read()
            refused = None  # a sensor dead at the start: the run ends before anything moves
            if self.estimator is not None:
                try:
                    self.estimator.reset(state)
                except SensorFault as err:
                    refused = err
                    ended, said, exc = "device", [str(err)], err
            q0 = np.array(state.q_rad, dtype=float)
            self._cmd = self._cmd_prev = self._cmd_prev2 = q0
            for m, view in zip(self.modules, self._views, strict=True):
                m.reset(q0.copy(), state, view)
            while refused is None and (duration_s is None or stance is not None
                                       or self.period * self.dt_s < duration_s - 1e-9):
                t_s = self.period * self.dt_s
                if interrupt_pending() is not None:  # noted (or swallowed): act on it now
                    cause = take_interrupt()
                    if stance is not None and interrupted:  # the second: the brake
                        stance.end(f"braked: {cause} while standing up", t_s)
                        said.append(f"interrupted ({cause})")
                        break
                    interrupted = True
                    if stance is not None:  # a fault's or a log failure's stance goes on
                        said.append(f"interrupted ({cause})")
                    else:
                        ended, said = "interrupted", [f"interrupted ({cause})"]
                        stance = self._stance_stop(t_s)
                        if stance is None:
                            break
                late_s = self._pace(1.0 if stance is not None else 0.0)
                cycle = Cycle(t_s, self.dt_s, store=self.store)
                started = self.clock()
                stage = "target"
                try:
                    q_target, info = self.target(t_s, state)
                    info = info or {}
                    if self.operator is not None:
                        info = _merge_info(info, self.operator.take())
                    cycle.estop_requests.update(_as_requests(info.get("estop")))
                    if stance is not None:
                        cycle.estop_requests.add(STOP_SOURCE)
                        stance.asked = True
                    cycle.flags.update(_as_requests(info.get("flags")))
                    if info.get("release"):
                        for m in self.modules:
                            m.release()
                    q = self._nan if q_target is None else np.asarray(q_target, dtype=float)
                    target_logged = q
                    stage = "module"
                    for m, view in zip(self.modules, self._views, strict=True):
                        cycle.store = view
                        q = m.update(q, state, cycle)
                except Exception as err:  # noqa: BLE001 (any failure ends in a smooth stop)
                    # (a module that finds the robot not following: device trouble, braked)
                    ended = "device" if isinstance(err, DeviceError) else f"{stage}-error"
                    # a library error is already a message for the user; anything else is a bug
                    said = [str(err) if isinstance(err, HuboError) else (
                        f"{type(err).__name__} in {stage}: {err}")]
                    exc = err
                    break
                if not all_finite(np.ascontiguousarray(q, dtype=float)):
                    q = np.where(np.isfinite(q), q, self._cmd)
                    cycle.flags.add("holding")
                compute_s = self.clock() - started
                stage = "driver"
                try:
                    applied = driver.send(q)
                    state = driver.step()
                except Exception as err:  # noqa: BLE001
                    ended = "device" if isinstance(err, DeviceError) else "driver-error"
                    said, exc = [f"{type(err).__name__}: {err}"], err
                    driver.stop()
                    held = True  # (the driver braked and holds by itself)
                    break
                if self.estimator is not None:
                    try:
                        self.estimator.update(state)
                        if self._torso_bounds_m is not None:  # before any module acts on it
                            check_torso_height(self.store.get(T_WORLD_TORSO),
                                               self._torso_bounds_m, t_s)
                    except SensorFault as err:  # (raised once: the estimate is whole)
                        exc = exc or err
                        if stance is not None:  # already stopping in a stance: said too
                            said.append(str(err))
                        else:  # a walk stops in a stance as after Ctrl-C, the rest brakes
                            ended, said = "device", [str(err)]
                            stance = self._stance_stop(t_s)
                            if stance is None:
                                break
                    except Exception as err:  # noqa: BLE001 (ends in a smooth stop)
                        ended = "device" if isinstance(err, DeviceError) else "estimation-error"
                        exc = err
                        said = [str(err) if isinstance(err, HuboError) else (
                            f"{type(err).__name__} in estimation: {err}")]
                        break
                self._remember(np.array(q, dtype=float))
                self.target.robot_flags = state.flags
                cycle.flags.update(state.flags)
                extras = dict(cycle.info)
                for key, value in info.items():
                    if isinstance(value, (int, float)):
                        extras[key] = value
                extras.update(driver.log_values())
                if self.estimator is not None:
                    extras.update(self.estimator.log_values())
                if self._watching_status:
                    self.module_status = self._published()
                self._write(t_s, cycle.flags, compute_s, late_s, target_logged, applied, state,
                            extras)
                self.period += 1
                if self.log is not None and self.log.error and not log_failed:
                    log_failed = True  # control goes on without the log (a full disk)
                    if stance is not None:
                        said.append(self.log.error)
                    else:
                        ended, said = "log-error", [self.log.error]
                        stance = self._stance_stop(t_s)
                        if stance is None:
                            break
                if stance is not None and stance.over(self.store, self.period * self.dt_s):
                    break
                if info.get("done"):
                    if stance is None:
                        ended = "done"
                    elif not stance.outcome:
                        stance.end("ended: the target finished", self.period * self.dt_s)
                    break
            if interrupt_pending() is not None and ended in ("finished", "done"):
                # noted in the last period: the run ends interrupted (nothing more to do)
                ended, said = "interrupted", [f"interrupted ({take_interrupt()})"]
        except KeyboardInterrupt as err:
            cause = interrupt_cause(err)
            if stance is not None:
                stance.end(f"braked: a second interrupt ({cause})", self.period * self.dt_s)
                said.append(f"second interrupt ({cause})")
            else:
                ended, said = "interrupted", [f"interrupted ({cause})"]
            exc = err
            self._count_a_logged_period()
        if stance is not None and not stance.outcome:  # an error ended it
            stance.end(f"ended: {ended}", self.period * self.dt_s)
        stopping_from = self.period
        try:
            if not held:
                self._smooth_stop()
        except KeyboardInterrupt:
            self._count_a_logged_period()
            said.append("second Ctrl-C: stopped without the ramp")
            if ended in ("finished", "done"):
                ended = "interrupted"
        finally:
            meanwhile = loop_given_back(handlers)  # (signals after the first, not Ctrl-C)
            if meanwhile:
                said.append(f"{', '.join(meanwhile)} during the stop, which went on")
            loop_ended()  # an interrupt from here on waits until the run's files are whole
            driver.stop()
            if self.log is not None:
                self.log.close()
                if self.log.error and not log_failed:  # the CSV at close (said once)
                    said.append(self.log.error)
                    if ended in ("finished", "done"):
                        ended = "log-error"
        self.module_status = self._published()
        dropped = self.period - self.log.rows if self.log is not None and self.log.error else 0
        if isinstance(exc, HuboError):  # what else the run saw goes with its error
            exc.events = tuple(said) if len(said) > 1 else ()
        return LoopResult(
            ended=ended, periods=self.period, t_end_s=self.period * self.dt_s,
            error="; ".join(said), said=tuple(said),
            stop_periods=self.period - stopping_from, status_counts=dict(self._statuses),
            flag_counts=dict(self._flags),
            safety_events=[(m.name, e.t_s, e.kind, e.sources) for m in self.modules
                          for e in m.events],
            overruns=self.overruns, skipped_s=self.skipped_s, log_path=self.log_path,
            final_command_rad=self._cmd.copy(), exception=exc,
            module_status=self.module_status,
            interrupt_stop="" if stance is None else stance.outcome,
            interrupt_stop_s=math.nan if stance is None else stance.took_s(self.period
                                                                            * self.dt_s),
            interrupt_t_s=math.nan if stance is None else stance.t_start_s,
            log_periods_dropped=max(dropped, 0),
            log_error=self.log.error if self.log is not None else "")

    def _count_a_logged_period(self) -> None:
        """An interrupt (Ctrl-C, SIGTERM) lands between any two bytecodes: one that came after
        a period's record was written and before the period was counted counts it, so that
        ``periods`` is the log's length."""
        if self.log is not None and self.log.rows == self.period + 1:
            self.period += 1

    def _smooth_stop(self) -> None:
        """Brake the command to rest within the limits, sending every period (each counted in
        ``self.period``)."""
        dt = self.dt_s
        q1, q2, q3 = self._cmd, self._cmd_prev, self._cmd_prev2
        v = (q1 - q2) / dt
        a = (q1 - 2 * q2 + q3) / dt**2
        if np.max(np.abs(v)) < 1e-9 and np.max(np.abs(a)) < 1e-9:
            return
        tracker = JointTracker(self.limits, dt)
        tracker.reset(q1, v + 0.5 * a * dt, a)
        limiter = SoftErrorLimiter(self.driver.model, dt, error_limit_rad=0.0, limits=self.limits)
        limiter.seed(q1, q2)
        # paced from now at real time at least: a slowed replay's stop does not keep Ctrl-C waiting
        self._deadline = min(self._deadline, self.clock())
        for _ in range(int(MAX_STOP_S / dt)):
            late_s = self._pace(min_speed=1.0)
            started = self.clock()
            q = limiter.step(tracker.brake())
            compute_s = self.clock() - started
            try:
                applied = self.driver.send(q)
                state = self.driver.step()
            except Exception:  # noqa: BLE001 (the driver is stopped by the caller)
                break
            self._remember(q)
            flags = {"smooth-stop"} | set(state.flags)
            self._write(self.period * dt, flags, compute_s, late_s, self._nan, applied, state,
                        None)
            self.period += 1
            if tracker.at_rest and np.max(np.abs(limiter.velocity_rad_s)) < 1e-9:
                break


def status_name(code: int) -> str:
    """The label of a status code (``"e-stopped"`` style words, see :class:`Status`)."""
    return Status(int(code)).label
