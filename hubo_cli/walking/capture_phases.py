"""The capture stepper's phases (:class:`~hubo_cli.control.phase.Phase`), in the order of
:data:`PHASES` (the log's ``capture.phase_code`` is the index), and the capture step's pattern
(:func:`pendulum`, :func:`travel`, :func:`capture_swing_rows`, :func:`landing`).

Each acts on its :class:`~hubo_cli.walking.capture_step.CaptureStepper` and returns this
period's joint target and the pattern's CoM reference (x, y; NaN while none). They hand over by
themselves: *stand* until the capture point comes within ``TRIGGER_M`` of the shrunk soles;
*step* (started in that period: the swing foot and the stance ZMP chosen) until the swing foot
is down; *catch* (planned at touch-down: a short step's rest over the landed sole and return
step, or a long step's lunge) until its pattern reaches the return; *return* (the lunge's
return step planned when it starts) until the pattern ends; *stood*, holding the pattern's last
posture. A phase entered at a touch-down or a pattern's end runs from the next period (the
output of the one it follows stands). What a phase asks of the pipeline
(:meth:`CapturePhase.balancers_rest`, :meth:`CapturePhase.planned_soles`) the stepper writes as
store keys every period, never touching a module.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hubo_cli.control.phase import Phase
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
)
from hubo_cli.geometry import pose_laid_flat
from hubo_cli.kinematics.limb import Limb
from hubo_cli.state import GRAVITY_M_S2, RobotState
from hubo_cli.walking.body import SIDE_LEG, WalkingBody, pose_of_row
from hubo_cli.walking.footsteps import SIDE_SIGN, Footstep, stance_of, wrap_angle
from hubo_cli.walking.gait import SWING_MOVE, Gait, make_gait, smoothstep5
from hubo_cli.walking.preview import CoMPath
from hubo_cli.walking.stabilizer import SoleDamper, StabilizerGains
from hubo_cli.walking.support import SIDES, ankle_wrenches, estimated_feet, planned_support

if TYPE_CHECKING:
    from hubo_cli.walking.capture_step import CaptureStepper

PHASES = ("stand", "step", "catch", "return", "stood")  # capture.phase_code is the index

SINGLE_SUPPORT_S = 0.40  # [chosen] the capture step's swing: short, the pendulum diverges
SWING_HEIGHT_M = 0.04    # [chosen] sole clearance at mid-swing
ZMP_AHEAD_M = 0.09       # [chosen] stance ZMP ahead of the sole's middle, toward the push
ZMP_INSET_M = 0.04       # [chosen] ... and inside, toward the swing foot
MIN_STEP_M = 0.10        # [chosen] the step goes at least this far the push's way
MAX_STEP_M = 0.50        # [chosen] landing within this of the stance foot (the legs reach it
#                          with the torso lowered, see reach_drop_m: 0.05 m for 0.48 m ahead)
MAX_WIDTH_M = 0.35       # [chosen] the feet at most this far apart sideways
CATCH_S = 1.0            # [chosen] both feet down, the CoM comes to rest on the landed foot
CATCH_EDGE_M = 0.03      # [chosen] the catch's ZMP stays this far inside the landed sole's ends
LANDED_M = 0.003         # a swing sole this close to the ground has landed
LAND_WAIT_S = 0.2        # [chosen] wait at most this long after the swing for it to land
TOUCH_FRACTION = 0.5     # [chosen] a swing sole carrying estimation.swing_touchdown_n is
#                          down once this much of the swing has passed
LONG_STEP_M = 0.15       # [chosen] a capture step longer than this: the robot stays in the lunge
LUNGE_CATCH_S = 2.0      # [chosen] ... while the CoM comes to rest in it, at least, and then
LUNGE_WAIT_S = 2.0       # [chosen] ... at most this much longer until it is at rest: its
SETTLED_SPEED_M_S = 0.05  # [chosen] ... estimated speed under this (the return, a walking
#                          step with the balancers at rest, started in mid-sway after 2 s and
#                          the sway carried the robot out of the stance: 150 N backward at 1.0
#                          and 2.0 s)
UPRIGHT_S = 0.3          # [chosen] ... and the torso turns back upright over this long
RETURN_FOOT_SPEED_M_S = 0.5  # [chosen] the return swing's peak foot speed (its smoothstep's)
RETURN_SHIFT_S = 1.0     # [chosen] the return's double support: the CoM over the front foot
MAX_SOLE_ERROR_M = 0.2   # [chosen] the legs' capped solutions accepted this far off their soles
TRIGGER_M = 0.05         # [chosen] step once the CP is within this of the shrunk polygon's edge
REPLAN_FRACTION = 0.6    # [chosen] the landing follows the measured CP over this much of the swing
RAMP_FRACTION = 0.2      # [chosen] the capture swing's speed ramps over this much of its travel
TRAVEL_END = 0.9         # [chosen] ... which ends at this fraction of the swing

NO_REFERENCE = (math.nan, math.nan)


def pendulum(c0: np.ndarray, v0: np.ndarray, p: np.ndarray, omega: float,
             t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear inverted pendulum over a fixed ZMP ``p`` (2,): CoM position, velocity and
    acceleration (len(t), 2) from (c0, v0) at t = 0."""
    ch, sh = np.cosh(omega * t_s)[:, None], np.sinh(omega * t_s)[:, None]
    d0, w = c0 - p, omega
    c = p + d0 * ch + v0 / w * sh
    v = d0 * w * sh + v0 * ch
    return c, v, w * w * (c - p)


