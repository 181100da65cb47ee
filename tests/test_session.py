"""The run scaffold: one pipeline per safety profile, one meaning of --no-estop, one owner of
the control period, declared module hooks, pacing, the tool reaching the collision detector."""

from __future__ import annotations

import pytest

from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Cycle
from hubo_cli.control.pipeline import DEFAULT_ORDER, SafetyProfile, build_pipeline
from hubo_cli.control.stop_choice import ActiveStops
from hubo_cli.drivers.registry import make_driver
from hubo_cli.errors import ConfigError, InputError, SafetyError
from hubo_cli.estimation.build import build_estimator
from hubo_cli.experiments.push_wall import push_wall_setup
from hubo_cli.posture import home_posture
from hubo_cli.session import RunSetup
from hubo_cli.tasks.runner import check_task, task_setup
from hubo_cli.tasks.spec import load_task
from hubo_cli.teleop.session import TeleopSettings, prepare, teleop_setup


@pytest.fixture(scope="module")
def setups(model):
    """Each command's run set-up, with and without --no-estop."""
    plan = check_task(load_task("cut-rectangle", {"width_mm": 60, "height_mm": 40}), model)
    out = {}
    for estop in (True, False):
        stops = None if estop else ActiveStops(())  # --no-estop
        settings = TeleopSettings(replay="x.csv", mode="drill", stops=stops)
        _, body, _, _ = prepare(settings, model)
        out[estop] = {"task": task_setup(plan, stops=stops),
                      "teleop": teleop_setup(settings, body, 1.0),
                      "push-wall": push_wall_setup(model, "forward", estop=estop)[0]}
    return out


def test_no_estop_removes_the_same_modules_in_every_command(setups, model):
    for by_command in setups.values():
        orders = {name: s.safety.order() for name, s in by_command.items()}
        assert len(set(orders.values())) == 1, orders
        built = {name: [m.name for m in s.safety.build(model, model.control_period_s, s.tools)]
                 for name, s in by_command.items()}
        assert all(names == list(orders["task"]) for names in built.values())
    on, off = setups[True]["task"].safety.order(), setups[False]["task"].safety.order()
    assert set(on) - set(off) == {"estop"}
    # the hard stopper, collision detector and limiter always stay; the capture point only
    # measures without the soft stopper
    assert {"hard-estop", "collision", "limiter", "capture-point"} <= set(off)
    for setup in setups[False].values():
        assert setup.safety.options(setup.tools)["capture-point"]["request_estop"] is False


def test_the_tool_reaches_the_collision_detector_and_the_simulator(setups, model):
    for estop in (True, False):
        for name in ("task", "teleop"):
            setup = setups[estop][name]
            assert setup.tools["right-arm"] == "drill"
            assert setup.safety.options(setup.tools)["collision"]["drill"] is True
            detector = next(m for m in setup.safety.build(model, 0.005, setup.tools)
                            if m.name == "collision")
            assert any("drill" in a or "drill" in b for a, b in detector.checker.pair_names)
    from hubo_cli.drivers.base import RunContext
    from hubo_cli.drivers.sim import SimDriver

    options = SimDriver.run_options(RunContext(".", setups[True]["task"].tools))
    assert options["drill"] is True


def test_the_run_uses_the_plan_s_own_model(setups):
    plan_setup = setups[True]["task"]
    assert plan_setup.model is plan_setup.model  # identity kept through the set-up
    plan = check_task(load_task("cut-rectangle", {"width_mm": 60, "height_mm": 40}))
    assert task_setup(plan).model is plan.body.model


def test_every_info_key_a_module_writes_is_a_declared_log_column(model):
    dt = model.control_period_s
    profiles = [SafetyProfile(), SafetyProfile(interpolator="hoff-arbib",
                                               wrist_torque_limit_nm=1.21)]
    for profile in profiles:
        modules = profile.build(model, dt, {"right-arm": "drill"})
        estimator = build_estimator(model, {"right-arm": "drill"}, dt)
        with make_driver("ideal", model) as robot:
            state = robot.start(home_posture(model))
            store = estimator.reset(state)
            for m in modules:
                m.reset(state.q_rad.copy(), state, store)
            q_goal = home_posture(model)
            q_goal[model.limb_slice("right-arm")] += 0.3
            for k in range(40):
                q = q_goal.copy()
                for m in modules:
                    cycle = Cycle(k * dt, dt, store=store)
                    q = m.update(q, state, cycle)
                    undeclared = set(cycle.info) - set(m.log_columns)
                    assert not undeclared, f"{m.name} writes undeclared {undeclared}"
                robot.send(q)
                state = robot.step()
                estimator.update(state)


def test_a_pipeline_built_for_another_period_is_refused(model):
    modules = build_pipeline(model, DEFAULT_ORDER, dt_s=0.01)
    with make_driver("ideal", model) as robot:
        robot.start(home_posture(model))
        with pytest.raises(ConfigError, match="10 ms period"):
            ControlLoop(robot, modules, lambda t, s: (None, {}))


