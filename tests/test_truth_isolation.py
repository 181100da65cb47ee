"""Nothing that acts on the robot reads the simulator's truth (issue 33).

The simulator knows the torso's true pose, the feet's true contact, its draws of the robot's
parameters; a Hubo knows none of these. So that what runs in simulation is what can run on the
robot, every module, target and planner (the packages in SCANNED, and the scene and session
modules) reads the estimate (:mod:`hubo_cli.estimation.keys`) and never:

* ``state.truth`` (:class:`~hubo_cli.state.Truth`, the simulator's ground truth beside the
  sensors), nor the simulator's ``frame_pose`` or its true centre of mass ``com_world_m``;
* any reader of the simulated world (:data:`READERS`: what the simulator driver offers beyond
  the driver contract and :class:`~hubo_cli.scene.SceneActions`, taken from the types);
* a private attribute of another object (``x._p``, ``actions._world``), a name built at run
  time (``getattr(state, "tru" + "th")``), ``importlib`` or ``__import__``;
* pybullet or the simulator driver, directly or through the modules it imports at module
  level (the import graph of hubo_cli), nor a helper of a module outside these packages that
  reads the truth.

By type: a target's ``attach`` takes :class:`~hubo_cli.scene.SceneActions` (actions, no
readers), and the session gives it one, never the driver.

Logs, reports, plots, viewers and the drivers may read the truth: outside SCANNED, or listed
in ALLOWED with the reason and the exact reads allowed. The checker is tested on planted
violations (the independent review's ten misses among them).
"""

from __future__ import annotations

import ast
import inspect
import sys
import typing
from pathlib import Path

import pytest

from hubo_cli.drivers.base import Driver
from hubo_cli.drivers.sim import SimDriver
from hubo_cli.scene import SceneActions

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hubo_cli"
SCANNED = ("control", "estimation", "walking", "tasks", "teleop", "kinematics", "experiments",
           "motion", "input")
SCANNED_FILES = ("scene.py", "session.py")
# attributes that are the simulator's truth on whatever object they are read
TRUTH_ATTRIBUTES = {"truth", "frame_pose", "com_world_m"}


def _public(cls) -> set[str]:
    return {n for n in dir(cls) if not n.startswith("_")}


# the simulated world's readers: what the simulator offers beyond the driver contract and the
# actions a target gets (by type, so a reader added to the simulator is forbidden at once)
READERS = (_public(SimDriver) - _public(Driver) - _public(SceneActions)
           - {"add_valve", "add_door"})  # actions at absolute places
# readers whose names the scanned code also gives its own figures (a task's ``spec.scene``,
# a watch's ``max_tilt_deg``): forbidden on an object named as a simulator (WORLDLY)
OWN_NAMES = {"scene", "max_tilt_deg"}
WORLDLY = ("world", "sim", "driver", "bullet")
DYNAMIC = {"getattr", "hasattr", "setattr", "delattr", "__import__", "vars"}
# what reaches past an object to what it holds (a bound method's ``__self__``, ``__dict__``)
INTROSPECTION = {"__dict__", "__self__", "__globals__", "__closure__", "__wrapped__"}
FORBIDDEN_MODULES = ("pybullet", "pybullet_utils", "hubo_cli.drivers.sim")
DYNAMIC_IMPORT = "importlib"  # an import by a name built at run time
ALLOWED = {
    "hubo_cli/control/log.py": (
        "the per-period log writes the truth beside the estimate, for reports and plots only",
        {"state.truth"}),
    "hubo_cli/scene.py": (
        "places the scene where the robot truly stands (the simulator's business), inside "
        "SceneActions' private helpers; a target gets the actions only",
        {"world.frame_pose"}),
    "hubo_cli/session.py": (
        "the run keeps the whole world for its reports: snapshot, scene, draws, max tilt",
        {"world.scene", "world.perturbation", "world.max_tilt_deg", "world.snapshot_png"}),
}


