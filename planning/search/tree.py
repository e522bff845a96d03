"""The search tree every sampling-based planner of ``planning.search`` grows.

Nodes are stored in arrays grown by doubling: ``X (n, dim)`` the configurations, ``parent
(n,)`` (-1 for a root), ``alive (n,)`` (False once dropped with its subtree by ``kill``)
and ``checked (n,)`` (whether the edge to the parent was checked at the final resolution;
a lazy search checks it only when a path through it is found).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Tree"]


class Tree:
    """A tree of configurations (module docstring) with roots ``roots (R, dim)``, all
    checked; ``capacity`` nodes before the first growth."""

    def __init__(self, roots: np.ndarray, capacity: int = 1024) -> None:
        roots = np.atleast_2d(roots)
        cap = max(capacity, 2 * len(roots))
        self.X = np.empty((cap, roots.shape[1]))
        self.parent = np.empty(cap, dtype=np.int64)
        self.alive = np.zeros(cap, dtype=bool)
        self.checked = np.zeros(cap, dtype=bool)
        self.n = len(roots)
        self.X[:self.n] = roots
        self.parent[:self.n] = -1
        self.alive[:self.n] = True
        self.checked[:self.n] = True

    def add(self, x: np.ndarray, parent: int, checked: bool = False) -> int:
        """Append node ``x (dim,)`` below ``parent``; its index."""
        if self.n == len(self.X):
            self.X = np.concatenate([self.X, np.empty_like(self.X)])
            self.parent = np.concatenate([self.parent, np.empty_like(self.parent)])
            self.alive = np.concatenate([self.alive, np.zeros_like(self.alive)])
            self.checked = np.concatenate([self.checked, np.zeros_like(self.checked)])
        self.X[self.n] = x
        self.parent[self.n] = parent
        self.alive[self.n] = True
        self.checked[self.n] = checked
        self.n += 1
        return self.n - 1

    @property
    def nodes(self) -> np.ndarray:
        """The configurations ``(n, dim)`` (a view)."""
        return self.X[:self.n]

    def branch(self, i: int) -> list[int]:
        """Node indices from node ``i`` up to its root."""
        out = []
        while i >= 0:
            out.append(i)
            i = int(self.parent[i])
        return out

    def kill(self, i: int) -> None:
        """Drop node ``i`` and every node below it."""
        dead = np.zeros(self.n, dtype=bool)
        dead[i] = True
        par = self.parent[:self.n]
        # Children always come after their parents: one pass in index order.
        for k in range(i + 1, self.n):
            if par[k] >= 0 and dead[par[k]]:
                dead[k] = True
        self.alive[:self.n] &= ~dead
