"""Collision checking of robots against a site's geometry and themselves.

* ``shapes``: scene objects in the API format (box, sphere, cylinder, capsule, mesh, point
  cloud), their validation and caps, ``load_mesh_file`` for uploaded STL/OBJ/PLY files;
* ``scene``: ``CollisionScene``, the objects and their query structures (exact primitive
  distances, ball sets for meshes and clouds, a distance grid);
* ``moveit``: MoveIt planning scenes to objects (``scene_from_moveit``) and back;
* ``spheres``: conservative sphere coverings (the union of the balls contains the shape);
* ``robot``: ``RobotCollisionModel``, sphere trees on an imported robot's links or on a
  D-H / PoE robot's link capsules, and its self-collision pairs;
* ``checker``: ``check`` (a ``CollisionReport``) and ``collides`` (yes/no, for planners):
  the sphere stage, then the exact stage (``exact``, FCL) for what the spheres flag;
* ``distance``: exact point-to-shape distances.

Design, guarantees and caps: docs/collision.md. Lengths in mm, poses 4x4. The names below
load their module on first use, so importing this package costs nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from .checker import CollisionReport as CollisionReport
    from .checker import check as check
    from .checker import collides as collides
    from .moveit import scene_from_moveit as scene_from_moveit
    from .moveit import scene_to_moveit as scene_to_moveit
    from .robot import RobotCollisionModel as RobotCollisionModel
    from .scene import CollisionScene as CollisionScene
    from .shapes import MAX_MESH_TRIANGLES as MAX_MESH_TRIANGLES
    from .shapes import MAX_OBJECTS as MAX_OBJECTS
    from .shapes import MAX_POINTS as MAX_POINTS
    from .shapes import MAX_SCENE_TRIANGLES as MAX_SCENE_TRIANGLES
    from .shapes import MESH_FILE_TYPES as MESH_FILE_TYPES
    from .shapes import OBJECT_TYPES as OBJECT_TYPES
    from .shapes import SceneObject as SceneObject
    from .shapes import load_mesh_file as load_mesh_file

#: Public name -> the module it loads from on first use.
_LAZY = {
    "CollisionReport": "checker",
    "check": "checker",
    "collides": "checker",
    "scene_from_moveit": "moveit",
    "scene_to_moveit": "moveit",
    "RobotCollisionModel": "robot",
    "CollisionScene": "scene",
    "MAX_MESH_TRIANGLES": "shapes",
    "MAX_OBJECTS": "shapes",
    "MAX_POINTS": "shapes",
    "MAX_SCENE_TRIANGLES": "shapes",
    "MESH_FILE_TYPES": "shapes",
    "OBJECT_TYPES": "shapes",
    "SceneObject": "shapes",
    "load_mesh_file": "shapes",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
