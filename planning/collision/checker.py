"""Collision checks of robot configurations against a scene and the robot itself.

Two stages:

1. **Spheres** (vectorised numpy over the batch): the robot's sphere trees
   (``RobotCollisionModel``) against the scene (``CollisionScene``) and against each other
   (the model's self-collision pairs), level by level: link balls, group balls, leaf balls.
   Against the scene, a level's balls are first tested against the scene's distance grid (a
   lower bound), and only the leaves the grid cannot clear get exact distances to each object;
   between links, ball pairs whose distance exceeds the threshold are dropped at each level.
   Balls contain the geometry, so a configuration the spheres call free is free.
2. **Exact** (``planning.collision.exact``, FCL): only the pairs the spheres flag, on the real
   shapes, so a configuration is reported colliding only when the exact check says so.

``collides(model, q, scene)`` answers yes/no per configuration (spheres only by default: a
"no" is certain, a "yes" may be a near miss; ``exact=True`` confirms the yeses).
``check(model, q, scene)`` answers with a ``CollisionReport``: per configuration whether it
collides, its distance (mm) and the colliding pairs (or the closest pair when free).

``distance`` is signed: at most 0 in contact. For a configuration that collides it is the
sphere model's (a lower bound of the true clearance, at most ``margin``). For a free one it is
the distance between the sphere models, a lower bound of the true clearance, unless the exact
stage measured it: configurations the spheres flagged that turn out free, and every free one
with ``exact_distance=True``, get FCL's exact distance (``distance_exact`` says which).
Lengths in mm; big batches are processed in chunks sized by the model and the scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError

from .exact import exact_stage
from .robot import RobotCollisionModel
from .scene import CollisionScene, CompiledScene

__all__ = ["CollisionReport", "check", "collides", "CHUNK_BYTES"]

#: Most bytes of temporaries one chunk of configurations may take (about).
CHUNK_BYTES = 64 << 20


@dataclass(frozen=True)
class CollisionReport:
    """Collision answers for ``B`` configurations (or one, when ``q`` was ``(dof,)``: then
    ``collides`` is a bool, ``distance`` a float and ``pairs`` one list).

    * ``collides (B,)``: the final answer (exact when ``exact``, else the spheres');
    * ``distance (B,)`` mm: see the module docstring (``inf`` with nothing to collide with);
    * ``pairs``: per configuration, the colliding pairs ``(link, object id)`` or
      ``(link, link)``, or the closest pair when free (empty when there is none);
    * ``sphere_collides (B,)``: what the spheres alone said;
    * ``distance_exact (B,)``: whether ``distance`` was measured by the exact stage.
    """

    collides: Any
    distance: Any
    pairs: Any
    sphere_collides: Any
    distance_exact: Any
    single: bool = False
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: lists for a batch, plain values for one configuration."""
        def num(x):
            return float(x) if math.isfinite(float(x)) else None

        if self.single:
            return {"collides": bool(self.collides), "distance": num(self.distance),
                    "pairs": [list(p) for p in self.pairs],
                    "sphere_collides": bool(self.sphere_collides),
                    "distance_exact": bool(self.distance_exact)}
        return {"collides": [bool(x) for x in self.collides],
                "distance": [num(x) for x in self.distance],
                "pairs": [[list(p) for p in row] for row in self.pairs],
                "sphere_collides": [bool(x) for x in self.sphere_collides],
                "distance_exact": [bool(x) for x in self.distance_exact]}


# ---- inputs ---------------------------------------------------------------------------------
def _inputs(model: RobotCollisionModel, q, scene, margin) -> tuple:
    if not isinstance(model, RobotCollisionModel):
        raise TypeError("model must be a RobotCollisionModel")
    if scene is not None and not isinstance(scene, CollisionScene):
        raise TypeError("scene must be a CollisionScene or None")
    if isinstance(margin, bool) or not isinstance(margin, int | float) \
            or not math.isfinite(margin) or margin < 0:
        raise FieldError(("margin",), "margin must be a finite number >= 0 (mm)")
    q2, single = model.batch(q)
    cs = scene.compiled() if scene is not None and len(scene) else None
    return q2, single, cs


def _chunk(model: RobotCollisionModel, cs: CompiledScene | None) -> int:
    t = model.tree
    L, G, m = t.leaf.shape[:3]
    per = 8 * (L * (G * m) * 16 + len(model.pairs) * (G * G + m * m) * 4
               + L * (cs.n if cs is not None else 0) * (G * m + 4))
    return int(np.clip(CHUNK_BYTES // max(per, 1), 8, 8192))


# ---- the sphere stage -------------------------------------------------------------------------
_EMPTY = (np.empty(0, np.intp), np.empty(0, np.intp), np.empty(0, np.intp), np.empty(0))


def _roots(model: RobotCollisionModel, M: np.ndarray) -> np.ndarray:
    """World centres ``(B, L, 3)`` of the links' root balls."""
    return np.matmul(M, model.tree.root[:, :, None])[..., 0]


def _place(Mk: np.ndarray, local: np.ndarray) -> np.ndarray:
    """World centres ``(K, n, 3)`` of ``local (K, n, w)`` under states ``Mk (K, 3, w)``."""
    return np.matmul(local, Mk.transpose(0, 2, 1))


def _where(mask: np.ndarray) -> tuple[np.ndarray, ...]:
    """``np.nonzero`` of a C-contiguous mask, through its flat indices (faster)."""
    return np.unravel_index(np.flatnonzero(mask), mask.shape)


def _sq(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Squared distances between broadcast point arrays ``(..., 3)``, per component."""
    d = X[..., 0] - Y[..., 0]
    out = d * d
    for j in (1, 2):
        d = X[..., j] - Y[..., j]
        out += d * d
    return out


def _dist(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    return np.sqrt(_sq(X, Y))


def _scene_near(model: RobotCollisionModel, cs: CompiledScene, M: np.ndarray,
                W0: np.ndarray, tau: np.ndarray) -> tuple:
    """``(b, link, object, d)`` for every configuration ``b``, link and object whose sphere
    distance ``d`` (the least over the link's leaves) is at most ``tau[b]``."""
    t = model.tree
    L = M.shape[1]
    lb = cs.lower_bound(W0) - t.root_r
    b, l = _where(lb <= tau[:, None])
    if len(b) == 0:
        return _EMPTY
    Mk = M[b, l]
    lb = cs.lower_bound(_place(Mk, t.group[l])) - t.group_r[l]
    k, g = _where(lb <= tau[b][:, None])
    if len(k) == 0:
        return _EMPTY
    Wl = _place(Mk[k], t.leaf[l[k], g])
    rl = t.leaf_r[l[k], g]
    bk = b[k]
    lb = cs.lower_bound(Wl) - rl
    k2, j = _where(lb <= tau[bk][:, None])
    if len(k2) == 0:
        return _EMPTY
    D = cs.object_distance(Wl[k2, j]) - rl[k2, j][:, None]
    bb, ll = bk[k2], l[k[k2]]
    i, o = _where(D <= tau[bb][:, None])
    if len(i) == 0:
        return _EMPTY
    key = (bb[i] * L + ll[i]) * cs.n + o
    uniq, inv = np.unique(key, return_inverse=True)
    d = np.full(len(uniq), np.inf)
    np.minimum.at(d, inv, D[i, o])
    return uniq // (L * cs.n), (uniq // cs.n) % L, uniq % cs.n, d


def _self_near(model: RobotCollisionModel, M: np.ndarray, W0: np.ndarray,
               tau: np.ndarray, need_distance: bool = True) -> tuple:
    """``(b, pair, d)`` for every configuration ``b`` and sphere-checked self pair (index
    into ``model.pairs``) whose sphere distance ``d`` is at most ``tau[b] >= 0`` (``d`` is
    NaN unless ``need_distance``)."""
    t = model.tree
    idx = model.sphere_pairs
    if len(idx) == 0:
        return _EMPTY[1:]
    pa, pc = model.pairs[idx, 0], model.pairs[idx, 1]
    lim = tau[:, None] + t.root_r[pa] + t.root_r[pc]
    b, p = _where(_sq(W0[:, pa], W0[:, pc]) <= lim * lim)
    if len(b) == 0:
        return _EMPTY[1:]
    la, lc = pa[p], pc[p]
    Ga = _place(M[b, la], t.group[la])
    Gc = _place(M[b, lc], t.group[lc])
    lim = tau[b][:, None, None] + t.group_r[la][:, :, None] + t.group_r[lc][:, None, :]
    k, ga, gc = _where(_sq(Ga[:, :, None], Gc[:, None]) <= lim * lim)
    if len(k) == 0:
        return _EMPTY[1:]
    A = _place(M[b[k], la[k]], t.leaf[la[k], ga])
    C = _place(M[b[k], lc[k]], t.leaf[lc[k], gc])
    ra, rc = t.leaf_r[la[k], ga], t.leaf_r[lc[k], gc]
    sq = _sq(A[:, :, None], C[:, None])
    if not need_distance:
        lim = tau[b[k]][:, None, None] + ra[:, :, None] + rc[:, None, :]
        hit = (sq <= lim * lim).reshape(len(k), -1).any(axis=1)
        found = np.zeros(len(b), dtype=bool)
        found[k[hit]] = True
        return b[found], idx[p[found]], np.full(int(found.sum()), np.nan)
    d2 = (np.sqrt(sq) - ra[:, :, None] - rc[:, None, :]).reshape(len(k), -1).min(axis=1)
    d = np.full(len(b), np.inf)
    np.minimum.at(d, k, d2)
    keep = d <= tau[b]
    return b[keep], idx[p[keep]], d[keep]


def _table_near(model: RobotCollisionModel, q2: np.ndarray, tau: np.ndarray) -> tuple:
    """``(b, pair, d)`` for the table-checked self pairs whose table lower bound ``d`` is at
    most ``tau[b]``."""
    if not model.tables:
        return _EMPTY[1:]
    D = _tables(model, q2)
    b, t = _where(D <= tau[:, None])
    return b, np.array([x.pair for x in model.tables], dtype=np.intp)[t], D[b, t]


def _tables(model: RobotCollisionModel, q2: np.ndarray) -> np.ndarray:
    """Every table's lower bound ``(B, n_tables)``."""
    return np.column_stack([table.lower_bound(q2) for table in model.tables])


def _upper_bound(model: RobotCollisionModel, cs: CompiledScene | None, M: np.ndarray,
                 W0: np.ndarray, q2: np.ndarray, self_collision: bool) -> tuple:
    """An upper bound ``(B,)`` of each configuration's stage-one distance (the exact sphere
    distance, or table bound, of its closest-looking pair), and lower bounds of every pair:
    scene ``(B, L, n)`` and self ``(B, P)`` (None when not checked)."""
    t = model.tree
    B, L = M.shape[:2]
    ar = np.arange(B)
    U = np.full(B, np.inf)
    d0s = d0p = None
    flat_leaf = t.leaf.reshape(L, -1, t.leaf.shape[-1])
    flat_r = t.leaf_r.reshape(L, -1)
    if cs is not None:
        d0s = cs.object_distance(W0.reshape(-1, 3)).reshape(B, L, cs.n) - t.root_r[:, None]
        best = d0s.reshape(B, -1).argmin(axis=1)
        l, o = best // cs.n, best % cs.n
        W = _place(M[ar, l], flat_leaf[l])
        D = cs.object_distance(W.reshape(-1, 3)).reshape(B, -1, cs.n)
        U = np.minimum(U, (D[ar, :, o] - flat_r[l]).min(axis=1))
    if self_collision and len(model.pairs):
        pa, pc = model.pairs[:, 0], model.pairs[:, 1]
        d0p = _dist(W0[:, pa], W0[:, pc]) - t.root_r[pa] - t.root_r[pc]
        if model.tables:
            D = _tables(model, q2)
            d0p[:, [x.pair for x in model.tables]] = D
            U = np.minimum(U, D.min(axis=1))
        idx = model.sphere_pairs
        if len(idx):
            p = idx[d0p[:, idx].argmin(axis=1)]
            a, c = pa[p], pc[p]
            A = _place(M[ar, a], flat_leaf[a])
            C = _place(M[ar, c], flat_leaf[c])
            d = _dist(A[:, :, None], C[:, None]) - flat_r[a][:, :, None] \
                - flat_r[c][:, None]
            U = np.minimum(U, d.reshape(B, -1).min(axis=1))
    return U, d0s, d0p


# ---- public checks ------------------------------------------------------------------------------
def collides(model: RobotCollisionModel, q, scene: CollisionScene | None = None,
             self_collision: bool = True, exact: bool = False, margin: float = 0.0):
    """Whether each configuration collides: ``q (dof,) -> bool``, ``(B, dof) -> (B,)``.

    The fast path for planners: spheres only unless ``exact`` (then the spheres' yeses are
    confirmed on the real shapes); never a false "free". ``margin`` (mm): closer than that
    counts as a collision."""
    q2, single, cs = _inputs(model, q, scene, margin)
    out = np.zeros(len(q2), dtype=bool)
    step = _chunk(model, cs)
    for s in range(0, len(q2), step):
        out[s:s + step] = _collides_chunk(model, scene, cs, q2[s:s + step], self_collision,
                                          exact, float(margin))
    return bool(out[0]) if single else out


def _collides_chunk(model, scene, cs, q2, self_collision, exact, margin) -> np.ndarray:
    M = model.state(q2)
    W0 = _roots(model, M)
    B = len(q2)
    tau = np.full(B, margin)
    hit = np.zeros(B, dtype=bool)
    found = []
    if cs is not None:
        b, l, o, _ = _scene_near(model, cs, M, W0, tau)
        hit[b] = True
        found.append((b, l, o, np.zeros(len(b), dtype=bool)))
    if self_collision and len(model.pairs):
        for near in (_table_near, _self_near):
            todo = np.flatnonzero(~hit) if not exact else np.arange(B)
            if len(todo) == 0:
                break
            if near is _table_near:
                b, p, _ = near(model, q2[todo], tau[todo])
            else:
                b, p, _ = near(model, M[todo], W0[todo], tau[todo], need_distance=False)
            hit[todo[b]] = True
            found.append((todo[b], model.pairs[p, 0], model.pairs[p, 1],
                          np.ones(len(b), dtype=bool)))
    if not exact or not hit.any():
        return hit
    stage = exact_stage(model, scene)
    final = np.zeros(B, dtype=bool)
    bs = np.concatenate([f[0] for f in found])
    A = np.concatenate([f[1] for f in found])
    C = np.concatenate([f[2] for f in found])
    S = np.concatenate([f[3] for f in found])
    order = np.argsort(bs, kind="stable")
    bs, A, C, S = bs[order], A[order], C[order], S[order]
    for i in range(len(bs)):
        bi = bs[i]
        if final[bi]:
            continue
        final[bi] = stage.pair_collides(M[bi], int(A[i]), int(C[i]), bool(S[i]), margin)
    return final


def check(model: RobotCollisionModel, q, scene: CollisionScene | None = None,
          self_collision: bool = True, exact: bool = True, exact_distance: bool = False,
          margin: float = 0.0) -> CollisionReport:
    """Collision report of configurations ``q (dof,)`` or ``(B, dof)`` (module docstring):
    against ``scene`` (None: none) and, with ``self_collision``, the model's own pairs.
    ``exact``: confirm the spheres' collisions on the real shapes; ``exact_distance``: the
    exact distance for every free configuration; ``margin`` (mm): closer counts as a
    collision."""
    q2, single, cs = _inputs(model, q, scene, margin)
    B = len(q2)
    collide = np.zeros(B, dtype=bool)
    sphere = np.zeros(B, dtype=bool)
    dist = np.full(B, np.inf)
    measured = np.zeros(B, dtype=bool)
    pairs: list[list[tuple[str, str]]] = [[] for _ in range(B)]
    step = _chunk(model, cs)
    for s in range(0, B, step):
        pairs[s:s + step] = _check_chunk(
            model, scene, cs, q2[s:s + step], self_collision, exact, exact_distance,
            float(margin), collide[s:s + step], sphere[s:s + step], dist[s:s + step],
            measured[s:s + step])
    if single:
        return CollisionReport(bool(collide[0]), float(dist[0]), pairs[0], bool(sphere[0]),
                               bool(measured[0]), single=True)
    return CollisionReport(collide, dist, pairs, sphere, measured)


def _check_chunk(model, scene, cs, q2, self_collision, exact, exact_distance, margin,
                 collide, sphere, dist, measured) -> list:
    """Fills the chunk's rows of ``collide``, ``sphere``, ``dist``, ``measured`` (views)
    and returns its pairs."""
    M = model.state(q2)
    W0 = _roots(model, M)
    B = len(q2)
    pairs: list = [[] for _ in range(B)]
    self_on = bool(self_collision and len(model.pairs))
    if cs is None and not self_on:
        return pairs
    U, d0s, d0p = _upper_bound(model, cs, M, W0, q2, self_on)
    tau = np.maximum(U, margin) * (1 + 1e-12) + 1e-9
    rec: list[list[tuple[float, int, int, bool]]] = [[] for _ in range(B)]
    if cs is not None:
        for b, l, o, d in zip(*_scene_near(model, cs, M, W0, tau)):
            rec[b].append((float(d), int(l), int(o), False))
    if self_on:
        for b, p, d in zip(*_self_near(model, M, W0, tau), strict=True):
            rec[b].append((float(d), int(model.pairs[p, 0]), int(model.pairs[p, 1]), True))
        for b, p, d in zip(*_table_near(model, q2, tau), strict=True):
            rec[b].append((float(d), int(model.pairs[p, 0]), int(model.pairs[p, 1]), True))
    names, ids = model.names, (cs.ids if cs is not None else ())

    def label(a, c, is_self):
        return (names[a], names[c] if is_self else ids[c])

    stage = None
    for b in range(B):
        r = sorted(rec[b])
        dist[b] = r[0][0] if r else np.inf
        hits = [x for x in r if x[0] <= margin]
        sphere[b] = bool(hits)
        collide[b] = bool(hits)
        pairs[b] = [label(*x[1:]) for x in hits] if hits else [label(*r[0][1:])] if r else []
        if not (exact and hits) and not (exact_distance and not hits):
            continue
        if stage is None:
            stage = exact_stage(model, scene)
        if hits:
            confirmed = [x for x in hits if stage.pair_collides(M[b], x[1], x[2], x[3],
                                                                margin)]
            collide[b] = bool(confirmed)
            if confirmed:
                pairs[b] = [label(*x[1:]) for x in confirmed]
                continue
        # Free: the exact distance, pairs taken in order of their sphere lower bound.
        known = {(x[1], x[2], x[3]): x[0] for x in r}
        floor = float(tau[b])
        bounds = []
        if d0s is not None:
            for a in range(M.shape[1]):
                for o in range(cs.n):
                    bounds.append((known.get((a, o, False), max(d0s[b, a, o], floor)),
                                   a, o, False))
        if d0p is not None:
            for p, (a, c) in enumerate(model.pairs):
                bounds.append((known.get((int(a), int(c), True), max(d0p[b, p], floor)),
                               int(a), int(c), True))
        bounds.sort()
        best, where = np.inf, None
        for lb, a, c, is_self in bounds:
            if lb >= best:
                break
            d = stage.pair_distance(M[b], a, c, is_self, reach=best)
            if d < best:
                best, where = d, (a, c, is_self)
        dist[b] = best
        measured[b] = True
        pairs[b] = [label(*where)] if where is not None else []
    return pairs

