"""Triangles against boxes and cylinders, compiled: the exact stage of a mesh link against a
box or a cylinder of the scene without leaving compiled code.

The exact stage's semantics are FCL's (docs/collision.md): a mesh is its surface, boxes and
cylinders are solid, and touching counts.

* **Box**: a triangle meets a solid box exactly when no separating axis exists among the
  box's three face normals, the triangle's normal and the nine cross products of a box axis
  with a triangle edge (the separating axis theorem for two convex sets; Akenine-Möller's
  triangle-box test); each axis is tested with ``>`` (a gap), so touching is a hit.
* **Cylinder**: the triangle clipped to the cylinder's slab (``|z| <= h``, Sutherland-Hodgman)
  is a convex polygon whose points are inside the cylinder exactly when they are within the
  radius of the axis, so it meets the cylinder exactly when its projection on the plane
  across the axis comes within the radius of the axis (inside the projected polygon, or an
  edge that near).

A link's triangles are kept in its own frame with their bounding boxes, ordered along a
space-filling curve (Morton order of their centres) and grouped in chunks of ``CHUNK`` with
the chunks' bounding boxes; an object is brought into that frame once per test (its centre,
axes and the half widths of its bounding box there), only the chunks whose boxes meet that
box are opened, and only their triangles whose boxes meet it are transformed and tested (a
gripper's 40,000-triangle mesh beside a box: a few chunks, not 40,000 box tests). Lengths
in mm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from .kernels import _JIT
from .registry import KERNEL_CODES

__all__ = ["MeshTriangles", "triangles_meet_object"]

BOX = KERNEL_CODES["box"]


#: Triangles per chunk (the last chunk of a link may hold fewer).
CHUNK = 32


def _morton_order(centres: np.ndarray) -> np.ndarray:
    """The order of the points ``(T, 3)`` along a Morton (Z-order) curve over their bounding
    box, 10 bits an axis: neighbours in the order are near in space."""
    lo = centres.min(axis=0)
    span = np.maximum(centres.max(axis=0) - lo, 1e-12)
    cell = np.minimum((centres - lo) / span * 1024.0, 1023.0).astype(np.uint64)
    code = np.zeros(len(centres), dtype=np.uint64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cell[:, axis] >> np.uint64(bit)) & np.uint64(1)) \
                << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


class MeshTriangles:
    """The triangles of several links, flattened: ``tri (N, 3, 3)`` in each link's frame,
    their bounding boxes ``lo``, ``hi`` ``(N, 3)``; link ``k``'s rows are
    ``first[k]:first[k + 1]``, in Morton order, and ``whole[k]`` says whether they are all
    of its geometry (a link with primitives, solids, is not settled here). Its rows are cut
    in chunks of at most ``CHUNK``: link ``k``'s chunks are ``cfirst[k]:cfirst[k + 1]``,
    chunk ``j``'s rows ``cstart[j]:cstart[j + 1]``, its bounding box ``cbox[j]`` (lo xyz,
    hi xyz)."""

    def __init__(self, links: list[Any]) -> None:
        """``links``: per link, its triangles ``(T, 3, 3)`` in its frame, or None."""
        parts = []
        for t in links:
            t = np.zeros((0, 3, 3)) if t is None else np.asarray(t, float).reshape(-1, 3, 3)
            if len(t) > CHUNK:
                t = t[_morton_order(t.mean(axis=1))]
            parts.append(t)
        self.whole = np.array([t is not None and len(t) > 0 for t in links], dtype=np.bool_)
        self.first = np.cumsum([0] + [len(x) for x in parts]).astype(np.int64)
        self.tri = np.ascontiguousarray(np.concatenate(parts) if parts
                                        else np.zeros((0, 3, 3)))
        self.lo = np.ascontiguousarray(self.tri.min(axis=1)) if len(self.tri) \
            else np.zeros((0, 3))
        self.hi = np.ascontiguousarray(self.tri.max(axis=1)) if len(self.tri) \
            else np.zeros((0, 3))
        starts = [np.arange(self.first[k], self.first[k + 1], CHUNK)
                  for k in range(len(parts))]
        self.cfirst = np.cumsum([0] + [len(x) for x in starts]).astype(np.int64)
        self.cstart = np.ascontiguousarray(np.r_[np.concatenate(starts) if starts else [],
                                                 self.first[-1]].astype(np.int64))
        n = len(self.cstart) - 1
        self.cbox = np.empty((n, 6))
        if n:
            self.cbox[:, :3] = np.minimum.reduceat(self.lo, self.cstart[:-1], axis=0)
            self.cbox[:, 3:] = np.maximum.reduceat(self.hi, self.cstart[:-1], axis=0)

    def meets(self, k: int, Mk: np.ndarray, T_inv: np.ndarray, kind: int,
              par: np.ndarray) -> bool:
        """``triangles_meet_object`` of link ``k``'s triangles."""
        return bool(triangles_meet_object(
            self.tri, self.lo, self.hi, self.cbox, self.cstart, self.cfirst[k],
            self.cfirst[k + 1], np.ascontiguousarray(Mk, dtype=float),
            np.ascontiguousarray(T_inv, dtype=float), np.int64(kind),
            np.asarray(par, dtype=float)))


