"""A finished job's motion as one self-contained HTML page, for ``GET /jobs/{id}/replay.html``.

The page plays the job offline in any browser (opened from disk, no network): the robot, the
scene it planned in and the tool's path, with a time slider, Play/Pause, orbit (drag) and
zoom (wheel). Everything is computed here and embedded as JSON in the page
(``replay_page.html``, shipped with the package), whose small script draws it on a 2D canvas
(painter's algorithm: triangles moved by their node's pose, sorted by depth, filled with
Lambert shading). No library, font or file is fetched.

Which jobs: those ``app.trajectory_export`` reads a trajectory from (``extract`` and
``select``: motion, path with a robot, multiarm with every arm, tracking), with its errors
(``ExportError``). What is drawn:

* the robot: an imported robot's own geometry (its visual shapes, else its collision
  shapes) in each link's frame, posed by ``ImportedRobot.link_poses``; any other robot as
  solids along its chain (``fk_frames``, as the viewer draws it): a base disc, a cylinder
  per link, a ball per joint, the tool's axes;
* the scene: a motion job's objects (``collision_scene`` of its params; box, sphere,
  cylinder, capsule, mesh as triangles, points as dots), a path job's obstacles and bounds, a
  multiarm plan's holes, a tracking job's desired tool path;
* the tool path: FK of the samples, one polyline per arm.

Data (mm, s): ``nodes`` (triangles ``v`` in the frame of their pose ``pose``, or in the world
frame for ``pose`` None), ``poses`` (per key, 12 numbers per frame: the rows of the 3x4
affine map of that frame; a stretched link cylinder is an affine map, not a rigid one),
``t`` (the frame times), ``lines`` and ``points``. Triangles are capped at
``MAX_TRIANGLES`` (meshes decimated by vertex clustering), frames at ``MAX_FRAMES`` (every
k-th sample and the last), points at ``MAX_POINTS``.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import numpy as np
import orjson

from kinematics.fk import fk, fk_frames, joint_axes
from kinematics.model import RobotModel
from kinematics.rigs import builtin_rig

from .trajectory_export import Track, extract, select

__all__ = ["MAX_FRAMES", "MAX_POINTS", "MAX_TRIANGLES", "Replay", "build_replay",
           "replay_html", "decimate"]

#: Most triangles in one page (robot and scene together); meshes beyond it are decimated.
MAX_TRIANGLES = 20_000
#: Most frames (trajectory samples) embedded: longer trajectories keep every k-th and the last.
MAX_FRAMES = 600
#: Most points of point clouds drawn (every k-th beyond).
MAX_POINTS = 5_000
#: Meshes of at most this many triangles are never decimated (the solids made here).
SMALL_MESH = 600
#: Decimals kept: rotation entries, then lengths in mm.
ROT_DECIMALS, MM_DECIMALS = 5, 2

LINK_COLOR = (230, 120, 20)
JOINT_COLOR = (60, 60, 70)
BASE_COLOR = (90, 90, 100)
MESH_COLOR = (175, 178, 185)
OBJECT_COLOR = (120, 140, 170)
OBSTACLE_COLOR = (200, 70, 70)
PATH_COLOR = (20, 160, 60)
DESIRED_COLOR = (30, 120, 230)
ARM_COLORS = {"left": (30, 120, 230), "middle": (20, 160, 60), "right": (200, 60, 160)}
AXIS_COLORS = ((220, 40, 40), (40, 180, 40), (40, 80, 230))
TEMPLATE = "replay_page.html"
DATA_MARK = "/*__REPLAY_DATA__*/null"
TITLE_MARK = "__REPLAY_TITLE__"

Models = Callable[[str], RobotModel]
Imported = Callable[[str], Any]


# ---- triangle solids ------------------------------------------------------------------------
def box_mesh(size: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """A box centred on the origin with full side lengths ``size (3,)``: 8 vertices, 12
    triangles."""
    h = 0.5 * np.asarray(size, dtype=np.float64)
    V = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)],
                 dtype=np.float64) * h
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return V, F


def sphere_mesh(radius: float, subdivisions: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """An icosphere of ``radius`` about the origin (80 triangles at 1 subdivision)."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=float(radius))
    return np.asarray(s.vertices, dtype=np.float64), np.asarray(s.faces, dtype=np.int64)


