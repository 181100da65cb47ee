"""tools/teleop_lag_floor.py's speed floor on goals whose answer is known, and the generated
streams' turn-rate cap against the joint speeds it asks at the ready pose (the tool's --rates)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from hubo_cli.input.operator_stream import MAX_TURN_RATE_DEG_S
from hubo_cli.kinematics import get_limb
from hubo_cli.model import load_model
from hubo_cli.teleop.session import FREE_READY_ARM_RAD

TOOL = Path(__file__).resolve().parent.parent / "tools" / "teleop_lag_floor.py"


def _tool():
    spec = importlib.util.spec_from_file_location("teleop_lag_floor", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_speed_floor_is_zero_within_the_limit_and_grows_with_the_speed_beyond_it():
    """The elbow of the ready pose swept at 0.5, 2 and 3 times the speed limit for 1 s: no
    floor within the limit; beyond it the floor's position error grows with the excess (the
    other joints take up part of it, and the Jacobian changes along the sweep: measured 5.7
    and 13.3 mm, a ratio of 2.3 for an excess twice as large)."""
    tool = _tool()
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
        need = _tool().joint_speed_per_rate(arm)["turn"]
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

    spec = importlib.util.spec_from_file_location(
        "teleop_error_sources", TOOL.parent / "teleop_error_sources.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
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
