"""Hole sequencing: the open path through a set of holes, and the problem every sequencer
solves.

The problem (paper 002, section 3.2.1, eqs. 4-5): the drill visits every hole exactly once,
starting from the arm's current tool position and not returning; minimise the total travel
``D = d(start, h_1) + sum_k d(h_k, h_{k+1})`` (Euclidean, mm). Without a start position the
first hole of the list is the start (and is drilled first).

The same open path over any symmetric cost table (e.g. a boom's travel time between holes)
is a ``SequencingProblem.from_costs``; every sequencer takes either.

Internally a sequencer works on *free nodes*: the holes other than a start hole, numbered
``0..n-1``, with distances ``D (n, n)`` between them and ``d0 (n,)`` from the start. An
*order* is a permutation ``(n,)`` of free nodes; a batch of orders is ``(B, n)``. The local
searches use an extended matrix ``E (n+2, n+2)`` where node ``n`` is the start and node
``n+1`` a dummy end at distance 0 from everything, so the open path is the sequence
``[start, order..., end]`` with both ends fixed.

Every sequencer is a frozen dataclass of its parameters (defaults = the paper's) with
``solve(problem, rng, *, progress=None, max_evaluations=None) -> SequenceResult``; it takes a
seeded ``numpy.random.Generator``, keeps a convergence history (best length after each
iteration) and reports progress through a ``planning.budget.Budget``, as the continuous
optimisers in ``planning.optimisers`` do (``iterative``). The exact solver is in ``exact``,
the dense reference moves in ``local``, the compiled search of ``auto`` in ``oropt``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from kinematics.errors import FieldError, loc_from_path

from ..budget import ProgressFn

__all__ = [
    "bad_param",
    "DUPLICATE_TOL",
    "MAX_HOLES",
    "IMPROVE_EPS",
    "check_holes",
    "SequencingProblem",
    "SequenceResult",
    "ProgressFn",
]

#: Two holes closer than this (mm) are the same hole.
DUPLICATE_TOL = 1.0
#: Most holes one sequencing problem takes (a face has a few hundred).
MAX_HOLES = 5000
#: Improvements smaller than this (mm) do not count (round-off).
IMPROVE_EPS = 1e-9


def bad_param(name: str, message: str) -> FieldError:
    """A sequencer parameter out of range: ``FieldError`` at ``params.<name>``."""
    return FieldError(("params", name), f"params.{name}: {message}")


def check_holes(holes, name: str = "holes", *, min_count: int = 2,
                labels: list[str] | None = None) -> np.ndarray:
    """Validate a hole list: ``(N, 3)`` finite numbers (mm), at least ``min_count`` holes,
    no two within ``DUPLICATE_TOL`` of each other. Returns it as float64 ``(N, 3)``.

    Raises ``FieldError`` naming the field and the hole at fault, e.g. ``("holes", 7)``:
    ``"holes[7]: duplicate of holes[2] ..."`` (``labels[k]`` instead of ``holes[k]`` when
    given, e.g. ``"holes.left[3]"``; ``name`` and the labels are field paths).
    """
    def label(k: int) -> str:
        return labels[k] if labels is not None else f"{name}[{k}]"

    def bad(path: str, message: str) -> FieldError:
        return FieldError(loc_from_path(path), f"{path}: {message}")

    try:
        P = np.array(holes, dtype=float)
    except (TypeError, ValueError):
        raise bad(name, "must be a list of [x, y, z] in mm") from None
    if P.ndim == 1 and P.size == 0:
        P = P.reshape(0, 3)
    if P.ndim != 2 or P.shape[1] != 3:
        raise bad(name, f"must have shape (N, 3), got {list(P.shape)}")
    nonfinite = ~np.all(np.isfinite(P), axis=1)
    if nonfinite.any():
        raise bad(label(int(np.argmax(nonfinite))), "has a NaN or infinite coordinate")
    if len(P) < min_count:
        raise bad(name, f"need at least {min_count} holes, got {len(P)}")
    if len(P) > MAX_HOLES:
        raise bad(name, f"at most {MAX_HOLES} holes, got {len(P)}")
    pairs = cKDTree(P).query_pairs(DUPLICATE_TOL, output_type="ndarray") if len(P) else []
    if len(pairs):
        pairs = np.sort(pairs, axis=1)
        i, j = pairs[np.lexsort((pairs[:, 0], pairs[:, 1]))][0]
        raise bad(label(j), f"duplicate of {label(i)} (within {DUPLICATE_TOL:g} mm: "
                  f"{P[j].round(3).tolist()})")
    return P


@dataclass(frozen=True, eq=False)
class SequencingProblem:
    """An open-path sequencing problem on ``holes (N, 3)`` (mm) from ``start (3,)``.

    ``start_hole`` is True when no start was given: ``start = holes[0]`` and hole 0 is drilled
    first. ``free (n,)`` maps free node -> hole index; ``D (n, n)`` and ``d0 (n,)`` are the
    costs between free nodes and from the start: Euclidean distances (mm) between the holes
    (computed on first use), or the tables given to ``from_costs`` (any symmetric cost, e.g.
    boom travel time; ``holes`` and ``start`` are then None).
    """

    holes: np.ndarray | None
    start: np.ndarray | None
    start_hole: bool
    free: np.ndarray
    given_D: np.ndarray | None = None
    given_d0: np.ndarray | None = None

    @classmethod
    def from_holes(cls, holes, start=None) -> SequencingProblem:
        """Validate ``holes (N, 3)`` and the optional ``start (3,)`` (mm). ``FieldError``
        naming ``holes`` or ``start``."""
        P = check_holes(holes)
        if start is None:
            s = P[0].copy()
            free = np.arange(1, len(P))
        else:
            try:
                s = np.array(start, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise FieldError("start", "start: must be [x, y, z] in mm") from None
            if s.shape != (3,) or not np.all(np.isfinite(s)):
                raise FieldError("start", "start: must be 3 finite numbers [x, y, z] in mm")
            free = np.arange(len(P))
        for a in (P, s, free):
            a.setflags(write=False)
        return cls(P, s, start is None, free)

    @classmethod
    def from_costs(cls, costs, start_costs=None, *, name: str = "costs",
                   symmetry_tol: float = 1e-9) -> SequencingProblem:
        """A problem on ``N`` nodes with the symmetric costs ``costs (N, N)`` between them and
        ``start_costs (N,)`` from the start (None: node 0 is the start, visited first).
        ``FieldError`` naming ``name`` if the costs are not square, finite, non-negative and
        symmetric (to ``symmetry_tol`` relative to the largest)."""
        C = np.array(costs, dtype=float)
        if C.ndim != 2 or C.shape[0] != C.shape[1] or len(C) < 2:
            raise FieldError(name, f"{name}: must be a square matrix of at least 2 nodes")
        if not np.all(np.isfinite(C)) or (C < 0).any():
            raise FieldError(name, f"{name}: must be finite and non-negative")
        if np.abs(C - C.T).max() > symmetry_tol * max(1.0, float(C.max())):
            raise FieldError(name, f"{name}: must be symmetric")
        if start_costs is None:
            free = np.arange(1, len(C))
            D, d0 = C[1:, 1:].copy(), C[0, 1:].copy()
        else:
            d0 = np.array(start_costs, dtype=float).reshape(-1)
            if d0.shape != (len(C),) or not np.all(np.isfinite(d0)) or (d0 < 0).any():
                raise FieldError(f"start_{name}", f"start_{name}: must be {len(C)} finite "
                                 "non-negative numbers")
            free, D = np.arange(len(C)), C.copy()
        np.fill_diagonal(D, 0.0)
        for a in (free, D, d0):
            a.setflags(write=False)
        return cls(None, None, start_costs is None, free, D, d0)

    @property
    def euclidean(self) -> bool:
        """Whether the costs are distances between the holes (else given tables)."""
        return self.given_D is None

    @cached_property
    def points(self) -> np.ndarray:
        """The free holes, then the start: ``(n+1, 3)`` mm (Euclidean problems only)."""
        if not self.euclidean:
            raise ValueError("a problem built from costs has no points")
        X = np.vstack([self.holes[self.free], self.start[None]])
        X.setflags(write=False)
        return X

    @cached_property
    def D(self) -> np.ndarray:
        """Costs between free nodes ``(n, n)`` (mm for hole problems)."""
        if self.given_D is not None:
            return self.given_D
        Q = self.points[: self.n]
        D = cdist(Q, Q)
        D.setflags(write=False)
        return D

    @cached_property
    def d0(self) -> np.ndarray:
        """Costs from the start to each free node ``(n,)``."""
        if self.given_d0 is not None:
            return self.given_d0
        d0 = np.linalg.norm(self.points[: self.n] - self.start, axis=1)
        d0.setflags(write=False)
        return d0

    @property
    def size(self) -> int:
        """Number of holes (nodes), the start hole included."""
        return self.n + (1 if self.start_hole else 0)

    @property
    def n(self) -> int:
        """Number of free nodes (holes to order)."""
        return len(self.free)

    @cached_property
    def E(self) -> np.ndarray:
        """Extended distances ``(n+2, n+2)``: node n = start, node n+1 = dummy end (0)."""
        n = self.n
        E = np.zeros((n + 2, n + 2))
        E[:n, :n] = self.D
        E[n, :n] = E[:n, n] = self.d0
        E.setflags(write=False)
        return E

    @cached_property
    def nn_distance(self) -> float:
        """Mean distance from a free node to its nearest other node (start included), mm:
        the natural scale of one move."""
        if self.n == 0:
            return 0.0
        E = self.E[: self.n + 1, : self.n + 1] + np.diag(np.full(self.n + 1, np.inf))
        return float(E[: self.n].min(axis=1).mean())

    def lengths(self, orders) -> np.ndarray:
        """Path lengths (mm; cost units for ``from_costs``) of a batch of free-node orders:
        ``(B, n) -> (B,)``."""
        o = np.asarray(orders)
        if o.shape[1] == 0:
            return np.zeros(len(o))
        if self.euclidean:  # from the points: no (n, n) table needed
            X = self.points
            path = np.concatenate([np.full((len(o), 1), self.n), o], axis=1)
            return np.linalg.norm(np.diff(X[path], axis=1), axis=2).sum(axis=1)
        return self.d0[o[:, 0]] + self.D[o[:, :-1], o[:, 1:]].sum(axis=1)

    def length(self, order) -> float:
        """Path length (mm) of one free-node order ``(n,)``."""
        return float(self.lengths(np.asarray(order)[None])[0])

    def hole_order(self, order) -> np.ndarray:
        """Free-node order ``(n,)`` -> hole indices in drilling order ``(N,)``."""
        o = self.free[np.asarray(order, dtype=int)]
        return np.concatenate([[0], o]) if self.start_hole else o

    def free_order(self, hole_order) -> np.ndarray:
        """Inverse of ``hole_order``: hole indices ``(N,)`` -> free-node order ``(n,)``.
        ``FieldError`` naming ``order`` if it is not a permutation of the holes (with hole 0
        first when the start is hole 0)."""
        h = np.asarray(hole_order, dtype=int).reshape(-1)
        if sorted(h.tolist()) != list(range(self.size)):
            raise FieldError("order", "order: must be a permutation of the hole indices")
        if self.start_hole:
            if h[0] != 0:
                raise FieldError("order", "order: must start with hole 0 (the start)")
            h = h[1:]
        inv = np.empty(self.size, dtype=int)
        inv[self.free] = np.arange(self.n)
        return inv[h]


@dataclass(frozen=True)
class SequenceResult:
    """A drilling order: ``order (N,)`` hole indices, ``length`` of the open path from the
    start (mm), ``history`` = best length after each iteration (mm). A sequencer always
    answers with an order; ``budget_spent`` says it is the best found before the evaluation
    budget ran out rather than at the end of its iterations."""

    order: np.ndarray
    length: float
    history: np.ndarray
    runtime_s: float
    evaluations: int
    iterations: int
    algorithm: str
    message: str = ""
    extra: dict = field(default_factory=dict)
    budget_spent: bool = False
