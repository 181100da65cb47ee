"""The hardware driver's checks of what the robot measures (hrpsys RobotHardware and
ThermoLimiter): each looks at one fresh ``hubo_state`` and says whether the run must end.

- :class:`ServoErrorGuard`: a joint whose measured position departs from the position its
  references should have brought it to by more than ``servo_error_limit_rad`` (hrpsys'
  ``servoErrorLimit``, 0.2 rad). In hubo-ach's mode 0 the expected position is hubo-daemon's
  reference filter run on the references sent (the filter's 0.2 s lag is expected, not an
  error); in mode 1 it is the reference itself. The error is the smallest over the last
  ``servo_error_window_periods`` expected positions: the bus and the motor's own lag.
- :class:`SoleForceGuard`: a sole's vertical force that is not finite, or beyond
  ``sole_force_max_n`` (about 3x the robot's weight) in ``sole_force_window_periods``
  consecutive states (a touchdown's impact lasts less), or, once the robot has stood (both soles
  together carrying ``sole_standing_min_n``), both soles under ``sole_unloaded_n`` for longer
  than ``sole_unloaded_grace_s``: the robot is no longer on the ground.
- :class:`ThermalLimiter`: a motor's temperature (``joint[].tmp``, degrees C) between
  ``motor_warning_temperature_c`` and ``motor_max_temperature_c`` scales that joint's velocity
  linearly from 1 down to 0; at the maximum the run ends.

Their parameters are the robot file's ``[hardware_guards]``. A trip is a
:class:`~hubo_cli.errors.DeviceError` (exit 3): the driver holds the last reference and ends
the run with it.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from hubo_cli.drivers import hubo_ach
from hubo_cli.errors import ConfigError, DeviceError

SOLES = (("right", hubo_ach.FT_R_FOOT), ("left", hubo_ach.FT_L_FOOT))

# The largest value each guard's parameter may take: beyond it the guard is switched off in
# all but name, so a robot file cannot do that unseen (review 22 left them unbounded). The
# servo error at 2.5x hrpsys' 0.2 rad; a window of 0.2 s (40 states: a motor lagging longer is
# not lagging); a sole's force at 10x the 38.7 kg robot's weight (the shipped 1,140 N is 3x;
# the largest impact measured 1,640 N); off the ground for 2 s; a motor at the class-B winding
# insulation's 130 C, which the shipped 80 C is kept well below.
GUARD_MAX = {"servo_error_limit_rad": 0.5, "servo_error_window_periods": 40,
             "sole_force_max_n": 3800.0, "sole_force_window_periods": 40,
             "sole_unloaded_grace_s": 2.0, "motor_max_temperature_c": 130.0}
HINT_SERVO = ("check the joint (a blocked limb, a motor off or a board fault: hubo-console), "
              "then start the run again (it starts from the measured posture)")


class ServoError(DeviceError):
    """A joint's measured position left its reference by more than the limit."""

    def __init__(self, joint: str, error_rad: float, limit_rad: float, t_s: float) -> None:
        super().__init__(f"servo error: {joint} is {error_rad:.3f} rad from its reference "
                         f"(limit {limit_rad:.2f} rad) at t = {t_s:.2f} s; the robot holds its "
                         "last reference", hint=HINT_SERVO)
        self.joint, self.error_rad = joint, error_rad


class SoleForceError(DeviceError):
    """A sole's force sensor reads the impossible, or the standing robot left the ground."""

    def __init__(self, what: str, t_s: float) -> None:
        super().__init__(f"sole force: {what} at t = {t_s:.2f} s; the robot holds its last "
                         "reference",
                         hint="check the ankle force-torque sensors (hubo-console) and that the "
                              "robot stands; then start the run again")


class MotorTooHot(DeviceError):
    """A motor reached its maximum temperature."""

    def __init__(self, joint: str, temperature_c: float, max_c: float, t_s: float) -> None:
        super().__init__(f"motor too hot: {joint} at {temperature_c:.1f} C reached its limit "
                         f"{max_c:.1f} C at t = {t_s:.2f} s; it was slowed to a stop and the "
                         "robot holds its last reference",
                         hint="let the motor cool below its warning temperature before the "
                              "next run")
        self.joint, self.temperature_c = joint, temperature_c


