"""Timelines of a drilling round: each boom's phases on one clock, and the exact distance
between booms over time.

A boom's timeline is a list of ``Phase`` values back to back from time 0: ``wait`` (still),
``transfer`` (a timed joint trajectory between holes), ``collar`` (the feed advancing onto
the collar, then the collaring dwell), ``drill`` (the feed along the hole axis at the
penetration rate) and ``retract`` (the feed back off the hole). Before its first phase the
boom rests at ``q0``; after its last, at the last phase's end.

Distances between booms are those of the booms' collision models
(``planning.collision.RobotCollisionModel.from_model``: a capsule per link, the model's exact
geometry): the segment-segment distance of every pair of capsules of two booms minus both
radii (``planning.geometry.segments.segment_segment_distance``), at instants no more than
``CHECK_DT`` (10 ms) apart and close enough that no point of any boom moves more than
``CHECK_STEP_MM`` (5 mm, the target ``REFINE_MM`` leaves room for curvature) between two of
them. Every point of a capsule's axis is a convex combination of its end points, so its
motion between two instants is at most the larger end point motion: refining on the end
points bounds every point.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..geometry.segments import segment_segment_distance

__all__ = [
    "CHECK_DT",
    "CHECK_STEP_MM",
    "PHASE_KINDS",
    "Phase",
    "BoomTimeline",
    "BoomGeometry",
    "check_times",
    "sample_ends",
    "refine",
    "pair_clearance",
]

#: Largest time between two checked instants, s.
CHECK_DT = 0.01
#: Largest motion of any point of a boom between two checked instants, mm.
CHECK_STEP_MM = 5.0
#: The motion aimed for when refining (below ``CHECK_STEP_MM``: the end point paths curve).
REFINE_MM = 4.0
#: What a boom does in a phase.
PHASE_KINDS = ("wait", "transfer", "collar", "drill", "retract")
#: Instants evaluated at once in the distance computation.
CHUNK = 4096
#: Instants per block of the pruned distance (``pair_clearance`` with ``below``): the box
#: round each capsule's end points over a block bounds its distance to another's.
BLOCK = 32


@dataclass(frozen=True, eq=False)
class Phase:
    """One phase of a boom: ``kind`` (``PHASE_KINDS``), ``t0`` s on the round's clock,
    ``duration`` s, ``evaluate(tau (S,)) -> q (S, dof)`` at local times in
    ``[0, duration]``, ``hole`` the id of the hole it serves (None: a wait or the return to
    park)."""

    kind: str
    t0: float
    duration: float
    evaluate: Callable[[np.ndarray], np.ndarray]
    hole: str | None = None
    q_end: np.ndarray | None = None

    @property
    def t1(self) -> float:
        return self.t0 + self.duration


def still(q: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """An evaluator that stays at ``q (dof,)``."""
    q = np.asarray(q, dtype=float)
    return lambda tau: np.repeat(q[None], len(np.atleast_1d(tau)), axis=0)


@dataclass(eq=False)
class BoomTimeline:
    """One boom over the round: at ``q0 (dof,)`` until its first phase, then ``phases`` in
    time order (contiguous), then still at the end of the last."""

    q0: np.ndarray
    phases: list[Phase] = field(default_factory=list)

    @property
    def end(self) -> float:
        return self.phases[-1].t1 if self.phases else 0.0

    @property
    def q_final(self) -> np.ndarray:
        if not self.phases:
            return self.q0
        last = self.phases[-1]
        return last.q_end if last.q_end is not None else \
            last.evaluate(np.array([last.duration]))[0]

    def evaluate(self, t) -> np.ndarray:
        """Configurations at times ``t (S,)`` s -> ``(S, dof)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        q = np.repeat(np.asarray(self.q0, dtype=float)[None], len(t), axis=0)
        if not self.phases:
            return q
        starts = np.array([p.t0 for p in self.phases])
        k = np.searchsorted(starts, t, side="right") - 1
        after = t >= self.end
        if after.any():
            q[after] = self.q_final
        sel_all = (k >= 0) & ~after
        for m in np.unique(k[sel_all]):
            sel = np.flatnonzero(sel_all & (k == m))
            ph = self.phases[m]
            q[sel] = ph.evaluate(np.clip(t[sel] - ph.t0, 0.0, ph.duration))
        return q

    def moving(self, t0: float, t1: float) -> bool:
        """Whether any phase other than a wait overlaps ``[t0, t1]``."""
        return any(p.kind != "wait" and p.t0 < t1 and p.t1 > t0 for p in self.phases)


