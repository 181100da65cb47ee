"""The arm's joint target, smoothed before the trajectory generator.

The pipeline's trajectory generator (ruckig, :mod:`hubo_cli.control.otg`) plans, every period,
to arrive at its position target at rest within the arms' 0.8 rad/s^2 and 4 rad/s^3. The IK
solution of an operator's goal carries the operator's 8-10 Hz tremor (about 1.3 mm RMS on the
shipped samples) and, between the tracker's samples (60 Hz per station), steps. Behind such a
target the generator keeps re-planning its braking and falls further behind the slow motion:
on ``two-hand-free.csv`` the hands trail by about 10 mm RMS in joint-space terms. A critically
damped alpha-beta filter of the solution takes the tremor and the steps out and follows a
steady motion without any lag of its own (the filter tracks a ramp exactly), and the generator
behind it trails by about 1 mm less there and 1 mm less on ``drill-rectangle.csv``; it also
swings out less at the corners of the operator's path.

The rest of the lag is the generator's stopping distance at the speeds the operator asks for
(0.016 rad at 0.1 rad/s, 0.045 rad at 0.2 rad/s): the limits, not the filter, decide it.
"""

from __future__ import annotations

import numpy as np

from hubo_cli.errors import ConfigError

BANDWIDTH_RAD_S = 8.0  # passes the operator's motion (below 1 Hz), damps the 8-10 Hz tremor


class TargetSmoother:
    """Critically damped alpha-beta (g-h) filter of one arm's joint target.

    Args:
        n: the number of joints.
        dt_s: the control period (s): ``step`` is called once per period.
        bandwidth_rad_s: the filter's bandwidth (rad/s); 0 passes the input through.
    """

    def __init__(self, n: int, dt_s: float, bandwidth_rad_s: float = BANDWIDTH_RAD_S) -> None:
        if not (np.isfinite(bandwidth_rad_s) and bandwidth_rad_s >= 0):
            raise ConfigError(f"target smoothing bandwidth {bandwidth_rad_s} rad/s is not >= 0",
                              hint=f"use e.g. {BANDWIDTH_RAD_S} (0 = off)")
        self.dt_s = float(dt_s)
        self.enabled = bandwidth_rad_s > 0
        theta = max(0.0, 1.0 - bandwidth_rad_s * self.dt_s)  # the discrete pole
        self._g = 1.0 - theta * theta
        self._h = (1.0 - theta) ** 2
        self.q_rad: np.ndarray | None = None
        self.v_rad_s = np.zeros(n)

    def reset(self, q_rad: np.ndarray) -> None:
        """Start at rest at ``q_rad`` (when the operator takes over, after a branch move)."""
        self.q_rad = np.array(q_rad, dtype=float)
        self.v_rad_s = np.zeros_like(self.q_rad)

    def settled(self, q_rad: np.ndarray, tol_rad: float = 1e-5) -> bool:
        """The output has come to rest at ``q_rad``."""
        return self.q_rad is None or bool(
            np.max(np.abs(self.q_rad - q_rad)) < tol_rad
            and np.max(np.abs(self.v_rad_s)) * self.dt_s < tol_rad)

    def step(self, q_rad: np.ndarray, lower_rad: np.ndarray, upper_rad: np.ndarray
             ) -> np.ndarray:
        """Filter this period's target; returns the smoothed target (rad), kept within
        [lower_rad, upper_rad] (the filter stops at a bound instead of overshooting it)."""
        q = np.asarray(q_rad, dtype=float)
        if not self.enabled:
            return np.clip(q, lower_rad, upper_rad)
        if self.q_rad is None:
            self.reset(q)
        predicted = self.q_rad + self.v_rad_s * self.dt_s
        residual = q - predicted
        self.q_rad = predicted + self._g * residual
        self.v_rad_s = self.v_rad_s + (self._h / self.dt_s) * residual
        clipped = np.clip(self.q_rad, lower_rad, upper_rad)
        self.v_rad_s[clipped != self.q_rad] = 0.0
        self.q_rad = clipped
        return self.q_rad.copy()