def _names_world(node: ast.expr) -> bool:
    """The expression names a simulator (``world``, ``self.sim``, ``driver``)."""
    while isinstance(node, ast.Attribute):
        if any(w in node.attr for w in WORLDLY):
            return True
        node = node.value
    return isinstance(node, ast.Name) and any(w in node.id for w in WORLDLY)


def _is_self(node: ast.expr) -> bool:
    return isinstance(node, ast.Name) and node.id in ("self", "cls")


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _dynamic_name_read(node: ast.Call) -> bool:
    """``getattr(x, name)`` and its kin with a name that is built at run time (a dataclass
    field's ``f.name`` excepted) or names the truth or a private attribute, on another object;
    ``__import__`` at all."""
    if not isinstance(node.func, ast.Name) or node.func.id not in DYNAMIC:
        return False
    if node.func.id == "__import__":
        return True
    if node.func.id == "vars":
        return not (node.args and _is_self(node.args[0]))
    if len(node.args) < 2 or _is_self(node.args[0]):
        return False
    name = node.args[1]
    if isinstance(name, ast.Constant) and isinstance(name.value, str):
        return (name.value in TRUTH_ATTRIBUTES | READERS) or _private(name.value)
    return not (isinstance(name, ast.Attribute) and name.attr == "name")


def truth_reads(source: str, truth_modules: frozenset[str] = frozenset()) -> list[str]:
    """Each read of the simulator's truth in a module's source, as ``line: what``;
    ``truth_modules``: modules (outside the scanned ones) that read the truth, whose names a
    scanned module may not import."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            if (node.attr in TRUTH_ATTRIBUTES
                    or (node.attr in READERS - OWN_NAMES and not _is_self(node.value))
                    or (node.attr in OWN_NAMES and _names_world(node.value))
                    or (_private(node.attr) and not _is_self(node.value))
                    or (node.attr in INTROSPECTION and not _is_self(node.value))):
                found.append(f"{node.lineno}: {ast.unparse(node)}")
        elif isinstance(node, ast.Call) and _dynamic_name_read(node):
            found.append(f"{node.lineno}: {ast.unparse(node)}")
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                names = [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
                if node.module in truth_modules | {"hubo_cli.scene"}:  # its private helpers
                    names += [a.name for a in node.names if _private(a.name)]
            for name in names:
                if (any(name == m or name.startswith(m + ".")
                        for m in (*FORBIDDEN_MODULES, DYNAMIC_IMPORT))
                        or name in truth_modules or _private(name)
                        or name.rsplit(".", 1)[0] in truth_modules):
                    found.append(f"{node.lineno}: import {name}")
                    break
    return found


def _allowed_reads(name: str, found: list[str]) -> list[str]:
    """The reads in ``found`` that ALLOWED does not grant file ``name``."""
    if name not in ALLOWED:
        return found
    granted = ALLOWED[name][1]
    return [f for f in found if f.split(": ", 1)[1] not in granted]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_level_imports(source: str, name: str, is_package: bool) -> set[str]:
    """The modules a module imports when it is imported: its top-level imports (those under
    ``if TYPE_CHECKING`` excluded; those inside functions run later, by a caller's choice)."""
    found: set[str] = set()

    def visit(body) -> None:
        for node in body:
            if isinstance(node, ast.If):
                if "TYPE_CHECKING" not in ast.unparse(node.test):
                    visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)
                for handler in node.handlers:
                    visit(handler.body)
            elif isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    package = name.split(".") if is_package else name.split(".")[:-1]
                    package = package[:len(package) - node.level + 1]
                    base = ".".join(package + ([base] if base else []))
                found.add(base)
                found.update(f"{base}.{alias.name}" for alias in node.names)

    visit(ast.parse(source).body)
    return found


def forbidden_import_chain(graph: dict[str, set[str]], start: str) -> list[str] | None:
    """The chain of module-level imports from ``start`` to a FORBIDDEN_MODULES module (a
    module imports its parent packages too), or None."""
    parent: dict[str, str] = {}
    stack, seen = [start], {start}
    while stack:
        module = stack.pop()
        for imported in graph.get(module, ()):
            parts = imported.split(".")
            for k in range(1, len(parts) + 1):
                name = ".".join(parts[:k])
                if name in seen:
                    continue
                seen.add(name)
                parent[name] = module
                if any(name == m or name.startswith(m + ".") for m in FORBIDDEN_MODULES):
                    chain = [name]
                    while chain[-1] != start:
                        chain.append(parent[chain[-1]])
                    return chain[::-1]
                if name in graph:
                    stack.append(name)
    return None


