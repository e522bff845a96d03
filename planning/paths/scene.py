"""A path-planning scene: a bounding box and convex obstacles, with exact distances.

Obstacles are spheres (the pile-driver paper's only kind), axis-aligned boxes and capsules
(a segment swept by a ball). Every distance here is exact (closed forms, no sampling):

* segment–sphere: distance from the centre to the segment's closest point, minus the radius;
* segment–capsule: segment–segment distance (Ericson, *Real-Time Collision Detection* 5.1.9)
  minus the radius;
* segment–box: outside the box, the squared distance along the segment is piecewise
  quadratic in the segment parameter with at most six breakpoints (where a coordinate
  crosses a face plane), minimised in closed form on each piece; inside, the box's signed
  distance is the maximum of six linear functions of the parameter, whose minimum lies at an
  end or where two of them cross (15 candidates).

A *clearance* is a signed distance: positive outside, negative inside (minus the penetration
depth). A path is clear when every segment's clearance to every obstacle is at least the
scene's ``safety_margin`` (touching an obstacle exactly is clear with margin 0). Lengths in
mm. Batched functions take segments as ``P0, P1: (M, 3)`` and return ``(M, n_obstacles)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError, loc_from_path

from .broadphase import BroadPhase

__all__ = [
    "Sphere",
    "Box",
    "Capsule",
    "Obstacle",
    "Scene",
    "segment_point_distance",
    "segment_segment_distance",
    "segment_box_distance",
]

#: Largest |coordinate| (mm) accepted in a scene: beyond it the numbers stop being useful.
MAX_COORDINATE = 1e9
#: From this many obstacles on, clearance checks go through the broad phase
#: (``planning.paths.broadphase``); below it every pair is computed, which is faster there.
BROAD_PHASE_MIN_OBSTACLES = 24
#: Most temporary bytes one batch of exact distance computations may take: larger inputs
#: are computed in chunks of this size.
CHUNK_BYTES = 64 << 20
#: Peak temporary bytes per (segment, obstacle) pair of the exact kernels, by obstacle type
#: (measured, with room).
PAIR_BYTES = {"sphere": 120, "capsule": 220, "box": 3600}


def _bad(name: str, message: str) -> FieldError:
    """``FieldError`` at the field path ``name`` (``obstacles[2].radius``), its message
    starting with that path."""
    return FieldError(loc_from_path(name), f"{name} {message}")


def _vec3(value: Any, name: str) -> np.ndarray:
    """``value`` as a finite float ``(3,)``; ``FieldError`` naming ``name`` otherwise."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise _bad(name, "must be 3 numbers [x, y, z]") from None
    if v.shape != (3,):
        raise _bad(name, f"must be 3 numbers [x, y, z], got shape {list(v.shape)}")
    if not np.all(np.isfinite(v)):
        raise _bad(name, "has a NaN or infinite entry")
    if np.any(np.abs(v) > MAX_COORDINATE):
        raise _bad(name, f"has a coordinate beyond {MAX_COORDINATE:.0e} mm")
    v.setflags(write=False)
    return v


