"""Push recovery by stepping: when the capture point leaves what the ankles can hold, step
toward it (the capture step), then bring the other foot back beside it.

The robot stands (a standing target, e.g. :class:`~hubo_cli.experiments.standing.StandTarget`,
gives the posture and does its own measuring). Each period the :class:`CaptureStepper` reads
the estimate (:mod:`hubo_cli.estimation.keys`: the soles, the torso, contact, the ankles'
compensated wrenches, the CoM, its velocity and the capture point); when the CP comes within
``TRIGGER_M`` of the soles' hull shrunk by the capture-point monitor's margin (where the ankle
and hip strategies run out) it plans, from the estimated feet and CoM, on the linear inverted
pendulum (omega^2 = g / z_c):

1. *capture step*, ``SINGLE_SUPPORT_S``: the foot on the CP's side (the less loaded one when
   the CP lies between the feet) swings; the ZMP sits on the stance sole ``ZMP_AHEAD_M`` ahead
   of its middle toward the push and ``ZMP_INSET_M`` inside toward the swing foot, and the CoM
   follows the pendulum, c(t) = p + (c0 - p) cosh(wt) + v0 / w sinh(wt). The swing foot lands
   with its sole's middle on the capture point the pendulum has at touch-down,
   xi = c + c' / w (within ``MAX_STEP_M`` of the stance foot and at least the standing width
   from it sideways; a landing too far gives up its sideways part first, down to the standing
   width, then its forward one). It travels from the first period on at a trapezoidal speed
   (:func:`~.capture_phases.travel`: the legs' speed limit bounds the foot's peak speed, which a
   trapezoid keeps near the mean) and lifts as sin(pi tau). The torso lowers over the swing as
   far as the legs need to reach both soles with the pelvis midway between them, each leg no
   longer hip to ankle than standing (the model's thigh, shin and hip offsets;
   :meth:`~CaptureStepper.reach_drop_m`).
   The step ends when the swing sole carries the robot file's ``estimation.swing_touchdown_n``
   (after ``TOUCH_FRACTION`` of the swing) or is down;
2. *catch*, ``CATCH_S``: both feet down, the ZMP on the landed sole's middle (= xi); the CoM
   comes to rest there, c(t) = xi + (c_T - xi) exp(-w t);
3. *return*: one walking step of :func:`~hubo_cli.walking.gait.make_gait` brings the other foot
   beside the landed one at the standing width (the stance, moved by the push); the CoM
   returns between the feet.

After a long step (more than ``LONG_STEP_M`` the push's way) the robot stays in the stepped
stance, a lunge (one step): both feet stay down for at least ``LUNGE_CATCH_S`` and then
until the estimated CoM is slower than ``SETTLED_SPEED_M_S`` (at most ``LUNGE_WAIT_S`` more:
the return, an open-loop walking step, must not start in mid-sway), the torso turns back
upright over ``UPRIGHT_S`` and the CoM comes to rest, c' = w (r - c), on a point r that
follows the measured capture point (time constant ``REST_TAU_S``) held on the line through
the soles' middles, from ``REST_BACK_FRACTION`` of the way from the back sole's middle to the
front one's up to ``CATCH_EDGE_M`` inside the front toe (both soles carry the robot: resting
over the back foot alone, it rocked sideways and tipped as the return began). Meanwhile the
torso lowers as far as the legs need to reach both soles from a pelvis over the pattern's CoM
(at most ``RETURN_MAX_DROP_M``, at ``CATCH_LOWER_M_S``) and the back heel rises for the rest
(after a backward push the stance foot is the front one: its toe rises;
:meth:`CaptureStepper._toe_off_pose`), so the stance foot stays on the floor. After a
backward push the landed foot went hip-width further out than the capture point
(:func:`~hubo_cli.walking.capture_phases.landing`) and the rest point and the pattern's CoM
stay where the legs can hold both soles: sideways in the band where each hip is inside its
ankle (:meth:`CaptureStepper.in_hip_band`; the hip roll joints only abduct), along the
stance no further than the stance leg reaches its flat sole with the torso lowered by
``RETURN_MAX_DROP_M``.
The pattern so follows where the landing (its impact took an unknown part of the momentum)
left the robot instead of driving it on toward its own capture point; the standing balancers
rest (acting in the lunge's long diagonal stance they rocked it sideways ever wider). Then
the return (:meth:`~hubo_cli.walking.capture_phases.Return.start`): one
walking step of :func:`~hubo_cli.walking.gait.make_gait` from the measured soles (its lead-in
from the lunge's CoM, a ``RETURN_SHIFT_S`` double support that moves the CoM over the front sole, a
swing whose smoothstep peaks at ``RETURN_FOOT_SPEED_M_S``, the settle between the feet)
brings the back foot beside the front one at the standing width: two steps in all. With the
CoM over the front sole the back foot is out of a flat leg's reach (the former quick swing-in
lagged its pattern under the legs' speed limit and tipped the robot), so the torso lowers
for the reach (at most ``RETURN_MAX_DROP_M``, rising again at most ``RETURN_RISE_M_S``) and
leans as when walking (``RETURN_LEAN_FRACTION`` of it: the front hip only abducts), and the
back heel rises about the toe as far as the leg needs (:meth:`CaptureStepper._toe_off_pose`,
at most ``MAX_TOE_OFF_RAD``; from the lunge's reach, its knee perhaps straight, to
standing's over ``RETURN_BEND_S``), on the ground and in the swing. The front sole complies
with its measured ground moment (the walking stabilizer's foot damping,
:class:`~hubo_cli.walking.stabilizer.SoleDamper`): without it the robot rocked sideways onto
the sole's outer edge over the shift and tipped toward the swing foot in the single support.

The pattern's joints come from :class:`~hubo_cli.walking.body.WalkingBody` (the legs' IK, the
neck placed so that the model's CoM follows the pattern), one period at a time. The phases
(stand, step, catch, return, stood: :mod:`hubo_cli.walking.capture_phases`, with the capture
step's pattern) are explicit states run by a :class:`~hubo_cli.control.phase.Phases` machine,
each planning when it starts; what the phase in force asks of the pipeline the stepper writes
to the store every period (:mod:`hubo_cli.control.phase`), never touching a module.
While it steps and catches, the capture-point monitor watches the planned support (the swing
foot at its landing place, as when walking; then the stepped stance, where the estimate has
the feet now) with no margin: the stepping is the answer to the capture point leaving the
shrunk polygon, and the stop is left for a capture point beyond the stepped stance itself.
Such a stop is not reverted (reverting a step does not keep the robot up): as a walk, the
stepper tells the soft stopper that it stops itself
(:data:`~hubo_cli.control.phase.PHASE_STOP`): the swing lands, the catch runs to its end in
the stepped stance and the robot stands there, held by the stopper (which brakes it where it
is if that takes longer than the phase said), its return step pending (a return step under
way stands once its foot is down). The stop is read each period from the stopper's mode
(:data:`~hubo_cli.control.keys.STOP_MODE`), never remembered past a release (released while
the phase still moves, the stopper passes it on at once): a catch that ends while the
stopper is latched or blending back stands with its return pending, which starts once the
stopper passes the target through again (:class:`~.capture_phases.Stood`). No step starts
while it is latched or blending back; a stop released while still standing (before any
step) leaves the stepper ready to step on a push, but a run steps once: after its return
(or a stop in it) the robot stands and a second push is the monitor's. The standing
balancers rest (:data:`~hubo_cli.control.phase.BALANCERS_REST`) while it steps, in every
catch (a short step's and the lunge's) and return step, after a lunge until the back foot
is down, and while the return is pending; afterwards the robot holds the pattern's last
posture, the balancers act and the monitor watches the estimated soles with its margin
again. At most two steps per push; one plan at a time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from hubo_cli.control.capture_point import CP_MARGIN_M
from hubo_cli.control.estop import LATCHED_MODES
from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.module import Module
from hubo_cli.control.phase import (
    BALANCERS_REST,
    PHASE_STOP,
    SUPPORT_PLAN,
    Phases,
    PhaseStop,
    SupportPlan,
)
from hubo_cli.control.target import Target, TargetOutput
from hubo_cli.dataflow import Store
from hubo_cli.errors import InputError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
    T_WORLD_TORSO,
    WRENCHES,
)
from hubo_cli.model import RobotModel
from hubo_cli.scene import SceneActions
from hubo_cli.state import RobotState
from hubo_cli.walking.body import SIDE_LEG, WalkingBody, pose_of_row
from hubo_cli.walking.capture_phases import Catch, Return, Stand, Step, Stood
from hubo_cli.walking.footsteps import SIDE_SIGN, Footstep
from hubo_cli.walking.gait import Gait, smoothstep5
from hubo_cli.walking.params import WalkingParams
from hubo_cli.walking.preview import CoMPath
from hubo_cli.walking.support import SIDES, ankle_wrenches, zmp_outside_m

REST_TAU_S = 0.1         # [chosen] the lunge's rest point follows the measured CP this fast
REST_BACK_FRACTION = 0.5  # [chosen] ... held no further back than this part of the way from
#                          the back sole's middle to the front one's (none: the CoM came to
#                          rest over the back foot, which carried it alone, the robot rocked
#                          sideways, 125 N fell and 130 N stopped; 0.4 to 0.6 caught both)
RETURN_RISE_M_S = 0.05   # [chosen] the torso rises at most this fast while it returns
RETURN_LEAN_FRACTION = 0.8  # [chosen] this much of the walking lean (all of it: 120 and
#                             160 N fell; 0.6: 140 N; none: 150 N)
RETURN_BEND_S = 1.0      # [chosen] the back knee bends from the lunge's reach over this long
RETURN_MAX_DROP_M = 0.11  # [chosen] the torso lowers at most this much while it returns ...
MAX_TOE_OFF_RAD = 0.8    # [chosen] ... and the back foot's heel rises at most this far
TOE_OFF_STEP_RAD = 0.025  # [chosen] the heel's rise is searched in steps of this
HIP_BAND_MARGIN_M = 0.005  # [chosen] the lunge's pelvis keeps each hip this far inside its ankle
CATCH_STOP_SPARE_S = 0.4  # [chosen] a capture stopping itself settles within its pattern and
#                           this: the phases end on period counts (the swing at the latest
#                           LAND_WAIT_S after its pattern, the lunge's catch after LUNGE_CATCH_S
#                           + LUNGE_WAIT_S), so this only covers the stepper seeing the latch a
#                           period late; the worst case, 4.6 s from the step's start, and this
#                           stay within the stopper's MAX_FINISH_S (tests/test_capture_step.py)
MAX_DROP_M = 0.08        # [chosen] the torso lowers at most this much for the legs' reach
CATCH_LOWER_M_S = 0.2    # [chosen] ... and in the lunge's catch at most this fast, down to
#                          RETURN_MAX_DROP_M, the back heel rising for the rest (with the
#                          back foot flat out of the leg's reach it lifted for 0.4-0.8 s and
#                          the robot balanced on the front foot alone)


class CaptureStepper(Target):
    """Stand with ``stand`` and catch a push by stepping (see the module docstring).

    Args:
        stand: the standing target (its posture and measurements; it keeps being called).
        model: the robot model (the ``walking`` limit set: a capture step needs the legs'
            walking speeds).
        params: walking parameters (the return step's timing; the standing width is
            measured).
        q_stand_rad: the standing posture (the pattern's IK starts from it).
    """

    def __init__(self, stand: Target, model: RobotModel, params: WalkingParams,
                 q_stand_rad: np.ndarray) -> None:
        self.stand = stand
        self.model = model
        self.params = params
        self.q_stand = np.asarray(q_stand_rad, dtype=float)
        self.log_columns = (*stand.log_columns, "capture.phase_code", "capture.com_ref_x_m",
                            "capture.com_ref_y_m")
        self.reads = tuple(dict.fromkeys((*stand.reads, *self.reads)))
        self.writes = tuple(dict.fromkeys((*stand.writes, *self.writes)))
        self.follows = tuple(dict.fromkeys((*stand.follows, *self.follows)))
        self.previous = tuple(dict.fromkeys((*stand.previous, *self.previous)))
        self.store: Store | None = None
        self.corners = np.ascontiguousarray(model.feet.sole_corners_m()[:, :3])
        self.phases = Phases([Stand(self), Step(self), Catch(self), Return(self), Stood(self)])
        self.q_standing = self.q_stand  # the standing target's posture this period
        self.body: WalkingBody | None = None
        self.rest: Gait | None = None  # the catch and the return step, planned at touch-down
        # (PatternPhase.follow) its support per period ((n, 2, 4, 4) world poses, right and
        # left: support.planned_support) and the inverse of the landed sole's planned pose
        self.rest_support: np.ndarray | None = None
        self.T_landed_plan_world: np.ndarray | None = None
        self.k = 0  # the pattern's period
        self.q_last: np.ndarray | None = None  # the pattern's last joints
        self.steps: list[Footstep] = []
        self.start_feet: list[Footstep] = []
        self.trigger_s: float | None = None
        self.track: dict | None = None  # the lunge's catch (Catch.start)
        self.lunge_return = False
        self.way = 1.0  # the lunge's landed foot ahead (1) or behind (-1; Catch)
        self.stood_s: float | None = None
        self.stood_feet: list[Footstep] = []
        self.stop_latched = False  # the soft stopper holds the robot (the last period's mode)
        self.stop_released = True  # ... passes the target through (not even blending back)
        self.latch_s: float | None = None  # when the stop latched last (kept after a release)
        self.stop_s: float | None = None  # the stop seen that ended the stepping in its stance
        self.return_pending = False  # a stop ended the catch: the return step still to come

    name = "capture-step"
    reads = (T_WORLD_SOLES, T_WORLD_TORSO, CONTACT, WRENCHES, COM_WORLD, COM_VELOCITY_WORLD,
             CAPTURE_POINT_WORLD)
    writes = (SUPPORT_PLAN, BALANCERS_REST, PHASE_STOP)
    previous = (STOP_MODE,)

    def attach(self, world: SceneActions | None, modules: Sequence[Module],
               store: Store) -> None:
        self.store = store
        self.stand.attach(world, modules, store)

    def outside_m(self) -> float:
        """How far the estimated capture point lies beyond the hull of the soles in contact
        shrunk by the capture-point monitor's margin (m; > 0 outside; -inf with no sole in
        contact: nothing to step from)."""
        store = self.store
        outside = zmp_outside_m(store[CAPTURE_POINT_WORLD], store[T_WORLD_SOLES], self.corners,
                                store[CONTACT])
        return outside + CP_MARGIN_M if math.isfinite(outside) else -math.inf

    @property
    def phase(self) -> str:
        """The phase in force (one of :data:`~hubo_cli.walking.capture_phases.PHASES`)."""
        return self.phases.current.name

    def __call__(self, t_s: float, state: RobotState) -> TargetOutput:
        self.q_standing, info = self.stand(t_s, state)
        # the stop as it stands now (never remembered past a release): latched, a catch ends
        # in its stance; not released (latched or blending back), no step starts
        mode = self.store.get(STOP_MODE, "release")
        if mode in LATCHED_MODES and not self.stop_latched:
            self.latch_s = t_s
        self.stop_latched, self.stop_released = mode in LATCHED_MODES, mode == "release"
        q, ref = self.phases(t_s, state)
        # what the phase in force asks of the pipeline: the balancers rest while the pattern
        # moves the CoM; the monitor watches the planned support, unshrunk, until the robot
        # stands; a stop latched while it steps lets it finish into its stance
        phase = self.phases.current
        self.store[BALANCERS_REST] = phase.balancers_rest()
        soles = phase.planned_soles()
        self.store[SUPPORT_PLAN] = None if soles is None else SupportPlan(soles, 0.0)
        within_s = phase.stop_within_s()
        self.store[PHASE_STOP] = None if within_s is None else PhaseStop(
            settled=within_s == 0.0, within_s=within_s + CATCH_STOP_SPARE_S)
        return q, info | {"capture.phase_code": self.phases.code,
                          "capture.com_ref_x_m": ref[0], "capture.com_ref_y_m": ref[1]}

    # ------------------------------------------------------------------ the pattern's period
    def in_stance(self, point_m: np.ndarray) -> np.ndarray:
        """``point_m`` projected on the line through the lunge's soles' middles, from
        REST_BACK_FRACTION of the way from the back one to the front one up to ``reach``
        ahead of the front one; in a backward lunge no further than the stance leg reaches
        and sideways within :meth:`in_hip_band`."""
        tr = self.track
        axis = tr["front"] - tr["back"]
        length = float(np.hypot(*axis))
        axis = axis / length
        along = float((np.asarray(point_m, dtype=float) - tr["back"]) @ axis)
        along = min(max(along, REST_BACK_FRACTION * length), length + tr["reach"])
        if tr["ankles"] is not None:  # a backward lunge: the pelvis where the legs reach
            # no further than the stance leg reaches its flat sole from a pelvis over it
            # (its knee bent as standing, the torso lowered by RETURN_MAX_DROP_M)
            h = self.hip_height_m
            stance_reach_m = math.sqrt(h * h - (h - RETURN_MAX_DROP_M) ** 2)
            reachable = ((stance_reach_m + self.model.feet.forward_m)
                         / max(abs(float(axis @ self.heading)), 1e-6))
            along = max(min(along, reachable), REST_BACK_FRACTION * length)
        return self.in_hip_band(tr["back"] + along * axis)

    def in_hip_band(self, point_m: np.ndarray) -> np.ndarray:
        """``point_m`` moved sideways (across the heading) into the band where the pelvis
        over it keeps each hip no further out than its foot's ankle (less HIP_BAND_MARGIN_M):
        the hip roll joints only abduct, a leg cannot bring its foot in under a hip beyond
        it (Table IV). Only in a backward lunge (``track["ankles"]``); otherwise as it is."""
        tr = self.track
        if tr["ankles"] is None:
            return np.asarray(point_m, dtype=float)
        normal = np.array([-self.heading[1], self.heading[0]])  # to the left
        hip_m = self.model.lengths_m["lL1"]
        right = float(tr["ankles"]["right"] @ normal) + hip_m + HIP_BAND_MARGIN_M
        left = float(tr["ankles"]["left"] @ normal) - hip_m - HIP_BAND_MARGIN_M
        point = np.asarray(point_m, dtype=float)
        across = float(point @ normal)
        lo, hi = (right, left) if right <= left else ((right + left) / 2,) * 2
        return point + (min(max(across, lo), hi) - across) * normal

    def _lunge_com(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The lunge's CoM for this period (rows (1, 2): position, velocity, acceleration)
        and ZMP (2,): the rest point r follows the measured capture point held in the stance
        (time constant REST_TAU_S), the CoM converges on it as the pendulum's stable part,
        c' = w (r - c)."""
        tr, period, omega = self.track, self.model.control_period_s, self.omega
        target = self.in_stance(self.store[CAPTURE_POINT_WORLD][:2])
        tr["rest"] = tr["rest"] + min(period / REST_TAU_S, 1.0) * (target - tr["rest"])
        v = omega * (tr["rest"] - tr["com"])
        tr["com"] = self.in_hip_band(tr["com"] + v * period)
        return (tr["com"].reshape(1, 2), v.reshape(1, 2), (-omega * v).reshape(1, 2),
                tr["rest"].copy())

    def pattern_period(self) -> tuple[np.ndarray, tuple[float, float]]:
        """One period of the catch or the return step (the planned pattern): the joints and
        the CoM reference; over the catch the torso turns from its tilt at touch-down back
        upright (both soles stay flat)."""
        rest, k = self.rest, self.k
        feet = {side: rows[k] for side, rows in rest.feet.items()}
        if self.track is None and self.lunge_return:
            self._return_drop(k, rest.com.com_m[k], feet)
        if self.track is not None:
            c, v, a, zmp = self._lunge_com()
            self._catch_drop(c[0], feet)
        else:
            c, v, a = (rest.com.com_m[k:k + 1], rest.com.com_velocity_m_s[k:k + 1],
                       rest.com.com_acceleration_m_s2[k:k + 1])
            zmp = rest.zmp_ref_m[k]
        # the lunge (its catch and return): the back leg's ankle where the raised heel puts it
        back_reaches = self.lunge_return or self.track is not None
        if back_reaches:
            rear = feet[self.stance_side]
            T_world_foot = self._toe_off_pose(c[0], rear)
            feet = feet | {self.stance_side: np.append(
                T_world_foot[:3, 3] + (T_world_foot[:3, 2] - [0.0, 0.0, 1.0])
                * self.model.lengths_m["lL5"], rear[3])}
        q = self.solve_period(c, v, a, zmp, feet, rest.support[k:k + 1])
        if back_reaches and self.toe_off_rad > 0.0:
            q = self._solve_leg(q, self.stance_side, T_world_foot)
        if self.lunge_return:  # from the lunge's last joints (a capped leg's solution may
            # differ): their difference fades over the pattern's lead-in
            if k == 0:
                self.q_jump = self.q_last - q
            q = q + (1.0 - self._lead_in(k)) * self.q_jump
            # the front sole complies with its ground moment (the walking stabilizer's foot
            # damping): it stays flat instead of rocking onto an edge
            delta = self.damper.update(ankle_wrenches(self.store)[SIDES.index(self.swing)])
            leg = "R" if self.swing == "right" else "L"
            names = list(self.model.joint_names)
            q[names.index(leg + "AR")] += delta[0]
            q[names.index(leg + "AP")] += delta[1]
        b = float(smoothstep5(min((k + 1) / self.n_upright, 1.0)))
        if b < 1.0:
            T = self.body_neck.copy()
            T[:3, :3] = (Rotation.from_matrix(self.R_touch_down)
                         * Rotation.from_rotvec(b * (Rotation.from_matrix(self.R_touch_down).inv()
                                                     * Rotation.from_matrix(T[:3, :3])
                                                     ).as_rotvec())).as_matrix()
            T_neck_world = np.linalg.inv(T)
            q = q.copy()
            for side, row in feet.items():
                part = self.model.limb_slice(SIDE_LEG[side])
                result = self.legs[side].solve(T_neck_world @ pose_of_row(row), q[part])
                if result.status in ("exact", "capped"):
                    q[part] = result.q_rad
        self.q_last = q
        self.k += 1
        return q, (float(c[0, 0]), float(c[0, 1]))

    def _return_drop(self, k: int, com_m: np.ndarray, feet: dict) -> None:
        """The torso's height and lean in period ``k`` of the return: low enough for each leg
        to reach its sole flat from a pelvis over the pattern's CoM, no longer hip to ankle
        than standing (at most RETURN_MAX_DROP_M; the back heel's rise does the rest), rising
        at most RETURN_RISE_M_S; RETURN_LEAN_FRACTION of the walking lean (the front hip
        only abducts: without it the robot fell). Over the
        pattern's lead-in both blend in from the lunge's."""
        b = self._lead_in(k)
        drop = self.drop_m + b * (self._reach_need_m(com_m, feet) - self.drop_m)
        # the torso rises slowly (a quick rise on one leg hops the robot)
        drop = max(drop, self.neck_z0_m - self.body.neck_z_m
                   - RETURN_RISE_M_S * self.model.control_period_s)
        self.body.lean_rad_per_m = b * RETURN_LEAN_FRACTION * self.params.lean_rad_per_m
        self.body.neck_z_m = self.neck_z0_m - drop

    def _reach_need_m(self, com_m: np.ndarray, feet: dict) -> float:
        """How much lower than standing the torso must be for each leg to reach its sole
        flat from a pelvis over ``com_m``, no longer hip to ankle than standing: at most
        RETURN_MAX_DROP_M."""
        hip_m = self.model.lengths_m["lL1"]
        normal = np.array([-self.heading[1], self.heading[0]])
        need = 0.0
        h = self.hip_height_m
        for side, row in feet.items():
            hip = np.asarray(com_m, dtype=float) + SIDE_SIGN[side] * hip_m * normal
            r = float(np.hypot(*(row[:2] - hip)))
            need = max(need, h - math.sqrt(max(h * h - r * r, 0.0)))
        return min(need, RETURN_MAX_DROP_M)

    def _catch_drop(self, com_m: np.ndarray, feet: dict) -> None:
        """The torso's height in a period of the lunge's catch: as low as the legs need
        (:meth:`_reach_need_m`), lowering at most CATCH_LOWER_M_S and rising at most
        RETURN_RISE_M_S (the back heel's rise does the rest, :meth:`_toe_off_pose`)."""
        period = self.model.control_period_s
        now = self.neck_z0_m - self.body.neck_z_m
        drop = min(max(self._reach_need_m(com_m, feet), now - RETURN_RISE_M_S * period),
                   now + CATCH_LOWER_M_S * period)
        self.body.neck_z_m = self.neck_z0_m - drop

    def _lead_in(self, k: int) -> float:
        """0 -> 1 over the return pattern's lead-in (``start_s``; smoothstep)."""
        return float(smoothstep5((k + 1) / max(1, round(self.params.start_s
                                                        / self.model.control_period_s))))

    def _toe_off_pose(self, com_m: np.ndarray, row: np.ndarray) -> np.ndarray:
        """T_world_foot of the stance foot of the capture step (on the ground or swinging)
        turned about its sole's edge facing the landed foot as far as the leg needs to reach
        it from the hip where the last period's neck had it: after a forward push it is the
        back foot and its heel rises about the toe; after a backward one it is the front foot
        and its toe rises about the heel (raised about its toe as a back foot's heel, the
        front foot's ankle went further from the hip, its knee straight, and the foot stood on
        its toe, 0.77 rad, leaving the robot on the landed foot alone). Hip to ankle no
        longer than standing (from the lunge's reach, its knee perhaps straight, over
        RETURN_BEND_S); at most MAX_TOE_OFF_RAD. Sets
        ``toe_off_rad`` (the turn's size)."""
        L, feet = self.model.lengths_m, self.model.feet
        side = self.stance_side
        # the hip where the last period's neck had it (its height this period's)
        T = self.body_neck
        hip = T[:3, :3] @ np.array([0.0, SIDE_SIGN[side] * L["lL1"], -L["lT"] - L["lL2"]])
        hip = hip + np.append(T[:2, 3], self.body.neck_z_m)
        way = self.way  # 1: the landed foot ahead (toe, heel up); -1: behind (heel, toe up)
        edge_m = feet.forward_m + way * feet.length_m / 2
        T_world_sole = pose_of_row(row)
        angles = np.arange(0.0, MAX_TOE_OFF_RAD + 1e-9, TOE_OFF_STEP_RAD)
        turns = way * angles  # about the sole's y axis (> 0: heel up)
        ankle = np.stack([edge_m - edge_m * np.cos(turns) + L["lL5"] * np.sin(turns),
                          np.zeros_like(angles),
                          edge_m * np.sin(turns) + L["lL5"] * np.cos(turns)], axis=1)
        ankle_world = ankle @ T_world_sole[:3, :3].T + T_world_sole[:3, 3]
        reach = np.linalg.norm(ankle_world - hip, axis=1)
        if self.reach_m is None:  # the lunge's own reach (its back knee may be straight)
            self.reach_m = max(self.hip_height_m, float(reach[0]))
        # from it the allowed reach shrinks to standing's over RETURN_BEND_S: the knee bends
        b = float(smoothstep5(self.k * self.model.control_period_s / RETURN_BEND_S))
        allowed = self.reach_m + b * (self.hip_height_m - self.reach_m)
        # the least rise that fits, between the samples
        fits = np.nonzero(reach <= allowed)[0]
        i = int(fits[0]) if len(fits) else len(angles) - 1
        angle = float(angles[i])
        if 0 < i < len(angles) and len(fits):
            angle -= TOE_OFF_STEP_RAD * (allowed - reach[i]) / (reach[i - 1] - reach[i])
        self.toe_off_rad = angle
        pivot = np.eye(4)
        pivot[0, 3] = edge_m
        turn = np.eye(4)
        turn[:3, :3] = Rotation.from_rotvec([0.0, way * angle, 0.0]).as_matrix()
        return T_world_sole @ pivot @ turn @ np.linalg.inv(pivot)

    def _solve_leg(self, q: np.ndarray, side: str, T_world_foot: np.ndarray) -> np.ndarray:
        """``q`` with the leg ``side`` re-solved for the sole pose ``T_world_foot`` (the
        body's neck this period)."""
        part = self.model.limb_slice(SIDE_LEG[side])
        result = self.legs[side].solve(np.linalg.inv(self.body_neck) @ T_world_foot, q[part])
        if result.status in ("exact", "capped"):
            q = q.copy()
            q[part] = result.q_rad
            self.body.q_start = q
        return q

    def reach_drop_m(self, stance: Footstep, land: Footstep) -> float:
        """How much lower the torso must stand for each leg, with the pelvis midway between
        the soles, to be no longer hip to ankle than standing (its knee keeps the standing
        bend; the hips ``lL1`` either side of the pelvis, the model's lengths): at most
        MAX_DROP_M."""
        hip_m = self.model.lengths_m["lL1"]
        ankles = np.array([[stance.x_m, stance.y_m], [land.x_m, land.y_m]])
        middle = ankles.mean(axis=0)
        normal = np.array([-self.heading[1], self.heading[0]])
        hips = middle + np.sign((ankles - middle) @ normal)[:, None] * hip_m * normal
        r = float(np.max(np.hypot(*(ankles - hips).T)))
        h = self.hip_height_m
        return min(h - math.sqrt(max(h * h - r * r, 0.0)), MAX_DROP_M)

    def solve_period(self, c, v, a, zmp, feet: dict, support: np.ndarray) -> np.ndarray:
        """The body's IK for one period of pattern (CoM rows (1, 2), feet rows (4,))."""
        period = self.model.control_period_s
        zmp = np.asarray(zmp, dtype=float).reshape(1, 2)
        one = Gait(period, (), self.height_m, zmp, CoMPath(c, v, a, zmp),
                   {side: np.asarray(row, dtype=float).reshape(1, 4)
                    for side, row in feet.items()}, support, np.zeros(1, dtype=int))
        try:
            plan = self.body.solve(one)
        except InputError:  # a sole out of the legs' reach: keep the last joints
            return self.body.q_start
        q, self.body_neck = plan.q_rad[0], plan.T_world_neck[0]
        self.body.q_start = q
        return q

    def summary(self) -> dict:
        """What the stepping did, for the run's summary (``capture_step``): the footsteps
        taken (a return step's once it started), when the pattern stood and where the soles
        stood then, and ``stop_s``: when the stepper saw the stop that ended the stepping in
        its stance (the period after the stopper latched it: the stopper's mode is read from
        the previous period), the catch with its return step pending or the return step once
        its foot was down (None: none, or the return followed the release)."""
        return {"stepped": self.trigger_s is not None, "trigger_s": self.trigger_s,
                "steps": len(self.steps) if self.trigger_s is not None else 0,
                "start_feet": [f.to_json() for f in self.start_feet],
                "stood_s": self.stood_s, "stop_s": self.stop_s,
                "stood_feet": [f.to_json() for f in self.stood_feet],
                "footsteps": [f.to_json() for f in self.steps]}
