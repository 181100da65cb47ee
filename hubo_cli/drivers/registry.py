"""Imports the built-in drivers so that each registers itself with :func:`base.register`."""
# One import per driver module; each module calls base.register(name, factory).
import hubo_cli.drivers.hardware  # noqa: F401  ("hardware": hubo-ach frames, echo by default)
import hubo_cli.drivers.ideal  # noqa: F401  ("ideal": state = command, no physics)
import hubo_cli.drivers.sim  # noqa: F401  ("sim": PyBullet, the default)

DRIVER_NAMES = ("sim", "hardware", "ideal")
