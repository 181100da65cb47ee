"""The manipulation experiments of the multi-layer controller paper (IV-C.2, Figs. 11-13): the
right hand turns a valve or pushes a door open, on a scene the planner may have misrecognised.

Valve (``turn-valve``)
    A wheel (:class:`~hubo_cli.hinged_objects.Valve`, radius 0.12 m, 3 N m of dry friction)
    stands in front of the robot's right shoulder, its axis along x, on a stem from a panel
    behind it. The plan (Fig. 13 alpha, beta): reach up and over the rim, lower the hand onto the
    rim's top, close the hand (the grip holds only if the rim is really there:
    :meth:`~hubo_cli.scene.SceneActions.grasp`), then carry the grip clockwise (as
    the robot sees it) along the rim's circle through ``turn_deg`` and hold.
Door (``push-door``)
    A door (:class:`~hubo_cli.hinged_objects.Door`, 0.9 m wide, hinged on the robot's left, a closer
    of 2 N m + 10 N m/rad) stands closed just in front of the hands. The plan (Fig. 13
    gamma): bring the right hand's fingertips to the leaf, then push the leaf along its arc
    about the hinge through ``door_deg`` and hold it there against the closer.

The recognition errors are where the plan and the world part. The robot plans on the scene
as seen; the real object stands elsewhere: a valve seen ``seen_offset_m`` away from where it
is (seen minus true, world axes: the paper's 131 mm forward and 33 mm up, or 195 mm to the
left; the robot planned its stance from what it saw, so the plan is the nominal one and the
true valve is displaced by minus that offset), and a door planned as a push door that in
truth opens toward the robot (``door_opens = "toward"``: pushed, it stands against its
frame's stop). The hand then meets the object where the plan did not expect it.

Each runs with the paper's emergency stopper (operator and capture point, eq. 15) or without
it (``--no-estop``); the ankle balancer as in the push-wall experiment. Outcomes: ``fell``
(:mod:`hubo_cli.falls`), ``tipped`` (a sole corner 2 cm up) and ``overloaded``: an arm motor
at its torque limit (the URDF's effort) for ``OVERLOAD_S`` in all, the arm stalled against
the object. The run folder holds ``log.csv`` (the hand force, the object's angle, the torso
tilt per period), ``summary.json`` and ``manipulation.png``: the capture-point error and the
hand force over time, as the paper's Figs. 11-12. The wrist is judged apart from the motors:
``wrist_overloaded`` when the wrist sensor's bending moment stays beyond the robot's wrist
torque limit (``[safety] wrist_torque_limit_nm``, 1.21 N m, the limit the teleoperation paper
determined on the robot) for ``OVERLOAD_S`` in all; the simulated wrist motors themselves are
modelled stronger (their URDF effort).

Hand geometry: the hand keeps its start orientation (fingers forward) rolled outward by
``HAND_ROLL_RAD`` on the way (so the upper arm clears the torso); its collision box (from the
URDF) sets how far above the rim its point rides (``clearance_m``) and where its fingertips are
(``tip_m`` ahead of the hand point).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hubo_cli.control.collision import SelfCollisionChecker
from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.dataflow import Store
from hubo_cli.drivers.base import grip_flag
from hubo_cli.errors import ConfigError, InputError, quoted
from hubo_cli.estimation.keys import COM_WORLD, T_WORLD_SOLES, WRENCHES
from hubo_cli.experiments.push_wall import ARM_START_RAD, hand_box_extent_m
from hubo_cli.experiments.watch import WatchedTarget
from hubo_cli.geometry import min_jerk
from hubo_cli.hinged_objects import DOOR_OPENS, Door, Valve
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture
from hubo_cli.scene import SceneActions
from hubo_cli.session import RunObserver, RunResult, RunSetup, run

KINDS = ("turn-valve", "push-door")
ARM = "right-arm"
HAND = "right_hand"
WRIST = "right-wrist"
# the scene as the plan sees it, in the start neck frame N (m): found with the arm's IK and the
# self-collision checker so that every pose of both plans has an exact solution at least
# COLLISION_MARGIN_M clear of the body (the collision detector holds the arm nearer than 1 cm)
VALVE_CENTRE_N_M = (0.34, -0.20, -0.21)  # low enough that the valve seen 131 mm too far and
# 33 mm too high (so truly that much nearer and lower) is still clear of the hand at the start
HAND_ROLL_RAD = math.radians(-30.0)  # the hand rolled outward: the elbow clears the torso
VALVE_RADIUS_M = 0.12
VALVE_STEM_M = 0.06        # the panel stays clear of the hand at the start in every case
DOOR_GAP_M = 0.03          # the fingertips to the closed leaf at the start
DOOR_LEVER_M = 0.35        # the pushed point to the hinge
RIM_GAP_M = 0.004          # the hand's underside above the rim's tube when it grips
ABOVE_RIM_M = 0.05         # the pre-grip pose above the grip
GRIP_REACH_M = 0.005       # the grip closes once the rim lies within this of its planned place
OVERLOAD_RATIO = 0.95      # of a motor's torque limit
OVERLOAD_S = 0.25
COLLISION_MARGIN_M = 0.012
MAX_TURN_DEG = 96.0        # the last turn whose every pose has an exact arm solution


@dataclass(frozen=True)
class Segment:
    """One piece of the hand's path: ``duration_s`` long, the hand point (N, m) at progress
    ``u`` (0..1, minimum-jerk in time) given by ``point``, the hand rolled about its own x axis
    (fingers forward) from its start orientation by ``roll_rad`` (from, to; linear in ``u``);
    ``grasp``: the hand closes during it, as soon as the object is within its reach (the
    trajectory generator brings the hand there a few tenths of a second after the goal)."""

    name: str
    duration_s: float
    point: Callable[[float], np.ndarray]
    roll_rad: tuple[float, float] = (0.0, 0.0)
    grasp: bool = False

    def roll_at(self, u: float) -> float:
        return self.roll_rad[0] + (self.roll_rad[1] - self.roll_rad[0]) * u


@dataclass(frozen=True)
class ManipulationSpec:
    """One experiment: what kind, the recognition error, how far to turn or push.

    Attributes:
        kind: ``turn-valve`` or ``push-door``.
        seen_offset_m: the valve as seen minus as it is (world axes, m).
        door_opens: how the real door opens (``away``: as planned; ``toward``).
        turn_deg: the valve's planned turn (deg, clockwise as the robot sees it).
        door_deg: the door's planned opening (deg).
        end_hold_s: holding still after the motion (s).
        impedance: the ImpedanceController on the right hand (the paper's was on; no
            reference force: the hand yields to what it meets, up to its offset limits).
    """

    kind: str
    seen_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    door_opens: str = "away"
    turn_deg: float = 95.0
    door_deg: float = 24.0
    end_hold_s: float = 1.0
    impedance: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"unknown manipulation experiment {quoted(self.kind)}",
                             hint=f"use one of {', '.join(KINDS)}")
        offset = np.asarray(self.seen_offset_m, dtype=float)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)) \
                or np.max(np.abs(offset)) > 0.5:
            raise InputError(f"seen_offset_mm must be 3 finite numbers within 500 mm, got "
                             f"{[round(float(v) * 1000, 3) for v in np.ravel(offset)]}",
                             hint="e.g. --set seen_offset_mm=[131,0,33]")
        if self.door_opens not in DOOR_OPENS:
            raise InputError(f"door_opens must be {' or '.join(DOOR_OPENS)}, got "
                             f"{quoted(self.door_opens)}")
        if not 0.0 < self.turn_deg <= MAX_TURN_DEG:
            raise InputError(f"turn_deg must be in (0, {MAX_TURN_DEG:g}], got "
                             f"{quoted(self.turn_deg)}",
                             hint="the right hand reaches that far along this valve's rim")
        if not 0.0 < self.door_deg <= 30.0:
            raise InputError(f"door_deg must be in (0, 30], got {quoted(self.door_deg)}")
        if not 0.0 <= self.end_hold_s <= 60.0:
            raise InputError(f"end_hold_s must be in [0, 60] s, got {quoted(self.end_hold_s)}")

    @property
    def misrecognised(self) -> bool:
        return bool(np.any(np.asarray(self.seen_offset_m) != 0.0)) or self.door_opens != "away"

    @property
    def case(self) -> str:
        """The case's name for the run folder and the plot."""
        if self.kind == "push-door":
            return "nominal" if self.door_opens == "away" else "opens-toward"
        if not self.misrecognised:
            return "nominal"
        return "seen-" + "-".join(f"{axis}{v * 1000:+.0f}mm" for axis, v
                                  in zip("xyz", self.seen_offset_m, strict=True) if v)


