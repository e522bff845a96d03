"""The compiled point kernels (numba): signed distances from one point to one scene object,
the twins of the vectorised functions of ``planning.geometry.distance``.

Each primitive's kernel takes the point in the object's local frame and the object's row of
parameters ``par (n_o, 4)`` (``ShapeKind.kernel_params``): box half sides; cylinder radius,
half height; sphere radius; capsule radius and half length along local z. Ball sets (meshes
and point clouds) are balls sorted by the cells of a grid (``planning.geometry.balls``):
``balls (N, 4)``, cell starts ``cells``, per set ``set_meta (S, 9)`` = lo xyz, h, shape xyz,
first cell, largest radius.

``object_distance`` and ``object_within`` dispatch on the object's code, ``KERNEL_CODES`` of
``planning.geometry.registry``: the one table of codes, frozen in here at compile time. A
test (tests/planning/test_geometry.py) checks every registered code's kernel against its
Python twin on random cases. Lengths in mm.
"""

from __future__ import annotations

import math

from numba import njit

from .registry import KERNEL_CODES

__all__ = ["box_point", "cylinder_point", "sphere_point", "capsule_point", "local_distance",
           "local_within", "ballset_distance", "ballset_within", "to_local", "object_distance",
           "object_within"]

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

BOX = KERNEL_CODES["box"]
CYLINDER = KERNEL_CODES["cylinder"]
SPHERE = KERNEL_CODES["sphere"]
CAPSULE = KERNEL_CODES["capsule"]
BALLS = KERNEL_CODES["balls"]


# ---- primitives (local frame) ------------------------------------------------------------
@njit(**_JIT)
def box_point(x, y, z, par, o):
    """Box of half sides ``par[o, :3]`` centred on the origin."""
    qx = abs(x) - par[o, 0]
    qy = abs(y) - par[o, 1]
    qz = abs(z) - par[o, 2]
    ox = max(qx, 0.0)
    oy = max(qy, 0.0)
    oz = max(qz, 0.0)
    return math.sqrt(ox * ox + oy * oy + oz * oz) + min(max(qx, max(qy, qz)), 0.0)


@njit(**_JIT)
def cylinder_point(x, y, z, par, o):
    """Solid cylinder along z: radius ``par[o, 0]``, half height ``par[o, 1]``."""
    dr = math.sqrt(x * x + y * y) - par[o, 0]
    dz = abs(z) - par[o, 1]
    a = max(dr, 0.0)
    b = max(dz, 0.0)
    return math.sqrt(a * a + b * b) + min(max(dr, dz), 0.0)


@njit(**_JIT)
def sphere_point(x, y, z, par, o):
    """Ball of radius ``par[o, 0]`` at the origin."""
    return math.sqrt(x * x + y * y + z * z) - par[o, 0]


@njit(**_JIT)
def capsule_point(x, y, z, par, o):
    """Capsule along z: radius ``par[o, 0]``, segment from ``-par[o, 1]`` to ``par[o, 1]``."""
    zz = min(max(z, -par[o, 1]), par[o, 1])
    return math.sqrt(x * x + y * y + (z - zz) * (z - zz)) - par[o, 0]


@njit(**_JIT)
def local_distance(k, x, y, z, par, o):
    """Signed distance from the local point ``(x, y, z)`` to primitive ``o`` of code
    ``k``: the switch over ``KERNEL_CODES``."""
    if k == BOX:
        return box_point(x, y, z, par, o)
    if k == CYLINDER:
        return cylinder_point(x, y, z, par, o)
    if k == SPHERE:
        return sphere_point(x, y, z, par, o)
    if k == CAPSULE:
        return capsule_point(x, y, z, par, o)
    return math.nan


@njit(**_JIT)
def local_within(k, x, y, z, par, o, reach):
    """Whether the local point ``(x, y, z)`` is within ``reach`` (>= 0) of primitive ``o``
    of code ``k``: ``local_distance(...) <= reach``, compared squared where the shape's
    distance is a square root (box, sphere, capsule), which the leaf tests of the motion
    checker make millions of times."""
    if k == BOX:
        ox = max(abs(x) - par[o, 0], 0.0)
        oy = max(abs(y) - par[o, 1], 0.0)
        oz = max(abs(z) - par[o, 2], 0.0)
        return ox * ox + oy * oy + oz * oz <= reach * reach
    if k == SPHERE:
        lim = par[o, 0] + reach
        return x * x + y * y + z * z <= lim * lim
    if k == CAPSULE:
        zz = min(max(z, -par[o, 1]), par[o, 1])
        lim = par[o, 0] + reach
        return x * x + y * y + (z - zz) * (z - zz) <= lim * lim
    return local_distance(k, x, y, z, par, o) <= reach


