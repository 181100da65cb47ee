"""The trajectory generator's tracker groups: one tracker per arm and one for the legs keeps
every safety behaviour of the whole-body tracker, and a hand no longer waits for the legs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from control_support import assert_within_braking_limits, assert_within_limits, ideal

from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Cycle
from hubo_cli.control.otg import TrajectoryGenerator, tracker_groups
from hubo_cli.control.pipeline import SafetyProfile, build_pipeline, find_module
from hubo_cli.dataflow import Store
from hubo_cli.errors import ConfigError
from hubo_cli.model import ARMS, LEGS
from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import SYNCHRONIZATIONS, JointTracker
from hubo_cli.posture import home_posture
from hubo_cli.state import RobotState

DT = 0.005


def _state(model):
    return RobotState(0.0, home_posture(model), np.zeros(24))


def _run(otg, model, goal, periods):
    q0 = home_posture(model)
    otg.reset(q0, _state(model), Store())
    return np.array([otg.update(goal, _state(model), Cycle(k * DT, DT)).copy()
                     for k in range(periods)])


def test_limbs_groups_cover_every_joint_once(model):
    groups = tracker_groups(model, "limbs")
    assert list(groups) == [*ARMS, "legs"]
    assert np.array_equal(np.sort(np.concatenate(list(groups.values()))), np.arange(24))
    for arm in ARMS:
        assert [model.joint_names[i] for i in groups[arm]] == list(model.limb(arm).joints)
    assert {model.joint_names[i] for i in groups["legs"]} == {
        j for leg in LEGS for j in model.limb(leg).joints}
    assert len(tracker_groups(model, "body")) == 1
    with pytest.raises(ConfigError):
        tracker_groups(model, "joints")
    with pytest.raises(ConfigError):
        SafetyProfile(tracker_groups="arms")
    with pytest.raises(ConfigError):
        SafetyProfile(tracker_sync="time")


def test_an_arm_does_not_wait_for_the_legs_with_its_own_tracker(model):
    """A small elbow step while a knee makes a long move: the whole-body tracker (phase
    synchronised) stretches the elbow over the knee's time; with one tracker per limb the elbow
    arrives in a fraction of it. The knee arrives when it would alone either way."""
    goal = home_posture(model)
    goal[3] += 0.1                                  # REB (right elbow): 0.1 rad
    knee = model.joint_names.index("RKN")
    goal[knee] += 0.8                               # right knee: 0.8 rad
    arrive = {}
    for groups in ("body", "limbs"):
        otg = TrajectoryGenerator(model, DT, groups=groups)
        out = _run(otg, model, goal, 1200)
        at = {j: int(np.argmax(np.all(np.abs(out[:, [j]] - goal[j]) < 1e-9, axis=1)))
              for j in (3, knee)}
        assert np.abs(out[-1] - goal).max() < 1e-9
        assert_within_limits(model, np.vstack([out[:1], out[:1], out]), DT)
        arrive[groups] = at
    assert arrive["body"][3] == pytest.approx(arrive["body"][knee], abs=2)
    assert arrive["limbs"][3] < 0.5 * arrive["body"][3]
    assert arrive["limbs"][knee] == pytest.approx(arrive["body"][knee], abs=2)


def test_limbs_groups_clamp_hold_and_go_stale(model):
    otg = TrajectoryGenerator(model, DT, stale_timeout_s=0.1, groups="limbs")
    q0 = home_posture(model)
    otg.reset(q0, _state(model), Store())
    far = q0.copy()
    far[1] = 5.0                                    # RSR above its 0.3 rad limit
    cycle = Cycle(0.0, DT)
    moving = [otg.update(far, _state(model), cycle).copy()]
    assert "joint-limit" in cycle.flags and otg.target[1] == model.upper_rad[1]
    some = np.full(24, np.nan)
    some[6] = q0[6] + 0.2                           # the left arm's first joint only
    cycle = Cycle(DT, DT)
    moving.append(otg.update(some, _state(model), cycle).copy())
    assert "holding" in cycle.flags and otg.target[1] == model.upper_rad[1]
    for k in range(2, 300):
        cycle = Cycle(k * DT, DT)
        moving.append(otg.update(np.full(24, np.nan), _state(model), cycle).copy())
    assert "stale-input" in cycle.flags and "stale-input" in cycle.estop_requests
    # stale: every group brakes to rest (no longer toward the target), within the limits
    assert otg.at_rest and np.allclose(moving[-1], moving[-2], atol=1e-12)
    assert moving[-1][1] < model.upper_rad[1] and moving[-1][6] < q0[6] + 0.2
    assert_within_limits(model, np.vstack([q0, q0, moving]), DT)


def test_a_ruckig_error_in_one_group_brakes_every_group(model):
    """The left arm's limits are broken (ruckig rejects a zero jerk): the right arm and the legs,
    moving at the time, brake to rest with it ("slowing"), as the whole-body tracker does."""
    limits = JointLimits.from_model(model)
    jerk = limits.jerk_rad_s3.copy()
    otg = TrajectoryGenerator(model, DT, groups="limbs", limits=limits)
    q0 = home_posture(model)
    otg.reset(q0, _state(model), Store())
    goal = q0.copy()
    goal[0] += 0.5                                  # right shoulder pitch
    goal[model.joint_names.index("RKN")] += 0.3
    out = [q0, q0]
    for k in range(40):                             # both groups get going
        out.append(otg.update(goal, _state(model), Cycle(k * DT, DT)).copy())
    assert not otg.at_rest
    jerk[model.limb_slice("left-arm")] = 0.0
    otg.trackers[1]._inp.max_jerk = jerk[model.limb_slice("left-arm")]
    goal[6] += 0.2                                  # the left arm now has to move: ruckig fails
    flags = []
    for k in range(40, 400):
        cycle = Cycle(k * DT, DT)
        out.append(otg.update(goal, _state(model), cycle).copy())
        flags.append("slowing" in cycle.flags)
        if otg.at_rest:
            break
    assert otg.errors >= 1 and flags[0] and otg.at_rest
    assert abs(out[-1][0] - goal[0]) > 0.05         # stopped short of the right arm's goal
    assert_within_limits(model, np.array(out), DT)


def test_teleop_pipeline_with_limbs_groups_keeps_to_the_limits_and_reverts(model):
    """A pipeline with the generator split into limbs: a step keeps every limit without the
    limiter, and an operator stop still reverts to the command of 0.5 s before and holds."""
    profile = SafetyProfile(tracker_groups="limbs", tracker_sync="none", balance=False)
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    goal = q0.copy()
    goal[:6] += [0.7, -0.5, 0.6, -0.8, 1.0, 0.5]
    goal[6:12] += [0.3, 0.2, -0.2, -0.4, 0.0, 0.0]
    modules = profile.build(model, DT, {"right-arm": "hand", "left-arm": "hand"})
    assert find_module(modules, "otg").groups == "limbs"
    stop_at = 1.0

    def target(t, state):
        return goal, ({"estop": "operator"} if abs(t - stop_at) < DT / 2 else {})

    ControlLoop(robot, modules, target).run(duration_s=8.0)
    commands = robot.commands(q0)
    k_stop = int(round(stop_at / DT)) + 2            # the two rest rows in front
    # the step within the trajectory limits; the stop's revert first brakes to rest at the
    # emergency ones
    assert_within_limits(model, commands[:k_stop], DT)
    assert_within_braking_limits(model, commands, DT)
    assert find_module(modules, "limiter").clamped_periods == 0
    k_back = k_stop - int(round(0.5 / DT))
    near = np.abs(commands[k_back - 3:k_back + 4] - commands[-1]).max(axis=1)
    assert near.min() < 1e-9                        # reverted to a command of 0.5 s before
    assert np.abs(commands[-100:] - commands[-1]).max() < 1e-12   # and holding it
    assert np.abs(commands[-1] - goal).max() > 0.1


def test_whole_body_tracker_is_the_default(model):
    otg = build_pipeline(model, ["otg", "limiter"])[0]
    assert otg.groups == "body" and len(otg.trackers) == 1
    limbs = dataclasses.replace(SafetyProfile(), tracker_groups="limbs")
    assert limbs.options({})["otg"] == {"groups": "limbs", "synchronization": "phase"}


def test_synchronize_unties_the_arms_joints_and_leaves_the_legs_phase_synchronised(model):
    """After ``synchronize("none", groups=ARMS)`` an arm's short joint arrives well before its
    long one, while the legs' joints still arrive together on a straight line."""
    otg = TrajectoryGenerator(model, DT, groups="limbs")
    otg.synchronize("none", groups=ARMS)
    goal = home_posture(model)
    goal[0] += 0.6                                  # RSP, long
    goal[3] -= 0.06                                 # REB, short
    hip, knee = model.joint_names.index("RHP"), model.joint_names.index("RKN")
    goal[hip] -= 0.4
    goal[knee] += 0.8
    out = _run(otg, model, goal, 1200)
    assert np.abs(out[-1] - goal).max() < 1e-9

    def arrival(j):
        return int(np.argmax(np.abs(out[:, j] - goal[j]) < 1e-9))

    assert arrival(3) < 0.7 * arrival(0)
    assert abs(arrival(hip) - arrival(knee)) <= 2
    q0 = home_posture(model)
    ratio = (out[20:, hip] - q0[hip]) / (out[20:, knee] - q0[knee])
    assert np.all(np.abs(ratio + 0.5) < 1e-3)
    with pytest.raises(ConfigError):
        otg.synchronize("time")


