"""Foot contact: the one definition every module, target and report uses.

Per foot, from its ankle sensor's F_z with the foot's own weight removed (``WRENCHES``: the
floor's push on the sole):

1. one filter: a first-order low-pass at ``contact_cutoff_hz`` (started at the first reading);
2. loaded: the filtered F_z above ``contact_threshold_n`` (hrpsys' contact decision: a foot
   that only brushes the floor, a rocking sole touching with a few newtons, is no support);
3. one debounce: a foot counts as down from the period it is loaded until
   ``contact_release_s`` after it was last loaded (a sensed contact flickers for a period now
   and then; a foot lifted on purpose is up after that delay).

The settings are the robot file's ``[estimation]`` table (:class:`~hubo_cli.model.
EstimationConfig`). A non-finite F_z leaves the filter where it was.
"""

from __future__ import annotations

import math

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import CONTACT, WRENCHES
from hubo_cli.estimation.observer import Observer
from hubo_cli.model import EstimationConfig
from hubo_cli.state import ANKLE_SENSORS, RobotState


class ContactObserver(Observer):
    """Writes ``CONTACT`` (right, left) from the compensated ankle F_z (see the module
    docstring).

    Args:
        config: the thresholds and filters (``model.estimation``).
        period_s: the control period (s).

    Attributes:
        filtered_fz_n: the low-passed F_z per foot (N; None before the first reading).
        loaded: per foot, the filtered F_z above the threshold this period.
    """

    name = "contact"
    reads = (WRENCHES,)
    writes = (CONTACT,)

    def __init__(self, config: EstimationConfig, period_s: float) -> None:
        self.config = config
        tau_s = 1.0 / (2.0 * math.pi * config.contact_cutoff_hz)
        self.alpha = period_s / (period_s + tau_s)
        # whole periods a foot stays down after its last loaded one
        self.release_periods = int(round(config.contact_release_s / period_s))
        self.filtered_fz_n: list[float | None] = [None, None]
        self.loaded = [False, False]
        self._since_loaded = [math.inf, math.inf]  # periods since the foot was last loaded

    def reset(self, state: RobotState, store: Store) -> None:
        self.filtered_fz_n = [None, None]
        self.loaded = [False, False]
        self._since_loaded = [math.inf, math.inf]
        self.update(state, store)

    def update(self, state: RobotState, store: Store) -> None:
        wrenches = store[WRENCHES]
        down = []
        for k, sensor in enumerate(ANKLE_SENSORS):
            fz = float(wrenches[sensor][2])
            if math.isfinite(fz):
                previous = self.filtered_fz_n[k]
                self.filtered_fz_n[k] = fz if previous is None else (
                    previous + self.alpha * (fz - previous))
            filtered = self.filtered_fz_n[k]
            self.loaded[k] = filtered is not None and filtered > self.config.contact_threshold_n
            self._since_loaded[k] = 0 if self.loaded[k] else self._since_loaded[k] + 1
            down.append(self._since_loaded[k] <= self.release_periods)
        store[CONTACT] = (down[0], down[1])