def guard_parameters(model) -> dict[str, float]:
    """The robot file's ``[hardware_guards]`` as floats, checked.

    Raises:
        ConfigError: a missing or inconsistent parameter, or one beyond GUARD_MAX.
    """
    names = ("servo_error_limit_rad", "servo_error_window_periods", "sole_force_max_n",
             "sole_force_window_periods", "sole_standing_min_n", "sole_unloaded_n",
             "sole_unloaded_grace_s",
             "motor_warning_temperature_c", "motor_max_temperature_c")
    raw = model.hardware_guards
    missing = [n for n in names if n not in raw]
    if missing:
        raise ConfigError(f"the robot file's [hardware_guards] lacks {', '.join(missing)}",
                          path=str(model.source))
    numbers = all(isinstance(raw[n], int | float) and not isinstance(raw[n], bool)
                  for n in names)  # a text here was a ValueError's traceback (review 22)
    p = {n: float(raw[n]) if numbers else math.nan for n in names}
    if not (all(np.isfinite(v) for v in p.values()) and p["servo_error_limit_rad"] > 0
            and p["servo_error_window_periods"] >= 1 and p["sole_force_window_periods"] >= 1
            and 0 < p["sole_unloaded_n"] < p["sole_standing_min_n"] < p["sole_force_max_n"]
            and p["sole_unloaded_grace_s"] >= 0
            and p["motor_warning_temperature_c"] < p["motor_max_temperature_c"]):
        raise ConfigError("the robot file's [hardware_guards] are inconsistent",
                          path=str(model.source),
                          hint="limits > 0, sole_unloaded_n < sole_standing_min_n < "
                               "sole_force_max_n, warning temperature < maximum")
    for name, most in GUARD_MAX.items():
        if p[name] > most:
            raise ConfigError(f"must be at most {most:g}, got {p[name]:g}: a larger value is "
                              "no guard on Hubo", path=str(model.source),
                              field=f"hardware_guards.{name}")
    return p


class ServoErrorGuard:
    """Measured position against the position the references sent should give.

    Args:
        joint_names: the driven joints; ``index`` their hubo-ach indices.
        limit_rad: the servo-error limit.
        window: how many periods of expected positions an error may lag behind.
        filter_length: hubo-daemon's reference filter length (mode 0).
    """

    def __init__(self, joint_names, index: np.ndarray, limit_rad: float, window: int,
                 filter_length: int) -> None:
        self.joint_names = tuple(joint_names)
        self.index = np.asarray(index)
        self.limit_rad = float(limit_rad)
        self.filter_length = int(filter_length)
        self._expected: deque[np.ndarray] = deque(maxlen=int(window))
        self._filtered = np.zeros(hubo_ach.JOINT_COUNT)
        self.error_rad = np.zeros(len(self.joint_names))

    def reset(self, pos42_rad: np.ndarray) -> None:
        """Start at the measured posture (hubo-daemon's filter starts there too)."""
        self._filtered = np.array(pos42_rad, dtype=float)
        self._expected.clear()
        self._expected.append(self._filtered[self.index].copy())
        self.error_rad = np.zeros(len(self.joint_names))

    def sent(self, ref42_rad: np.ndarray, mode: np.ndarray) -> None:
        """A reference was put: what the motors are given next (hubo-daemon's filter)."""
        self._filtered = hubo_ach.reference_filter(self._filtered, ref42_rad, mode,
                                                   self.filter_length)
        self._expected.append(self._filtered[self.index].copy())

    def check(self, pos42_rad: np.ndarray, t_s: float) -> ServoError | None:
        """The error of a fresh state; the trip if a joint is beyond the limit."""
        pos = pos42_rad[self.index]
        self.error_rad = np.min(np.abs(np.array(self._expected) - pos), axis=0)
        worst = int(np.argmax(self.error_rad))
        if self.error_rad[worst] > self.limit_rad:
            return ServoError(self.joint_names[worst], float(self.error_rad[worst]),
                              self.limit_rad, t_s)
        return None


