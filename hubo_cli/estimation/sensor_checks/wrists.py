"""The wrist force-torque sensors dead or off their load (rounds 17 and 18,
docs/history/safety.md):

- bit-identical for :data:`WRIST_FLAT_STATES` fresh states while its arm moves (one of its
  joints at least :data:`ARM_MOVING_RAD_S` fast between fresh states, from their positions: a
  daemon may leave the velocities 0), or reading exactly 0 in every component at the start (a
  dead channel, or a sensor nulled with the hand on: the estimate removes the hand's weight
  from the reading, :mod:`hubo_cli.estimation.wrenches`, so it needs the sensor as it reads
  with nothing removed; refused);
- its reading, the weight of the hand and its tool removed (as the run declares the tool:
  :mod:`hubo_cli.estimation.wrenches`), averaging more than :data:`WRIST_START_MAX_N` along its
  z over the run's first :data:`WRIST_START_PERIODS` periods, while the hands touch nothing
  yet: an offset, a wrong tool in the task file (the drill declared and not held weighs 5.2 N),
  or the other wrist's sensor (round 18; averaged, because one reading's noise alone is 1 N).
"""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import WRENCHES
from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.model import ARMS, RobotModel
from hubo_cli.state import RobotState

WRIST_FLAT_STATES = 40   # fresh states (0.2 s) of its arm moving
ARM_MOVING_RAD_S = 0.02  # an arm moves: one of its joints this fast between fresh states
WRISTS = ("right-wrist", "left-wrist")
# A wrist's compensated F_z, averaged over the run's first WRIST_START_PERIODS periods (0.1 s),
# at most this far from 0 (N). Healthy starts (round 18; the same runs as
# imu_tilt.IMU_LEGS_MAX_DEG) averaged 0.02 N nominal and up to 0.92 N perturbed (single
# readings 3.7 N): the masses of the hand and the drill drawn 10 % off (0.8 N with the drill),
# the noise (1 N a reading, 0.22 N averaged). The drill declared and not held reads 5.2 N
WRIST_START_MAX_N = 2.5
WRIST_START_PERIODS = 20


class WristChecks:
    """Both wrists' checks (module docstring).

    Args:
        model: the robot model (the arms' joints).
        period_s: the control period (s).
        drill_kg: the drill's declared mass (kg) when the right hand holds it (the start
            check's hint names it), else None.
    """

    def __init__(self, model: RobotModel, period_s: float, drill_kg: float | None) -> None:
        self.period_s, self.drill_kg = period_s, drill_kg
        self._arms = {wrist: model.limb_slice(arm) for wrist, arm in zip(WRISTS, ARMS,
                                                                          strict=True)}
        self._last = dict.fromkeys(WRISTS)  # the last fresh state's reading
        self._flat = dict.fromkeys(WRISTS, 0)  # fresh states in a row the same, its arm moving
        self._periods = 0  # periods judged since the start
        self._sums = np.zeros((2, len(WRISTS)))  # per wrist: compensated F_z, raw F_z

    def start(self, state: RobotState) -> None:
        """Refuse a wrist reading exactly 0 in every component."""
        for wrist in WRISTS:
            reading = state.ft.get(wrist)
            if reading is not None and not np.any(np.asarray(reading, dtype=float)):
                raise sensor_fault(
                    f"the {wrist} force-torque sensor reads exactly 0 in every component at the "
                    "start: refused before anything moved (a dead channel reads so, and so does "
                    "a sensor nulled with the hand on: the estimate removes the hand's weight "
                    "itself, so null the wrist sensors with nothing beyond them or not at all; "
                    "against hubo hardware fake-daemon pass --echo-sensors)",
                    hint="check the sensor's cable and power, or how it was nulled, then start "
                         "the run again", refuse=True)

    def update_start(self, state: RobotState, store: Store) -> None:
        """Every period of the first WRIST_START_PERIODS (a repeat weighs the same): sum each
        wrist's compensated and raw F_z; at the last, fault a wrist whose compensated mean is
        beyond WRIST_START_MAX_N."""
        self._periods += 1
        if self._periods > WRIST_START_PERIODS:
            return
        wrenches = store.get(WRENCHES)
        for k, wrist in enumerate(WRISTS):
            reading = state.ft.get(wrist)
            if wrenches is None or reading is None:
                self._sums[:, k] = np.nan  # not judged
                continue
            self._sums[0, k] += float(wrenches[wrist][2])
            self._sums[1, k] += float(np.asarray(reading, dtype=float)[2])
        if self._periods < WRIST_START_PERIODS:
            return
        compensated, raw = self._sums / WRIST_START_PERIODS
        for k, wrist in enumerate(WRISTS):
            if abs(compensated[k]) > WRIST_START_MAX_N:  # (NaN: not judged)
                tool = "the drill" if self.drill_kg is not None and wrist == "right-wrist" \
                    else "its tool"
                raise sensor_fault(
                    f"the {wrist} force-torque sensor read {raw[k]:.1f} N along its z over the "
                    f"first {WRIST_START_PERIODS * self.period_s:.2f} s, where the hand and "
                    f"{tool} as the run declares it weigh {raw[k] - compensated[k]:.1f} N: "
                    f"{abs(compensated[k]):.1f} N apart (at most {WRIST_START_MAX_N:g} N) at "
                    f"t = {state.time_s:.2f} s", hint=self._hint(wrist, compensated[k]))

    def update_dead(self, state: RobotState, speed_rad_s: np.ndarray) -> None:
        """Each fresh state but the first: a wrist sensor bit-identical for WRIST_FLAT_STATES
        fresh states while its arm moved (``speed_rad_s``: the joints' from their positions, a
        daemon's velocities may read 0)."""
        for wrist, arm in self._arms.items():
            reading = state.ft.get(wrist)
            if reading is None:
                continue
            reading = np.asarray(reading, dtype=float)
            flat = self._last[wrist] is not None and np.array_equal(reading, self._last[wrist])
            self._last[wrist] = reading.copy()
            if not flat:
                self._flat[wrist] = 0
            elif np.max(speed_rad_s[arm]) >= ARM_MOVING_RAD_S:
                self._flat[wrist] += 1
                if self._flat[wrist] >= WRIST_FLAT_STATES:
                    raise sensor_fault(f"the {wrist} force-torque sensor read the same values "
                                       f"to the last bit for {self._flat[wrist]} states while "
                                       f"its arm moved, at t = {state.time_s:.2f} s: dead")

    def _hint(self, wrist: str, apart_n: float) -> str:
        """What to check for a wrist reading ``apart_n`` more than its declared load (N)."""
        check = "the sensor's zero, which wrist it is wired to and the task file's [stance] tool"
        if self.drill_kg is None or wrist != "right-wrist":
            return f"check {check}, then start the run again"
        heavier = "heavier" if apart_n > 0 else "lighter"
        return (f"a drill about {abs(apart_n) / 9.80665:.2f} kg {heavier} (along the sensor's "
                f"z) than the {self.drill_kg:g} kg the run declares reads so: weigh it and give "
                "its mass in the task file's [stance] tool_mass_kg or with --set "
                f"stance.tool_mass_kg=KG; else check {check}, then start the run again")
