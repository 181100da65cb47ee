"""The emergency-stop experiment of the multi-layer controller paper (IV-C, Fig. 8-10).

A wall stands just in front of the hands. Both hands are commanded 0.25 m forward in 4 s
(``direction="forward"``), or the left hand 0.25 m leftward in 2 s toward a block on its left
(``direction="left"``). The goal poses move along a minimum-jerk profile and become joint
targets through the closed-form arm IK every period; the default pipeline runs on the simulated
robot. With the emergency stopper off the hands keep pushing and the robot tips over; with it
on the capture-point monitor raises the flag, the stopper reverts the arms to where they were
0.5 s earlier and holds, and the robot stays up.

Fall criterion (the same as hrpsys' TILT check): the torso tilts more than 30 deg from upright,
or drops 0.2 m below its start height; the run ends 0.5 s after a fall.
A sole corner rising more than 2 cm off the floor (the robot rocked onto its heels or onto one
foot) counts as ``tipped``, even when the robot comes back down.

``run_push_wall`` writes the run folder: ``log.csv`` (the loop's per-period log plus the
push offset, torso tilt and height), ``summary.json`` and ``cp_error.png`` (the capture-point
error along the push axis against time with the support-polygon thresholds, as Fig. 10).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from hubo_cli.control.log import LogData
from hubo_cli.control.loop import LoopResult
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError, InputError, quoted
from hubo_cli.experiments.watch import TIP_LIFT_M, WatchedTarget
from hubo_cli.falls import FALL_TILT_DEG
from hubo_cli.geometry import min_jerk
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, RobotModel
from hubo_cli.pin_robot import load_pin_robot
from hubo_cli.posture import home_posture
from hubo_cli.scene import SceneActions
from hubo_cli.session import RunObserver, RunResult, RunSetup, run

DIRECTIONS = ("forward", "left")
WALL_HEIGHT_M = 2.0
# Elbows fully bent, hands level in front of the chest (hand x forward): from here the fixed-
# orientation IK reaches the whole 0.25 m forward push exactly. For the left push the left
# wrist is yawed so that the 0.25 m leftward path is reachable too.
ARM_START_RAD = {"right-arm": (0.0, 0.0, 0.0, -2.45, 0.0, 0.9),
                 "left-arm": (0.0, 0.0, 0.0, -2.45, 0.0, 0.9)}
LEFT_PUSH_ARM_START_RAD = (0.0, 0.0, 0.0, -2.2, -0.5, 0.0)
HAND_LINKS = {"right-arm": "RWP_link", "left-arm": "LWP_link"}


@dataclass(frozen=True)
class PushSpec:
    """One push: which arms move, along which unit vector (neck frame), how far and how fast.

    Attributes:
        direction: ``forward`` or ``left``.
        arms: the arms that push.
        axis: the push direction (3,), and the CP error axis (0 = x, 1 = y).
        push_m, push_s: distance (m) and duration (s) of the commanded motion.
        start_s: standing still before the push (s).
        end_s: length of the run (s).
        wall_gap_m: clearance between the hand and the wall at the start (m).
    """

    direction: str
    arms: tuple[str, ...]
    axis: np.ndarray
    push_m: float = 0.25
    push_s: float = 4.0
    start_s: float = 0.5
    end_s: float = 8.0
    wall_gap_m: float = 0.02

    @property
    def axis_index(self) -> int:
        return int(np.argmax(np.abs(self.axis)))


def push_spec(direction: str) -> PushSpec:
    """The paper's two pushes: ``forward`` (both hands, 4 s) or ``left`` (left hand, 2 s)."""
    if direction == "forward":
        return PushSpec("forward", ("right-arm", "left-arm"), np.array([1.0, 0.0, 0.0]),
                        push_s=4.0, end_s=8.0)
    if direction == "left":
        return PushSpec("left", ("left-arm",), np.array([0.0, 1.0, 0.0]), push_s=2.0,
                        end_s=6.0)
    raise InputError(f"unknown push direction {quoted(direction)}",
                     hint=f"use one of {', '.join(DIRECTIONS)}")


def start_posture(model: RobotModel, spec: PushSpec) -> np.ndarray:
    """Home legs, arms raised in front (rad)."""
    q = home_posture(model)
    for arm, values in ARM_START_RAD.items():
        q[model.limb_slice(arm)] = values
    if spec.direction == "left":
        q[model.limb_slice("left-arm")] = LEFT_PUSH_ARM_START_RAD
    return q


