"""Point-path obstacles: spheres, axis-aligned boxes and capsules in the world frame (mm),
the format of a path scene's ``obstacles`` (``planning.paths.scene``).

Each is convex and knows its bounds (``bounding_sphere``, ``bounding_box``: what the broad
phase indexes), its ``size``, its surface offset by a distance (``offset_surface``: the
visibility graphs' nodes) and the same shape as a scene object (``object_dict``: the arm's
collision checks). Their distances to segments are the ``("segment", shape)`` rows of the
pair table (``planning.geometry.segments``). Every shape of a stored scene becomes these
through its ``path_cover`` (``planning.geometry.registry``).

Errors are ``FieldError``s at the field path (``obstacles[2].radius``), the message starting
with that path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.errors import FieldError, loc_from_path

from .segments import fibonacci_sphere, unit

__all__ = ["MAX_COORDINATE", "Sphere", "Box", "Capsule", "Obstacle", "obstacle_from_dict",
           "field_error", "vec3", "positive", "translation"]

#: Largest |coordinate| (mm) accepted in a scene: beyond it the numbers stop being useful.
MAX_COORDINATE = 1e9


def translation(p: np.ndarray) -> np.ndarray:
    """The pose ``(4, 4)`` that moves the origin to ``p (3,)``."""
    T = np.eye(4)
    T[:3, 3] = p
    return T


def field_error(name: str, message: str) -> FieldError:
    """``FieldError`` at the field path ``name`` (``obstacles[2].radius``), its message
    starting with that path."""
    return FieldError(loc_from_path(name), f"{name} {message}")


def vec3(value: Any, name: str) -> np.ndarray:
    """``value`` as a finite float ``(3,)``; ``FieldError`` naming ``name`` otherwise."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise field_error(name, "must be 3 numbers [x, y, z]") from None
    if v.shape != (3,):
        raise field_error(name, f"must be 3 numbers [x, y, z], got shape {list(v.shape)}")
    if not np.all(np.isfinite(v)):
        raise field_error(name, "has a NaN or infinite entry")
    if np.any(np.abs(v) > MAX_COORDINATE):
        raise field_error(name, f"has a coordinate beyond {MAX_COORDINATE:.0e} mm")
    v.setflags(write=False)
    return v


