"""Building the ordered module list from names.

hrpsys-base chains ``seq -> es -> ic -> abc -> st -> co -> hes -> el``; mapped onto this
project's modules the default is::

    otg -> capture-point -> estop -> balance -> collision -> hard-estop -> limiter

``otg`` (ruckig) is the sequence player, ``estop`` the soft emergency stopper, ``balance`` the
ankle balancer (in place of abc/st), ``collision`` the collision detector, ``hard-estop`` the
second stopper (freeze preset, reacting only to the ``hard`` source) and ``limiter`` the soft
error limiter. The capture-point monitor passes the command through; it sits before ``estop``
so that its request is seen in the same period. ``hoff-arbib`` can replace ``otg``.
The limiter must stay last: it is what guarantees the limits.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from hubo_cli.control.module import Module
from hubo_cli.errors import ConfigError
from hubo_cli.model import RobotModel

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


def _collision(model, dt_s, **options):
    from hubo_cli.control.collision import CollisionDetector
    return CollisionDetector(model, dt_s, **options)


def _capture_point(model, dt_s, **options):
    from hubo_cli.control.capture_point import CapturePointMonitor
    return CapturePointMonitor(model, dt_s, **options)


def _limiter(model, dt_s, **options):
    from hubo_cli.control.limiter import SoftErrorLimiter
    return SoftErrorLimiter(model, dt_s, **options)


FACTORIES: dict[str, Callable[..., Module]] = {
    "otg": _otg,
    "hoff-arbib": _hoff_arbib,
    "capture-point": _capture_point,
    "estop": _estop,
    "balance": _balance,
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
        raise ConfigError(f"unknown interpolator {interpolator!r}",
                          hint=f"use one of {', '.join(GENERATORS)}")
    names = [interpolator if n in GENERATORS else n for n in names]
    unknown = [n for n in names if n not in FACTORIES]
    if unknown:
        raise ConfigError(f"unknown pipeline module {unknown[0]!r}",
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
