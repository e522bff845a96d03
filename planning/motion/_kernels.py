"""Compiled collision kernels of the joint-space planner (numba).

Imported only by ``planning.motion.checker``. One call checks one configuration, or every
state of a straight joint-space segment, from the joint values to the answer: link frames
along the chain (``kinematics._kernels``' layout: ``T = C[0] M_0(x_0) C[1] ... C[n]``), the
sphere trees of the links (root, group, leaf balls, as ``planning.collision.checker``) against
the scene and against each other. A ball that contains a piece of the robot and is farther than
``margin`` from everything that piece could touch proves the piece free, so a "free" answer is
certain; a "flagged" answer is a near miss or a collision, settled by the exact stage (FCL) in
Python.

Arrays (all C-contiguous float64 unless said):

* chain ``C (n + 1, 3, 4)``, ``prismatic (n,)`` bool, ``offset (n,)``;
* ``body (E,)`` int: frame ``e`` is ``P_body[e] @ X[e]`` with ``X (E, 3, 4)`` constant and
  ``P_j = C[0] M_0 C[1] ... C[j-1] M_{j-1}`` (``P_0`` the identity);
* ``capsule`` models (``w == 2``): link ``l`` runs from the origin of frame ``ends[l]`` to that
  of frame ``ends[l] + 1``; ``imported`` models (``w == 4``): link ``l`` is frame ``l``;
* trees ``root (L, w)``, ``root_r (L,)``, ``group (L, G, w)``, ``group_r (L, G)``,
  ``leaf (L, G, m, w)``, ``leaf_r (L, G, m)``;
* scene: objects ``kind (n_o,)`` int (their shapes' codes, ``KERNEL_CODES`` of
  ``planning.geometry.registry``), ``T_inv (n_o, 3, 4)`` (world to object), ``par (n_o, 4)``
  (the shapes' ``kernel_params``; ball set: index of its ball grid), ``aabb (n_o, 6)``, as
  ``planning.geometry.compiled.kernel_objects`` lays them out; the distances themselves are
  ``planning.geometry.kernels``' (the one switch over the shape codes); the scene's
  distance grid ``grid (nx*ny*nz,)`` with ``grid_meta (7,)`` = lo xyz, h, shape xyz
  (``h == 0``: no grid, objects are tested one by one), and the scene bounds
  ``scene_box (6,)``; ball
  sets ``balls (N, 4)`` sorted by cell, ``cells (n_cells + 1,)`` int starts and per set
  ``set_meta (S, 9)`` = lo xyz, h, shape xyz, first cell, largest radius;
* self pairs ``pairs (P, 2)`` int (the sphere-checked ones), and the pair tables
  (``planning.collision.tables``) of the others: per table ``tab_i (T, 8)`` int = joints
  (two, -1 for none), shape (two), first value, number of joints, the two links,
  ``tab_f (T, 6)`` = lo (two), step (two), rho (two), and their ``tab_values`` concatenated.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planning.geometry.kernels import (
    BALLS,
    ballset_within,
    local_within,
    object_distance,
    to_local,
)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

#: Answers of ``check_state``.
FREE = 0
FLAGGED = 1


# ---- frames ---------------------------------------------------------------------------------
@njit(**_JIT)
def frames(C, prismatic, offset, body, X, q, T, F):
    """Frames ``F (E, 3, 4)`` of configuration ``q``; ``T (3, 4)`` is scratch. The running
    transform is held in scalars (the compiler keeps them in registers)."""
    n = q.shape[0]
    E = body.shape[0]
    t00 = 1.0
    t01 = 0.0
    t02 = 0.0
    t03 = 0.0
    t10 = 0.0
    t11 = 1.0
    t12 = 0.0
    t13 = 0.0
    t20 = 0.0
    t21 = 0.0
    t22 = 1.0
    t23 = 0.0
    for i in range(n + 1):
        for e in range(E):
            if body[e] == i:
                for c in range(4):
                    x0 = X[e, 0, c]
                    x1 = X[e, 1, c]
                    x2 = X[e, 2, c]
                    F[e, 0, c] = t00 * x0 + t01 * x1 + t02 * x2
                    F[e, 1, c] = t10 * x0 + t11 * x1 + t12 * x2
                    F[e, 2, c] = t20 * x0 + t21 * x1 + t22 * x2
                F[e, 0, 3] += t03
                F[e, 1, 3] += t13
                F[e, 2, 3] += t23
        if i == n:
            break
        # T = T @ C[i] @ M_i(x_i)
        a00 = t00 * C[i, 0, 0] + t01 * C[i, 1, 0] + t02 * C[i, 2, 0]
        a01 = t00 * C[i, 0, 1] + t01 * C[i, 1, 1] + t02 * C[i, 2, 1]
        a02 = t00 * C[i, 0, 2] + t01 * C[i, 1, 2] + t02 * C[i, 2, 2]
        a03 = t00 * C[i, 0, 3] + t01 * C[i, 1, 3] + t02 * C[i, 2, 3] + t03
        a10 = t10 * C[i, 0, 0] + t11 * C[i, 1, 0] + t12 * C[i, 2, 0]
        a11 = t10 * C[i, 0, 1] + t11 * C[i, 1, 1] + t12 * C[i, 2, 1]
        a12 = t10 * C[i, 0, 2] + t11 * C[i, 1, 2] + t12 * C[i, 2, 2]
        a13 = t10 * C[i, 0, 3] + t11 * C[i, 1, 3] + t12 * C[i, 2, 3] + t13
        a20 = t20 * C[i, 0, 0] + t21 * C[i, 1, 0] + t22 * C[i, 2, 0]
        a21 = t20 * C[i, 0, 1] + t21 * C[i, 1, 1] + t22 * C[i, 2, 1]
        a22 = t20 * C[i, 0, 2] + t21 * C[i, 1, 2] + t22 * C[i, 2, 2]
        a23 = t20 * C[i, 0, 3] + t21 * C[i, 1, 3] + t22 * C[i, 2, 3] + t23
        x = q[i] + offset[i]
        if prismatic[i]:
            t00, t01, t02, t03 = a00, a01, a02, a03 + x * a02
            t10, t11, t12, t13 = a10, a11, a12, a13 + x * a12
            t20, t21, t22, t23 = a20, a21, a22, a23 + x * a22
        else:
            c = math.cos(x)
            s = math.sin(x)
            t00, t01, t02, t03 = c * a00 + s * a01, c * a01 - s * a00, a02, a03
            t10, t11, t12, t13 = c * a10 + s * a11, c * a11 - s * a10, a12, a13
            t20, t21, t22, t23 = c * a20 + s * a21, c * a21 - s * a20, a22, a23


@njit(**_JIT)
def link_state(F, ends, w, M):
    """Link states ``M (L, 3, w)`` from frames ``F``: the frame's rows (``w == 4``) or the
    capsule's start and run (``w == 2``)."""
    L = M.shape[0]
    for l in range(L):
        if w == 4:
            for r in range(3):
                for c in range(4):
                    M[l, r, c] = F[l, r, c]
        else:
            a = ends[l]
            for r in range(3):
                M[l, r, 0] = F[a, r, 3]
                M[l, r, 1] = F[a + 1, r, 3] - F[a, r, 3]


