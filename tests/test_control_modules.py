"""Unit tests of the single modules: limiter, trajectory generators, collision, capture point."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from control_support import assert_within_limits, ideal

from hubo_cli.control.capture_point import CapturePointMonitor, convex_hull, outside_distance
from hubo_cli.control.collision import SelfCollisionChecker
from hubo_cli.control.hoff_arbib import hoff_arbib_step
from hubo_cli.control.keys import SUPPORT_BOX_WORLD
from hubo_cli.control.limiter import SoftErrorLimiter
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Cycle
from hubo_cli.control.otg import TrajectoryGenerator
from hubo_cli.control.pipeline import build_pipeline, find_module
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.estimation.keys import (
    CAPTURE_POINT_WORLD,
    COM_VELOCITY_WORLD,
    COM_WORLD,
    CONTACT,
    T_WORLD_SOLES,
)
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

DT = 0.005


def _state(model, q=None, **fields):
    q = home_posture(model) if q is None else q
    return RobotState(0.0, q, np.zeros(24), **fields)


# ------------------------------------------------------------------ limiter
def test_limiter_turns_a_jump_into_a_limited_move_without_ringing(model):
    limiter = SoftErrorLimiter(model, DT)
    q0 = home_posture(model)
    limiter.reset(q0, _state(model), Store())
    goal = q0.copy()
    goal[0] += 0.8
    out = np.array([limiter.step(goal) for _ in range(800)])
    assert_within_limits(model, np.vstack([q0, q0, out]), DT)
    assert out[-1, 0] == pytest.approx(goal[0], abs=1e-12)
    assert np.max(out[:, 0]) <= goal[0]            # lands without ringing around the goal


@pytest.mark.parametrize("speed_rad_s", [0.05, 0.2, -0.4])
def test_limiter_catches_a_moving_target_and_lands_on_it(model, speed_rad_s):
    """A ramp starting from rest (its first period a velocity step, clamped): the command
    catches up within the acceleration band, lands on the ramp and follows it exactly, never
    ahead of it, and the flags stop. Before the fix the catch-up braked against the target's
    position now rather than a period ago: the command settled w dt ahead of the ramp (1 mrad
    at 0.2 rad/s), flagged `slowing` every period while it moved (a task's retract: 492
    periods on the shoulder roll)."""
    limiter = SoftErrorLimiter(model, DT, error_limit_rad=0.0)
    limiter.checks.measured = lambda *args: None  # the measured robot stands still for this
    # test of the command's arithmetic: the following checks would end it (test_following.py)
    q0 = home_posture(model)
    limiter.reset(q0, _state(model), Store())
    gaps, flagged = [], []
    for k in range(1, 401):
        want = q0.copy()
        want[0] += speed_rad_s * k * DT
        cycle = Cycle(k * DT, DT)
        out = limiter.update(want, _state(model), cycle)
        gaps.append((out[0] - want[0]) * np.sign(speed_rad_s))
        flagged.append(bool(cycle.flags))
    assert max(gaps) <= 1e-12  # never ahead of the target
    # the fastest catch-up from rest at 0.8 rad/s^2 takes (1 + sqrt 2) |w| / 0.8 s
    landed = int(3 * abs(speed_rad_s) / 0.8 / DT) + 10
    assert not any(flagged[landed:]) and max(abs(g) for g in gaps[landed:]) <= 1e-12


def test_limiter_position_band_only_blocks_moving_further_out(model):
    limiter = SoftErrorLimiter(model, DT, error_limit_rad=0.0)
    upper = model.upper_rad[1]                     # RSR upper limit 0.3
    q_out = home_posture(model)
    q_out[1] = upper + 0.05                        # start outside the limit
    limiter.reset(q_out, _state(model, q_out), Store())
    further = q_out.copy()
    further[1] += 0.2
    assert limiter.step(further)[1] == pytest.approx(q_out[1])  # no further out
    back = q_out.copy()
    back[1] = 0.0
    values = [limiter.step(back)[1] for _ in range(300)]
    assert values[-1] == 0.0 and np.all(np.diff(values) <= 0.0)


def test_a_joint_resting_on_its_limit_is_no_event_but_one_pushed_beyond_it_is(model):
    """The hip yaws and rolls stand at their 0 rad limits; upstream rounding asks up to 7.5e-7
    rad beyond them (measured over a default cut). That is no flag (the status stays ok); a
    wanted command beyond the limit by 50x the rounding tolerance is ``joint-limit``, and the
    command stays on the limit either way."""
    from hubo_cli.control.limiter import POSITION_ROUNDING_RAD

    limiter = SoftErrorLimiter(model, DT)
    q0 = home_posture(model)
    hip = model.joint_names.index("RHY")
    assert q0[hip] == model.upper_rad[hip] == 0.0
    limiter.reset(q0, _state(model), Store())
    rng = np.random.default_rng(7)
    for k in range(300):
        want = q0.copy()
        want[hip] += rng.uniform(0.0, 2.0) * 7.5e-7 if k % 3 else 7.5e-7
        cycle = Cycle(k * DT, DT)
        out = limiter.update(want, _state(model), cycle)
        assert cycle.flags == set() and out[hip] <= model.upper_rad[hip] + 1e-15
    want = q0.copy()
    want[hip] += 50 * POSITION_ROUNDING_RAD
    cycle = Cycle(300 * DT, DT)
    out = limiter.update(want, _state(model), cycle)
    assert "joint-limit" in cycle.flags and out[hip] == pytest.approx(0.0, abs=1e-12)


def test_limiter_tracking_error_band(model):
    limiter = SoftErrorLimiter(model, DT)
    q0 = home_posture(model)
    limiter.reset(q0, _state(model), Store())
    measured = q0.copy()                           # the joint is stuck at q0
    goal = q0.copy()
    goal[0] += 0.5
    for _ in range(600):
        out = limiter.step(goal, measured)
    assert out[0] - q0[0] == pytest.approx(0.18, abs=1e-9)


def test_limiter_holds_nan(model):
    limiter = SoftErrorLimiter(model, DT)
    q0 = home_posture(model)
    limiter.reset(q0, _state(model), Store())
    want = q0.copy()
    want[4] = np.nan
    out = limiter.step(want)
    assert np.all(np.isfinite(out)) and out[4] == q0[4]


# ------------------------------------------------------------------ generators
def test_tracker_never_raises_on_ruckig_errors(model):
    limits = JointLimits.from_model(model)
    bad = dataclasses.replace(limits, jerk_rad_s3=np.zeros(24))  # ruckig rejects zero limits
    tracker = JointTracker(bad, DT)
    q0 = home_posture(model)
    tracker.reset(q0)
    out = tracker.track(q0 + 0.1)
    assert tracker.error and np.all(np.isfinite(out))
    assert np.all(np.isfinite(tracker.brake()))


def test_tracker_synchronization_phase_keeps_a_straight_line_none_does_not(model):
    limits = JointLimits.from_model(model).subset(np.arange(6))  # the right arm
    q0, goal = np.zeros(6), np.array([0.6, 0.0, 0.0, -0.06, 0.0, 0.0])
    paths = {}
    for sync in ("phase", "none"):
        tracker = JointTracker(limits, DT, sync)
        tracker.reset(q0)
        paths[sync] = np.array([tracker.track(goal).copy() for _ in range(600)])
        assert np.allclose(paths[sync][-1], goal, atol=1e-9)
    # phase: the short joint stays in proportion to the long one all the way
    ratio = paths["phase"][:, 3] / paths["phase"][:, 0].clip(1e-9)
    assert np.all(np.abs(ratio[10:] + 0.1) < 1e-3)
    # none: each joint time-optimal, so the short one arrives first (well before the long one)
    arrive = {j: int(np.argmax(np.all(np.abs(paths["none"][:, [j]] - goal[j]) < 1e-6, axis=1)))
              for j in (0, 3)}
    assert arrive[3] < 0.7 * arrive[0]
    with pytest.raises(ConfigError):
        JointTracker(limits, DT, "time")


def test_otg_clamps_targets_and_goes_stale(model):
    otg = TrajectoryGenerator(model, DT, stale_timeout_s=0.1)
    q0 = home_posture(model)
    otg.reset(q0, _state(model), Store())
    far = q0.copy()
    far[1] = 5.0                                   # RSR above its 0.3 rad limit
    cycle = Cycle(0.0, DT)
    otg.update(far, _state(model), cycle)
    assert "joint-limit" in cycle.flags and otg.target[1] == model.upper_rad[1]
    for k in range(1, 40):
        cycle = Cycle(k * DT, DT)
        otg.update(np.full(24, np.nan), _state(model), cycle)
    assert "stale-input" in cycle.flags and "stale-input" in cycle.estop_requests


def test_otg_respects_limits_on_a_step(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    goal = q0.copy()
    goal[:6] += [0.7, -0.5, 0.6, -0.8, 1.0, 0.5]
    modules = build_pipeline(model, ["otg", "limiter"])
    ControlLoop(robot, modules, lambda t, s: (goal, {})).run(duration_s=5.0)
    commands = robot.commands(q0)
    assert_within_limits(model, commands, DT)
    assert np.abs(commands[-1] - goal).max() < 1e-9
    # the generator alone already keeps to the limits: the limiter never had to clamp
    assert find_module(modules, "limiter").clamped_periods == 0


def test_hoff_arbib_min_jerk_oracle():
    """0 -> 1 in 1 s from rest: peak velocity 1.875, peak acceleration 5.7735 (hrpsys)."""
    x, v, a = np.zeros(1), np.zeros(1), np.zeros(1)
    dt, xs, vs, accs = 0.001, [], [], []
    for k in range(1000):
        x, v, a = hoff_arbib_step(x, v, a, np.ones(1), 1.0 - k * dt, dt)
        xs.append(x[0])
        vs.append(v[0])
        accs.append(a[0])
    assert xs[-1] == pytest.approx(1.0, abs=1e-6)
    assert max(vs) == pytest.approx(1.875, rel=1e-3)
    assert max(np.abs(accs)) == pytest.approx(5.7735, rel=2e-3)


# ------------------------------------------------------------------ collision
def test_collision_checker_distances(model):
    checker = SelfCollisionChecker(model)
    q0 = home_posture(model)
    assert checker.check(q0).distance_m > 0.01
    q = q0.copy()
    q[1] = 0.3                                     # right arm rolled in: forearm meets pelvis
    clearance = checker.check(q)
    assert clearance.distance_m < 0 and "RWY_link_0" in clearance.pair
    with_drill = SelfCollisionChecker(model, drill=True)
    assert len(with_drill.pair_names) > len(checker.pair_names)
    assert with_drill.check(q0).distance_m > 0.01


def test_collision_checker_remembers_the_pairs_the_legs_do_not_move(model):
    """The pairs the legs do not move are computed again only when the arms move: a sequence
    with the legs moving and the arms now creeping by nanoradians, now jumping, gives each
    posture's closest pair as a checker that sees it alone does (to coal's GJK tolerance),
    thighs included."""
    from hubo_cli.model import LEGS

    rng = np.random.default_rng(5)
    legs = np.zeros(len(model.joint_names), dtype=bool)
    for name in LEGS:
        legs[model.limb_slice(name)] = True
    checker = SelfCollisionChecker(model)
    base = home_posture(model)
    base[:6] = 0.19, -0.03, 0.95, -0.01, -0.96, -0.06  # the right hand near the right thigh
    base[12:15] = -0.66, -0.59, 0.16                   # lifted forward and out
    pairs = set()
    for k in range(120):
        if k % 30 == 29:  # the arms move now and then, otherwise creep by rounding's order
            base = np.where(legs, base, base + rng.normal(0.0, 0.03, base.size))
        base = np.where(legs, base, base + 2e-9)
        q = np.clip(base + legs * rng.normal(0.0, 0.05, base.size), model.lower_rad,
                    model.upper_rad)
        seen = checker.check(q)
        alone = SelfCollisionChecker(model).check(q)
        assert seen.pair == alone.pair
        assert seen.distance_m == pytest.approx(alone.distance_m, abs=1e-6)
        pairs.add(seen.pair)
    thigh = {pair for pair in pairs if "HP_link" in pair[0] + pair[1]}
    assert thigh and pairs - thigh  # now a thigh's pair was the closest, now another


def test_collision_detector_holds_then_recovers(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    inward = q0.copy()
    inward[1] = 0.3                                # collides (see above)
    modules = build_pipeline(model, ["otg", "collision", "limiter"])
    collision = find_module(modules, "collision")

    def target(t_s, state):
        return (inward if t_s < 3.0 else q0), {}

    result = ControlLoop(robot, modules, target).run(duration_s=8.0)
    commands = robot.commands(q0)
    assert_within_limits(model, commands, DT)
    checker = SelfCollisionChecker(model)
    assert min(checker.check(q).distance_m for q in commands[::5]) > 0.0
    assert result.status_counts.get("collision", 0) > 0
    assert collision.events and collision.events[0].kind == "collision"
    assert collision.mode == "safe"
    assert np.abs(commands[-1] - q0).max() < 1e-6
    assert find_module(modules, "limiter").clamped_periods == 0  # hold/recover within limits


# ------------------------------------------------------------------ capture point
def test_hull_and_outside_distance():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float)
    hull = convex_hull(square)
    assert len(hull) == 4
    assert outside_distance(hull, np.array([0.5, 0.5])) == pytest.approx(-0.5)
    assert outside_distance(hull, np.array([1.2, 0.5])) == pytest.approx(0.2)


def _estimate(model, q, T_world_torso=None, contact=(True, True), cp_xy=None,
              velocity=(0.0, 0.0, 0.0)) -> Store:
    """A store holding what the estimation layer would write for joints ``q`` and a torso pose
    (pinocchio on the URDF; default upright with the soles on the floor): the CoM, its
    velocity, the capture point (default: under the CoM), the contact and the soles."""
    import pinocchio as pin

    from hubo_cli.pin_robot import load_pin_robot

    robot = load_pin_robot(model, floating=True)
    data = robot.model.createData()
    T = np.eye(4) if T_world_torso is None else T_world_torso
    pose = robot.configuration(q, T)
    com = pin.centerOfMass(robot.model, data, pose, False).copy()
    soles = np.array([pin.updateFramePlacement(robot.model, data, robot.frame_id(f)).homogeneous
                      for f in ("right_sole", "left_sole")])
    if T_world_torso is None:  # stand the soles on the floor
        lift = -soles[:, 2, 3].min()
        com[2] += lift
        soles[:, 2, 3] += lift
    store = Store()
    store[COM_WORLD] = com
    store[COM_VELOCITY_WORLD] = np.asarray(velocity, dtype=float)
    store[CAPTURE_POINT_WORLD] = com[:2].copy() if cp_xy is None else np.asarray(cp_xy, float)
    store[CONTACT] = contact
    store[T_WORLD_SOLES] = soles
    return store


def test_capture_point_standing_still_is_inside(model):
    monitor = CapturePointMonitor(model, DT)
    state = _state(model)
    store = _estimate(model, state.q_rad)
    monitor.reset(state.q_rad, state, store)
    cycle = Cycle(0.0, DT, store=store)
    monitor.update(state.q_rad, state, cycle)
    assert not monitor.flag and monitor.outside_m < -0.03
    box = monitor.support_box_m
    assert box[0] < monitor.cp_m[0] < box[1] and box[2] < monitor.cp_m[1] < box[3]
    assert monitor.com_m[2] - monitor.ground_z_m > 0.4   # well above the soles
    assert np.array_equal(store[SUPPORT_BOX_WORLD], box)  # published for the hip strategy
    status = monitor.status()
    assert status.feet_loaded == (True, True) and status.margin_m > 0.06


def test_capture_point_flags_a_capture_point_moving_out_behind_the_heels(model):
    """The estimate's capture point backing out of the soles at 0.5 m/s: the flag comes on
    the confirm_periods-th period beyond the shrunk rear edge, not before, and the e-stop
    request with it."""
    monitor = CapturePointMonitor(model, DT)
    q = home_posture(model)
    store = _estimate(model, q)
    monitor.reset(q, _state(model), store)
    cp0 = store[CAPTURE_POINT_WORLD].copy()
    outside = 0
    for k in range(200):
        store[CAPTURE_POINT_WORLD] = cp0 - (0.5 * k * DT, 0.0)
        cycle = Cycle(k * DT, DT, store=store)
        monitor.update(q, _state(model), cycle)
        outside = outside + 1 if monitor.outside_m > 0 else 0
        assert ("capture-point" in cycle.estop_requests) is (outside >= monitor.confirm_periods)
        if outside >= monitor.confirm_periods:
            break
    assert outside == monitor.confirm_periods
    assert monitor.cp_m[0] < monitor.support_box_m[0]


def test_capture_point_ignores_a_robot_in_the_air(model):
    monitor = CapturePointMonitor(model, DT)
    q = home_posture(model)
    store = _estimate(model, q, contact=(False, False), cp_xy=(5.0, 5.0))
    cycle = Cycle(0.0, DT, store=store)
    monitor.update(q, _state(model), cycle)
    assert not cycle.estop_requests and not monitor.flag


def test_capture_point_reference_matches_a_still_robot(model):
    monitor = CapturePointMonitor(model, DT)
    q = home_posture(model)
    store = _estimate(model, q)
    monitor.reset(q, _state(model), store)
    cycle = Cycle(0.0, DT, store=store)
    monitor.update(q, _state(model), cycle)
    assert abs(cycle.info["cp_error_x_m"]) < 1e-9 and abs(cycle.info["cp_error_y_m"]) < 1e-9


def _pitched(angle_rad):
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    T = np.eye(4)
    T[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    return T


def test_capture_point_flags_feet_tipping_on_their_heels(model):
    """A robot rocking back on its heels is caught although its CoM is still over the soles."""
    q = home_posture(model)
    for angle_deg, expected in ((0.5, False), (3.0, True)):
        monitor = CapturePointMonitor(model, DT)
        store = _estimate(model, q, _pitched(np.radians(-angle_deg)))
        monitor.reset(q, _state(model), store)
        for k in range(monitor.confirm_periods):
            assert not monitor.flag
            monitor.update(q, _state(model), Cycle(k * DT, DT, store=store))
        assert monitor.flag is expected, angle_deg


def test_capture_point_ignores_a_one_period_outlier(model):
    """One period of tipped soles (a measurement outlier) is not a fall; three are."""
    q = home_posture(model)
    monitor = CapturePointMonitor(model, DT)
    upright = _estimate(model, q, np.eye(4))
    tipped = _estimate(model, q, _pitched(np.radians(-3.0)))
    monitor.reset(q, _state(model), upright)
    for k, store in enumerate([upright, tipped, upright, tipped, tipped, tipped]):
        cycle = Cycle(k * DT, DT, store=store)
        monitor.update(q, _state(model), cycle)
        assert ("capture-point" in cycle.estop_requests) is (k == 5), k


def test_capture_point_judges_the_feet_the_estimate_has_in_contact(model):
    """The support is the soles in contact as the estimate says (its one filter and
    debounce): with the left foot out of contact the capture point between the feet lies
    outside the right sole, and the monitor counts the contact loss (after 20 ms)."""
    monitor = CapturePointMonitor(model, DT)
    q = home_posture(model)
    both = _estimate(model, q)
    monitor.reset(q, _state(model), both)
    for k in range(10):
        monitor.update(q, _state(model), Cycle(k * DT, DT, store=both))
    assert not monitor.flag and monitor.status().contact_losses == 0
    right_only = _estimate(model, q, contact=(True, False))
    for k in range(10, 20):
        monitor.update(q, _state(model), Cycle(k * DT, DT, store=right_only))
    assert monitor.flag and monitor.status().feet_loaded == (True, False)
    assert monitor.status().contact_losses == 1


COMPILE_CHECK = """
import json
import sys
from pathlib import Path
from hubo_cli.control import balance, capture_point, collision, limiter
from hubo_cli.motion import limits
from hubo_cli.experiments.standing import stand
from hubo_cli.model import load_model