@dataclass(frozen=True, eq=False)
class BoomGeometry:
    """A boom's capsules: ``ends(q (S, dof)) -> (S, L, 2, 3)`` end points (mm, rig frame)
    and ``radius (L,)`` mm, from its collision model."""

    collision_model: object
    radius: np.ndarray

    @classmethod
    def of(cls, collision_model) -> BoomGeometry:
        return cls(collision_model, np.asarray(collision_model.capsule_radius, dtype=float))

    def ends(self, q: np.ndarray) -> np.ndarray:
        M = self.collision_model.state(np.atleast_2d(q))  # (S, L, 3, 2): start, run
        A = M[..., 0]
        return np.stack([A, A + M[..., 1]], axis=2)


def check_times(t0: float, t1: float, ends: Callable[[np.ndarray], Sequence[np.ndarray]],
                dt: float = CHECK_DT, step_mm: float = REFINE_MM) -> np.ndarray:
    """Instants over ``[t0, t1]``: every ``dt`` s at most, refined where some capsule end
    point of the booms ``ends(t)`` gives moves more than ``step_mm`` between two of them.
    ``ends(t (S,))`` -> a list of ``(S, L, 2, 3)`` arrays, one per boom."""
    n = max(1, int(math.ceil((t1 - t0) / dt - 1e-9)))
    t = np.linspace(t0, t1, n + 1)
    if t1 <= t0:
        return np.array([t0])
    move = np.zeros(n)
    for E in ends(t):
        d = np.linalg.norm(np.diff(E, axis=0), axis=-1).reshape(n, -1).max(axis=1)
        np.maximum(move, d, out=move)
    parts = np.maximum(1, np.ceil(move / step_mm)).astype(int)
    if np.all(parts == 1):
        return t
    pieces = [t[:1]]
    for i in np.flatnonzero(parts > 1):
        pieces.append(np.linspace(t[i], t[i + 1], parts[i] + 1)[1:-1])
    return np.sort(np.concatenate(pieces + [t[1:]]))


def sample_ends(t0: float, t1: float, ends: Callable[[np.ndarray], Sequence[np.ndarray]],
                dt: float = CHECK_DT, step_mm: float = REFINE_MM
                ) -> tuple[np.ndarray, list[np.ndarray]]:
    """The instants of ``check_times`` and the booms' capsule end points at them, each boom
    evaluated once per instant (the refined instants alone are evaluated a second time):
    ``(t (S,), [(S, L, 2, 3), ...])``."""
    if t1 <= t0:
        t = np.array([t0])
        return t, list(ends(t))
    n = max(1, int(math.ceil((t1 - t0) / dt - 1e-9)))
    t = np.linspace(t0, t1, n + 1)
    return refine(t, list(ends(t)), ends, step_mm)


def refine(t: np.ndarray, E: list[np.ndarray], ends: Callable[[np.ndarray], Sequence[np.ndarray]],
           step_mm: float = REFINE_MM) -> tuple[np.ndarray, list[np.ndarray]]:
    """Instants ``t (S,)`` (increasing) with the booms' end points ``E`` at them, refined
    wherever some end point moves more than ``step_mm`` between two: the added instants are
    evaluated by ``ends`` and merged in time order."""
    if len(t) < 2:
        return t, E
    n = len(t) - 1
    move = np.zeros(n)
    for e in E:
        d = np.linalg.norm(np.diff(e, axis=0), axis=-1).reshape(n, -1).max(axis=1)
        np.maximum(move, d, out=move)
    parts = np.maximum(1, np.ceil(move / step_mm)).astype(int)
    if np.all(parts == 1):
        return t, E
    extra = np.concatenate([np.linspace(t[i], t[i + 1], parts[i] + 1)[1:-1]
                            for i in np.flatnonzero(parts > 1)])
    Ex = ends(extra)
    order = np.argsort(np.concatenate([t, extra]), kind="stable")
    return (np.concatenate([t, extra])[order],
            [np.concatenate([e, x])[order] for e, x in zip(E, Ex, strict=True)])