def hand_box_extent_m(model: RobotModel, q_rad: np.ndarray, arm: str) -> np.ndarray:
    """The hand's collision box in the neck frame at ``q_rad``: (2, 3) min and max corner (m)."""
    robot = load_pin_robot(model)
    geom = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.COLLISION)
    data, geom_data = robot.model.createData(), pin.GeometryData(geom)
    pin.updateGeometryPlacements(robot.model, data, geom, geom_data, robot.configuration(q_rad))
    index = geom.getGeometryId(f"{HAND_LINKS[arm]}_0")
    half = np.asarray(geom.geometryObjects[index].geometry.halfSide)
    placement = geom_data.oMg[index]
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = (signs * half) @ placement.rotation.T + placement.translation
    return np.array([corners.min(axis=0), corners.max(axis=0)])


class PushTargets(WatchedTarget):
    """The target source: goal poses along the push, through the arm IK every period.

    It also watches the torso (tilt, height) and ends the run shortly after a fall. Once the
    robot stands it places the obstacle (:meth:`attach`).
    """

    name = "push-wall"
    log_columns = ("push_offset_m", "tilt_deg", "torso_z_m", "sole_lift_m")

    def __init__(self, model: RobotModel, spec: PushSpec, q_start: np.ndarray) -> None:
        super().__init__(model)
        self.model = model
        self.spec = spec
        self.q_start = q_start.copy()
        self.limbs = {arm: Limb(model, arm, "hand") for arm in spec.arms}
        self.slices = {arm: model.limb_slice(arm) for arm in spec.arms}
        self.T_start = {arm: self.limbs[arm].fk(q_start[self.slices[arm]]) for arm in spec.arms}
        self.q_prev = {arm: q_start[self.slices[arm]].copy() for arm in spec.arms}
        self.ik_status: dict[str, int] = {}
        self.obstacle: dict = {}

    def attach(self, world: SceneActions | None, modules, store: Store) -> None:
        if world is None:
            raise ConfigError("the push-wall experiment needs the simulator",
                              hint="run it with the sim driver")
        super().attach(world, modules, store)
        self.obstacle = _place_obstacle(world, self.model, self.spec, self.q_start)

    def __call__(self, t_s: float, state):
        tilt_deg, z = self.watch(t_s, state)
        spec = self.spec
        offset = spec.push_m * min_jerk((t_s - spec.start_s) / spec.push_s)
        q = self.q_start.copy()
        for arm, limb in self.limbs.items():
            goal = self.T_start[arm].copy()
            goal[:3, 3] += offset * spec.axis
            result = limb.solve(goal, self.q_prev[arm])
            self.ik_status[result.status] = self.ik_status.get(result.status, 0) + 1
            self.q_prev[arm] = result.q_rad
            q[self.slices[arm]] = result.q_rad
        done = self.fall_done(t_s)
        return q, {"push_offset_m": offset, "tilt_deg": tilt_deg, "torso_z_m": z,
                   "sole_lift_m": self.lift_m, "done": done}


def _place_obstacle(world: SceneActions, model: RobotModel, spec: PushSpec,
                    q_start: np.ndarray) -> dict:
    """A wall in front of both hands, or a block on the left of the left hand (world frame:
    the robot as the simulator sets it down in ``q_start``, its neck over the origin, the
    lower sole on the floor)."""
    neck_height_m = -min(float(Limb(model, leg).fk(q_start[model.limb_slice(leg)])[2, 3])
                         for leg in LEGS)
    arm = spec.arms[0]
    box = hand_box_extent_m(model, q_start, arm)
    offset = np.array([0.0, 0.0, neck_height_m])  # neck frame -> world
    lo, hi = box[0] + offset, box[1] + offset
    if spec.direction == "forward":
        distance_m = float(hi[0] + spec.wall_gap_m)
        world.add_wall(distance_m, WALL_HEIGHT_M, width_m=1.2, thickness_m=0.05)
        return {"kind": "wall", "near_face_x_m": distance_m, "height_m": WALL_HEIGHT_M}
    top_m = min(hi[2] + 0.25, neck_height_m - 0.05)  # below the shoulder
    # a block whose right face is wall_gap_m left of the left hand, spanning the hand along x
    width_m, thickness_m = 0.2, 0.3
    near_y_m = float(hi[1] + spec.wall_gap_m)
    x0_m = float(lo[0] - 0.05)
    world.add_wall(x0_m, top_m, width_m=width_m, thickness_m=thickness_m,
                    centre_y_m=near_y_m + width_m / 2)
    return {"kind": "block", "near_face_y_m": near_y_m, "x_from_m": x0_m,
            "x_to_m": x0_m + thickness_m, "height_m": top_m}


