"""A phase-synchronised tracker never swings a joint that has (almost) nothing to do.

Ruckig stretches every joint's profile to the slowest joint's duration; a knee 5e-12 rad from
its target, with 1e-10 rad/s left over, stretched to an arm's 35 ms, swung 3.9 mrad out and
back (the leg's 15000 rad/s^3 allows it). That happened in a task after a walk, in the period
the arm began its cut, and the jolt stopped the cut on the wrist-torque source. The bound the
tests hold a joint to is independent of ruckig: beyond the stretch between its position and
its target a joint may go no farther than it takes to stop from its velocity and acceleration
under its own limits (``stopping_distance_bound_rad``, plus 10 urad)."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.motion.limits import JointLimits
from hubo_cli.motion.tracker import JointTracker, stopping_distance_bound_rad

DT = 0.005


def _swing(tracker, q0, v0, a0, target, periods=60):
    """How far each joint's samples leave the stretch between q0 and target (rad)."""
    tracker.reset(q0, v0, a0)
    q = np.array([tracker.track(target).copy() for _ in range(periods)])
    low, high = np.minimum(q0, target), np.maximum(q0, target)
    return np.maximum(low - q.min(axis=0), q.max(axis=0) - high).clip(0.0)


@pytest.fixture(scope="module")
def arm_and_knee(walking_model):
    """An arm joint and a knee of the walking limit set (1 rad/s, 0.8 rad/s^2, 4 rad/s^3 and
    2.6 rad/s, 150 rad/s^2, 15000 rad/s^3)."""
    knee = walking_model.joint_names.index("RKN")
    return JointLimits.from_model(walking_model).subset(np.array([0, knee]))


def test_the_knee_that_swung_in_the_cut_stays_put(arm_and_knee):
    """The state of the cut's period (rounded): the arm starts a 13 urad move, the knee is
    5e-12 rad from its target with -1.2e-10 rad/s. Before, the knee swung 9.5 mrad."""
    tracker = JointTracker(arm_and_knee, DT)
    swing = _swing(tracker, np.zeros(2), np.array([0.0, -1.2e-10]), np.zeros(2),
                   np.array([1.31e-5, 4.7e-12]))
    assert swing[1] < 1e-9


@pytest.mark.parametrize("seed", range(4))
def test_a_joint_with_little_to_do_goes_no_farther_than_its_stop(arm_and_knee, walking_model,
                                                                   seed):
    """Random states in and around the regime ruckig swings in: one joint with 1e-14 to 1e-4
    rad to go and a little velocity and acceleration left over, the other with 1e-8 to 1 rad to
    go; arm and knee limits both ways round (an arm's tiny move against a knee's, an arm's
    against an arm's, ...). Every joint stays within its stopping distance of the stretch."""
    rng = np.random.default_rng(seed)
    limits = JointLimits.from_model(walking_model)
    knee = walking_model.joint_names.index("RKN")
    pairs = [np.array(p) for p in ([0, knee], [knee, 0], [0, 1], [knee, knee + 6])]
    worst = 0.0
    for k in range(150):
        sub = limits.subset(pairs[k % 4])
        amax, jmax = sub.acceleration_rad_s2, sub.jerk_rad_s3
        sign = rng.choice([-1.0, 0.0, 1.0], (3, 2))
        target = np.array([10 ** rng.uniform(-8, 0), 10 ** rng.uniform(-14, -4)]) * sign[0]
        v0 = np.array([0.0, 10 ** rng.uniform(-14, -4)]) * sign[1]
        a0 = np.array([0.0, 10 ** rng.uniform(-12, -2)]) * sign[2] * amax
        swing = _swing(JointTracker(sub, DT), np.zeros(2), v0, a0, target,
                       periods=int(rng.integers(20, 120)))
        excess = swing - stopping_distance_bound_rad(v0, a0, amax, jmax)
        worst = max(worst, float(excess.max()))
    assert worst < 1e-5
