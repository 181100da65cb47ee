"""Walking to the working stance first and stepping to catch a push: the pure parts (the
closing steps, the rise, the wall's plane, the capture step's pendulum and landing)."""

import math

import numpy as np
import pytest

from hubo_cli.control.target import FunctionTarget
from hubo_cli.errors import InputError
from hubo_cli.kinematics.limb import Limb
from hubo_cli.model import LEGS, load_model
from hubo_cli.posture import home_posture
from hubo_cli.walking.approach import (
    WALL_MARGIN_M,
    rise_rows,
    stance_width_m,
    walk_first,
    wall_clearance_m,
)
from hubo_cli.walking.body import walking_posture
from hubo_cli.walking.capture_phases import MAX_STEP_M, MAX_WIDTH_M, landing, pendulum
from hubo_cli.walking.footsteps import Footstep, Stance, closing_steps, plan_footsteps


@pytest.fixture(scope="module")
def model():
    return load_model()


def hold(model):
    return FunctionTarget(lambda t, state: (home_posture(model), {"done": True}))


def test_the_home_stance_is_narrower_than_the_walking_one(model, params):
    width = stance_width_m(model, home_posture(model))
    assert 0.17 < width < params.step_width_m - 0.05  # 177 mm: the hips' spacing


def test_closing_steps_alternate_and_end_at_the_width(params):
    goal = Stance(1.0, 0.2, 0.3)
    right, left = goal.foot("right", params.step_width_m), goal.foot("left", params.step_width_m)
    steps = closing_steps(right, left, goal, 0.177, first="left")
    assert [s.side for s in steps] == ["left", "right"]
    assert math.hypot(steps[0].x_m - steps[1].x_m, steps[0].y_m - steps[1].y_m) == \
        pytest.approx(0.177, abs=1e-9)
    assert closing_steps(*reversed(steps), goal, 0.177) == []  # already there
    assert closing_steps(steps[1], steps[0], goal, 0.177) == []


def test_a_walk_ends_on_the_stance_at_the_task_width(model, params):
    """walk_first's plan: the walking width on the way, the home width at the end, the feet
    alternating throughout (the same foot twice would swing the loaded one)."""
    target, walking_model, q_start, budget = walk_first(model, hold(model), (-0.4, 0.1),
                                                        home_posture(model), 0.47)
    assert walking_model.limits_name == "walking"
    width = params.step_width_m
    q_walk, _ = walking_posture(walking_model, width, params.crouch_m)
    np.testing.assert_allclose(q_start, q_walk)
    here = Stance(0.0, 0.0, 0.0)
    right, left = here.foot("right", width), here.foot("left", width)
    steps = plan_footsteps(right, left, Stance(0.4, -0.1, 0.0), params)
    first = "left" if steps[-1].side == "right" else "right"
    steps += closing_steps(steps[-2] if steps[-2].side == "right" else steps[-1],
                           steps[-2] if steps[-2].side == "left" else steps[-1],
                           Stance(0.4, -0.1, 0.0), 0.177, first)
    assert all(a.side != b.side for a, b in zip(steps, steps[1:], strict=False))
    assert budget > len(steps) * params.step_s  # the run's duration covers the walk
    assert target.wall_x_m == pytest.approx(0.4 + 0.47)


def test_a_walk_first_keeps_the_robot_file_it_runs_on(model, tmp_path):
    """Round 21: walk_first reloaded the walking limit set from the shipped file's parameter
    set by name, so a run on another robot file walked the shipped robot's model."""
    from robot_file_support import robot_file_with

    robot = load_model(path=robot_file_with(model, tmp_path, "robot", "control_period_s",
                                            "0.01"))
    _, walking_model, _, _ = walk_first(robot, hold(robot), (-0.4, 0.1), home_posture(robot),
                                        0.47)
    assert walking_model.source == robot.source and walking_model.limits_name == "walking"
    assert walking_model.control_period_s == 0.01


def test_a_start_beyond_the_wall_is_refused(model):
    with pytest.raises(InputError, match="wall"):
        walk_first(model, hold(model), (0.6, 0.0), home_posture(model), 0.47)
    with pytest.raises(InputError, match="finite"):
        walk_first(model, hold(model), (math.nan, 0.0), home_posture(model), 0.47)


def test_wall_clearance_counts_the_toes():
    feet = [Footstep("right", 0.0, -0.1, 0.0), Footstep("left", 0.2, 0.1, 0.0)]
    assert wall_clearance_m(feet, 0.5, 0.13) == pytest.approx(0.5 - 0.33)
    assert wall_clearance_m(feet, 0.3, 0.13) < WALL_MARGIN_M


