"""The packages' public surface and import structure.

* ``kinematics`` and ``planning`` re-export their public names at the top level (each the
  same object as in its module), ship ``py.typed``, and stay light to import;
* ``kinematics`` and ``planning`` never import ``app`` or ``web``, counting imports inside
  functions;
* no import cycle among the modules of the project's packages (imports inside functions
  count, and so do literal module names, such as those the algorithm catalogue hands to the
  registry; ``if TYPE_CHECKING:`` blocks, which never run, do not);
* the floors declared in ``pyproject.toml`` (``[tool.kinoplan] floors``): no module imports a
  unit beside or above its own, and every module belongs to a declared unit;
* every module of ``kinematics`` and ``planning`` imports on its own, first.
"""

from __future__ import annotations

import ast
import functools
import importlib
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The project's packages; ``kinoplan`` (the composition root) when it is there.
PACKAGES = tuple(p for p in ("app", "kinematics", "planning", "web", "kinoplan")
                 if (ROOT / p).is_dir())
LIBRARIES = ("kinematics", "planning")

#: Names the README and the docs use from the top level.
EXPECTED = {
    "kinematics": {"RobotModel", "Joint", "fk", "fk_frames", "jacobian", "solve_ik", "IKResult",
                   "IKStatus", "builtin_model", "sample_workspace", "CylinderSet", "Rig",
                   "builtin_rig", "drill_ik", "calibrate", "LearnedIK", "FieldError",
                   "PositionJacobian", "position_ik"},
    "planning": {"plan_trajectory", "Trajectory", "Limits", "Scene", "plan_path", "PathResult",
                 "PlanStatus", "sequence_holes", "plan_arm_path", "simulate", "tune_gains"},
}

#: Import cycles tolerated, as the sets of modules that import one another (strongly
#: connected components): none. The test fails on any cycle that is not inside one of these.
KNOWN_CYCLES: list[set[str]] = []


# ---- the public names ------------------------------------------------------------------
@pytest.mark.parametrize("package", LIBRARIES)
def test_public_names_import_from_the_top_level(package):
    pkg = importlib.import_module(package)
    assert EXPECTED[package] <= set(pkg.__all__)
    assert len(set(pkg.__all__)) == len(pkg.__all__)
    for name in pkg.__all__:
        value = getattr(pkg, name)
        home = getattr(value, "__module__", None)
        if home is not None and home.startswith(package + "."):
            # Re-exported: the very object its module defines.
            assert getattr(sys.modules[home], name, value) is value, name
    namespace: dict = {}
    exec(f"from {package} import *", namespace)  # noqa: S102 - the star import works
    assert set(pkg.__all__) <= set(namespace)
    with pytest.raises(AttributeError):
        pkg.no_such_name  # noqa: B018


def test_functions_named_like_their_modules_stay_functions():
    """``kinematics.fk`` and ``kinematics.jacobian`` are the functions, also after their
    modules have been imported by name."""
    importlib.import_module("kinematics.fk")
    importlib.import_module("kinematics.jacobian")
    import kinematics

    assert kinematics.fk is sys.modules["kinematics.fk"].fk
    assert kinematics.jacobian is sys.modules["kinematics.jacobian"].jacobian


def _reexports(path: Path) -> tuple[dict[str, str], dict[str, str], set[str]]:
    """From an ``__init__.py``: ``{name: module}`` of its ``from .m import Name as Name``
    lines outside and inside ``if TYPE_CHECKING:``, and the names it defines itself."""
    tree = ast.parse(path.read_text())
    eager: dict[str, str] = {}
    typing_only: dict[str, str] = {}
    defined: set[str] = set()

    def collect(nodes, into):
        for node in nodes:
            # ``from . import module`` runs a module for its effect (``planning.catalog``
            # registers the built-in algorithms); it re-exports nothing.
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                for alias in node.names:
                    assert alias.asname == alias.name, (
                        f"{path}: re-export as 'from .{node.module} import {alias.name} as "
                        f"{alias.name}'")
                    into[alias.name] = node.module

    collect(tree.body, eager)
    for node in tree.body:
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING":
            collect(node.body, typing_only)
        elif isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            defined.add(node.name)
        elif isinstance(node, ast.Assign):
            defined |= {t.id for t in node.targets
                        if isinstance(t, ast.Name) and not t.id.startswith("_")}
    return eager, typing_only, defined - {"__all__"}


