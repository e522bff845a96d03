"""The registry of shapes and the table of their pair functions: one place that knows every
shape by name.

A shape module (``planning.geometry.shapes.box`` and its siblings, or a module of your own)
registers

* a ``ShapeKind``: its name (the JSON ``type``), its fields, its parser from the JSON spec,
  its writer back to JSON, its bounds, its compiled-kernel code and parameters, its exact
  (FCL) geometry, its cover by point-path obstacles and the scene budget it draws on;
* its rows of the pair table (``register_pair``): for a query (``"point"``: signed distances
  of points to objects of the shape; ``"segment"``: of segments, for point paths and
  envelopes), the vectorised Python function and, where the compiled checker needs one, the
  name of its numba kernel in ``planning.geometry.kernels``.

Everything that used to branch on a shape's name looks it up instead (through
``planning.geometry.table``, which loads the built-in shapes first): parsing
(``planning.geometry.objects``), the collision scene's distances and bounds, the exact stage,
the compiled checker's arrays, and the conversion of a stored scene into point-path
obstacles.

The compiled kernels cannot call a Python dict, so they switch on an integer code: the codes
are ``KERNEL_CODES`` below, the one table that ``planning.geometry.kernels`` compiles in. A
shape without a code has no compiled kernel; the joint-space checker then runs its scenes on
the Python path (``planning.collision.collides``), with the same answers.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "KERNEL_CODES",
    "Budget",
    "ShapeKind",
    "PairFunctions",
    "register_shape",
    "unregister_shape",
    "register_pair",
    "registered_shape",
    "registered_pair",
    "registered_shapes",
    "registered_pairs",
]

#: Codes of the compiled point kernels (``planning.geometry.kernels`` switches on them):
#: one row per kernel. ``"balls"`` is the ball set that stands for meshes and point clouds.
#: numba freezes these into its cached machine code: change them together with
#: ``planning.geometry.kernels`` (whose cache is keyed on its own source).
KERNEL_CODES: Mapping[str, int] = {"box": 0, "cylinder": 1, "sphere": 2, "capsule": 3,
                                   "balls": 4}


@dataclass(frozen=True)
class Budget:
    """A scene-wide budget an object draws on: ``count(obj)`` units (points, triangles) of
    at most ``cap`` over the whole scene; over it, ``FieldError`` at the object's ``field``
    with ``message``."""

    name: str
    count: Callable[[Any], int]
    cap: int
    field: str
    message: str


@dataclass(frozen=True)
class ShapeKind:
    """One shape, as its module registers it. Objects are ``SceneObject``s
    (``planning.geometry.objects``); poses are ``T_world_object (4, 4)``, lengths mm.

    * ``name``: the JSON ``type``; ``required``, ``optional``: its own fields (beside
      ``type``, ``id``, ``pose``);
    * ``parse(data, loc, resolve_mesh) -> dict``: the validated fields of a ``SceneObject``
      from the JSON dict (``FieldError`` at ``loc + (field,)``), checked in the order the
      shape wants its errors reported;
    * ``to_dict(obj) -> dict``: its own fields back in the JSON format;
    * ``bounds(obj) -> (lower (3,), upper (3,))``: world axis-aligned bounds (None for a
      ball-set shape: the bounds of its balls);
    * ``pack(objs) -> tuple``: the arrays its ``("point", name)`` twin takes for several
      objects at once (primitives);
    * ``balls(obj, resolution) -> (K, 4)``: for a shape the sphere stage sees as a ball set
      (meshes, point clouds), balls whose union contains it;
    * ``code``: its compiled kernel's code (``KERNEL_CODES``), None for none;
      ``kernel_params(obj) -> (T_world_local (4, 4), par (4,))``: the kernel's local frame
      and parameters (primitives);
    * ``exact(obj) -> item``: the exact stage's item (``("fcl", fcl.CollisionObject)`` or
      ``("points", P, tree, radius)``);
    * ``path_cover(obj) -> [obstacle dicts]``: point-path obstacles (spheres, axis-aligned
      boxes, capsules) that contain it, never smaller;
    * ``budget``: the scene-wide budget it draws on, if any.
    """

    name: str
    required: tuple[str, ...]
    optional: tuple[str, ...]
    parse: Callable[[dict, tuple, Any], dict[str, Any]]
    to_dict: Callable[[Any], dict[str, Any]]
    bounds: Callable[[Any], tuple[np.ndarray, np.ndarray]] | None = None
    pack: Callable[[list], tuple] | None = None
    balls: Callable[[Any, float], np.ndarray] | None = None
    code: int | None = None
    kernel_params: Callable[[Any], tuple[np.ndarray, np.ndarray]] | None = None
    exact: Callable[[Any], tuple] | None = None
    path_cover: Callable[[Any], list[dict[str, Any]]] | None = None
    budget: Budget | None = None


@dataclass(frozen=True)
class PairFunctions:
    """A row of the pair table: ``query`` against ``shape``, the vectorised Python function
    ``twin`` and the name of the compiled ``kernel`` in ``planning.geometry.kernels`` (None
    where nothing compiled needs one). For ``"point"`` rows ``twin(P (K, 3), *packed)
    -> (K, n)`` with ``packed`` from the shape's ``pack`` (or ``(balls (M, 4),)`` for
    ``"balls"``)."""

    query: str
    shape: str
    twin: Callable[..., Any]
    kernel: str | None = None


_SHAPES: dict[str, ShapeKind] = {}
_PAIRS: dict[tuple[str, str], PairFunctions] = {}
_LOCK = threading.Lock()


def register_shape(kind: ShapeKind) -> ShapeKind:
    """Add a shape (``ValueError`` if its name or its code is taken, or its code is not one
    of ``KERNEL_CODES``). Returns it."""
    if not isinstance(kind, ShapeKind):
        raise TypeError("register_shape takes a ShapeKind")
    if not kind.name or not kind.name.isidentifier():
        raise ValueError(f"shape name {kind.name!r} must be a plain identifier")
    if kind.code is not None and kind.code not in KERNEL_CODES.values():
        raise ValueError(f"shape {kind.name!r}: code {kind.code} has no compiled kernel "
                         f"(codes: {dict(KERNEL_CODES)})")
    if kind.code is not None and kind.code != KERNEL_CODES["balls"] \
            and kind.kernel_params is None:
        raise ValueError(f"shape {kind.name!r}: a compiled code needs kernel_params")
    if kind.balls is None and kind.pack is None:
        raise ValueError(f"shape {kind.name!r}: give pack (and a point pair) or balls")
    with _LOCK:
        if kind.name in _SHAPES:
            raise ValueError(f"shape {kind.name!r} is already registered")
        if kind.code is not None and kind.code != KERNEL_CODES["balls"] and any(
                k.code == kind.code for k in _SHAPES.values()):
            raise ValueError(f"shape {kind.name!r}: code {kind.code} is already used")
        _SHAPES[kind.name] = kind
    return kind


def unregister_shape(name: str) -> None:
    """Remove a shape and its rows of the pair table (``KeyError`` if unknown)."""
    with _LOCK:
        del _SHAPES[name]
        for key in [k for k in _PAIRS if k[1] == name]:
            del _PAIRS[key]


def register_pair(query: str, shape: str, twin: Callable[..., Any],
                  kernel: str | None = None) -> PairFunctions:
    """Add the row ``(query, shape)`` of the pair table (``ValueError`` if taken)."""
    row = PairFunctions(query, shape, twin, kernel)
    with _LOCK:
        if (query, shape) in _PAIRS:
            raise ValueError(f"the pair ({query!r}, {shape!r}) is already registered")
        _PAIRS[(query, shape)] = row
    return row


def registered_shape(name: str) -> ShapeKind:
    """The shape ``name`` registered so far (``KeyError`` if none)."""
    return _SHAPES[name]


def registered_pair(query: str, shape: str) -> PairFunctions:
    """The row ``(query, shape)`` of the pair table registered so far (``KeyError``)."""
    return _PAIRS[(query, shape)]


def registered_shapes() -> dict[str, ShapeKind]:
    """The shapes registered so far, by name in registration order (a copy; the lookups of
    ``planning.geometry.table`` load the built-ins first)."""
    with _LOCK:
        return dict(_SHAPES)


def registered_pairs() -> dict[tuple[str, str], PairFunctions]:
    """The rows of the pair table registered so far (a copy)."""
    with _LOCK:
        return dict(_PAIRS)
