"""The built-in shapes, one module each; importing this package registers them (in this
order, which is the order error messages list the known types in).

A module defines its parser, writer, bounds, kernel parameters, exact geometry and cover by
point-path obstacles, and registers them with its rows of the pair table
(``planning.geometry.registry``). See docs/extending.md, "Adding a collision shape".
"""

from __future__ import annotations

# isort: off
# The order the shapes register in: the order error messages list the known types in.
from . import box, sphere, cylinder, capsule, mesh, points  # noqa: F401
# isort: on

__all__: list[str] = []
