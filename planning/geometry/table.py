"""Lookups in the shape registry and the pair table (``planning.geometry.registry``), with
the built-in shapes (``planning.geometry.shapes``) registered first: what the rest of the code
calls to find a shape or a distance function by name.
"""

from __future__ import annotations

from . import shapes as _builtins  # noqa: F401 - registers the built-in shapes
from .registry import (
    PairFunctions,
    ShapeKind,
    registered_pair,
    registered_pairs,
    registered_shape,
    registered_shapes,
)

__all__ = ["shape_kind", "shape_names", "pair_functions", "pairs"]


def shape_kind(name: str) -> ShapeKind:
    """The registered shape ``name`` (``KeyError`` if none)."""
    return registered_shape(name)


def shape_names() -> tuple[str, ...]:
    """The registered shapes' names, in registration order (the built-ins first)."""
    return tuple(registered_shapes())


def pair_functions(query: str, shape: str) -> PairFunctions:
    """The row ``(query, shape)`` of the pair table (``KeyError`` if none)."""
    return registered_pair(query, shape)


def pairs() -> tuple[PairFunctions, ...]:
    """Every row of the pair table."""
    return tuple(registered_pairs().values())