def positive(value: Any, name: str, allow_zero: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise field_error(name, "must be a number") from None
    if not math.isfinite(x):
        raise field_error(name, f"must be finite, got {x}")
    if x < 0 or (x == 0 and not allow_zero):
        raise field_error(name, f"must be {'non-negative' if allow_zero else 'positive'}")
    return x


@dataclass(frozen=True)
class Sphere:
    """A ball: ``center (3,)`` mm, ``radius`` mm > 0."""

    center: np.ndarray
    radius: float
    kind = "sphere"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "sphere", "center": self.center.tolist(), "radius": self.radius}

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre ``(3,)`` and radius of a ball containing it: itself."""
        return self.center, self.radius

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``lower (3,)``, ``upper (3,)`` of an axis-aligned box containing it."""
        return self.center - self.radius, self.center + self.radius

    @property
    def size(self) -> float:
        """Its size (mm): the radius."""
        return self.radius

    def object_dict(self, oid: str) -> dict[str, Any]:
        """The same ball as a scene object (``planning.geometry.objects``) named ``oid``."""
        return {"type": "sphere", "id": oid, "radius": float(self.radius),
                "pose": translation(self.center).tolist()}

    def offset_surface(self, u: np.ndarray, offset: float) -> np.ndarray:
        """Points ``(n, 3)`` at signed distance ``offset``, one along each unit direction
        ``u (n, 3)`` from the centre (a Fibonacci lattice: even, deterministic)."""
        return self.center + (self.radius + offset) * u


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``lower (3,) < upper (3,)`` mm."""

    lower: np.ndarray
    upper: np.ndarray
    kind = "box"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "box", "lower": self.lower.tolist(), "upper": self.upper.tolist()}

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre ``(3,)`` and radius of a ball containing it: its circumscribed ball."""
        return 0.5 * (self.lower + self.upper), 0.5 * float(np.linalg.norm(self.upper
                                                                           - self.lower))

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``lower (3,)``, ``upper (3,)`` of an axis-aligned box containing it."""
        return self.lower, self.upper

    @property
    def size(self) -> float:
        """Its size (mm): half its smallest side."""
        return 0.5 * float(np.min(self.upper - self.lower))

    def object_dict(self, oid: str) -> dict[str, Any]:
        """The same box as a scene object (``planning.geometry.objects``) named ``oid``."""
        return {"type": "box", "id": oid, "size": (self.upper - self.lower).tolist(),
                "pose": translation((self.lower + self.upper) / 2).tolist()}

    def offset_surface(self, u: np.ndarray, offset: float) -> np.ndarray:
        """``len(u)`` points at least ``offset`` away: the sharp box grown by ``offset`` (it
        contains the rounded offset surface): its 8 corners, points along its 12 edges
        (where shortest paths wrap) and a lattice on its faces."""
        n = len(u)
        lo, hi = self.lower - offset, self.upper + offset
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])
        per_edge = max(0, (n - 8) // 24)
        s = (np.arange(per_edge) + 1) / (per_edge + 1)
        edges = []
        for axis_i in range(3):
            others = [j for j in range(3) if j != axis_i]
            for a0 in (lo[others[0]], hi[others[0]]):
                for a1 in (lo[others[1]], hi[others[1]]):
                    E = np.empty((per_edge, 3))
                    E[:, axis_i] = lo[axis_i] + s * (hi[axis_i] - lo[axis_i])
                    E[:, others[0]], E[:, others[1]] = a0, a1
                    edges.append(E)
        m = max(0, n - 8 - 12 * per_edge)
        c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
        v = fibonacci_sphere(m)
        faces = c + v / np.max(np.abs(v) / h, axis=1, keepdims=True)
        return np.vstack([corners, *edges, faces])


@dataclass(frozen=True)
class Capsule:
    """All points within ``radius`` of the segment ``a (3,)``–``b (3,)`` (mm)."""

    a: np.ndarray
    b: np.ndarray
    radius: float
    kind = "capsule"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "capsule", "a": self.a.tolist(), "b": self.b.tolist(),
                "radius": self.radius}

    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        """Centre ``(3,)`` and radius of a ball containing it."""
        return 0.5 * (self.a + self.b), 0.5 * float(np.linalg.norm(self.b - self.a)) \
            + self.radius

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``lower (3,)``, ``upper (3,)`` of an axis-aligned box containing it."""
        return (np.minimum(self.a, self.b) - self.radius,
                np.maximum(self.a, self.b) + self.radius)

    @property
    def size(self) -> float:
        """Its size (mm): the radius."""
        return self.radius

    def object_dict(self, oid: str) -> dict[str, Any]:
        """The same capsule as a scene object (``planning.geometry.objects``) named
        ``oid``."""
        return {"type": "capsule", "id": oid, "a": self.a.tolist(), "b": self.b.tolist(),
                "radius": float(self.radius)}

    def offset_surface(self, u: np.ndarray, offset: float) -> np.ndarray:
        """``len(u)`` points at signed distance ``offset``: the directions ``u (n, 3)``
        from the nearer end for half of them (the caps), rings along the axis for the
        rest (golden-angle spaced)."""
        n = len(u)
        R = self.radius + offset
        axis = self.b - self.a
        L = float(np.linalg.norm(axis))
        ax = axis / L if L > 0 else np.array([0.0, 0.0, 1.0])
        caps = u[: max(2, n // 2)]
        X = np.where((caps @ ax)[:, None] >= 0, self.b, self.a) + R * caps
        m = n - len(caps)
        if m > 0:  # the cylinder: rings along the axis, golden-angle spaced
            e1 = unit(np.cross(ax, [1.0, 0, 0] if abs(ax[0]) < 0.9 else [0, 1.0, 0]))
            e2 = np.cross(ax, e1)
            k = np.arange(m) + 0.5
            phi = k * math.pi * (3 - math.sqrt(5))
            ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
            X = np.vstack([X, self.a + np.outer(k / m, axis) + R * ring])
        return X


Obstacle = Sphere | Box | Capsule


def obstacle_from_dict(data: Any, name: str = "") -> Obstacle:
    """An obstacle from JSON: ``{"center", "radius"}`` (sphere; ``"type"`` optional),
    ``{"type": "box", "lower", "upper"}`` or ``{"type": "box", "center", "size"}``,
    ``{"type": "capsule", "a", "b", "radius"}``. ``FieldError`` naming the field at fault,
    below ``name`` (the obstacle's own path, e.g. ``obstacles[2]``; empty: its fields
    alone, ``radius``)."""

    def field_name(key: str) -> str:
        return f"{name}.{key}" if name else key

    if isinstance(data, Sphere | Box | Capsule):
        data = data.to_dict()
    if not isinstance(data, dict):
        raise field_error(name or "obstacle", "must be an object")
    kind = data.get("type")
    if kind is None:  # inferred from the fields: radius (and a) first, then box fields
        kind = ("capsule" if "a" in data else "sphere") if "radius" in data else \
            ("box" if "lower" in data or "size" in data else "sphere")
    allowed = {"sphere": {"center", "radius"}, "box": {"lower", "upper", "center", "size"},
               "capsule": {"a", "b", "radius"}}
    if kind not in allowed:
        raise field_error(field_name("type"), f"must be 'sphere', 'box' or 'capsule', got {kind!r}")
    extra = set(data) - allowed[kind] - {"type"}
    if extra:
        raise field_error(field_name(sorted(extra)[0]), f"is not a field of a {kind}")

    def need(key: str) -> Any:
        if key not in data:
            raise field_error(field_name(key), f"is required for a {kind}")
        return data[key]

    if kind == "sphere":
        return Sphere(vec3(need("center"), field_name("center")),
                      positive(need("radius"), field_name("radius")))
    if kind == "capsule":
        return Capsule(vec3(need("a"), field_name("a")), vec3(need("b"), field_name("b")),
                       positive(need("radius"), field_name("radius")))
    if "size" in data or "center" in data:
        center = vec3(need("center"), field_name("center"))
        size = vec3(need("size"), field_name("size"))
        if np.any(size <= 0):
            raise field_error(field_name("size"), "must be positive on every axis")
        lower, upper = center - size / 2, center + size / 2
    else:
        lower = vec3(need("lower"), field_name("lower"))
        upper = vec3(need("upper"), field_name("upper"))
    if np.any(upper <= lower):
        axis = "xyz"[int(np.argmax(upper <= lower))]
        raise field_error(field_name("upper"), f"must exceed {field_name('lower')} on every axis "
                   f"({axis} does not)")
    lower, upper = np.array(lower), np.array(upper)
    lower.setflags(write=False)
    upper.setflags(write=False)
    return Box(lower, upper)
