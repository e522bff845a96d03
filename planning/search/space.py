"""What a sampling-based search needs of the space it searches: the ``SearchSpace`` protocol,
and ``BoxSpace``, a Euclidean box with a segment test (the space of tool points, and the
simplest space a new planner can be tried on).

A space answers five questions, each a callback the searches of ``planning.search`` call in a
fixed order (so that a seeded search draws the same numbers every run):

* ``sample(rng) -> (dim,)``: a random configuration (the space decides how many numbers it
  draws: the drilling arms draw ``rng.random(3)``, joint space ``lo + (hi - lo) *
  rng.random(dof)``);
* ``nearest(tree, x) -> int``: the index of the live tree node nearest ``x`` in the
  space's metric;
* ``steer(a, b) -> (new, reached)``: the configuration one step from ``a`` towards ``b``
  (``b`` itself when within a step: ``reached``), or ``(None, True)`` when ``b`` coincides
  with ``a`` (the node is its own extension, no edge is added);
* ``segment_free(a, b) -> bool``: whether the straight segment is free at the final
  resolution (the guarantee of every path a search returns);
* ``coarse_free(a, b) -> bool``: the cheaper test a lazy search adds edges with (checked
  again by ``segment_free`` once a path through them is found); spaces without one use
  ``segment_free``.

``distances(X, x) -> (n,)``, ``distance(a, b)`` and ``segments_free(A, B) -> (k,)`` (the
batch form of the segment test) are what RRT* uses (``planning.search.rrt_star``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from .tree import Tree

__all__ = ["SearchSpace", "BoxSpace"]


class SearchSpace(Protocol):
    """The callbacks of a space (module docstring)."""

    def sample(self, rng: np.random.Generator) -> np.ndarray: ...

    def nearest(self, tree: Tree, x: np.ndarray) -> int: ...

    def steer(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray | None, bool]: ...

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool: ...


class BoxSpace:
    """The box ``[lower, upper]`` (``(dim,)`` each) with the Euclidean metric, steps of at
    most ``step`` and a batch segment test ``segments_free(A (k, dim), B (k, dim)) -> (k,)``
    bool (None: the whole box is free).

    ``sample`` draws ``rng.uniform(lower, upper)`` (``dim`` numbers)."""

    def __init__(self, lower, upper, step: float,
                 segments_free: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                 ) -> None:
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        if self.lower.shape != self.upper.shape or self.lower.ndim != 1:
            raise ValueError("lower and upper must be vectors of the same length")
        if not step > 0:
            raise ValueError("step must be positive")
        self.step = float(step)
        self._free = segments_free

    @property
    def dim(self) -> int:
        return len(self.lower)

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(self.lower, self.upper)

    def distances(self, X: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Distances ``(n,)`` from the rows of ``X (n, dim)`` to ``x (dim,)``."""
        return np.linalg.norm(X - x, axis=1)

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """The distance between two configurations."""
        return float(np.linalg.norm(a - b))

    def nearest(self, tree: Tree, x: np.ndarray) -> int:
        d = self.distances(tree.nodes, x)
        d[~tree.alive[:tree.n]] = np.inf
        return int(np.argmin(d))

    def steer(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray | None, bool]:
        d = float(np.linalg.norm(b - a))
        if d == 0.0:
            return None, True
        if d <= self.step:
            return b, True
        return a + (b - a) * (self.step / d), False

    def segments_free(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        if self._free is None:
            return np.ones(len(A), dtype=bool)
        return np.asarray(self._free(A, B), dtype=bool)

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        return bool(self.segments_free(a[None], b[None])[0])
