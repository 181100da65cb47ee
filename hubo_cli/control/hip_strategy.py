"""Hip strategy: bow the trunk when a push leaves the ankles nothing more to give.

A standing robot pushed hard on the torso has its feet's centre of pressure on the toe (or heel)
edge within a few control periods; from then on no ankle motion moves it further and the body
rotates about that edge as one piece. What is left is to rotate the trunk relative to the legs
(Horak and Nashner's hip strategy; hrpsys Stabilizer's and the multi-layer paper's answer once
the ankles saturate): bowing the trunk toward the fall stores angular momentum in it and pushes
the hips the other way, which slows the centre of mass.

Each period, from the store (declared in ``reads``): the estimate's capture point
(``CAPTURE_POINT_WORLD``) and the capture-point monitor's shrunk support box of the same period
(``SUPPORT_BOX_WORLD``), world x, along the standing robot's feet: while the capture point
lies within ``start_m`` of the box's front (back) edge, the bow grows forward (backward) at
``gain`` rad/s per metre of the excess over that band, at most ``max_rate_rad_s``, up to
``max_bow_rad``. The bow turns both hip pitches, with the knees
and ankles moving along so that the model's centre of mass keeps its x and height
(:data:`BOW_JOINTS_RAD`, per rad of bow). Once the capture point has stayed inside the band
for ``hold_s``, the bow returns to zero with time constant ``return_s`` (at most
``return_rate_rad_s``), so the trunk stands upright again. Un-bowing turns the trunk the
other way, which is what the body's rebound needs; the return is therefore not interrupted by
the body rocking back into the band: a new bow starts only once the trunk is upright
(re-bowing on every rock pumps a heel-to-toe limit cycle). While it returns the bow also
damps that rocking (the body tipping onto its toes and heels as one piece): its rate gets
``rock_gain`` times the soles' pitch (the estimate's ``T_WORLD_SOLES``, their mean, > 0 on
the toes, from their pitch standing before the bow), so the trunk turns toward the side the
body tips to and its reaction turns the body back (the bow may change sign then). Measured
on the nominal simulated robot after a 90 N push: the torso's largest tilt from 3 s after
the push on 3.5-4.2 deg forward / 3.4-3.6 deg backward with it, 8.3 / 7.1 deg with the
return alone, standing in the standing posture; 1.08 / 0.92 deg braced (the standing
experiment's posture with it, ``hubo_cli.experiments.standing.BRACE_LIFT_M``).

The bow needs legs faster than Table IV's 0.6 rad/s^2: the limiter clamps it there (the robot
file's ``walking`` limit set, legs 2.6 rad/s and 150 rad/s^2, lets it act). It never acts while
the capture point stays more than ``start_m`` inside the shrunk soles (a standing robot, the
cutting tasks); it is only sagittal (sideways the feet stand apart).
"""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.control.keys import SUPPORT_BOX_WORLD
from hubo_cli.control.module import Cycle, Module
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import CAPTURE_POINT_WORLD, T_WORLD_SOLES
from hubo_cli.model import RobotModel
from hubo_cli.state import RobotState