def _blocks(E: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Boxes round each capsule's end points over blocks of ``size`` instants:
    ``E (S, L, 2, 3)`` -> ``lo``, ``hi`` ``(nb, L, 3)`` (the last block may be short)."""
    S = len(E)
    lo = np.minimum(E[:, :, 0], E[:, :, 1])
    hi = np.maximum(E[:, :, 0], E[:, :, 1])
    full = (S // size) * size
    L = E.shape[1]
    blo = lo[:full].reshape(-1, size, L, 3).min(axis=1)
    bhi = hi[:full].reshape(-1, size, L, 3).max(axis=1)
    if full < S:
        blo = np.concatenate([blo, lo[full:].min(axis=0)[None]])
        bhi = np.concatenate([bhi, hi[full:].max(axis=0)[None]])
    return blo, bhi


def pair_clearance(Ea: np.ndarray, ra: np.ndarray, Eb: np.ndarray, rb: np.ndarray,
                   below: float | None = None) -> np.ndarray:
    """Least signed surface distance between two booms' capsules at each instant:
    ``Ea (S, La, 2, 3)``, ``Eb (S, Lb, 2, 3)`` -> ``(S,)`` mm (negative: they overlap).

    With ``below``: exact wherever the distance is under ``below``, and elsewhere a lower
    bound that is itself at least ``below``. Per block of ``BLOCK`` instants the box round
    each capsule's end points holds the capsule at every instant of the block (a capsule's
    axis is the convex hull of its ends), so the distance of two boxes less both radii
    bounds the capsules' distance from below; the exact segment-segment distance is
    computed only for the pairs of capsules and blocks whose bound is under ``below``."""
    S = len(Ea)
    if below is None or not math.isfinite(below):
        return _exact(Ea, ra, Eb, rb)
    lo_a, hi_a = _blocks(Ea, BLOCK)
    lo_b, hi_b = _blocks(Eb, BLOCK)
    gap = np.maximum(np.maximum(lo_b[:, None] - hi_a[:, :, None],
                                lo_a[:, :, None] - hi_b[:, None]), 0.0)
    bound = np.linalg.norm(gap, axis=-1) - ra[None, :, None] - rb[None, None, :]  # (nb,La,Lb)
    near = bound < below
    far = np.where(near, np.inf, bound).reshape(len(bound), -1).min(axis=1)
    out = np.repeat(far, BLOCK)[:S]
    blk, i, j = np.nonzero(near)
    if not len(blk):
        return out
    steps = np.arange(BLOCK)
    per = max(1, CHUNK // BLOCK)
    for c0 in range(0, len(blk), per):
        kb, ki, kj = blk[c0:c0 + per], i[c0:c0 + per], j[c0:c0 + per]
        s = np.minimum(kb[:, None] * BLOCK + steps[None], S - 1)       # (m, BLOCK)
        A, B = Ea[s, ki[:, None]], Eb[s, kj[:, None]]                  # (m, BLOCK, 2, 3)
        d, _, _ = segment_segment_distance(A[..., 0, :], A[..., 1, :], B[..., 0, :],
                                           B[..., 1, :])
        d = d - ra[ki][:, None] - rb[kj][:, None]
        np.minimum.at(out, s.reshape(-1), d.reshape(-1))
    return out


def _exact(Ea: np.ndarray, ra: np.ndarray, Eb: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """``pair_clearance`` computed exactly for every pair of capsules at every instant."""
    S = len(Ea)
    out = np.empty(S)
    for s0 in range(0, S, CHUNK):
        a, b = Ea[s0:s0 + CHUNK], Eb[s0:s0 + CHUNK]
        d, _, _ = segment_segment_distance(a[:, :, None, 0], a[:, :, None, 1],
                                           b[:, None, :, 0], b[:, None, :, 1])
        d = d - ra[None, :, None] - rb[None, None, :]
        out[s0:s0 + CHUNK] = d.reshape(len(d), -1).min(axis=1)
    return out
