"""The declared data flow: keys read before they are written, or written twice, are build errors."""

from __future__ import annotations

import numpy as np
import pytest

from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.module import Module
from hubo_cli.dataflow import FlowError, Key, Store, check_flow
from hubo_cli.drivers.registry import make_driver
from hubo_cli.estimation.estimator import Estimator
from hubo_cli.estimation.observer import Observer
from hubo_cli.model import load_model

A = Key("a_m", float, "a test quantity (m)")
B = Key("b_m", float, "another (m)")


class Writes(Observer):
    name, writes = "writes-a", (A,)

    def update(self, state, store):
        store[A] = float(state.time_s)


class Reads(Module):
    name, reads, writes = "reads-a", (A,), (B,)
    seen: list[float]

    def __init__(self):
        self.seen = []

    def update(self, q_rad, state, cycle):
        self.seen.append(cycle.store[A])
        cycle.store[B] = 2 * cycle.store[A]
        return q_rad


def test_a_read_before_any_writer_is_a_build_error():
    with pytest.raises(FlowError, match="reads-a reads a_m, which no earlier stage writes"):
        check_flow([Reads()])
    check_flow([Writes(), Reads()])


def test_two_writers_of_one_key_are_a_build_error():
    with pytest.raises(FlowError, match="a_m is written by both writes-a and writes-a"):
        Estimator([Writes(), Writes()])


def test_an_unwritten_key_cannot_be_read():
    store = Store()
    with pytest.raises(FlowError, match="nothing has written b_m"):
        store[B]
    assert store.get(B, 1.5) == 1.5


def test_the_loop_runs_the_estimator_before_the_modules_and_checks_the_flow():
    model = load_model()
    with make_driver("ideal", model) as driver:
        driver.start()
        with pytest.raises(FlowError):
            ControlLoop(driver, [Reads()], lambda t, s: (None, {}))
        reader = Reads()
        loop = ControlLoop(driver, [reader], lambda t, s: (None, {}),
                           estimator=Estimator([Writes()]))
        result = loop.run(0.05)
    assert result.ok
    # period k sees the estimate of the state after period k - 1's step (period 0: the start)
    assert np.allclose(np.diff(reader.seen), driver.period_s)
    assert loop.store[B] == 2 * reader.seen[-1]


class Follows(Module):
    name, follows = "follows-a", (A,)

    def update(self, q_rad, state, cycle):
        return q_rad


def test_a_followed_key_needs_no_writer_but_one_after_the_follower_is_a_build_error():
    """A phase's key (the planned support) is followed when written and done without
    otherwise; its writer must still come first."""
    check_flow([Follows()])
    check_flow([Writes(), Follows()])
    with pytest.raises(FlowError, match="follows-a follows a_m, which writes-a writes after it"):
        check_flow([Follows(), Writes()])


class Sneaks(Module):
    """Declares nothing, then reads (or writes) a key anyway."""

    name = "sneaks"

    def __init__(self, write: bool) -> None:
        self.write = write

    def update(self, q_rad, state, cycle):
        if self.write:
            cycle.store[B] = 1.0
        else:
            cycle.store.get(A)
        return q_rad


@pytest.mark.parametrize("write", [False, True])
def test_a_stage_that_touches_a_key_it_did_not_declare_stops_the_run(write):
    model = load_model()
    with make_driver("ideal", model) as driver:
        driver.start()
        loop = ControlLoop(driver, [Sneaks(write)], lambda t, s: (None, {}),
                           estimator=Estimator([Writes()]))
        result = loop.run(0.02)
    assert not result.ok and result.ended == "module-error"
    verb, key = ("writes", "b_m") if write else ("reads", "a_m")
    assert f"sneaks {verb} {key}, which it does not declare" in result.error


def test_a_view_reads_only_declared_keys_and_writes_only_written_ones():
    store = Store()
    store[A] = 1.0
    view = store.view(Reads())
    assert view[A] == 1.0 and A in view and view.get(B, 2.0) == 2.0
    view[B] = 3.0
    assert store[B] == 3.0 and view[B] == 3.0  # a stage may read back what it writes
    with pytest.raises(FlowError, match="reads-a writes a_m, which it does not declare"):
        view[A] = 2.0
    follower = store.view(Follows())
    assert follower.get(A) == 1.0
    with pytest.raises(FlowError, match="follows-a reads b_m, which it does not declare"):
        follower[B]
    with pytest.raises(FlowError, match="follows-a asks for b_m"):
        B in follower  # noqa: B015