@njit(**_JIT)
def _place(M, l, local, out):
    """World point ``out (3,)`` of ``local (w,)`` on link ``l``."""
    w = local.shape[0]
    for r in range(3):
        v = 0.0
        for c in range(w):
            v += M[l, r, c] * local[c]
        out[r] = v


# ---- scene distances --------------------------------------------------------------------------
@njit(**_JIT)
def _grid_bound(p, grid, meta, box):
    """A lower bound of the distance from ``p`` to the scene (the grid's, and outside the
    scene's box at least the distance to the box)."""
    gx = max(box[0] - p[0], p[0] - box[3], 0.0)
    gy = max(box[1] - p[1], p[1] - box[4], 0.0)
    gz = max(box[2] - p[2], p[2] - box[5], 0.0)
    gap = math.sqrt(gx * gx + gy * gy + gz * gz)
    h = meta[3]
    sx = int(meta[4])
    sy = int(meta[5])
    sz = int(meta[6])
    ix = min(max(int(round((p[0] - meta[0]) / h)), 0), sx - 1)
    iy = min(max(int(round((p[1] - meta[1]) / h)), 0), sy - 1)
    iz = min(max(int(round((p[2] - meta[2]) / h)), 0), sz - 1)
    dx = p[0] - (meta[0] + ix * h)
    dy = p[1] - (meta[1] + iy * h)
    dz = p[2] - (meta[2] + iz * h)
    lb = grid[(ix * sy + iy) * sz + iz] - math.sqrt(dx * dx + dy * dy + dz * dz)
    if gap > 0.0 and gap > lb:
        return gap
    return lb