def spec_from_parameters(kind: str, params: dict) -> ManipulationSpec:
    """The experiment's spec from a task file's ``[parameters]`` (``seen_offset_mm`` [x, y, z]
    in mm, ``door_opens``, ``turn_deg``, ``door_deg``; missing ones take their defaults).

    Raises:
        InputError: a value of the wrong kind or out of range (exit 2).
    """
    def number(name: str, default: float) -> float:
        value = params.get(name, default)
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise InputError(f"parameter {name} must be a number, got {quoted(value)}",
                             hint=f"e.g. --set {name}={default:g}")
        return float(value)

    def flag(name: str) -> bool:
        value = params.get(name, False)
        if not isinstance(value, bool):
            raise InputError(f"parameter {name} must be true or false, got {quoted(value)}",
                             hint=f"e.g. --set {name}=true")
        return value

    offset = params.get("seen_offset_mm", [0.0, 0.0, 0.0])
    if not (isinstance(offset, list | tuple) and len(offset) == 3 and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in offset)):
        raise InputError(f"parameter seen_offset_mm must be three numbers [x, y, z] in mm, got "
                         f"{quoted(offset)}", hint="e.g. --set seen_offset_mm=[131,0,33]")
    defaults = ManipulationSpec("turn-valve")
    return ManipulationSpec(kind, seen_offset_m=tuple(float(v) / 1000.0 for v in offset),
                            door_opens=str(params.get("door_opens", "away")),
                            turn_deg=number("turn_deg", defaults.turn_deg),
                            door_deg=number("door_deg", defaults.door_deg),
                            impedance=flag("impedance"))