def test_preview_shows_the_way_track_takes_and_leaves_the_tracker_as_it_was(model):
    """A tracker's preview toward a target is the path its ``track`` calls then follow (phase:
    a straight joint-space line, none: the short joint arrives first), and previewing changes
    nothing of the tracker: tracking afterwards gives the same samples as without it."""
    otg = TrajectoryGenerator(model, DT, groups="limbs")
    k = otg.group_names.index("right-arm")
    tracker = otg.trackers[k]
    q0 = home_posture(model)[model.limb_slice("right-arm")]
    goal = q0.copy()
    goal[0] += 0.6                                  # RSP, long
    goal[3] -= 0.06                                 # REB, short
    for sync in ("phase", "none"):
        tracker.reset(q0)
        for _ in range(30):                         # under way, not at rest
            tracker.track(q0 + 0.5 * (goal - q0))
        state = (tracker.q.copy(), tracker.v.copy(), tracker.a.copy())
        path = tracker.preview(goal, sync, 9)
        assert path.shape == (9, 6)
        assert np.array_equal(path[0], state[0]) and np.abs(path[-1] - goal).max() < 1e-9
        for before, after in zip(state, (tracker.q, tracker.v, tracker.a), strict=True):
            assert np.array_equal(before, after)
        tracker.set_synchronization(sync)
        tracked = np.array([tracker.track(goal).copy() for _ in range(400)])
        # the previewed points lie on the tracked path (within a period's motion)
        step = np.abs(np.diff(tracked, axis=0)).max()
        for point in path[1:-1]:
            assert np.min(np.abs(tracked - point).max(axis=1)) <= step
        share = (path[1:-1, [0, 3]] - path[0, [0, 3]]) / (goal - path[0])[[0, 3]]
        spread = np.abs(share[:, 0] - share[:, 1]).max()   # RSP's and REB's share of the way
        assert (spread < 0.05) if sync == "phase" else (spread > 0.2), (sync, spread)
    with pytest.raises(ConfigError):
        tracker.preview(goal, "time", 5)