@njit(**_JIT)
def _near_box(p, reach, box):
    """Whether ``p`` is within ``reach`` of the box ``(6,)`` = lo xyz, hi xyz."""
    gx = max(box[0] - p[0], p[0] - box[3], 0.0)
    gy = max(box[1] - p[1], p[1] - box[4], 0.0)
    gz = max(box[2] - p[2], p[2] - box[5], 0.0)
    return gx * gx + gy * gy + gz * gz <= reach * reach


@njit(**_JIT)
def _table_bound(q, t, tab_i, tab_f, tab_values):
    """Table ``t``'s lower bound (mm) of its pair's distance at ``q``: the largest of its
    grid values at the cell's corners, each less the distance ``q`` is from that corner
    times the table's rate (``planning.collision.tables``)."""
    k = tab_i[t, 5]
    first = tab_i[t, 4]
    best = -np.inf
    if k == 1:
        j = tab_i[t, 0]
        last = tab_i[t, 2] - 1
        x = q[j]
        base = min(max(int((x - tab_f[t, 0]) / tab_f[t, 2]), 0), last)
        for c0 in range(2):
            i0 = min(base + c0, last)
            v = tab_values[first + i0] - abs(x - (tab_f[t, 0] + i0 * tab_f[t, 2])) \
                * tab_f[t, 4]
            if v > best:
                best = v
    else:
        j0 = tab_i[t, 0]
        j1 = tab_i[t, 1]
        last0 = tab_i[t, 2] - 1
        last1 = tab_i[t, 3] - 1
        x0 = q[j0]
        x1 = q[j1]
        b0 = min(max(int((x0 - tab_f[t, 0]) / tab_f[t, 2]), 0), last0)
        b1 = min(max(int((x1 - tab_f[t, 1]) / tab_f[t, 3]), 0), last1)
        for c0 in range(2):
            i0 = min(b0 + c0, last0)
            g0 = abs(x0 - (tab_f[t, 0] + i0 * tab_f[t, 2])) * tab_f[t, 4]
            for c1 in range(2):
                i1 = min(b1 + c1, last1)
                g1 = abs(x1 - (tab_f[t, 1] + i1 * tab_f[t, 3])) * tab_f[t, 5]
                v = tab_values[first + i0 * tab_i[t, 3] + i1] - g0 - g1
                if v > best:
                    best = v
    return best


@njit(**_JIT)
def _table_flagged(q, margin, tab_i, tab_f, tab_values, hits, n_hits, cap):
    """Flag the pairs whose table lower bound at ``q`` is at most ``margin`` (as
    ``_scene_link``: the new hit count; stops at the first when ``cap == 0``)."""
    for t in range(tab_i.shape[0]):
        if _table_bound(q, t, tab_i, tab_f, tab_values) <= margin:
            if cap == 0:
                return n_hits + 1
            if n_hits < cap:
                hits[n_hits, 0] = tab_i[t, 6]
                hits[n_hits, 1] = tab_i[t, 7]
                hits[n_hits, 2] = 1
                n_hits += 1
    return n_hits