def start_posture(model: RobotModel) -> np.ndarray:
    """Home legs, both arms raised in front with the hands level (as the push-wall start)."""
    q = home_posture(model)
    for arm, values in ARM_START_RAD.items():
        q[model.limb_slice(arm)] = values
    return q


def _line(a, b) -> Callable[[float], np.ndarray]:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return lambda u: a + (b - a) * u


def valve_plan(spec: ManipulationSpec, p0: np.ndarray, clearance_m: float
               ) -> tuple[list[Segment], Valve]:
    """The valve plan from the hand's start point ``p0`` (N): its segments and the valve as
    seen (centre in N)."""
    c = np.asarray(VALVE_CENTRE_N_M)
    radius = VALVE_RADIUS_M + clearance_m  # the hand point's circle

    def on_circle(angle_rad: float) -> np.ndarray:
        return c + radius * np.array([0.0, -math.sin(angle_rad), math.cos(angle_rad)])

    grip = on_circle(0.0)
    above = grip + [0.0, 0.0, ABOVE_RIM_M]
    turn = math.radians(spec.turn_deg)
    roll = (HAND_ROLL_RAD, HAND_ROLL_RAD)
    segments = [Segment("stand", 0.3, _line(p0, p0)),
                Segment("reach", 1.8, _line(p0, above), (0.0, HAND_ROLL_RAD)),
                Segment("lower", 0.8, _line(above, grip), roll),
                Segment("close", 1.2, _line(grip, grip), roll, grasp=True),
                Segment("turn", 3.0, lambda u: on_circle(turn * u), roll),
                Segment("hold", spec.end_hold_s, _line(on_circle(turn), on_circle(turn)), roll)]
    return segments, Valve(tuple(c), radius_m=VALVE_RADIUS_M, stem_m=VALVE_STEM_M)


