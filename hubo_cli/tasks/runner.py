"""The task runner: pre-flight, then the plan through the pipeline on a driver, then the run
folder.

``check_task`` lays the task out and checks every pose (no driver is touched); ``run_task``
runs a checked plan and writes ``runs/<time>-task-<name>/``: ``log.csv`` (every period),
``summary.json``, ``task.toml`` (the file as run, with the parameters used, to run it again),
``path.png`` (commanded vs actual bit path in the wall plane, the paper's Fig. 5),
``wrist_torque.png`` and ``snapshot.png`` (the scene at the end, simulation only).
Experiment tasks (``experiment = "push-wall"``) run their built-in procedure instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hubo_cli.control.estop import EmergencyStopper
from hubo_cli.control.log import load_log, max_velocity_ratio
from hubo_cli.control.loop import ControlLoop, LoopResult
from hubo_cli.control.pipeline import DEFAULT_ORDER, build_pipeline, find_module
from hubo_cli.drivers.base import make_driver
from hubo_cli.errors import SafetyError
from hubo_cli.kinematics.wholebody import WholeBody
from hubo_cli.model import RobotModel, load_model
from hubo_cli.posture import home_posture
from hubo_cli.runs import make_run_dir, write_json
from hubo_cli.tasks.plan import EDGE_NAMES, Plan, make_plan
from hubo_cli.tasks.spec import TaskSpec
from hubo_cli.tasks.target import SETTLE_TIMEOUT_S, TaskTarget
from hubo_cli.urdf import DRILL_FRAME

PAPER_TORQUE_NM = {"horizontal": {"mean": 0.14, "max": 0.23},
                   "vertical": {"mean": 0.15, "max": 0.35}}
PAPER_RMS_ERROR_MM = 17.0


@dataclass
class TaskRun:
    """A finished run: its folder, summary (also in summary.json) and how the loop ended."""

    run_dir: Path
    summary: dict
    loop: LoopResult
    plan: Plan | None = None


def check_task(spec: TaskSpec, model: RobotModel | None = None) -> Plan:
    """Pre-flight: lay the task out and solve every period; nothing moves.

    Returns the plan; ``plan.preflight.ok`` says whether every pose is reachable, and
    ``plan.preflight.worst_per_step()`` what misses and by how much.
    """
    return make_plan(spec, model or load_model())


def _pipeline(plan: Plan, model: RobotModel, estop: bool):
    safety = plan.spec.safety
    sources = set(safety.estop_sources)
    order = [n for n in DEFAULT_ORDER
             if estop or n not in ("estop", "capture-point")]
    options = {"estop": {"sources": tuple(sources), "revert_s": safety.revert_s,
                         "stop_s": safety.stop_s,
                         "wrist_torque_limit_nm": safety.wrist_torque_limit_nm},
               "capture-point": {"drill": plan.spec.stance.tool == "drill"},
               "balance": {"drill": plan.spec.stance.tool == "drill"}}
    modules = build_pipeline(model, order, options=options)
    return modules, find_module(modules, "estop")


def run_task(plan: Plan, *, driver: str = "sim", out: str | Path | None = None,
             speed: float | None = None, gui: bool = False, estop: bool = True,
             driver_options: dict | None = None, on_start=None) -> TaskRun:
    """Run a checked plan and write its run folder.

    Args:
        plan: from :func:`check_task`; refused unless its pre-flight passed.
        driver: ``sim``, ``ideal`` or ``hardware``.
        out: the run folder (default ``runs/<time>-task-<name>``).
        speed: None = as fast as possible, 1.0 = real time.
        gui: open the PyBullet window (sim).
        estop: keep the soft emergency stopper and the capture-point monitor.
        driver_options: passed to the driver (e.g. ``armed`` for hardware).
        on_start: called with the :class:`TaskTarget` once the robot has started (live view).

    Raises:
        SafetyError: the plan did not pass pre-flight (nothing moves).
    """
    if not plan.preflight.ok:
        raise SafetyError(plan.preflight.worst_per_step()[0].message(),
                          hint="the task was refused in pre-flight; nothing moved")
    spec = plan.spec
    model = load_model()
    body = WholeBody(model, {spec.stance.limb: spec.stance.tool},
                     plan.placement.working_height_m)
    modules, stopper = _pipeline(plan, model, estop)
    run_dir = make_run_dir(f"task-{spec.name}", out)
    _write_task_copy(spec, run_dir)
    options = dict(driver_options or {})
    if driver == "sim":
        options.update(gui=gui, drill=spec.stance.tool == "drill",
                       cutting={"coulomb_n": spec.scene.coulomb_n,
                                "viscous_n_s_per_m": spec.scene.viscous_n_s_per_m})
    placed: dict = {}
    with make_driver(driver, model, **options) as robot:
        robot.start(home_posture(model))

        def place_wall() -> None:
            """The wall at the task's distance from the tool as the robot now holds it (the
            standing robot leans a little forward under the ankle controller, eq. 11-12; an
            operator walks it up to the wall as it stands)."""
            if not hasattr(robot, "add_wall"):
                return
            distance = plan.placement.wall_distance_m
            if spec.stance.tool == "drill" and hasattr(robot, "frame_pose"):
                bit_x = robot.frame_pose(DRILL_FRAME)[0, 3]
                distance = bit_x + distance - plan.T_first_S[0, 3]
            robot.add_wall(distance, spec.scene.wall_height_m, spec.scene.wall_width_m,
                           spec.scene.wall_thickness_m)
            placed["wall_x_world_m"] = float(distance)

        target = TaskTarget(plan, body, stopper, on_ready=place_wall)
        if on_start is not None:
            on_start(target)
        loop = ControlLoop(robot, modules, target, speed=speed, log_path=run_dir)
        # the plan, plus the waits for the robot to settle (raise, end, after a stop)
        result = loop.run(plan.duration_s + 3 * SETTLE_TIMEOUT_S + 10.0)
        if hasattr(robot, "snapshot_png"):
            robot.snapshot_png(run_dir / "snapshot.png")
    summary = summarise(plan, model, target, result, stopper, run_dir, driver)
    summary["scene"] = placed
    write_json(run_dir / "summary.json", summary)
    return TaskRun(run_dir, summary, result, plan)


def _write_task_copy(spec: TaskSpec, run_dir: Path) -> None:
    """The task file as run; overridden parameters are noted at the top (``--set`` them)."""
    header = [f"# run of {spec.path}"]
    if spec.overridden:
        sets = " ".join(f"--set {k}={v}" for k, v in spec.overridden.items())
        header.append(f"# parameters changed for this run: hubo task run task.toml {sets}")
    (run_dir / "task.toml").write_text("\n".join(header) + "\n" + spec.path.read_text())


def _stats(values) -> dict:
    v = np.asarray(values, dtype=float)
    if not len(v):
        return {"mean": None, "std": None, "max": None, "samples": 0}
    return {"mean": float(v.mean()), "std": float(v.std()), "max": float(v.max()),
            "samples": len(v)}


def _plane_rms_mm(goal_m: np.ndarray, actual_m: np.ndarray) -> float | None:
    """RMS distance in the wall plane (y, z) between matching rows (mm)."""
    if not len(actual_m) or len(actual_m) != len(goal_m):
        return None
    d = goal_m[:, 1:] - actual_m[:, 1:]
    return float(np.sqrt(np.mean(np.sum(d**2, axis=1))) * 1000)


def summarise(plan: Plan, model: RobotModel, target: TaskTarget, result: LoopResult,
              stopper: EmergencyStopper | None, run_dir: Path, driver: str) -> dict:
    """The summary.json content; also draws the plots into the run folder."""
    from hubo_cli.plots.paths import plot_path_comparison
    from hubo_cli.plots.task import plot_wrist_torque

    spec = plan.spec
    limit = spec.safety.wrist_torque_limit_nm
    goal = np.array(target.cut_goal_m).reshape(-1, 3)
    actual = np.array(target.cut_actual_m).reshape(-1, 3)
    errors = np.linalg.norm(goal - actual, axis=1)
    world = np.array(target.cut_world_m).reshape(-1, 3)
    edge = np.array(target.cut_edge, dtype=int)
    torque = np.array(target.cut_torque_nm)
    log = load_log(run_dir)
    torque_stats = {name: _stats(torque[edge == code]) for code, name in EDGE_NAMES.items()}
    all_torque = log["task_wrist_torque_nm"]
    stops = [e for e in result.safety_events if e[2] == "stop"]
    completed = result.ok and target.phase == "settle" and target.step_stopped is None
    files = ["log.csv", "summary.json", "task.toml"]
    T_S_W = plan.placement.T_S_W()
    if len(goal):
        rms = float(np.sqrt(np.mean(errors**2)) * 1000)
        plot_path_comparison(goal - T_S_W[:3, 3], actual - T_S_W[:3, 3], run_dir / "path.png",
                             plane="yz", frame="the wall frame",
                             title=f"{spec.name}: commanded vs actual drill bit while cutting",
                             rms_error_mm=rms)
        files.append("path.png")
    plot_wrist_torque(log, run_dir / "wrist_torque.png", limit_nm=limit,
                      title=f"{spec.name}: wrist torque (limit {limit:g} N m)",
                      stop_times_s=[e[1] for e in stops])
    files.append("wrist_torque.png")
    if (run_dir / "snapshot.png").exists():
        files.append("snapshot.png")
    stop = None
    if stops:
        module, t_stop, _, sources = stops[0]
        step = spec.steps[target.step_stopped] if target.step_stopped is not None else None
        stop = {"t_s": t_stop, "sources": list(sources),
                "step": None if step is None else step.name,
                "reverted_to_t_s": t_stop - spec.safety.revert_s,
                "held": target.phase == "stopped" and stopper is not None
                and stopper.mode == "hold",
                "wrist_torque_nm": float(np.nanmax(all_torque[log["t_s"] <= t_stop + 1e-9]))
                if len(all_torque) else None}
    return {
        "task": spec.name,
        "task_file": str(spec.path),
        "parameters": spec.parameters,
        "driver": driver,
        "completed": completed,
        "ended": result.ended,
        "error": result.error,
        "duration_s": result.t_end_s,
        "periods": result.periods,
        "stance": plan.placement.to_json(),
        "steps": [{"name": s.name, "kind": s.kind, "description": s.describe(),
                   "done": completed or (target.step_stopped is not None
                                         and s.number - 1 < target.step_stopped)}
                  for s in spec.steps],
        "rms_error_mm": float(np.sqrt(np.mean(errors**2)) * 1000) if len(errors) else None,
        "max_error_mm": float(errors.max() * 1000) if len(errors) else None,
        "error_measured_by": "forward kinematics of the measured joints (bit position in S), "
                             "against the commanded bit position of the same period",
        "hole_rms_error_mm": _plane_rms_mm(goal, world),
        "hole_error_measured_by": "the bit's world position (simulation) in the wall plane, "
                                  "relative to where it stood when the wall was placed",
        "cut_samples": len(goal),
        "wrist_torque_nm": torque_stats | {
            "limit": limit,
            "max_while_cutting": float(torque.max()) if len(torque) else None,
            "max_whole_run": float(np.nanmax(all_torque)) if len(all_torque) else None,
            "over_limit": bool(len(torque) and torque.max() > limit),
            "paper": PAPER_TORQUE_NM},
        "paper_rms_error_mm": PAPER_RMS_ERROR_MM,
        "estop": stop,
        "estop_events": [{"module": m, "t_s": t, "kind": k, "sources": list(s)}
                         for m, t, k, s in result.safety_events if k in ("stop", "release")],
        "status_counts": result.status_counts,
        "max_joint_velocity_ratio": max_velocity_ratio(model, log),
        "overruns": result.overruns,
        "files": files,
    }


def run_experiment(spec: TaskSpec, *, out: str | Path | None = None, gui: bool = False
                   ) -> TaskRun:
    """Run an experiment task (its built-in procedure with the file's parameters)."""
    from hubo_cli.experiments.push_wall import run_push_wall

    params = spec.parameters
    result = run_push_wall(load_model(), direction=str(params.get("direction", "forward")),
                           estop=bool(params.get("estop", True)), out=out,
                           speed=1.0 if gui else None, gui=gui,
                           interpolator=str(params.get("interpolator", "otg")))
    summary = {"task": spec.name, "parameters": params} | result.summary
    write_json(result.run_dir / "summary.json", summary)
    return TaskRun(result.run_dir, summary, result.loop)
