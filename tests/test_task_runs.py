"""Scripted tasks end to end: pre-flight refusals move nothing, the rectangle is cut within the
paper's accuracy, and a cut too fast for the wrist is stopped and backed out of the wall."""

import json
import math
import re

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.balance_report import bit_poses, flutes_in_wall
from hubo_cli.cli.main import main
from hubo_cli.control.log import load_log
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import T_WORLD_SOLES, T_WORLD_TORSO, WRENCHES
from hubo_cli.geometry import rpy_to_quat_wxyz
from hubo_cli.kinematics.torso import torso_in_stance
from hubo_cli.model import load_model
from hubo_cli.state import RobotState
from hubo_cli.tasks import target as target_module
from hubo_cli.tasks.plan import make_plan
from hubo_cli.tasks.spec import load_task
from hubo_cli.tasks.target import RETREAT_ALONG_M, RETREAT_M, RETREAT_STEPS, TaskTarget


def _invoke(*args):
    return CliRunner().invoke(main, ["task", *args], catch_exceptions=False)


@pytest.fixture(scope="module")
def rectangle_plan():
    return make_plan(load_task("cut-rectangle"), load_model())


def test_default_plan_passes_preflight_and_follows_the_rectangle(rectangle_plan):
    model = load_model()
    plan = rectangle_plan
    assert plan.preflight.ok and not plan.preflight.warnings
    corners = plan.placement.T_S_W()[:3, 3]
    cut = plan.goal_S_m[plan.cutting] - corners
    assert cut[:, 1].max() == pytest.approx(0.075) and cut[:, 1].min() == pytest.approx(-0.075)
    assert cut[:, 2].max() == pytest.approx(0.050) and cut[:, 2].min() == pytest.approx(-0.050)
    assert np.allclose(cut[:, 0], 0.0025)                   # the bit's middle in the cardboard
    # every planned joint target reproduces its goal (whole-body FK: the legs' lift and, with
    # CoM control, their waist shift)
    body = plan.body
    sl = model.limb_slice("right-arm")
    for k in range(0, len(plan.t_s), 250):
        q = plan.q_rad[k]
        bit = body.arms["right-arm"].fk(q[sl])[:3, 3] + (body.shift_of(q), 0.0, body.lift_of(q))
        assert np.linalg.norm(bit - plan.goal_S_m[k]) < 1e-9


def test_the_task_phases_hand_over_and_a_released_stop_resumes_the_frozen_row(rectangle_plan):
    """The task's phases as explicit states: raise -> run once the robot is still on the first
    pose; a stop latched (the stopper's mode, the store's STOP_MODE) freezes the plan's row;
    released, the run goes on from that very row; at the plan's end, settle waits from the next
    period and ends the run once the robot is still. Without an operator a held stop ends the
    run after STOP_HOLD_S of stillness."""
    from hubo_cli.control.keys import STOP_MODE
    from hubo_cli.drivers.registry import make_driver
    from hubo_cli.estimation.build import build_estimator
    from hubo_cli.tasks.phases import PHASES, STOP_HOLD_S

    plan, dt = rectangle_plan, rectangle_plan.dt_s
    rows = len(plan.t_s)

    def target_on_still_robot(resumable):
        target = TaskTarget(plan, correction=False, resumable=resumable)
        estimator = build_estimator(plan.body.model, dict(plan.body.tools))
        with make_driver("ideal", plan.body.model) as driver:
            driver.start(plan.q_first_rad)
            estimator.reset(driver.read())  # every estimate key the target reads
        target.attach(None, [], estimator.store)
        return target, estimator.store

    def still(q):
        return RobotState(0.0, q, np.zeros(len(q)))

    target, store = target_on_still_robot(resumable=True)
    codes = []
    for k in range(11):
        _, info = target(k * dt, still(plan.q_first_rad))
        codes.append(info["phase_code"])
    assert target.phase == "run" and target.k == 10 and codes[0] == PHASES.index("run")
    store[STOP_MODE] = "stop"
    _, info = target(11 * dt, still(plan.q_first_rad))
    assert target.phase == "stopped" and info["phase_code"] == PHASES.index("stopped")
    assert target.t_stop_s == 11 * dt and target.k == 10
    store[STOP_MODE] = "hold"
    for k in range(12, 12 + round(2 * STOP_HOLD_S / dt)):  # an operator: it holds on
        _, info = target(k * dt, still(plan.q_first_rad))
        assert "done" not in info
    store[STOP_MODE] = "release"
    t_resume = 500 * dt
    q, _ = target(t_resume, still(plan.q_first_rad))
    assert target.phase == "run" and target.k == 10 and target.resumed_t_s == [t_resume]
    assert np.array_equal(q, plan.q_rad[10])
    t_end = t_resume + (rows - 10) * dt
    _, info = target(t_end, still(plan.q_rad[-1]))  # past the last row: settle next period
    assert target.phase == "settle" and target.k == rows - 1 and "done" not in info
    _, info = target(t_end + dt, still(plan.q_rad[-1]))
    assert info["done"] and info["phase_code"] == PHASES.index("settle")

    target, store = target_on_still_robot(resumable=False)
    target(0.0, still(plan.q_first_rad))
    store[STOP_MODE] = "hold"
    t_held = dt
    for k in range(1, round(STOP_HOLD_S / dt) + 1):
        _, info = target(k * dt, still(plan.q_first_rad))
        assert "done" not in info
    assert target.t_held_s == t_held and target.step_stopped == plan.step_index[0]
    _, info = target(t_held + STOP_HOLD_S + dt, still(plan.q_first_rad))
    assert info["done"]