def door_plan(spec: ManipulationSpec, p0: np.ndarray, tip_m: float
              ) -> tuple[list[Segment], Door]:
    """The door plan from the hand's start point ``p0`` (N): its segments and the door as
    seen (a push door; N)."""
    face_x = p0[0] + tip_m + DOOR_GAP_M
    hinge = np.array([face_x, p0[1] + DOOR_LEVER_M, p0[2]])
    opening = math.radians(spec.door_deg)

    def pushed(angle_rad: float) -> np.ndarray:  # the hand point with its tips on the leaf
        return hinge + [DOOR_LEVER_M * math.sin(angle_rad) - tip_m,
                        -DOOR_LEVER_M * math.cos(angle_rad), 0.0]

    touch = pushed(0.0)
    roll = (HAND_ROLL_RAD, HAND_ROLL_RAD)
    segments = [Segment("stand", 0.3, _line(p0, p0)),
                Segment("reach", 1.0, _line(p0, touch), (0.0, HAND_ROLL_RAD)),
                Segment("push", 3.0, lambda u: pushed(opening * u), roll),
                Segment("hold", spec.end_hold_s, _line(pushed(opening), pushed(opening)), roll)]
    return segments, Door(float(face_x), float(hinge[1]), opens="away")


class ManipulationTargets(WatchedTarget):
    """The target source: the hand's path through the arm's IK every period (the start
    orientation held), the grasp at its time, the object placed once the robot stands.

    Raises:
        ConfigError: a pose of the plan has no exact IK solution (nothing moved).
    """

    reads = (*WatchedTarget.reads, WRENCHES, COM_WORLD)
    previous = (STOP_MODE,)  # the soft stopper's mode: no grasp while it stops the motion
    log_columns = ("hand_axial_n", "wrist_moment_nm", "com_inside_m",
                   "holding_flag", "arm_torque_ratio", "tilt_deg", "torso_z_m", "sole_lift_m",
                   "segment_code")

    def __init__(self, model: RobotModel, spec: ManipulationSpec, q_start: np.ndarray) -> None:
        super().__init__(model)
        self.model = model
        self.spec = spec
        self.q_start = q_start.copy()
        self.limb = Limb(model, ARM, "hand")
        self.slice = model.limb_slice(ARM)
        self.T_start = self.limb.fk(q_start[self.slice])
        p0 = self.T_start[:3, 3]
        self.tip_m = float(hand_box_extent_m(model, q_start, ARM)[1, 0] - p0[0])
        self.clearance_m = self._hand_below_m(HAND_ROLL_RAD) \
            + Valve((0, 0, 0)).tube_radius_m + RIM_GAP_M
        if spec.kind == "turn-valve":
            self.segments, self.seen = valve_plan(spec, p0, self.clearance_m)
        else:
            self.segments, self.seen = door_plan(spec, p0, self.tip_m)
        self.ends_s = np.cumsum([s.duration_s for s in self.segments])
        self.duration_s = float(self.ends_s[-1])
        self.q_prev = q_start[self.slice].copy()
        self._check_reach()
        self.effort_nm = _arm_effort(load_pin_robot(model), model)
        self.grasp_miss_m: float | None = None  # the rim's distance at the last try (m)
        self.grasped_at_s: float | None = None
        self.placed: dict = {}
        self.world: SceneActions | None = None
        self.overload_periods = 0
        self.max_torque_ratio = 0.0
        self.max_torque_nm = np.zeros(len(self.effort_nm))  # each arm joint's largest |tau| (N m)
        self.max_axial_n = 0.0  # the largest |f_z| along the forearm (N)
        self.max_moment_nm = 0.0  # the largest wrist bending moment (N m)
        self.wrist_limit_nm = float(model.safety.get("wrist_torque_limit_nm", math.inf))
        self.wrist_over_periods = 0  # periods with the bending moment beyond wrist_limit_nm
        # the centre of mass's ground point inside the box of both soles (lifted or not, m):
        # while it stays inside, gravity alone brings a robot tipped onto its heels or onto one
        # foot back onto both soles; once it leaves, the robot falls unless something holds it
        self.min_com_inside_m = math.inf

    def _hand(self, point_m, roll_rad: float) -> np.ndarray:
        """The hand goal (4x4, N): at ``point_m``, rolled by ``roll_rad`` from its start."""
        c, s = math.cos(roll_rad), math.sin(roll_rad)
        T = self.T_start.copy()
        T[:3, :3] = T[:3, :3] @ np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        T[:3, 3] = point_m
        return T

    def _hand_below_m(self, roll_rad: float) -> float:
        """How far the hand's collision box reaches below the hand point when rolled (m)."""
        p0 = self.T_start[:3, 3]
        result = self.limb.solve(self._hand(p0, roll_rad), self.q_start[self.slice])
        q = self.q_start.copy()
        q[self.slice] = result.q_rad
        return float(p0[2] - hand_box_extent_m(self.model, q, ARM)[0, 2])

    def goal(self, t_s: float) -> tuple[int, np.ndarray]:
        """The segment's index and the hand goal (4x4, N) at ``t_s``."""
        k = min(int(np.searchsorted(self.ends_s, t_s, side="right")), len(self.segments) - 1)
        segment = self.segments[k]
        start = self.ends_s[k] - segment.duration_s
        u = float(min_jerk((t_s - start) / segment.duration_s)) if segment.duration_s > 0 \
            else 1.0
        return k, self._hand(segment.point(u), segment.roll_at(u))

    def _check_reach(self) -> None:
        """Every pose of the plan (each 50 ms) has an exact arm solution clear of the body."""
        checker = SelfCollisionChecker(self.model)
        q, q_all = self.q_prev, self.q_start.copy()
        for t_s in np.arange(0.0, self.duration_s + 1e-9, 0.05):
            k, T = self.goal(float(t_s))
            result = self.limb.solve(T, q)
            q = q_all[self.slice] = result.q_rad
            clear = checker.check(q_all) if result.status == "exact" else None
            if clear is None or clear.distance_m < COLLISION_MARGIN_M:
                why = (f"no exact arm solution ({result.status})" if clear is None else
                       f"{clear.pair[0]} {clear.distance_m * 1000:.0f} mm from {clear.pair[1]}")
                raise ConfigError(
                    f"the {self.spec.kind} plan's {self.segments[k].name} pose at "
                    f"{t_s:.2f} s: {why}",
                    hint="the scene constants in hubo_cli/experiments/manipulation.py were "
                         "chosen for the arm's reach; keep turn_deg and door_deg in range")

    def _com_inside_m(self) -> float:
        """How far the centre of mass's ground point lies inside the box of both soles' corners
        (the estimate; negative: outside), m."""
        corners = np.concatenate([self._corners @ T[:3, :3].T + T[:3, 3]
                                  for T in self.store[T_WORLD_SOLES]])[:, :2]
        com = self.store[COM_WORLD][:2]
        return float(np.min(np.concatenate([com - corners.min(axis=0),
                                            corners.max(axis=0) - com])))

    def attach(self, world: SceneActions | None, modules, store: Store) -> None:
        if world is None:
            raise ConfigError(f"the {self.spec.kind} experiment needs the simulator",
                              hint="run it with the sim driver")
        super().attach(world, modules, store)
        self.world = world
        # planned in N; the scene module puts it where the robot truly stands (its lean)
        if isinstance(self.seen, Valve):
            centre = np.asarray(self.seen.centre_world_m) - self.spec.seen_offset_m
            valve = world.place_object(replace(self.seen, centre_world_m=tuple(
                float(v) for v in centre)), HAND, self.T_start, "valve")
            seen = np.asarray(valve.centre_world_m) + self.spec.seen_offset_m
            self.placed = {"kind": "valve", "true_centre_world_m": valve.centre_world_m,
                           "seen_centre_world_m": tuple(float(v) for v in seen),
                           "radius_m": valve.radius_m, "friction_nm": valve.friction_nm}
        else:
            door = world.place_object(replace(self.seen, opens=self.spec.door_opens), HAND,
                                      self.T_start, "door")
            self.placed = {"kind": "door", "near_face_x_world_m": door.near_face_x_m,
                           "hinge_y_world_m": door.hinge_y_m, "opens": door.opens,
                           "planned_as": "away", "push_lever_m": DOOR_LEVER_M}

    def __call__(self, t_s: float, state):
        tilt_deg, z = self.watch(t_s, state)
        com_inside_m = self._com_inside_m()
        self.min_com_inside_m = min(self.min_com_inside_m, com_inside_m)
        k, T = self.goal(t_s)
        stopped = self.store.get(STOP_MODE, "release") != "release"
        holding = grip_flag(HAND) in state.flags  # the hand's grip sensor
        if holding and self.grasped_at_s is None:
            self.grasped_at_s = t_s
        if self.segments[k].grasp and not holding and not stopped:
            self.grasp_miss_m = self.world.grasp(HAND, "valve", self.clearance_m + GRIP_REACH_M)
        result = self.limb.solve(T, self.q_prev)
        self.q_prev = result.q_rad
        q = self.q_start.copy()
        q[self.slice] = result.q_rad
        # what Hubo's wrist sensor sees (compensated): the force along the forearm f_z (+: the
        # hand pulled out along it) and the bending moment |m_x, m_y|, which a force across the
        # forearm makes at its lever (a push at the fingertips, a grip on the rim); a force
        # across the forearm is not read as a force (the sensor has no f_x, f_y)
        wrench = self.store[WRENCHES][WRIST]
        axial_n, moment_nm = float(wrench[2]), math.hypot(float(wrench[3]), float(wrench[4]))
        self.max_axial_n = max(self.max_axial_n, abs(axial_n))
        self.max_moment_nm = max(self.max_moment_nm, moment_nm)
        self.wrist_over_periods += moment_nm > self.wrist_limit_nm
        tau_nm = np.abs(state.tau_nm[self.slice])
        np.maximum(self.max_torque_nm, np.where(np.isfinite(tau_nm), tau_nm, 0.0),
                   out=self.max_torque_nm)
        ratio = float(np.max(tau_nm / self.effort_nm))
        self.max_torque_ratio = max(self.max_torque_ratio, ratio)
        self.overload_periods += ratio >= OVERLOAD_RATIO
        return q, {"hand_axial_n": axial_n, "wrist_moment_nm": moment_nm,
                   "com_inside_m": com_inside_m,
                   "holding_flag": float(holding),
                   "arm_torque_ratio": ratio, "tilt_deg": tilt_deg, "torso_z_m": z,
                   "sole_lift_m": self.lift_m, "segment_code": float(k),
                   "done": self.fall_done(t_s)}


