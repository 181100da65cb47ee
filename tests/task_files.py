"""Small task files the tests run: raise (or move) the drill 50 mm off the wall, then hold it;
or a short cut (drill in, cut 20 mm, pull out)."""

from __future__ import annotations

DRILL_STANCE = 'arm = "right"\ntool = "drill"\n'  # the right hand holds the drill


def _task(name: str, description: str, stance: str, steps: str) -> str:
    """A task file's text: its name, description, the automatic stance with ``stance``'s
    lines added, then ``steps`` (the ``[[steps]]`` tables)."""
    return f"""\
name = "{name}"
description = "{description}"

[stance]
wall_distance_mm = "auto"
centre_mm = "auto"
{stance}
{steps}"""


def _raise(to_mm: tuple[float, float] | None) -> str:
    """The first step: a 1 s move 50 mm off the wall (to ``to_mm`` on it, if given)."""
    to = "" if to_mm is None else f"to_mm = [{to_mm[0]:g}, {to_mm[1]:g}]\n"
    return f"""\
[[steps]]
kind = "move"
name = "raise the drill"
depth_mm = -50.0
{to}duration_s = 1.0
"""


def raise_and_hold(name: str, hold_s: float, *, stance: str = "",
                   to_mm: tuple[float, float] | None = None) -> str:
    """A task file's text: a 1 s move that raises the drill (to ``to_mm`` on the wall, mm, if
    given), then a wait of ``hold_s`` (s); ``stance``: more lines for its ``[stance]`` table
    (e.g. :data:`DRILL_STANCE`)."""
    return _task(name, "Raise the drill and hold it", stance, f"""\
{_raise(to_mm)}
[[steps]]
kind = "wait"
name = "hold"
duration_s = {hold_s:g}
""")


def short_cut(name: str = "short-cut") -> str:
    """A task file's text: the drill raised, in, a 20 mm cut, out (the right hand)."""
    return _task(name, "Raise the drill, drill in, cut 20 mm, pull out", DRILL_STANCE, f"""\
{_raise(None)}
[[steps]]
kind = "plunge"
name = "drill in"
depth_mm = 2.5
speed_mm_s = 50.0

[[steps]]
kind = "follow"
name = "cut"
path = "polyline"
points_mm = [[10.0, 0.0], [-10.0, 0.0]]
speed_mm_s = 20.0
accel_mm_s2 = 100.0

[[steps]]
kind = "retract"
name = "pull out"
depth_mm = -50.0
speed_mm_s = 50.0
""")