# joint offsets per rad of trunk bow (hip pitch, knee, ankle pitch), solved on the model so that
# the torso pitches forward by 1 rad with the CoM's x and height unchanged to first order
# (pinocchio; at a 0.2 rad bow the CoM moves 0.4 mm along x and 3 mm down, a test checks it).
# Solved in the standing posture; in the braced one the hip strategy runs in (10 cm lower) the
# same bow moves the CoM 3.5 mm toward the bow. Offsets solved for an 8 cm brace (-1.306,
# -0.020, 0.326) kept it within 0.4 mm there but damped the rocking after a 90 N push worse on
# the perturbed robots (docs/history/balance.md), so these stay.
BOW_JOINTS_RAD = {"HP": -1.258, "KN": -0.028, "AP": 0.287}
START_M = 0.02           # act once the capture point is this close to the shrunk support edge
GAIN_RAD_S_PER_M = 60.0  # bow rate per metre of the capture point's excess over that band
MAX_RATE_RAD_S = 1.5
MAX_BOW_RAD = 0.3        # about 17 deg of trunk, on top of the body's own rocking
HOLD_S = 0.2             # the capture point back inside the band this long: return upright
RETURN_S = 1.0           # time constant of the return (0.5 with the rocking term: the body
#                          rocked 10.3 deg 2-3 s after a 90 N push; 2.0: 8.0 deg; 1.0: 6.9)
RETURN_RATE_RAD_S = 0.6
RETURN_MIN_RATE_RAD_S = 0.01  # so that the return ends
ROCK_GAIN = 5.0          # bow rate (rad/s) per rad of the soles' pitch while it returns
#                          (after a 90 N push, the largest tilt 3-4 s later: 3: 5.2 deg,
#                          5: 3.6, 8: 5.1, 15: 6.6)
FLAT_PITCH_RAD = 0.01    # the return ends once the soles are this flat for hold_s (the
#                          perturbed IMU's noise puts 0.2 deg on the estimated soles)
REST_PITCH_S = 1.0       # the soles' pitch standing (a tilted floor, the IMU's bias: up to
#                          0.5 and 0.2 deg perturbed) is learnt with this time constant, and
#                          the rocking measured from it


