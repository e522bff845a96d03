"""Collision checking of robots against a site's geometry and themselves.

The shapes themselves (the scene objects' API format, validation, caps, distances, ball
coverings) are ``planning.geometry``'s; ``OBJECT_TYPES``, ``SceneObject``, the caps and
``load_mesh_file`` are re-exported here for the service.

* ``scene``: ``CollisionScene``, the objects and their query structures (exact distances
  through the shape registry, ball sets for meshes and clouds, a distance grid);
* ``moveit``: MoveIt planning scenes to objects (``scene_from_moveit``) and back;
* ``robot``: ``RobotCollisionModel``, sphere trees on an imported robot's links or on a
  D-H / PoE robot's link capsules, and its self-collision pairs;
* ``checker``: ``check`` (a ``CollisionReport``) and ``collides`` (yes/no, for planners):
  the sphere stage, then the exact stage (``exact``, FCL) for what the spheres flag;
* ``exact``: the exact stage, public for the compiled checker of ``planning.motion``:
  ``exact_stage(model, scene)`` gives an ``ExactStage`` whose ``pair_collides`` and
  ``pair_distance`` settle the pairs the sphere stage flags.

Design, guarantees and caps: docs/collision.md. Lengths in mm, poses 4x4. The names below
load their module on first use, so importing this package costs nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from ..geometry.objects import MAX_OBJECTS as MAX_OBJECTS
    from ..geometry.objects import SceneObject as SceneObject
    from ..geometry.shapes.mesh import MAX_MESH_TRIANGLES as MAX_MESH_TRIANGLES
    from ..geometry.shapes.mesh import MAX_SCENE_TRIANGLES as MAX_SCENE_TRIANGLES
    from ..geometry.shapes.mesh import MESH_FILE_TYPES as MESH_FILE_TYPES
    from ..geometry.shapes.mesh import load_mesh_file as load_mesh_file
    from ..geometry.shapes.points import MAX_POINTS as MAX_POINTS
    from .attached import Attachment as Attachment
    from .checker import CollisionReport as CollisionReport
    from .checker import check as check
    from .checker import collides as collides
    from .exact import ExactStage as ExactStage
    from .exact import exact_stage as exact_stage
    from .moveit import scene_from_moveit as scene_from_moveit
    from .moveit import scene_to_moveit as scene_to_moveit
    from .robot import RobotCollisionModel as RobotCollisionModel
    from .scene import OBJECT_TYPES as OBJECT_TYPES
    from .scene import CollisionScene as CollisionScene

#: Public name -> the module it loads from on first use.
_LAZY = {
    "Attachment": "attached",
    "CollisionReport": "checker",
    "check": "checker",
    "collides": "checker",
    "scene_from_moveit": "moveit",
    "scene_to_moveit": "moveit",
    "RobotCollisionModel": "robot",
    "CollisionScene": "scene",
    "OBJECT_TYPES": "scene",
    "ExactStage": "exact",
    "exact_stage": "exact",
    # The shapes' own names, from planning.geometry (relative to this package: "..").
    "MAX_MESH_TRIANGLES": ".geometry.shapes.mesh",
    "MAX_OBJECTS": ".geometry.objects",
    "MAX_POINTS": ".geometry.shapes.points",
    "MAX_SCENE_TRIANGLES": ".geometry.shapes.mesh",
    "MESH_FILE_TYPES": ".geometry.shapes.mesh",
    "SceneObject": ".geometry.objects",
    "load_mesh_file": ".geometry.shapes.mesh",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
