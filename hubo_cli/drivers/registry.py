"""Imports the built-in drivers so that each registers itself with :func:`base.register`."""
# One import per driver module; each module calls base.register(name, factory).