def test_real_robots_live_input_and_the_window_run_in_real_time(model):
    assert RunSetup("x", model, driver="sim").pace() is None
    assert RunSetup("x", model, driver="ideal", speed=3.0).pace() == 3.0
    for setup in (RunSetup("x", model, driver="hardware"),
                  RunSetup("x", model, live_input=True),
                  RunSetup("x", model, gui=True)):
        assert setup.pace() == 1.0
    for setup in (RunSetup("x", model, driver="hardware", speed=4.0),
                  RunSetup("x", model, live_input=True, speed=2.0)):
        with pytest.raises(InputError, match="real time"):
            setup.pace()
    with pytest.raises(InputError):
        RunSetup("x", model, speed=float("nan")).pace()


def test_no_module_or_driver_is_probed_for_optional_behaviour():
    import ast
    from pathlib import Path

    import hubo_cli

    root = Path(hubo_cli.__file__).parent
    offenders = []
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                probing = node.func.id == "hasattr" or (node.func.id == "getattr"
                                                        and len(node.args) == 3)
                if probing and path.parts[-2] in ("control", "drivers", "tasks", "teleop",
                                                  "experiments", "hubo_cli"):
                    offenders.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not offenders


def test_teleop_wall_distance_puts_the_hole_on_that_distance_s_reachable_rectangle():
    from hubo_cli.teleop.session import PAPER_HOLE_M, drill_stance
    from hubo_cli.workspace.stance import best_stance

    for wall_m in (0.44, 0.50):
        wall, corner, height = drill_stance(wall_m)
        rect = best_stance(tool="drill", arm="right", vertical="arm", size_m=PAPER_HOLE_M,
                           wall_distance_m=wall_m).rectangle
        assert wall == wall_m and abs(rect.wall_distance_m - wall_m) < 0.011
        centre_y = corner[1] - PAPER_HOLE_M[0] / 2
        centre_z = corner[2] - PAPER_HOLE_M[1] / 2
        assert rect.y_min_m - 1e-9 <= centre_y <= rect.y_max_m + 1e-9
        assert rect.z_min_m - 1e-9 <= centre_z <= rect.z_max_m + 1e-9
        assert abs(height - (rect.z_min_m + rect.z_max_m) / 2) < 1e-9
    with pytest.raises(SafetyError, match="reaches nothing"):  # exit 4, as a task's
        drill_stance(0.95)


@pytest.mark.physical
@pytest.mark.slow
def test_a_stream_that_swings_the_drill_into_the_torso_is_held_by_the_collision_detector(
        tmp_path):
    """Drill mode at a wall 380 mm from the neck; the operator moves the bit from the hole's
    corner to 10 cm right of the centre line, in front of the chest: the drill and the forearm
    would enter the torso. The collision detector (which checks the drill the robot holds)
    holds the arm; the summary counts the periods. (The bit is in the cardboard meanwhile, so
    the wrist-torque stop may follow: it is not what this test is about.) The paper's reach rule
    lets the IK send the arm there; the default one keeps the hand on its branch, short of it."""
    from hubo_cli.kinematics.arm_reach import ReachSettings
    from hubo_cli.teleop.session import drill_stance, run_teleop

    _, corner, _ = drill_stance(0.38)
    dy, dz = -0.10 - corner[1], 0.04 - corner[2]  # robot frame: y left, z up
    rows = ["t_s,station,x_m,y_m,z_m,qw,qx,qy,qz,status"]
    # 12 s at 60 Hz: the operator's swing (0.5 s to 3.5 s), then he holds his hand there while
    # the drill goal follows at drill mode's speed across the wall (wall_speed_m_s, 25 mm/s:
    # 0.22 m in about 9 s). The tracker frame has y right, z down.
    for k in range(721):
        t = k / 60.0
        s = min(max((t - 0.5) / 3.0, 0.0), 1.0)
        rows.append(f"{t:.6f},1,0.3,{-dy * s:.6f},{-dz * s:.6f},1,0,0,0,")
    stream = tmp_path / "swing.csv"
    stream.write_text("\n".join(rows) + "\n")
    run = run_teleop(TeleopSettings(replay=stream, mode="drill", wall_distance_m=0.38,
                                    reach=ReachSettings(mode="paper"), out=tmp_path / "run"))
    s = run.summary
    assert s["tools"]["right-arm"] == "drill" and "collision" in s["pipeline"]
    # 1891 periods, the first hold at 11.635 s, on both code paths (AVX-512 / portable)
    assert s["collision_periods"] > 20, s["status_counts"]
    first = s["collision_holds"][0]
    assert first["t_s"] > 1.0  # not during the approach
    assert any(name.startswith(("drill", "R")) for name in first["pair"])
    assert any(name.startswith("torso") for name in first["pair"])


def test_the_limit_set_is_the_profile_s_and_a_model_with_another_is_refused(model):
    from hubo_cli.model import load_model

    walking = load_model(model.params_name, "walking")
    assert RunSetup("x", walking, safety=SafetyProfile(limit_set="walking")).model is walking
    assert RunSetup("x", model).model is model  # None: the model's own set
    with pytest.raises(ConfigError, match="'walking' joint-limit set .* loaded with 'table4'"):
        RunSetup("x", model, safety=SafetyProfile(limit_set="walking"))