def test_the_task_corrects_the_arm_by_the_measured_torso_lean(rectangle_plan):
    """A torso leaning 0.5 deg forward (the estimate's torso pose, S where the soles stand):
    the target's arm joints put the bit back on the plan's goal in S; the plan's own joints,
    which the target plays without the correction, leave it several millimetres off."""
    plan = rectangle_plan
    body, sl = plan.body, plan.body.model.limb_slice("right-arm")
    q = plan.q_first_rad.copy()
    lean = RobotState(0.0, q, np.zeros_like(q))
    T_S_N = torso_in_stance(body, q, rpy_to_quat_wxyz(0.0, np.radians(0.5), 0.0))
    T_world_S = np.eye(4)
    T_world_S[:3, 3] = 0.4, -0.2, 0.9  # the estimate's world: S anywhere
    store = Store()
    store[T_WORLD_TORSO] = T_world_S @ T_S_N  # the estimate: the body leaning on its soles
    store[T_WORLD_SOLES] = np.array([T_world_S @ body.T_S_sole[leg]
                                     for leg in ("right-leg", "left-leg")])
    store[WRENCHES] = lean.ft  # and nothing on the wrists
    target = TaskTarget(plan)
    target.attach(None, [], store)
    for k in range(300):
        q_out, _ = target(k * plan.dt_s, lean)
    plain = target.q_target  # the plan's joints for this period
    goal = (torso_in_stance(body, plain) @ body.arms["right-arm"].fk(plain[sl]))[:3, 3]
    uncorrected, corrected = ((T_S_N @ body.arms["right-arm"].fk(q_arm[sl]))[:3, 3]
                              for q_arm in (plain, q_out))
    assert np.linalg.norm(uncorrected - goal) > 0.004
    assert np.linalg.norm(corrected - goal) < 0.0005
    assert corrected[0] < uncorrected[0] - 0.003  # held back against the forward lean
    plain_target = TaskTarget(plan, correction=False)
    plain_target.attach(None, [], store)
    assert np.array_equal(plain_target(0.0, lean)[0], plan.q_first_rad)


