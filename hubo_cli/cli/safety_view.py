"""The safety state the operator must always see, read from the pipeline, as a rich renderable.

One line per concern, each in words and in colour: the emergency stop (its source; stopping,
held, or blending back after a release; the key that releases it), the collision layer (holding
or recovering, which pair, how close), and per hand the clutch (waiting for a re-centre), stale
input and the reach limit. A new stop rings the terminal bell and flashes the line for a second.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from rich.text import Text

from hubo_cli.control.collision import CollisionDetector
from hubo_cli.control.estop import EmergencyStopper

FLASH_S = 1.0
REACH_STATUSES = {"capped": "at its reach limit (capped)", "held": "out of reach (held)",
                  "unreachable": "out of reach"}


@dataclass
class HandSafety:
    """What the operator must know about one hand (words for the view)."""

    arm: str
    stale: bool = False
    needs_clutch: bool = False
    calibrating: bool = False
    ik_status: str = "-"


@dataclass
class SafetyState:
    """A snapshot of the pipeline's safety layers.

    Attributes:
        estop: ``off`` (nothing latched), ``stopping``, ``held`` or ``releasing``.
        soft_estop: the soft emergency stopper is in the pipeline (not ``--no-estop``).
        estop_sources: the sources of the latest stop.
        stops: emergency stops latched so far (releases not counted).
        collision: ``clear``, ``holding`` or ``recovering``.
        collision_pair: the closest pair of link names.
        collision_distance_m: its distance (m; negative: overlapping), None if unknown.
        hands: per driven hand, its input and reach state.
    """

    estop: str = "off"
    soft_estop: bool = False
    estop_sources: tuple[str, ...] = ()
    stops: int = 0
    collision: str = "clear"
    collision_pair: tuple[str, str] | None = None
    collision_distance_m: float | None = None
    hands: list[HandSafety] = field(default_factory=list)


ESTOP_WORDS = {"stop": "stopping", "hold": "held", "recover": "releasing"}
COLLISION_WORDS = {"hold": "holding", "recover": "recovering"}


def read_safety(modules: Iterable, hands: Iterable[HandSafety] = ()) -> SafetyState:
    """The safety state of a pipeline's modules (the soft and hard emergency stoppers and the
    collision detector; others are ignored)."""
    state = SafetyState(hands=list(hands))
    latest = None
    for module in modules:
        if isinstance(module, EmergencyStopper):
            state.soft_estop |= module.name == "estop"
            stops = [e for e in module.events if e.kind == "stop"]
            state.stops += len(stops)
            if module.mode != "release" and (latest is None or module.mode == "hold"):
                latest = module
        elif isinstance(module, CollisionDetector):
            state.collision = COLLISION_WORDS.get(module.mode, "clear")
            clearance = module.last_clearance
            if clearance is not None:
                state.collision_pair = clearance.pair
                state.collision_distance_m = clearance.distance_m
    if latest is not None:
        state.estop = ESTOP_WORDS[latest.mode]
        stops = [e for e in latest.events if e.kind == "stop"]
        state.estop_sources = stops[-1].sources if stops else ()
    return state


def _pair(pair: tuple[str, str] | None) -> str:
    if not pair:
        return "-"
    return " / ".join(name.rsplit("_", 1)[0] if name.rsplit("_", 1)[-1].isdigit() else name
                      for name in pair)


def safety_text(state: SafetyState, flash: bool = False, release_key: str | None = "r") -> Text:
    """The state in words and colour (several lines)."""
    text = Text()
    sources = ", ".join(state.estop_sources) or "unknown"
    if state.estop in ("stopping", "held"):
        how = "reverting" if state.estop == "stopping" else "held"
        key = f" — press {release_key} to release" if release_key else ""
        style = "bold white on red" if flash else "bold red"
        text.append(f"E-STOP ({sources}){key} ({how})", style=style)
    elif state.estop == "releasing":
        text.append(f"e-stop ({sources}) released — blending back", style="yellow")
    else:
        text.append("e-stop ready" if state.soft_estop else "e-stop disabled (--no-estop)",
                    style="green" if state.soft_estop else "yellow")
    text.append(f"   stops {state.stops}", style="dim")
    text.append("\n")
    distance = ("-" if state.collision_distance_m is None
                else f"{state.collision_distance_m * 1000:+.0f} mm")
    if state.collision == "holding":
        text.append(f"COLLISION HOLD: {_pair(state.collision_pair)} at {distance}",
                    style="bold red")
    elif state.collision == "recovering":
        text.append(f"collision cleared, recovering: {_pair(state.collision_pair)} at "
                    f"{distance}", style="yellow")
    else:
        text.append(f"collision clear (closest {_pair(state.collision_pair)} {distance})",
                    style="green")
    for hand in state.hands:
        text.append("\n")
        if hand.needs_clutch:
            text.append(f"{hand.arm}: INPUT BACK — press c to re-centre (clutch); holding",
                        style="bold yellow")
        elif hand.stale:
            text.append(f"{hand.arm}: STALE INPUT — holding", style="bold red")
        elif hand.calibrating:
            text.append(f"{hand.arm}: waiting for the tracker (clutch)", style="yellow")
        else:
            text.append(f"{hand.arm}: input ok", style="green")
        reach = REACH_STATUSES.get(hand.ik_status)
        if reach:
            text.append(f", {reach}", style="yellow" if hand.ik_status == "capped" else "red")
    return text


class SafetyPanel:
    """Renders the safety state; rings the bell and flashes on every new stop.

    Args:
        read: returns the current :class:`SafetyState`.
        bell: called once per new stop (e.g. ``console.bell``).
        release_key: the key that releases a stop (None: none, e.g. a scripted task).
        clock: time source (s), injectable for tests.
    """

    def __init__(self, read: Callable[[], SafetyState], bell: Callable[[], None] | None = None,
                 release_key: str | None = "r",
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.read = read
        self.bell = bell
        self.release_key = release_key
        self.clock = clock
        self.stops_seen = 0
        self.flash_until = 0.0
        self.last = SafetyState()

    def __call__(self) -> Text:
        state = self.last = self.read()
        now = self.clock()
        if state.stops > self.stops_seen:
            self.stops_seen = state.stops
            self.flash_until = now + FLASH_S
            if self.bell is not None:
                self.bell()
        return safety_text(state, flash=now < self.flash_until, release_key=self.release_key)

    def words(self) -> str:
        """The state as plain words on one line (for piped output)."""
        return " | ".join(safety_text(self.read(), release_key=self.release_key).plain
                          .splitlines())
