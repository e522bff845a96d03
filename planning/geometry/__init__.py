"""Geometry: the shapes, their poses and bounds, and one table of distance functions keyed
by shape pair, shared by point paths, drilling envelopes, the arm collision checker and the
scene store.

* ``registry``: ``ShapeKind`` and ``register_shape`` (each shape module registers its name,
  parser, bounds, kernel code and exact geometry), and the pair table (``register_pair``:
  the Python function and the compiled kernel of each query against each shape);
  ``table``: the lookups (``shape_kind``, ``pair_functions``), the built-ins loaded first;
* ``shapes``: the built-in shapes, one module each (box, sphere, cylinder, capsule, mesh,
  points);
* ``objects``: ``SceneObject`` and the API format, parsed through the registry;
* ``fields``: validation of numbers, vectors, arrays and poses with errors naming the field;
* ``distance``: point-to-shape distances (the Python twins of ``kernels``);
* ``segments``: segment-to-shape distances (point paths, capsule envelopes);
* ``spheres``, ``balls``: conservative ball coverings and ball sets;
* ``kernels`` (numba), ``compiled``: the compiled point kernels and a scene's arrays for them.

Geometry imports nothing of ``planning`` but its own modules (and ``kinematics``). Lengths in
mm, poses ``T_world_object (4, 4)``. The names below load their module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from .objects import MAX_OBJECTS as MAX_OBJECTS
    from .objects import SceneObject as SceneObject
    from .objects import object_types as object_types
    from .objects import parse_object as parse_object
    from .objects import parse_objects as parse_objects
    from .registry import KERNEL_CODES as KERNEL_CODES
    from .registry import Budget as Budget
    from .registry import PairFunctions as PairFunctions
    from .registry import ShapeKind as ShapeKind
    from .registry import register_pair as register_pair
    from .registry import register_shape as register_shape
    from .registry import unregister_shape as unregister_shape
    from .table import pair_functions as pair_functions
    from .table import pairs as pairs
    from .table import shape_kind as shape_kind
    from .table import shape_names as shape_names

#: Public name -> the module it loads from on first use.
_LAZY = {
    "MAX_OBJECTS": "objects",
    "SceneObject": "objects",
    "object_types": "objects",
    "parse_object": "objects",
    "parse_objects": "objects",
    "KERNEL_CODES": "registry",
    "Budget": "registry",
    "PairFunctions": "registry",
    "ShapeKind": "registry",
    "pair_functions": "table",
    "pairs": "table",
    "register_pair": "registry",
    "register_shape": "registry",
    "shape_kind": "table",
    "shape_names": "table",
    "unregister_shape": "registry",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
