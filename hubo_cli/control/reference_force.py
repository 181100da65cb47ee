"""The ReferenceForceUpdater (hrpsys-base ``rtc/ReferenceForceUpdater``): the hand force the
balance plans for follows the measured one.

A plan balances for the hand force it expects (eq. 6: the waist leans into a thrust); the force
the hand really meets differs (a wall nearer than planned pushes harder, a tool in free air
feels none). hrpsys moves the reference force along a motion direction d toward the measured
force at ``p_gain`` per update, interpolated between updates; here, per hand, every period:

    f_filtered <- f_filtered + a (f_measured . d - f_filtered)      (first-order low-pass)
    f_ref      <- f_ref + clip(gain dt (f_filtered - f_ref), +-max_rate dt)

with ``a = dt / (dt + 1 / (2 pi cutoff))``; the output is ``f_ref d`` (N, the frame d is
given in). Like hrpsys' ``is_hold_value`` the update can be held (:meth:`hold`).
"""

from __future__ import annotations

import math

import numpy as np

CUTOFF_HZ = 2.0          # [chosen] above the 0.5 Hz impedance spring, below the arm's jitter
# [chosen] the closing rate (1/s). The waist leans ~4 mm per newton of the reference in the
# tasks (eq. 6) and the torso follows the waist: at 2 /s (closing in ~0.5 s) the lean closed a
# second loop around the thrust, through the torso and the arm's correction, that kept the
# hand's impedance ringing at ~0.55 Hz (+-1 N, +-1.7 mm of torso, on every vertical edge of a
# cut) and took the thrust out of +-2 N at the corners. At 0.2 /s (a 5 s time constant, 6 % of
# the thrust's swing at 0.55 Hz) the lean follows the steady force only
# (docs/history/impedance.md, round 4).
GAIN_PER_S = 0.2
MAX_RATE_N_S = 1.0       # [chosen] the waist shift it drives (~4 mm/N in the tasks) < 10 mm/s


class ReferenceForceUpdater:
    """One hand's balance force, following the measured force along ``direction``.

    Args:
        direction: the motion direction d (3, any frame; normalised).
        dt_s: the control period (s).
        initial_n: the reference to start from (N along d; the plan's).
        cutoff_hz, gain_per_s, max_rate_n_s: the low-pass, the closing rate and the rate
            limit (see the module docstring).
    """

    def __init__(self, direction, dt_s: float, initial_n: float = 0.0,
                 cutoff_hz: float = CUTOFF_HZ, gain_per_s: float = GAIN_PER_S,
                 max_rate_n_s: float = MAX_RATE_N_S) -> None:
        d = np.asarray(direction, dtype=float).reshape(3)
        n = float(np.linalg.norm(d))
        if not (n > 0 and math.isfinite(n)):
            raise ValueError("the motion direction must be a finite nonzero 3-vector")
        self.direction = d / n
        self.dt_s = float(dt_s)
        self.alpha = self.dt_s / (self.dt_s + 1.0 / (2 * math.pi * cutoff_hz))
        self.gain_per_s = float(gain_per_s)
        self.max_step_n = float(max_rate_n_s) * self.dt_s
        self.filtered_n = self.reference_n = float(initial_n)
        self.held = False

    def hold(self, held: bool = True) -> None:
        """Freeze the reference (it keeps filtering the measurement)."""
        self.held = held

    def update(self, force_n) -> float:
        """Take this period's measured force (3, N, the direction's frame; a non-finite one
        is skipped) and return the reference along d (N)."""
        along = float(np.dot(np.asarray(force_n, dtype=float), self.direction))
        if math.isfinite(along):
            self.filtered_n += self.alpha * (along - self.filtered_n)
        if not self.held:
            step = self.gain_per_s * self.dt_s * (self.filtered_n - self.reference_n)
            self.reference_n += min(max(step, -self.max_step_n), self.max_step_n)
        return self.reference_n

    @property
    def force_n(self) -> np.ndarray:
        """The reference force (3, N, the direction's frame)."""
        return self.reference_n * self.direction
