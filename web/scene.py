"""Robots and plans turned into viser scene nodes.

Units: the models and the API speak millimetres; the scene is in metres (viser's camera and
grid defaults suit metres). ``MM_TO_M`` is applied here and nowhere else. Every pose comes from
the kinematics library (``fk_frames``, ``joint_axes``, ``CylinderSet``); this module only
decides how to draw it.

Node names follow the kinematic chain under one root per arm (``/robot/<id>`` for a robot,
``/robot/<rig id>/<arm>`` for an arm of a rig)::

    <root>/base                    disc at the base frame
    <root>/link_<i>                cylinder from frame i to frame i+1 (fk_frames origins)
    <root>/joint_<i>               sphere on joint i's axis (i = 0 .. dof-1)
    <root>/tool                    axes of the tool frame
    <root>/cylinders/<name>/barrel, .../rod     hydraulic cylinders (robots with "cylinders")
    <root>/cylinders/<name>/rocker, .../coupler, .../crank    four-bar linkage bars

Hydraulic cylinders. The model data give each cylinder's pin *distances* from the joint axis
and the pin *angle* as a function of the joint (``kinematics.cylinders``), not where the pin
rays point on the links. ``CylinderSet.pins`` places the pins (and a four-bar's points) in
the plane of the joint they act about; the drawing puts that plane's x axis on the driven
link's x axis projected onto the plane, turned back by the joint value. So the triangle
about the joint may be rotated against the real machine, but every drawn cylinder is exactly
as long as ``CylinderSet.lengths`` says (the tests check this).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser.transforms as vtf

from kinematics.cylinders import CylinderError, cylinder_set
from kinematics.fk import fk_frames, joint_axes
from kinematics.model import RobotModel

__all__ = [
    "MM_TO_M",
    "RobotStyle",
    "CylinderDrawing",
    "RobotDrawing",
    "RobotNodes",
    "robot_drawing",
    "cylinder_drawings",
    "segment_pose",
    "wxyz_from_matrix",
    "height_colors",
    "reach_m",
    "add_segments",
    "draw_plan",
]

MM_TO_M = 1e-3

LINK_COLOR = (230, 120, 20)
JOINT_COLOR = (60, 60, 70)
BASE_COLOR = (90, 90, 100)
BARREL_COLOR = (40, 90, 160)
ROD_COLOR = (200, 200, 210)
LINKAGE_COLOR = (120, 120, 130)
OUT_OF_STROKE_COLOR = (220, 30, 30)

#: Links shorter than this (m) are hidden: consecutive frames that coincide draw nothing.
MIN_LINK_M = 1e-6
#: Fraction of the retracted length taken by the barrel; the rod is long enough to meet the
#: barrel's end at full extension.
BARREL_FRACTION = 0.9
#: Above this many balls in one group (e.g. drill holes) they are drawn as one point cloud.
MAX_SPHERE_NODES = 200


# ---- geometry helpers (drawing only) ----------------------------------------------------
def wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix ``(3, 3)``."""
    return vtf.SO3.from_matrix(np.asarray(R, dtype=float)).wxyz


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def segment_pose(p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Pose of a viser cylinder (axis = local z, centred) spanning ``p0 -> p1`` ``(3,)``.

    Returns ``(position (3,), wxyz (4,), length)``: the midpoint, the shortest rotation taking
    +z onto the segment direction, and the segment length (units of the input).
    """
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    d = p1 - p0
    length = float(np.linalg.norm(d))
    if length == 0.0:
        return 0.5 * (p0 + p1), np.array([1.0, 0.0, 0.0, 0.0]), 0.0
    d = d / length
    # (1 + z.d, z x d), normalised; 1 + d_z written so it keeps its digits near d = -z.
    w = 1.0 + d[2] if d[2] >= 0 else (d[0] ** 2 + d[1] ** 2) / (1.0 - d[2])
    q = np.array([w, -d[1], d[0], 0.0])
    if not q.any():  # exactly -z: half a turn about x
        q = np.array([0.0, 1.0, 0.0, 0.0])
    return 0.5 * (p0 + p1), q / np.linalg.norm(q), length


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: ``v (3,)`` turned by ``angle`` (rad) about the unit ``axis (3,)``."""
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * float(axis @ v) * (1.0 - c)


def height_colors(z: np.ndarray, cmap: str = "viridis") -> np.ndarray:
    """RGB colours ``(N, 3) uint8`` for heights ``z (N,)``: low = dark, high = bright."""
    from matplotlib import colormaps

    z = np.asarray(z, dtype=float)
    span = float(np.ptp(z)) if z.size else 0.0
    t = (z - z.min()) / span if span > 0 else np.zeros_like(z)
    return (colormaps[cmap](t)[:, :3] * 255).astype(np.uint8)


def reach_m(model: RobotModel) -> float:
    """Size of the arm for drawing (m): the farthest frame origin from the base at
    mid-limits, at least 0.2 m."""
    frames = fk_frames(model, model.mid_configuration())
    p = frames[:, :3, 3] - frames[0, :3, 3]
    return max(float(np.linalg.norm(p, axis=1).max()) * MM_TO_M, 0.2)


# ---- what to draw -------------------------------------------------------------------------
@dataclass(frozen=True)
class CylinderDrawing:
    """One hydraulic cylinder at one configuration (mm). ``barrel_pin`` on the carrying link,
    ``rod_pin`` on the driven side; ``bars`` extra linkage bars ``{name: (p0, p1)}``."""

    name: str
    joint: str
    barrel_pin: np.ndarray
    rod_pin: np.ndarray
    length: float
    min_length: float
    max_length: float
    within_stroke: bool
    bars: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    @property
    def stroke(self) -> float:
        """Extension beyond the retracted length (mm)."""
        return self.length - self.min_length


@dataclass(frozen=True)
class RobotDrawing:
    """Everything drawn for one arm at ``q (dof,)``, in mm: ``frames (dof+1, 4, 4)``
    (base, after each joint; the last is the tool), ``joint_points (dof, 3)`` a point on each
    joint axis, and the hydraulic cylinders."""

    q: np.ndarray
    frames: np.ndarray
    joint_points: np.ndarray
    cylinders: tuple[CylinderDrawing, ...]

    @property
    def T_base_tool(self) -> np.ndarray:
        return self.frames[-1]


def _joint_plane(axis: np.ndarray, x_child: np.ndarray, theta: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """In-plane directions of a revolute joint ``(3,)`` each: ``u_c`` fixed to the driven link
    (its x axis projected onto the joint plane), ``u_p`` fixed to the carrying link (``u_c``
    turned back by the joint value ``theta``), ``v_p = axis x u_p`` and the unit axis."""
    a = _unit(np.asarray(axis, dtype=float))
    u_c = x_child - float(x_child @ a) * a
    if np.linalg.norm(u_c) < 1e-9:  # x along the axis (possible for PoE frames)
        u_c = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u_c = _unit(u_c)
    u_p = _rotate(u_c, a, -theta)
    return u_c, u_p, np.cross(a, u_p), a


def cylinder_drawings(model: RobotModel, q: np.ndarray, frames: np.ndarray | None = None
                      ) -> tuple[CylinderDrawing, ...]:
    """Pin positions (mm, base frame) of every hydraulic cylinder of ``model`` at ``q (dof,)``;
    empty for a robot without cylinder data (or with data the library rejects)."""
    if "cylinders" not in model.extras:
        return ()
    try:
        cs = cylinder_set(model)
    except CylinderError:
        return ()
    q = np.asarray(q, dtype=float)
    frames = fk_frames(model, q) if frames is None else frames
    axes, points, _ = joint_axes(model, q[None])
    lengths = cs.lengths(q)
    inside = cs.within_stroke(lengths)
    out: list[CylinderDrawing] = []
    for c in cs.pins(q).values():  # pins in the plane of the joint each cylinder drives
        j = c.joint
        _, u_p, v_p, _ = _joint_plane(axes[0, j], frames[j + 1][:3, 0], float(q[j]))
        origin, plane = points[0, j], np.stack([u_p, v_p])  # plane (x, y) -> world: p @ plane
        P = {key: origin + p @ plane for key, p in c.linkage.items()}
        bars = {"rocker": (P["N"], P["M"]), "coupler": (P["M"], P["K"]),
                "crank": (P["H"], P["K"])} if P else {}
        min_length, max_length = cs.limits(c.name)
        out.append(CylinderDrawing(
            name=c.name, joint=model.joints[j].name, barrel_pin=origin + c.barrel @ plane,
            rod_pin=origin + c.rod @ plane, length=float(lengths[c.name]), min_length=min_length,
            max_length=max_length, within_stroke=bool(inside[c.name]), bars=bars,
        ))
    return tuple(out)


def robot_drawing(model: RobotModel, q) -> RobotDrawing:
    """What to draw for ``model`` at ``q (dof,)`` (rad; mm for prismatic joints)."""
    q = np.asarray(q, dtype=float)
    frames = fk_frames(model, q)
    _, points, _ = joint_axes(model, q[None])
    return RobotDrawing(q, frames, points[0], cylinder_drawings(model, q, frames))


# ---- viser nodes --------------------------------------------------------------------------
@dataclass(frozen=True)
class RobotStyle:
    """Sizes (m) of one arm's nodes, scaled to the arm's reach."""

    link_radius: float
    joint_radius: float
    barrel_radius: float
    rod_radius: float
    tool_axes: float

    @classmethod
    def for_model(cls, model: RobotModel) -> RobotStyle:
        r = float(np.clip(0.018 * reach_m(model), 0.008, 0.15))
        return cls(r, 1.4 * r, 0.6 * r, 0.35 * r, max(6 * r, 0.08))


class RobotNodes:
    """The scene nodes of one arm under ``root``; ``update(q)`` moves them.

    Not thread-safe by itself: the viewer calls it under its lock.
    """

    def __init__(self, scene: Any, root: str, model: RobotModel, q,
                 style: RobotStyle | None = None) -> None:
        self.scene = scene
        self.root = root
        self.model = model
        self.style = style or RobotStyle.for_model(model)
        self.handles: dict[str, Any] = {}
        self.drawing = robot_drawing(model, q)
        self._build()

    # names ---------------------------------------------------------------------------------
    def link(self, i: int) -> str:
        return f"{self.root}/link_{i}"

    def joint(self, i: int) -> str:
        return f"{self.root}/joint_{i}"

    @property
    def tool(self) -> str:
        return f"{self.root}/tool"

    @property
    def names(self) -> list[str]:
        """Every node name this arm owns (root first)."""
        return list(self.handles)

    # building ------------------------------------------------------------------------------
    def _segment(self, name: str, p0_mm, p1_mm, radius: float, color) -> None:
        pos, wxyz, length = segment_pose(np.asarray(p0_mm) * MM_TO_M,
                                         np.asarray(p1_mm) * MM_TO_M)
        self.handles[name] = self.scene.add_cylinder(
            name, radius=radius, height=max(length, MIN_LINK_M), color=color,
            radial_segments=20, position=pos, wxyz=wxyz, visible=length > MIN_LINK_M,
        )

    def _build(self) -> None:
        s, d = self.style, self.drawing
        self.handles[self.root] = self.scene.add_frame(self.root, show_axes=False)
        T0 = d.frames[0]
        self.handles[f"{self.root}/base"] = self.scene.add_cylinder(
            f"{self.root}/base", radius=3.0 * s.link_radius, height=s.link_radius,
            color=BASE_COLOR, position=T0[:3, 3] * MM_TO_M, wxyz=wxyz_from_matrix(T0[:3, :3]),
        )
        origins = d.frames[:, :3, 3]
        for i in range(self.model.dof):
            self._segment(self.link(i), origins[i], origins[i + 1], s.link_radius, LINK_COLOR)
            self.handles[self.joint(i)] = self.scene.add_icosphere(
                self.joint(i), radius=s.joint_radius, color=JOINT_COLOR, subdivisions=2,
                position=d.joint_points[i] * MM_TO_M,
            )
        T = d.T_base_tool
        self.handles[self.tool] = self.scene.add_frame(
            self.tool, axes_length=s.tool_axes, axes_radius=s.tool_axes / 15,
            position=T[:3, 3] * MM_TO_M, wxyz=wxyz_from_matrix(T[:3, :3]),
        )
        for c in d.cylinders:
            self._build_cylinder(c)

    def _cylinder_parts(self, c: CylinderDrawing) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Barrel from the barrel pin, rod from the rod pin back into the barrel (mm)."""
        u = _unit(c.rod_pin - c.barrel_pin)
        barrel = BARREL_FRACTION * c.min_length
        rod = c.max_length - barrel
        return {"barrel": (c.barrel_pin, c.barrel_pin + barrel * u),
                "rod": (c.rod_pin - rod * u, c.rod_pin)}

    def _build_cylinder(self, c: CylinderDrawing) -> None:
        s = self.style
        base = f"{self.root}/cylinders/{c.name}"
        color = BARREL_COLOR if c.within_stroke else OUT_OF_STROKE_COLOR
        parts = self._cylinder_parts(c)
        self._segment(f"{base}/barrel", *parts["barrel"], s.barrel_radius, color)
        self._segment(f"{base}/rod", *parts["rod"], s.rod_radius, ROD_COLOR)
        for bar, (p0, p1) in c.bars.items():
            self._segment(f"{base}/{bar}", p0, p1, 0.5 * s.rod_radius, LINKAGE_COLOR)

    # moving --------------------------------------------------------------------------------
    def _move(self, name: str, p0_mm, p1_mm) -> None:
        h = self.handles[name]
        pos, wxyz, length = segment_pose(np.asarray(p0_mm) * MM_TO_M,
                                         np.asarray(p1_mm) * MM_TO_M)
        visible = length > MIN_LINK_M
        if visible and abs(h.height - length) > 1e-9:
            h.height = length  # prismatic joints change link lengths
        if h.visible != visible:
            h.visible = visible
        h.position = pos
        h.wxyz = wxyz

    def update(self, q) -> RobotDrawing:
        """Move every node to configuration ``q (dof,)``; returns the new drawing."""
        d = self.drawing = robot_drawing(self.model, q)
        origins = d.frames[:, :3, 3]
        for i in range(self.model.dof):
            self._move(self.link(i), origins[i], origins[i + 1])
            self.handles[self.joint(i)].position = d.joint_points[i] * MM_TO_M
        T = d.T_base_tool
        tool = self.handles[self.tool]
        tool.position = T[:3, 3] * MM_TO_M
        tool.wxyz = wxyz_from_matrix(T[:3, :3])
        for c in d.cylinders:
            base = f"{self.root}/cylinders/{c.name}"
            parts = self._cylinder_parts(c)
            self._move(f"{base}/barrel", *parts["barrel"])
            self._move(f"{base}/rod", *parts["rod"])
            color = BARREL_COLOR if c.within_stroke else OUT_OF_STROKE_COLOR
            if tuple(self.handles[f"{base}/barrel"].color) != color:
                self.handles[f"{base}/barrel"].color = color
            for bar, (p0, p1) in c.bars.items():
                self._move(f"{base}/{bar}", p0, p1)
        return d

    def bounds_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounds ``(lower (3,), upper (3,))`` mm of the arm as drawn: its frame
        origins, joint spheres, cylinder pins and the base disc, padded by their radii."""
        d = self.drawing
        pts = [d.frames[:, :3, 3], d.joint_points]
        pts += [np.stack([c.barrel_pin, c.rod_pin]) for c in d.cylinders]
        P = np.vstack(pts)
        pad = max(3.0 * self.style.link_radius, self.style.joint_radius) / MM_TO_M
        return P.min(axis=0) - pad, P.max(axis=0) + pad

    def remove(self) -> None:
        """Remove the arm's nodes (the root takes its children with it)."""
        self.handles[self.root].remove()
        self.handles.clear()


def add_segments(scene: Any, name: str, points_mm: Sequence, color, thickness_m: float):
    """A polyline through ``points_mm (N, 3)`` as line segments (N >= 1)."""
    p = np.asarray(points_mm, dtype=float).reshape(-1, 3) * MM_TO_M
    if len(p) == 1:
        p = np.vstack([p, p])  # a lone point: one segment of length zero
    segs = np.stack([p[:-1], p[1:]], axis=1)
    return scene.add_line_segments(name, segs, color, thickness=thickness_m,
                                   thickness_units="world")


def draw_plan(scene: Any, root: str, plan: Any, size_m: float) -> dict[str, Any]:
    """Draw a ``web.results.Plan`` under ``root``; returns its handles by node name.

    ``size_m`` scales point and line sizes (the reach of the arm shown with it).
    """
    handles: dict[str, Any] = {root: scene.add_frame(root, show_axes=False)}
    line = max(0.004, 0.004 * size_m)
    for c in plan.clouds:
        name = f"{root}/{c.name}"
        pts = np.asarray(c.points, dtype=float).reshape(-1, 3)
        colors = height_colors(pts[:, 2]) if len(pts) else np.zeros((0, 3), np.uint8)
        handles[name] = scene.add_point_cloud(
            name, pts * MM_TO_M, colors, point_size=max(0.006, 0.006 * size_m),
            point_shape="circle", precision="float32",
        )
    for p in plan.polylines:
        name = f"{root}/{p.name}"
        handles[name] = add_segments(scene, name, p.points, p.color,
                                     line * p.width)
    for s in plan.spheres:
        if len(s.centers) > MAX_SPHERE_NODES:  # many holes: one node, not hundreds
            name = f"{root}/{s.name}"
            handles[name] = scene.add_point_cloud(
                name, np.asarray(s.centers) * MM_TO_M, s.color,
                point_size=2.0 * float(np.max(s.radii)) * MM_TO_M, point_shape="circle",
                precision="float32",
            )
            continue
        for k, (c, r) in enumerate(zip(s.centers, s.radii)):
            name = f"{root}/{s.name}/{k}"
            handles[name] = scene.add_icosphere(
                name, radius=float(r) * MM_TO_M, color=s.color, opacity=s.opacity,
                subdivisions=3, position=np.asarray(c) * MM_TO_M,
            )
    for b in plan.boxes:
        name = f"{root}/{b.name}"
        lo, hi = np.asarray(b.lower) * MM_TO_M, np.asarray(b.upper) * MM_TO_M
        handles[name] = scene.add_box(
            name, color=b.color, dimensions=hi - lo, wireframe=b.wireframe,
            opacity=None if b.wireframe else 0.5, position=0.5 * (lo + hi),
        )
    for c in plan.capsules:
        name = f"{root}/{c.name}"
        pos, wxyz, length = segment_pose(np.asarray(c.a) * MM_TO_M, np.asarray(c.b) * MM_TO_M)
        r = c.radius * MM_TO_M
        handles[name] = scene.add_cylinder(name, radius=r, height=max(length, MIN_LINK_M),
                                           color=c.color, opacity=0.5, position=pos, wxyz=wxyz)
        for end, p in (("a", c.a), ("b", c.b)):
            handles[f"{name}_{end}"] = scene.add_icosphere(
                f"{name}_{end}", radius=r, color=c.color, opacity=0.5,
                position=np.asarray(p) * MM_TO_M,
            )
    return handles
