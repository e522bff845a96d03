"""Path simplification passes shared by the planners: every pass keeps a path's ends and
keeps a change only when the space's segment test passes.

* ``reduce_waypoints``: from each kept waypoint, jump to the farthest later one in sight
  (tested one at a time, farthest first: a costly test runs as few times as it can);
  ``farthest_visible`` is the same pass with a batch test (one call per kept waypoint);
* ``shortcut``: random shortcuts between two points anywhere along the path (arc lengths
  drawn as ``rng.random(2) * length``, optionally weighted per coordinate), each kept when
  it is shorter and the new segment and the kept pieces of the old ones are free; ends
  after ``patience`` failures in a row or when ``stop()``; ``reduce_waypoints`` before and
  after (joint-space motion);
* ``shortcut_chords``: random chords between points along the path (arc lengths drawn as
  ``rng.uniform(0, length, 2)``), each kept when the chord alone is free (tool paths, after
  ``farthest_visible``);
* ``shortcut_vertices``: random pairs of waypoints (``rng.choice(n, 2, replace=False)``)
  joined when they see each other (the drilling arms' RRT baseline).

The passes differ in what they draw and what they accept, and each planner's seeded answers
depend on exactly that, so each is kept as its own pass here rather than one pass with the
union of their rules.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .result import Stop

__all__ = ["path_length", "reduce_waypoints", "farthest_visible", "shortcut",
           "shortcut_chords", "shortcut_vertices", "dedupe"]

#: ``free(a (dim,), b (dim,)) -> bool``: whether the straight segment is free.
Free = Callable[[np.ndarray, np.ndarray], bool]
#: ``free_many(A (k, dim), B (k, dim)) -> (k,) bool``: the batch form.
FreeMany = Callable[[np.ndarray, np.ndarray], np.ndarray]


def path_length(path: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Sum of the Euclidean lengths of the segments of ``path (K, dim)`` (each coordinate
    scaled by ``weights (dim,)`` when given)."""
    if len(path) < 2:
        return 0.0
    d = np.diff(path, axis=0)
    if weights is not None:
        d = d * weights
    return float(np.sqrt((d * d).sum(1)).sum())


def dedupe(path: np.ndarray) -> np.ndarray:
    """Drop consecutive duplicate vertices of ``path (n, dim)`` (keeps at least its ends)."""
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.any(np.abs(np.diff(path, axis=0)) > 0, axis=1)
    keep[-1] = True
    out = path[keep]
    return out if len(out) >= 2 else np.vstack([path[0], path[-1]])


def reduce_waypoints(path: np.ndarray, free: Free) -> np.ndarray:
    """Drop waypoints: from each kept waypoint, jump to the farthest later one in sight
    (the next one when none is)."""
    if len(path) <= 2:
        return path
    keep = [0]
    i = 0
    n = len(path)
    while i < n - 1:
        j = n - 1
        while j > i + 1 and not free(path[i], path[j]):
            j -= 1
        keep.append(j)
        i = j
    return path[keep]


def farthest_visible(path: np.ndarray, free_many: FreeMany) -> np.ndarray:
    """``reduce_waypoints`` with a batch test: each kept waypoint tests every later one at
    once."""
    out, i = [path[0]], 0
    while i < len(path) - 1:
        later = path[i + 1:]
        ok = free_many(np.broadcast_to(path[i], later.shape), later)
        j = i + 1 + (int(np.nonzero(ok)[0].max()) if ok.any() else 0)
        out.append(path[j])
        i = j
    return np.array(out)


def _point_at(path: np.ndarray, cum: np.ndarray, s: float) -> tuple[int, np.ndarray]:
    """The segment index and the point at arc length ``s`` of the path."""
    i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2))
    seg = cum[i + 1] - cum[i]
    t = 0.0 if seg <= 0 else (s - cum[i]) / seg
    return i, path[i] + (path[i + 1] - path[i]) * min(max(t, 0.0), 1.0)


def shortcut(path: np.ndarray, free: Free, rng: np.random.Generator, stop: Stop,
             attempts: int = 100, patience: int = 25,
             weights: np.ndarray | None = None) -> np.ndarray:
    """A shorter path with the same ends (module docstring): at most ``attempts`` random
    shortcuts, ending after ``patience`` failures in a row or when ``stop()``. Lengths are
    weighted by ``weights (dim,)`` (None: unweighted)."""
    w = 1.0 if weights is None else weights
    path = reduce_waypoints(np.asarray(path, dtype=float), free)
    fails = 0
    for _ in range(attempts):
        if len(path) <= 2 or fails >= patience or stop():
            break
        seg = np.sqrt((((np.diff(path, axis=0)) * w) ** 2).sum(1))
        cum = np.r_[0.0, np.cumsum(seg)]
        total = cum[-1]
        s0, s1 = np.sort(rng.random(2) * total)
        i, a = _point_at(path, cum, s0)
        j, b = _point_at(path, cum, s1)
        if j <= i:
            fails += 1
            continue
        old = (cum[i + 1] - s0) + (s1 - cum[j]) + (cum[j] - cum[i + 1])
        new = float(np.sqrt((((b - a) * w) ** 2).sum()))
        # The new segment, and the pieces of the old ones it keeps (checked at states of
        # their own, which the whole segments never checked).
        if new >= old - 1e-9 or not free(a, b) or not free(path[i], a) \
                or not free(b, path[j + 1]):
            fails += 1
            continue
        path = np.concatenate([path[:i + 1], a[None], b[None], path[j + 1:]])
        # Points that coincide with their neighbours add nothing.
        keep = np.r_[True, np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)]
        path = path[keep]
        fails = 0
    return reduce_waypoints(path, free)


def shortcut_chords(path: np.ndarray, free_many: FreeMany, rng: np.random.Generator,
                    tries: int) -> np.ndarray:
    """``tries`` random chords between two points anywhere on the path (vertices or inside
    segments), each kept if the chord is free (module docstring)."""
    for _ in range(tries):
        n = len(path)
        if n <= 2:
            break
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        s1, s2 = np.sort(rng.uniform(0.0, cum[-1], size=2))
        i1 = min(int(np.searchsorted(cum, s1, side="right")) - 1, n - 2)
        i2 = min(int(np.searchsorted(cum, s2, side="right")) - 1, n - 2)
        if i1 == i2:
            continue
        p1 = path[i1] + (s1 - cum[i1]) / max(seg[i1], 1e-300) * (path[i1 + 1] - path[i1])
        p2 = path[i2] + (s2 - cum[i2]) / max(seg[i2], 1e-300) * (path[i2 + 1] - path[i2])
        if free_many(p1[None], p2[None])[0]:
            path = dedupe(np.vstack([path[: i1 + 1], p1, p2, path[i2 + 1:]]))
    return path


def shortcut_vertices(path: np.ndarray, free: Free, rng: np.random.Generator,
                      attempts: int) -> np.ndarray:
    """``attempts`` random pairs of waypoints ``i < j`` joined (the waypoints between them
    dropped) when ``j - i >= 2`` and they see each other."""
    P = list(path)
    for _ in range(attempts):
        if len(P) < 3:
            break
        i, j = sorted(rng.choice(len(P), size=2, replace=False))
        if j - i < 2:
            continue
        if free(P[i], P[j]):
            P = P[: i + 1] + P[j:]
    return np.array(P)