def _scanned_files() -> list[Path]:
    return sorted([p for package in SCANNED for p in (PACKAGE / package).rglob("*.py")]
                  + [PACKAGE / name for name in SCANNED_FILES])


def _relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _import_graph() -> dict[str, set[str]]:
    return {module_name(p): module_level_imports(p.read_text(), module_name(p),
                                                 p.name == "__init__.py")
            for p in PACKAGE.rglob("*.py")}


def _truth_modules() -> frozenset[str]:
    """The modules outside the scanned ones that read the truth (reports, plots, drivers):
    nothing scanned may import from them."""
    scanned = {_relative(p) for p in _scanned_files()}
    return frozenset(module_name(p) for p in PACKAGE.rglob("*.py")
                     if _relative(p) not in scanned and _reads_the_world(p.read_text()))


def _reads_the_world(source: str) -> bool:
    """The source reads the truth or a world reader (its own private attributes aside)."""
    return any(isinstance(n, ast.Attribute) and (
        n.attr in TRUTH_ATTRIBUTES or (n.attr in READERS - OWN_NAMES and not _is_self(n.value))
        or (n.attr in OWN_NAMES and _names_world(n.value))) for n in ast.walk(ast.parse(source)))


# ------------------------------------------------------------------ the code base
def test_no_module_target_or_planner_reads_the_simulators_truth():
    files = _scanned_files()
    assert len(files) > 60  # the packages were found
    truth_modules = _truth_modules()
    assert "hubo_cli.drivers.sim" in truth_modules  # the search found the simulator
    violations = {}
    for path in files:
        name = _relative(path)
        found = _allowed_reads(name, truth_reads(path.read_text(), truth_modules))
        if found:
            violations[name] = found
    assert not violations, (
        "modules, targets and planners act on the estimate (hubo_cli.estimation.keys), never "
        f"on the simulator's truth: {violations}")


def test_nothing_they_import_brings_in_the_simulator():
    graph = _import_graph()
    chains = {}
    for path in _scanned_files():
        if _relative(path) == "hubo_cli/session.py":  # the run holds the driver
            continue
        chain = forbidden_import_chain(graph, module_name(path))
        if chain:
            chains[_relative(path)] = " -> ".join(chain)
    assert not chains, chains


def test_the_allowed_entries_are_still_needed():
    """An entry whose file no longer makes a granted read is trimmed (the list only
    shrinks)."""
    truth_modules = _truth_modules()
    for name, (_, granted) in ALLOWED.items():
        path = ROOT / name
        assert path.exists(), name
        made = {f.split(": ", 1)[1] for f in truth_reads(path.read_text(), truth_modules)}
        assert granted <= made, f"{name} no longer makes {granted - made}: drop it"


