"""Robots imported from URDF drawn with their own geometry (``kinematics.urdf_import``).

Each link that carries geometry gets a frame node placed at its world pose
(``ImportedRobot.link_poses``); its shapes are children of that frame, posed by their URDF
``origin`` and uploaded once. Moving the robot moves the link frames only (``position`` and
``wxyz``): meshes are never sent again.

Which geometry: the links' ``<visual>`` shapes when the robot has any, else their
``<collision>`` shapes (a URDF without visuals still shows its bodies). Colours come from the
URDF materials (alpha below 1 draws translucent); shapes without one are neutral grey. Meshes
are flat shaded, as RViz shows STL files: their vertices are shared across sharp CAD edges,
where smoothed normals would smear the light. A robot with no geometry at all is drawn as a
D-H robot (``web.scene.RobotNodes``).

Node names under the arm's root (``/robot/<id>``; link names are the URDF's with ``/``
replaced by ``_``)::

    <root>/links/<link>              frame at the link's pose (moves with q)
    <root>/links/<link>/visual_<k>   its k-th visual shape (collision_<k> without visuals)
    <root>/tool                      axes of the tool frame (the tip link's pose)

Lengths in the library are mm; the scene is in metres (``MM_TO_M``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kinematics.model import RobotModel

from .scene import (
    MM_TO_M,
    RobotDrawing,
    RobotNodes,
    RobotStyle,
    robot_drawing,
    wxyz_from_matrix,
)

__all__ = [
    "MESH_COLOR",
    "ImportedRobotNodes",
    "robot_nodes",
    "geometry_corners",
    "node_safe",
    "rgb_and_opacity",
    "box_corners",
    "bounds_of",
    "add_geometry",
]

#: Colour of shapes whose URDF gives no material colour.
MESH_COLOR = (175, 178, 185)


# ---- helpers -------------------------------------------------------------------------------
def node_safe(name: str, taken: set[str]) -> str:
    """``name`` usable as one level of a scene node path (no ``/``), made unique against
    ``taken`` (which it is added to) by a ``_<k>`` suffix."""
    base = name.replace("/", "_") or "_"
    out, k = base, 1
    while out in taken:
        out, k = f"{base}_{k}", k + 1
    taken.add(out)
    return out


def rgb_and_opacity(color: Sequence[float] | None,
                    default: tuple[int, int, int] = MESH_COLOR
                    ) -> tuple[tuple[int, int, int], float | None]:
    """An RGBA colour in 0..1 (URDF material) as ``(r, g, b)`` 0..255 and an opacity (None when
    opaque); ``default`` for None."""
    if color is None:
        return default, None
    rgba = np.clip(np.asarray(color, dtype=float), 0.0, 1.0)
    rgb = tuple(int(round(255 * v)) for v in rgba[:3])
    return rgb, (float(rgba[3]) if rgba[3] < 1.0 else None)


def box_corners(lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of the box ``lower (3,)`` .. ``upper (3,)``."""
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    pick = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=bool)
    return np.where(pick, hi, lo)