# ---- one configuration ------------------------------------------------------------------------
@njit(inline="always", **_JIT)
def _object_near(p, reach, o, kind, T_inv, par, balls, cells, set_meta):
    """``object_within`` (``planning.geometry.kernels``) written into the loops that call
    it: a call passing its nine arrays cost about 100 ns, more than the test of a box or a
    cylinder itself, and the group and leaf balls make many."""
    k = kind[o]
    if k == BALLS:
        return ballset_within(p, reach, int(par[o, 0]), balls, cells, set_meta)
    x, y, z = to_local(p, o, T_inv)
    return local_within(k, x, y, z, par, o, reach)


@njit(**_JIT)
def _place_groups(M, l, group, Wg):
    w = group.shape[2]
    for g in range(group.shape[1]):
        for r in range(3):
            v = 0.0
            for c in range(w):
                v += M[l, r, c] * group[l, g, c]
            Wg[l, g, r] = v


@njit(**_JIT)
def _place_leaves(M, l, leaf, Wl):
    w = leaf.shape[3]
    for g in range(leaf.shape[1]):
        for j in range(leaf.shape[2]):
            for r in range(3):
                v = 0.0
                for c in range(w):
                    v += M[l, r, c] * leaf[l, g, j, c]
                Wl[l, g, j, r] = v


@njit(**_JIT)
def _ready(M, l, level, group, leaf, Wg, Wl, done):
    """Place link ``l``'s group (``level`` 1) or leaf (2) centres if not yet placed."""
    if done[l] < 1:
        _place_groups(M, l, group, Wg)
        done[l] = 1
    if level >= 2 and done[l] < 2:
        _place_leaves(M, l, leaf, Wl)
        done[l] = 2


@njit(**_JIT)
def _add_hit(hits, n_hits, cap, a, c, is_self):
    for h in range(n_hits):
        if hits[h, 0] == a and hits[h, 1] == c and hits[h, 2] == is_self:
            return n_hits
    if n_hits < cap:
        hits[n_hits, 0] = a
        hits[n_hits, 1] = c
        hits[n_hits, 2] = is_self
        return n_hits + 1
    return n_hits


@njit(**_JIT)
def _sq3(P, Q):
    dx = P[0] - Q[0]
    dy = P[1] - Q[1]
    dz = P[2] - Q[2]
    return dx * dx + dy * dy + dz * dz


@njit(**_JIT)
def _close(P, Q, lim):
    dx = P[0] - Q[0]
    dy = P[1] - Q[1]
    dz = P[2] - Q[2]
    return dx * dx + dy * dy + dz * dz <= lim * lim


@njit(inline="always", **_JIT)
def _box_gaps(px, py, pz, gaps, n):
    """Squared gaps of the point ``(px, py, pz)`` to the first ``n`` boxes of ``gaps``
    (``_scratch``) into its row 6: one loop without branches, which the compiler
    vectorises (a root ball against a scene's boxes took two thirds of a state's check as
    a loop that tested each box and then its shape)."""
    for o in range(n):
        gx = max(gaps[0, o] - px, px - gaps[3, o], 0.0)
        gy = max(gaps[1, o] - py, py - gaps[4, o], 0.0)
        gz = max(gaps[2, o] - pz, pz - gaps[5, o], 0.0)
        gaps[6, o] = gx * gx + gy * gy + gz * gz