def _arm_effort(robot, model: RobotModel) -> np.ndarray:
    """The arm motors' torque limits (N m, the URDF's effort) in the arm's joint order."""
    pin_model = robot.model
    names = model.joint_names[model.limb_slice(ARM)]
    return np.array([pin_model.effortLimit[pin_model.joints[pin_model.getJointId(n)].idx_v]
                     for n in names])


def manipulation_setup(model: RobotModel, spec: ManipulationSpec, estop: bool = True,
                       out: str | Path | None = None, gui: bool = False,
                       balance: str = "default") -> RunSetup:
    """The experiment's run set-up: the simulated robot, both hands free, the stopper
    listening to the operator and the capture point (as the push-wall experiment)."""
    return RunSetup(
        command=f"{spec.kind}-{spec.case}-{'estop' if estop else 'no-estop'}"
        + ("-impedance" if spec.impedance else ""), model=model,
        tools={"right-arm": "hand", "left-arm": "hand"}, driver="sim",
        safety=SafetyProfile(estop=estop, sources=("operator", "capture-point"),
                             impedance=spec.impedance, impedance_arms=(ARM,))
        .with_balance(balance), gui=gui, out=out, q_start_rad=start_posture(model),
        driver_options={"logged_object": "valve" if spec.kind == "turn-valve" else "door"})


