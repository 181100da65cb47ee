"""The task's target source: plays a checked :class:`~hubo_cli.tasks.plan.Plan` in the loop.

Phases (explicit states, :mod:`hubo_cli.tasks.phases`, run one at a time by a
:class:`~hubo_cli.control.phase.Phases` machine):

1. ``raise``: the joint-space move of the first step (joint target ``plan.q_first_rad``), then
   a wait until the robot is still with the tool on its first pose (within
   ``ON_POSE_M``, as the robot measures it); the wall is placed then, ahead of the tool as the
   robot holds it (in a simulator; a real robot stands at its wall);
2. ``run``: the plan's joint targets period by period;
3. ``settle``: the plan has ended; wait until the robot is still;
4. ``stopped``: an emergency stop latched; the plan is frozen where it was. Without an
   operator at a keyboard the run ends once the stopper holds and the robot is still (the
   operator can look at the scene, then start again). With one (``resumable``) it holds until
   the operator finishes the run (q) or releases the stop (r): once the stopper has blended
   back to the frozen plan, the plan goes on from where it froze, as hrpsys's sequence player
   resumes after an emergency. A stop on the wrist torque brakes, then backs the tool out of
   the wall along its normal (:meth:`TaskTarget.relieve`, written as the store's
   WRIST_RELIEF for the stopper). The target knows of the stopper only its mode, the store's
   STOP_MODE of the previous period.

Each period the measured torso pose (the estimate's, the store's T_WORLD_TORSO in S;
:mod:`hubo_cli.kinematics.torso`) corrects the arm's joint target: the
plan's tool goal, given in S (the wall's frame), is solved in the measured neck frame,
low-passed and bounded, so the body's residual sway moves the arm and not the hole. The
correction runs from the first period on (``correction=False`` turns it
off), so the wall is placed in front of a tool that already holds its place.

Each period it measures the tool as the robot does (FK of the measured arm, through the
measured torso pose in the stance frame S); while the plan cuts it keeps the commanded and
measured tool positions, the wrist torque and the edge they belong to, with the times, and
it notes when the wall was placed: the task's report (:mod:`hubo_cli.tasks.runner`) traces
the hole as it was cut from the log's true world poses at those times. The target itself
never reads the simulator's truth.

A plan with a thrust (:attr:`Plan.has_force`) runs under force control: every period the target
writes the plan's hand force, turned into the measured neck frame, as the hand wrench
reference (:data:`~hubo_cli.control.wrench.HAND_WRENCH_PLAN`; the emergency stopper reverts it,
the ImpedanceController presses with it, switched on through the store's IMPEDANCE_ON once the
plan runs), logs it with the measured thrust, and lets the
waist lean into the force the hand really meets: a
:class:`~hubo_cli.control.reference_force.ReferenceForceUpdater` follows the measured force
along the bit, and the legs take the plan's CoM shift moved by eq. 6's slope
(:attr:`Placement.shift_per_force_m_n`) times its difference from the plan's force.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hubo_cli.control.estop import wrist_torque_nm
from hubo_cli.control.keys import IMPEDANCE_ON, STOP_MODE, WRIST_RELIEF
from hubo_cli.control.module import Module
from hubo_cli.control.phase import Phases
from hubo_cli.control.reference_force import ReferenceForceUpdater
from hubo_cli.control.target import Target
from hubo_cli.control.wrench import (
    ALONG_MIN,
    HAND_WRENCH_PLAN,
    force_at_point,
    measured_hand_wrench,
    tool_point_S_m,
)
from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import T_WORLD_SOLES, T_WORLD_TORSO, WRENCHES
from hubo_cli.kinematics.limb import Limb
from hubo_cli.kinematics.torso import MeasuredTorso, TorsoCorrection
from hubo_cli.kinematics.wholebody import MAX_SHIFT_M
from hubo_cli.scene import SceneActions, WallPlacement, WallSize
from hubo_cli.state import T_frame_sensor
from hubo_cli.tasks.phases import Raise, Run, Settle, Stopped
from hubo_cli.tasks.plan import EDGE_NONE, Plan
from hubo_cli.urdf import tool_frame

ON_POSE_M = 0.0005  # the raise ends with the tool this close to its first pose
RETREAT_M = 0.005  # a wrist-torque stop backs the tool this far out of the wall (its normal)
RETREAT_ALONG_M = 0.0005  # ... moving it at most this far along the wall on the way
RETREAT_STEPS = 8  # postures of that path


class TaskTarget(Target):
    """Plays a checked plan in the control loop.

    Args:
        plan: the checked plan (its whole-body solver gives the measured tool pose).
        correction: correct the arm's goal by the measured torso pose (see the module
            docstring); False plays the plan's joint targets as they are.
        resumable: an operator at a keyboard can release a stop and resume the plan; without
            one a stop ends the run once held.

    After :meth:`attach`: ``scene`` is what was placed in the simulator.
    """

    reads = (T_WORLD_TORSO, T_WORLD_SOLES, WRENCHES)
    writes = (WRIST_RELIEF,)
    previous = (STOP_MODE,)
    log_columns = ("step_code", "phase_code", "goal_x_m", "goal_y_m", "goal_z_m", "actual_x_m",
                   "actual_y_m", "actual_z_m", "error_m", "cutting", "edge_code",
                   "task_wrist_torque_nm", "thrust_n")
    force_columns = ("thrust_ref_n", "balance_thrust_n", "waist_shift_m")

    def __init__(self, plan: Plan, correction: bool = True, resumable: bool = False) -> None:
        self.plan = plan
        self.resumable = resumable
        self.body = body = plan.body
        self.world: SceneActions | None = None
        self.scene: dict = {}
        self.limb = plan.spec.stance.limb
        self.slice = body.model.limb_slice(self.limb)
        self.sensor = "right-wrist" if self.limb == "right-arm" else "left-wrist"
        self.phases = Phases([Raise(self), Run(self), Settle(self), Stopped(self)])
        self.stop_mode = "release"  # the stopper's, after the previous period (STOP_MODE)
        self.q_target = plan.q_first_rad.copy()  # the plan's joint target
        self.q_out = self.q_target.copy()           # ... corrected by the torso pose
        self.torso = MeasuredTorso(body)  # the estimate's torso pose, in S
        self.correction = (TorsoCorrection(body, (self.limb,), plan.dt_s)
                           if correction else None)
        self.k = 0                       # the plan row being commanded
        self.t_run_s: float | None = None
        self.t_stop_s: float | None = None
        self.t_held_s: float | None = None  # ... with the robot still (joints < 0.05 rad/s)
        self.retreat_m: float | None = None  # how far a wrist-torque stop backed the tool out
        self.step_stopped: int | None = None
        self._phase_before_stop = "raise"  # the phase a released stop resumes
        self.resumed_t_s: list[float] = []  # when the plan went on after a released stop
        self.t_placed_s: float | None = None  # when the wall was placed (the cut's origin)
        # while cutting: commanded and measured tool positions (S, m), wrist torque (N m), edge
        self.cut_goal_m: list[np.ndarray] = []
        self.cut_actual_m: list[np.ndarray] = []
        self.cut_torque_nm: list[float] = []
        self.cut_edge: list[int] = []
        self.cut_t_s: list[float] = []
        self.torque_nm = 0.0
        self.error_m = float("nan")
        self.T_S_N: np.ndarray | None = None  # the torso pose last measured (S, m)
        # force control (a plan with a thrust): the hand frame's arm, the balance's force
        self.force = plan.has_force
        self.cut_thrust_n: list[float] = []
        self.cut_thrust_ref_n: list[float] = []
        self.thrust_n = 0.0
        self.hand = Limb(body.model, self.limb, "hand")  # the wrist sensor's on it
        self.R_hand_sensor = T_frame_sensor(self.sensor)[:3, :3]
        self.bit_S = np.array([1.0, 0.0, 0.0])  # the bit's axis: S's x, into the wall
        # where the tool's force acts, in the sensor frame: its moments carry the force across
        # the forearm (Hubo's sensor has one force axis, 45 deg off the bit)
        self.tool_point_S_m = tool_point_S_m(body.model, body.tools[self.limb],
                                             T_frame_sensor(self.sensor))
        if self.force:
            self.writes = self.writes + (HAND_WRENCH_PLAN, IMPEDANCE_ON)
            self.log_columns = self.log_columns + self.force_columns
            self.rfu = ReferenceForceUpdater((1.0, 0.0, 0.0), plan.dt_s)

    def attach(self, world: SceneActions | None, modules: Sequence[Module],
               store: Store) -> None:
        self.world, self.store = world, store

    def relieve(self, q_rad: np.ndarray) -> np.ndarray | None:
        """The path that relieves the wrist after a wrist-torque stop braked the command
        ``q_rad`` (rad, every joint): the tool backed RETREAT_M straight out of the wall along
        its normal (S's -x), its orientation and the other joints kept, as RETREAT_STEPS
        postures (the stopper moves in straight joint-space lines between them). None (hold
        where braked) when the arm cannot reach one exactly, or when the path, checked halfway
        between the postures too, would take the tool into the wall or more than
        RETREAT_ALONG_M along it."""
        if self.T_S_N is None:
            return None
        arm, T_S_N = self.body.arms[self.limb], self.T_S_N
        q_arm = np.asarray(q_rad, dtype=float)[self.slice]
        T_N_E = arm.fk(q_arm)
        out_N = -T_S_N[0, :3]  # S's -x in N: minus the first row of R_S_N
        path = [q_arm]
        for f in np.arange(1, RETREAT_STEPS + 1) / RETREAT_STEPS:
            goal = T_N_E.copy()
            goal[:3, 3] += f * RETREAT_M * out_N
            result = arm.solve(goal, path[-1])
            if not result.exact:
                return None
            path.append(result.q_rad)
        path = np.array(path)
        checked = np.vstack([path, 0.5 * (path[1:] + path[:-1])])
        moved = T_S_N[:3, :3] @ (arm.fk_batch(checked)[:, :3, 3] - T_N_E[:3, 3]).T
        if moved[0].max() > 1e-4 or np.hypot(moved[1], moved[2]).max() > RETREAT_ALONG_M:
            return None
        out = np.repeat(np.asarray(q_rad, dtype=float)[None, :], RETREAT_STEPS, axis=0)
        out[:, self.slice] = path[1:]
        self.retreat_m = RETREAT_M
        return out

    def place_wall(self) -> None:
        """The wall at the task's distance from the tool as the robot now holds it (the
        standing robot leans a little under the balancer; an operator walks it up to the wall
        as it stands), moved by the scene's ``wall_misplaced_m`` (a wall the plan misjudged)."""
        if self.world is None:
            return
        spec, placement = self.plan.spec, self.plan.placement
        scene = spec.scene
        self.scene = WallPlacement(
            tool_frame(spec.stance.limb, spec.stance.tool),
            placement.wall_distance_m - self.plan.T_first_S[0, 3] + scene.wall_misplaced_m,
            WallSize(scene.wall_height_m, scene.wall_width_m, scene.wall_thickness_m),
        ).place(self.world)

    # ------------------------------------------------------------------ progress (live view)
    @property
    def phase(self) -> str:
        """The phase in force (one of :data:`~hubo_cli.tasks.phases.PHASES`)."""
        return self.phases.current.name

    @property
    def step(self) -> int:
        """Index of the step in progress."""
        if self.phase == "raise":
            return 0
        return int(self.plan.step_index[min(self.k, len(self.plan.t_s) - 1)])

    def step_fraction(self, index: int) -> float:
        """How much of step ``index`` is done (0..1)."""
        if self.phase == "raise":
            return 0.0
        if index == 0:
            return 1.0
        start, end = self.plan.step_times_s[index]
        t = self.plan.t_s[min(self.k, len(self.plan.t_s) - 1)]
        if self.phase == "settle":
            return 1.0
        if end <= start:
            return 1.0 if t >= end else 0.0
        return float(np.clip((t - start) / (end - start), 0.0, 1.0))

    # ------------------------------------------------------------------ the loop's call
    def still(self, state, tolerance_rad: float = 0.01) -> bool:
        """The robot is at the last output (within ``tolerance_rad``) and still."""
        return bool(np.max(np.abs(state.q_rad - self.q_out)) < tolerance_rad
                    and np.max(np.abs(state.dq_rad_s)) < 0.05)

    def __call__(self, t_s: float, state) -> tuple[np.ndarray, dict]:
        info: dict = {}
        self.stop_mode = mode = self.store.get(STOP_MODE, "release")
        self.store[WRIST_RELIEF] = self.relieve
        stopped = mode != "release"
        if stopped and self.phase != "stopped":  # latched: the plan freezes where it is
            self._phase_before_stop = self.phase
            self.phases.go("stopped", t_s, state)
        elif not stopped and self.phase == "stopped":  # released and blended back: go on
            self.phases.go(self._phase_before_stop, t_s, state)
        if self.phases(t_s, state):
            info["done"] = True
        q_target = self._leaning(self.q_target, info) if self.force else self.q_target
        self.q_out = (q_target if self.correction is None
                      else self.correction(q_target, self._T_S_N()))
        self._measure(t_s, state, info)
        return self.q_out, info

    def _plan_force_S_n(self) -> np.ndarray:
        """The plan's hand force (N, in S) this period: zero until the plan runs."""
        return self.plan.hand_force_S_n(self.k) if self.phase != "raise" else np.zeros(3)

    def _leaning(self, q_rad: np.ndarray, info: dict) -> np.ndarray:
        """Force control: write the plan's hand force as the wrench reference (in the neck
        frame last measured) and return ``q_rad`` with the legs leaning into the force the
        hand meets (eq. 6 with the ReferenceForceUpdater's force instead of the plan's)."""
        force_S = self._plan_force_S_n()
        R_N_S = np.eye(3) if self.T_S_N is None else self.T_S_N[:3, :3].T
        if self.store is not None:
            self.store[HAND_WRENCH_PLAN] = {self.limb: np.concatenate([R_N_S @ force_S,
                                                                       np.zeros(3)])}
            self.store[IMPEDANCE_ON] = self.t_run_s is not None  # force control from the run on
        placement = self.plan.placement
        lean_m = placement.shift_per_force_m_n * (self.rfu.reference_n - force_S[0])
        info["balance_thrust_n"] = -self.rfu.reference_n
        info["waist_shift_m"] = placement.shift_m + lean_m
        if abs(lean_m) < 1e-6:
            return q_rad
        body = self.body
        goal = self.plan.T_first_S.copy()
        if self.phase != "raise":
            goal[:3, 3] = self.plan.goal_S_m[self.k]
        shift = min(max(placement.shift_m + lean_m, -MAX_SHIFT_M), MAX_SHIFT_M)
        solved = body.solve({self.limb: goal}, q_rad, lift_m=body.lift_of(q_rad), shift_m=shift)
        return solved.q_rad if solved.arms[self.limb].exact else q_rad

    def on_first_pose(self, state) -> bool:
        """The tool, as the robot measures it, is within ON_POSE_M of the plan's first pose
        (the torso correction may still be bringing it there when the joints look still);
        without the correction nothing would bring it closer than the joints."""
        if self.correction is None:
            return True
        T_N_E = self.body.arms[self.limb].fk(state.q_rad[self.slice])
        tool = (self._T_S_N() @ T_N_E)[:3, 3]
        return bool(np.linalg.norm(tool - self.plan.T_first_S[:3, 3]) < ON_POSE_M)

    def _T_S_N(self) -> np.ndarray:
        """The measured neck frame in S (4x4, m): the estimate's torso pose."""
        return self.torso(self.store[T_WORLD_TORSO], self.store[T_WORLD_SOLES])

    def _measure(self, t_s: float, state, info: dict) -> None:
        # through the measured torso pose: the legs' lift and the waist's CoM shift included
        T_N_E = self.body.arms[self.limb].fk(state.q_rad[self.slice])
        self.T_S_N = self._T_S_N()
        actual = (self.T_S_N @ T_N_E)[:3, 3]
        self.torque_nm = wrist_torque_nm(self.store[WRENCHES].get(self.sensor))
        self._measure_force(state, info)
        running = self.phase != "raise"
        k = self.k
        goal = self.plan.goal_S_m[k] if running else actual
        cutting = self.phase == "run" and bool(self.plan.cutting[k])
        d = goal - actual
        self.error_m = math.sqrt(d.dot(d))  # np.linalg.norm's arithmetic, without its checks
        info.update({"step_code": float(self.step), "phase_code": self.phases.code,
                     "goal_x_m": goal[0], "goal_y_m": goal[1], "goal_z_m": goal[2],
                     "actual_x_m": actual[0], "actual_y_m": actual[1], "actual_z_m": actual[2],
                     "error_m": self.error_m, "cutting": float(cutting),
                     "edge_code": float(self.plan.edge[k] if cutting else EDGE_NONE),
                     "task_wrist_torque_nm": self.torque_nm})
        if cutting:
            self.cut_thrust_n.append(self.thrust_n)
            self.cut_thrust_ref_n.append(float(self.plan.thrust_n[k]))
            self.cut_goal_m.append(goal.copy())
            self.cut_actual_m.append(actual)
            self.cut_torque_nm.append(self.torque_nm)
            self.cut_edge.append(int(self.plan.edge[k]))
            self.cut_t_s.append(t_s)

    def _measure_force(self, state, info: dict) -> None:
        """The thrust the tool presses into the wall with (N, along S's x: minus the force
        on the tool, :func:`force_at_point` at the tool's point, through the measured hand
        pose and torso; NaN without a wrist sensor); under force control also the plan's and
        the ReferenceForceUpdater's update."""
        wrench = measured_hand_wrench(state, self.store, self.sensor)
        along = math.nan
        if wrench is not None:
            R_S_sensor = (self.T_S_N[:3, :3] @ self.hand.fk(state.q_rad[self.slice])[:3, :3]
                          @ self.R_hand_sensor)
            along = float(R_S_sensor @ force_at_point(wrench, self.tool_point_S_m)
                          @ self.bit_S)
            axis = float(R_S_sensor[:, 2] @ self.bit_S)  # the forearm's along the bit
            if math.isnan(along) and axis * axis >= ALONG_MIN:
                # a point on the sensor (the hand): its moments cannot place the force, so
                # f_z alone, taken to lie along the bit (as the hand's force tracking takes it)
                along = float(wrench[2]) / axis
        force_S = along * self.bit_S
        self.thrust_n = -along
        info["thrust_n"] = self.thrust_n
        if self.force:
            self.rfu.update(force_S)
            info["thrust_ref_n"] = -float(self._plan_force_S_n()[0])
