"""A momentum (hip) strategy against a side push toward the stance foot in single support
(issue 37's 100 N pushes; docs/history/walking.md, round 12).

Pushed sideways toward the stance foot, the ZMP reaches the stance sole's outer edge and the
ankle can give no more: only the centroidal angular momentum's rate moves the centroidal
moment pivot (CMP) beyond that edge, cmp = zmp - dL/dt / (m g). The capture point the joints'
motion brings back is (omega^2 / (m g)) e^(omega T) sum_j A_j integral qdot_j e^(-omega t) dt
(tools/side_push_bound.py), A_j joint j's column of the centroidal map about the edge's axis:
motion early counts most, so each joint accelerates at once, runs at its top speed and brakes
only as late as its range lets it. The largest columns with the room toward the helpful side
are the two hip rolls, each abducting (the walking set lets them do nothing else): the stance
one rolls the torso toward the fall, the swing one lifts the swing leg outward (the flamingo).

:class:`MomentumStrategy` acts on the estimate only (the capture point, the stance sole's
pose; the plan's support). In a single support whose capture-point error from the pattern's was
under TRIGGER_M, an error past it toward the stance sole's outer side starts a watch: DECIDE_S
later, if the capture point would reach that sole's outer edge within EDGE_TIME_S at the speed
it came (or is past it), the strategy starts; else that step's push is left alone (the ankle,
the floor reach and the capture-point stop catch those pushes: round 10's 23 moments at 60 N,
and main's catches at 100 N, never start it) unless, later in the same single support, the
capture point goes PAST_M past that edge after all (a push a little weaker than the watch's
starts, as seed 18's at 75-80 N, round 14: the rest could not catch it); such a late start
counts the capture point's retreat only from the hips' arrival. A step that begins with the
error already past TRIGGER_M (the rebound after a push) is not watched. Started, the swing hip
roll abducts by SWING_AMPLITUDE_RAD (at most SWING_HIP_ROLL_MAX_RAD from zero: the hand hangs
by the thigh) and STANCE_DELAY_S later the stance hip roll by STANCE_AMPLITUDE_RAD (its
torque's reaction then meets the swing one's braking), each on a time-optimal profile
(VELOCITY_RAD_S, ACCELERATION_RAD_S2: a ramp, never a jump) within the walking set's limits less
LIMIT_MARGIN_RAD. They hold, and go back to zero at RETURN_VELOCITY_RAD_S and
RETURN_ACCELERATION_RAD_S2 once the capture point has come back RETREAT_M from its furthest
past the edge, or once both soles are planned down and in contact (the stop's stance). Once
per walk. Measured: docs/history/walking.md, round 12 (100 N on round 10's 23 moments: 12
without a fall against 5, portable 13 against 6; seeds 6, 10 and 18 of 1-20 still fall) and
round 14 (the late start: seed 18 at 75-80 N stands where main falls).
"""

from __future__ import annotations

import math

import numpy as np

DECIDE_S = 0.03  # [chosen] once the error passes TRIGGER_M, the capture point's approach to
                 # the stance sole's outer edge is watched this long; it starts if that
EDGE_TIME_S = 0.2  # [chosen] ... approach would reach the edge within this (or it is past)
RETREAT_M = 0.02  # [chosen] hand back once the capture point came back this far from its
                  # furthest past that edge
PAST_M = 0.01  # [chosen] a push left alone (passed) starts it after all once the capture
               # point is this far past the stance sole's outer edge (main's catches at
               # 75-80 N: 3.2-5.5 mm past; its falls: 15-56 mm; round 14)
TRIGGER_M = 0.025  # [chosen] the capture point's error toward the stance sole's outer side
                   # that starts a watch (unpushed 1 m walks: at most 12.8 mm, round 10; on
                   # round 14's main up to 31 mm, the capture point 158 mm or more inside)
VELOCITY_RAD_S = 2.3  # [chosen] under the walking set's 2.6 rad/s: the pattern's own hip
                      # roll moves meanwhile
ACCELERATION_RAD_S2 = 140.0  # [chosen] under the walking set's 150 rad/s^2
RETURN_VELOCITY_RAD_S = 1.0  # [chosen] the way back, slower
RETURN_ACCELERATION_RAD_S2 = 8.0  # [chosen]
LIMIT_MARGIN_RAD = 0.02  # [chosen] kept off the walking set's limit
SWING_HIP_ROLL_MAX_RAD = 0.33  # [measured] the swing hip roll's abduction at most this (from
                               # zero): the hand hanging by the thigh is 10 mm from it at 0.37
STANCE_AMPLITUDE_RAD = 0.25  # [chosen] the stance hip roll's abduction
SWING_AMPLITUDE_RAD = 0.5    # [chosen] the swing hip roll's abduction
STANCE_DELAY_S = 0.1  # [chosen] the stance hip roll starts this long after the swing one
                      # (both at once: the stance sole unloaded and the robot hopped)