@njit(inline="always", **_JIT)
def _axis_gap(p0, p1, p2, r):
    """Whether the projections ``p0..p2`` of a triangle miss ``[-r, r]``."""
    lo = min(p0, p1, p2)
    hi = max(p0, p1, p2)
    return lo > r or hi < -r


@njit(**_JIT)
def _triangle_meets_box(v, h0, h1, h2):
    """Whether triangle ``v (3, 3)`` (box frame) meets the solid box of half sides
    ``h0, h1, h2`` centred on the origin: the thirteen axes of the separating axis test."""
    x0, y0, z0 = v[0, 0], v[0, 1], v[0, 2]
    x1, y1, z1 = v[1, 0], v[1, 1], v[1, 2]
    x2, y2, z2 = v[2, 0], v[2, 1], v[2, 2]
    # The box's face normals: the triangle's bounding box against the box.
    if min(x0, x1, x2) > h0 or max(x0, x1, x2) < -h0:
        return False
    if min(y0, y1, y2) > h1 or max(y0, y1, y2) < -h1:
        return False
    if min(z0, z1, z2) > h2 or max(z0, z1, z2) < -h2:
        return False
    # Edge x box axis: for edge (ex, ey, ez), the axes (0, -ez, ey), (ez, 0, -ex) and
    # (-ey, ex, 0); the box's half width along each is the sum of |component| x half side.
    for k in range(3):
        if k == 0:
            ex, ey, ez = x1 - x0, y1 - y0, z1 - z0
        elif k == 1:
            ex, ey, ez = x2 - x1, y2 - y1, z2 - z1
        else:
            ex, ey, ez = x0 - x2, y0 - y2, z0 - z2
        # a = (0, -ez, ey)
        r = h1 * abs(ez) + h2 * abs(ey)
        if _axis_gap(-ez * y0 + ey * z0, -ez * y1 + ey * z1, -ez * y2 + ey * z2, r):
            return False
        # a = (ez, 0, -ex)
        r = h0 * abs(ez) + h2 * abs(ex)
        if _axis_gap(ez * x0 - ex * z0, ez * x1 - ex * z1, ez * x2 - ex * z2, r):
            return False
        # a = (-ey, ex, 0)
        r = h0 * abs(ey) + h1 * abs(ex)
        if _axis_gap(-ey * x0 + ex * y0, -ey * x1 + ex * y1, -ey * x2 + ex * y2, r):
            return False
    # The triangle's normal: its plane against the box.
    ax, ay, az = x1 - x0, y1 - y0, z1 - z0
    bx, by, bz = x2 - x0, y2 - y0, z2 - z0
    nx = ay * bz - az * by
    ny = az * bx - ax * bz
    nz = ax * by - ay * bx
    d = nx * x0 + ny * y0 + nz * z0
    r = h0 * abs(nx) + h1 * abs(ny) + h2 * abs(nz)
    return not (d > r or d < -r)