def _summary(spec: PushSpec, estop: bool, targets: PushTargets, loop: LoopResult,
             log: LogData, obstacle: dict) -> dict:
    axis = "xy"[spec.axis_index]
    error = log[f"cp_error_{axis}_m"]
    outside = log["cp_outside_m"]
    running = np.isfinite(error)
    stops = [e for e in loop.safety_events if e[0] == "estop" and e[2] == "stop"]
    cp_flags = np.nonzero(log["cp_flag"] > 0.5)[0]
    return {
        "experiment": "push-wall",
        "direction": spec.direction,
        "estop": "on" if estop else "off",
        "fell": targets.fell,
        "tipped": targets.tipped,
        "max_sole_lift_mm": round(targets.max_lift_m * 1000, 1),
        "t_fall_s": targets.t_fall_s,
        "max_tilt_deg": round(targets.max_tilt_deg, 2),
        "t_emergency_s": stops[0][1] if stops else None,
        "emergency_sources": list(stops[0][3]) if stops else [],
        "t_cp_flag_s": float(log["t_s"][cp_flags[0]]) if len(cp_flags) else None,
        "max_cp_error_mm": round(float(np.nanmax(np.abs(error[running]))) * 1000, 1),
        "cp_error_axis": axis,
        "max_cp_outside_mm": round(float(np.nanmax(outside[running])) * 1000, 1),
        "push_m": spec.push_m,
        "push_s": spec.push_s,
        "push_start_s": spec.start_s,
        "obstacle": obstacle,
        "ik_status_periods": targets.ik_status,
    }


def push_wall_setup(model: RobotModel, direction: str = "forward", estop: bool = True,
                    out: str | Path | None = None, gui: bool = False,
                    end_s: float | None = None, interpolator: str = "otg",
                    balance: str = "default") -> tuple[RunSetup, PushSpec]:
    """The experiment's run set-up (the simulated robot, both hands free, the stopper
    listening to the operator and the capture point) and its push."""
    spec = push_spec(direction)
    if end_s is not None:
        spec = PushSpec(spec.direction, spec.arms, spec.axis, spec.push_m, spec.push_s,
                        spec.start_s, float(end_s), spec.wall_gap_m)
    setup = RunSetup(
        command=f"push-wall-{direction}-{'estop' if estop else 'no-estop'}", model=model,
        tools={"right-arm": "hand", "left-arm": "hand"}, driver="sim",
        safety=SafetyProfile(estop=estop, sources=("operator", "capture-point"),
                             interpolator=interpolator).with_balance(balance),
        gui=gui, out=out, duration_s=spec.end_s, q_start_rad=start_posture(model, spec))
    return setup, spec


def run_push_wall(model: RobotModel, direction: str = "forward", estop: bool = True,
                  out: str | Path | None = None, gui: bool = False, end_s: float | None = None,
                  interpolator: str = "otg", perturb_seed: int | None = None,
                  balance: str = "default", live: RunObserver | None = None) -> RunResult:
    """Run the experiment on the simulated robot and write its run folder.

    Args:
        model: the robot model.
        direction: ``forward`` or ``left``.
        estop: keep the soft emergency stopper (sources: operator, capture point).
        out: the run folder (default ``runs/<time>-push-wall-...``).
        gui: open the PyBullet window (real time).
        end_s: shorten (or lengthen) the run (s).
        interpolator: the first module, ``otg`` (ruckig) or ``hoff-arbib`` (eq. 1).
        perturb_seed: a perturbed simulated robot and world (:mod:`hubo_cli.perturb`).
        balance: the balancer, ``default``, ``paper`` or ``off`` (``--balance``).
        live: the live viewer's publisher (``--live``), if any.
    """
    setup, spec = push_wall_setup(model, direction, estop, out, gui, end_s, interpolator,
                                  balance)
    setup = replace(setup, perturb_seed=perturb_seed, live=live)
    targets = PushTargets(model, spec, setup.q_start_rad)
    done = run(setup, targets)
    summary = _summary(spec, estop, targets, done.loop, done.log, targets.obstacle)
    summary["interpolator"] = interpolator
    if setup.safety.estop:  # the soft stopper's T1 and T2, as the profile built it
        summary["revert_s"] = setup.safety.revert_s
        summary["stop_s"] = setup.safety.stop_s
    done.save_summary(summary)
    plot_cp_error(done.log, done.summary, done.run_dir / "cp_error.png")
    done.add_file("cp_error.png")
    done.save_summary({})
    return done