def travel(tau: np.ndarray) -> np.ndarray:
    """The capture swing's progress (0..1) at swing fractions ``tau``: a trapezoidal speed
    from the swing's start to TRAVEL_END, each ramp RAMP_FRACTION of that. The legs' speed
    limit bounds the swing foot's peak speed: a trapezoid needs 1 / (1 - r) of the mean
    (1.25), the walking swing's fifth-order smoothstep over 0.1..0.9 of the swing 2.3 times."""
    u = np.clip(np.asarray(tau, dtype=float) / TRAVEL_END, 0.0, 1.0)
    r = RAMP_FRACTION
    peak = 1.0 / (1.0 - r)
    return np.where(u < r, peak * u**2 / (2 * r),
                    np.where(u > 1 - r, 1.0 - peak * (1 - u)**2 / (2 * r),
                             peak * (u - r / 2)))


def capture_swing_rows(start: Footstep, end: Footstep, n: int, height_m: float,
                       z_m: float) -> np.ndarray:
    """The capture step's swing foot: (n, 4) rows of (x, y, z, yaw), sample k at
    tau = (k + 1) / n; it travels from the first period on (:func:`travel`) and lifts as
    sin(pi tau) (off the ground early, down late: a foot that lags its pattern under the
    speed limit still clears the ground)."""
    tau = (np.arange(n) + 1.0) / n
    s = travel(tau)
    rows = np.empty((n, 4))
    rows[:, 0] = start.x_m + s * (end.x_m - start.x_m)
    rows[:, 1] = start.y_m + s * (end.y_m - start.y_m)
    rows[:, 2] = z_m + height_m * np.sin(np.pi * tau)
    rows[:, 3] = start.yaw_rad + s * wrap_angle(end.yaw_rad - start.yaw_rad)
    return rows


def _row(foot: Footstep, z_m: float) -> np.ndarray:
    return np.array([foot.x_m, foot.y_m, z_m, foot.yaw_rad])


