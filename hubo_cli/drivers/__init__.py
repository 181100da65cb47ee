"""Drivers: the robot behind one small contract (:class:`hubo_cli.drivers.base.Driver`)."""
