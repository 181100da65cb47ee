"""Nothing that acts on the robot reads the simulator's truth (issue 33).

The simulator knows the torso's true pose, the feet's true contact, its draws of the robot's
parameters; a Hubo knows none of these. So that what runs in simulation is what can run on the
robot, every module, target and planner (the packages in SCANNED) reads the estimate
(:mod:`hubo_cli.estimation.keys`) and never:

* ``state.truth`` (:class:`~hubo_cli.state.Truth`, the simulator's ground truth beside the
  sensors), nor the simulator's ``frame_pose`` or its true centre of mass ``com_world_m``;
* a simulated world's ``max_tilt_deg``, ``perturbation`` or ``scene()``;
* pybullet or the simulator driver, directly or through the modules it imports at module
  level (the import graph of hubo_cli).

Logs, reports, plots, viewers and the drivers may read the truth (the log writes it beside the
estimate for the reports): outside SCANNED, or listed in ALLOWED with the reason. The checker
is tested on planted violations.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hubo_cli"
SCANNED = ("control", "estimation", "walking", "tasks", "teleop", "kinematics", "experiments")
# attributes that are the simulator's truth on whatever object they are read
TRUTH_ATTRIBUTES = {"truth", "frame_pose", "com_world_m"}
# attributes that are the simulator's truth when read on a simulated world
WORLD_ATTRIBUTES = {"max_tilt_deg", "perturbation", "scene"}
FORBIDDEN_MODULES = ("pybullet", "pybullet_utils", "hubo_cli.drivers.sim")
ALLOWED = {
    "hubo_cli/control/log.py": "the per-period log writes the truth beside the estimate, for "
                               "reports and plots only",
}
PENDING_FLOW_WALK: set[str] = set()  # walking and experiments now act on the estimate


def _names_world(node: ast.expr) -> bool:
    """The expression names a simulated world (``world``, ``self.world``, ``target.world``)."""
    while isinstance(node, ast.Attribute):
        if "world" in node.attr:
            return True
        node = node.value
    return isinstance(node, ast.Name) and "world" in node.id


def truth_reads(source: str) -> list[str]:
    """Each read of the simulator's truth in a module's source, as ``line: what``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            if node.attr in TRUTH_ATTRIBUTES or (node.attr in WORLD_ATTRIBUTES
                                                 and _names_world(node.value)):
                found.append(f"{node.lineno}: {ast.unparse(node)}")
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                names = [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
            for name in names:
                if any(name == m or name.startswith(m + ".") for m in FORBIDDEN_MODULES):
                    found.append(f"{node.lineno}: import {name}")
                    break
    return found


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
    return sorted(p for package in SCANNED for p in (PACKAGE / package).rglob("*.py"))


def _relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _import_graph() -> dict[str, set[str]]:
    return {module_name(p): module_level_imports(p.read_text(), module_name(p),
                                                 p.name == "__init__.py")
            for p in PACKAGE.rglob("*.py")}


# ------------------------------------------------------------------ the code base
def test_no_module_target_or_planner_reads_the_simulators_truth():
    files = _scanned_files()
    assert len(files) > 60  # the packages were found
    violations = {}
    for path in files:
        name = _relative(path)
        if name in ALLOWED or name in PENDING_FLOW_WALK:
            continue
        found = truth_reads(path.read_text())
        if found:
            violations[name] = found
    assert not violations, (
        "modules, targets and planners act on the estimate (hubo_cli.estimation.keys), never "
        f"on the simulator's truth: {violations}")


def test_nothing_they_import_brings_in_the_simulator():
    graph = _import_graph()
    chains = {}
    for path in _scanned_files():
        if _relative(path) in ALLOWED or _relative(path) in PENDING_FLOW_WALK:
            continue
        chain = forbidden_import_chain(graph, module_name(path))
        if chain:
            chains[_relative(path)] = " -> ".join(chain)
    assert not chains, chains


def test_the_allowed_and_pending_entries_are_still_needed():
    """An entry whose file no longer reads the truth is dropped (the lists only shrink)."""
    for name in (*ALLOWED, *PENDING_FLOW_WALK):
        path = ROOT / name
        assert path.exists(), name
        assert truth_reads(path.read_text()), f"{name} no longer reads the truth: drop it"


# ------------------------------------------------------------------ the checker itself
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
])
def test_a_planted_truth_read_is_found(planted):
    found = truth_reads("import numpy as np\n\n" + planted)
    assert found and all(": " in f for f in found), planted


def test_reads_of_the_estimate_and_own_attributes_pass():
    clean = (
        "from hubo_cli.estimation.keys import T_WORLD_TORSO, CONTACT\n"
        "class T:\n"
        "    def update(self, state, cycle):\n"
        "        self.max_tilt_deg = max(self.max_tilt_deg, 1.0)  # its own figure\n"
        "        T = cycle.store[T_WORLD_TORSO]\n"
        "        self.world.push_torso([1.0, 0.0, 0.0], 0.2)  # an action, not a reading\n"
        "        return state.imu_quat_wxyz, cycle.store[CONTACT]\n")
    assert truth_reads(clean) == []


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