class HipStrategy(Module):
    """Bow the trunk at the hips while the capture point nears the soles' front or back edge.

    Args:
        model: the robot model (joint names and limits).
        start_m: the band inside the shrunk support box's front and back edges where the bow
            starts (m, > 0).
        gain: bow rate per metre of excess over that band (rad/s/m, > 0).
        max_rate_rad_s, max_bow_rad: the bow's rate and size bounds (> 0).
        hold_s: how long the capture point must stay inside the band before the return (s).
        return_s, return_rate_rad_s: the return's time constant (s) and rate bound (rad/s).

    Raises:
        ConfigError: a non-positive bound or gain.
    """

    name = "hip"
    reads = (CAPTURE_POINT_WORLD, SUPPORT_BOX_WORLD, T_WORLD_SOLES)
    log_columns = ("hip_bow_rad",)

    def __init__(self, model: RobotModel, dt_s: float, start_m: float = START_M,
                 gain: float = GAIN_RAD_S_PER_M, max_rate_rad_s: float = MAX_RATE_RAD_S,
                 max_bow_rad: float = MAX_BOW_RAD, hold_s: float = HOLD_S,
                 return_s: float = RETURN_S,
                 return_rate_rad_s: float = RETURN_RATE_RAD_S,
                 rock_gain: float = ROCK_GAIN) -> None:
        values = (start_m, gain, max_rate_rad_s, max_bow_rad, return_s, return_rate_rad_s)
        if not all(math.isfinite(v) and v > 0 for v in values) or not hold_s >= 0 \
                or not (math.isfinite(rock_gain) and rock_gain >= 0):
            raise ConfigError("hip strategy gains, bounds and times must be positive (the "
                              "rocking gain finite and >= 0)",
                              hint=f"e.g. start_m={START_M}, max_bow_rad={MAX_BOW_RAD}, "
                                   f"rock_gain={ROCK_GAIN}")
        self.dt_s = float(dt_s)
        self.start_m, self.gain = float(start_m), float(gain)
        self.max_rate_rad_s, self.max_bow_rad = float(max_rate_rad_s), float(max_bow_rad)
        self.hold_s, self.return_s = float(hold_s), float(return_s)
        self.return_rate_rad_s = float(return_rate_rad_s)
        self.rock_gain = float(rock_gain)
        names = model.joint_names
        self._joints = [(names.index(side + joint), per_rad)
                        for joint, per_rad in BOW_JOINTS_RAD.items() for side in "RL"]
        self._lower, self._upper = model.lower_rad, model.upper_rad
        self.reset(np.zeros(len(names)), None, None)

    def reset(self, q_rad: np.ndarray, state: RobotState | None,
              store: Store | None) -> None:
        """Start upright."""
        self.bow_rad = 0.0
        self.max_abs_bow_rad = 0.0
        self._inside_s = math.inf
        self._flat_s = 0.0  # how long the soles have been flat while it returns
        self._rest_pitch_rad: float | None = None  # the soles' pitch standing (low-passed)
        self._returning = False

    def _excess_m(self, cycle: Cycle) -> float:
        """The capture point's signed excess over the band: > 0 toward the front edge, < 0
        toward the back, 0 inside (m); 0 without a finite capture point or support box."""
        store = cycle.store
        cp_x = float(store[CAPTURE_POINT_WORLD][0])
        lo, hi = np.asarray(store[SUPPORT_BOX_WORLD], dtype=float)[:2].tolist()
        if not math.isfinite(cp_x + lo + hi):
            return 0.0
        forward = cp_x - (hi - self.start_m)
        backward = (lo + self.start_m) - cp_x
        if forward > 0 and forward >= backward:
            return forward
        if backward > 0:
            return -backward
        return 0.0

    @staticmethod
    def _soles_pitch_rad(cycle: Cycle) -> float:
        """The estimated soles' mean pitch (rad, > 0 tipped onto the toes); 0 when not
        finite. In Python floats (numpy's mean and arctan2 on two soles cost more, every
        standing period)."""
        pitches = [math.atan2(-z, math.hypot(x, y))  # each sole's x axis (x, y, z)
                   for x, y, z in np.asarray(cycle.store[T_WORLD_SOLES], dtype=float)[:, :3, 0]
                   .tolist()]
        pitch = sum(pitches) / len(pitches) if pitches else math.nan
        return pitch if math.isfinite(pitch) else 0.0

    def update(self, q_rad: np.ndarray, state: RobotState, cycle: Cycle) -> np.ndarray:
        excess = self._excess_m(cycle)
        bow, dt = self.bow_rad, cycle.dt_s
        if bow == 0.0:  # standing: the soles' pitch on this floor, as the estimate has it
            pitch = self._soles_pitch_rad(cycle)
            self._rest_pitch_rad = (pitch if self._rest_pitch_rad is None else
                                    self._rest_pitch_rad + dt / REST_PITCH_S
                                    * (pitch - self._rest_pitch_rad))
        if bow != 0.0 and (excess * bow < 0.0 or self._returning):
            excess = 0.0  # the body rocking back: the bow returns first
        if excess != 0.0:
            self._inside_s = self._flat_s = 0.0
            rate = min(self.gain * abs(excess), self.max_rate_rad_s)
            bow = min(max(bow + math.copysign(rate * dt, excess), -self.max_bow_rad),
                      self.max_bow_rad)
        else:
            self._inside_s += dt
            if self._inside_s >= self.hold_s and bow != 0.0:
                self._returning = True
                step = max(min(abs(bow) / self.return_s, self.return_rate_rad_s),
                           RETURN_MIN_RATE_RAD_S) * dt
                pitch = self._soles_pitch_rad(cycle) - self._rest_pitch_rad
                self._flat_s = self._flat_s + dt if abs(pitch) < FLAT_PITCH_RAD else 0.0
                rock = self.rock_gain * pitch * dt
                rock = min(max(rock, -self.max_rate_rad_s * dt), self.max_rate_rad_s * dt)
                if abs(bow) <= step and self._flat_s >= self.hold_s:  # settled
                    bow = 0.0
                else:
                    bow = min(max(bow - math.copysign(min(step, abs(bow)), bow) + rock,
                                  -self.max_bow_rad), self.max_bow_rad)
        if bow == 0.0:
            self._returning = False
        self.bow_rad = bow
        self.max_abs_bow_rad = max(self.max_abs_bow_rad, abs(bow))
        cycle.info["hip_bow_rad"] = bow
        if bow == 0.0:
            return q_rad
        q = np.array(q_rad, dtype=float)
        for i, per_rad in self._joints:
            if math.isfinite(q[i]):
                q[i] = min(max(q[i] + per_rad * bow, self._lower[i]), self._upper[i])
        return q