@njit(**_JIT)
def _triangle_meets_cylinder(v, R, hz):
    """Whether triangle ``v (3, 3)`` (cylinder frame) meets the solid cylinder of radius
    ``R`` and half height ``hz`` about the z axis: the triangle clipped to the slab
    ``|z| <= hz`` (a convex polygon of at most five corners) meets it exactly when the
    polygon's projection on the xy plane comes within ``R`` of the origin (inside the slab,
    only the distance from the axis decides)."""
    # Sutherland-Hodgman against z <= hz, then z >= -hz.
    P = np.empty((5, 3))
    Qp = np.empty((5, 3))
    n = 3
    for i in range(3):
        for j in range(3):
            P[i, j] = v[i, j]
    for side in range(2):
        sgn = 1.0 if side == 0 else -1.0
        m = 0
        for i in range(n):
            j = (i + 1) % n
            di = sgn * P[i, 2] - hz
            dj = sgn * P[j, 2] - hz
            if di <= 0.0:
                for c in range(3):
                    Qp[m, c] = P[i, c]
                m += 1
            if (di < 0.0 < dj) or (dj < 0.0 < di):
                t = di / (di - dj)
                for c in range(3):
                    Qp[m, c] = P[i, c] + t * (P[j, c] - P[i, c])
                m += 1
        if m == 0:
            return False
        n = m
        for i in range(n):
            for c in range(3):
                P[i, c] = Qp[i, c]
    # The projected polygon: the origin inside it (all turns one way, some area), or an
    # edge within R of the origin.
    pos = False
    neg = False
    best = np.inf
    for i in range(n):
        j = (i + 1) % n
        ax, ay = P[i, 0], P[i, 1]
        ex, ey = P[j, 0] - ax, P[j, 1] - ay
        cr = ex * (-ay) - ey * (-ax)
        if cr > 0.0:
            pos = True
        elif cr < 0.0:
            neg = True
        ee = ex * ex + ey * ey
        t = 0.0 if ee == 0.0 else min(max(-(ax * ex + ay * ey) / ee, 0.0), 1.0)
        px, py = ax + t * ex, ay + t * ey
        d = px * px + py * py
        if d < best:
            best = d
    if best <= R * R:
        return True
    return not (pos and neg) and (pos or neg)


@njit(**_JIT)
def triangles_meet_object(tri, lo, hi, cbox, cstart, a, b, Mk, T_inv, kind, par):
    """Whether any triangle of the chunks ``a:b`` (``MeshTriangles``: rows ``cstart``,
    boxes ``cbox``; triangles ``tri`` in the link frame, their boxes ``lo``, ``hi``) of a
    link posed ``Mk (3, 4)`` (link -> world) meets a solid box (``kind`` the box's code,
    half sides ``par[:3]``) or else cylinder (radius ``par[0]``, half height ``par[1]``)
    whose world -> object frame is ``T_inv (3, 4)``."""
    half = np.empty(3)
    if kind == BOX:
        half[0], half[1], half[2] = par[0], par[1], par[2]
    else:
        half[0], half[1], half[2] = par[0], par[0], par[1]
    # Link -> object frame: R x + t.
    R = np.empty((3, 3))
    t = np.empty(3)
    for i in range(3):
        for j in range(3):
            R[i, j] = T_inv[i, 0] * Mk[0, j] + T_inv[i, 1] * Mk[1, j] + T_inv[i, 2] * Mk[2, j]
        t[i] = T_inv[i, 0] * Mk[0, 3] + T_inv[i, 1] * Mk[1, 3] + T_inv[i, 2] * Mk[2, 3] \
            + T_inv[i, 3]
    # The object's bounding box in the link frame: centre -R^T t, half widths
    # sum_j |R[j, i]| half_j.
    c = np.empty(3)
    e = np.empty(3)
    for i in range(3):
        c[i] = -(R[0, i] * t[0] + R[1, i] * t[1] + R[2, i] * t[2])
        e[i] = abs(R[0, i]) * half[0] + abs(R[1, i]) * half[1] + abs(R[2, i]) * half[2]
    v = np.empty((3, 3))
    for j in range(a, b):
        if cbox[j, 0] > c[0] + e[0] or cbox[j, 3] < c[0] - e[0] \
                or cbox[j, 1] > c[1] + e[1] or cbox[j, 4] < c[1] - e[1] \
                or cbox[j, 2] > c[2] + e[2] or cbox[j, 5] < c[2] - e[2]:
            continue
        for s in range(cstart[j], cstart[j + 1]):
            if lo[s, 0] > c[0] + e[0] or hi[s, 0] < c[0] - e[0] \
                    or lo[s, 1] > c[1] + e[1] or hi[s, 1] < c[1] - e[1] \
                    or lo[s, 2] > c[2] + e[2] or hi[s, 2] < c[2] - e[2]:
                continue
            for p in range(3):
                for i in range(3):
                    v[p, i] = R[i, 0] * tri[s, p, 0] + R[i, 1] * tri[s, p, 1] \
                        + R[i, 2] * tri[s, p, 2] + t[i]
            if kind == BOX:
                if _triangle_meets_box(v, half[0], half[1], half[2]):
                    return True
            elif _triangle_meets_cylinder(v, par[0], par[1]):
                return True
    return False
