"""When the robot has fallen: one criterion for every experiment (hrpsys Stabilizer's TILT check).

The torso tilts more than ``FALL_TILT_DEG`` from upright (the angle between its z axis and the
world's, :func:`hubo_cli.geometry.tilt_rad_of_matrix`), or drops more than ``FALL_DROP_M``
below its start height (on the floor).
"""

from __future__ import annotations

FALL_TILT_DEG = 30.0  # hrpsys Stabilizer tilt_margin default
FALL_DROP_M = 0.2     # torso this much below its start height = on the floor


def has_fallen(tilt_deg: float, drop_m: float) -> bool:
    """True if a torso tilt of ``tilt_deg`` (deg) or a drop of ``drop_m`` (m, positive down
    from the start height) is a fall."""
    return tilt_deg > FALL_TILT_DEG or drop_m > FALL_DROP_M
