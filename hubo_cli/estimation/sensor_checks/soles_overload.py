"""The soles' F_z together over :data:`SOLES_MAX_WEIGHTS` times the robot's weight for longer
than :data:`SOLES_OVER_S` (a landing's impact is shorter): force sensors reading far more than
the robot weighs (round 17, docs/history/safety.md)."""

from __future__ import annotations

from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.state import ANKLE_SENSORS, RobotState

SOLES_MAX_WEIGHTS = 2.5  # the soles' F_z together, in robot weights ...
SOLES_OVER_S = 0.1       # ... for longer than this (s)


class SolesOverload:
    """Counts the periods in a row the soles read over the limit (every period, fresh or
    repeated: a repeat reads the same)."""

    def __init__(self, weight_n: float, period_s: float) -> None:
        self.weight_n, self.period_s = weight_n, period_s
        self._over = 0  # periods in a row over the limit

    def update(self, state: RobotState) -> None:
        soles_n = sum(float(state.ft[s][2]) for s in ANKLE_SENSORS if s in state.ft)
        over = soles_n > SOLES_MAX_WEIGHTS * self.weight_n
        self._over = self._over + 1 if over else 0
        if self._over * self.period_s > SOLES_OVER_S + 1e-9:
            raise sensor_fault(f"the ankle force sensors read {soles_n:.0f} N together "
                               f"({soles_n / self.weight_n:.1f} times the robot's "
                               f"{self.weight_n:.0f} N) for {self._over * self.period_s:.3f} s "
                               f"at t = {state.time_s:.2f} s")
