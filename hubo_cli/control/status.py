"""The per-period status code: one number saying what the safety layers did this period.

Modules report by adding flags to :attr:`Cycle.flags`; the loop folds the flags of one period
into the single most serious :class:`Status` (higher value = more serious) and logs it.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class Status(IntEnum):
    """What the pipeline did in one period, most serious wins."""

    OK = 0
    SLOWING = 1        # a generator or the limiter slowed the command (rate/acceleration clamp)
    HOLDING = 2        # no target yet, or some joints kept their last target (NaN input)
    STALE_INPUT = 3    # no new target for longer than the stale timeout: stopping smoothly
    JOINT_LIMIT = 4    # a target or the command was clamped at a joint position limit
    COLLISION = 5      # the collision detector holds (or recovers from) a colliding posture
    ESTOPPED = 6       # an emergency stopper reverts, holds or blends back after release
    SERVO_OFF = 7      # the driver reports its servos off
    STATE_STALE = 8    # no fresh robot state: the driver brakes and holds, the run ends

    @property
    def label(self) -> str:
        """Lower-case words (``"stale input"``, ``"e-stopped"``)."""
        if self is Status.ESTOPPED:
            return "e-stopped"
        return self.name.lower().replace("_", " ")


# flag -> status; a period's status is the most serious status among its flags.
FLAG_STATUS = {
    "slowing": Status.SLOWING,
    "recovering": Status.SLOWING,
    "smooth-stop": Status.SLOWING,
    "tracking-error": Status.SLOWING,
    "thermal": Status.SLOWING,  # the hardware driver slows a joint whose motor runs hot
    "holding": Status.HOLDING,
    "stale-input": Status.STALE_INPUT,
    "joint-limit": Status.JOINT_LIMIT,
    "collision": Status.COLLISION,
    "estop": Status.ESTOPPED,
    "servo-off": Status.SERVO_OFF,
    "stale-state": Status.STATE_STALE,
    "stale-hold": Status.STATE_STALE,
}


def status_from_flags(flags) -> Status:
    """The most serious :class:`Status` named by an iterable of flag strings."""
    best = Status.OK
    for flag in flags:
        status = FLAG_STATUS.get(flag)
        if status is not None and status > best:
            best = status
    return best


@dataclass
class SafetyEvent:
    """One thing a safety module did: time (s), kind (``stop``, ``release``, ``collision``,
    ``finish``, ``finish-deadline``) and the sources or link names involved."""

    t_s: float
    kind: str
    sources: tuple[str, ...]


# ------------------------------------------------------------- what modules publish to a viewer
# Each safety module answers ``status()`` with one of these small snapshots (declared on
# :class:`~hubo_cli.control.module.Module`); a viewer reads them, never a module's internals.


@dataclass(frozen=True)
class StopperStatus:
    """An emergency stopper's state: ``mode`` (``run``, ``stop``, ``hold``, ``release``), the
    sources it acts on, its stops so far (releases not counted) and the latest stop's
    sources."""

    mode: str
    sources: tuple[str, ...]
    stops: int
    last_stop_sources: tuple[str, ...]


@dataclass(frozen=True)
class CollisionStatus:
    """The collision detector's state: ``mode`` (``run``, ``hold``, ``recover``) and the
    closest pair of links with their distance (m; negative: overlapping), None if unknown."""

    mode: str
    pair: tuple[str, str] | None
    distance_m: float | None


@dataclass(frozen=True)
class SupportStatus:
    """The capture-point monitor's view of the balance: the capture point's margin inside the
    support polygon now and at its smallest (m, and when, s; None before a measurement), the
    feet in contact (right, left; the estimate's) and the contact losses so far."""

    margin_m: float | None
    min_margin_m: float | None
    min_margin_t_s: float | None
    feet_loaded: tuple[bool, bool] | None
    contact_losses: int


@dataclass(frozen=True)
class LimiterStatus:
    """The soft error limiter's share of periods with an ankle clamped (None before any)."""

    ankle_clamp_fraction: float | None
