"""Package names loaded from their module on first use (PEP 562), shared by the packages of
the library so that ``import kinematics`` or ``import planning`` stays cheap.

A package lists ``_LAZY = {name: module}`` and ends with::

    __getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, lazy: Mapping[str, str], namespace: dict[str, Any]
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``(__getattr__, __dir__)`` for ``package``: ``lazy[name]`` is the module (relative to
    the package) that defines ``name``; a loaded name is kept in ``namespace``."""

    def __getattr__(name: str) -> Any:
        module = lazy.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{module}", package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(lazy))

    return __getattr__, __dir__