def test_the_preview_is_ruckigs_own_samples_to_the_last_bit(model):
    """The preview's rows are ruckig's ``at_time`` at evenly spaced times of its trajectory
    (the first is the current position: ``at_time(0)``; a position of exactly -0 may come
    out +0 there, the same number), its target velocity clipped as ``track`` clips it: the
    same numbers, on drawn states beyond the limits too, with target velocities that are
    NaN, infinite, beyond the limits or -0."""
    from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

    rng = np.random.default_rng(34)
    limits = JointLimits.from_model(model).subset(np.arange(24)[model.limb_slice("left-arm")])
    tracker = JointTracker(limits, DT)
    otg, inp, trajectory = Ruckig(6), InputParameter(6), Trajectory(6)
    inp.max_velocity, inp.max_acceleration = limits.velocity_rad_s, limits.acceleration_rad_s2
    inp.max_jerk = limits.jerk_rad_s3
    odd = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e308, 3.0, -3.0])
    compared = 0
    for k in range(300):
        q = rng.uniform(limits.lower_rad, limits.upper_rad)
        if k % 10 == 0:
            q[:3] = (0.0, -0.0, 0.0)
        v = rng.normal(0.0, 0.5, 6) * (k % 4 != 0)
        a = rng.normal(0.0, 1.0, 6) * (k % 3 != 0)  # beyond the limit at times: reset clips
        target = q + rng.normal(0.0, 0.3, 6) * (k % 7 != 0)
        v_goal = rng.choice(odd, 6) if k % 5 == 0 else rng.normal(0.0, 0.8, 6)
        sync = ("none", "phase")[k % 2]
        tracker.reset(q, v, a)
        path = tracker.preview(target, sync, 8, None if k % 6 == 0 else v_goal)
        inp.current_position, inp.current_velocity = tracker.q, tracker.v
        inp.current_acceleration, inp.target_position = tracker.a, target
        inp.target_velocity = (np.zeros(6) if k % 6 == 0
                               else tracker._target_velocity(v_goal))  # track's clip
        inp.synchronization = SYNCHRONIZATIONS[sync]
        try:
            result = otg.calculate(inp, trajectory)
        except RuckigError:
            result = None
        if result not in (Result.Working, Result.Finished):
            assert path.shape == (1, 6)
            continue
        expected = np.array([trajectory.at_time(trajectory.duration * i / 7)[0]
                             for i in range(8)])
        assert np.array_equal(path, expected), k
        compared += 1
    assert compared > 250


