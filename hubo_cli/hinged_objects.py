"""The hinged objects of the manipulation experiments (:class:`Valve`, :class:`Door`): what a
scene asks the simulator to build, checked once. The simulator's :class:`SimulatedWorld` takes
them, so they sit below the drivers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import ConfigError, quoted


@dataclass(frozen=True)
class Valve:
    """A valve wheel on a revolute joint, as in the DRC (world frame, m): a rim (a ring of
    ``radius_m`` with a round section of ``tube_radius_m``), a hub and three spokes, turning
    about the world x axis through ``centre_world_m``, on a stem ``stem_m`` long from a panel
    behind it. The joint brakes with a dry friction torque ``friction_nm`` (N m), as a valve
    stem's packing does. Its angle is positive clockwise as the robot sees it (about +x)."""

    centre_world_m: tuple[float, float, float]
    radius_m: float = 0.15
    tube_radius_m: float = 0.012
    friction_nm: float = 3.0
    mass_kg: float = 2.0
    stem_m: float = 0.10

    def __post_init__(self) -> None:
        _check_finite("valve centre_world_m", self.centre_world_m, 3)
        _check_positive("valve", radius_m=self.radius_m, tube_radius_m=self.tube_radius_m,
                        mass_kg=self.mass_kg, stem_m=self.stem_m)
        if isinstance(self.friction_nm, bool) or not (
                isinstance(self.friction_nm, int | float) and math.isfinite(self.friction_nm)
                and self.friction_nm >= 0):
            raise ConfigError(f"valve friction_nm must be >= 0 N m, got {quoted(self.friction_nm)}")
        if self.tube_radius_m >= self.radius_m:
            raise ConfigError("the valve's tube radius must be smaller than its radius")


@dataclass(frozen=True)
class Door:
    """A hinged door (world frame, m): its leaf's near face at x = ``near_face_x_m`` when
    closed, the hinge (a vertical axis) at y = ``hinge_y_m`` on the robot's left, the leaf
    ``width_m`` wide toward -y. ``opens`` says which way it turns from closed: ``away`` from
    the robot (a push door) or ``toward`` it (a pull door: pushed, it stands against its
    frame's stop). A closer holds it shut with ``closer_nm`` (N m) plus
    ``closer_nm_per_rad`` per radian open and damps it with ``closer_nm_s_per_rad``; the
    hinge brakes with a dry friction torque ``friction_nm``. Its angle is positive away from
    the robot (the free edge moving +x)."""

    near_face_x_m: float
    hinge_y_m: float
    opens: str = "away"
    width_m: float = 0.9
    height_m: float = 2.0
    thickness_m: float = 0.04
    mass_kg: float = 10.0
    closer_nm: float = 2.0
    closer_nm_per_rad: float = 10.0
    closer_nm_s_per_rad: float = 2.0
    friction_nm: float = 0.5
    max_open_rad: float = math.radians(100.0)

    def __post_init__(self) -> None:
        if self.opens not in DOOR_OPENS:
            raise ConfigError(f"a door opens {' or '.join(DOOR_OPENS)}, not {quoted(self.opens)}")
        _check_finite("door near_face_x_m, hinge_y_m", (self.near_face_x_m, self.hinge_y_m), 2)
        _check_positive("door", width_m=self.width_m, height_m=self.height_m,
                        thickness_m=self.thickness_m, mass_kg=self.mass_kg,
                        max_open_rad=self.max_open_rad)
        for name in ("closer_nm", "closer_nm_per_rad", "closer_nm_s_per_rad", "friction_nm"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, int | float)
                                               and math.isfinite(value) and value >= 0):
                raise ConfigError(f"door {name} must be >= 0, got {quoted(value)}")

    @property
    def limits_rad(self) -> tuple[float, float]:
        """The hinge's range (rad, + away from the robot): closed at 0 against the stop."""
        return (0.0, self.max_open_rad) if self.opens == "away" else (-self.max_open_rad, 0.0)

    def closer_torque_nm(self, angle_rad: float, rate_rad_s: float) -> float:
        """The closer's torque about the hinge (+z, N m): back toward closed, more the wider
        the door stands open, damped; none once closed."""
        opened = angle_rad if self.opens == "away" else -angle_rad
        if opened <= 0.0:
            return 0.0
        sign = 1.0 if self.opens == "away" else -1.0
        return -sign * (self.closer_nm + self.closer_nm_per_rad * opened) \
            - self.closer_nm_s_per_rad * rate_rad_s


DOOR_OPENS = ("away", "toward")


def _check_finite(what: str, values, n: int) -> None:
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be {n} numbers, got {quoted(values)}") from None
    if array.shape != (n,) or not np.all(np.isfinite(array)):
        raise ConfigError(f"{what} must be {n} finite numbers, got {quoted(values)}")


def _check_positive(what: str, **values: float) -> None:
    for name, value in values.items():
        if isinstance(value, bool) or not (isinstance(value, int | float)
                                           and math.isfinite(value) and value > 0):
            raise ConfigError(f"{what} {name} must be a positive number, got {quoted(value)}")
