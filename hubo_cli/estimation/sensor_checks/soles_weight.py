"""The ankle sensors' F_z together against the weight they carry while the whole robot stands
still (:mod:`.still_window` with ``whole_body``: arms moving shift the soles' load, and a
sensor reading low unloads its sole, so the soles' load is not asked): more than
:data:`SOLES_WEIGHT_MAX_OFF` of the weight above the sensors (the robot's less the feet below
them, which do not load them) off it is a sensor at the wrong gain, or frozen since the load
changed (round 21: the right ankle's at half gain stood and walked, exit 0). The sum cannot say
which sensor: the message gives both. Not judged while the right hand holds the drill (the
observer's choice, :mod:`hubo_cli.estimation.plausibility`)."""

from __future__ import annotations

from hubo_cli.dataflow import Store
from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.estimation.sensor_checks.still_window import STILL_STATES, StillWindow
from hubo_cli.estimation.wrenches import sensor_loads
from hubo_cli.model import RobotModel
from hubo_cli.state import ANKLE_SENSORS, FT_SENSORS, GRAVITY_M_S2, RobotState

# Healthy runs (round 21, docs/history/safety.md, both code paths): stands nominal and
# perturbed 0.024 off at most, pushes settled 0.037 (a step), walks' stances 0.021, the hands'
# tasks 0.040 (the door, seed 79), teleop 0.021; the arms moving (not judged) 0.17. An ankle
# sensor at half gain on a stand reads 0.25 off: the bound 2.5 times the healthy worst
SOLES_WEIGHT_MAX_OFF = 0.1


class SolesWeight:
    """Judges each fresh state (module docstring).

    Attributes:
        carried_n: the weight above the ankle sensors (N).
    """

    def __init__(self, model: RobotModel, weight_n: float, period_s: float) -> None:
        feet_kg = sum(sensor_loads(model, False)[0][FT_SENSORS.index(s)] for s in ANKLE_SENSORS)
        self.carried_n = weight_n - feet_kg * GRAVITY_M_S2
        self.period_s = period_s
        self._still = StillWindow(whole_body=True)

    def update(self, state: RobotState, store: Store) -> None:
        """At the end of each still window, its mean F_z of both soles more than
        SOLES_WEIGHT_MAX_OFF of carried_n off it is a fault."""
        if self._still.update(state, store, self.carried_n) is None:
            return
        right_n, left_n = self._still.soles_fz_n
        share = (right_n + left_n) / self.carried_n
        if abs(share - 1.0) > SOLES_WEIGHT_MAX_OFF:
            raise sensor_fault(
                f"standing still for {STILL_STATES * self.period_s:.2f} s at t = "
                f"{state.time_s:.2f} s, the right-ankle force-torque sensor read F_z "
                f"{right_n:.0f} N and the left-ankle sensor {left_n:.0f} N: together {share:.2f} "
                f"of the {self.carried_n:.0f} N the robot weighs above them (within "
                f"{SOLES_WEIGHT_MAX_OFF:g} of it): one of them reads wrong (its gain, or frozen)",
                hint="check both ankle sensors' calibration (gain) and cables, then start the "
                     "run again")