def test_the_scene_reads_the_truth_only_inside_its_private_helpers():
    """A target imports the scene module (for SceneActions): its truth reads live only in
    private functions, which nothing scanned may import (a private name)."""
    tree = ast.parse((PACKAGE / "scene.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and truth_reads(ast.unparse(node)):
            assert _private(node.name), node.name


# ------------------------------------------------------------------ by type
def _target_classes() -> list[type]:
    import importlib

    from hubo_cli.control.target import Target
    for path in _scanned_files():
        if path.name != "__init__.py":
            importlib.import_module(module_name(path))
    found, stack = [], [Target]
    while stack:
        cls = stack.pop()
        found.append(cls)
        stack.extend(cls.__subclasses__())
    return [c for c in found if c.__module__.startswith("hubo_cli.")]


def test_every_targets_attach_takes_the_actions_not_the_simulator():
    classes = _target_classes()
    assert len(classes) > 8  # the targets were found
    for cls in classes:
        if "attach" not in vars(cls):
            continue
        world = list(inspect.signature(cls.attach).parameters)[1]
        module = vars(sys.modules[cls.__module__])
        # control/target.py names SceneActions under TYPE_CHECKING only (no import cycle)
        hint = eval(inspect.signature(cls.attach).parameters[world].annotation,
                    {"SceneActions": SceneActions, **module})
        assert set(typing.get_args(hint)) == {SceneActions, type(None)}, (cls, hint)


def test_the_actions_offer_no_reader():
    """SceneActions' public members are the actions (and the physics clock); it keeps no
    attribute beyond its slot, so nothing can be hung on it."""
    assert _public(SceneActions) == {"add_wall", "place_wall", "place_object", "push_torso",
                                     "grasp", "release", "physics_wall_s"}
    assert SceneActions.__slots__ == ("_world",)
    assert not (_public(SceneActions) & (READERS | TRUTH_ATTRIBUTES))
    assert {"frame_pose", "holding", "hinge_angle_rad", "walls", "cutting_force_n",
            "perturbation", "max_tilt_deg", "scene"} <= READERS | TRUTH_ATTRIBUTES


def test_the_session_gives_targets_the_actions():
    """Every ``attach`` call in the session passes SceneActions made from the world (or
    None), never the world or the driver itself."""
    calls = [n for n in ast.walk(ast.parse((PACKAGE / "session.py").read_text()))
             if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
             and n.func.attr == "attach"]
    assert calls
    for call in calls:
        given = call.args[0]
        assert isinstance(given, ast.IfExp), ast.unparse(given)
        made = given.orelse
        assert (isinstance(given.body, ast.Constant) and given.body.value is None
                and isinstance(made, ast.Call) and ast.unparse(made.func) == "SceneActions"), \
            ast.unparse(given)


# ------------------------------------------------------------------ the checker itself
# the independent review's ten misses (REVIEW33 item 4), each a line the old checker passed
REVIEW_MISSES = [
    "def f(self):\n    return self.world._p.getBasePositionAndOrientation(self.world._robot)\n",
    "def f(self):\n    return self.world.hinge_angle_rad('valve')\n",
    "def f(self):\n    return self.world.holding('right_hand')\n",
    "def f(world):\n    return world.cutting_force_n\n",
    "def f(world):\n    return world.walls[0].distance_m\n",
    "def f(self):\n    return self.sim.max_tilt_deg\n",
    "def f(driver):\n    return driver.perturbation\n",
    "def f(state):\n    return getattr(state, 'tru' + 'th').T_world_torso\n",
    "import importlib\n\ndef f():\n    return importlib.import_module('pybullet')\n",
    "from hubo_cli.scene import _robot_offset_world_m\n",
]


@pytest.fixture(scope="module")
def truth_modules() -> frozenset[str]:
    return _truth_modules()


@pytest.mark.parametrize("planted", [
    "def f(state):\n    return state.truth.T_world_torso\n",
    "def f(self, state):\n    contact = state.truth.feet_contact\n",
    "def f(world):\n    return world.frame_pose('right_sole')\n",
    "def f(self):\n    return self.world.frame_pose('torso')[:3, 3]\n",
    "def f(self):\n    return self.world.max_tilt_deg\n",
    "def f(target):\n    return target.world.perturbation.foot_friction\n",
    "def f(world):\n    return world.scene()['walls']\n",
    "def f(robot):\n    return robot.com_world_m()\n",
    "import pybullet\n",
    "import pybullet as p\n",
    "from pybullet_utils import bullet_client\n",
    "def f():\n    from hubo_cli.drivers.sim import SimDriver\n",
    "from hubo_cli.drivers import sim\n",
    *REVIEW_MISSES,
    # and their kin: a helper module that reads the truth, whatever the object is called
    "from hubo_cli.viz.live import LiveServer\n",
    "def f(x):\n    return x.holding('right_hand')\n",
    "def f(actions):\n    return actions._world.frame_pose('torso')\n",
    "def f(actions):\n    return actions.push_torso.__self__\n",
    "def f(state):\n    return getattr(state, 'truth')\n",
    "def f(actions):\n    return vars(actions)\n",
    "def f():\n    return __import__('pybullet')\n",
])
def test_a_planted_truth_read_is_found(planted, truth_modules):
    found = truth_reads("import numpy as np\n\n" + planted, truth_modules)
    assert found and all(": " in f for f in found), planted


def test_the_helper_modules_that_read_the_truth_are_found():
    """The modules outside the scanned ones that read the truth are found from their code
    (the simulator's own helpers and the live viewer among them)."""
    modules = _truth_modules()
    assert {"hubo_cli.drivers.sim", "hubo_cli.viz.live"} <= modules
    assert "hubo_cli.fastrak.records" not in modules  # private helpers of its own only


def test_reads_of_the_estimate_and_own_attributes_pass():
    clean = (
        "from dataclasses import fields\n"
        "from hubo_cli.estimation.keys import T_WORLD_TORSO, CONTACT\n"
        "from hubo_cli.scene import SceneActions, WallPlacement\n"
        "class T:\n"
        "    def update(self, state, cycle, spec, targets):\n"
        "        self.max_tilt_deg = max(self.max_tilt_deg, targets.max_tilt_deg)\n"
        "        T = cycle.store[T_WORLD_TORSO]\n"
        "        self.world.push_torso([1.0, 0.0, 0.0], 0.2)  # an action, not a reading\n"
        "        self.placed = self.world.place_wall(spec.scene)  # for the reports\n"
        "        values = [getattr(spec, f.name) for f in fields(spec)]\n"
        "        return state.imu_quat_wxyz, cycle.store[CONTACT], self._own, values\n")
    assert truth_reads(clean, frozenset({"hubo_cli.viz.live"})) == []
def test_the_import_graph_finds_the_simulator_behind_an_import():
    """A planted module two imports away from the simulator driver is caught with its chain;
    an import inside a function or under TYPE_CHECKING is not the module's."""
    sources = {
        "hubo_cli.control.planted": "from hubo_cli.control import helper\n",
        "hubo_cli.control.helper": "import numpy as np\nfrom hubo_cli.drivers.sim import X\n",
        "hubo_cli.control.lazy": ("from typing import TYPE_CHECKING\n"
                                  "if TYPE_CHECKING:\n    from hubo_cli.drivers.sim import X\n"
                                  "def f():\n    import pybullet\n"),
    }
    graph = {name: module_level_imports(source, name, False) for name, source in sources.items()}
    assert forbidden_import_chain(graph, "hubo_cli.control.planted") == [
        "hubo_cli.control.planted", "hubo_cli.control.helper", "hubo_cli.drivers.sim"]
    assert forbidden_import_chain(graph, "hubo_cli.control.lazy") is None
    # relative imports resolve like absolute ones
    relative = module_level_imports("from ..drivers import sim\n", "hubo_cli.control.x", False)
    assert "hubo_cli.drivers.sim" in relative


def test_a_violation_planted_in_a_real_module_is_found():
    """The hip strategy's own source passes; with one line reading the truth it does not."""
    source = (PACKAGE / "control" / "hip_strategy.py").read_text()
    assert truth_reads(source) == []
    planted = source + "\n\ndef _cheat(state):\n    return state.truth.feet_contact\n"
    assert truth_reads(planted) == [f"{len(planted.splitlines())}: state.truth"]


@pytest.mark.parametrize("planted", REVIEW_MISSES)
def test_each_review_miss_planted_in_a_real_target_fails_the_scan(planted, truth_modules):
    """The valve/door target's own source passes; with one of the review's misses appended
    (a function of its own) the scan finds it."""
    name = "hubo_cli/experiments/manipulation.py"
    source = (ROOT / name).read_text()
    assert truth_reads(source, truth_modules) == []
    found = truth_reads(source + "\n\n" + planted, truth_modules)
    assert found and all(int(f.split(":")[0]) > len(source.splitlines()) for f in found)
