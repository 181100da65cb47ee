"""Property tests of the default pipeline: whatever the targets, the commands stay safe."""

from __future__ import annotations

import numpy as np
import pytest
from control_support import assert_within_braking_limits, assert_within_limits, ideal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import DEFAULT_ORDER, build_pipeline, find_module
from hubo_cli.control.status import Status
from hubo_cli.errors import ConfigError
from hubo_cli.posture import home_posture

# One event = (kind, joint, value, periods). Kinds:
#   set      target[joint] = home + value (value up to +-6 rad: far outside some limits)
#   scatter  every joint uniform in [lower - 1, upper + 1] (seeded by joint*value)
#   nan      this joint NaN (the others keep the current target)
#   inf      this joint +-inf
#   all-nan  the whole vector NaN
#   gap      no target at all (None)
KINDS = ("set", "scatter", "nan", "inf", "all-nan", "gap")
EVENT = st.tuples(st.sampled_from(KINDS), st.integers(0, 23),
                  st.floats(-6.0, 6.0, allow_nan=False), st.integers(1, 60))


class EventTargets:
    """Plays a list of events as a target source."""

    def __init__(self, model, events) -> None:
        self.model = model
        self.current = home_posture(model)
        self.schedule = []
        for kind, joint, value, periods in events:
            self.schedule += [(kind, joint, value)] * periods
        self.schedule += [("hold", 0, 0.0)] * 20

    def __call__(self, t_s, state):
        k = int(round(t_s / self.model.control_period_s))
        if k >= len(self.schedule):
            return self.current, {"done": True}
        kind, joint, value = self.schedule[k]
        target = self.current.copy()
        if kind == "set":
            self.current[joint] = home_posture(self.model)[joint] + value
            target = self.current.copy()
        elif kind == "scatter":
            rng = np.random.default_rng(abs(int(joint * 1000 + value * 100)))
            self.current = rng.uniform(self.model.lower_rad - 1, self.model.upper_rad + 1)
            target = self.current.copy()
        elif kind == "nan":
            target[joint] = np.nan
        elif kind == "inf":
            target[joint] = np.inf if value >= 0 else -np.inf
        elif kind == "all-nan":
            target[:] = np.nan
        elif kind == "gap":
            return None, {}
        return target, {}


def _run(model, events, interpolator="otg"):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    modules = build_pipeline(model, interpolator=interpolator)
    result = ControlLoop(robot, modules, EventTargets(model, events)).run(duration_s=10.0)
    return robot, q0, result


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(events=st.lists(EVENT, min_size=1, max_size=7))
def test_default_pipeline_commands_are_finite_and_within_limits(model, events):
    robot, q0, result = _run(model, events)
    assert result.ended in ("done", "finished"), result.error
    # a gap stops on stale input: the revert brakes at the emergency limits
    assert_within_braking_limits(model, robot.commands(q0), model.control_period_s)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(events=st.lists(EVENT, min_size=1, max_size=5))
def test_hoff_arbib_pipeline_commands_are_within_limits(model, events):
    robot, q0, result = _run(model, events, interpolator="hoff-arbib")
    assert result.ended in ("done", "finished"), result.error
    # a gap stops on stale input: the revert brakes at the emergency limits
    assert_within_braking_limits(model, robot.commands(q0), model.control_period_s)


def test_hostile_burst_is_smoothed(model):
    """A fixed nasty stream: a huge jump, NaN, inf, a gap, an out-of-limit target, then every
    joint scattered beyond its limits. Smoothed at the normal limits until the scattered legs
    lift a foot with the centre of mass beyond the other sole (the ideal driver's ankles feel
    it): the capture-point stop then reverts, at the emergency braking limits."""
    events = [("set", 0, 5.0, 40), ("nan", 3, 0.0, 10), ("inf", 1, -1.0, 10),
              ("gap", 0, 0.0, 30), ("set", 9, -6.0, 60), ("scatter", 7, 1.5, 60)]
    robot, q0, result = _run(model, events)
    commands = robot.commands(q0)
    dt = model.control_period_s
    stops = [(t_s, sources) for kind, t_s, mode, sources in result.safety_events
             if kind == "estop" and mode == "stop"]
    assert [sources for _, sources in stops] == [("capture-point",)]
    assert stops[0][0] > (40 + 10 + 10 + 30 + 60) * dt  # in the scatter
    assert_within_limits(model, commands[:int(round(stops[0][0] / dt)) + 1], dt)
    assert_within_braking_limits(model, commands, dt)
    assert result.status_counts.get(Status.JOINT_LIMIT.label, 0) > 0


def test_hostile_burst_never_trips_the_hardware_servo_off(model, tmp_path):
    """The hubo-ach driver (dry run: echo source) latches servo-off on any too-fast reference."""
    from hubo_cli.drivers.registry import make_driver

    driver = make_driver("hardware", model, armed=True, sink="file",
                         sink_path=tmp_path / "hubo-ref.bin")
    driver.start()
    events = [("set", 0, 5.0, 40), ("nan", 3, 0.0, 10), ("gap", 0, 0.0, 30),
              ("set", 9, -6.0, 60), ("scatter", 7, 1.5, 60)]
    with driver:
        result = ControlLoop(driver, build_pipeline(model),
                             EventTargets(model, events)).run(duration_s=10.0)
    assert result.ok and Status.SERVO_OFF.label not in result.status_counts
    assert not driver.servo_off


def test_stale_input_stops_smoothly_and_requests_an_estop(model):
    robot = ideal(model)
    q0 = robot.read().q_rad.copy()
    goal = q0.copy()
    goal[0] += 0.6

    def target(t_s, state):
        return (goal if t_s < 0.6 else None), {}

    modules = build_pipeline(model)
    result = ControlLoop(robot, modules, target).run(duration_s=3.0)
    commands = robot.commands(q0)
    # the stop's revert brakes at the emergency limits before it goes back
    assert_within_braking_limits(model, commands, model.control_period_s)
    assert result.status_counts.get(Status.ESTOPPED.label, 0) > 0
    events = find_module(modules, "estop").events
    assert events and events[0].sources == ("stale-input",)
    assert 1.1 - 1e-9 <= events[0].t_s <= 1.2
    v_end = (commands[-1] - commands[-2]) / model.control_period_s
    assert np.max(np.abs(v_end)) < 1e-9


def test_build_pipeline_checks_names(model):
    names = [m.name for m in build_pipeline(model)]
    assert names == list(DEFAULT_ORDER)
    assert [m.name for m in build_pipeline(model, interpolator="hoff-arbib")][0] == "hoff-arbib"
    with pytest.raises(ConfigError, match="end with the limiter"):
        build_pipeline(model, ["limiter", "otg"])
    with pytest.raises(ConfigError, match="unknown pipeline module"):
        build_pipeline(model, ["otg", "warp-drive", "limiter"])
    with pytest.raises(ConfigError, match="twice"):
        build_pipeline(model, ["otg", "estop", "estop", "limiter"])