def bounds_of(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Axis-aligned bounds ``(lower (3,), upper (3,))`` of points ``(N, 3)``; None if empty."""
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    if not len(P):
        return None
    return P.min(axis=0), P.max(axis=0)


def geometry_corners(geometry: Any, meshes: Mapping[str, Any]) -> np.ndarray:
    """Corners ``(8, 3)`` (mm, link frame) of a box around a URDF shape
    (``kinematics.urdf_import.Geometry``): the shape's own bounds moved by its ``origin``."""
    g = geometry
    if g.kind == "mesh":
        V = np.asarray(meshes[g.mesh].vertices, dtype=float)
        lo, hi = V.min(axis=0), V.max(axis=0)
    elif g.kind == "box":
        hi = 0.5 * np.asarray(g.size, dtype=float)
        lo = -hi
    elif g.kind == "cylinder":
        hi = np.array([g.radius, g.radius, 0.5 * g.length])
        lo = -hi
    else:
        hi = np.full(3, float(g.radius))
        lo = -hi
    T = np.asarray(g.origin, dtype=float)
    return box_corners(lo, hi) @ T[:3, :3].T + T[:3, 3]


def add_geometry(scene: Any, name: str, geometry: Any, meshes: Mapping[str, Any]) -> Any:
    """One URDF shape as a viser node ``name`` posed by its ``origin`` relative to its parent
    node (the link frame)."""
    g = geometry
    T = np.asarray(g.origin, dtype=float)
    color, opacity = rgb_and_opacity(g.color)
    pose = {"position": T[:3, 3] * MM_TO_M, "wxyz": wxyz_from_matrix(T[:3, :3])}
    if g.kind == "mesh":
        data = meshes[g.mesh]
        return scene.add_mesh_simple(
            name, np.asarray(data.vertices, dtype=np.float32) * np.float32(MM_TO_M),
            np.asarray(data.faces, dtype=np.uint32), color=color, opacity=opacity,
            side="double", flat_shading=True, **pose)
    if g.kind == "box":
        return scene.add_box(name, color=color, dimensions=np.asarray(g.size) * MM_TO_M,
                             opacity=opacity, **pose)
    if g.kind == "cylinder":
        return scene.add_cylinder(name, radius=g.radius * MM_TO_M,
                                  height=g.length * MM_TO_M, color=color, opacity=opacity,
                                  radial_segments=32, **pose)
    return scene.add_icosphere(name, radius=g.radius * MM_TO_M, color=color, opacity=opacity,
                               subdivisions=3, **pose)


# ---- nodes ---------------------------------------------------------------------------------
class ImportedRobotNodes:
    """The scene nodes of an imported robot under ``root``; ``update(q)`` moves its link
    frames. Same interface as ``web.scene.RobotNodes`` (``root``, ``model``, ``drawing``,
    ``handles``, ``names``, ``update``, ``remove``, ``bounds_mm``).

    ``robot`` is a ``kinematics.urdf_import.ImportedRobot`` with some geometry (see
    ``robot_nodes``). Not thread-safe by itself: the viewer calls it under its lock."""

    def __init__(self, scene: Any, root: str, robot: Any, q,
                 style: RobotStyle | None = None) -> None:
        self.scene = scene
        self.root = root
        self.robot = robot
        self.model: RobotModel = robot.model
        self.style = style or RobotStyle.for_model(self.model)
        self.source = "visual" if any(link.visual for link in robot.links) else "collision"
        self.handles: dict[str, Any] = {}
        #: Node name of each drawn link frame, by URDF link name.
        self.link_nodes: dict[str, str] = {}
        self._drawn: list[int] = []  # indices into robot.links of the links drawn
        self._corners: list[np.ndarray] = []  # (8 * shapes, 3) mm in each drawn link's frame
        q = np.asarray(q, dtype=float)
        self.drawing: RobotDrawing = robot_drawing(self.model, q)
        self._poses = robot.link_poses(q)
        self._build()

    @property
    def tool(self) -> str:
        return f"{self.root}/tool"

    @property
    def names(self) -> list[str]:
        """Every node name this arm owns (root first)."""
        return list(self.handles)

    def shapes_of(self, link: Any) -> tuple[Any, ...]:
        return link.visual if self.source == "visual" else link.collision

    def _build(self) -> None:
        scene = self.scene
        self.handles[self.root] = scene.add_frame(self.root, show_axes=False)
        self.handles[f"{self.root}/links"] = scene.add_frame(f"{self.root}/links",
                                                             show_axes=False)
        taken: set[str] = set()
        meshes = self.robot.meshes
        for k, link in enumerate(self.robot.links):
            shapes = self.shapes_of(link)
            if not shapes:
                continue
            node = f"{self.root}/links/{node_safe(link.name, taken)}"
            T = self._poses[k]
            self.handles[node] = scene.add_frame(node, show_axes=False,
                                                 position=T[:3, 3] * MM_TO_M,
                                                 wxyz=wxyz_from_matrix(T[:3, :3]))
            self.link_nodes[link.name] = node
            for i, g in enumerate(shapes):
                name = f"{node}/{self.source}_{i}"
                self.handles[name] = add_geometry(scene, name, g, meshes)
            self._drawn.append(k)
            self._corners.append(np.vstack([geometry_corners(g, meshes) for g in shapes]))
        T = self.drawing.T_base_tool
        s = self.style
        self.handles[self.tool] = scene.add_frame(
            self.tool, axes_length=s.tool_axes, axes_radius=s.tool_axes / 15,
            position=T[:3, 3] * MM_TO_M, wxyz=wxyz_from_matrix(T[:3, :3]))

    def update(self, q) -> RobotDrawing:
        """Move the link frames and the tool axes to ``q (dof,)``; returns the new drawing."""
        q = np.asarray(q, dtype=float)
        self.drawing = robot_drawing(self.model, q)
        self._poses = self.robot.link_poses(q)
        if self._drawn:
            T = self._poses[self._drawn]
            positions = T[:, :3, 3] * MM_TO_M
            wxyzs = _wxyz_batch(T[:, :3, :3])
            for j, k in enumerate(self._drawn):
                h = self.handles[self.link_nodes[self.robot.links[k].name]]
                h.position = positions[j]
                h.wxyz = wxyzs[j]
        T = self.drawing.T_base_tool
        tool = self.handles[self.tool]
        tool.position = T[:3, 3] * MM_TO_M
        tool.wxyz = wxyz_from_matrix(T[:3, :3])
        return self.drawing

    def link_pose(self, name: str) -> np.ndarray:
        """World pose ``(4, 4)`` mm of a URDF link as drawn."""
        return self._poses[self.robot.link_names.index(name)].copy()

    def bounds_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounds ``(lower (3,), upper (3,))`` mm of the shapes as drawn (and the chain's
        frame origins)."""
        pts = [self.drawing.frames[:, :3, 3]]
        for k, corners in zip(self._drawn, self._corners):
            T = self._poses[k]
            pts.append(corners @ T[:3, :3].T + T[:3, 3])
        return bounds_of(np.vstack(pts))

    def remove(self) -> None:
        """Remove the arm's nodes (the root takes its children with it)."""
        self.handles[self.root].remove()
        self.handles.clear()


def _wxyz_batch(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(N, 4)`` of rotation matrices ``(N, 3, 3)``."""
    import viser.transforms as vtf

    return np.asarray(vtf.SO3.from_matrix(np.asarray(R, dtype=float)).wxyz).reshape(-1, 4)


def robot_nodes(scene: Any, root: str, model: RobotModel, q, imported: Any = None
                ) -> RobotNodes | ImportedRobotNodes:
    """The nodes of one arm: its own geometry when ``imported`` (the robot's
    ``ImportedRobot``, whose ``model`` is ``model``) has any, else the D-H drawing."""
    if imported is not None and any(link.visual or link.collision for link in imported.links):
        return ImportedRobotNodes(scene, root, imported, q)
    return RobotNodes(scene, root, model, q)