def _positive(value: Any, name: str, allow_zero: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise _bad(name, "must be a number") from None
    if not math.isfinite(x):
        raise _bad(name, f"must be finite, got {x}")
    if x < 0 or (x == 0 and not allow_zero):
        raise _bad(name, f"must be {'non-negative' if allow_zero else 'positive'}")
    return x


# ---- obstacles ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Sphere:
    """A ball: ``center (3,)`` mm, ``radius`` mm > 0."""

    center: np.ndarray
    radius: float
    kind = "sphere"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "sphere", "center": self.center.tolist(), "radius": self.radius}


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``lower (3,) < upper (3,)`` mm."""

    lower: np.ndarray
    upper: np.ndarray
    kind = "box"

    def to_dict(self) -> dict[str, Any]:
        return {"type": "box", "lower": self.lower.tolist(), "upper": self.upper.tolist()}


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
        raise _bad(name or "obstacle", "must be an object")
    kind = data.get("type")
    if kind is None:  # inferred from the fields: radius (and a) first, then box fields
        kind = ("capsule" if "a" in data else "sphere") if "radius" in data else \
            ("box" if "lower" in data or "size" in data else "sphere")
    allowed = {"sphere": {"center", "radius"}, "box": {"lower", "upper", "center", "size"},
               "capsule": {"a", "b", "radius"}}
    if kind not in allowed:
        raise _bad(field_name("type"), f"must be 'sphere', 'box' or 'capsule', got {kind!r}")
    extra = set(data) - allowed[kind] - {"type"}
    if extra:
        raise _bad(field_name(sorted(extra)[0]), f"is not a field of a {kind}")

    def need(key: str) -> Any:
        if key not in data:
            raise _bad(field_name(key), f"is required for a {kind}")
        return data[key]

    if kind == "sphere":
        return Sphere(_vec3(need("center"), field_name("center")),
                      _positive(need("radius"), field_name("radius")))
    if kind == "capsule":
        return Capsule(_vec3(need("a"), field_name("a")), _vec3(need("b"), field_name("b")),
                       _positive(need("radius"), field_name("radius")))
    if "size" in data or "center" in data:
        center = _vec3(need("center"), field_name("center"))
        size = _vec3(need("size"), field_name("size"))
        if np.any(size <= 0):
            raise _bad(field_name("size"), "must be positive on every axis")
        lower, upper = center - size / 2, center + size / 2
    else:
        lower = _vec3(need("lower"), field_name("lower"))
        upper = _vec3(need("upper"), field_name("upper"))
    if np.any(upper <= lower):
        axis = "xyz"[int(np.argmax(upper <= lower))]
        raise _bad(field_name("upper"), f"must exceed {field_name('lower')} on every axis "
                   f"({axis} does not)")
    lower, upper = np.array(lower), np.array(upper)
    lower.setflags(write=False)
    upper.setflags(write=False)
    return Box(lower, upper)


# ---- distance kernels (broadcasting; last axis = xyz) --------------------------------------
def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", u, v)


def segment_point_distance(P0, P1, C) -> tuple[np.ndarray, np.ndarray]:
    """Distance from segments ``P0–P1`` to points ``C`` (all broadcast, ``(..., 3)``).

    Returns ``(distance (...), t (...))`` with ``P0 + t (P1 - P0)`` the closest point.
    Zero-length segments are points (t = 0).
    """
    d = P1 - P0
    dd = _dot(d, d)
    t = np.where(dd > 0, _dot(C - P0, d) / np.where(dd > 0, dd, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    closest = P0 + t[..., None] * d
    return np.linalg.norm(C - closest, axis=-1), t


def segment_segment_distance(P0, P1, Q0, Q1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance between segments ``P0–P1`` and ``Q0–Q1`` (broadcast, ``(..., 3)``).

    Returns ``(distance, s, t)``: closest points ``P0 + s (P1-P0)`` and ``Q0 + t (Q1-Q0)``.
    Ericson's clamped solution; handles zero-length and parallel segments.
    """
    d1, d2, r = P1 - P0, Q1 - Q0, P0 - Q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    a_ok, e_ok = a > 0, e > 0
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    general = denom > 1e-12 * a * e
    s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0, np.clip(-c / a_s, 0, 1), np.where(t > 1, np.clip((b - c) / a_s, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # Degenerate cases: one or both segments are points.
    only_q = ~a_ok & e_ok
    only_p = a_ok & ~e_ok
    both = ~a_ok & ~e_ok
    s = np.where(only_q | both, 0.0, np.where(only_p, np.clip(-c / a_s, 0, 1), s))
    t = np.where(both | only_p, 0.0, np.where(only_q, np.clip(f / e_s, 0, 1), t))
    p = P0 + s[..., None] * d1
    q = Q0 + t[..., None] * d2
    return np.linalg.norm(p - q, axis=-1), s, t


def segment_box_distance(P0, P1, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance between segments ``P0–P1`` and boxes ``[lower, upper]`` (broadcast).

    Returns ``(clearance, t)``: the least signed distance from a point of the segment to
    the box (negative = deepest penetration) and the segment parameter where it occurs.
    """
    P0, P1, lower, upper = np.broadcast_arrays(P0, P1, lower, upper)
    d = P1 - P0
    # Outside part: breakpoints where a coordinate meets a face plane.
    with np.errstate(divide="ignore", invalid="ignore"):
        tb = np.concatenate([(lower - P0) / d, (upper - P0) / d], axis=-1)
    tb = np.where(np.isfinite(tb), np.clip(tb, 0.0, 1.0), 0.0)
    knots = np.sort(np.concatenate([np.zeros(tb.shape[:-1] + (1,)), tb,
                                    np.ones(tb.shape[:-1] + (1,))], axis=-1), axis=-1)
    t_lo, t_hi = knots[..., :-1], knots[..., 1:]  # (..., 7) pieces
    tm = 0.5 * (t_lo + t_hi)
    pm = P0[..., None, :] + tm[..., None] * d[..., None, :]  # (..., 7, 3)
    below = pm < lower[..., None, :]
    above = pm > upper[..., None, :]
    bound = np.where(below, lower[..., None, :], upper[..., None, :])
    active = below | above
    alpha = np.where(active, P0[..., None, :] - bound, 0.0)
    beta = np.where(active, d[..., None, :], 0.0)
    A = np.sum(beta * beta, axis=-1)
    B = np.sum(alpha * beta, axis=-1)
    tq = np.where(A > 0, -B / np.where(A > 0, A, 1.0), t_lo)
    tq = np.clip(tq, t_lo, t_hi)
    res = alpha + beta * tq[..., None]
    f2 = np.sum(res * res, axis=-1)
    k = np.argmin(f2, axis=-1)
    out_d = np.sqrt(np.take_along_axis(f2, k[..., None], -1)[..., 0])
    out_t = np.take_along_axis(tq, k[..., None], -1)[..., 0]
    # Inside part: sdf(t) = max of 6 linear functions g_j(t) = c_j + m_j t.
    cst = np.concatenate([lower - P0, P0 - upper], axis=-1)  # (..., 6)
    slope = np.concatenate([-d, d], axis=-1)
    i, j = np.triu_indices(6, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = (cst[..., j] - cst[..., i]) / (slope[..., i] - slope[..., j])
    tx = np.where(np.isfinite(tx), np.clip(tx, 0.0, 1.0), 0.0)
    cand = np.concatenate([tx, np.zeros(tx.shape[:-1] + (1,)), np.ones(tx.shape[:-1] + (1,))],
                          axis=-1)  # (..., 17)
    g = np.max(cst[..., None, :] + slope[..., None, :] * cand[..., None], axis=-1)
    kin = np.argmin(g, axis=-1)
    in_d = np.take_along_axis(g, kin[..., None], -1)[..., 0]
    in_t = np.take_along_axis(cand, kin[..., None], -1)[..., 0]
    inside = in_d < 0
    return np.where(inside, in_d, out_d), np.where(inside, in_t, out_t)


def _box_point_sdf(X, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points to boxes and its gradient (unit, ``(..., 3)``)."""
    q = np.maximum(lower - X, X - upper)  # per-axis outside distance (negative inside)
    outside = np.maximum(q, 0.0)
    n_out = np.linalg.norm(outside, axis=-1)
    m = np.max(q, axis=-1)
    sdf = np.where(n_out > 0, n_out, m)
    sign = np.where(lower - X > X - upper, -1.0, 1.0)
    g_out = sign * outside / np.where(n_out > 0, n_out, 1.0)[..., None]
    face = np.argmax(q, axis=-1)
    g_in = np.take_along_axis(sign, face[..., None], -1) * (
        np.arange(3) == face[..., None])
    return sdf, np.where((n_out > 0)[..., None], g_out, g_in)


# ---- the scene ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Scene:
    """Bounds ``lower (3,) < upper (3,)`` mm, convex obstacles, and a safety margin (mm).

    Build with ``Scene.create`` (validates, accepts JSON-like obstacles) or
    ``Scene.from_dict``; a ``FieldError`` names the field at fault within the scene's JSON
    (``("obstacles", 2, "radius")``).
    """

    lower: np.ndarray
    upper: np.ndarray
    obstacles: tuple[Obstacle, ...] = ()
    safety_margin: float = 0.0
    _arrays: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        lower = _vec3(self.lower, "bounds[0]")
        upper = _vec3(self.upper, "bounds[1]")
        if np.any(upper <= lower):
            axis = "xyz"[int(np.argmax(upper <= lower))]
            raise _bad("bounds[1]", f"must exceed bounds[0] on every axis ({axis} does not)")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        obs = tuple(obstacle_from_dict(o, f"obstacles[{i}]")
                    for i, o in enumerate(self.obstacles))
        object.__setattr__(self, "obstacles", obs)
        object.__setattr__(self, "safety_margin",
                           _positive(self.safety_margin, "safety_margin", allow_zero=True))
        arr: dict[str, Any] = {}
        for kind in ("sphere", "box", "capsule"):
            arr[kind + "_index"] = np.array([i for i, o in enumerate(obs) if o.kind == kind],
                                            dtype=int)
        sph = [o for o in obs if o.kind == "sphere"]
        box = [o for o in obs if o.kind == "box"]
        cap = [o for o in obs if o.kind == "capsule"]
        arr["sc"] = np.array([o.center for o in sph]).reshape(-1, 3)
        arr["sr"] = np.array([o.radius for o in sph], dtype=float)
        arr["bl"] = np.array([o.lower for o in box]).reshape(-1, 3)
        arr["bu"] = np.array([o.upper for o in box]).reshape(-1, 3)
        arr["ca"] = np.array([o.a for o in cap]).reshape(-1, 3)
        arr["cb"] = np.array([o.b for o in cap]).reshape(-1, 3)
        arr["cr"] = np.array([o.radius for o in cap], dtype=float)
        # Each obstacle's kind (0 sphere, 1 capsule, 2 box) and row in that kind's arrays.
        kind_code = {"sphere": 0, "capsule": 1, "box": 2}
        arr["kind_of"] = np.array([kind_code[o.kind] for o in obs], dtype=int)
        arr["row_of"] = np.zeros(len(obs), dtype=int)
        for kind in ("sphere", "box", "capsule"):
            idx = arr[kind + "_index"]
            arr["row_of"][idx] = np.arange(len(idx))
        self._arrays.update(arr)

    @classmethod
    def create(cls, bounds, obstacles=(), safety_margin: float = 0.0) -> Scene:
        """Scene from ``bounds [[x,y,z], [x,y,z]]`` and obstacles (objects or dicts)."""
        try:
            b = np.asarray(bounds, dtype=float)
        except (TypeError, ValueError):
            raise _bad("bounds", "must be [[x, y, z], [x, y, z]]") from None
        if b.shape != (2, 3):
            raise _bad("bounds", f"must be [[x, y, z], [x, y, z]], got shape {list(b.shape)}")
        return cls(b[0], b[1], tuple(obstacles), safety_margin)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scene:
        """Scene from the API's JSON ``{"bounds", "obstacles", "safety_margin"?}``."""
        if not isinstance(data, dict):
            raise FieldError((), "scene must be an object with 'bounds'")
        if "bounds" not in data:
            raise FieldError("bounds", "scene must be an object with 'bounds'")
        obstacles = data.get("obstacles", [])
        if not isinstance(obstacles, list | tuple):
            raise _bad("obstacles", "must be a list")
        return cls.create(data["bounds"], obstacles, data.get("safety_margin", 0.0))

    def to_dict(self) -> dict[str, Any]:
        return {"bounds": [self.lower.tolist(), self.upper.tolist()],
                "obstacles": [o.to_dict() for o in self.obstacles],
                "safety_margin": self.safety_margin}

    def with_obstacles(self, extra, safety_margin: float | None = None) -> Scene:
        """A copy with ``extra`` obstacles appended (and optionally another margin)."""
        margin = self.safety_margin if safety_margin is None else safety_margin
        return Scene(self.lower, self.upper, self.obstacles + tuple(extra), margin)

    @property
    def diagonal(self) -> float:
        """Length of the bounds' diagonal (mm): the scene's length scale."""
        return float(np.linalg.norm(self.upper - self.lower))

    # ---- distances ------------------------------------------------------------------------
    def bounding_spheres(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres ``(n, 3)`` and radii ``(n,)`` of balls containing each obstacle."""
        centres = np.empty((len(self.obstacles), 3))
        radii = np.empty(len(self.obstacles))
        for i, o in enumerate(self.obstacles):
            if o.kind == "sphere":
                centres[i], radii[i] = o.center, o.radius
            elif o.kind == "box":
                centres[i] = 0.5 * (o.lower + o.upper)
                radii[i] = 0.5 * float(np.linalg.norm(o.upper - o.lower))
            else:
                centres[i] = 0.5 * (o.a + o.b)
                radii[i] = 0.5 * float(np.linalg.norm(o.b - o.a)) + o.radius
        return centres, radii

    def bounding_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``lower (n, 3)``, ``upper (n, 3)`` of axis-aligned boxes containing each
        obstacle."""
        lo = np.empty((len(self.obstacles), 3))
        hi = np.empty((len(self.obstacles), 3))
        for i, o in enumerate(self.obstacles):
            if o.kind == "sphere":
                lo[i], hi[i] = o.center - o.radius, o.center + o.radius
            elif o.kind == "box":
                lo[i], hi[i] = o.lower, o.upper
            else:
                lo[i] = np.minimum(o.a, o.b) - o.radius
                hi[i] = np.maximum(o.a, o.b) + o.radius
        return lo, hi

    def obstacle_sizes(self) -> np.ndarray:
        """Each obstacle's size ``(n,)`` mm: the radius of a sphere or capsule, half the
        smallest side of a box."""
        if "sizes" not in self._arrays:
            self._arrays["sizes"] = np.array([
                0.5 * float(np.min(o.upper - o.lower)) if o.kind == "box" else o.radius
                for o in self.obstacles], dtype=float)
        return self._arrays["sizes"]

    @property
    def broad_phase(self) -> BroadPhase | None:
        """The obstacles' broad phase (built on first use), or None below
        ``BROAD_PHASE_MIN_OBSTACLES`` obstacles."""
        if len(self.obstacles) < BROAD_PHASE_MIN_OBSTACLES:
            return None
        if "broad_phase" not in self._arrays:
            self._arrays["broad_phase"] = BroadPhase(*self.bounding_spheres(),
                                                     *self.bounding_boxes())
        return self._arrays["broad_phase"]

    def _dense_rows(self) -> int:
        """Segments per chunk of ``segment_clearance`` that keep it within ``CHUNK_BYTES``."""
        a = self._arrays
        per_segment = sum(PAIR_BYTES[k] * len(a[k + "_index"]) for k in PAIR_BYTES)
        return max(1, CHUNK_BYTES // max(1, per_segment))

    def segment_clearance(self, P0, P1, *, details: bool = False):
        """Signed clearance of segments ``P0, P1 (M, 3)`` to each obstacle ``(M, n_obs)``.

        With ``details=True`` also returns ``t (M, n_obs)``, the segment parameter of the
        closest point, and ``normal (M, n_obs, 3)``, the unit gradient of the clearance with
        respect to that point (pointing away from the obstacle): the clearance's gradient
        with respect to ``P0`` is ``(1 - t) normal`` and to ``P1`` is ``t normal`` where the
        closest point is unique. Computed in chunks of segments, so the temporary memory
        stays within ``CHUNK_BYTES`` beside the answer itself.
        """
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        M, n = len(P0), len(self.obstacles)
        out = np.empty((M, n))
        tt = np.empty((M, n)) if details else None
        nn = np.empty((M, n, 3)) if details else None
        rows = self._dense_rows()
        for s in range(0, M, rows):
            part = slice(s, s + rows)
            self._dense_clearance(P0[part], P1[part], out[part],
                                  tt[part] if details else None,
                                  nn[part] if details else None)
        if details:
            return out, tt, nn
        return out

    def _dense_clearance(self, P0, P1, out, tt, nn) -> None:
        """``segment_clearance`` of one chunk, written into ``out`` (and ``tt``, ``nn``)."""
        details = tt is not None
        a = self._arrays
        A, B = P0[:, None, :], P1[:, None, :]
        if len(a["sr"]):
            dist, t = segment_point_distance(A, B, a["sc"][None])
            out[:, a["sphere_index"]] = dist - a["sr"]
            if details:
                p = A + t[..., None] * (B - A)
                tt[:, a["sphere_index"]] = t
                nn[:, a["sphere_index"]] = _unit(p - a["sc"][None])
        if len(a["cr"]):
            dist, s, t = segment_segment_distance(A, B, a["ca"][None], a["cb"][None])
            out[:, a["capsule_index"]] = dist - a["cr"]
            if details:
                p = A + s[..., None] * (B - A)
                q = a["ca"][None] + t[..., None] * (a["cb"] - a["ca"])[None]
                tt[:, a["capsule_index"]] = s
                nn[:, a["capsule_index"]] = _unit(p - q)
        if len(a["bl"]):
            dist, t = segment_box_distance(A, B, a["bl"][None], a["bu"][None])
            out[:, a["box_index"]] = dist
            if details:
                p = A + t[..., None] * (B - A)
                tt[:, a["box_index"]] = t
                nn[:, a["box_index"]] = _box_point_sdf(p, a["bl"][None], a["bu"][None])[1]

    def pair_clearance(self, P0, P1, obstacle, *, details: bool = False):
        """Signed clearance ``(k,)`` of segment ``P0[j]–P1[j]`` to obstacle ``obstacle[j]``
        (``P0, P1 (k, 3)``, ``obstacle (k,)`` indices): the entries of ``segment_clearance``
        that are asked for, and only those. ``details=True`` adds ``t (k,)`` and
        ``normal (k, 3)`` as there."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        obstacle = np.asarray(obstacle, dtype=int).reshape(-1)
        k = len(obstacle)
        out = np.empty(k)
        tt = np.empty(k) if details else None
        nn = np.empty((k, 3)) if details else None
        a = self._arrays
        kind, row = a["kind_of"][obstacle], a["row_of"][obstacle]
        for code, name in enumerate(("sphere", "capsule", "box")):
            sel = np.nonzero(kind == code)[0]
            step = max(1, CHUNK_BYTES // PAIR_BYTES[name])
            for s in range(0, len(sel), step):
                j = sel[s:s + step]
                r, A, B = row[j], P0[j], P1[j]
                if code == 0:
                    c = a["sc"][r]
                    dist, t = segment_point_distance(A, B, c)
                    out[j] = dist - a["sr"][r]
                    if details:
                        nn[j] = _unit(A + t[:, None] * (B - A) - c)
                elif code == 1:
                    qa, qb = a["ca"][r], a["cb"][r]
                    dist, t, u = segment_segment_distance(A, B, qa, qb)
                    out[j] = dist - a["cr"][r]
                    if details:
                        nn[j] = _unit(A + t[:, None] * (B - A) - (qa + u[:, None] * (qb - qa)))
                else:
                    lo, hi = a["bl"][r], a["bu"][r]
                    point = np.all(A == B, axis=1)  # points: the box's distance field
                    t = np.zeros(len(j))
                    dist = np.empty(len(j))
                    if point.any():
                        dist[point] = _box_point_sdf(A[point], lo[point], hi[point])[0]
                    if not point.all():
                        seg = ~point
                        dist[seg], t[seg] = segment_box_distance(A[seg], B[seg], lo[seg],
                                                                 hi[seg])
                    out[j] = dist
                    if details:
                        nn[j] = _box_point_sdf(A + t[:, None] * (B - A), lo, hi)[1]
                if details:
                    tt[j] = t
        if details:
            return out, tt, nn
        return out

    def near_pairs(self, P0, P1, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every (segment, obstacle) pair whose clearance is at most ``reach`` (mm):
        ``(segment (k,), obstacle (k,), clearance (k,))``, sorted by segment then
        obstacle. Through the broad phase when the scene has many obstacles."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        bp = self.broad_phase
        segs, obs, cls = [], [], []
        step = bp.chunk() if bp is not None else self._dense_rows()
        for s in range(0, len(P0), step):
            A, B = P0[s:s + step], P1[s:s + step]
            if bp is None:
                c = self.segment_clearance(A, B)
                seg, ob = np.nonzero(c <= reach)
                c = c[seg, ob]
            else:
                seg, ob = bp.pairs(A, B, reach)
                n = len(self.obstacles)
                key = np.unique(seg * n + ob)  # once each, by segment then obstacle
                seg, ob = key // n, key % n
                c = self.pair_clearance(A[seg], B[seg], ob)
                near = c <= reach
                seg, ob, c = seg[near], ob[near], c[near]
            segs.append(seg + s)
            obs.append(ob)
            cls.append(c)
        if not segs:
            return np.empty(0, dtype=int), np.empty(0, dtype=int), np.empty(0)
        return np.concatenate(segs), np.concatenate(obs), np.concatenate(cls)

    def point_clearance(self, X) -> np.ndarray:
        """Signed clearance of points ``X (M, 3)`` to each obstacle ``(M, n_obs)``."""
        X = np.asarray(X, dtype=float).reshape(-1, 3)
        return self.segment_clearance(X, X)

    def segments_clear(self, P0, P1, margin: float | None = None) -> np.ndarray:
        """``(M,)`` bool: segment ``P0[i]–P1[i]`` keeps a clearance of at least ``margin``
        (default the scene's ``safety_margin``) to every obstacle. Exact: only pairs whose
        bounding spheres come within ``margin`` are computed, and no other pair can fail."""
        margin = self.safety_margin if margin is None else float(margin)
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        ok = np.ones(len(P0), dtype=bool)
        if not self.obstacles:
            return ok
        bp = self.broad_phase
        if bp is None:
            step = self._dense_rows()
            for s in range(0, len(P0), step):
                c = self.segment_clearance(P0[s:s + step], P1[s:s + step])
                ok[s:s + step] = np.all(c >= margin, axis=1)
            return ok
        step = bp.chunk()
        for s in range(0, len(P0), step):
            A, B = P0[s:s + step], P1[s:s + step]
            seg, ob = bp.pairs(A, B, margin)
            if len(seg):
                c = self.pair_clearance(A[seg], B[seg], ob)
                ok[s + seg[c < margin]] = False
        return ok

    def min_segment_clearance(self, P0, P1) -> np.ndarray:
        """Least clearance over obstacles of each segment ``(M,)`` (inf with no obstacles).

        Exact. With many obstacles it asks the broad phase for the pairs within a reach that
        grows fourfold until each segment has a pair within it: an obstacle left out lies
        beyond the reach, so farther than the least clearance found."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        M = len(P0)
        out = np.full(M, np.inf)
        if not self.obstacles:
            return out
        bp = self.broad_phase
        if bp is None:
            step = self._dense_rows()
            for s in range(0, M, step):
                out[s:s + step] = self.segment_clearance(P0[s:s + step],
                                                         P1[s:s + step]).min(axis=1)
            return out
        todo = np.arange(M)
        reach = 0.02 * self.diagonal
        for _ in range(4):
            if not len(todo):
                return out
            left = []
            step = bp.chunk()
            for s in range(0, len(todo), step):
                rows = todo[s:s + step]
                A, B = P0[rows], P1[rows]
                seg, ob = bp.pairs(A, B, reach)
                best = np.full(len(rows), np.inf)
                if len(seg):
                    np.minimum.at(best, seg, self.pair_clearance(A[seg], B[seg], ob))
                found = best <= reach
                out[rows[found]] = best[found]
                left.append(rows[~found])
            todo = np.concatenate(left)
            reach *= 4.0
        step = self._dense_rows()
        for s in range(0, len(todo), step):  # far from every obstacle: all pairs
            rows = todo[s:s + step]
            out[rows] = self.segment_clearance(P0[rows], P1[rows]).min(axis=1)
        return out

    def path_clearance(self, path) -> float:
        """Least clearance (mm) of a polyline ``(n, 3)`` over all its segments."""
        path = np.asarray(path, dtype=float).reshape(-1, 3)
        if len(path) == 1:
            path = np.vstack([path, path])
        return float(np.min(self.min_segment_clearance(path[:-1], path[1:]), initial=np.inf))

    def in_bounds(self, X, tol: float = 1e-9) -> np.ndarray:
        """``X (M, 3) -> (M,)`` bool: inside the bounds (within ``tol`` mm)."""
        X = np.asarray(X, dtype=float).reshape(-1, 3)
        return np.all((X >= self.lower - tol) & (X <= self.upper + tol), axis=1)

    def path_is_clear(self, path, margin: float | None = None) -> bool:
        """The exact check: every vertex in bounds and every segment's clearance to every
        obstacle at least ``margin`` (default the scene's ``safety_margin``)."""
        margin = self.safety_margin if margin is None else margin
        path = np.asarray(path, dtype=float).reshape(-1, 3)
        if not np.all(np.isfinite(path)) or not np.all(self.in_bounds(path)):
            return False
        if len(path) == 1:
            path = np.vstack([path, path])
        return bool(np.all(self.segments_clear(path[:-1], path[1:], margin)))

    def check_endpoint(self, point, name: str) -> np.ndarray:
        """Validate a start or goal ``(3,)``: finite, in bounds, clear of every obstacle by
        the safety margin. ``FieldError`` at ``name`` (a field path) naming the obstacle
        otherwise."""
        p = _vec3(point, name)
        if not self.in_bounds(p)[0]:
            raise _bad(name, "is outside bounds")
        if self.obstacles:
            c = self.point_clearance(p)[0]
            k = int(np.argmin(c))
            if c[k] < 0:
                raise _bad(name, f"is inside obstacles[{k}]")
            if c[k] < self.safety_margin:
                raise _bad(name, f"is within safety_margin ({self.safety_margin} mm) of "
                           f"obstacles[{k}] ({c[k]:.3f} mm away)")
        return p

    # ---- surfaces (for visibility graphs) ---------------------------------------------------
    def surface_points(self, index: int, n: int, offset: float,
                       rng: np.random.Generator | None = None, *,
                       rotation: np.ndarray | None = None) -> np.ndarray:
        """``n`` points ``(n, 3)`` at signed distance ``offset`` from obstacle ``index``.

        Spheres use a Fibonacci lattice (even, deterministic); boxes and capsules project
        directions from their centre onto the offset surface, which also places points on
        the rounded edges and corners where shortest paths wrap. The lattice is turned by
        ``rotation (3, 3)`` if given, else by a random rotation drawn from ``rng`` if given.
        """
        o = self.obstacles[index]
        u = _fibonacci_sphere(n)
        if rotation is None and rng is not None:  # a random rotation of the lattice
            rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        if rotation is not None:
            u = u @ np.asarray(rotation, dtype=float).T
        if o.kind == "sphere":
            return o.center + (o.radius + offset) * u
        if o.kind == "capsule":
            R = o.radius + offset
            axis = o.b - o.a
            L = float(np.linalg.norm(axis))
            ax = axis / L if L > 0 else np.array([0.0, 0.0, 1.0])
            caps = u[: max(2, n // 2)]
            X = np.where((caps @ ax)[:, None] >= 0, o.b, o.a) + R * caps
            m = n - len(caps)
            if m > 0:  # the cylinder: rings along the axis, golden-angle spaced
                e1 = _unit(np.cross(ax, [1.0, 0, 0] if abs(ax[0]) < 0.9 else [0, 1.0, 0]))
                e2 = np.cross(ax, e1)
                k = np.arange(m) + 0.5
                phi = k * math.pi * (3 - math.sqrt(5))
                ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
                X = np.vstack([X, o.a + np.outer(k / m, axis) + R * ring])
            return X
        # Boxes: the sharp box grown by ``offset`` (it contains the rounded offset surface,
        # so every point is at least ``offset`` away): its 8 corners, points along its 12
        # edges (where shortest paths wrap) and a lattice on its faces.
        lo, hi = o.lower - offset, o.upper + offset
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
        v = _fibonacci_sphere(m)
        faces = c + v / np.max(np.abs(v) / h, axis=1, keepdims=True)
        return np.vstack([corners, *edges, faces])


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1.0), 0.0)


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly evenly spread unit vectors ``(n, 3)``."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = k * math.pi * (3 - math.sqrt(5))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