def plot_cp_error(log: LogData, summary: dict, path: str | Path) -> Path:
    """The run at a glance (PNG), like the paper's Fig. 10: the capture-point error along the
    push axis with the support-polygon edges (minus 3 cm) as thresholds; below it the flag
    criterion (how far the CP lies outside the support that still touches the ground) and the
    torso tilt. The emergency-stop period is shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hubo_cli.plots import STOP_COLOUR, save_figure, shade_emergency_stop

    axis = summary["cp_error_axis"]
    t = log["t_s"]
    error_mm = log[f"cp_error_{axis}_m"] * 1000
    ref = log[f"cp_ref_{axis}_m"]
    low_mm = (log[f"support_min_{axis}_m"] - ref) * 1000
    high_mm = (log[f"support_max_{axis}_m"] - ref) * 1000
    outside_mm = np.clip(log["cp_outside_m"] * 1000, -200, 200)
    tilt = log["tilt_deg"]
    fig, (ax, ax_flag, ax_tilt) = plt.subplots(
        3, 1, figsize=(8.0, 7.6), dpi=120, sharex=True,
        gridspec_kw={"height_ratios": [2.2, 1.1, 1.0]})
    push_start = summary["push_start_s"]
    for a in (ax, ax_flag, ax_tilt):
        a.axvspan(push_start, push_start + summary["push_s"], color="#e6e6e6", lw=0,
                  label="commanded push" if a is ax else None)
        shade_emergency_stop(a, log, summary, label=a is ax)
        a.grid(alpha=0.3)
    ax.plot(t, low_mm, "--", color="#1f77b4", lw=1.3, label="threshold: sole edge - 3 cm")
    ax.plot(t, high_mm, "--", color="#1f77b4", lw=1.3)
    ax.plot(t, error_mm, color="#d62728", lw=1.7, label=f"capture-point error ({axis})")
    if summary.get("t_emergency_s") is not None:
        ax.annotate(f"emergency flag {summary['t_emergency_s']:.2f} s",
                    (summary["t_emergency_s"], 0.03), xycoords=("data", "axes fraction"),
                    xytext=(5, 0), textcoords="offset points", color=STOP_COLOUR, fontsize=9)
    finite = np.isfinite(error_mm) & np.isfinite(low_mm) & np.isfinite(high_mm)
    if finite.any():  # show the thresholds well; a fall's huge error runs off the top
        threshold_span = float(np.max(np.abs(np.concatenate([low_mm[finite], high_mm[finite]]))))
        error_span = float(np.max(np.abs(error_mm[finite])))
        span = max(1.3 * threshold_span, min(1.15 * error_span, 3.0 * threshold_span))
    else:
        span = 100.0
    ax.set_ylim(-span, span)
    ax.set_ylabel("CP error [mm]")
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9, ncol=2)
    outcome = ("fell" if summary["fell"] else "tipped (a sole off the floor)" if summary["tipped"]
               else "stayed up")
    ax.set_title(f"push-wall {summary['direction']}, emergency stop {summary['estop']}: "
                 f"{outcome} (max tilt {summary['max_tilt_deg']:.1f} deg)")
    ax_flag.plot(t, outside_mm, color="#9467bd", lw=1.4,
                 label="CP beyond the shrunk support on the ground")
    ax_flag.axhline(0.0, color="#555555", ls=":", lw=1.0, label="flag threshold")
    ax_flag.set_ylabel("outside [mm]")
    ax_flag.legend(loc="upper left", fontsize=8, framealpha=0.9)
    ax_tilt.plot(t, tilt, color="#2ca02c", lw=1.5, label="torso tilt")
    ax_tilt.axhline(FALL_TILT_DEG, color="#555555", ls=":", lw=1.0,
                    label=f"fall {FALL_TILT_DEG:.0f} deg")
    ax_lift = ax_tilt.twinx()
    ax_lift.plot(t, log["sole_lift_m"] * 1000, color="#8c564b", lw=1.1, alpha=0.8)
    ax_lift.axhline(TIP_LIFT_M * 1000, color="#8c564b", ls="--", lw=0.8)
    ax_lift.set_ylabel("sole lift [mm]", color="#8c564b")
    ax_lift.tick_params(axis="y", colors="#8c564b")
    ax_lift.set_ylim(0, max(3 * TIP_LIFT_M * 1000, float(np.nanmax(log["sole_lift_m"])) * 1100))
    ax_tilt.plot([], [], color="#8c564b", lw=1.1, label="highest sole corner lift")
    ax_tilt.plot([], [], color="#8c564b", ls="--", lw=0.8,
                 label=f"tip {TIP_LIFT_M * 1000:.0f} mm")
    ax_tilt.set_ylabel("tilt [deg]")
    ax_tilt.set_xlabel("time [s]")
    ax_tilt.set_ylim(0, max(FALL_TILT_DEG * 1.2, float(np.nanmax(tilt)) * 1.1))
    ax_tilt.legend(loc="upper left", fontsize=8, framealpha=0.9, ncol=4)
    fig.align_ylabels()
    fig.tight_layout()
    return save_figure(fig, path)