@pytest.mark.parametrize("package", LIBRARIES)
def test_lazy_names_match_what_type_checkers_see(package):
    """Names loaded on first use (``_LAZY``) are exactly the ``if TYPE_CHECKING:`` imports,
    from the same modules, and ``__all__`` is every re-exported or defined name."""
    pkg = importlib.import_module(package)
    eager, typing_only, defined = _reexports(ROOT / package / "__init__.py")
    assert pkg._LAZY == typing_only
    assert set(pkg.__all__) == set(eager) | set(typing_only) | defined


@pytest.mark.parametrize("package", LIBRARIES)
def test_py_typed_is_shipped(package):
    assert (ROOT / package / "py.typed").is_file()
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in data["tool"]["setuptools"]["package-data"][package]


@pytest.mark.parametrize("package", LIBRARIES)
def test_importing_the_package_loads_no_scipy(package):
    """scipy (a few hundred ms) loads with the first name that needs it, not before."""
    code = f"import sys, {package}; print(sorted(m for m in ('scipy', 'app', 'web') " \
           "if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=60, check=True)
    assert done.stdout.strip() == "[]"


def test_readme_library_example_runs_from_the_top_level():
    text = (ROOT / "README.md").read_text()
    example = text.split("As a library:", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    tree = ast.parse(example)
    sources = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert sources == set(LIBRARIES), sources  # no submodule paths
    namespace: dict = {}
    exec(compile(tree, "README.md", "exec"), namespace)  # noqa: S102
    assert namespace["T"].shape == (4, 4) and namespace["J"].shape == (6, 6)
    assert str(namespace["result"].status) == "ok"


# ---- the import graph ------------------------------------------------------------------
def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


@functools.cache  # parsed once per run: several tests walk every module's imports
def imported_names(module: str) -> frozenset[str]:
    """Absolute names ``module`` imports anywhere in its file (functions included): ``a.b``
    for ``import a.b``, ``a.b`` and ``a.b.c`` for ``from a.b import c``, relative imports
    resolved; and the literal module names of a file that calls ``import_module`` or hands
    names to the registry's ``register`` (which loads them by ``import_module`` on first use).
    A module named for another process to import (the forkserver's preload) is not an
    import of this one."""
    path = MODULES[module]
    tree = ast.parse(path.read_text())
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    out: set[str] = set()
    dynamic = False
    strings: set[str] = set()

    def visit(node: ast.AST) -> None:
        nonlocal dynamic
        if isinstance(node, ast.If) and _type_checking(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            out.add(source)
            out.update(f"{source}.{alias.name}" for alias in node.names)
            if source.endswith("registry") and any(a.name == "register" for a in node.names):
                dynamic = True  # it names modules for the registry to load
        elif isinstance(node, ast.Attribute | ast.Name) and "import_module" in (
                getattr(node, "attr", None), getattr(node, "id", None)):
            dynamic = True
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            strings.add(node.value)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    if dynamic:
        out |= strings & set(MODULES)
    return frozenset(out)


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of the four packages it imports."""
    graph: dict[str, set[str]] = {}
    for module in MODULES:
        edges = set()
        for name in imported_names(module):
            while name and name not in MODULES:  # ``from a import name``: a, if not a module
                name = name.rpartition(".")[0]
            if name and name != module:
                edges.add(name)
        graph[module] = edges
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[set[str]]:
    """Components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
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
                    found.append(component)
    return found


def a_cycle(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """One cycle through the component's first module, for the failure message."""
    start = min(component)
    paths = [[start]]
    seen = {start}
    while paths:
        path = paths.pop(0)
        for nxt in sorted(graph[path[-1]] & component):
            if nxt == start:
                return path + [start]
            if nxt not in seen:
                seen.add(nxt)
                paths.append(path + [nxt])
    return sorted(component)


@pytest.mark.slow
@pytest.mark.parametrize("package", LIBRARIES)
def test_libraries_never_import_app_or_web(package):
    offenders = sorted(
        f"{module} imports {name}"
        for module in MODULES if module.split(".")[0] == package
        for name in imported_names(module) if name.split(".")[0] in ("app", "web"))
    assert not offenders, offenders


def test_the_graph_sees_imports_inside_functions():
    graph = import_graph()
    assert "planning.paths.compare" in graph["app.jobs.path_kinds"]  # inside run_path_compare
    assert "planning.optimisers.aca" in graph["planning.catalog"]  # named for importlib
    assert "planning.optimisers.aca" in graph["planning.paths.planners"]
    cycle = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert strongly_connected(cycle) == [{"a", "b", "c"}]
    assert a_cycle(cycle, {"a", "b", "c"}) == ["a", "b", "c", "a"]


@pytest.mark.slow
def test_no_import_cycles():
    graph = import_graph()
    new = [component for component in strongly_connected(graph)
           if not any(component <= known for known in KNOWN_CYCLES)]
    assert not new, "import cycles: " + "; ".join(
        " -> ".join(a_cycle(graph, component)) for component in new)


@pytest.mark.slow
def test_every_library_module_imports_first():
    """Each module of ``kinematics`` and ``planning`` imports in a fresh state (its packages'
    ``__init__`` files run first, which the graph above does not model)."""
    modules = sorted(m for m in MODULES if m.split(".")[0] in LIBRARIES)
    code = (
        "import importlib, sys\n"
        f"failed = []\nfor name in {modules!r}:\n"
        "    for m in [m for m in sys.modules if m.split('.')[0] in {LIBRARIES!r}]:\n"
        "        del sys.modules[m]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as exc:\n"
        "        failed.append(f'{name}: {exc!r}')\n"
        "print(failed)\n"
    ).replace("{LIBRARIES!r}", repr(LIBRARIES))
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, check=True)
    assert done.stdout.strip() == "[]", done.stdout


# ---- the floors ------------------------------------------------------------------------
FLOORS: list[list[str]] = tomllib.loads(
    (ROOT / "pyproject.toml").read_text())["tool"]["kinoplan"]["floors"]


def unit_of(module: str, floors: list[list[str]]) -> tuple[str, int] | None:
    """The declared unit ``module`` belongs to (the longest name it is or starts with) and
    that unit's floor (0 at the bottom); None if no unit covers it."""
    best = None
    for level, units in enumerate(floors):
        for unit in units:
            if (module == unit or module.startswith(unit + ".")) and (
                    best is None or len(unit) > len(best[0])):
                best = (unit, level)
    return best


def floor_offences(graph: dict[str, set[str]], floors: list[list[str]]) -> list[str]:
    """Every import of a unit beside or above the importing module's own."""
    found = []
    for module in sorted(graph):
        here = unit_of(module, floors)
        for name in sorted(graph[module]):
            there = unit_of(name, floors)
            if here and there and there[0] != here[0] and there[1] >= here[1]:
                side = "beside" if there[1] == here[1] else "above"
                found.append(f"{module} ({here[0]}, floor {here[1]}) imports {name} "
                             f"({there[0]}, {side} it)")
    return found


def test_the_floor_rule_finds_imports_up_and_across():
    floors = [["low"], ["mid.a", "mid.b"], ["mid"], ["top"]]
    graph = {"top.x": {"mid.a.y", "low.z"}, "mid.a.y": {"mid.a.w", "low.z", "mid.b.v"},
             "mid.b.v": {"top.x"}, "mid": {"mid.a.y"}, "low.z": set(), "mid.a.w": set()}
    assert unit_of("mid.a.y", floors) == ("mid.a", 1)
    assert unit_of("mid.c", floors) == ("mid", 2)
    assert unit_of("other", floors) is None
    assert floor_offences(graph, floors) == [
        "mid.a.y (mid.a, floor 1) imports mid.b.v (mid.b, beside it)",
        "mid.b.v (mid.b, floor 1) imports top.x (top, above it)"]


def test_the_floors_are_declared_once_and_cover_every_module():
    units = [unit for floor in FLOORS for unit in floor]
    assert len(units) == len(set(units)), "a unit declared twice"
    assert set(PACKAGES) <= set(units)
    for module in MODULES:
        unit = unit_of(module, FLOORS)
        assert unit is not None, f"{module} is on no floor"
        # A package split into floors declares each of its subpackages: a new one is placed
        # on purpose, not by default at the package's own (top) floor.
        split = any(u.startswith(unit[0] + ".") for u in units)
        assert not split or module == unit[0], (
            f"{module}: declare its floor in pyproject.toml [tool.kinoplan] floors")


@pytest.mark.slow
def test_no_import_runs_up_or_across_a_floor():
    offences = floor_offences(import_graph(), FLOORS)
    assert not offences, "\n".join(offences)
