"""A path-planning scene: a bounding box and convex obstacles, with exact distances.

Obstacles (``planning.geometry.obstacles``) are spheres (the pile-driver paper's only kind),
axis-aligned boxes and capsules (a segment swept by a ball): the point-path format, which
every shape of a stored scene becomes through its ``path_cover``
(``planning.geometry.registry``). Every distance here is exact (closed forms, no
sampling), from the ``("segment", shape)`` rows of the geometry's pair table
(``planning.geometry.segments``):

* segment–sphere: distance from the centre to the segment's closest point, minus the radius;
* segment–capsule: segment–segment distance minus the radius;
* segment–box: the signed segment–box distance (outside and inside the box).

A *clearance* is a signed distance: positive outside, negative inside (minus the penetration
depth). A path is clear when every segment's clearance to every obstacle is at least the
scene's ``safety_margin`` (touching an obstacle exactly is clear with margin 0). Lengths in
mm. Batched functions take segments as ``P0, P1: (M, 3)`` and return ``(M, n_obstacles)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError

from ..geometry.obstacles import (
    Box,
    Capsule,
    Obstacle,
    Sphere,
    field_error,
    obstacle_from_dict,
    positive,
    vec3,
)
from ..geometry.segments import (
    box_point_sdf,
    fibonacci_sphere,
    segment_box_distance,
    segment_point_distance,
    segment_segment_distance,
    unit,
)
from .broadphase import BroadPhase

__all__ = [
    "Sphere",
    "Box",
    "Capsule",
    "Obstacle",
    "Scene",
]

#: From this many obstacles on, clearance checks go through the broad phase
#: (``planning.paths.broadphase``); below it every pair is computed, which is faster there.
BROAD_PHASE_MIN_OBSTACLES = 24
#: Most temporary bytes one batch of exact distance computations may take: larger inputs
#: are computed in chunks of this size.
CHUNK_BYTES = 64 << 20
#: Peak temporary bytes per (segment, obstacle) pair of the exact kernels, by obstacle type
#: (measured, with room).
PAIR_BYTES = {"sphere": 120, "capsule": 220, "box": 3600}


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
        lower = vec3(self.lower, "bounds[0]")
        upper = vec3(self.upper, "bounds[1]")
        if np.any(upper <= lower):
            axis = "xyz"[int(np.argmax(upper <= lower))]
            raise field_error("bounds[1]", f"must exceed bounds[0] on every axis ({axis} does not)")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        obs = tuple(obstacle_from_dict(o, f"obstacles[{i}]")
                    for i, o in enumerate(self.obstacles))
        object.__setattr__(self, "obstacles", obs)
        object.__setattr__(self, "safety_margin",
                           positive(self.safety_margin, "safety_margin", allow_zero=True))
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
            raise field_error("bounds", "must be [[x, y, z], [x, y, z]]") from None
        if b.shape != (2, 3):
            raise field_error("bounds", f"must be [[x, y, z], [x, y, z]], got shape "
                              f"{list(b.shape)}")
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
            raise field_error("obstacles", "must be a list")
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
            centres[i], radii[i] = o.bounding_sphere()
        return centres, radii

    def bounding_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners ``lower (n, 3)``, ``upper (n, 3)`` of axis-aligned boxes containing each
        obstacle."""
        lo = np.empty((len(self.obstacles), 3))
        hi = np.empty((len(self.obstacles), 3))
        for i, o in enumerate(self.obstacles):
            lo[i], hi[i] = o.bounding_box()
        return lo, hi

    def obstacle_sizes(self) -> np.ndarray:
        """Each obstacle's size ``(n,)`` mm: the radius of a sphere or capsule, half the
        smallest side of a box."""
        if "sizes" not in self._arrays:
            self._arrays["sizes"] = np.array([o.size for o in self.obstacles], dtype=float)
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
                nn[:, a["sphere_index"]] = unit(p - a["sc"][None])
        if len(a["cr"]):
            dist, s, t = segment_segment_distance(A, B, a["ca"][None], a["cb"][None])
            out[:, a["capsule_index"]] = dist - a["cr"]
            if details:
                p = A + s[..., None] * (B - A)
                q = a["ca"][None] + t[..., None] * (a["cb"] - a["ca"])[None]
                tt[:, a["capsule_index"]] = s
                nn[:, a["capsule_index"]] = unit(p - q)
        if len(a["bl"]):
            dist, t = segment_box_distance(A, B, a["bl"][None], a["bu"][None])
            out[:, a["box_index"]] = dist
            if details:
                p = A + t[..., None] * (B - A)
                tt[:, a["box_index"]] = t
                nn[:, a["box_index"]] = box_point_sdf(p, a["bl"][None], a["bu"][None])[1]

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
                        nn[j] = unit(A + t[:, None] * (B - A) - c)
                elif code == 1:
                    qa, qb = a["ca"][r], a["cb"][r]
                    dist, t, u = segment_segment_distance(A, B, qa, qb)
                    out[j] = dist - a["cr"][r]
                    if details:
                        nn[j] = unit(A + t[:, None] * (B - A) - (qa + u[:, None] * (qb - qa)))
                else:
                    lo, hi = a["bl"][r], a["bu"][r]
                    point = np.all(A == B, axis=1)  # points: the box's distance field
                    t = np.zeros(len(j))
                    dist = np.empty(len(j))
                    if point.any():
                        dist[point] = box_point_sdf(A[point], lo[point], hi[point])[0]
                    if not point.all():
                        seg = ~point
                        dist[seg], t[seg] = segment_box_distance(A[seg], B[seg], lo[seg],
                                                                 hi[seg])
                    out[j] = dist
                    if details:
                        nn[j] = box_point_sdf(A + t[:, None] * (B - A), lo, hi)[1]
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
        p = vec3(point, name)
        if not self.in_bounds(p)[0]:
            raise field_error(name, "is outside bounds")
        if self.obstacles:
            c = self.point_clearance(p)[0]
            k = int(np.argmin(c))
            if c[k] < 0:
                raise field_error(name, f"is inside obstacles[{k}]")
            if c[k] < self.safety_margin:
                raise field_error(name, f"is within safety_margin ({self.safety_margin} mm) of "
                           f"obstacles[{k}] ({c[k]:.3f} mm away)")
        return p

    # ---- surfaces (for visibility graphs) ---------------------------------------------------
    def surface_points(self, index: int, n: int, offset: float,
                       rng: np.random.Generator | None = None, *,
                       rotation: np.ndarray | None = None) -> np.ndarray:
        """``n`` points ``(n, 3)`` at signed distance ``offset`` from obstacle ``index``.

        The directions are a Fibonacci lattice (even, deterministic), turned by
        ``rotation (3, 3)`` if given, else by a random rotation drawn from ``rng`` if given;
        each obstacle places them on its offset surface (``offset_surface``: also on the
        rounded edges and corners where shortest paths wrap).
        """
        o = self.obstacles[index]
        u = fibonacci_sphere(n)
        if rotation is None and rng is not None:  # a random rotation of the lattice
            rotation, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        if rotation is not None:
            u = u @ np.asarray(rotation, dtype=float).T
        return o.offset_surface(u, offset)

