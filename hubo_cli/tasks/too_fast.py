"""Steps a plan asks the joints to follow faster than they can: found from the plan's joint
targets, before anything moves.

The plan solves every period as it will run, so each joint's planned velocity and
acceleration (finite differences over the control period) can be compared with its limits.
The pipeline keeps the robot within them whatever the plan says, so a step over them makes the
robot lag behind its path there: pre-flight says so in a warning. How far behind is
:mod:`hubo_cli.tasks.cut_lag`'s to measure (a cut too far behind is refused): a limit exceeded
for a period or two costs nothing (cut_lag's docstring has the measurement: cut-rectangle's
corners).

What the step can do instead scales from what it asks: a joint's velocity grows with the
tool's speed; its acceleration with the tool's own (in the ramps at each corner of a cut) plus
a part that grows with the square of the speed (the arm's geometry changing along a line),
read where the tool moves at constant speed. Measured on cut-rectangle's cut (speeds 10-60
mm/s, accelerations 100-2,000 mm/s^2): the value suggested passed pre-flight in every case,
on the safe side (13-67 mm/s^2 suggested where about 80 passes at 40 mm/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hubo_cli.model import RobotModel
from hubo_cli.tasks.spec import Step, TaskSpec

# a plan's joint target up to 10 % over a limit for a few periods: the robot lags by a
# fraction of a millimetre (the shipped tasks ask at most 0.95 of an acceleration limit:
# cut-rectangle's knees in the lift, cut-slot's RWP; at most 0.36 of a velocity limit)
LIMIT_TOLERANCE = 1.1

@dataclass(frozen=True)
class TooFast:
    """A step whose joint targets exceed a joint's velocity or acceleration limit.

    Attributes:
        step: the step.
        joint: the joint asked the most (hubo-ach name).
        what: ``velocity`` or ``acceleration``.
        ratio: what the plan asks of that joint over its limit (1.0: at the limit).
        asked: the step's speed (m/s) or, for a cut's ramps, its acceleration (m/s^2).
        possible: how much of ``asked`` the joints follow (same unit; an estimate on the
            safe side, see the module docstring), None when it does not scale (a step
            without a speed).
        quantity: ``speed`` or ``acceleration``: which of the step's settings is too high.
    """

    step: Step
    joint: str
    what: str
    ratio: float
    asked: float | None
    possible: float | None
    quantity: str = "speed"

    def message(self) -> str:
        """One line: the step, what it asks and what the arm follows."""
        need = (f"needs {self.joint} at {self.ratio:.0%} of its {self.what} limit")
        if self.asked is None or self.possible is None:
            return f"{self.step.label} ({self.step.kind}) {need}"
        unit, setting = self._unit_setting()
        return (f"{self.step.label} ({self.step.kind}) at {mm_text(self.asked)} {unit} {need}: "
                f"the arm follows about {mm_text(self.possible)} {unit} or less "
                f"(the step's {setting}, estimated from the plan)")

    def fix(self) -> str:
        """What to change in the task (a hint)."""
        if self.possible is None:
            return "make the step slower"
        unit, setting = self._unit_setting()
        shortcut = " (--speed for the shipped cuts)" if self.quantity == "speed" else ""
        return (f"set the step's {setting} to {mm_text(self.possible)} {unit} or less{shortcut}; "
                "pre-flight checks again")

    def _unit_setting(self) -> tuple[str, str]:
        """The unit of ``asked`` and ``possible`` and the step's setting they are."""
        return (("mm/s", "speed_mm_s") if self.quantity == "speed"
                else ("mm/s^2", "accel_mm_s2"))


def mm_text(value_m: float) -> str:
    """Metres (per second, per second squared) as millimetres: 2 significant digits below
    10, else whole."""
    mm = value_m * 1000
    return f"{mm:.2g}" if mm < 10 else f"{math.floor(mm):.0f}"


def too_fast_steps(spec: TaskSpec, model: RobotModel, q_rad: np.ndarray,
                   step_index: np.ndarray, goal_m: np.ndarray, dt_s: float,
                   cut_accel_m_s2: float) -> list[TooFast]:
    """The steps whose joint targets exceed a velocity or acceleration limit by more than
    :data:`LIMIT_TOLERANCE`, the worst joint of each (velocity first).

    Args:
        spec: the task.
        model: the robot (its joints' limits).
        q_rad: (N, n_joints) the plan's joint targets, one row per period.
        step_index: (N,) the step each row belongs to.
        goal_m: (N, 3) the tool's planned position (m).
        dt_s: the control period (s).
        cut_accel_m_s2: a cut's acceleration at its corners unless its step sets one.
    """
    if len(q_rad) < 3:
        return []
    v = np.abs(np.diff(q_rad, axis=0)) / dt_s / model.velocity_rad_s
    a = np.abs(np.diff(q_rad, 2, axis=0)) / dt_s**2 / model.acceleration_rad_s2
    tool_accel = np.linalg.norm(np.diff(goal_m, 2, axis=0), axis=1) / dt_s**2
    out = []
    for k, step in enumerate(spec.steps):
        rows = np.nonzero(step_index[1:-1] == k)[0]
        if not len(rows):
            continue
        for what, ratio in (("velocity", v[rows]), ("acceleration", a[rows])):
            worst = np.unravel_index(np.argmax(ratio), ratio.shape)
            if ratio[worst] > LIMIT_TOLERANCE:
                out.append(_excess(step, model.joint_names[worst[1]], what,
                                   float(ratio[worst]), ratio, tool_accel[rows],
                                   cut_accel_m_s2))
    return out


def _excess(step: Step, joint: str, what: str, ratio: float, ratios: np.ndarray,
            tool_accel: np.ndarray, cut_accel_m_s2: float) -> TooFast:
    """The step's excess and what it could ask instead (see the module docstring);
    ``ratios``: (rows, joints) what each row asks of each joint over its limit."""
    speed = step.speed_m_s
    if speed is None:
        return TooFast(step, joint, what, ratio, None, None)
    if what == "velocity":  # in proportion to the speed
        return TooFast(step, joint, what, ratio, speed, speed / ratio)
    if step.kind != "follow":  # minimum-jerk: its accelerations grow with its speed squared
        return TooFast(step, joint, what, ratio, speed, speed / math.sqrt(ratio))
    accel = step.accel_m_s2 or cut_accel_m_s2
    ramps = tool_accel > 1e-3 * accel  # the rows speeding up or slowing down at a corner
    j = int(np.argmax(ratios.max(axis=0)))  # the joint asked the most
    cruise = float(ratios[~ramps, j].max()) if (~ramps).any() else 0.0
    if cruise > 1.0 or not ramps.any():  # the speed's part alone is too much
        return TooFast(step, joint, what, ratio, speed, speed / math.sqrt(max(cruise, ratio)))
    return TooFast(step, joint, what, ratio, accel,  # the ramps' part scales with ``accel``
                   accel * (1.0 - cruise) / (ratio - cruise), "acceleration")