@njit(**_JIT)
def check_state(M, margin, root, root_r, group, group_r, leaf, leaf_r, has_scene, kind,
                T_inv, par, aabb, grid, grid_meta, scene_box, balls, cells, set_meta, pairs,
                q, tab_i, tab_f, tab_values, hits, cap, Wr, Wg, Wl, done, gaps, near_r,
                near_g):
    """Sphere and table check of one state ``M (L, 3, w)`` of configuration ``q``: the
    number of flagged pairs written to ``hits (cap, 3)`` as ``(link, object, 0)`` or
    ``(link, link, 1)``; with ``cap == 0`` it stops at the first and answers 0 (free) or 1
    (flagged). Ball centres are placed once per state, a link's groups and leaves only when
    a coarser ball of it is near something; a leaf is tested only against the objects its
    group ball is near. ``Wr (L, 3)``, ``Wg``, ``Wl``, ``done (L,)``, ``gaps``, ``near_r``,
    ``near_g`` are scratch (``_scratch``). The loops that check state after state call
    ``_check``, its body, with the arrays grouped in tuples (inlined into them: numba's
    inliner takes at most 30 arguments, and a call passing these 33 costs as much as a
    third of an empty scene's check)."""
    return _check(M, margin, (root, root_r, group, group_r, leaf, leaf_r),
                  (has_scene, kind, T_inv, par, aabb, grid, grid_meta, scene_box, balls,
                   cells, set_meta), pairs, q, (tab_i, tab_f, tab_values), hits, cap,
                  (Wr, Wg, Wl, done, gaps, near_r, near_g))


@njit(inline="always", **_JIT)
def _check(M, margin, sph, scn, pairs, q, tabs, hits, cap, scr):
    """``check_state`` with ``sph = (root, root_r, group, group_r, leaf, leaf_r)``, ``scn``
    the scene's arrays (``MotionChecker._scene``), ``tabs = (tab_i, tab_f, tab_values)``
    and ``scr = (Wr, Wg, Wl, done, gaps, near_r, near_g)``."""
    root, root_r, group, group_r, leaf, leaf_r = sph
    has_scene, kind, T_inv, par, aabb, grid, grid_meta, scene_box, balls, cells, set_meta = scn
    tab_i, tab_f, tab_values = tabs
    Wr, Wg, Wl, done, gaps, near_r, near_g = scr
    n_hits = _table_flagged(q, margin, tab_i, tab_f, tab_values, hits, 0, cap)
    if cap == 0 and n_hits:
        return 1
    L = M.shape[0]
    G = group.shape[1]
    m = leaf.shape[2]
    for l in range(L):
        done[l] = 0
        for r in range(3):
            v = 0.0
            for c in range(root.shape[1]):
                v += M[l, r, c] * root[l, c]
            Wr[l, r] = v
    if has_scene:
        n_o = kind.shape[0]
        for l in range(L):
            reach = root_r[l] + margin
            # A link's ball beyond the scene's box (inflated by its reach) is near nothing.
            if not _near_box(Wr[l], reach, scene_box):
                continue
            if grid_meta[3] > 0.0 and _grid_bound(Wr[l], grid, grid_meta, scene_box) > reach:
                continue
            # The root ball against every object's box in one branch-free pass (vectorised
            # over the objects), then the shapes of the boxes it comes near.
            _box_gaps(Wr[l, 0], Wr[l, 1], Wr[l, 2], gaps, n_o)
            r2 = reach * reach
            nr = 0
            for o in range(n_o):
                if gaps[6, o] <= r2 and _object_near(Wr[l], reach, o, kind, T_inv, par,
                                                      balls, cells, set_meta):
                    near_r[nr] = o
                    nr += 1
            if nr == 0:
                continue
            _ready(M, l, 1, group, leaf, Wg, Wl, done)
            for g in range(G):
                # Only the objects near the root ball can be near a group ball within it.
                ng = 0
                reach = group_r[l, g] + margin
                for i in range(nr):
                    o = near_r[i]
                    if _object_near(Wg[l, g], reach, o, kind, T_inv, par, balls, cells,
                                    set_meta):
                        near_g[ng] = o
                        ng += 1
                if ng == 0:
                    continue
                _ready(M, l, 2, group, leaf, Wg, Wl, done)
                for j in range(m):
                    reach = leaf_r[l, g, j] + margin
                    for i in range(ng):
                        o = near_g[i]
                        if _object_near(Wl[l, g, j], reach, o, kind, T_inv, par, balls,
                                          cells, set_meta):
                            if cap == 0:
                                return 1
                            n_hits = _add_hit(hits, n_hits, cap, l, o, 0)
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        c = pairs[k, 1]
        if not _close(Wr[a], Wr[c], root_r[a] + root_r[c] + margin):
            continue
        _ready(M, a, 1, group, leaf, Wg, Wl, done)
        _ready(M, c, 1, group, leaf, Wg, Wl, done)
        found = False
        for ga in range(G):
            for gc in range(G):
                if not _close(Wg[a, ga], Wg[c, gc], group_r[a, ga] + group_r[c, gc] + margin):
                    continue
                _ready(M, a, 2, group, leaf, Wg, Wl, done)
                _ready(M, c, 2, group, leaf, Wg, Wl, done)
                for ja in range(m):
                    ra = leaf_r[a, ga, ja] + margin
                    for jc in range(m):
                        if _close(Wl[a, ga, ja], Wl[c, gc, jc], ra + leaf_r[c, gc, jc]):
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
            if found:
                break
        if found:
            if cap == 0:
                return 1
            n_hits = _add_hit(hits, n_hits, cap, a, c, 1)
    return n_hits


