"""Ankle force-torque sensors wired wrong, on the simulated robot: a measurement tool.

    LIE=KIND [STOP_AT=S] python tools/ankle_wiring.py OUT.npy hubo ARGS...

runs ``hubo ARGS`` in this process with the sim driver's ankle readings rewired as KIND says
(``none``, ``swap``: each foot's reading given as the other's; ``rot90-right``, ``rot180-left``
...: that sensor turned about its z; ``flip-fz-right``, ``flip-mx-left`` ...: that component's
sign flipped), and saves what the estimate saw each period (the bounds of the wiring checks
in :mod:`hubo_cli.estimation.sensor_checks.ankle_wiring`, docs/history/safety.md round 20) to
OUT.npy, one row a period: time (s), CoM (3, m), its velocity (3, m/s), ZMP (2, m), contact
(right, left), the soles' poses (2 x 3 x 4, the rows of T_world_sole), the right and left
ankles' compensated wrenches (6 each). ``STOP_AT``: the run ends once it reaches S seconds.
"""

from __future__ import annotations

import atexit
import os
import sys

import numpy as np

from hubo_cli.drivers import sim
from hubo_cli.estimation import estimator as est
from hubo_cli.estimation.keys import (
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
    WRENCHES,
    ZMP_WORLD,
)

COMPONENTS = ("fx", "fy", "fz", "mx", "my", "mz")


def rewire(ft: dict, kind: str) -> dict:
    """The ankle readings of ``ft`` as a sensor wired per ``kind`` gives them."""
    ft = dict(ft)
    if kind == "none":
        return ft
    if kind == "swap":
        ft["right-ankle"], ft["left-ankle"] = ft["left-ankle"], ft["right-ankle"]
        return ft
    what, side = kind.rsplit("-", 1)
    sensor = f"{side}-ankle"
    w = np.array(ft[sensor], dtype=float)
    if what.startswith("rot"):
        a = np.radians(float(what[3:]))
        R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        w = np.concatenate([R.T @ w[:3], R.T @ w[3:]])  # the frame turned by a about z
    else:
        w[COMPONENTS.index(what.split("-")[1])] *= -1.0
    ft[sensor] = w
    return ft


def rewired(measure, kind: str):
    """The sim driver's ``_measure`` with its ankle readings rewired per ``kind``."""
    def lying(self):
        state = measure(self)
        state.ft.update(rewire(state.ft, kind))
        return state
    return lying


def main() -> None:
    out, argv = sys.argv[1], sys.argv[2:]
    sim.SimDriver._measure = rewired(sim.SimDriver._measure, os.environ.get("LIE", "none"))
    rows = []
    update = est.Estimator.update

    def recording(self, state):
        store = update(self, state)
        w = store[WRENCHES]
        rows.append(np.concatenate([
            [state.time_s], store[COM_WORLD], store[COM_VELOCITY_WORLD], store[ZMP_WORLD],
            np.asarray(store[CONTACT], dtype=float),
            np.asarray(store[T_WORLD_SOLES], dtype=float)[:, :3, :].ravel(),
            w["right-ankle"], w["left-ankle"]]))
        if state.time_s >= stop_s:  # enough seen: the rest of the run is not needed
            np.save(out, np.array(rows))
            os._exit(0)
        return store
    stop_s = float(os.environ.get("STOP_AT", "inf"))
    est.Estimator.update = recording
    atexit.register(lambda: np.save(out, np.array(rows)))
    sys.argv = argv
    from hubo_cli.cli.main import entry
    entry()


if __name__ == "__main__":
    main()