def landing(stance: Footstep, side: str, xi_m: np.ndarray, forward_m: float,
            width_m: float, min_ahead_m: float = 0.0, hip_m: float = 0.0) -> Footstep:
    """Where the swing foot ``side`` lands: its sole's middle on ``xi_m`` (world x, y), within
    MAX_STEP_M of the stance foot, ``width_m`` to MAX_WIDTH_M from it sideways, at least
    ``min_ahead_m`` ahead of it (negative: at least that far behind; the push's way), heading
    as the stance foot. A landing too far gives up its sideways part first (down to
    ``width_m``), then its forward one: the length the push's way is what catches it. A long
    one (beyond LONG_STEP_M) then goes ``hip_m`` further out (at most MAX_WIDTH_M): the
    backward lunge's, so that the landed leg's hip stays inside its ankle with the CoM over
    the capture point (the hip roll joints only abduct: landed under the CoM, the leg could
    not hold its sole under the pelvis, the pattern froze and the stance foot hung)."""
    c, s = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
    dx, dy = xi_m[0] - stance.x_m, xi_m[1] - stance.y_m
    ahead = c * dx + s * dy - forward_m          # the ankle goes forward_m behind the middle
    if min_ahead_m > 0:
        ahead = max(ahead, min_ahead_m)
    elif min_ahead_m < 0:
        ahead = min(ahead, min_ahead_m)
    across = SIDE_SIGN[side] * (-s * dx + c * dy)  # toward the swing side: positive
    across = min(max(across, width_m), MAX_WIDTH_M)
    if math.hypot(ahead, across) > MAX_STEP_M:
        across = max(math.sqrt(max(MAX_STEP_M**2 - ahead**2, 0.0)), width_m)
        ahead = math.copysign(min(abs(ahead),
                                  math.sqrt(max(MAX_STEP_M**2 - across**2, 0.0))), ahead)
    if abs(ahead) > LONG_STEP_M:
        across = min(across + hip_m, MAX_WIDTH_M)
    left = SIDE_SIGN[side] * across
    return Footstep(side, stance.x_m + c * ahead - s * left, stance.y_m + s * ahead + c * left,
                    stance.yaw_rad)


def landed_period(gait: Gait) -> int:
    """The first period of ``gait`` after its last swing, both feet down."""
    return int(np.nonzero(~gait.support.all(axis=1))[0][-1]) + 1


Output = tuple[np.ndarray, tuple[float, float]]


class CapturePhase(Phase[Output]):
    """A phase of the capture stepper: its output is the period's joint target and the
    pattern's CoM reference (x, y). What it asks of the pipeline: by default nothing (the
    balancers act, the monitor watches the estimated soles with its margin)."""

    def __init__(self, stepper: CaptureStepper) -> None:
        self.stepper = stepper

    def balancers_rest(self) -> bool:
        """The standing balancers rest this period (the pattern moves the CoM itself)."""
        return False

    def planned_soles(self) -> np.ndarray | None:
        """(2, 4, 4) the support the monitor watches, unshrunk (None: the estimated soles
        with its margin)."""
        return None

    def stop_within_s(self) -> float | None:
        """How a stop latched now ends this phase: None, the stopper reverts the motion
        (standing); else the time (s) the phase takes to finish into its double-support
        stance, where the stopper holds it (0: it stands there now)."""
        return None


class Stand(CapturePhase):
    """The standing target's posture, until the capture point comes within TRIGGER_M of the
    soles' hull shrunk by the monitor's margin (not in the first period, nor while the soft
    stopper is latched or blending back after a release: its output is not the step's)."""

    name = "stand"

    def run(self, t_s: float, state: RobotState) -> tuple[Output, str | None]:
        stepper = self.stepper
        triggered = (state.time_s > 0 and stepper.stop_released
                     and stepper.outside_m() > -TRIGGER_M)
        return (stepper.q_standing, NO_REFERENCE), ("step" if triggered else None)