@njit(**_JIT)
def _scratch(L, G, m, aabb):
    """Scratch of ``_check``: ball centres ``Wr``, ``Wg``, ``Wl``, ``done``, the objects'
    boxes ``gaps (7, n_o)`` (rows 0-5 the bounds of ``aabb`` transposed, row 6 the squared
    gaps of one ball to them) and the near lists ``near_r``, ``near_g``."""
    n_o = aabb.shape[0]
    gaps = np.zeros((7, max(n_o, 1)))
    for o in range(n_o):
        for c in range(6):
            gaps[c, o] = aabb[o, c]
    return (np.empty((L, 3)), np.empty((L, G, 3)), np.empty((L, G, m, 3)),
            np.zeros(L, dtype=np.int8), gaps, np.empty(max(n_o, 1), dtype=np.int64),
            np.empty(max(n_o, 1), dtype=np.int64))


@njit(**_JIT)
def check_states(C, prismatic, offset, body, X, ends, w, Q, margin, root, root_r, group,
                 group_r, leaf, leaf_r, has_scene, kind, T_inv, par, aabb, grid, grid_meta,
                 scene_box, balls, cells, set_meta, pairs, tab_i, tab_f, tab_values, out):
    """Sphere answers ``out (B,)`` (0 free, 1 flagged) of configurations ``Q (B, n)``."""
    E = body.shape[0]
    L = root.shape[0]
    T = np.empty((3, 4))
    F = np.empty((E, 3, 4))
    M = np.empty((L, 3, w))
    hits = np.empty((1, 3), dtype=np.int64)
    Wr, Wg, Wl, done, gaps, near_r, near_g = _scratch(L, group.shape[1], leaf.shape[2], aabb)
    for b in range(Q.shape[0]):
        frames(C, prismatic, offset, body, X, Q[b], T, F)
        link_state(F, ends, w, M)
        out[b] = _check(M, margin, (root, root_r, group, group_r, leaf, leaf_r),
                        (has_scene, kind, T_inv, par, aabb, grid, grid_meta, scene_box,
                         balls, cells, set_meta), pairs, Q[b], (tab_i, tab_f, tab_values),
                        hits, 0, (Wr, Wg, Wl, done, gaps, near_r, near_g))