def test_an_observer_touching_an_undeclared_key_is_refused():
    class Wrong(Observer):
        name, writes = "wrong", (A,)

        def update(self, state, store):
            store[B] = 0.0

    model = load_model()
    with make_driver("ideal", model) as driver:
        driver.start()
        with pytest.raises(FlowError, match="wrong writes b_m"):
            Estimator([Wrong()]).reset(driver.read())


def test_no_target_reaches_into_a_pipeline_module():
    """Targets exchange with the modules only through store keys: none picks a module out of
    the pipeline by its class, asks it for its status or mode, switches it, or sets its
    attributes (the stopper's relief, the impedance controller, otg's trackers)."""
    import ast
    from pathlib import Path

    import hubo_cli
    import hubo_cli.control as control

    for path in Path(control.__file__).parent.glob("*.py"):  # every module class's name
        __import__(f"hubo_cli.control.{path.stem}")
    module_classes = set()
    todo = [Module]
    while todo:
        cls = todo.pop()
        module_classes.add(cls.__name__)
        todo += cls.__subclasses__()
    reaching = {"status", "switch_on", "switch_off", "synchronize", "release", "stop", "reset"}
    root = Path(hubo_cli.__file__).parent
    found = []
    for package in ("tasks", "teleop", "walking", "experiments"):
        for path in sorted((root / package).glob("*.py")):
            tree = ast.parse(path.read_text())
            for node in ast.walk(tree):
                if not isinstance(node, ast.ClassDef):
                    continue
                bases = {getattr(b, "id", getattr(b, "attr", "")) for b in node.bases}
                if not bases & {"Target", "WatchedTarget"}:
                    continue
                for inner in ast.walk(node):
                    where = f"{path.name}:{getattr(inner, 'lineno', 0)}"
                    if (isinstance(inner, ast.Call) and getattr(inner.func, "id", "")
                            == "isinstance" and len(inner.args) == 2
                            and getattr(inner.args[1], "id", "") in module_classes):
                        found.append(f"{where} picks a {inner.args[1].id} by its class")
                    if (isinstance(inner, ast.Attribute) and inner.attr in reaching
                            and isinstance(inner.value, ast.Name)
                            and inner.value.id in {"m", "module", "stopper", "impedance"}):
                        found.append(f"{where} calls {inner.value.id}.{inner.attr}")
    assert {"EmergencyStopper", "ImpedanceController", "TrajectoryGenerator"} <= module_classes
    assert not found, found


def test_nothing_outside_the_control_loop_reads_a_module():
    """What the modules publish reaches a viewer or a use case through the loop's record
    (``module_status``) and the store, never from a module: outside ``control/`` (the loop and
    the modules) and ``bench/`` (which times the modules themselves), no code asks a module
    for its status, picks one out of a pipeline, or keeps the pipeline to read later."""
    import ast
    from pathlib import Path

    import hubo_cli

    root = Path(hubo_cli.__file__).parent
    found = []
    for path in sorted(root.rglob("*.py")):
        part = path.relative_to(root).parts[0]
        if part in ("control", "bench"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            where = f"{path.relative_to(root)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Call):
                name = getattr(node.func, "attr", getattr(node.func, "id", ""))
                if name == "status" and not node.args:
                    found.append(f"{where} asks for a status()")
                if name in ("find_module", "module"):
                    found.append(f"{where} picks a module by name")
            if (isinstance(node, ast.Assign) and any(
                    isinstance(t, ast.Attribute) and t.attr == "modules" for t in node.targets)
                    and path.parts[-2] != "walking"):  # (walking hands its pipeline on)
                found.append(f"{where} keeps the pipeline")
    assert not found, found


def test_a_real_pipeline_without_a_producer_is_refused_when_the_loop_is_built():
    """The impedance controller takes the hand wrench plan from the target when no soft
    stopper reverts it: a target that does not write it is a build error of the loop, before
    the robot moves; with the writer declared, the loop builds."""
    from hubo_cli.control.pipeline import SafetyProfile
    from hubo_cli.control.target import FunctionTarget
    from hubo_cli.control.wrench import HAND_WRENCH_PLAN

    model = load_model()
    profile = SafetyProfile(impedance=True, wrench_reference=True, estop=False)
    with make_driver("ideal", model) as driver:
        driver.start()
        modules = profile.build(model, driver.period_s, {})
        with pytest.raises(FlowError, match="impedance reads hand_wrench_plan"):
            ControlLoop(driver, modules, lambda t, s: (None, {}))
        writer = FunctionTarget(lambda t, s: (None, {}))
        writer.writes = (HAND_WRENCH_PLAN,)
        ControlLoop(driver, modules, writer)