class Step(CapturePhase):
    """The capture step: the foot on the capture point's side swings toward it, the CoM
    follows the pendulum over the stance ZMP, until the swing foot is down."""

    name = "step"

    def start(self, t_s: float, state: RobotState) -> None:
        """Choose the swing foot and the stance ZMP; the step starts this period."""
        s = self.stepper
        store = s.store
        feet = estimated_feet(store)
        self.feet = feet
        s.start_feet = [feet["right"], feet["left"]]
        s.sole_z_m = float(store[T_WORLD_SOLES][0, 2, 3])
        s.height_m = float(store[COM_WORLD][2]) - s.sole_z_m
        s.omega = math.sqrt(GRAVITY_M_S2 / s.height_m)
        cp = np.array(store[CAPTURE_POINT_WORLD][:2], dtype=float)
        velocity = np.array(store[COM_VELOCITY_WORLD][:2], dtype=float)
        middle = stance_of(feet["right"], feet["left"])
        across = (-math.sin(middle.yaw_rad) * (cp[0] - middle.x_m)
                  + math.cos(middle.yaw_rad) * (cp[1] - middle.y_m))
        if abs(across) > 0.01:
            swing = "left" if across > 0 else "right"
        else:  # between the feet: the less loaded one lifts
            wrenches = ankle_wrenches(store)
            swing = "right" if wrenches[0, 2] < wrenches[1, 2] else "left"
        s.swing, s.stance_side = swing, "left" if swing == "right" else "right"
        stance = feet[s.stance_side]
        s.width_m = math.hypot(feet["right"].x_m - feet["left"].x_m,
                               feet["right"].y_m - feet["left"].y_m)
        c, sn = math.cos(stance.yaw_rad), math.sin(stance.yaw_rad)
        s.heading = np.array([c, sn])
        inward = -SIDE_SIGN[s.stance_side] * np.array([-sn, c])
        forward = s.model.feet.forward_m
        way = float(np.sign(velocity @ s.heading))  # forward (1) or backward (-1) push
        ahead = way * ZMP_AHEAD_M
        self.min_ahead_m = way * MIN_STEP_M
        self.zmp_m = (np.array([stance.x_m, stance.y_m]) + (forward + ahead) * s.heading
                      + ZMP_INSET_M * inward)
        T_world_neck = np.array(store[T_WORLD_TORSO], dtype=float)
        s.body = WalkingBody(s.model, s.q_stand, T_world_neck)
        # a long step asks the legs for their full reach (the torso lowering follows): take
        # their capped solutions rather than freeze the joints
        s.body.max_error_m = MAX_SOLE_ERROR_M
        s.neck_z0_m = s.body.neck_z_m
        L = s.model.lengths_m  # the hip joints above the ankles, standing
        s.hip_height_m = (s.neck_z0_m - L["lT"] - L["lL2"]) - (s.sole_z_m + L["lL5"])
        s.legs = {side: Limb(s.model, SIDE_LEG[side]) for side in ("right", "left")}
        self.n = max(1, int(round(SINGLE_SUPPORT_S / s.model.control_period_s)))
        self.k, s.trigger_s = 0, t_s
        self.land = feet[swing]

    def run(self, t_s: float, state: RobotState) -> tuple[Output, str | None]:
        """One period of the capture step: the landing follows the measured capture point
        (until REPLAN_FRACTION of the swing), the CoM the pendulum from the measured state.
        The swing foot lags its pattern under the limits: the step ends when it carries the
        robot file's ``estimation.swing_touchdown_n`` (after TOUCH_FRACTION of the swing) or
        is down (or LAND_WAIT_S after the pattern's end)."""
        s = self.stepper
        store, period, omega = s.store, s.model.control_period_s, s.omega
        k, n = self.k, self.n
        stance = self.feet[s.stance_side]
        if k <= REPLAN_FRACTION * n:
            xi = self.zmp_m + ((store[CAPTURE_POINT_WORLD][:2] - self.zmp_m)
                               * math.exp(omega * (n - k) * period))
            self.land = landing(stance, s.swing, xi, s.model.feet.forward_m, s.width_m,
                                self.min_ahead_m,
                                s.model.lengths_m["lL1"] if self.min_ahead_m < 0 else 0.0)
        com, velocity = store[COM_WORLD][:2], store[COM_VELOCITY_WORLD][:2]
        c, v, a = pendulum(com, velocity, self.zmp_m, omega, np.array([period]))
        swing_row = capture_swing_rows(self.feet[s.swing], self.land, n, SWING_HEIGHT_M,
                                       s.sole_z_m)[min(k, n - 1)]
        feet = {s.stance_side: _row(stance, s.sole_z_m), s.swing: swing_row}
        support = np.zeros((1, 2), dtype=bool)
        support[0, 0 if s.stance_side == "right" else 1] = True
        drop = s.reach_drop_m(stance, self.land) * float(smoothstep5(min((k + 1) / n, 1.0)))
        s.body.neck_z_m = s.neck_z0_m - drop
        q = s.solve_period(c, v, a, self.zmp_m, feet, support)
        # the swing foot lands flat where it should in the world whatever the torso's tilt:
        # its goal in the measured neck frame
        T_world_neck = np.array(store[T_WORLD_TORSO], dtype=float)
        leg, part = s.legs[s.swing], s.model.limb_slice(SIDE_LEG[s.swing])
        result = leg.solve(np.linalg.inv(T_world_neck) @ pose_of_row(swing_row), q[part])
        if result.status in ("exact", "capped"):
            q = q.copy()
            q[part] = result.q_rad
            s.body.q_start = q
        self.k += 1
        swing = SIDES.index(s.swing)
        height = float(store[T_WORLD_SOLES][swing, 2, 3]) - s.sole_z_m
        loaded = (float(ankle_wrenches(store)[swing, 2])
                  > s.model.estimation.swing_touchdown_n)
        following = None
        if (self.k >= TOUCH_FRACTION * n and loaded) or (
                self.k >= n and (height < LANDED_M or self.k >= n + LAND_WAIT_S / period)):
            s.R_touch_down = T_world_neck[:3, :3].copy()
            s.touch_down_com = (c[0], v[0])
            following = "catch"
        return (q, (float(c[0, 0]), float(c[0, 1]))), following

    def balancers_rest(self) -> bool:
        return True

    def stop_within_s(self) -> float:
        """The swing lands, then the catch (:class:`Catch`)."""
        period = self.stepper.model.control_period_s
        return (max(self.n - self.k, 0) * period + LAND_WAIT_S
                + max(CATCH_S, LUNGE_CATCH_S + LUNGE_WAIT_S))

    def planned_soles(self) -> np.ndarray:
        """The swing foot at its landing place."""
        s = self.stepper
        feet = {s.stance_side: self.feet[s.stance_side], s.swing: self.land}
        return np.array([pose_of_row(_row(feet[side], s.sole_z_m))
                         for side in ("right", "left")])


