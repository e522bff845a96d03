"""The exact stage: the real geometry, through FCL (python-fcl, BSD-3).

Used only for what the sphere stage flags (and for exact distances on request): a link's
URDF shapes (triangle meshes as ``fcl.BVHModel``, boxes, cylinders, spheres) or a D-H
link's capsule, against a scene object (boxes, spheres, cylinders, capsules, meshes) or
another link. A scene object's exact geometry is its shape's (``ShapeKind.exact`` in
``planning.geometry.registry``). A point cloud is checked point by point with exact
point-shape distances (the ``("point", shape)`` rows of the pair table): a point ``p`` of
radius ``r`` hits a shape when its distance is at most ``r``.

``exact_stage(model, scene)`` is the public entry: an ``ExactStage`` (built once per robot
model and scene, then kept) whose ``pair_collides`` / ``pair_distance`` settle one flagged
pair, and ``collide`` / ``distance`` two FCL objects; the compiled checker of
``planning.motion`` uses it.

Semantics, as FCL's: a mesh is its surface (triangles); a box, cylinder, sphere or capsule is
solid. So an object wholly inside a link mesh without touching its triangles is not a
collision for either stage. Touching (distance 0) is a collision. With a ``margin``, two
shapes collide when their distance is below it. Lengths in mm.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..geometry.distance import (
    box_distance,
    cylinder_distance,
    segment_distance,
    segment_frame,
    sphere_distance,
    triangle_distance,
)
from ..geometry.table import shape_kind

__all__ = ["ExactRobot", "ExactScene", "ExactStage", "exact_stage", "pair_collides",
           "pair_distance", "fcl_collide", "fcl_distance"]


def _fcl():
    import fcl

    return fcl


def _transform(T: np.ndarray):
    return _fcl().Transform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


def _bvh(V: np.ndarray, F: np.ndarray):
    fcl = _fcl()
    m = fcl.BVHModel()
    m.beginModel(len(V), len(F))
    m.addSubModel(np.ascontiguousarray(V, dtype=float), np.ascontiguousarray(F, dtype=np.int64))
    m.endModel()
    return m


class _Shape:
    """One exact shape in its owner's frame: ``kind``, ``T`` (owner -> shape), the FCL
    geometry and what point distances need (``size``, ``radius``, ``height``, triangles)."""

    def __init__(self, kind: str, T: np.ndarray, geom: Any, **data: Any) -> None:
        self.kind, self.T, self.geom, self.data = kind, T, geom, data

    def point_distance(self, W: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Distance ``(K,)`` of world points to the shape posed ``W`` in the world (signed
        for solids)."""
        if self.kind == "box":
            return box_distance(P, W[None], np.asarray(self.data["size"])[None])[:, 0]
        if self.kind == "cylinder":
            return cylinder_distance(P, W[None], np.array([self.data["radius"]]),
                                     np.array([self.data["height"]]))[:, 0]
        if self.kind == "sphere":
            return sphere_distance(P, W[None, :3, 3], np.array([self.data["radius"]]))[:, 0]
        if self.kind == "capsule":
            h = 0.5 * self.data["height"]
            a, b = W[:3, 3] - h * W[:3, 2], W[:3, 3] + h * W[:3, 2]
            return segment_distance(P, a[None], b[None])[:, 0] - self.data["radius"]
        L = (P - W[:3, 3]) @ W[:3, :3]
        tri = self.data["triangles"]
        out = np.full(len(P), np.inf)
        step = max(1, 4_000_000 // max(len(tri), 1))
        for s in range(0, len(P), step):
            out[s:s + step] = triangle_distance(L[s:s + step], tri[:, 0], tri[:, 1],
                                                tri[:, 2]).min(axis=1)
        return out


def link_shape(g: Any, meshes: Any, cache: dict) -> _Shape:
    fcl = _fcl()
    T = np.asarray(g.origin, dtype=float)
    if g.kind == "box":
        return _Shape("box", T, fcl.Box(*g.size), size=tuple(g.size))
    if g.kind == "cylinder":
        return _Shape("cylinder", T, fcl.Cylinder(g.radius, g.length), radius=g.radius,
                      height=g.length)
    if g.kind == "sphere":
        return _Shape("sphere", T, fcl.Sphere(g.radius), radius=g.radius)
    if g.mesh not in cache:
        data = meshes[g.mesh]
        V, F = np.asarray(data.vertices, dtype=float), np.asarray(data.faces, dtype=np.int64)
        cache[g.mesh] = (_bvh(V, F), V[F])
    geom, tri = cache[g.mesh]
    return _Shape("mesh", T, geom, triangles=tri)


class ExactRobot:
    """The exact shapes of a ``RobotCollisionModel``'s links and attached objects (FCL
    geometry built once). ``shapes``: per body with a rigid state frame (an imported
    robot's links, then the attachments; for a capsule model, the attachments only, after
    ``first_rigid`` capsules), its shapes in that frame."""

    def __init__(self, model: Any) -> None:
        self.model = model
        self.shapes: list[list[_Shape]] = []
        self.first_rigid = 0
        if model.kind == "imported":
            cache: dict = {}
            for k in model.link_index:
                link = model.source.links[int(k)]
                self.shapes.append([link_shape(g, model.source.meshes, cache)
                                    for g in link.collision])
        else:
            self.first_rigid = len(model.names) - len(model.attached)
        for a in model.attached:
            self.shapes.append(a.exact_shapes())

    def link_shapes(self, k: int, M: np.ndarray) -> list[tuple[_Shape, np.ndarray]]:
        """Link (or attachment) ``k``'s shapes and their world poses, from its state
        ``M (3, w)``."""
        if k >= self.first_rigid:
            T = np.eye(4)
            T[:3, :] = M
            return [(s, T @ s.T) for s in self.shapes[k - self.first_rigid]]
        # A capsule: [start | run] without attachments, [run | 0 | 0 | start] with them.
        A, E = (M[:, 3], M[:, 0]) if M.shape[1] == 4 else (M[:, 0], M[:, 1])
        r = float(self.model.capsule_radius[k])
        L = float(np.linalg.norm(E))
        fcl = _fcl()
        geom = fcl.Capsule(r, L) if L > 0 else fcl.Sphere(r)
        shape = _Shape("capsule" if L > 0 else "sphere", np.eye(4), geom, radius=r, height=L)
        return [(shape, segment_frame(A, A + E))]

    def objects(self, k: int, M: np.ndarray) -> list[tuple[Any, _Shape, np.ndarray]]:
        """FCL collision objects of link ``k`` at state ``M``, with their shapes."""
        fcl = _fcl()
        return [(fcl.CollisionObject(s.geom, _transform(W)), s, W)
                for s, W in self.link_shapes(k, M)]


class ExactScene:
    """The exact shapes of a ``CollisionScene``'s objects: FCL objects (posed in the world,
    built once) and, for point clouds, the points and a k-d tree."""

    def __init__(self, scene: Any) -> None:
        self.items: list[Any] = [shape_kind(o.type).exact(o) for o in scene.objects]


def fcl_collide(o1: Any, o2: Any, margin: float) -> bool:
    """Whether two FCL objects touch (``margin`` 0) or come closer than ``margin`` mm."""
    fcl = _fcl()
    if margin <= 0:
        return bool(fcl.collide(o1, o2, fcl.CollisionRequest(), fcl.CollisionResult()))
    d = fcl.distance(o1, o2, fcl.DistanceRequest(), fcl.DistanceResult())
    return d < margin


def fcl_distance(o1: Any, o2: Any) -> float:
    """FCL's distance (mm) of two objects, 0 when they touch or overlap."""
    fcl = _fcl()
    d = fcl.distance(o1, o2, fcl.DistanceRequest(), fcl.DistanceResult())
    return 0.0 if d < 0 else float(d)


def _near_points(item: tuple, centre: np.ndarray, reach: float) -> np.ndarray:
    _, P, tree, r = item
    idx = tree.query_ball_point(centre, reach + r)
    return P[np.asarray(idx, dtype=np.intp)]


def pair_collides(robot: ExactRobot, scene: ExactScene | None, M: np.ndarray, a: int,
                  b: int, is_self: bool, margin: float = 0.0) -> bool:
    """Whether link ``a`` touches scene object ``b`` (``is_self`` False) or link ``b``
    (True) exactly, at link states ``M (L, 3, w)``."""
    A = robot.objects(a, M[a])
    if is_self:
        B = robot.objects(b, M[b])
        return any(fcl_collide(o1, o2, margin) for o1, _, _ in A for o2, _, _ in B)
    item = scene.items[b]
    if item[0] == "fcl":
        return any(fcl_collide(o1, item[1], margin) for o1, _, _ in A)
    d = _points_distance(robot, item, a, M, max(margin, 0.0))
    return d < margin if margin > 0 else d <= 0


def _points_distance(robot: ExactRobot, item: tuple, a: int, M: np.ndarray,
                     reach: float) -> float:
    """Least distance (mm) from link ``a`` to the balls of a point cloud (negative inside
    a solid shape), or ``inf`` when no ball comes within ``reach`` of the link's bounding
    ball."""
    tree = robot.model.tree
    centre = M[a] @ tree.root[a]
    P = _near_points(item, centre, float(tree.root_r[a]) + reach)
    if len(P) == 0:
        return math.inf
    best = min(float(s.point_distance(W, P).min()) for s, W in robot.link_shapes(a, M[a]))
    return best - item[3]


def pair_distance(robot: ExactRobot, scene: ExactScene | None, M: np.ndarray, a: int,
                  b: int, is_self: bool, reach: float = math.inf) -> float:
    """Exact distance (mm; 0 when touching or overlapping) between link ``a`` and scene
    object ``b`` or link ``b``. For a point cloud, the points within ``reach`` of the
    link's bounding ball are looked at (``inf`` if none)."""
    if not is_self and scene.items[b][0] == "points":
        return max(_points_distance(robot, scene.items[b], a, M, min(reach, 1e12)), 0.0)
    A = robot.objects(a, M[a])
    if is_self:
        B = robot.objects(b, M[b])
        return min(fcl_distance(o1, o2) for o1, _, _ in A for o2, _, _ in B)
    return min(fcl_distance(o1, scene.items[b][1]) for o1, _, _ in A)


class ExactStage:
    """The exact stage of one robot model in one scene (or none): the FCL shapes of the
    links (``robot``, an ``ExactRobot``) and of the scene objects (``world``, an
    ``ExactScene`` or None)."""

    def __init__(self, robot: ExactRobot, world: ExactScene | None) -> None:
        self.robot = robot
        self.world = world

    def pair_collides(self, M: np.ndarray, a: int, b: int, is_self: bool,
                      margin: float = 0.0) -> bool:
        """Whether link ``a`` touches scene object ``b`` (``is_self`` False) or link ``b``
        (True), or comes closer than ``margin`` mm, at link states ``M (L, 3, w)``."""
        return pair_collides(self.robot, self.world, M, a, b, is_self, margin)

    def pair_distance(self, M: np.ndarray, a: int, b: int, is_self: bool,
                      reach: float = math.inf) -> float:
        """Exact distance (mm, 0 in contact) of link ``a`` and object or link ``b``."""
        return pair_distance(self.robot, self.world, M, a, b, is_self, reach=reach)

    def is_fcl(self, b: int) -> bool:
        """Whether scene object ``b`` is one FCL object (``item(b)``), not a point cloud."""
        return self.world.items[b][0] == "fcl"

    def item(self, b: int) -> Any:
        """The FCL object of scene object ``b`` (see ``is_fcl``)."""
        return self.world.items[b][1]

    collide = staticmethod(fcl_collide)
    distance = staticmethod(fcl_distance)


def exact_stage(model: Any, scene: Any = None) -> ExactStage:
    """The exact stage of a ``RobotCollisionModel`` in a ``CollisionScene`` (or None): the
    links' FCL shapes are built once per model and the objects' once per scene, then kept
    on them."""
    robot = model.__dict__.get("_exact")
    if robot is None:
        robot = ExactRobot(model)
        object.__setattr__(model, "_exact", robot)
    world = None
    if scene is not None:
        world = scene._exact
        if world is None:
            world = ExactScene(scene)
            scene._exact = world
    return ExactStage(robot, world)