# ---- ball sets ------------------------------------------------------------------------------
@njit(**_JIT)
def _cells_around(p, ext, s, set_meta):
    """The cell ranges of ball set ``s`` within ``ext`` of ``p`` (each axis clipped to the
    grid), its first cell and the strides."""
    h = set_meta[s, 3]
    sx = int(set_meta[s, 4])
    sy = int(set_meta[s, 5])
    sz = int(set_meta[s, 6])
    i0 = max(int(math.floor((p[0] - ext - set_meta[s, 0]) / h)), 0)
    i1 = min(int(math.floor((p[0] + ext - set_meta[s, 0]) / h)), sx - 1)
    j0 = max(int(math.floor((p[1] - ext - set_meta[s, 1]) / h)), 0)
    j1 = min(int(math.floor((p[1] + ext - set_meta[s, 1]) / h)), sy - 1)
    k0 = max(int(math.floor((p[2] - ext - set_meta[s, 2]) / h)), 0)
    k1 = min(int(math.floor((p[2] + ext - set_meta[s, 2]) / h)), sz - 1)
    return i0, i1, j0, j1, k0, k1, int(set_meta[s, 7]), sy, sz


@njit(**_JIT)
def ballset_within(p, reach, s, balls, cells, set_meta):
    """Whether a ball of set ``s`` comes within ``reach`` of ``p`` (surface distance)."""
    i0, i1, j0, j1, k0, k1, first, sy, sz = _cells_around(p, reach + set_meta[s, 8], s,
                                                          set_meta)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                cell = first + (i * sy + j) * sz + k
                for b in range(cells[cell], cells[cell + 1]):
                    dx = p[0] - balls[b, 0]
                    dy = p[1] - balls[b, 1]
                    dz = p[2] - balls[b, 2]
                    lim = reach + balls[b, 3]
                    if dx * dx + dy * dy + dz * dz <= lim * lim:
                        return True
    return False


@njit(**_JIT)
def ballset_distance(p, reach, s, balls, cells, set_meta):
    """Signed distance from ``p`` to the balls of set ``s``, or ``reach`` when none comes
    within it (a lower bound then)."""
    i0, i1, j0, j1, k0, k1, first, sy, sz = _cells_around(p, reach + set_meta[s, 8], s,
                                                          set_meta)
    best = reach
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                cell = first + (i * sy + j) * sz + k
                for b in range(cells[cell], cells[cell + 1]):
                    dx = p[0] - balls[b, 0]
                    dy = p[1] - balls[b, 1]
                    dz = p[2] - balls[b, 2]
                    d = math.sqrt(dx * dx + dy * dy + dz * dz) - balls[b, 3]
                    if d < best:
                        best = d
    return best


# ---- any object -----------------------------------------------------------------------------
@njit(inline="always", **_JIT)
def to_local(p, o, T_inv):
    """The world point ``p`` in the frame of object ``o`` (``T_inv[o] (3, 4)``: world to
    object)."""
    p0 = p[0]
    p1 = p[1]
    p2 = p[2]
    return (T_inv[o, 0, 0] * p0 + T_inv[o, 0, 1] * p1 + T_inv[o, 0, 2] * p2 + T_inv[o, 0, 3],
            T_inv[o, 1, 0] * p0 + T_inv[o, 1, 1] * p1 + T_inv[o, 1, 2] * p2 + T_inv[o, 1, 3],
            T_inv[o, 2, 0] * p0 + T_inv[o, 2, 1] * p1 + T_inv[o, 2, 2] * p2 + T_inv[o, 2, 3])


@njit(**_JIT)
def object_distance(p, reach, o, kind, T_inv, par, balls, cells, set_meta):
    """Signed distance from the world point ``p`` to object ``o`` of code ``kind[o]``,
    posed ``T_inv[o] (3, 4)`` (world to object); ball sets: at most ``reach``."""
    k = kind[o]
    if k == BALLS:
        return ballset_distance(p, reach, int(par[o, 0]), balls, cells, set_meta)
    x, y, z = to_local(p, o, T_inv)
    return local_distance(k, x, y, z, par, o)


@njit(**_JIT)
def object_within(p, reach, o, kind, T_inv, par, balls, cells, set_meta):
    """Whether the point ``p`` is within ``reach`` (>= 0) of object ``o`` (a ball set
    stops at the first ball near enough)."""
    k = kind[o]
    if k == BALLS:
        return ballset_within(p, reach, int(par[o, 0]), balls, cells, set_meta)
    x, y, z = to_local(p, o, T_inv)
    return local_within(k, x, y, z, par, o, reach)