class PatternPhase(CapturePhase):
    """A phase that follows the pattern planned at touch-down (the catch and the return);
    the monitor watches the pattern's support, where the estimate has the feet now."""

    def follow(self, rest: Gait) -> None:
        """The stepper plays ``rest`` from now: with its support
        (:func:`~hubo_cli.walking.support.planned_support`) and the inverse of the landed
        foot's planned sole at its start, constant while it plays (:meth:`planned_soles`
        moves the plan by it every period)."""
        s = self.stepper
        s.rest = rest
        s.rest_support = planned_support(rest)
        s.T_landed_plan_world = np.linalg.inv(s.rest_support[0][SIDES.index(s.swing)])

    def planned_soles(self) -> np.ndarray:
        """The pattern's support this period, in the estimate's frame of now: the estimate's
        world drifts under a bouncing, sliding foot (the floating base hands its anchor from
        sole to sole), so the soles planned where the estimate had them at the pattern's
        start are stale. A foot the pattern keeps where it started is taken where the
        estimate has it now, laid flat; a foot that swings (or has swung), at its planned
        landing moved as the landed foot (which the pattern never moves) has moved since."""
        s = self.stepper
        k = min(s.k, s.rest.n - 1)
        plan = s.rest_support[k].copy()
        now = s.store[T_WORLD_SOLES]
        z = float(plan[0, 2, 3])
        flat = [pose_laid_flat(T, z) for T in now]
        anchor = SIDES.index(s.swing)  # the landed foot
        moved = flat[anchor] @ s.T_landed_plan_world
        for i, side in enumerate(SIDES):
            rows = s.rest.feet[side]
            kept = s.rest.support[k, i] and np.array_equal(rows[k], rows[0])
            plan[i] = flat[i] if kept else moved @ plan[i]
        return plan

    def stop_within_s(self) -> float:
        """The pattern plays on to its stance: the catch's end (a lunge's at the latest)."""
        s = self.stepper
        end = s.n_catch if s.track is None else s.rest.n
        return max(end - s.k, 0) * s.model.control_period_s