def cylinder_mesh(radius: float, z0: float, z1: float, sections: int = 16
                  ) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder of ``radius`` along z from ``z0`` to ``z1`` (4 triangles a section)."""
    a = np.linspace(0.0, 2.0 * math.pi, sections, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    V = np.vstack([np.column_stack([ring, np.full(sections, z0)]),
                   np.column_stack([ring, np.full(sections, z1)]),
                   [[0.0, 0.0, z0], [0.0, 0.0, z1]]])
    i = np.arange(sections)
    j = (i + 1) % sections
    n = sections
    F = np.vstack([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i]),
                   np.column_stack([np.full(n, 2 * n), j, i]),
                   np.column_stack([np.full(n, 2 * n + 1), n + i, n + j])])
    return V, F


def capsule_mesh(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule between the points ``a (3,)`` and ``b (3,)``."""
    import trimesh

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    length = float(np.linalg.norm(b - a))
    c = trimesh.creation.capsule(height=length, radius=float(radius), count=[12, 12])
    V = np.asarray(c.vertices, dtype=np.float64)
    R = _frame_along((b - a) / length if length > 0 else np.array([0.0, 0.0, 1.0]))
    return V @ R.T + 0.5 * (a + b), np.asarray(c.faces, dtype=np.int64)


def _frame_along(d: np.ndarray) -> np.ndarray:
    """A rotation ``(3, 3)`` whose third column is the unit vector ``d (3,)``."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(ref, d)
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(d, u), d])


def transformed(V: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Vertices ``(V, 3)`` moved by the pose ``T (4, 4)``."""
    T = np.asarray(T, dtype=np.float64)
    return np.asarray(V, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]


