"""The built-in drivers by name, imported only when one is made (``--driver`` choices)."""

from __future__ import annotations

import importlib

from hubo_cli.drivers.base import Driver
from hubo_cli.errors import ConfigError, quoted
from hubo_cli.model import RobotModel

# name -> "module:class"; the first is the default
DRIVERS = {
    "sim": "hubo_cli.drivers.sim:SimDriver",          # PyBullet
    "ideal": "hubo_cli.drivers.ideal:IdealDriver",    # state = command, no physics
    "hardware": "hubo_cli.drivers.hardware:HardwareDriver",  # hubo-ach
}
DRIVER_NAMES = tuple(DRIVERS)


def driver_class(name: str) -> type[Driver]:
    """The driver class registered under ``name``."""
    if name not in DRIVERS:
        raise ConfigError(f"unknown driver {quoted(name)}", hint=f"use one of {', '.join(DRIVERS)}")
    module, attr = DRIVERS[name].split(":")
    return getattr(importlib.import_module(module), attr)


def make_driver(name: str, model: RobotModel, **options) -> Driver:
    """Create a driver by name (``sim``, ``ideal``, ``hardware``) with its options."""
    return driver_class(name)(model, **options)