class Catch(PatternPhase):
    """Both feet down: after a short step the CoM comes to rest over the landed sole (the
    pattern then goes on into the return step); after a long one (LONG_STEP_M) the robot
    stays in the lunge while the CoM comes to rest in it (LUNGE_CATCH_S, then until the
    estimated CoM is slower than SETTLED_SPEED_M_S, at most LUNGE_WAIT_S more). The standing
    balancers rest throughout: acting in the lunge's stance, whose soles are far apart
    along a diagonal, they rocked the robot sideways ever wider (150 N forward pushed at
    1.0 s rolled out over the back foot's edge). A catch ending while the soft stopper is
    latched (or still blending back after a release: the return step, an open-loop pattern,
    must not play lagged through its blend) goes to stood with the return step pending, held
    there by the stopper; it follows once the stopper is released (:class:`Stood`)."""

    name = "catch"
    runs_at_start = False  # the step's last output stands in the period it touches down

    def start(self, t_s: float, state: RobotState) -> None:
        """The swing foot is down: plan the catch and the return step."""
        s = self.stepper
        com_m, velocity_m_s = s.touch_down_com
        period, omega = s.model.control_period_s, s.omega
        # from where the feet are now (the swing foot lags its pattern under the limits and
        # lands short of its goal; the stance foot may have slid): the catch and the return
        # step start from the measured soles, so the legs do not fight each other
        measured = estimated_feet(s.store)
        land, stance = measured[s.swing], measured[s.stance_side]
        forward = s.model.feet.forward_m
        sole_middle = np.array([land.x_m, land.y_m]) + forward * s.heading
        xi = com_m + velocity_m_s / omega
        # the ZMP can only be held on the landed sole: the CoM comes to rest within it
        ahead = float(np.array([land.x_m - stance.x_m, land.y_m - stance.y_m]) @ s.heading)
        long_step = abs(ahead) > LONG_STEP_M
        reach = s.model.feet.length_m / 2 - CATCH_EDGE_M
        xi = sole_middle + np.clip(xi - sole_middle, -reach, reach)
        after = {s.swing: land, s.stance_side: stance}
        beside = SIDE_SIGN[s.stance_side] * s.width_m
        sn, co = s.heading[1], s.heading[0]
        back = Footstep(s.stance_side, land.x_m - sn * beside, land.y_m + co * beside,
                        land.yaw_rad)
        s.k = 0
        if long_step:
            self._lunge(land, stance, sole_middle, com_m, xi)
            return
        n = max(1, int(round(CATCH_S / period)))
        t = (np.arange(n) + 1.0) * period
        # the CoM from (c, v) to rest over the landed sole (the ZMP held at its middle, the
        # capture point's excess decays with the stable root): c = m + (xi - m) ... shaped as
        # the pendulum's converging part plus the stable decay
        d = com_m - sole_middle
        e = xi - sole_middle  # the part that diverges: the ZMP is held on it below
        decay = np.exp(-omega * t)[:, None]
        c = sole_middle + e + (d - e) * decay
        v = -omega * (d - e) * decay
        a = omega**2 * (d - e) * decay
        zmp = np.tile(sole_middle + e, (n, 1))
        s.n_upright = n
        ret = make_gait(after["right"], after["left"], [back], s.params, period,
                        s.height_m, s.sole_z_m, forward, com_start_m=c[-1])
        rows = {side: np.vstack([np.tile(_row(after[side], s.sole_z_m), (n, 1)),
                                 ret.feet[side]]) for side in ("right", "left")}
        self.follow(Gait(period, (back,), s.height_m, np.vstack([zmp, ret.zmp_ref_m]),
                         CoMPath(np.vstack([c, ret.com.com_m]),
                                 np.vstack([v, ret.com.com_velocity_m_s]),
                                 np.vstack([a, ret.com.com_acceleration_m_s2]),
                                 np.vstack([zmp, ret.com.zmp_m])),
                         rows, np.vstack([np.ones((n, 2), dtype=bool), ret.support]),
                         np.concatenate([np.full(n, -1), ret.step_index])))
        s.landed_k = landed_period(s.rest)
        s.n_catch = n
        s.steps, s.return_step = [land], back  # the return footstep once it starts

    def _lunge(self, land: Footstep, stance: Footstep, sole_middle: np.ndarray,
               com_m: np.ndarray, xi_m: np.ndarray) -> None:
        """After a long step: both feet stay down (the stepped stance, one step); the CoM
        comes to rest where the measured capture point says (the stepper's pattern period)."""
        s = self.stepper
        period = s.model.control_period_s
        n = max(1, int(round((LUNGE_CATCH_S + LUNGE_WAIT_S) / period)))  # at most
        rows = {s.swing: np.tile(_row(land, s.sole_z_m), (n, 1)),
                s.stance_side: np.tile(_row(stance, s.sole_z_m), (n, 1))}
        c = np.tile(com_m, (n, 1))
        zmp = np.tile(sole_middle, (n, 1))
        self.follow(Gait(period, (), s.height_m, zmp, CoMPath(c, 0 * c, 0 * c, zmp), rows,
                         np.ones((n, 2), dtype=bool), np.full(n, -1)))
        back = np.array([stance.x_m, stance.y_m]) + s.model.feet.forward_m * s.heading
        # the landed foot ahead of the stance foot (1, a forward push) or behind it (-1)
        s.way = 1.0 if (sole_middle - back) @ s.heading >= 0.0 else -1.0
        s.track = {"com": np.asarray(com_m, dtype=float).copy(), "front": sole_middle,
                   "back": back, "reach": s.model.feet.length_m / 2 - CATCH_EDGE_M,
                   "ankles": None if s.way > 0 else {foot.side: np.array([foot.x_m, foot.y_m])
                                                     for foot in (land, stance)}}
        s.track["rest"] = s.in_stance(xi_m)
        s.reach_m = None  # the back leg's reach at touch-down (toe-off)
        s.n_upright = max(1, int(round(UPRIGHT_S / period)))
        s.n_catch = max(1, int(round(LUNGE_CATCH_S / period)))  # at least
        s.steps = [land]

    def run(self, t_s: float, state: RobotState) -> tuple[Output, str | None]:
        s = self.stepper
        out = s.pattern_period()
        if s.k < s.n_catch or (s.track is not None and s.k < s.rest.n and float(
                np.hypot(*s.store[COM_VELOCITY_WORLD][:2])) >= SETTLED_SPEED_M_S):
            return out, None
        if s.stop_released:
            return out, "return"
        s.return_pending, s.stop_s = True, s.latch_s  # held in the catch's stance
        return out, "stood"

    def balancers_rest(self) -> bool:
        return True


