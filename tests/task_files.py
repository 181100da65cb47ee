"""Small task files the tests run: raise the drill 50 mm off the wall, then hold it."""

from __future__ import annotations


def raise_and_hold(name: str, hold_s: float, *, stance: str = "") -> str:
    """A task file's text: a 1 s move that raises the drill, then a wait of ``hold_s`` (s);
    ``stance``: more lines for its ``[stance]`` table (e.g. the arm and the tool)."""
    return f"""\
name = "{name}"
description = "Raise the drill and hold it"

[stance]
wall_distance_mm = "auto"
centre_mm = "auto"
{stance}
[[steps]]
kind = "move"
name = "raise the drill"
depth_mm = -50.0
duration_s = 1.0

[[steps]]
kind = "wait"
name = "hold"
duration_s = {hold_s:g}
"""
