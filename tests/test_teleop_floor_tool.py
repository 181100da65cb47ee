"""tools/teleop_lag_floor.py's speed floor on goals whose answer is known, and the generated
streams' turn-rate cap against the joint speeds it asks at the ready pose (the tool's --rates)."""

from __future__ import annotations

import numpy as np
from tool_support import load_tool

from hubo_cli.input.operator_stream import MAX_TURN_RATE_DEG_S
from hubo_cli.kinematics import get_limb
from hubo_cli.model import load_model
from hubo_cli.teleop.session import FREE_READY_ARM_RAD


def test_the_speed_floor_is_zero_within_the_limit_and_grows_with_the_speed_beyond_it():
    """The elbow of the ready pose swept at 0.5, 2 and 3 times the speed limit for 1 s: no
    floor within the limit; beyond it the floor's position error grows with the excess (the
    other joints take up part of it, and the Jacobian changes along the sweep: measured 5.7
    and 13.3 mm, a ratio of 2.3 for an excess twice as large)."""
    tool = load_tool("teleop_lag_floor")
    limb = get_limb("right-arm", "hand")
    vmax = np.full(6, 1.0)
    t = np.arange(0.0, 1.0, 0.005)
    floors = []
    for share in (0.5, 2.0, 3.0):
        q = np.tile(np.array(FREE_READY_ARM_RAD["right-arm"], dtype=float), (len(t), 1))
        q[:, 3] += 0.2 * share * (t - 0.5)  # an elbow sweep of 0.2 share rad/s, about the pose
        pos, rot = tool.speed_floor_errors(t, q, np.ones(len(t), bool), 0.2 * vmax, 3.0, 0.025,
                                           limb, 10e-3 / np.radians(3.0))
        floors.append(np.sqrt(np.nanmean(pos**2)))
    assert floors[0] < 1e-9
    assert floors[1] > 1e-4
    assert floors[2] > 1.5 * floors[1]


def test_the_generated_turn_rate_is_what_the_arm_joints_follow_about_the_median_axis():
    """At the free-mode ready pose a turn of the hand with its position held asks the fastest
    arm joint for 1.43 rad/s per rad/s about the median axis: at the joints' 1.0 rad/s, 40.06
    deg/s. The generator's cap must not ask more (geometry, no simulation: the same on every
    CPU)."""
    model = load_model(limits="teleop")
    for arm in ("right-arm", "left-arm"):
        need = load_tool("teleop_lag_floor").joint_speed_per_rate(arm)["turn"]
        vmax = float(model.limb(arm).velocity_rad_s.min())
        assert MAX_TURN_RATE_DEG_S <= np.degrees(vmax / np.median(need))


def test_the_error_sources_add_up_on_a_generated_stream():
    """tools/teleop_error_sources.py on one short stream of the test's draw (about 1 s of CPU):
    per hand the target is within the reachable tolerance of the goal (what "reachable" means,
    so a frame or lift wrong in the tool shows), its rotation is the filter's where nothing
    else relaxes it, and the shares are shares."""
    from hubo_cli.input.operator_stream import StreamSettings
    from hubo_cli.teleop.stream_runs import GENERATED_SEEDS
    from hubo_cli.teleop.target import REACHABLE_POSITION_M, REACHABLE_ROTATION_RAD

    tool = load_tool("teleop_error_sources")
    seed = GENERATED_SEEDS[0]
    hands = tool.error_sources(seed, StreamSettings(duration_s=1.5, max_speed_m_s=0.25))
    assert set(hands) == {"right-arm", "left-arm"}
    for f in hands.values():
        assert f["target_position_mm"] <= 1e3 * REACHABLE_POSITION_M
        assert abs(f["target_rotation_deg"] - f["filter_rotation_deg"]) <= np.degrees(
            REACHABLE_ROTATION_RAD)
        assert f["tracking_position_mm"] > 0.0 and f["filter_rotation_deg"] > 0.0
        for share in ("reachable_share", "room_share", "limit_share",
                      "at_acceleration_limit_share"):
            assert 0.0 <= f[share] <= 1.0


def test_the_causal_return_floor_keeps_the_elbow_able_to_stop_within_the_lead():
    """tools/reach_return_bound.py's causal floor on a made-up elbow (the bend falls by 20 rad
    per m out to the reach 50 mm ahead; the goal comes back at 45 mm/s, 0.9 rad/s of bend,
    and stops at 1 rad): knowing the goal's future within the 10 mm lead the elbow arrives at
    re-entry at the lead's 0.2 rad bend at 0.54 rad/s and stays within 2 mm 1.20 s after;
    able to stop within the lead until re-entry (bend + speed^2 / 2 accel within 0.2 rad, to
    the tangents' 0.05 rad/s steps) it is there slower and stays within 2 mm 0.20 s later
    (measured on a 0.1 s grid; linear programs, no simulation, about 0.5 s)."""
    tool = load_tool("reach_return_bound")
    t_s = np.arange(0.0, 3.0, 0.001)
    goal_m = np.maximum(0.05 + 0.045 * (1.0 - t_s), 0.0)
    ahead_m = np.linspace(0.0, 0.05, 501)
    bend = 1.0 - 20.0 * ahead_m
    args = (t_s, goal_m, ahead_m, bend, 1.0, 0.0, 1.0, 0.8)
    t_led, bend_led, speed_led = tool._perfect_meet_s(*args, step_s=0.1, lead_m=0.01)
    t_causal, bend_in, speed_in = tool._perfect_meet_s(*args, step_s=0.1, lead_m=0.01,
                                                       stoppable=True)
    assert bend_led + speed_led**2 / (2 * 0.8) > 0.3      # the non-causal way could not stop
    assert bend_in + speed_in**2 / (2 * 0.8) <= 0.2 + 0.025**2 / (2 * 0.8) + 1e-6
    assert t_causal > t_led + 0.1, (t_led, t_causal)      # measured 0.20 s later


def test_the_receding_horizon_family_rests_on_a_resting_goal_and_predicts_a_steady_sweep():
    """The causal family (``--causal``) on goals whose answer is known: on a goal at rest the
    hand stays on it; on an elbow sweep at a steady 0.1 rad/s from rest at the ready pose (the
    joint must catch up within its 0.8 rad/s^2) the member that extrapolates the goal's line
    ends on it and beats the one that holds the goal where it is (measured over the second
    half: 0.27 mm, the one period of delay, against 2.2 mm RMS; asserted: below 0.5 mm and
    above 1.5 mm)."""
    tool = load_tool("teleop_lag_floor")
    limb = get_limb("right-arm", "hand")
    t = np.arange(0.0, 0.6, 0.005)
    q = np.tile(np.array(FREE_READY_ARM_RAD["right-arm"], dtype=float), (len(t), 1))
    w = 10e-3 / np.radians(3.0)
    pos, rot = tool.receding_horizon_errors(t[:40], q[:40], limb, 0.8, 1.0, w,
                                            ("hold", 0.0, 0.0))
    assert np.max(pos) < 1e-9 and np.max(rot) < 1e-9
    q[:, 3] += 0.1 * t
    late = t >= 0.3
    rms = {}
    for member in (("hold", 0.0, 0.0), ("velocity", 0.1, 0.1)):
        pos, _ = tool.receding_horizon_errors(t, q, limb, 0.8, 1.0, w, member)
        rms[member[0]] = float(np.sqrt(np.mean(pos[late]**2)))
    assert rms["velocity"] < 0.5e-3 < 1.5e-3 < rms["hold"], rms