class Return(PatternPhase):
    """One walking step brings the other foot beside the landed one: a short step's pattern
    goes on; after the lunge it is planned now (:meth:`start`). The balancers rest until the
    back foot is down. A stop latched meanwhile: the robot stands once that foot is down
    (the settle between the feet is not played, then or after the release: the feet stand
    side by side and the balancers act)."""

    name = "return"
    runs_at_start = False  # the catch's last output stands

    def start(self, t_s: float, state: RobotState) -> None:
        """After the lunge: one walking step (:func:`~hubo_cli.walking.gait.make_gait`, the
        robot file's walking parameters but a RETURN_SHIFT_S double support and a swing whose
        smoothstep peaks at RETURN_FOOT_SPEED_M_S) from the measured soles brings the back
        foot beside the front one at the standing width. The torso lowers and leans as when
        walking and the back heel rises for the legs' reach; the front sole's foot damping
        starts from rest."""
        s = self.stepper
        s.return_pending, s.stop_s = False, None
        if s.track is None:  # a short step: the catch's pattern goes on into the return
            s.steps = [s.steps[0], s.return_step]
            return
        period, forward = s.model.control_period_s, s.model.feet.forward_m
        measured = estimated_feet(s.store)
        front = measured[s.swing]
        beside = SIDE_SIGN[s.stance_side] * s.width_m
        sn, co = math.sin(front.yaw_rad), math.cos(front.yaw_rad)
        back = Footstep(s.stance_side, front.x_m - sn * beside, front.y_m + co * beside,
                        front.yaw_rad)
        rear = measured[s.stance_side]
        distance = math.hypot(back.x_m - rear.x_m, back.y_m - rear.y_m)
        lo, hi = SWING_MOVE
        single = max(s.params.single_support_s,
                     distance * 1.875 / (hi - lo) / RETURN_FOOT_SPEED_M_S)
        params = s.params.with_changes(single_support_s=single,
                                       double_support_s=RETURN_SHIFT_S,
                                       swing_height_m=SWING_HEIGHT_M)
        self.follow(make_gait(measured["right"], measured["left"], [back], params, period,
                              s.height_m, s.sole_z_m, forward,
                              com_start_m=s.track["com"].copy()))
        s.landed_k = landed_period(s.rest)
        s.drop_m = s.neck_z0_m - s.body.neck_z_m
        s.reach_m = None
        feet = s.model.feet
        box = (feet.forward_m - feet.length_m / 2, feet.forward_m + feet.length_m / 2,
               -feet.width_m / 2, feet.width_m / 2)
        s.damper = SoleDamper(StabilizerGains(), box, period,
                              s.model.estimation.sole_damping_min_fz_n)
        # the back leg reaches its sole with the heel raised (toe-off), not flat
        s.body.max_error_m = math.inf
        s.track, s.lunge_return = None, True
        s.n_catch, s.n_upright = 0, 1
        s.steps = [front, back]
        s.k = 0

    def run(self, t_s: float, state: RobotState) -> tuple[Output, str | None]:
        s = self.stepper
        out = s.pattern_period()
        # a stop latched: the robot stands once the back foot is down beside the front one
        if s.stop_latched and s.landed_k <= s.k < s.rest.n:
            s.stop_s = s.latch_s
            return out, "stood"
        return out, ("stood" if s.k >= s.rest.n else None)

    def stop_within_s(self) -> float:
        """The return step plays on until its foot is down."""
        s = self.stepper
        return max(s.landed_k - s.k, 0) * s.model.control_period_s

    def balancers_rest(self) -> bool:
        s = self.stepper  # after the lunge: until the back foot is beside the front one
        return not (s.lunge_return and s.k >= s.landed_k)