SWING_DELAY_S = 0.0   # [chosen] the swing hip roll starts at once


def profile_step(x: float, v: float, goal: float, v_max: float, a_max: float, dt: float
                 ) -> tuple[float, float]:
    """One period of the time-optimal motion of ``x`` (speed ``v``) to ``goal``: accelerate at
    ``a_max`` up to ``v_max``, brake at ``a_max`` as late as lets it stop at ``goal``. The
    speed never changes by more than ``a_max * dt`` a period; the last periods may pass the
    goal by under ``a_max * dt**2`` (3.5 mrad at 140 rad/s^2) and come back (the goals keep
    LIMIT_MARGIN_RAD from the limits)."""
    d = goal - x
    if d == 0.0 and v == 0.0:
        return x, 0.0
    direction = 1.0 if d > 0 else -1.0
    # the fastest speed this period that still stops at goal, braking a_max * dt a period
    # from the next one on (d = v^2 / (2 a) + v dt / 2)
    brake = (math.sqrt((a_max * dt) ** 2 + 8.0 * a_max * abs(d)) - a_max * dt) / 2.0
    wanted = direction * min(v_max, brake)
    step = a_max * dt
    v_new = v + min(max(wanted - v, -step), step)
    if abs(v_new) * dt >= abs(d):  # the last step: onto the goal, as near as a_max lets it
        v_new = min(max(d / dt, v - step), v + step)
    x_new = x + v_new * dt
    if abs(goal - x_new) < 1e-12:
        return goal, v_new  # (arrived; the speed, under a_max * dt, goes to 0 next period)
    return x_new, v_new


PHASES = ("idle", "armed", "watching", "passed", "acting", "returning", "done")
"""The strategy's phases (:attr:`MomentumStrategy.phase`), each walk from ``idle``:

* ``idle``: nothing watched; a single support whose error is under TRIGGER_M arms it.
* ``armed``: this single support (its stance) had the error under TRIGGER_M; an error past it
  (with an estimate of the capture point past the edge) starts a watch. The support ended or
  changed: idle.
* ``watching``: a push watched since its error passed TRIGGER_M; after DECIDE_S, acting if the
  capture point would reach the outer edge within EDGE_TIME_S (or is past it), else passed. The
  support ended or changed: idle; no estimate past the edge: armed again.
* ``passed``: this step's push was left alone (the ankle, the floor reach and the stop catch
  it); idle once the single support ends; acting (a late start) if the capture point goes
  PAST_M past the outer edge before.
* ``acting``: the hip rolls go to their abductions (after their delays) and hold; returning
  once they stand still and either both soles are planned down and in contact or the capture
  point came back RETREAT_M from its furthest past the edge (a late start: its furthest since
  the hips arrived).
* ``returning``: both go back to zero; done once there and still.
* ``done``: once per walk: nothing more.
"""
STARTED = ("acting", "returning", "done")  # the phases after the strategy started


