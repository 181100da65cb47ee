"""How slowly a run, or a replay of one, may go against the wall clock: the one floor of
``--speed`` (times real time) and its check, used wherever a speed enters the library (a run's
set-up, a video, the replay window)."""

from __future__ import annotations

import math

from hubo_cli.errors import InputError

MIN_SPEED = 0.01  # the slowest pace: a 5 ms control period lasts 0.5 s of wall time


def check_speed(speed: float | None) -> float | None:
    """``speed`` (times real time; None: as fast as possible) as a float.

    Raises:
        InputError: NaN, infinity or a speed below :data:`MIN_SPEED` (at 1e-9 a Ctrl-C waited
            for days; a video at 1e-7 would have ten million frames a second of the run).
    """
    if speed is None:
        return None
    if not (math.isfinite(speed) and speed >= MIN_SPEED):
        raise InputError(f"--speed must be a number of at least {MIN_SPEED:g}, got {speed:g}",
                         hint="--speed 1 is real time, 2 twice as fast")
    return float(speed)