@njit(**_JIT)
def state_hits(C, prismatic, offset, body, X, ends, w, q, margin, root, root_r, group,
               group_r, leaf, leaf_r, has_scene, kind, T_inv, par, aabb, grid, grid_meta,
               scene_box, balls, cells, set_meta, pairs, tab_i, tab_f, tab_values, hits, M):
    """Every flagged pair of configuration ``q`` into ``hits (cap, 3)`` (their number), and
    its link state into ``M``."""
    E = body.shape[0]
    L = root.shape[0]
    T = np.empty((3, 4))
    F = np.empty((E, 3, 4))
    Wr, Wg, Wl, done, gaps, near_r, near_g = _scratch(L, group.shape[1], leaf.shape[2], aabb)
    frames(C, prismatic, offset, body, X, q, T, F)
    link_state(F, ends, w, M)
    return check_state(M, margin, root, root_r, group, group_r, leaf, leaf_r, has_scene, kind,
                       T_inv, par, aabb, grid, grid_meta, scene_box, balls, cells, set_meta,
                       pairs, q, tab_i, tab_f, tab_values, hits, hits.shape[0], Wr, Wg, Wl,
                       done, gaps, near_r, near_g)


@njit(**_JIT)
def segment_first(C, prismatic, offset, body, X, ends, w, a, b, n, order, start, margin,
                  root, root_r, group, group_r, leaf, leaf_r, has_scene, kind, T_inv, par,
                  aabb, grid, grid_meta, scene_box, balls, cells, set_meta, pairs, tab_i, tab_f,
                  tab_values, q):
    """Check the states ``a + (b - a) k / n`` for ``k = order[start:]`` in that order; answer
    the position in ``order`` of the first the spheres flag (its configuration left in ``q``),
    or ``len(order)`` when all are free."""
    E = body.shape[0]
    L = root.shape[0]
    dof = a.shape[0]
    T = np.empty((3, 4))
    F = np.empty((E, 3, 4))
    M = np.empty((L, 3, w))
    hits = np.empty((1, 3), dtype=np.int64)
    Wr, Wg, Wl, done, gaps, near_r, near_g = _scratch(L, group.shape[1], leaf.shape[2], aabb)
    for i in range(start, order.shape[0]):
        s = order[i] / n
        for j in range(dof):
            q[j] = a[j] + (b[j] - a[j]) * s
        frames(C, prismatic, offset, body, X, q, T, F)
        link_state(F, ends, w, M)
        if _check(M, margin, (root, root_r, group, group_r, leaf, leaf_r),
                  (has_scene, kind, T_inv, par, aabb, grid, grid_meta, scene_box, balls,
                   cells, set_meta), pairs, q, (tab_i, tab_f, tab_values), hits, 0,
                  (Wr, Wg, Wl, done, gaps, near_r, near_g)):
            return i
    return order.shape[0]