kernels = (capture_point._support, balance._balance_step,
           balance.command_configuration, limiter.limit_step, limits._braking_distance)
model = load_model()
capture_point.CapturePointMonitor(model, 0.005)
balance.DampingBalancer(model)
limiter.SoftErrorLimiter(model, 0.005)
collision.CollisionDetector(model, 0.005)
built = [len(k.signatures) for k in kernels]
stand(model, 0.1, out=Path(sys.argv[1]))
print(json.dumps({"built": built, "after": [len(k.signatures) for k in kernels]}))
"""


def test_the_pipelines_kernels_compile_when_the_modules_are_built(tmp_path):
    """numba compiles a kernel on its first call with new argument types; building the modules
    makes that call with a run's types, so no control period compiles (that takes seconds on a
    fresh install, and a live run would hold its first command that long). In a fresh process:
    every kernel is compiled once the modules exist, and a standing run adds no signature."""
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", COMPILE_CHECK, str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert all(n >= 1 for n in counts["built"]), counts
    assert counts["after"] == counts["built"], counts


def test_ideal_driver_keeps_the_feet_flat_so_a_leaning_posture_stays_supported(model):
    """Ankles pitched 2 deg lean the ideal robot's torso 2 deg over flat feet (its IMU says so),
    so the capture-point monitor sees flat soles under the CoM, not soles tipped on an edge."""
    from hubo_cli.drivers.ideal import IdealDriver

    q = home_posture(model)
    for joint in ("RAP", "LAP"):
        q[model.joint_names.index(joint)] += np.radians(2.0)
    robot = IdealDriver(model)
    robot.start(q)
    robot.send(q)
    state = robot.step()
    assert abs(np.degrees(np.hypot(*state.tilt_rad())) - 2.0) < 0.05
    T_world_torso = np.eye(4)
    T_world_torso[:3, :3] = quat_wxyz_to_matrix(state.imu_quat_wxyz)
    store = _estimate(model, q, T_world_torso)  # the torso placed by the ideal IMU's attitude
    monitor = CapturePointMonitor(model, DT)
    monitor.reset(q, state, store)
    monitor.update(q, state, Cycle(0.0, DT, store=store))
    assert not monitor.flag and monitor.outside_m < -0.03
