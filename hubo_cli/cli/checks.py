"""Checks of command-line values shared by several commands (bad values exit 2, nothing runs)."""

from __future__ import annotations

import math

import click

from hubo_cli.errors import InputError

FASTRAK_BAUDS = (300, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)


def check_baud(ctx, param, value: int) -> int:
    """A click callback: a FASTRAK line rate (the unit's I/O switches offer only these)."""
    if value not in FASTRAK_BAUDS:
        raise click.BadParameter(f"{value} is not a FASTRAK baud rate; use one of "
                                 f"{', '.join(map(str, FASTRAK_BAUDS))}")
    return value


def check_seconds(option: str, value: float | None, maximum_s: float = 24 * 3600) -> None:
    """``value`` (None allowed) must be a positive, finite time of at most ``maximum_s``.

    Raises:
        InputError: naming the option.
    """
    if value is not None and not (math.isfinite(value) and 0 < value <= maximum_s):
        raise InputError(f"{option} {value:g} must be a positive number of seconds (at most "
                         f"{maximum_s:g})", hint=f"e.g. {option} 10")