class MomentumStrategy:
    """The hip rolls' offsets (rad, right and left, added to the joints sent) of the momentum
    strategy (see the module docstring; its phases: :data:`PHASES`)."""

    def __init__(self, lower_rad: tuple[float, float], upper_rad: tuple[float, float],
                 dt_s: float, stance_amplitude_rad: float = STANCE_AMPLITUDE_RAD,
                 swing_amplitude_rad: float = SWING_AMPLITUDE_RAD) -> None:
        self.lower_rad = lower_rad  # the hip rolls' walking limits (right, left)
        self.upper_rad = upper_rad
        self.dt_s = dt_s
        self.stance_amplitude_rad = stance_amplitude_rad
        self.swing_amplitude_rad = swing_amplitude_rad
        self.offset_rad = np.zeros(2)
        self.velocity_rad_s = np.zeros(2)
        self.goal_rad = np.zeros(2)
        self.delay_s = np.zeros(2)  # each hip roll's time left before it starts
        self.phase = "idle"
        self.stance = 0  # armed, watching: the stance column of the single support
        self.watch_s = 0.0  # watching: the push watched this long (s)
        self.watch_past_m = 0.0  # ... the capture point past the outer edge when it began
        self.past_max_m = -math.inf  # started: the capture point's furthest past that edge
        self.late = False  # started past the edge (PAST_M), not by a watch

    @property
    def started(self) -> bool:
        """It acted in this walk (once)."""
        return self.phase in STARTED

    @property
    def acting(self) -> bool:
        """Started and not yet handing back."""
        return self.phase == "acting"

    def _next_phase(self, single: bool, stance: int, error: float, past_edge_m: float,
                    support: tuple[bool, bool], contact: tuple[bool, bool],
                    hip_roll_rad: tuple[float, float]) -> None:
        """The phase's transitions (:data:`PHASES`) for one period: ``single`` a single support
        on the ``stance`` column, ``error`` the capture point's error toward that sole's outer
        side (NaN in double support), the rest as :meth:`update` has them."""
        if self.phase in ("armed", "watching") and (not single or stance != self.stance):
            self.phase = "idle"  # (the step ended: watched no more)
        elif self.phase == "watching" and not math.isfinite(past_edge_m):
            self.phase = "armed"  # (no estimate: watched no more, this period)
        elif self.phase == "armed" and error > TRIGGER_M and math.isfinite(past_edge_m):
            self.phase, self.watch_s, self.watch_past_m = "watching", 0.0, past_edge_m
        elif self.phase == "watching":
            self.watch_s += self.dt_s
            if self.watch_s >= DECIDE_S - 1e-9:
                speed = (past_edge_m - self.watch_past_m) / self.watch_s
                self.phase = "passed"
                if past_edge_m >= 0.0 or (speed > 0.0 and -past_edge_m / speed < EDGE_TIME_S):
                    self._start(stance, hip_roll_rad)
        elif self.phase == "passed" and not single:
            self.phase = "idle"
        elif self.phase == "passed" and past_edge_m >= PAST_M:
            # (the push left alone went on past the edge: the rest did not catch it)
            self.late = True
            self._start(stance, hip_roll_rad)
        if self.phase == "idle" and error <= TRIGGER_M:
            # (this single support under the trigger: a push in it is watched; a step that
            # begins with the error beyond it, the rebound of an earlier push, is not)
            self.phase, self.stance = "armed", stance
        if self.started and math.isfinite(past_edge_m) and (not self.late or (
                np.array_equal(self.offset_rad, self.goal_rad)
                and not np.any(self.velocity_rad_s))):
            # (a late start counts from the hips' arrival: the capture point they pull in while
            # they move goes out again as they brake, and is not the push's end)
            self.past_max_m = max(self.past_max_m, past_edge_m)
        if self.phase == "acting" and not np.any(self.velocity_rad_s) and (
                (all(support) and all(contact)) or self.past_max_m - past_edge_m > RETREAT_M):
            self.phase = "returning"  # the step finished: hand back (both hip rolls)
            self.goal_rad[:] = 0.0

    def _start(self, stance: int, hip_roll_rad: tuple[float, float]) -> None:
        self.phase = "acting"
        for column in range(2):
            amplitude = (self.stance_amplitude_rad if column == stance
                         else self.swing_amplitude_rad)
            self.delay_s[column] = STANCE_DELAY_S if column == stance else SWING_DELAY_S
            sign = 1.0 if column == 1 else -1.0  # each hip roll's abduction
            room = (self.upper_rad[column] - hip_roll_rad[column] if sign > 0
                    else hip_roll_rad[column] - self.lower_rad[column])
            if column != stance:
                room = min(room, SWING_HIP_ROLL_MAX_RAD + LIMIT_MARGIN_RAD
                           - sign * hip_roll_rad[column])
            self.goal_rad[column] = sign * min(amplitude, max(room - LIMIT_MARGIN_RAD, 0.0))

    def update(self, cp_error_y_m: float, past_edge_m: float, support: tuple[bool, bool],
               contact: tuple[bool, bool], hip_roll_rad: tuple[float, float]) -> np.ndarray:
        """One period: ``cp_error_y_m`` the estimated capture point's sideways error from the
        pattern's (world y, m; > 0 to the left), ``support`` the pattern's soles down and
        ``contact`` the estimate's (right, left), ``hip_roll_rad`` the hip rolls about to be
        sent without the offsets. Returns the offsets (right, left; rad)."""
        single = support[0] != support[1]
        stance = 0 if support[0] else 1
        outward = 1.0 if stance == 1 else -1.0  # the stance sole's outer side (world y)
        error = outward * cp_error_y_m if single else math.nan
        self._next_phase(single, stance, error, past_edge_m, support, contact, hip_roll_rad)
        if self.phase not in ("acting", "returning"):
            return self.offset_rad
        returning = self.phase == "returning"
        for column in range(2):
            if self.delay_s[column] > 0.0 and not returning:
                self.delay_s[column] -= self.dt_s
                continue
            v_max, a_max = ((RETURN_VELOCITY_RAD_S, RETURN_ACCELERATION_RAD_S2)
                            if returning else (VELOCITY_RAD_S, ACCELERATION_RAD_S2))
            self.offset_rad[column], self.velocity_rad_s[column] = profile_step(
                float(self.offset_rad[column]), float(self.velocity_rad_s[column]),
                float(self.goal_rad[column]), v_max, a_max, self.dt_s)
        if returning and not np.any(self.offset_rad) and not np.any(self.velocity_rad_s):
            self.phase = "done"
        return self.offset_rad