class SoleForceGuard:
    """The soles' vertical forces: possible, and on the ground once standing."""

    def __init__(self, max_n: float, standing_min_n: float, unloaded_n: float,
                 grace_s: float, window_periods: int = 1) -> None:
        self.max_n, self.standing_min_n = float(max_n), float(standing_min_n)
        self.unloaded_n, self.grace_s = float(unloaded_n), float(grace_s)
        self.window_periods = int(window_periods)
        self.reset()

    def reset(self) -> None:
        """Not standing yet (a robot hanging from its gantry reads ~0 N)."""
        self.stood = False
        self._unloaded_since_s: float | None = None
        self._beyond = {side: 0 for side, _ in SOLES}  # consecutive states beyond max_n

    def check(self, ft_mx_my_fz: np.ndarray, t_s: float) -> SoleForceError | None:
        """The trip if a sole reads the impossible (not finite, or beyond ``max_n`` in
        ``window_periods`` consecutive states) or the robot has left the ground."""
        fz = {side: float(ft_mx_my_fz[k][2]) for side, k in SOLES}
        for side, f in fz.items():
            beyond = not np.isfinite(f) or abs(f) > self.max_n
            self._beyond[side] = self._beyond[side] + 1 if beyond else 0
            if beyond and (not np.isfinite(f) or self._beyond[side] >= self.window_periods):
                return SoleForceError(f"the {side} sole reads {f:.0f} N (possible: within "
                                      f"{self.max_n:.0f} N)", t_s)
        if sum(fz.values()) >= self.standing_min_n:
            self.stood = True
        if not self.stood or max(abs(f) for f in fz.values()) >= self.unloaded_n:
            self._unloaded_since_s = None
            return None
        if self._unloaded_since_s is None:
            self._unloaded_since_s = t_s
        if t_s - self._unloaded_since_s > self.grace_s:
            return SoleForceError(
                f"both soles under {self.unloaded_n:.0f} N for "
                f"{t_s - self._unloaded_since_s:.2f} s (right {fz['right']:.0f} N, left "
                f"{fz['left']:.0f} N): the standing robot is off the ground", t_s)
        return None


class ThermalLimiter:
    """Per-joint velocity scale from the motors' temperatures (hrpsys ThermoLimiter)."""

    def __init__(self, joint_names, index: np.ndarray, warning_c: float, max_c: float) -> None:
        self.joint_names = tuple(joint_names)
        self.index = np.asarray(index)
        self.warning_c, self.max_c = float(warning_c), float(max_c)
        self.reset()

    def reset(self) -> None:
        self.scale = np.ones(len(self.joint_names))
        self.temperature_c = np.full(len(self.joint_names), np.nan)  # the last state's
        self.hottest = (None, -np.inf)  # the run's hottest motor so far: joint, degrees C

    def check(self, tmp42_c: np.ndarray | None, t_s: float) -> MotorTooHot | None:
        """Update :attr:`scale` (1 below the warning, 0 at the maximum); the trip at 0.

        A non-finite temperature counts as the maximum (a sensor that cannot be read is not
        a cool motor)."""
        if tmp42_c is None:
            return None
        tmp = np.asarray(tmp42_c, dtype=float)[self.index]
        tmp = np.where(np.isfinite(tmp), tmp, np.inf)
        self.temperature_c = tmp
        k = int(np.argmax(tmp))
        if tmp[k] > self.hottest[1]:
            self.hottest = (self.joint_names[k], float(tmp[k]))
        self.scale = np.clip((self.max_c - tmp) / (self.max_c - self.warning_c), 0.0, 1.0)
        hot = np.flatnonzero(tmp >= self.max_c)
        if hot.size:
            k = int(hot[np.argmax(tmp[hot])])
            return MotorTooHot(self.joint_names[k], float(tmp[k]), self.max_c, t_s)
        return None

    @property
    def limiting(self) -> bool:
        return bool(np.any(self.scale < 1.0))