def test_the_rise_keeps_the_feet_apart_and_ends_in_the_posture(model, params):
    """From the walking crouch at the home width to the home posture: the soles' distance and
    headings stay as they are (to 1 mm), the last row is the posture, and at the run's 5 ms
    period no joint moves faster than 30 % of its posture limit (Table IV)."""
    q_to = home_posture(model)
    q_from, _ = walking_posture(model, stance_width_m(model, q_to), params.crouch_m)
    rows = rise_rows(model, q_from, q_to, 800)
    np.testing.assert_allclose(rows[-1], q_to)
    legs = {leg: Limb(model, leg) for leg in LEGS}
    gaps = []
    for q in rows[::20]:
        T = [legs[leg].fk(q[model.limb_slice(leg)]) for leg in LEGS]
        gaps.append(np.linalg.norm(T[0][:3, 3] - T[1][:3, 3]))
        assert np.allclose(T[0][:3, :3], T[1][:3, :3], atol=1e-3)
    assert max(gaps) - min(gaps) < 0.001
    speed = np.abs(np.diff(rows, axis=0)).max(axis=0) / model.control_period_s
    assert np.all(speed < 0.3 * model.velocity_rad_s)


def test_pendulum_diverges_from_its_zmp():
    omega = math.sqrt(9.81 / 0.6)
    t = np.array([0.0, 0.2, 0.4])
    c, v, a = pendulum(np.array([0.0, 0.0]), np.array([0.5, 0.0]), np.array([0.05, 0.0]),
                       omega, t)
    xi = c[:, 0] + v[:, 0] / omega
    # the capture point runs away from the ZMP exponentially: xi - p = (xi0 - p) e^(wt)
    np.testing.assert_allclose(xi - 0.05, (0.5 / omega - 0.05) * np.exp(omega * t))
    np.testing.assert_allclose(a[:, 0], omega**2 * (c[:, 0] - 0.05))


def test_landing_stays_within_reach():
    stance = Footstep("right", 0.0, -0.088, 0.0)
    near = landing(stance, "left", np.array([0.15, 0.0]), 0.02, 0.177)
    assert near.x_m == pytest.approx(0.13) and near.y_m == pytest.approx(-0.088 + 0.177)
    far = landing(stance, "left", np.array([2.0, 1.0]), 0.02, 0.177)
    assert math.hypot(far.x_m - stance.x_m, far.y_m - stance.y_m) == \
        pytest.approx(MAX_STEP_M)
    # too far: the sideways part gives way first, down to the standing width
    assert far.y_m - stance.y_m == pytest.approx(0.177)
    wide = landing(stance, "left", np.array([0.1, 1.0]), 0.02, 0.177)  # within reach, wide
    assert wide.y_m - stance.y_m == pytest.approx(MAX_WIDTH_M)


def test_teleop_refuses_a_bad_walk_start():
    from click.testing import CliRunner

    from hubo_cli.cli.main import main

    result = CliRunner().invoke(main, ["teleop", "--replay", "trajectories/drill-rectangle.csv",
                                       "--walk-from", "nan", "0"])
    assert result.exit_code == 2
    assert "--walk-from" in result.output


@pytest.mark.parametrize("command", [
    ["teleop", "--replay", "trajectories/drill-rectangle.csv", "--walk-from", "-0.6", "0"],
    ["task", "run", "cut-rectangle", "--set", "stance.start_mm=[-600,0]"],
])
def test_a_walk_first_on_the_ideal_driver_is_refused_as_hubo_walk_is(tmp_path, command):
    """Review 23: `hubo walk --driver ideal` is refused (the ideal driver has no floor: every
    walk on it stopped at its first step), but `teleop --walk-from` on it walked one step,
    stopped 205 mm short and ended exit 2 "no operator input", and a task walking to its
    stance was not refused either. Now both exit 2 with hubo walk's line, nothing run."""
    from click.testing import CliRunner

    from hubo_cli.cli.main import main

    result = CliRunner().invoke(main, [*command, "--driver", "ideal",
                                       "--out", str(tmp_path / "run")])
    assert result.exit_code == 2, result.output
    assert "error: a walk needs a floor: the ideal driver has none" in result.output
    assert "Traceback" not in result.output and not (tmp_path / "run").exists()


@pytest.mark.parametrize("command", [
    ["walk", "--to", "1", "0", "0", "--no-estop"],
    ["walk", "--to", "1", "0", "0", "--estop-sources", "capture-point"],
    ["walk", "--to", "1", "0", "0", "--estop-sources", "none"],
    ["teleop", "--replay", "trajectories/drill-rectangle.csv", "--walk-from", "-0.6", "0",
     "--no-estop"],
    ["task", "run", "cut-rectangle", "--set", "stance.start_mm=[-600,0]", "--no-estop"],
])
def test_a_walk_without_the_operators_stop_is_refused(tmp_path, command):
    """A walk's Ctrl-C (SIGTERM, a full disk) finishes the step into a stance through the soft
    stopper's operator stop; without it (``--no-estop``, ``--estop-sources`` leaving it out)
    main braked the joints where they were, a foot in the air. Refused on one line, exit 4,
    before anything moves; ``--estop-sources operator`` is what the hint offers."""
    from click.testing import CliRunner

    from hubo_cli.cli.main import main

    result = CliRunner().invoke(main, [*command, "--out", str(tmp_path / "run")])
    assert result.exit_code == 4, result.output
    error = [line for line in result.output.splitlines() if line.startswith("error: ")]
    assert len(error) == 1 and "needs the operator stop" in error[0]
    assert "hint: keep it: --estop-sources operator" in result.output
    assert not (tmp_path / "run").exists()