@pytest.mark.parametrize("seed", range(3))
def test_the_wrist_stop_relief_backs_the_bit_straight_out_of_the_wall(rectangle_plan, seed,
                                                                       monkeypatch):
    """TaskTarget.relieve, the wrist-torque stop's relief, over random postures around the
    cut's (arm joints +-0.25 rad, torso leaning up to 2 deg): whenever it gives a path, the bit
    ends RETREAT_M out of the wall along S's -x with its orientation kept, and the straight
    joint-space moves between its postures (checked at 10 points each, independently of its
    own check) never take the bit into the wall nor more than RETREAT_ALONG_M along it; it
    refuses (None) rather than move otherwise, and without a torso pose."""
    plan = rectangle_plan
    body, sl, arm = plan.body, plan.body.model.limb_slice("right-arm"), plan.body.arms["right-arm"]
    target = TaskTarget(plan)
    assert target.relieve(plan.q_first_rad) is None  # no torso pose measured yet
    rng = np.random.default_rng(seed)
    cut_rows = np.nonzero(plan.cutting)[0]
    given = 0
    for _ in range(40):
        q = plan.q_rad[rng.choice(cut_rows)].copy()
        q[sl] += rng.uniform(-0.25, 0.25, 6)
        lean = np.radians(rng.uniform(-2.0, 2.0, 2))
        target.T_S_N = torso_in_stance(body, q, rpy_to_quat_wxyz(lean[0], lean[1], 0.0))
        path = target.relieve(q)
        if path is None:
            continue
        given += 1
        assert path.shape == (RETREAT_STEPS, 24) and np.all(np.isfinite(path))
        others = np.ones(24, dtype=bool)
        others[sl] = False
        assert np.array_equal(path[:, others], np.repeat(q[None, others], len(path), axis=0))
        T_start = target.T_S_N @ arm.fk(q[sl])
        T_end = target.T_S_N @ arm.fk(path[-1, sl])
        assert np.allclose(T_end[:3, 3] - T_start[:3, 3], [-RETREAT_M, 0.0, 0.0], atol=1e-9)
        assert np.allclose(T_end[:3, :3], T_start[:3, :3], atol=1e-9)
        joints = np.vstack([q[sl], path[:, sl]])
        fine = np.vstack([a + f * (b - a) for a, b in zip(joints[:-1], joints[1:], strict=True)
                          for f in np.linspace(0.0, 1.0, 10)])
        moved = (target.T_S_N @ arm.fk_batch(fine))[:, :3, 3] - T_start[:3, 3]
        assert moved[:, 0].max() <= 1e-4
        assert np.hypot(moved[:, 1], moved[:, 2]).max() <= RETREAT_ALONG_M
    assert given >= 30  # postures near the cut's back out: 40 of 40 for seeds 0-7
    # a path that would move the bit along the wall at all is refused
    monkeypatch.setattr(target_module, "RETREAT_ALONG_M", 1e-9)
    assert target.relieve(q) is None


def test_a_600_mm_rectangle_is_refused_in_preflight_and_nothing_moves(tmp_path, monkeypatch):
    def no_driver(*args, **kwargs):
        raise AssertionError("a driver was created: something could have moved")

    from hubo_cli import session

    monkeypatch.setattr(session, "make_driver", no_driver)
    out = tmp_path / "run"
    # at 40 mm/s: the same misses as at the default 10 mm/s, a quarter of the periods to check
    result = CliRunner().invoke(main, ["task", "cut-rectangle", "--width", "600",
                                       "--speed", "40", "--out", str(out)])
    assert result.exit_code == 4, result.output
    assert "refused in pre-flight, nothing moved" in result.output
    assert "step 3 'cut' (follow)" in result.output and "out of reach by" in result.output
    assert not out.exists()
    as_json = CliRunner().invoke(main, ["task", "cut-rectangle", "--width", "600", "--speed",
                                        "40", "--json"])
    report = json.loads(as_json.output)
    assert as_json.exit_code == 4 and report["refused"] is True
    cut = next(m for m in report["misses"] if m["kind"] == "follow")
    assert 50 < cut["miss_mm"] < 150  # the reach is about 445 mm wide: 600 mm misses by ~78


def test_a_task_too_long_names_its_longest_step_whole():
    """A rectangle at 0.1 mm/s: the cut, four sides of 1,500 and 1,000 s, is 5,000 s (a side
    alone is within the 30 min limit and was the figure named)."""
    with pytest.raises(ConfigError, match=r"step 3 'cut' alone 5,000 s\); the limit is 1800"):
        make_plan(load_task("cut-rectangle", {"speed_mm_s": 0.1}), load_model())