# ---- clearance ------------------------------------------------------------------------------
@njit(**_JIT)
def state_bounds(C, prismatic, offset, body, X, ends, w, q, reach, root, root_r, group,
                 group_r, leaf, leaf_r, has_scene, kind, T_inv, par, aabb, grid, grid_meta,
                 scene_box, balls, cells, set_meta, pairs, tab_i, tab_f, tab_values,
                 out_scene, out_self, out_tab, M, T, F, Wr, Wg, Wl, done, gaps):
    """Sphere lower bounds of every pair's distance at configuration ``q`` (capped at
    ``reach`` mm): link-object ``out_scene (L, n_o)``, sphere-checked self pairs
    ``out_self (P,)``, tabled pairs ``out_tab (T,)`` (the table's own bound); the link
    state into ``M``. ``T``, ``F``, ``Wr``, ``Wg``, ``Wl``, ``done``, ``gaps`` are scratch
    (``states_bounds``)."""
    frames(C, prismatic, offset, body, X, q, T, F)
    link_state(F, ends, w, M)
    L = M.shape[0]
    G = group.shape[1]
    m = leaf.shape[2]
    n_o = kind.shape[0]
    for l in range(L):
        done[l] = 0
        _place(M, l, root[l], Wr[l])
    # Balls contain their children: a coarser ball's distance bounds its leaves', so whole
    # links and groups are skipped once they cannot beat the pair's best so far (a link's
    # groups and leaves are placed only then), and an object whose bounding box is beyond
    # the cap is not measured.
    for l in range(L):
        if has_scene:
            _box_gaps(Wr[l, 0], Wr[l, 1], Wr[l, 2], gaps, n_o)
        lim = reach + root_r[l]
        for o in range(n_o):
            best = reach
            if has_scene and gaps[6, o] <= lim * lim \
                    and object_distance(Wr[l], reach + root_r[l], o, kind, T_inv, par,
                                        balls, cells, set_meta) - root_r[l] < best:
                _ready(M, l, 2, group, leaf, Wg, Wl, done)
                for g in range(G):
                    rg = group_r[l, g]
                    if object_distance(Wg[l, g], best + rg, o, kind, T_inv, par, balls, cells,
                                        set_meta) - rg >= best:
                        continue
                    for j in range(m):
                        r = leaf_r[l, g, j]
                        d = object_distance(Wl[l, g, j], best + r, o, kind, T_inv, par,
                                             balls, cells, set_meta) - r
                        if d < best:
                            best = d
            out_scene[l, o] = best
    for k in range(pairs.shape[0]):
        a = pairs[k, 0]
        c = pairs[k, 1]
        best = reach
        if math.sqrt(_sq3(Wr[a], Wr[c])) - root_r[a] - root_r[c] < best:
            _ready(M, a, 2, group, leaf, Wg, Wl, done)
            _ready(M, c, 2, group, leaf, Wg, Wl, done)
            for ga in range(G):
                for gc in range(G):
                    if math.sqrt(_sq3(Wg[a, ga], Wg[c, gc])) - group_r[a, ga] \
                            - group_r[c, gc] >= best:
                        continue
                    for ja in range(m):
                        for jc in range(m):
                            d = math.sqrt(_sq3(Wl[a, ga, ja], Wl[c, gc, jc])) \
                                - leaf_r[a, ga, ja] - leaf_r[c, gc, jc]
                            if d < best:
                                best = d
        out_self[k] = best
    for t in range(tab_i.shape[0]):
        out_tab[t] = min(_table_bound(q, t, tab_i, tab_f, tab_values), reach)


@njit(**_JIT)
def states_bounds(C, prismatic, offset, body, X, ends, w, Q, reach, root, root_r, group,
                  group_r, leaf, leaf_r, has_scene, kind, T_inv, par, aabb, grid, grid_meta,
                  scene_box, balls, cells, set_meta, pairs, tab_i, tab_f, tab_values,
                  out_scene, out_self, out_tab, M):
    """``state_bounds`` of each configuration of ``Q (S, n)``: ``out_scene (S, L, n_o)``,
    ``out_self (S, P)``, ``out_tab (S, T)`` and the link states ``M (S, L, 3, w)``."""
    L = root.shape[0]
    G = group.shape[1]
    m = leaf.shape[2]
    T = np.empty((3, 4))
    F = np.empty((body.shape[0], 3, 4))
    Wr, Wg, Wl, done, gaps, _, _ = _scratch(L, G, m, aabb)
    for s in range(Q.shape[0]):
        state_bounds(C, prismatic, offset, body, X, ends, w, Q[s], reach, root, root_r,
                     group, group_r, leaf, leaf_r, has_scene, kind, T_inv, par, aabb, grid,
                     grid_meta, scene_box, balls, cells, set_meta, pairs, tab_i, tab_f,
                     tab_values, out_scene[s], out_self[s], out_tab[s], M[s], T, F, Wr, Wg,
                     Wl, done, gaps)


# ---- search helpers ---------------------------------------------------------------------------
@njit(**_JIT)
def nearest(X, n, alive, x, w):
    """Index of the live row of ``X[:n]`` nearest to ``x`` in the ``w``-weighted metric."""
    best = np.inf
    arg = -1
    d = X.shape[1]
    for i in range(n):
        if not alive[i]:
            continue
        s = 0.0
        for j in range(d):
            t = (X[i, j] - x[j]) * w[j]
            s += t * t
            if s >= best:
                break
        if s < best:
            best = s
            arg = i
    return arg
