"""The marks of a test that runs against a daemon playing hubo-daemon in real time over libach's
channels: skipped with the reason where libach cannot be loaded (``HUBO_LIBACH``, the loader
path or the environment's copy that ``make`` builds from ``third_party/ach``), and ``realtime``,
which ``make test`` runs after the other tests, one at a time (beside another test's simulation
a 2-core machine delays the daemon's periods and the driver's plausibility checks rightly end
the run; round 26)."""

from __future__ import annotations

import pytest

from hubo_cli.drivers.ach import libach_status

AVAILABLE, WHERE = libach_status()
LIBACH_MARKS = (pytest.mark.skipif(not AVAILABLE, reason=f"needs libach: {WHERE}"),
                pytest.mark.realtime)


def needs_libach(test):
    """``test`` with :data:`LIBACH_MARKS`."""
    for mark in LIBACH_MARKS:
        test = mark(test)
    return test
