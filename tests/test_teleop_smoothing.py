"""The arm target's smoothing before the trajectory generator, and its body clearance."""

import numpy as np
import pytest

from hubo_cli.errors import ConfigError
from hubo_cli.teleop.smoothing import TargetSmoother

DT = 0.005
WIDE = (np.full(2, -10.0), np.full(2, 10.0))


def _filter(signal, smoother, bounds=WIDE):
    smoother.reset(signal[0])
    return np.array([smoother.step(q, *bounds) for q in signal])


def test_a_steady_motion_passes_without_lag():
    """A critically damped alpha-beta filter follows a ramp exactly once settled."""
    t = np.arange(0.0, 3.0, DT)
    ramp = np.column_stack([0.2 * np.maximum(t - 0.5, 0.0), -0.1 * np.maximum(t - 0.5, 0.0)])
    out = _filter(ramp, TargetSmoother(2, DT))
    assert np.max(np.abs(out[t > 2.0] - ramp[t > 2.0])) < 1e-5


def test_tremor_and_sample_steps_are_taken_out():
    """A 9 Hz tremor comes through at less than 40 % of its amplitude, and a target held
    between 60 Hz samples (steps every 3-4 periods) comes out without steps."""
    t = np.arange(0.0, 4.0, DT)
    slow = 0.05 * np.sin(2 * np.pi * 0.3 * t)
    tremor = 0.004 * np.sin(2 * np.pi * 9.0 * t)
    held = np.floor(t * 60.0) / 60.0  # sample-and-hold at 60 Hz
    signal = np.column_stack([np.interp(held, t, slow + tremor), np.interp(held, t, slow)])
    out = _filter(signal, TargetSmoother(2, DT))
    late = t > 1.5
    residual = out[late, 0] - out[late, 1]   # what is left of the tremor
    assert np.max(np.abs(residual)) < 0.4 * 0.004
    steps_in = np.max(np.abs(np.diff(signal[late, 1])))
    steps_out = np.max(np.abs(np.diff(out[late, 1])))
    assert steps_out < 0.5 * steps_in


def test_the_output_stops_at_its_bounds_and_off_passes_through():
    t = np.arange(0.0, 2.0, DT)
    step = np.column_stack([np.where(t > 0.5, 1.0, 0.0), np.zeros_like(t)])
    bounds = (np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    out = _filter(step, TargetSmoother(2, DT), bounds)   # an alpha-beta overshoots a step
    assert np.max(out[:, 0]) <= 1.0 and abs(out[-1, 0] - 1.0) < 1e-3
    off = _filter(step, TargetSmoother(2, DT, bandwidth_rad_s=0.0), bounds)
    assert np.array_equal(off, step)
    with pytest.raises(ConfigError):
        TargetSmoother(2, DT, bandwidth_rad_s=float("nan"))


@pytest.fixture(scope="module")
def body_checker():
    from hubo_cli.control.collision import SelfCollisionChecker
    from hubo_cli.model import load_model

    model = load_model()
    return model, SelfCollisionChecker(model)


def test_an_arm_target_stops_short_of_the_body_and_slides_along_it(body_checker):
    """The right hand swung into the torso (shoulder yaw 1 rad, roll 0.3): the target stops
    with the clearance kept, within a few millimetres of it; a step that is clear passes."""
    from hubo_cli.posture import home_posture
    from hubo_cli.teleop.clearance import BODY_CLEARANCE_M, clear_of_body
    from hubo_cli.teleop.session import FREE_READY_ARM_RAD

    model, checker = body_checker
    q = home_posture(model).copy()
    arm = model.limb_slice("right-arm")
    ready = np.array(FREE_READY_ARM_RAD["right-arm"])
    q[arm] = ready
    assert clear_of_body(checker, q, arm, ready, ready + 0.01) is None
    inside = np.array([0.0, 0.3, 1.0, -1.4, 0.0, 0.0])
    q_in = q.copy()
    q_in[arm] = inside
    assert checker.check(q_in).distance_m < 0          # the goal lies inside the torso
    stop = clear_of_body(checker, q, arm, ready, inside)
    q_stop = q.copy()
    q_stop[arm] = stop
    d = checker.check(q_stop).distance_m
    assert BODY_CLEARANCE_M <= d < BODY_CLEARANCE_M + 0.005, d
    assert np.linalg.norm(stop - ready) > 0.1             # it went part of the way
    # from there, a goal further in holds it where it is or lets it slide, never closer
    again = clear_of_body(checker, q_stop, arm, stop, inside + np.array([0, 0, 0.2, 0, 0, 0]))
    q_again = q.copy()
    q_again[arm] = stop if again is None else again
    assert checker.check(q_again).distance_m >= BODY_CLEARANCE_M - 1e-9
