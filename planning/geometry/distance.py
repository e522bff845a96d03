"""Exact distances from points to the convex primitives and to triangles: the Python twins
of the compiled point kernels (``planning.geometry.kernels``), side by side in the pair table
(``planning.geometry.table``).

Every function is vectorised: points ``P (K, 3)`` against ``n`` objects of one kind give
``(K, n)`` (positive outside, negative inside: minus the depth), in mm. A sphere of radius
``r`` centred at ``p`` touches or overlaps an object exactly when ``distance(p) <= r``, and
``distance(p) - r`` is then the sphere's signed distance to the object (exact for convex
objects outside, and a lower bound of it inside). The primitives' local frames are the scene
objects' (``planning.geometry.shapes``): a box centred on its origin with full sides
``size``, a cylinder centred on its origin along local z with ``height``, a capsule between
two points.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "to_local",
    "box_distance",
    "cylinder_distance",
    "sphere_distance",
    "segment_distance",
    "triangle_distance",
    "frames_along",
    "segment_frame",
    "capsule_distance",
    "ball_set_distance",
]


def to_local(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Points ``P (K, 3)`` in the frames of poses ``T (n, 4, 4)``: ``(K, n, 3)`` with
    ``p_local = R^T (p - t)``."""
    d = P[:, None, :] - T[None, :, :3, 3]
    return np.einsum("knj,nji->kni", d, T[:, :3, :3])


def box_distance(P: np.ndarray, T: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Signed distance ``(K, n)`` of points ``P (K, 3)`` to boxes posed ``T (n, 4, 4)`` with
    full sides ``size (n, 3)``."""
    q = np.abs(to_local(P, T)) - 0.5 * size[None]
    outside = np.sqrt(np.square(np.maximum(q, 0.0)).sum(-1))
    return outside + np.minimum(q.max(-1), 0.0)


def cylinder_distance(P: np.ndarray, T: np.ndarray, radius: np.ndarray,
                      height: np.ndarray) -> np.ndarray:
    """Signed distance ``(K, n)`` of points ``P (K, 3)`` to solid cylinders posed
    ``T (n, 4, 4)`` (axis local z, centred), ``radius (n,)`` and ``height (n,)``."""
    L = to_local(P, T)
    dr = np.hypot(L[..., 0], L[..., 1]) - radius[None]
    dz = np.abs(L[..., 2]) - 0.5 * height[None]
    outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
    return outside + np.minimum(np.maximum(dr, dz), 0.0)


def sphere_distance(P: np.ndarray, centre: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Signed distance ``(K, n)`` of points ``P (K, 3)`` to balls ``centre (n, 3)``,
    ``radius (n,)``."""
    return np.linalg.norm(P[:, None, :] - centre[None], axis=-1) - radius[None]


def segment_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distance ``(K, n)`` of points ``P (K, 3)`` to segments ``A (n, 3)`` - ``B (n, 3)``
    (a segment of zero length is its point)."""
    AB = B - A
    L2 = np.einsum("nj,nj->n", AB, AB)
    AP = P[:, None, :] - A[None]
    t = np.einsum("knj,nj->kn", AP, AB) / np.where(L2 > 0, L2, 1.0)[None]
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(AP - t[..., None] * AB[None], axis=-1)


def triangle_distance(P: np.ndarray, V0: np.ndarray, V1: np.ndarray,
                      V2: np.ndarray) -> np.ndarray:
    """Distance ``(K, n)`` of points ``P (K, 3)`` to triangles ``(V0, V1, V2)``, each
    ``(n, 3)`` (unsigned: a triangle has no inside). Closest point by the Voronoi regions of
    the triangle's vertices, edges and face (Ericson, *Real-Time Collision Detection*,
    5.1.5), evaluated for every region at once and picked by mask; a degenerate triangle
    falls back to its three edges."""
    a, b, c = V0[None], V1[None], V2[None]
    p = P[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d1 = (ab * ap).sum(-1)
    d2 = (ac * ap).sum(-1)
    bp = p - b
    d3 = (ab * bp).sum(-1)
    d4 = (ac * bp).sum(-1)
    cp = p - c
    d5 = (ab * cp).sum(-1)
    d6 = (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
    face = a + v[..., None] * ab + w[..., None] * ac
    best = np.linalg.norm(p - face, axis=-1)
    inside = (va >= 0) & (vb >= 0) & (vc >= 0) & (denom > 0)
    edges = np.minimum(np.minimum(_seg(p, a, b), _seg(p, b, c)), _seg(p, a, c))
    return np.where(inside, np.minimum(best, edges), edges)


def _seg(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of ``p (K, 1, 3)`` to segments ``a``-``b`` ``(1, n, 3)``: ``(K, n)``."""
    ab = b - a
    L2 = (ab * ab).sum(-1)
    t = ((p - a) * ab).sum(-1) / np.where(L2 > 0, L2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - a - t[..., None] * ab, axis=-1)


def frames_along(A: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Poses ``(..., 4, 4)`` at points ``A (..., 3)`` whose z axis is along ``E (..., 3)``
    (any z for a zero ``E``)."""
    n = np.linalg.norm(E, axis=-1, keepdims=True)
    z = np.where(n > 0, E / np.where(n > 0, n, 1.0), np.array([0.0, 0.0, 1.0]))
    helper = np.where(np.abs(z[..., :1]) < 0.9, np.array([1.0, 0.0, 0.0]),
                      np.array([0.0, 1.0, 0.0]))
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    T = np.zeros(A.shape[:-1] + (4, 4))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2], T[..., :3, 3] = x, y, z, A
    T[..., 3, 3] = 1.0
    return T


def segment_frame(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A pose ``(4, 4)`` at the midpoint of ``a``-``b`` ``(3,)`` whose z axis runs along it
    (a capsule's or a cylinder's frame between its ends)."""
    T = frames_along(a, b - a)
    T[:3, 3] = 0.5 * (a + b)
    return T


def capsule_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray,
                     radius: np.ndarray) -> np.ndarray:
    """Signed distance ``(K, n)`` of points ``P (K, 3)`` to capsules: segments
    ``A (n, 3)`` - ``B (n, 3)`` swept by balls of ``radius (n,)``."""
    return segment_distance(P, A, B) - radius


def ball_set_distance(P: np.ndarray, balls: np.ndarray) -> np.ndarray:
    """Signed distance ``(K,)`` of points ``P (K, 3)`` to the union of ``balls (M, 4)``
    (``[x, y, z, radius]``), by brute force: the twin of the compiled ball-set kernel (the
    collision scene answers the same through a k-d tree, ``planning.geometry.balls``)."""
    d = np.linalg.norm(P[:, None, :] - balls[None, :, :3], axis=-1) - balls[None, :, 3]
    return d.min(axis=1)
