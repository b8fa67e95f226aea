"""The package's import graph: no cycle, no import hidden inside a function, and every import points down
the layers (schema -> registration -> geometry -> terms -> backends -> compiler -> envs -> factory -> tools -> CLI).

The graph is read from the source with `ast`, so a new module joins the check without being listed; a module
that matches no layer fails the test until it is given one."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "envfactory"

# Lowest first. A module may import its own layer's modules and any lower layer's, never a higher one's.
LAYERS: list[tuple[str, ...]] = [
    (
        "envfactory.version",
        "envfactory.step_state",
        "envfactory.compiler.normalization",
        "envfactory.registration.user_config",
        "envfactory.user_folders",
    ),  # leaves
    ("envfactory.schema",),  # pydantic models, loading, Hydra composition, located problems
    (
        "envfactory.registration.registry",
        "envfactory.registration.validation_cache",
    ),  # which IDs the spec folders declare (no compile)
    ("envfactory.geometry",),  # the robot model built once per process, the safety proof
    ("envfactory.terms", "envfactory.experts"),  # the term library and the scripted policies
    ("envfactory.backends",),  # PyBullet, rosbridge: everything the env calls
    ("envfactory.compiler",),  # spec -> Blueprint
    ("envfactory.envs",),  # the gymnasium envs, generic over blueprints and backends
    ("envfactory.factory",),  # ID -> blueprint -> env
    (
        "envfactory.views.describe",
        "envfactory.envs.episodes",
        "envfactory.views.safety_picture",
        "envfactory.twin",
        "envfactory.learn",
        "envfactory.cluster",
        "envfactory.terms.sensing_from_log",
    ),  # tools over envs (cluster: the only wing that imports ray)
    ("envfactory.cli", "envfactory"),  # the command, and the package's own facade
]


def _modules() -> dict[str, Path]:
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


MODULES = _modules()


def _targets(module: str, node: ast.Import | ast.ImportFrom) -> set[str]:
    """The package modules an import statement loads."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = node.module or ""
        if node.level:
            package = module.split(".") if MODULES[module].name == "__init__.py" else module.split(".")[:-1]
            base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
        names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base for alias in node.names]
    found = set()
    for name in names:
        while name and name not in MODULES:
            name = name.rpartition(".")[0]
        if name and name != module:
            found.add(name)
    return found


def _imports() -> tuple[dict[str, set[str]], list[str]]:
    """(module -> modules it imports, 'file:line' of every package import inside a function)."""
    edges, hidden = {}, []
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text())
        edges[module] = set()
        inside = {
            id(node)
            for function in ast.walk(tree)
            if isinstance(function, (ast.FunctionDef, ast.AsyncFunctionDef))
            for node in ast.walk(function)
        }
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                targets = _targets(module, node)
                edges[module] |= targets
                if targets and id(node) in inside:
                    hidden.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    return edges, hidden


def _layer(module: str) -> int:
    best, rank = None, -1
    for index, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > rank:
                best, rank = index, len(prefix)
    if best is None:
        pytest.fail(f"module {module} belongs to no layer: add it to LAYERS in {Path(__file__).name}")
    return best


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], [0]
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_import_graph_has_no_cycle():
    edges, _ = _imports()
    assert _cycles(edges) == []


def test_no_package_import_hides_inside_a_function():
    _, hidden = _imports()
    assert hidden == []


def test_imports_point_down_the_layers():
    edges, _ = _imports()
    upward = [
        f"{module} (layer {_layer(module)}) imports {target} (layer {_layer(target)})"
        for module, targets in sorted(edges.items())
        for target in sorted(targets)
        if _layer(target) > _layer(module)
    ]
    assert upward == []


def test_the_checks_see_a_cycle_and_an_upward_import():
    """The checks themselves can fail: a made-up graph with a cycle and an upward edge is caught."""
    graph = {"envfactory.schema.a": {"envfactory.geometry.b"}, "envfactory.geometry.b": {"envfactory.schema.a"}}
    assert _cycles(graph) == [["envfactory.geometry.b", "envfactory.schema.a"]]
    assert _layer("envfactory.schema.a") < _layer("envfactory.geometry.b")


REPOSITORY = PACKAGE.parent


def _python_files(*folders: str) -> list[Path]:
    return [path for folder in folders for path in (REPOSITORY / folder).rglob("*.py")]


def test_the_library_never_imports_the_repositorys_own_python():
    """devkit (benchmarks, oracles, docs generators) and the tests sit above the library: it imports neither."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [alias.name for alias in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            found += [
                f"{path.relative_to(REPOSITORY)}:{node.lineno} imports {name}"
                for name in names
                if name.split(".")[0] in ("devkit", "tests")
            ]
    assert found == []


SYS_PATH_EDIT = re.compile(r"sys\.path(\.insert|\.append|\.extend|\[|\s*\+?=)")


def test_no_python_file_edits_the_import_path():
    """Every Python file of the repository imports by real names (devkit is a package, pytest's pythonpath holds
    the root): none edits the interpreter's import path."""
    edits = [
        f"{path.relative_to(REPOSITORY)}:{number}"
        for path in _python_files("envfactory", "devkit", "tests")
        for number, line in enumerate(path.read_text().splitlines(), start=1)
        if SYS_PATH_EDIT.search(line) and path.name != "test_layers.py"
    ]
    assert edits == []
