"""A robot's collision model drawn as translucent balls that follow the robot.

The balls are the leaf spheres of ``planning.collision.RobotCollisionModel.spheres(q)``: an
imported robot's sphere trees on its URDF collision geometry, or the balls along a D-H / PoE
robot's link capsules. They are one instanced node per arm (``<root>/collision``, viser's
batched meshes: one sphere mesh, a position and a scale per ball), so moving the robot sends
the centres and nothing else. Lengths mm in, metres in the scene.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .scene import MM_TO_M

__all__ = ["CollisionSpheres", "COLLISION_COLOR", "COLLISION_OPACITY"]

COLLISION_COLOR = (255, 60, 60)
COLLISION_OPACITY = 0.45


def _unit_sphere() -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    return np.asarray(s.vertices, dtype=np.float32), np.asarray(s.faces, dtype=np.uint32)


class CollisionSpheres:
    """The balls of ``model`` (a ``RobotCollisionModel``) at ``q (dof,)`` as the node
    ``name``; ``update(q)`` moves them. Not thread-safe by itself (the viewer's lock)."""

    def __init__(self, scene: Any, name: str, model: Any, q,
                 color: tuple[int, int, int] = COLLISION_COLOR,
                 opacity: float = COLLISION_OPACITY) -> None:
        self.name = name
        self.model = model
        balls = np.asarray(model.spheres(np.asarray(q, dtype=float)))  # (S, 4) mm
        self.count = int(len(balls))
        V, F = _unit_sphere()
        n = self.count
        self.handle = scene.add_batched_meshes_simple(
            name, V, F, batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
            batched_positions=balls[:, :3] * MM_TO_M, batched_scales=balls[:, 3] * MM_TO_M,
            batched_colors=color, opacity=opacity, lod="off", cast_shadow=False,
            receive_shadow=False)
        self.balls = balls

    def update(self, q) -> np.ndarray:
        """Move the balls to configuration ``q (dof,)``; returns them ``(S, 4)`` mm."""
        balls = np.asarray(self.model.spheres(np.asarray(q, dtype=float)))
        self.handle.batched_positions = balls[:, :3] * MM_TO_M
        self.balls = balls
        return balls

    def bounds_mm(self) -> tuple[np.ndarray, np.ndarray]:
        r = self.balls[:, 3:]
        return (self.balls[:, :3] - r).min(axis=0), (self.balls[:, :3] + r).max(axis=0)

    def remove(self) -> None:
        self.handle.remove()