@pytest.mark.parametrize("name", ["push-wall", "turn-valve", "push-door"])
def test_an_experiment_task_records_the_text_it_ran(tmp_path, monkeypatch, name):
    """An experiment's run folder has task.toml as the other tasks' do: the text read once (the
    file edited after it was read does not change it), the --set parameters, the stopper and
    the perturbed robot (--perturb) noted at the top. The procedure itself is replaced by one
    that only makes the folder."""
    from hubo_cli.experiments import manipulation, push_wall
    from hubo_cli.session import RunResult
    from hubo_cli.tasks.runner import run_experiment

    def procedure(model, *args, out, **kwargs):
        out.mkdir()
        return RunResult(out, None, {"files": ["log.csv", "summary.json"]})

    monkeypatch.setattr(push_wall, "run_push_wall", procedure)
    monkeypatch.setattr(manipulation, "run_manipulation", procedure)
    path = tmp_path / f"{name}.toml"
    text = load_task(name).path.read_text(encoding="utf-8")
    path.write_text(text, encoding="utf-8")
    spec = load_task(path, {"turn_deg": 60} if name == "turn-valve" else {})
    path.write_text("edited since", encoding="utf-8")
    done = run_experiment(spec, out=tmp_path / "run", estop=False,
                          perturb_seed=7 if name == "push-door" else None)
    copy = (tmp_path / "run" / "task.toml").read_text(encoding="utf-8")
    assert copy.endswith(text) and "emergency stopper off (--no-estop)" in copy
    assert ("--set turn_deg=60" in copy) == (name == "turn-valve")
    assert ("# perturbed robot and world of this run: --perturb 7" in copy) == \
        (name == "push-door")
    assert "task.toml" in done.summary["files"]
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["files"][-1] == \
        "task.toml"
    again = load_task(tmp_path / "run" / "task.toml", spec.overridden)  # as the header says
    assert again.parameters == spec.parameters and again.experiment == name


def test_too_fast_for_the_legs_is_refused_with_a_hint(tmp_path):
    """A vertical cut the legs cannot follow (the arm alone has only a few cm of height)."""
    text = load_task("cut-slot").path.read_text()
    path = tmp_path / "vertical.toml"
    path.write_text(text.replace("points_mm = [[150.0, 0.0], [-150.0, 0.0]]",
                                 "points_mm = [[0.0, 50.0], [0.0, -50.0]]")
                    .replace("accel_mm_s2 = 100.0", "accel_mm_s2 = 2000.0"))
    result = CliRunner().invoke(main, ["task", "run", str(path), "--set", "speed_mm_s=200"])
    assert result.exit_code == 4
    assert "legs cannot lower or raise the body fast enough" in result.output
    assert "--speed" in result.output


def test_a_cut_faster_than_the_arm_follows_is_refused_with_the_speed_it_follows(tmp_path):
    """cut-slot at 150 mm/s: its arm, within the joints' limits, would lag 52 mm RMS behind
    the path (main ran it: a wrist-torque stop mid-cut); refused in pre-flight (exit 4,
    nothing moved) on one line naming the cut, the speed asked, the lag and the speed the arm
    follows (53 mm/s, measured to pass pre-flight), and the fix."""
    out = tmp_path / "run"
    result = CliRunner().invoke(main, ["task", "cut-slot", "--set", "speed_mm_s=150",
                                       "--out", str(out)])
    assert result.exit_code == 4, result.output
    said = re.search(r"refused in pre-flight, nothing moved: step 3 'cut' \(follow\) at 150 "
                     r"mm/s: the arm, within its joints' limits, would lag (\d+) mm RMS behind "
                     r"the path \(\d+ mm at most; a cut may miss 20\); it follows about (\d+) "
                     r"mm/s", result.output)
    assert said, result.output
    assert 35 < int(said.group(1)) < 80 and 30 < int(said.group(2)) < 80
    assert "hint: cut at " in result.output and "speed_mm_s" in result.output
    assert not out.exists()


