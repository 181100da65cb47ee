"""Building the ordered module list from names.

hrpsys-base chains ``seq -> es -> ic -> abc -> st -> co -> hes -> el``; mapped onto this
project's modules the default is::

    otg -> capture-point -> estop -> balance -> collision -> hard-estop -> limiter

``otg`` (ruckig) is the sequence player, ``estop`` the soft emergency stopper, ``balance`` the
ankle balancer (in place of abc/st; ``stabilizer``, the CoM/ZMP feedback on the waist, can
follow it; ``hip``, the hip strategy of the standing experiment, comes before ``collision``),
``collision`` the collision detector, ``hard-estop`` the
second stopper (freeze preset, reacting only to the ``hard`` source) and ``limiter`` the soft
error limiter. The capture-point monitor passes the command through; it sits before ``estop``
so that its request is seen in the same period. ``hoff-arbib`` can replace ``otg``.
``impedance`` (hrpsys ``ic``, eq. 3) is optional and off by default: with
``SafetyProfile(impedance=True)`` it follows the soft stopper (before the balancer); with
``wrench_reference=True`` the stopper passes the target's hand wrench references on to it,
reverted with the motion (:mod:`hubo_cli.control.wrench`).
The limiter must stay last: it is what guarantees the limits.

A :class:`SafetyProfile` decides the order and the options of one run's pipeline; every robot
command builds its pipeline through one, so ``--no-estop`` means the same everywhere.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace

from hubo_cli.control.balance import BALANCE_MODES
from hubo_cli.control.estop import SOFT_SOURCES
from hubo_cli.control.module import Module
from hubo_cli.control.stop_choice import ActiveStops
from hubo_cli.control.wrench import HAND_WRENCH_PLAN, HAND_WRENCH_REF, WRENCH_AXES
from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import ARMS, RobotModel

BALANCE_CHOICES = (*BALANCE_MODES, "off")  # ``--balance``: a balancer's mode, or none
DEFAULT_ORDER = ("otg", "capture-point", "estop", "balance", "collision", "hard-estop",
                 "limiter")
GENERATORS = ("otg", "hoff-arbib")


def _otg(model, dt_s, **options):
    from hubo_cli.control.otg import TrajectoryGenerator
    return TrajectoryGenerator(model, dt_s, **options)


def _hoff_arbib(model, dt_s, **options):
    from hubo_cli.control.hoff_arbib import HoffArbibGenerator
    return HoffArbibGenerator(model, dt_s, **options)


def _estop(model, dt_s, **options):
    from hubo_cli.control.estop import EmergencyStopper
    return EmergencyStopper(model, dt_s, **options)


def _hard_estop(model, dt_s, **options):
    from hubo_cli.control.estop import HARD_SOURCES, EmergencyStopper
    options.setdefault("sources", HARD_SOURCES)
    options.setdefault("revert_s", dt_s)
    options.setdefault("stop_s", dt_s)
    return EmergencyStopper(model, dt_s, name="hard-estop", **options)


def _balance(model, dt_s, **options):
    from hubo_cli.control.balance import make_balancer
    # mode "default" (common + differential damping) or "paper" (eq. 11-12 as published);
    # it takes the period from each Cycle
    return make_balancer(model, **options)


def _stabilizer(model, dt_s, **options):
    from hubo_cli.control.stabilizer import Stabilizer
    return Stabilizer(model, dt_s, **options)


def _hip(model, dt_s, **options):
    from hubo_cli.control.hip_strategy import HipStrategy
    return HipStrategy(model, dt_s, **options)


def _collision(model, dt_s, **options):
    from hubo_cli.control.collision import CollisionDetector
    return CollisionDetector(model, dt_s, **options)


def _capture_point(model, dt_s, **options):
    from hubo_cli.control.capture_point import CapturePointMonitor
    return CapturePointMonitor(model, dt_s, **options)


def _impedance(model, dt_s, **options):
    from hubo_cli.control.impedance import ImpedanceController
    return ImpedanceController(model, dt_s, **options)


def _limiter(model, dt_s, **options):
    from hubo_cli.control.limiter import SoftErrorLimiter
    return SoftErrorLimiter(model, dt_s, **options)


FACTORIES: dict[str, Callable[..., Module]] = {
    "otg": _otg,
    "hoff-arbib": _hoff_arbib,
    "capture-point": _capture_point,
    "estop": _estop,
    "impedance": _impedance,
    "balance": _balance,
    "stabilizer": _stabilizer,
    "hip": _hip,
    "collision": _collision,
    "hard-estop": _hard_estop,
    "limiter": _limiter,
}


def parse_order(text: str) -> tuple[str, ...]:
    """Module names from a comma- or arrow-separated string (``"otg,estop,limiter"``)."""
    names = [n.strip() for n in text.replace("->", ",").split(",")]
    return tuple(n for n in names if n)


def build_pipeline(model: RobotModel, order: Iterable[str] = DEFAULT_ORDER,
                   dt_s: float | None = None, options: dict[str, dict] | None = None,
                   interpolator: str = "otg") -> list[Module]:
    """Create the modules named in ``order``.

    Args:
        model: the robot model.
        order: module names, first to last; ``limiter`` must be last.
        dt_s: the control period (s), default the model's.
        options: per-module keyword arguments, e.g. ``{"estop": {"revert_s": 1.0}}``.
        interpolator: ``otg`` (ruckig) or ``hoff-arbib``; replaces the generator in ``order``.
    """
    names = list(order)
    if interpolator not in GENERATORS:
        raise ConfigError(f"unknown interpolator {quoted(interpolator)}",
                          hint=f"use one of {', '.join(GENERATORS)}")
    names = [interpolator if n in GENERATORS else n for n in names]
    unknown = [n for n in names if n not in FACTORIES]
    if unknown:
        raise ConfigError(f"unknown pipeline module {quoted(unknown[0])}",
                          hint=f"use some of {', '.join(FACTORIES)}")
    if len(set(names)) != len(names):
        raise ConfigError("a pipeline module is listed twice", hint=", ".join(names))
    if not names or names[-1] != "limiter":
        raise ConfigError("the pipeline must end with the limiter",
                          hint="the soft error limiter is what keeps commands within limits")
    dt = model.control_period_s if dt_s is None else float(dt_s)
    options = options or {}
    return [FACTORIES[n](model, dt, **dict(options.get(n, {}))) for n in names]


def find_module(modules: list[Module], name: str) -> Module | None:
    """The module called ``name`` in a pipeline, or None."""
    for m in modules:
        if m.name == name:
            return m
    return None



@dataclass(frozen=True)
class SafetyProfile:
    """The safety layers of one run: which modules, in which order, with which options.

    Attributes:
        estop: the soft emergency stopper with its sources (operator key, capture point, wrist
            torque, stale input). ``--no-estop`` turns it off: the stopper leaves the pipeline
            and the capture-point monitor only measures (its margin is still logged); the hard
            stopper, the collision detector and the limiter always stay.
        sources: the stop requests the soft stopper acts on (a subset of SOFT_SOURCES).
        removed, removed_by: the sources the command line removed and its option (see
            :mod:`hubo_cli.control.stop_choice`, the one place that decides them).
        revert_s, stop_s: eq. 15's T1 and T2 (s).
        wrist_torque_limit_nm: the wrist-torque stop's limit (N m; None = the model's).
        interpolator: ``otg`` (ruckig) or ``hoff-arbib`` (eq. 1).
        balance: run the ankle balancer.
        balance_mode: ``default`` (common + differential damping) or ``paper`` (eq. 11-12 as
            published); see :func:`hubo_cli.control.balance.make_balancer`.
        stabilizer: with the default balancer, add the CoM/ZMP feedback on the waist
            (:class:`hubo_cli.control.stabilizer.Stabilizer`); off by default (under the
            legs' 0.6 rad/s^2 it does not yet help a 90 N push); the paper's mode runs
            without it.
        hip_strategy: add the hip strategy before the collision detector
            (:class:`hubo_cli.control.hip_strategy.HipStrategy`: the trunk bows when the
            capture point nears the toes or heels); off by default, on in the standing
            experiment, whose legs run the ``walking`` limit set it needs.
        tracker_groups: how ``otg`` groups the joints: ``body`` (one tracker, every joint
            arrives together) or ``limbs`` (one tracker per arm and one for the legs:
            teleoperation's hands keep their own pace); see
            :func:`hubo_cli.control.otg.tracker_groups`.
        impedance: add the ImpedanceController (eq. 3, :mod:`hubo_cli.control.impedance`)
            right after the soft stopper (hrpsys ``es -> ic``) on both hands, with the robot
            file's ``[impedance]`` gains; off by default.
        tracker_sync: within each of ``otg``'s trackers, ``phase`` (the joints arrive together
            on a straight line in joint space) or ``none`` (each joint time-optimal).
        wrench_reference: the target writes hand wrench references
            (:mod:`hubo_cli.control.wrench`): the soft stopper reverts them with the motion and
            the impedance controller (if on) takes them as its force setpoint.
        impedance_arms, impedance_axes: the hands the impedance controller acts on and the
            axes they yield along (neck-frame ``x y z rx ry rz``).
        impedance_active: it starts switched on (False: off until a target writes
            ``IMPEDANCE_ON``, e.g. a task once its plan runs).
        limit_set: the robot file's joint-limit set the limiter enforces (``table4``, the
            paper's, or e.g. ``walking``, whose legs are fast enough to step and to bow the
            trunk); None: the set the run's model was loaded with. Where a use case needs a
            set (the standing experiment's hip strategy or stepping) it names it here, and
            :class:`~hubo_cli.session.RunSetup` refuses a model that carries another.
    """

    estop: bool = True
    sources: tuple[str, ...] = SOFT_SOURCES
    revert_s: float = 0.5
    stop_s: float = 0.5
    wrist_torque_limit_nm: float | None = None
    interpolator: str = "otg"
    balance: bool = True
    balance_mode: str = "default"
    stabilizer: bool = False
    hip_strategy: bool = False
    tracker_groups: str = "body"
    tracker_sync: str = "phase"
    impedance: bool = False
    wrench_reference: bool = False
    impedance_arms: tuple[str, ...] = ARMS
    impedance_axes: tuple[str, ...] = WRENCH_AXES
    impedance_active: bool = True
    removed: tuple[str, ...] = ()
    removed_by: str = ""
    limit_set: str | None = None

    def __post_init__(self) -> None:
        if self.balance_mode not in BALANCE_MODES:
            raise ConfigError(f"unknown balance mode {quoted(self.balance_mode)}",
                              hint=f"use {', '.join(BALANCE_MODES)} (or balance off)")
        unknown = set(self.sources) - set(SOFT_SOURCES)
        if unknown:
            raise ConfigError(f"unknown emergency-stop source {quoted(sorted(unknown)[0])}",
                              hint=f"use some of {', '.join(SOFT_SOURCES)}")
        from hubo_cli.control.otg import TRACKER_GROUPS
        from hubo_cli.motion.tracker import SYNCHRONIZATIONS

        if self.tracker_groups not in TRACKER_GROUPS:
            raise ConfigError(f"unknown tracker groups {quoted(self.tracker_groups)}",
                              hint=f"use one of {', '.join(TRACKER_GROUPS)}")
        if self.tracker_sync not in SYNCHRONIZATIONS:
            raise ConfigError(f"unknown tracker synchronization {quoted(self.tracker_sync)}",
                              hint=f"use one of {', '.join(SYNCHRONIZATIONS)}")

    @property
    def active_sources(self) -> tuple[str, ...]:
        """The sources the soft stopper acts on in this run (none without it)."""
        return tuple(self.sources) if self.estop else ()

    def with_stops(self, stops: ActiveStops | None) -> SafetyProfile:
        """This profile with the stop sources :func:`~hubo_cli.control.stop_choice.decide_stops`
        decided (None: this profile's own); no source leaves the soft stopper out."""
        if stops is None:
            return self
        return replace(self, estop=bool(stops.sources), sources=stops.sources or self.sources,
                       removed=stops.removed, removed_by=stops.by)

    @property
    def balance_choice(self) -> str:
        """The balancer as ``--balance`` names it: its mode, or ``off``."""
        return self.balance_mode if self.balance else "off"

    def with_balance(self, choice: str) -> SafetyProfile:
        """This profile with the balancer ``--balance CHOICE`` names (one of BALANCE_CHOICES:
        ``default``, ``paper`` or ``off``)."""
        if choice not in BALANCE_CHOICES:
            raise ConfigError(f"unknown balance choice {quoted(choice)}",
                              hint=f"use one of {', '.join(BALANCE_CHOICES)}")
        if choice == "off":
            return replace(self, balance=False)
        return replace(self, balance=True, balance_mode=choice)

    def order(self) -> tuple[str, ...]:
        """Module names, first to last."""
        dropped = set()
        if not self.estop:
            dropped.add("estop")
        if not self.balance:
            dropped.add("balance")
        order = tuple(n for n in DEFAULT_ORDER if n not in dropped)
        if self.stabilizer and self.balance and self.balance_mode != "paper":
            k = order.index("balance") + 1  # hrpsys: abc -> st
            order = order[:k] + ("stabilizer",) + order[k:]
        if self.impedance:  # hrpsys: es -> ic -> abc
            k = order.index("capture-point") + 1 + ("estop" in order)
            order = order[:k] + ("impedance",) + order[k:]
        if self.hip_strategy:
            k = order.index("collision")
            order = order[:k] + ("hip",) + order[k:]
        return order

    def options(self, tools: Mapping[str, str]) -> dict[str, dict]:
        """Per-module options for a robot holding ``tools`` (arm -> tool)."""
        drill = tools.get("right-arm") == "drill"
        reference = None
        if self.wrench_reference:
            reference = HAND_WRENCH_REF if self.estop else HAND_WRENCH_PLAN
        return {
            "otg": {"groups": self.tracker_groups, "synchronization": self.tracker_sync},
            "estop": {"sources": tuple(self.sources), "revert_s": self.revert_s,
                      "stop_s": self.stop_s,
                      "wrist_torque_limit_nm": self.wrist_torque_limit_nm,
                      "wrench_reference": self.wrench_reference},
            "impedance": {"reference": reference, "arms": tuple(self.impedance_arms),
                          "axes": tuple(self.impedance_axes),
                          "active": self.impedance_active, "tools": dict(tools)},
            "capture-point": {"request_estop": self.estop, "drill": drill},
            "collision": {"drill": drill},
            "balance": {"mode": self.balance_mode, "drill": drill},
            "stabilizer": {"drill": drill},
        }

    def build(self, model: RobotModel, dt_s: float, tools: Mapping[str, str]) -> list[Module]:
        """The pipeline for a robot holding ``tools`` at control period ``dt_s`` (s)."""
        return build_pipeline(model, self.order(), dt_s, self.options(tools), self.interpolator)
