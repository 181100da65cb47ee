"""The import graph of ``hubo_cli``: no cycles, no upward import from drivers into control, and
the estimation layer below everything that reads its estimate.

The graph is read from the source with ``ast`` (nothing is imported): every ``import`` and
``from ... import`` statement counts, at module level or inside a function, with relative
imports resolved and ``from package import module`` pointing at the module. The layering tests
count the imports made only for type checking (``if TYPE_CHECKING:``) too; the cycle test does
not, since those are never executed (a phase annotated with the target that runs it).
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

pytestmark = pytest.mark.xdist_group("imports")  # the graph is read once, on one worker

PACKAGE = "hubo_cli"
ROOT = Path(__file__).resolve().parent.parent / PACKAGE


def _module_names() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    names = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        names[".".join(parts)] = path
    return names


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The absolute name a ``from`` import names (relative imports resolved)."""
    if not node.level:
        return node.module or ""
    base = module.split(".")
    drop = node.level - 1 if is_package else node.level
    base = base[:len(base) - drop]
    return ".".join(base + ([node.module] if node.module else []))


def _owner(name: str, modules: dict[str, Path]) -> str | None:
    """The longest package module that ``name`` is or lies in, or None outside the package."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _type_checking_only(tree: ast.Module) -> set[ast.AST]:
    """The import statements inside ``if TYPE_CHECKING:`` blocks."""
    return {node for block in ast.walk(tree)
            if isinstance(block, ast.If) and "TYPE_CHECKING" in ast.unparse(block.test)
            for statement in block.body for node in ast.walk(statement)}


@functools.cache
def import_graph(runtime_only: bool = False) -> dict[str, set[str]]:
    """Module -> the package modules it imports (anywhere in its body; with ``runtime_only``
    not those imported for type checking alone); read once per process (the tests only read
    it)."""
    modules = _module_names()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(), str(path))
        skipped = _type_checking_only(tree) if runtime_only else set()
        for node in ast.walk(tree):
            if node in skipped:
                continue
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_package, node)
                # ``from pkg import module`` imports the module; ``from mod import name`` the mod
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                           for alias in node.names]
            for target in targets:
                owner = _owner(target, modules)
                if owner is not None and owner != name:
                    graph[name].add(owner)
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(component)
    return components


def test_the_graph_is_read_from_every_module():
    graph = import_graph()
    assert "hubo_cli.geometry" in graph
    # a relative and a function-level import are both seen (the CLI imports its library lazily)
    assert "hubo_cli.kinematics.poses" in graph["hubo_cli.cli.kinematics"]
    assert "hubo_cli.fastrak.source" in graph["hubo_cli.fastrak"]


def test_relative_imports_resolve():
    node = ast.parse("from ..control import module").body[0]
    assert _resolve("hubo_cli.drivers.standing", False, node) == "hubo_cli.control"
    node = ast.parse("from .source import PoseSample").body[0]
    assert _resolve("hubo_cli.fastrak", True, node) == "hubo_cli.fastrak.source"


def test_type_checking_imports_are_runtime_free():
    tree = ast.parse("from typing import TYPE_CHECKING\nimport a\nif TYPE_CHECKING:\n"
                     "    from b import c\n")
    assert sorted(type(n).__name__ for n in _type_checking_only(tree)) == ["ImportFrom", "alias"]
    # the layering tests see the type-only import; the cycle test does not
    assert "hubo_cli.tasks.target" in import_graph()["hubo_cli.tasks.phases"]
    assert "hubo_cli.tasks.target" not in import_graph(runtime_only=True)["hubo_cli.tasks.phases"]


def test_a_cycle_is_found():
    toy = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert strongly_connected(toy) == [{"a", "b", "c"}]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    cycles = [sorted(c) for c in strongly_connected(import_graph(runtime_only=True))]
    assert cycles == [], f"import cycles: {cycles}"


@pytest.mark.parametrize(("lower", "upper"), [("hubo_cli.drivers", "hubo_cli.control"),
                                             ("hubo_cli.motion", "hubo_cli.control"),
                                             ("hubo_cli.motion", "hubo_cli.drivers"),
                                             *[("hubo_cli.estimation", upper) for upper in (
                                                 "hubo_cli.control", "hubo_cli.walking",
                                                 "hubo_cli.tasks", "hubo_cli.teleop",
                                                 "hubo_cli.drivers", "hubo_cli.experiments",
                                                 "hubo_cli.cli")]])
def test_no_upward_import(lower, upper):
    graph = import_graph()
    upward = sorted((module, target) for module, targets in graph.items()
                    if module.startswith(lower + ".") for target in targets
                    if target == upper or target.startswith(upper + "."))
    assert upward == [], f"{lower} imports {upper}: {upward}"