class Stood(CapturePhase):
    """The pattern has ended: hold its last posture (the balancers act); where the feet
    stand is noted for the summary. After a catch a stop ended, the return step is pending:
    the robot is held in the catch's stance, the monitor watching it unshrunk as in the
    catch (:meth:`planned_soles`), the balancers resting (in a lunge's long
    diagonal stance they rocked the robot sideways ever wider, as in the catch, and 165 N
    forward held there 5.5 s fell; and they would move the CoM off the pattern the return
    starts from), and once the soft stopper is released (its blend back over, which here
    ends where the pattern stands) the return step follows: a short step's pattern goes on,
    a lunge's return is planned from the measured soles. The robot so never stands with the
    balancers resting and no stop holding it."""

    name = "stood"
    runs_at_start = False  # the return's last output stands

    def start(self, t_s: float, state: RobotState) -> None:
        s = self.stepper
        self.q_hold = s.q_last
        s.stood_s = t_s
        feet = estimated_feet(s.store)
        s.stood_feet = [feet[side] for side in SIDES]

    def run(self, t_s: float, state: RobotState) -> tuple[Output, str | None]:
        s = self.stepper
        resume = s.return_pending and s.stop_released
        return (self.q_hold, NO_REFERENCE), ("return" if resume else None)

    def balancers_rest(self) -> bool:
        return self.stepper.return_pending

    def planned_soles(self) -> np.ndarray | None:
        """With the return pending, as in the catch: the stepped stance, unshrunk, where the
        estimate has the feet now (laid flat; with the margin a 150 N lunge's capture point
        was outside 10 ms into its stance, and its release met a capture-point stop)."""
        s = self.stepper
        if not s.return_pending:
            return None
        return np.array([pose_laid_flat(T, s.sole_z_m) for T in s.store[T_WORLD_SOLES]])

    def stop_within_s(self) -> float:
        return 0.0
