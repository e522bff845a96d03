"""Route modules translate HTTP and nothing else: what two of them share lives outside
``app/api/routes`` (``app.api.common``, ``app.api.deps``, ``app.collision_models``), so no
route module imports another."""

from __future__ import annotations

import ast
from pathlib import Path

import app.api.routes as routes_package

ROUTES = Path(routes_package.__file__).parent
PACKAGE = "app.api.routes"


def imported_modules(source: str, module: str) -> set[str]:
    """The absolute names of the modules ``source`` (the text of ``module``) imports, at
    any depth of the file (imports inside functions too); ``from P import name`` counts as
    ``P.name`` as well, since ``name`` may be a module."""
    package = module.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                parent = ".".join(base + ([node.module] if node.module else []))
            else:
                parent = node.module or ""
            out.add(parent)
            out.update(f"{parent}.{alias.name}" for alias in node.names)
    return out


def route_modules() -> dict[str, str]:
    return {f"{PACKAGE}.{p.stem}": p.read_text() for p in sorted(ROUTES.glob("*.py"))
            if p.stem != "__init__"}


def test_the_scan_sees_every_way_of_importing_a_sibling():
    module = f"{PACKAGE}.motion"
    for source in ("from .collision import resolve_scene\n",
                   "def f():\n    from .collision import resolve_scene\n",
                   "from . import collision\n",
                   "import app.api.routes.collision\n",
                   "from app.api.routes.collision import x\n"):
        assert f"{PACKAGE}.collision" in imported_modules(source, module), source
    assert f"{PACKAGE}.common" not in imported_modules("from ..common import joint_rows\n",
                                                       module)


def test_no_route_module_imports_another():
    modules = route_modules()
    assert len(modules) >= 10
    for name, source in modules.items():
        siblings = imported_modules(source, name) & (set(modules) - {name})
        assert not siblings, f"{name} imports {sorted(siblings)}"