# Not marked physical: this run is the same on both code paths to 1e-9 (round 18, AVX-512 /
# portable: every asserted figure within 1.6e-11 relative, the largest difference the torso
# tilt's, 0.26716276609 deg on both; the 5621 logged periods within the log's ten digits), so
# make test-portable would only repeat it (10 s of CPU).
@pytest.mark.slow
def test_a_small_rectangle_is_cut_accurately_with_a_full_run_folder(tmp_path):
    # The cut's accuracy is the point here, so the run goes without the soft e-stop: the
    # capture-point monitor still measures (its margin is in the log) but cannot stop the cut.
    # With it, this run's outcome sits on a knife edge (the monitor stops it while the legs
    # crouch on some CPUs, not on others): that balance outcome is measured, over perturbed
    # robots, by the robustness bench (make bench BENCH=robustness), not asserted here.
    out = tmp_path / "run"
    result = _invoke("cut-rectangle", "--width", "40", "--height", "30", "--no-estop",
                     "--out", str(out), "--json")
    assert result.exit_code == 0, result.output
    s = json.loads(result.stdout)
    assert s["completed"] is True and s["estop"] is None and not s["estop_events"]
    # measured on both code paths (AVX-512 / portable, equal to 1e-12): tilt 0.27 deg (bound
    # 11x), bit RMS 1.61 mm (1.9x), max 4.93 mm (1.5x), horizontal torque mean 0.178 N m (3.6x
    # over 0.05), max while cutting 0.33 N m (3.7x under the limit), support margin 101 mm
    # (3.4x), flutes-in-wall agreement 0.9996
    assert s["max_torso_tilt_deg"] < 3.0  # the robot stays up with a wide margin
    assert np.isfinite(load_log(out)["cp_outside_m"]).mean() > 0.5  # the monitor measured
    assert s["rms_error_mm"] <= 3.0 and s["max_error_mm"] < 7.5
    torque = s["wrist_torque_nm"]
    assert torque["horizontal"]["samples"] and torque["vertical"]["samples"]
    assert 0.05 < torque["horizontal"]["mean"] < torque["limit"]
    assert torque["max_while_cutting"] < torque["limit"] and not torque["over_limit"]
    assert s["max_joint_velocity_ratio"] <= 1.0 + 1e-9
    # the balance figures (hubo_cli/balance_report.py) of the same run
    assert s["balance"] == "default" and s["contact_losses"] == 0
    assert s["min_support_margin_mm"] > 30.0 and 0.0 <= s["ankle_clamp_fraction"] <= 1.0
    assert s["cutting_fraction"] > 0.9 and s["cutting"]["cut_window"] == "plan"
    # the report's flutes-in-the-wall test from the log agrees with the simulator's cutting
    # model (the periods in which it recorded the bit crossing the wall)
    log = load_log(out)
    model = load_model()
    inside = flutes_in_wall(bit_poses(log, model), log.metadata["scene"]["walls"][0],
                            model.drill.bit_half_length_m)
    crossed = np.isin(np.round(log["t_s"], 6), log.metadata["scene"]["hole_t_s"])
    # from the wall's placement on (the raise swings the bit through where it will stand)
    placed = log["phase_code"] > 0
    assert crossed.sum() > 1000 and (inside == crossed)[placed].mean() > 0.95
    for name in ("log.csv", "summary.json", "task.toml", "path.png", "wrist_torque.png",
                 "snapshot.png"):
        assert (out / name).is_file(), name
    assert "--set width_mm=40.0" in (out / "task.toml").read_text()
    assert json.loads((out / "summary.json").read_text())["parameters"]["width_mm"] == 40.0


@pytest.mark.slow
@pytest.mark.parametrize("perturb", [
    # The nominal robot's run is the same on both code paths to 1e-9 (round 18, AVX-512 /
    # portable: the stop's distances within 1.4e-12 mm, its wrist torque 1.22583204 N m and
    # hold 0.31 s on both, every figure of the summary within 1.1e-9 relative): make
    # test-portable runs the perturbed robot's alone, whose paths differ (its sole forces by
    # up to 11 N).
    pytest.param((), id="nominal"),
    pytest.param(("--perturb", "1"), id="perturb-1", marks=pytest.mark.physical)])