def decimate(V: np.ndarray, F: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh ``(V (n, 3), F (m, 3))`` with at most ``target`` triangles (about), by vertex
    clustering: vertices in one cell of a grid merge to their mean, triangles that collapse
    go. The cell is the smallest of a bisection over sizes that meets ``target``."""
    V, F = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)
    if len(F) <= target:
        return V, F
    extent = float(np.ptp(V, axis=0).max()) if len(V) else 0.0
    if extent <= 0.0:
        return V[:0], F[:0]

    def cluster(cell: float) -> tuple[np.ndarray, np.ndarray]:
        keys = np.floor((V - V.min(axis=0)) / cell).astype(np.int64)  # < 1e4 + 1 per axis
        span = keys.max(axis=0) + 1
        flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
        _, inverse = np.unique(flat, return_inverse=True)
        inverse = inverse.reshape(-1)
        count = np.bincount(inverse)
        merged = np.column_stack([np.bincount(inverse, V[:, k]) for k in range(3)])
        merged /= count[:, None]
        G = inverse[F]
        keep = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])
        G = G[keep]
        S = np.sort(G, axis=1)
        n = np.int64(len(merged))
        _, first = np.unique((S[:, 0] * n + S[:, 1]) * n + S[:, 2], return_index=True)
        return merged, G[np.sort(first)]

    lo, hi = math.log(extent * 1e-4), math.log(extent)
    best = cluster(extent)
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        out = cluster(math.exp(mid))
        if len(out[1]) <= target:
            best, hi = out, mid
        else:
            lo = mid
    used = np.unique(best[1])
    remap = np.full(len(best[0]), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return best[0][used], remap[best[1]]


# ---- what the page holds --------------------------------------------------------------------
@dataclass
class Node:
    """Triangles ``V (n, 3)`` mm, ``F (m, 3)`` in the frame of pose ``pose`` (None: world)."""

    name: str
    V: np.ndarray
    F: np.ndarray
    color: tuple[int, int, int]
    pose: str | None = None
    opacity: float = 1.0


@dataclass
class Replay:
    """What one page shows; ``data()`` is the JSON embedded in it."""

    job: str
    kind: str
    t: np.ndarray
    nodes: list[Node] = field(default_factory=list)
    poses: dict[str, np.ndarray] = field(default_factory=dict)  # key -> (frames, 3, 4)
    lines: list[dict[str, Any]] = field(default_factory=list)
    points: list[dict[str, Any]] = field(default_factory=list)
    robots: list[str] = field(default_factory=list)
    links: list[str] = field(default_factory=list)  # pose keys of the robots' links
    notes: list[str] = field(default_factory=list)

    @property
    def triangles(self) -> int:
        return int(sum(len(n.F) for n in self.nodes))

    def cap_triangles(self, budget: int = MAX_TRIANGLES) -> None:
        """Decimate the larger meshes so that all triangles fit ``budget``."""
        small = sum(len(n.F) for n in self.nodes if len(n.F) <= SMALL_MESH)
        large = [n for n in self.nodes if len(n.F) > SMALL_MESH]
        total = sum(len(n.F) for n in large)
        room = max(budget - small, 12 * len(large))
        if total <= room:
            return
        for n in large:
            n.V, n.F = decimate(n.V, n.F, max(12, int(len(n.F) * room / total)))
        self.notes.append(f"meshes decimated to {self.triangles} triangles")

    def bounds(self) -> tuple[list[float], list[float]]:
        """World bounds (mm) of everything at every frame (vertices moved by their poses)."""
        pts = []
        for n in self.nodes:
            if not len(n.V):
                continue
            if n.pose is None:
                pts.append(n.V)
                continue
            A = self.poses[n.pose]
            lo, hi = n.V.min(axis=0), n.V.max(axis=0)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                for z in (lo[2], hi[2])])
            pts.append((np.einsum("fij,cj->fci", A[:, :, :3], corners)
                        + A[:, None, :, 3]).reshape(-1, 3))
        pts += [np.asarray(x["pts"]).reshape(-1, 3) for x in self.lines + self.points]
        P = np.vstack(pts) if pts else np.zeros((1, 3))
        return P.min(axis=0).tolist(), P.max(axis=0).tolist()

    def data(self) -> dict[str, Any]:
        lo, hi = self.bounds()
        keys = list(self.poses)

        def rounded(A: np.ndarray) -> np.ndarray:
            out = np.round(A, ROT_DECIMALS)
            out[..., 3] = np.round(A[..., 3], MM_DECIMALS)
            return out.reshape(-1)

        nodes = [{"name": n.name, "color": list(n.color), "opacity": n.opacity,
                  "pose": n.pose, "v": np.round(n.V, MM_DECIMALS).reshape(-1),
                  "f": np.asarray(n.F, dtype=np.int64).reshape(-1)} for n in self.nodes]
        return {"job": self.job, "kind": self.kind, "robots": self.robots,
                "t": np.round(self.t, 6), "frames": len(self.t), "bounds": [lo, hi],
                "poses": {k: rounded(self.poses[k]) for k in keys}, "nodes": nodes,
                "links": self.links, "lines": self.lines, "points": self.points,
                "triangles": self.triangles, "notes": self.notes}


# ---- robots --------------------------------------------------------------------------------
def _affine(T: np.ndarray) -> np.ndarray:
    """The top three rows ``(..., 3, 4)`` of poses ``(..., 4, 4)``."""
    return np.ascontiguousarray(np.asarray(T, dtype=np.float64)[..., :3, :])


def _add_imported(replay: Replay, root: str, robot: Any, q: np.ndarray) -> None:
    """An imported robot's links: its visual shapes (else collision shapes), each a node in
    its link's frame (the shape's ``origin`` applied), posed by ``link_poses``."""
    visual = any(link.visual for link in robot.links)
    poses = robot.link_poses(q)  # (frames, L, 4, 4)
    for k, link in enumerate(robot.links):
        shapes = link.visual if visual else link.collision
        if not shapes:
            continue
        key = f"{root}/{link.name}"
        replay.poses[key] = _affine(poses[:, k])
        replay.links.append(key)
        for i, g in enumerate(shapes):
            if g.kind == "mesh":
                m = robot.meshes[g.mesh]
                V, F = np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces)
            elif g.kind == "box":
                V, F = box_mesh(g.size)
            elif g.kind == "cylinder":
                V, F = cylinder_mesh(g.radius, -0.5 * g.length, 0.5 * g.length, 24)
            else:
                V, F = sphere_mesh(g.radius, 2)
            color = MESH_COLOR if g.color is None else tuple(
                int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in g.color[:3])
            opacity = 1.0 if g.color is None else float(np.clip(g.color[3], 0.05, 1.0))
            replay.nodes.append(Node(f"{key}/{'visual' if visual else 'collision'}_{i}",
                                     transformed(V, g.origin), F, color, key, opacity))


def _reach_mm(model: RobotModel) -> float:
    """The farthest frame origin from the base at mid-limits (mm), at least 200."""
    frames = fk_frames(model, model.mid_configuration())
    p = frames[:, :3, 3] - frames[0, :3, 3]
    return max(float(np.linalg.norm(p, axis=1).max()), 200.0)


def _segment_maps(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Affine maps ``(N, 3, 4)`` taking the unit segment z in [0, 1] onto ``p0 -> p1`` (N, 3)
    each: x, y keep their length (the radius), z is stretched to the segment's length."""
    d = p1 - p0
    length = np.linalg.norm(d, axis=1)
    unit = np.where(length[:, None] > 0, d / np.maximum(length, 1e-300)[:, None],
                    [0.0, 0.0, 1.0])
    ref = np.where(np.abs(unit[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(ref, unit)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(unit, u)
    return np.stack([u, v, unit * length[:, None], p0], axis=2)


def _add_chain(replay: Replay, root: str, model: RobotModel, q: np.ndarray) -> None:
    """A robot without geometry of its own, as the viewer draws it: a base disc, a cylinder
    from each frame origin to the next (``fk_frames``), a ball on each joint axis, the tool's
    axes."""
    frames = fk_frames(model, q)  # (N, dof + 1, 4, 4)
    _, points, _ = joint_axes(model, q)
    r = float(np.clip(0.018 * _reach_mm(model), 8.0, 150.0))
    replay.poses[f"{root}/base"] = _affine(frames[:, 0])
    replay.nodes.append(Node(f"{root}/base", *cylinder_mesh(3 * r, -0.5 * r, 0.5 * r, 24),
                             BASE_COLOR, f"{root}/base"))
    origins = frames[:, :, :3, 3]
    unit = cylinder_mesh(r, 0.0, 1.0, 16)
    ball = sphere_mesh(1.4 * r, 1)
    for i in range(model.dof):
        key = f"{root}/link_{i}"
        replay.poses[key] = _segment_maps(origins[:, i], origins[:, i + 1])
        replay.nodes.append(Node(key, *unit, LINK_COLOR, key))
        key = f"{root}/joint_{i}"
        A = np.zeros((len(q), 3, 4))
        A[:, :, :3] = np.eye(3)
        A[:, :, 3] = points[:, i]
        replay.poses[key] = A
        replay.nodes.append(Node(key, *ball, JOINT_COLOR, key))
    key = f"{root}/tool"
    replay.poses[key] = _affine(frames[:, -1])
    length = max(6 * r, 80.0)
    for axis, color in zip("xyz", AXIS_COLORS):
        V, F = cylinder_mesh(0.07 * length, 0.0, length, 8)
        R = {"x": [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], "y": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
             "z": np.eye(3)}[axis]
        replay.nodes.append(Node(f"{key}/{axis}", V @ np.asarray(R, float).T, F, color, key))
    replay.links += [f"{root}/base", *(f"{root}/link_{i}" for i in range(model.dof)), key]


def _add_robot(replay: Replay, root: str, model: RobotModel, imported: Any,
               q: np.ndarray, color: tuple[int, int, int]) -> None:
    """One arm at the frames' joint values ``q (N, dof)``, and its tool path."""
    if imported is not None and imported.model.dof == model.dof and any(
            link.visual or link.collision for link in imported.links):
        _add_imported(replay, root, imported, q)
    else:
        _add_chain(replay, root, model, q)
    tool = fk(model, q)[:, :3, 3]
    replay.lines.append({"name": f"{root}/tool_path", "color": list(color),
                         "pts": np.round(tool, MM_DECIMALS).reshape(-1)})
    replay.robots.append(root)


# ---- scenes --------------------------------------------------------------------------------
def _add_points(replay: Replay, name: str, P: np.ndarray, radius: float, color) -> None:
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    if len(P) > MAX_POINTS:
        P = P[:: -(-len(P) // MAX_POINTS)]
    replay.points.append({"name": name, "color": list(color), "radius": float(radius),
                          "pts": np.round(P, MM_DECIMALS).reshape(-1)})


def _add_objects(replay: Replay, objects: Sequence[Any], root: str = "scene") -> None:
    """``SceneObject``s (``planning.geometry``) as world triangles (points as dots)."""
    coarse = len(objects) > 100
    for o in objects:
        name = f"{root}/{o.id}"
        T = np.asarray(o.pose, dtype=np.float64)
        if o.type == "points":
            _add_points(replay, name, o.world_points(), o.radius, OBJECT_COLOR)
            continue
        if o.type == "box":
            V, F = box_mesh(o.size)
        elif o.type == "sphere":
            V, F = sphere_mesh(o.radius, 0 if coarse else 2)
        elif o.type == "cylinder":
            V, F = cylinder_mesh(o.radius, -0.5 * o.height, 0.5 * o.height,
                                 8 if coarse else 24)
        elif o.type == "capsule":
            V, F = capsule_mesh(np.asarray(o.a), np.asarray(o.b), o.radius)
        elif o.type == "mesh":
            V = np.asarray(o.vertices, dtype=np.float64) * np.asarray(o.scale, dtype=float)
            F = np.asarray(o.faces, dtype=np.int64)
        else:  # a shape registered by another module: its bounds as a box
            replay.notes.append(f"object {o.id}: type {o.type} drawn as its bounds")
            continue
        replay.nodes.append(Node(name, transformed(V, T), F, OBJECT_COLOR))


def _motion_scene(replay: Replay, params: Mapping[str, Any]) -> None:
    scene = params.get("scene")
    if not isinstance(scene, Mapping):
        if scene is not None:
            replay.notes.append(f"stored scene {scene} not filled in: not drawn")
        return
    from .jobs.motion_kinds import collision_scene

    built = collision_scene(scene)
    if built is not None:
        _add_objects(replay, built.objects)


def _path_scene(replay: Replay, params: Mapping[str, Any]) -> None:
    from .jobs.path_kinds import SceneIn

    if not isinstance(params.get("scene"), Mapping):
        return
    scene_in = SceneIn.model_validate(params["scene"])
    parsed = scene_in.to_scene()
    for k, o in enumerate(parsed.obstacles):
        if o.kind == "sphere":
            V, F = sphere_mesh(o.radius, 2)
            V = V + np.asarray(o.center, dtype=np.float64)
        elif o.kind == "box":
            lo, hi = np.asarray(o.lower, float), np.asarray(o.upper, float)
            V, F = box_mesh(hi - lo)
            V = V + 0.5 * (lo + hi)
        elif o.kind == "capsule":
            V, F = capsule_mesh(np.asarray(o.a), np.asarray(o.b), o.radius)
        else:
            continue
        replay.nodes.append(Node(f"scene/obstacle_{k}", V, F, OBSTACLE_COLOR, None, 0.6))
    lo, hi = np.asarray(parsed.lower, float), np.asarray(parsed.upper, float)
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    edges = [0, 1, 3, 2, 0, 4, 5, 7, 6, 4, 5, 1, 3, 7, 6, 2]
    replay.lines.append({"name": "scene/bounds", "color": [150, 150, 150],
                         "pts": np.round(c[edges], MM_DECIMALS).reshape(-1)})
    objects = scene_in.collision_scene()
    if objects is not None:
        _add_objects(replay, objects.objects)


def _hole_points(replay: Replay, result: Mapping[str, Any]) -> None:
    for arm, data in (result.get("arms") or {}).items():
        holes = np.asarray(data.get("holes") or [], dtype=np.float64).reshape(-1, 3)
        if len(holes):
            _add_points(replay, f"{arm}/holes", holes, 40.0, ARM_COLORS.get(arm, PATH_COLOR))


def _round_holes(replay: Replay, params: Mapping[str, Any], result: Mapping[str, Any]) -> None:
    """A round's holes given as a list (collar to toe, rig frame), coloured by boom."""
    holes = params.get("holes") if params.get("rig_pose") is None else None
    if not isinstance(holes, list):
        replay.notes.append("the round's holes are not drawn (an IREDES plan or a rig_pose)")
        return
    boom_of = {h.get("id"): h.get("boom") for h in result.get("holes") or []
               if isinstance(h, Mapping)}
    by_boom: dict[str, list] = {}
    for h in holes:
        if isinstance(h, Mapping) and h.get("collar") is not None and h.get("toe") is not None:
            by_boom.setdefault(str(boom_of.get(h.get("id"), "unreached")), []).append(
                (h["collar"], h["toe"]))
    for boom, pairs in by_boom.items():
        P = np.asarray(pairs, dtype=np.float64).reshape(-1, 3)
        replay.lines.append({"name": f"{boom}/holes", "segments": True,
                             "color": list(ARM_COLORS.get(boom, PATH_COLOR)),
                             "pts": np.round(P, MM_DECIMALS).reshape(-1)})


# ---- the page --------------------------------------------------------------------------------
def _frames(t: np.ndarray) -> np.ndarray:
    """Indices of the samples kept: all, or every k-th and the last (``MAX_FRAMES``)."""
    n = len(t)
    if n <= MAX_FRAMES:
        return np.arange(n)
    stride = -(-(n - 1) // (MAX_FRAMES - 1))
    keep = np.arange(0, n, stride)
    return keep if keep[-1] == n - 1 else np.append(keep, n - 1)


def _at(track: Track, times: np.ndarray) -> np.ndarray:
    """The track's joints at ``times`` (linear between samples, held outside)."""
    return np.column_stack([np.interp(times, track.t, col) for col in track.q.T])


def build_replay(job_id: str, kind: str, params: Mapping[str, Any], result: Mapping[str, Any],
                 models: Models, imported: Imported | None = None, *,
                 arm: str | None = None, problem: int | None = None,
                 scene: Any = None) -> Replay:
    """The replay of a succeeded job: its trajectory (``extract`` and ``select`` of
    ``app.trajectory_export``: a batch's first solved problem, or ``problem``; every arm of a
    multiarm plan, or ``arm``), the robot drawn along it, its scene (``scene``, a built
    collision scene, is drawn instead of the params' one when given). ``models(id)`` and
    ``imported(id)`` (the ``ImportedRobot`` or None) are the registry's. ``ExportError`` for
    a job without a trajectory, as the trajectory export says it."""
    tracks = extract(kind, params, result, models)
    chosen, several = select(kind, tracks, "json", {"arm": arm, "problem": problem})
    if several and tracks.selector == "problem":
        chosen = chosen[:1]
    # The frames: the longest track's times (a round's booms end at different times).
    first = max((track for _, track in chosen), key=lambda track: track.t[-1] - track.t[0])
    keep = _frames(first.t)
    t = first.t[keep] - first.t[0]
    replay = Replay(job_id, kind, t)
    rig = None
    if kind in ("multiarm", "round"):
        rig = builtin_rig(result.get("rig") or params.get("rig", "tunnel_jumbo"))
    for label, track in chosen:
        q = _at(track, first.t[keep])
        if rig is not None:
            model, robot, root = rig.arms[label], None, str(label)
        else:
            model = models(track.robot)
            robot = imported(track.robot) if imported is not None else None
            root = str(track.robot)
        color = ARM_COLORS.get(str(label), PATH_COLOR)
        _add_robot(replay, root, model, robot, q, color)
    if scene is not None:
        _add_objects(replay, scene.objects)
    elif kind == "motion":
        _motion_scene(replay, params)
    elif kind == "path":
        _path_scene(replay, params)
    elif kind == "multiarm":
        _hole_points(replay, result)
    elif kind == "round":
        _round_holes(replay, params, result)
    elif kind == "tracking" and result.get("x_desired"):
        desired = np.asarray(result["x_desired"], dtype=np.float64).reshape(-1, 3)
        replay.lines.append({"name": "desired", "color": list(DESIRED_COLOR),
                             "pts": np.round(desired, MM_DECIMALS).reshape(-1)})
    if problem is not None or (several and tracks.selector == "problem"):
        replay.notes.append(f"problem {chosen[0][0]}")
    replay.cap_triangles()
    return replay


def _json_for_script(data: Any) -> str:
    """JSON safe inside a ``<script>`` element: no ``<``, ``>``, ``&`` to end it early."""
    text = orjson.dumps(data, option=orjson.OPT_SERIALIZE_NUMPY).decode()
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def replay_html(replay: Replay) -> str:
    """The page: the template with the replay's data and title filled in."""
    page = resources.files(__package__).joinpath(TEMPLATE).read_text(encoding="utf-8")
    title = html.escape(f"kinoplan replay: {replay.kind} job {replay.job}")
    return (page.replace(TITLE_MARK, title)
            .replace(DATA_MARK, _json_for_script(replay.data())))
