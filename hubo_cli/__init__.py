"""hubo-cli: teleoperation and task execution for the HUBO 2+ humanoid.

The library never prints and never exits; the command line in :mod:`hubo_cli.cli` is a thin
layer over it. SI units inside (m, rad, s, N); millimetres only at the user-facing edges.
"""

__version__ = "0.1.0"
