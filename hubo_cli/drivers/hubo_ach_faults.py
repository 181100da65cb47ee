"""Faults a daemon plays on request (``hubo hardware sim-daemon --fault SPEC``), as a real
robot's bus and motors would show them in ``hubo-state``.

A spec is a kind and ``key=value`` fields, comma separated; times are seconds after the first
``hubo-ref`` frame the daemon reads (the client's first reference, after its start-up delay),
on the simulated robot's clock (the daemon's periods; a loaded machine's late ones do not
count):

- ``missing,at=S,for=S``: no state is published for that long (a dead bus, a hung daemon);
- ``late,at=S,for=S,by=S``: each state published is the one measured ``by`` seconds earlier
  (rounded to whole periods), its ``time`` with it (a state older than the reference it
  answers);
- ``frozen,joint=NAME,at=S``: the limb joint stops where it is (a jammed gear): its encoder
  stays, its motor's reference keeps following the references, ``status[].jam`` is set;
- ``hot,joint=NAME,at=S,rate=K_PER_S``: that motor heats ``rate`` kelvin per second faster
  than its load makes it (``joint[].tmp`` climbs; ``status[].tempError`` past the board's
  limit).

``for`` may be left out for ``missing`` and ``late``: until the daemon stops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hubo_cli.errors import InputError, quoted

FIELDS = {"missing": {"at", "for"}, "late": {"at", "for", "by"}, "frozen": {"joint", "at"},
          "hot": {"joint", "at", "rate"}}
REQUIRED = {"missing": {"at"}, "late": {"at", "by"}, "frozen": {"joint", "at"},
            "hot": {"joint", "at", "rate"}}
BODY_FAULTS = ("frozen", "hot")  # played by the body (its motors); the others by the daemon
HINT = ("e.g. --fault frozen,joint=REB,at=2  --fault hot,joint=RKN,at=1,rate=10  "
        "--fault missing,at=3,for=0.3  --fault late,at=3,for=1,by=0.05")
MAX_S = 7 * 24 * 3600.0
# the daemon keeps every state of the last ``by`` seconds: 10 s is 2,000 states (8 MB), far past
# the hardware driver's 0.1 s stale limit; a motor heated 1,000 K/s is at any limit at once
MAX = {"at": MAX_S, "for": MAX_S, "by": 10.0, "rate": 1000.0}


@dataclass(frozen=True)
class Fault:
    """One requested fault.

    Attributes:
        kind: ``missing``, ``late``, ``frozen`` or ``hot``.
        at_s: when it begins (s after the first reference frame).
        for_s: how long it lasts (``missing``, ``late``; None: to the end).
        joint: the limb joint (``frozen``, ``hot``).
        by_s: how old the published state is (``late``).
        rate_k_s: the extra heating (``hot``, K/s).
    """

    kind: str
    at_s: float
    for_s: float | None = None
    joint: str | None = None
    by_s: float = 0.0
    rate_k_s: float = 0.0

    def active(self, t_s: float) -> bool:
        """Whether a timed fault (``missing``, ``late``) is on at ``t_s``."""
        return t_s >= self.at_s and (self.for_s is None or t_s < self.at_s + self.for_s)

    def describe(self) -> str:
        """The spec again (for reports)."""
        parts = [self.kind] + [f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                               for k, v in (("joint", self.joint), ("at", self.at_s),
                                            ("for", self.for_s), ("by", self.by_s),
                                            ("rate", self.rate_k_s))
                               if k in FIELDS[self.kind] and v is not None]
        return ",".join(parts)


def parse_fault(spec: str, joint_names) -> Fault:
    """A :class:`Fault` from its spec; ``joint_names``: the limb joints a fault may name.

    Raises:
        InputError: an unknown kind or field, a missing one, a value that is not a finite
            number in range, or an unknown joint.
    """
    text = str(spec).strip()
    kind, *pairs = [part.strip() for part in text.split(",")]
    if kind not in FIELDS:
        raise InputError(f"--fault {quoted(text)}: unknown kind {quoted(kind)} (one of "
                         f"{', '.join(FIELDS)})", hint=HINT)
    values: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or key not in FIELDS[kind] or key in values:
            raise InputError(f"--fault {quoted(text)}: {quoted(pair)} is not one of {kind}'s "
                             f"fields ({', '.join(sorted(FIELDS[kind]))}=VALUE, each once)",
                             hint=HINT)
        values[key] = value.strip()
    missing = REQUIRED[kind] - values.keys()
    if missing:
        raise InputError(f"--fault {quoted(text)}: {kind} needs {', '.join(sorted(missing))}",
                         hint=HINT)
    numbers = {}
    for key in values.keys() - {"joint"}:
        try:
            number = float(values[key])
        except ValueError:
            number = math.nan
        low = 0.0 if key == "at" else 1e-9  # for, by, rate: more than 0
        if not (math.isfinite(number) and low <= number <= MAX[key]):
            unit = "kelvin per second" if key == "rate" else "seconds"
            raise InputError(f"--fault {quoted(text)}: {key}={quoted(values[key])} is not a "
                             f"number of {unit} in {'[0' if key == 'at' else '(0'}, {MAX[key]:g}]",
                             hint=HINT)
        numbers[key] = number
    joint = values.get("joint")
    if joint is not None and joint not in joint_names:
        raise InputError(f"--fault {quoted(text)}: {quoted(joint)} is not a limb joint "
                         f"({', '.join(joint_names)})", hint=HINT)
    return Fault(kind, numbers["at"], numbers.get("for"), joint, numbers.get("by", 0.0),
                 numbers.get("rate", 0.0))


PUSH_HINT = "e.g. --push 120,at=3,dir=forward  (dir forward, backward, left or right; for=0.2 s)"
PUSH_FOR_S = 0.2  # as hubo sim --push


@dataclass(frozen=True)
class Push:
    """A push on the simulated torso (``hubo hardware sim-daemon --push SPEC``): ``force_n``
    along ``direction`` (a name of :data:`~hubo_cli.experiments.standing.PUSH_DIRECTIONS`)
    from ``at_s`` (s after the first reference frame, as a fault's) for ``for_s``."""

    force_n: float
    at_s: float
    direction: str = "forward"
    for_s: float = PUSH_FOR_S

    def describe(self) -> str:
        return f"{self.force_n:g},at={self.at_s:g},dir={self.direction},for={self.for_s:g}"


def parse_push(spec: str) -> Push:
    """A :class:`Push` from ``N,at=S[,dir=NAME][,for=S]``.

    Raises:
        InputError: a force that is not a number of 0 to MAX_PUSH_N newtons, an unknown
            field or direction, a time out of range.
    """
    from hubo_cli.experiments.standing import MAX_PUSH_N, PUSH_DIRECTIONS

    text = str(spec).strip()
    force, *pairs = [part.strip() for part in text.split(",")]
    values: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or key not in ("at", "dir", "for") or key in values:
            raise InputError(f"--push {quoted(text)}: {quoted(pair)} is not one of its fields "
                             "(at=S, dir=NAME, for=S, each once)", hint=PUSH_HINT)
        values[key] = value.strip()
    if "at" not in values:
        raise InputError(f"--push {quoted(text)}: when? it needs at=S", hint=PUSH_HINT)
    direction = values.get("dir", "forward")
    if direction not in PUSH_DIRECTIONS:
        raise InputError(f"--push {quoted(text)}: dir={quoted(direction)} is not one of "
                         f"{', '.join(PUSH_DIRECTIONS)}", hint=PUSH_HINT)
    numbers = {}
    for key, text_value, low, high in (("force", force, 0.0, MAX_PUSH_N),
                                       ("at", values["at"], 0.0, MAX_S),
                                       ("for", values.get("for", str(PUSH_FOR_S)), 1e-9, 10.0)):
        try:
            number = float(text_value)
        except ValueError:
            number = math.nan
        if not (math.isfinite(number) and low <= number <= high):
            raise InputError(f"--push {quoted(text)}: {key} {quoted(text_value)} is not a "
                             f"number in [{low:g}, {high:g}]", hint=PUSH_HINT)
        numbers[key] = number
    return Push(numbers["force"], numbers["at"], direction, numbers["for"])
