"""The safety state the operator must always see, as a rich renderable: read from what the
control loop records of the pipeline each period (the modules' published status), never from a
module.

One line per concern, each in words and in colour: the emergency stop (its source; stopping,
held, or blending back after a release; the key that releases it), the collision layer (holding
or recovering, which pair, how close), the balance (torso tilt, the capture point's support
margin now and at worst, the feet's load and contact losses, ankle clamps), the loop's timing
(overruns and the wall time skipped, once there are any), and per hand the clutch (waiting for
a re-centre), stale input and the reach limit. A new stop rings the terminal bell and flashes
the line for a second. Above them all, while the driver reports it, the robot's own trouble
(STATE STALE). Each concern is one function of :data:`SAFETY_LINES`: a new one is one
function and one entry there.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

from rich.text import Text

from hubo_cli.control.capture_point import CP_MARGIN_M
from hubo_cli.control.status import CollisionStatus, LimiterStatus, StopperStatus, SupportStatus

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
class BalanceWatch:
    """How well the body is held so far (the balance figures of ``summary.json``, live).

    Attributes:
        balancer: a balance module is in the pipeline (``--balance`` not ``off``).
        max_tilt_deg: the torso's largest tilt so far (simulator), None if unknown.
        margin_m, min_margin_m: the capture point's distance inside the support polygon now
            and its smallest so far (m), None without the capture-point monitor.
        min_margin_t_s: when the smallest margin was.
        feet_loaded: (right, left) in contact now, None unknown.
        contact_losses: intervals > 20 ms with a foot unloaded so far.
        ankle_clamp_fraction: share of periods so far with an ankle at the limiter's clamp.
    """

    balancer: bool = True
    max_tilt_deg: float | None = None
    margin_m: float | None = None
    min_margin_m: float | None = None
    min_margin_t_s: float | None = None
    feet_loaded: tuple[bool, bool] | None = None
    contact_losses: int = 0
    ankle_clamp_fraction: float | None = None


@dataclass
class SafetyState:
    """A snapshot of the pipeline's safety layers.

    Attributes:
        estop: ``off`` (nothing latched), ``stopping``, ``held`` or ``releasing``.
        soft_estop: the soft emergency stopper is in the pipeline (not ``--no-estop``).
        active_sources: what the soft stopper acts on (``--estop-sources``).
        estop_sources: the sources of the latest stop.
        stops: emergency stops latched so far (releases not counted).
        collision: ``clear``, ``holding`` or ``recovering``.
        collision_pair: the closest pair of link names.
        collision_distance_m: its distance (m; negative: overlapping), None if unknown.
        hands: per driven hand, its input and reach state.
        balance: how well the body is held (None: not read).
        overruns: periods the control loop ran so late that it re-anchored its schedule.
        skipped_s: the wall time skipped at those re-anchors (s).
        robot: the driver's trouble in words ("" when none), e.g. a stale robot state.
    """

    estop: str = "off"
    soft_estop: bool = False
    active_sources: tuple[str, ...] = ()
    estop_sources: tuple[str, ...] = ()
    stops: int = 0
    collision: str = "clear"
    collision_pair: tuple[str, str] | None = None
    collision_distance_m: float | None = None
    hands: list[HandSafety] = field(default_factory=list)
    balance: BalanceWatch | None = None
    overruns: int = 0
    skipped_s: float = 0.0
    robot: str = ""


# the stopper's modes (control.estop.MODES but release) as the view says them; while stopped
# (STOPPED_HOW), how the stop goes
ESTOP_WORDS = {"stop": "stopping", "finish": "finishing", "hold": "held", "recover": "releasing"}
STOPPED_HOW = {"stopping": "reverting", "finishing": "finishing the step", "held": "held"}
COLLISION_WORDS = {"hold": "holding", "recover": "recovering"}
ROBOT_WORDS = {  # driver flags of the robot's state the operator must see
    "stale-state": "STATE STALE: no fresh robot state — braked and holding; the run ends",
    "stale-hold": "STATE STALE: robot state back — held, not resumed; the run ends",
}


def read_balance(published: Mapping[str, object], world=None) -> BalanceWatch:
    """How well the body is held so far: from what the capture-point monitor and the limiter
    published (``published``: the loop's record, module name -> status snapshot), and the
    simulator's true tilt where there is one (``world``: a viewer may show the truth)."""
    watch = BalanceWatch(balancer="balance" in published,
                         max_tilt_deg=None if world is None else world.max_tilt_deg)
    for status in published.values():
        if isinstance(status, SupportStatus):
            watch.margin_m = status.margin_m
            watch.min_margin_m = status.min_margin_m
            watch.min_margin_t_s = status.min_margin_t_s
            watch.feet_loaded = status.feet_loaded
            watch.contact_losses = status.contact_losses
        elif isinstance(status, LimiterStatus):
            watch.ankle_clamp_fraction = status.ankle_clamp_fraction
    return watch


def read_safety(loop=None, hands: Iterable[HandSafety] = (), world=None,
                robot_flags: Iterable[str] = ()) -> SafetyState:
    """The safety state the control ``loop``'s record says (its ``module_status``: what the
    soft and hard emergency stoppers, the collision detector, and for the balance line the
    capture-point monitor and the limiter published; its overruns and skipped wall time; None:
    no loop yet); ``world``: the simulator, for the torso's true tilt; ``robot_flags``: the
    flags of the robot's latest state (the driver's trouble)."""
    published: Mapping[str, object] = {} if loop is None else loop.module_status
    robot = next((ROBOT_WORDS[f] for f in robot_flags if f in ROBOT_WORDS), "")
    state = SafetyState(hands=list(hands), balance=read_balance(published, world), robot=robot)
    if loop is not None:
        state.overruns, state.skipped_s = loop.overruns, loop.skipped_s
    latest = None
    for name, status in published.items():
        if isinstance(status, StopperStatus):
            if name == "estop":
                state.soft_estop, state.active_sources = True, status.sources
            state.stops += status.stops
            if status.mode != "release" and (latest is None or status.mode == "hold"):
                latest = status
        elif isinstance(status, CollisionStatus):
            state.collision = COLLISION_WORDS.get(status.mode, "clear")
            if status.pair is not None:
                state.collision_pair = status.pair
                state.collision_distance_m = status.distance_m
    if latest is not None:
        state.estop = ESTOP_WORDS[latest.mode]
        state.estop_sources = latest.last_stop_sources
    return state


def _pair(pair: tuple[str, str] | None) -> str:
    if not pair:
        return "-"
    return " / ".join(name.rsplit("_", 1)[0] if name.rsplit("_", 1)[-1].isdigit() else name
                      for name in pair)


@dataclass(frozen=True)
class Look:
    """How the view shows the state: flashing (a new stop), and the key that releases a stop
    (None: none, e.g. a scripted task)."""

    flash: bool = False
    release_key: str | None = "r"


def _estop_line(state: SafetyState, look: Look) -> Text:
    sources = ", ".join(state.estop_sources) or "unknown"
    if state.estop in STOPPED_HOW:
        how = STOPPED_HOW[state.estop]
        key = f" — press {look.release_key} to release" if look.release_key else ""
        text = Text(f"E-STOP ({sources}){key} ({how})",
                    style="bold white on red" if look.flash else "bold red")
    elif state.estop == "releasing":
        text = Text(f"e-stop ({sources}) released — blending back", style="yellow")
    else:
        text = Text(f"e-stop ready ({', '.join(state.active_sources)})" if state.soft_estop
                    else "e-stop disabled: no stop source (command line)",
                    style="green" if state.soft_estop else "yellow")
    text.append(f"   stops {state.stops}", style="dim")
    return text


def _robot_line(state: SafetyState, look: Look) -> Text | None:
    """Only while the driver reports trouble, e.g. no fresh robot state."""
    if not state.robot:
        return None
    return Text(state.robot, style="bold white on red" if look.flash else "bold red")


def _collision_line(state: SafetyState, look: Look) -> Text:
    distance = ("-" if state.collision_distance_m is None
                else f"{state.collision_distance_m * 1000:+.0f} mm")
    pair = _pair(state.collision_pair)
    if state.collision == "holding":
        return Text(f"COLLISION HOLD: {pair} at {distance}", style="bold red")
    if state.collision == "recovering":
        return Text(f"collision cleared, recovering: {pair} at {distance}", style="yellow")
    return Text(f"collision clear (closest {pair} {distance})", style="green")


def _balance_line(state: SafetyState, look: Look) -> Text | None:
    if state.balance is None:
        return None
    text = Text()
    _balance_text(text, state.balance)
    return text


def _timing_line(state: SafetyState, look: Look) -> Text | None:
    """Only once the loop has fallen behind: overruns and the wall time they skipped."""
    if not state.overruns:
        return None
    return Text(f"LOOP LATE: {state.overruns} overrun{'s' * (state.overruns != 1)}, "
                f"{state.skipped_s:.1f} s of wall time skipped (the machine is too busy)",
                style="bold yellow")


def _hand_lines(state: SafetyState, look: Look) -> Text | None:
    lines = []
    for hand in state.hands:
        if hand.needs_clutch:
            text = Text(f"{hand.arm}: INPUT BACK — press c to re-centre (clutch); holding",
                        style="bold yellow")
        elif hand.stale:
            text = Text(f"{hand.arm}: STALE INPUT — holding", style="bold red")
        elif hand.calibrating:
            text = Text(f"{hand.arm}: waiting for the tracker (clutch)", style="yellow")
        else:
            text = Text(f"{hand.arm}: input ok", style="green")
        reach = REACH_STATUSES.get(hand.ik_status)
        if reach:
            text.append(f", {reach}", style="yellow" if hand.ik_status == "capped" else "red")
        lines.append(text)
    return Text("\n").join(lines) if lines else None


SAFETY_LINES: tuple[Callable[[SafetyState, Look], Text | None], ...] = (
    _robot_line, _estop_line, _collision_line, _balance_line, _timing_line, _hand_lines)


def safety_text(state: SafetyState, flash: bool = False, release_key: str | None = "r") -> Text:
    """The state in words and colour (one line per concern of :data:`SAFETY_LINES`)."""
    look = Look(flash, release_key)
    return Text("\n").join(line for build in SAFETY_LINES
                            if (line := build(state, look)) is not None)


def _balance_text(text: Text, watch: BalanceWatch) -> None:
    """One line: tilt, support margin (now, worst), feet, contact losses, ankle clamps."""
    text.append("balance " + ("on" if watch.balancer else "off"),
                style="green" if watch.balancer else "yellow")
    if watch.max_tilt_deg is not None:
        text.append(f" | tilt max {watch.max_tilt_deg:.2f}°")
    if watch.min_margin_m is not None:
        worst = watch.min_margin_m
        style = "bold red" if worst < CP_MARGIN_M else "yellow" if worst < 0.08 else "green"
        now = "-" if watch.margin_m is None else f"{watch.margin_m * 1000:.0f}"
        text.append(f" | support margin {now} mm (min {worst * 1000:.0f} mm at "
                    f"{watch.min_margin_t_s:.1f} s)", style=style)
    if watch.feet_loaded is not None:
        unloaded = [f for f, on in zip(("right", "left"), watch.feet_loaded, strict=True)
                    if not on]
        text.append(" | feet " + ("loaded" if not unloaded else
                                  f"{' and '.join(unloaded)} UNLOADED"),
                    style="yellow" if unloaded else "")
        text.append(f", contact losses {watch.contact_losses}",
                    style="yellow" if watch.contact_losses else "")
    if watch.ankle_clamp_fraction is not None:
        text.append(f" | ankle clamps {watch.ankle_clamp_fraction:.1%}",
                    style="yellow" if watch.ankle_clamp_fraction >= 0.01 else "")


def balance_summary_line(summary: dict) -> str:
    """The balance figures of a finished run's summary in one line of words (text output)."""
    parts = [f"--balance {summary.get('balance', 'default')}"]
    if summary.get("max_torso_tilt_deg") is not None:
        parts.append(f"tilt max {summary['max_torso_tilt_deg']:.2f}°")
    margin = summary.get("min_support_margin_mm")
    if margin is not None:
        parts.append(f"support margin min {margin:.0f} mm at "
                     f"{summary['min_support_margin_at']['t_s']:.1f} s")
    if summary.get("contact_losses") is not None:
        parts.append(f"contact losses {summary['contact_losses']}")
    if summary.get("ankle_clamp_fraction") is not None:
        parts.append(f"ankle clamps {summary['ankle_clamp_fraction']:.1%}")
    if summary.get("cutting_fraction") is not None:
        parts.append(f"flutes in the wall {summary['cutting_fraction']:.0%} of the cut")
    return ", ".join(parts)


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

    def alarm(self) -> tuple:
        """What must be shown as soon as it changes (plain lines): the stop and collision
        states, the overruns, and each hand's input state."""
        state = self.read()
        return (state.robot, state.estop, state.estop_sources, state.collision, state.overruns,
                tuple((h.stale, h.needs_clutch, h.calibrating) for h in state.hands))

    def words(self) -> str:
        """The state as plain words on one line (for piped output)."""
        return " | ".join(safety_text(self.read(), release_key=self.release_key).plain
                          .splitlines())