def run_manipulation(model: RobotModel, spec: ManipulationSpec, estop: bool = True,
                     out: str | Path | None = None, gui: bool = False,
                     perturb_seed: int | None = None, balance: str = "default",
                     live: RunObserver | None = None) -> RunResult:
    """Run the experiment on the simulated robot and write its run folder (see the module
    docstring)."""
    setup = manipulation_setup(model, spec, estop, out, gui, balance)
    targets = ManipulationTargets(model, spec, setup.q_start_rad)
    setup = replace(setup, perturb_seed=perturb_seed, live=live, duration_s=targets.duration_s)
    done = run(setup, targets)
    summary = manipulation_summary(spec, estop, targets, done)
    if setup.safety.estop:  # the soft stopper's T1 and T2, as the profile built it
        summary |= {"revert_s": setup.safety.revert_s, "stop_s": setup.safety.stop_s}
    done.save_summary(summary)
    from hubo_cli.plots.manipulation import plot_manipulation

    plot_manipulation(done.log, done.summary, done.run_dir / "manipulation.png")
    done.add_file("manipulation.png")
    done.save_summary({})
    return done


def manipulation_summary(spec: ManipulationSpec, estop: bool, targets: ManipulationTargets,
                         done: RunResult) -> dict:
    """The experiment's fields of ``summary.json``."""
    log = done.log
    stops = [e for e in done.loop.safety_events if e[0] == "estop" and e[2] == "stop"]
    cp_flags = np.nonzero(log["cp_flag"] > 0.5)[0]
    error = np.hypot(log["cp_error_x_m"], log["cp_error_y_m"])
    angle = log["object_angle_deg"]
    tilt = log["tilt_deg"][np.isfinite(log["tilt_deg"])]
    period_s = targets.model.control_period_s
    return {
        "experiment": spec.kind,
        "case": spec.case,
        "seen_offset_mm": [round(v * 1000, 3) for v in spec.seen_offset_m],
        "door_opens": spec.door_opens if spec.kind == "push-door" else None,
        "planned_deg": spec.turn_deg if spec.kind == "turn-valve" else spec.door_deg,
        "estop": "on" if estop else "off",
        "fell": targets.fell,
        "t_fall_s": targets.t_fall_s,
        "tipped": targets.tipped,
        "max_sole_lift_mm": round(targets.max_lift_m * 1000, 1),
        "overloaded": targets.overload_periods * period_s >= OVERLOAD_S,
        "overload_s": round(targets.overload_periods * period_s, 3),
        "max_arm_torque_ratio": round(targets.max_torque_ratio, 3),
        # each arm joint's largest torque against its motor's limit (N m, the URDF's effort)
        "peak_arm_torque_nm": {
            name: [round(float(peak), 1), float(limit)] for name, peak, limit in zip(
                targets.model.joint_names[targets.slice], targets.max_torque_nm,
                targets.effort_nm, strict=True)},
        "max_tilt_deg": round(targets.max_tilt_deg, 2),
        "end_tilt_deg": round(float(tilt[-1]), 2) if len(tilt) else None,
        "min_com_inside_mm": round(targets.min_com_inside_m * 1000, 1)
        if math.isfinite(targets.min_com_inside_m) else None,
        "t_emergency_s": stops[0][1] if stops else None,
        "emergency_sources": list(stops[0][3]) if stops else [],
        "t_cp_flag_s": float(log["t_s"][cp_flags[0]]) if len(cp_flags) else None,
        "max_cp_error_mm": round(float(np.nanmax(error)) * 1000, 1),
        "max_axial_force_n": round(targets.max_axial_n, 1),
        "max_wrist_moment_nm": round(targets.max_moment_nm, 2),
        # the wrist judged against the robot's wrist torque limit (the robot file's [safety])
        "wrist_limit_nm": targets.wrist_limit_nm if math.isfinite(targets.wrist_limit_nm)
        else None,
        "wrist_over_limit_s": round(targets.wrist_over_periods * period_s, 3),
        "wrist_overloaded": targets.wrist_over_periods * period_s >= OVERLOAD_S,
        "impedance": "on" if spec.impedance else "off",
        "object_angle_deg": round(float(angle[np.isfinite(angle)][-1]), 2),
        "max_object_angle_deg": round(float(np.nanmax(np.abs(angle))), 2),
        "grasped_at_s": targets.grasped_at_s,
        "grasp_rim_distance_mm": None if targets.grasp_miss_m is None
        else round(targets.grasp_miss_m * 1000, 1),
        "object": targets.placed,
        "segments": [{"name": s.name, "end_s": round(float(e), 3)}
                     for s, e in zip(targets.segments, targets.ends_s, strict=True)],
    }

