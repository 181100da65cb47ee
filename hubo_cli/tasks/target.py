"""The task's target source: plays a checked :class:`~hubo_cli.tasks.plan.Plan` in the loop.

Phases:

1. ``raise``: the joint-space move of the first step (joint target ``plan.q_first_rad``), then
   a wait until the robot is still; the wall is placed then, ahead of the tool as the robot
   holds it (in a simulator; a real robot stands at its wall);
2. ``run``: the plan's joint targets period by period;
3. ``settle``: the plan has ended; wait until the robot is still;
4. ``stopped``: an emergency stop latched; the plan is frozen where it was and the run ends
   once the stopper holds and the robot is still (the operator can look at the scene, then
   start again).

Each period it measures the tool as the robot does (FK of the measured arm and legs, in the
stance frame S) and, where the driver knows the torso's pose, in the world; while the plan cuts
it keeps the commanded and measured tool positions and the wrist torque, with the edge they
belong to. The world positions are taken relative to where the tool stood when the wall was
placed, so they trace the hole as it is cut into the wall (the body's sway and any change of
its lean included).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hubo_cli.control.estop import EmergencyStopper, wrist_torque_nm
from hubo_cli.control.module import Module
from hubo_cli.control.target import Target
from hubo_cli.drivers.base import SimulatedWorld
from hubo_cli.scene import WallPlacement, WallSize
from hubo_cli.tasks.plan import EDGE_NONE, Plan
from hubo_cli.urdf import tool_frame

PHASES = ("raise", "run", "settle", "stopped")
SETTLE_TIMEOUT_S = 6.0
STOP_HOLD_S = 1.0  # after a stop, keep holding this long (still) before ending the run


class TaskTarget(Target):
    """Plays a checked plan in the control loop.

    Args:
        plan: the checked plan (its whole-body solver gives the measured tool pose).

    After :meth:`attach`: ``stopper`` is the pipeline's soft emergency stopper (None when the
    run has none) and ``scene`` what was placed in the simulator.
    """

    log_columns = ("step_code", "phase_code", "goal_x_m", "goal_y_m", "goal_z_m", "actual_x_m",
                   "actual_y_m", "actual_z_m", "error_m", "cutting", "edge_code",
                   "task_wrist_torque_nm")

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        self.body = body = plan.body
        self.stopper: EmergencyStopper | None = None
        self.world: SimulatedWorld | None = None
        self.modules: list = []  # set by attach()
        self.scene: dict = {}
        self.limb = plan.spec.stance.limb
        self.slice = body.model.limb_slice(self.limb)
        self.sensor = "right-wrist" if self.limb == "right-arm" else "left-wrist"
        self.phase = "raise"
        self.q_target = plan.q_first_rad.copy()
        self.k = 0                       # the plan row being commanded
        self.t_run_s: float | None = None
        self.t_phase_s = 0.0
        self.t_stop_s: float | None = None
        self._t_hold_s: float | None = None  # when the stopper reached its hold
        self.step_stopped: int | None = None
        self.offset_world_m: np.ndarray | None = None  # world bit - commanded bit, when ready
        # while cutting: commanded and measured tool positions (S, m), wrist torque (N m), edge
        self.cut_goal_m: list[np.ndarray] = []
        self.cut_actual_m: list[np.ndarray] = []
        self.cut_world_m: list[np.ndarray] = []
        self.cut_torque_nm: list[float] = []
        self.cut_edge: list[int] = []
        self.cut_t_s: list[float] = []
        self.torque_nm = 0.0
        self.error_m = float("nan")

    def attach(self, world: SimulatedWorld | None, modules: Sequence[Module]) -> None:
        self.world = world
        self.modules = list(modules)  # the pipeline, for the live view's safety state
        self.stopper = next((m for m in modules if isinstance(m, EmergencyStopper)
                             and m.name == "estop"), None)

    def _place_wall(self) -> None:
        """The wall at the task's distance from the tool as the robot now holds it (the
        standing robot leans a little under the balancer; an operator walks it up to the wall
        as it stands)."""
        if self.world is None:
            return
        spec, placement = self.plan.spec, self.plan.placement
        scene = spec.scene
        self.scene = WallPlacement(
            tool_frame(spec.stance.limb, spec.stance.tool),
            placement.wall_distance_m - self.plan.T_first_S[0, 3],
            WallSize(scene.wall_height_m, scene.wall_width_m, scene.wall_thickness_m),
        ).place(self.world)

    # ------------------------------------------------------------------ progress (live view)
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
        if self.phase == "settle" and self.step_stopped is None:
            return 1.0
        if end <= start:
            return 1.0 if t >= end else 0.0
        return float(np.clip((t - start) / (end - start), 0.0, 1.0))

    # ------------------------------------------------------------------ the loop's call
    def _still(self, state, tolerance_rad: float = 0.01) -> bool:
        return bool(np.max(np.abs(state.q_rad - self.q_target)) < tolerance_rad
                    and np.max(np.abs(state.dq_rad_s)) < 0.05)

    def __call__(self, t_s: float, state) -> tuple[np.ndarray, dict]:
        info: dict = {}
        stopped = self.stopper is not None and self.stopper.stopped
        if stopped and self.phase != "stopped":
            self.phase, self.t_stop_s = "stopped", t_s
            self.step_stopped = self.step
        if self.phase == "raise":
            if self._still(state) or t_s >= SETTLE_TIMEOUT_S:
                self._place_wall()
                world = self._tool_world(state)
                if world is not None:
                    self.offset_world_m = world - self.plan.T_first_S[:3, 3]
                self.phase, self.t_run_s = "run", t_s
        if self.phase == "run":
            self.k = int(round((t_s - self.t_run_s) / self.plan.dt_s))
            if self.k >= len(self.plan.t_s):
                self.k = len(self.plan.t_s) - 1
                self.phase, self.t_phase_s = "settle", t_s
            self.q_target = self.plan.q_rad[self.k]
        elif self.phase == "settle":
            if self._still(state) or t_s - self.t_phase_s >= SETTLE_TIMEOUT_S:
                info["done"] = True
        elif self.phase == "stopped":
            # the revert can outlast T2 under the limits: count the hold from its start
            holding = self.stopper.mode == "hold"
            if holding and self._t_hold_s is None:
                self._t_hold_s = t_s
            if holding and t_s - self._t_hold_s >= STOP_HOLD_S and np.max(
                    np.abs(state.dq_rad_s)) < 0.05:
                info["done"] = True
        self._measure(t_s, state, info)
        return self.q_target, info

    def _tool_world(self, state) -> np.ndarray | None:
        """The tool's position in the world (m), where the driver knows the torso's pose."""
        if state.T_world_torso is None:
            return None
        T = self.body.arms[self.limb].fk(state.q_rad[self.slice])
        return (state.T_world_torso @ T)[:3, 3]

    def _measure(self, t_s: float, state, info: dict) -> None:
        T = self.body.arms[self.limb].fk(state.q_rad[self.slice])
        actual = T[:3, 3].copy()
        actual[0] += self.plan.placement.shift_m  # the waist's CoM shift (0 without)
        actual[2] += self.body.lift_of(state.q_rad)
        self.torque_nm = wrist_torque_nm(state, self.sensor)
        running = self.phase != "raise"
        k = self.k
        goal = self.plan.goal_S_m[k] if running else actual
        cutting = self.phase == "run" and bool(self.plan.cutting[k])
        self.error_m = float(np.linalg.norm(goal - actual))
        info.update({"step_code": float(self.step), "phase_code": float(PHASES.index(self.phase)),
                     "goal_x_m": goal[0], "goal_y_m": goal[1], "goal_z_m": goal[2],
                     "actual_x_m": actual[0], "actual_y_m": actual[1], "actual_z_m": actual[2],
                     "error_m": self.error_m, "cutting": float(cutting),
                     "edge_code": float(self.plan.edge[k] if cutting else EDGE_NONE),
                     "task_wrist_torque_nm": self.torque_nm})
        if cutting:
            self.cut_goal_m.append(goal.copy())
            self.cut_actual_m.append(actual)
            self.cut_torque_nm.append(self.torque_nm)
            self.cut_edge.append(int(self.plan.edge[k]))
            self.cut_t_s.append(t_s)
            world = self._tool_world(state)
            if world is not None and self.offset_world_m is not None:
                self.cut_world_m.append(world - self.offset_world_m)