@pytest.mark.parametrize("seed", range(4))
def test_a_tracker_seeded_beyond_its_acceleration_limit_does_not_run_away(model, seed):
    """A command braked at the emergency limits (8 rad/s^2) seeds a tracker of the arms'
    0.8 rad/s^2 and 4 rad/s^3 (a collision hold or a hard stop in that moment): it starts from
    the acceleration limit, so it stops within the braking distance of that state, where ruckig
    seeded with 6 rad/s^2 kept accelerating for 1.5 s (to 4 rad/s). Random states, both
    signs; the tracker reaches its target, never faster than the seed or the limit."""
    rng = np.random.default_rng(seed)
    limits = JointLimits.from_model(model).subset(np.arange(6))
    tracker = JointTracker(limits, DT)
    v0 = rng.uniform(-0.6, 0.6, 6)
    a0 = rng.choice([-1.0, 1.0], 6) * rng.uniform(2.0, 8.0, 6)
    goal = rng.uniform(-0.02, 0.02, 6)
    tracker.reset(np.zeros(6), v0, a0)
    assert np.all(np.abs(tracker.a) <= limits.acceleration_rad_s2)
    speeds = []
    for _ in range(int(round(6.0 / DT))):
        tracker.track(goal, target_v_rad_s=np.zeros(6))
        speeds.append(np.abs(tracker.v))
    assert tracker.finished and np.allclose(tracker.q, goal, atol=1e-9)
    # from |v0| plus what the clipped acceleration adds while the jerk ramps it down
    amax, jmax = limits.acceleration_rad_s2, limits.jerk_rad_s3
    assert np.all(np.max(speeds, axis=0) <= np.maximum(np.abs(v0) + amax**2 / (2 * jmax),
                                                       limits.velocity_rad_s) + 1e-9)


class _AlwaysRuckig(JointTracker):
    """The tracker without its resting shortcut: ruckig every period."""

    def track(self, target_rad, min_duration_s=None, target_v_rad_s=None):
        self._rest = None
        return super().track(target_rad, min_duration_s, target_v_rad_s)


@pytest.mark.parametrize("seed", range(3))
def test_a_resting_tracker_gives_what_ruckig_gives(model, seed):
    """A tracker at rest on its target does not call ruckig again (the standing robot's every
    period): the samples, velocities and accelerations are ruckig's bit for bit through random
    holds, new targets (some a few ulp away), minimum durations, target velocities, brakes,
    resets and synchronization changes."""
    rng = np.random.default_rng(seed)
    limits = JointLimits.from_model(model).subset(np.arange(6))
    fast, slow = JointTracker(limits, DT), _AlwaysRuckig(limits, DT)
    goal = np.zeros(6)
    skipped = 0
    for k in range(2000):
        event = rng.random()
        if event < 0.004:
            goal = rng.uniform(-0.05, 0.05, 6)
        elif event < 0.006:
            goal = np.nextafter(goal, np.inf)  # a target one ulp away: ruckig again
        kwargs = {}
        if rng.random() < 0.003:
            kwargs["min_duration_s"] = float(rng.uniform(0.0, 0.5))
        if rng.random() < 0.003:
            kwargs["target_v_rad_s"] = np.zeros(6)
        for tracker in (fast, slow):
            if event > 0.998:
                tracker.reset(goal + 0.001)
            elif 0.996 < event <= 0.998:
                tracker.set_synchronization("none" if k % 2 else "phase")
            if 0.994 < event <= 0.996:
                out = tracker.brake()
            else:
                skipped += tracker is fast and fast._rest is not None
                out = tracker.track(goal, **kwargs)
            assert out is tracker.q
        assert fast.q.tolist() == slow.q.tolist(), k
        assert fast.v.tolist() == slow.v.tolist() and fast.a.tolist() == slow.a.tolist(), k
        assert fast.finished == slow.finished and fast.error == slow.error, k
    assert skipped > 200  # the shortcut was taken (measured 376-608 of the 2000 periods)