def test_cutting_too_fast_trips_the_wrist_torque_stop_which_relieves_the_wrist(tmp_path,
                                                                              perturb,
                                                                              monkeypatch):
    """`hubo task cut-slot --set speed_mm_s=150` (issue 32, case 3): the wrist-torque stop
    latches in the cut, brakes at the emergency limits and backs the bit 5 mm out of the wall,
    then holds. Before: eq. 15's revert under the arms' trajectory limits ran the bit on 53 mm
    along the wall and 12 mm up, loaded the wrist to 1.84 N m and held after 1.85 s.

    Bounds (the issue's) against the spread measured over cut-slot at 100, 150 and 250 mm/s
    (the same latch: it comes while the cut speeds up), at 150 mm/s with --perturb 1, 2, 3 and
    cut-rectangle at 40 and 50 mm/s: wrist torque after the latch 1.19-1.26 N m (at most
    0.05 N m past the 1.21 N m limit; <= 1.33 allows 0.12, 2.4x), bit along the wall after the
    latch 0.7-6.4 mm (<= 10 mm, 1.57x), into the wall 0-0.26 mm (<= 1 mm, 3.8x), out of it
    4.0-7.5 mm (>= 2.5 mm, 1.59x below the least), robot held still 0.31-0.35 s after the
    latch (<= 0.6 s, 1.7x). Nominal: 1.22 N m, 3.5 mm, 0.2 mm, 4.8 mm, 0.31 s; --perturb 1
    (the worst seen, a perturbed robot latching later and faster): 1.26 N m, 6.4 mm, 0.1 mm,
    7.5 mm, 0.35 s."""
    out = tmp_path / "run"
    slow = load_task("cut-slot")
    assert slow.parameters["speed_mm_s"] == 10.0
    # pre-flight refuses this cut since round 19 (the arm would lag 52 mm RMS behind it):
    # the stop is tested on it with that check off
    monkeypatch.setattr("hubo_cli.tasks.cut_lag.LAG_LIMIT_RMS_MM", math.inf)
    result = _invoke("cut-slot", "--set", "speed_mm_s=150", *perturb, "--out", str(out))
    assert result.exit_code == 1, result.output              # ran, but did not complete
    s = json.loads((out / "summary.json").read_text())
    assert s["completed"] is False
    stop = s["estop"]
    assert stop["sources"] == ["wrist-torque"] and stop["step"] == "cut" and stop["held"]
    limit = s["wrist_torque_nm"]["limit"]
    assert stop["wrist_torque_nm"] > limit                   # up to the latch
    assert stop["wrist_torque_after_nm"] <= 1.10 * limit     # after it, reported apart
    assert s["wrist_torque_nm"]["max_after_stop"] == stop["wrist_torque_after_nm"]
    assert stop["bit_along_wall_mm"] <= 10.0 and stop["bit_into_wall_mm"] <= 1.0
    assert stop["bit_out_of_wall_mm"] >= 2.5 and stop["retreat_mm"] == 5.0
    assert stop["held_after_s"] <= 0.6 and stop["reverted_to_t_s"] is None
    assert ("--perturb 1" in (out / "task.toml").read_text()) == bool(perturb)  # to run again
    # the text summary tells the peak after the latch apart from the one while cutting
    assert f"wrist {stop['wrist_torque_after_nm']:.2f} N m max" in result.output
    assert f"bit {stop['bit_along_wall_mm']:.1f} mm along the wall" in result.output
    log = load_log(out)
    model = load_model()
    arm = [log.joint_names.index(n) for n in model.joint_names[model.limb_slice("right-arm")]]
    cmd = log.joints("cmd")[:, arm]
    held = log["t_s"] > stop["t_s"] + 0.6
    assert np.abs(np.diff(cmd[held], axis=0)).max() < 1e-9   # and holding still


def test_an_operator_stop_before_an_interrupt_stays_in_the_summary():
    """Space in the approach walk, then Ctrl-C while it finishes its step: the interrupt's
    stance stop asks the stopper for the operator's stop too, and only that latch is the
    interrupt's. Measured (a 1.2 m approach, space at 2.0 s, SIGINT 0.25 s later): main
    reported ``estop: null``, the operator's latch dropped."""
    from hubo_cli.control.loop import LoopResult
    from hubo_cli.tasks.runner import estop_latches

    key = ("estop", 1.995, "stop", ("operator",))
    events = [key, ("estop", 1.995, "finish", ()),
              ("estop", 3.0, "stop", ("capture-point",))]
    interrupted = LoopResult("interrupted", 600, 3.0, safety_events=events,
                             interrupt_stop="stood", interrupt_stop_s=1.5, interrupt_t_s=2.245)
    assert estop_latches(interrupted) == [key, events[2]]
    # the interrupt's own request of the operator stop, on a stopper that had not latched
    own = LoopResult("interrupted", 600, 3.0, safety_events=[("estop", 2.245, "stop",
                                                              ("operator",))],
                     interrupt_stop="stood", interrupt_stop_s=1.5, interrupt_t_s=2.245)
    assert estop_latches(own) == []
