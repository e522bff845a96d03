"""Ant colony algorithm on a layered grid: paper 000's "basic ACA" baseline for 3D paths.

Paper 000 (section 4.3) gives 100 ants, pheromone weight alpha 10, heuristic weight beta 1,
evaporation 0.1, deposit constant Q 1, 100 iterations and "9 sliced structures", and no more.
We read it as the classic layered-grid ACO for 3D paths: the space between start and goal is
cut by ``n_slices`` planes perpendicular to the start-goal line, at equal spacing; each plane
carries a ``grid x grid`` lattice of nodes covering the scene's bounds; an ant walks from the
start through one node of each plane, in order, to the goal. From a node it may step to the
nodes of the next plane within ``window`` cells sideways (any node of the first plane from
the start), choosing among those whose connecting segment is clear (exact check) with
probability proportional to ``tau^alpha eta^beta``, ``eta = 1 / (|step| + |node - goal|)``.
An ant with no clear move, or whose last node does not see the goal, dies. After each
iteration the pheromone on every node evaporates, ``tau <- (1 - rho) tau``, and each ant that
arrived deposits ``Q / L`` on its nodes. Grid size and window are ours (the paper prints
none).

This needs the scene, not just a box, so ``plan_layers`` is the entry point
``planning.paths.plan_path`` uses for paths: it hands over the path encoding
(``planning.paths.PathEncoding``: scene, start, goal, penalised cost), so the colony never
imports the paths package that sits above it. ``minimize`` is the same colony on a generic
box problem: each coordinate is a "slice" of ``grid`` levels and there is no heuristic.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import Budget, OptimResult, Problem, ProgressFn, run_with_budget

__all__ = ["AntColony"]


def _roulette(rng: np.random.Generator, logw: np.ndarray) -> np.ndarray:
    """One index per row of log-weights ``(A, K)`` (``-inf`` = forbidden) -> ``(A,)``;
    -1 where a row has no allowed entry."""
    m = np.max(logw, axis=1, keepdims=True)
    ok = np.isfinite(m[:, 0])
    w = np.exp(logw - np.where(np.isfinite(m), m, 0.0))
    cum = np.cumsum(w, axis=1)
    r = rng.random(len(w))[:, None] * cum[:, -1:]
    idx = np.minimum(np.sum(cum < r, axis=1), w.shape[1] - 1)
    return np.where(ok, idx, -1)


@dataclass(frozen=True)
class AntColony:
    """Layered-grid ant colony; defaults = paper 000 plus our grid and window."""

    n_ants: int = field(default=100, metadata={"ge": 1, "le": 5000})
    alpha: float = field(default=10.0, metadata={"ge": 0.0, "le": 100.0})
    beta: float = field(default=1.0, metadata={"ge": 0.0, "le": 100.0})
    evaporation: float = field(default=0.1, metadata={"gt": 0.0, "le": 1.0})
    q: float = field(default=1.0, metadata={"ge": 0.0, "le": 1e9})
    iterations: int = field(default=100, metadata={"ge": 1, "le": 10_000})
    n_slices: int = field(default=9, metadata={"ge": 1, "le": 100})
    grid: int = field(default=21, metadata={"ge": 2, "le": 101})
    window: int = field(default=3, metadata={"ge": 1, "le": 20})

    name = "aca"

    def __post_init__(self) -> None:
        for name in ("n_ants", "iterations", "n_slices"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
        if self.grid < 2:
            raise ValueError("grid must be at least 2")
        if self.window < 1:
            raise ValueError("window must be at least 1")
        if not 0 < self.evaporation <= 1:
            raise ValueError("evaporation must be in (0, 1]")
        for name in ("alpha", "beta", "q"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be non-negative")

    # ---- generic box problems -------------------------------------------------------------
    def minimize(self, problem: Problem, rng: np.random.Generator, *,
                 max_evaluations: int | None = None,
                 progress: ProgressFn | None = None) -> OptimResult:
        """Minimise a box problem: coordinate d takes one of ``grid`` levels."""
        return run_with_budget(problem, lambda ev: self._run_box(ev, rng),
                               max_evaluations=max_evaluations, progress=progress)

    def _run_box(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        D, G = pb.dim, self.grid
        levels = np.linspace(pb.lower, pb.upper, G).T  # (D, G)
        tau = np.ones((D, G))
        for _ in range(self.iterations):
            pick = np.stack([_roulette(rng, np.broadcast_to(self.alpha * np.log(tau[d]),
                                                            (self.n_ants, G)))
                             for d in range(D)], axis=1)  # (A, D)
            X = levels[np.arange(D), pick]
            F = ev.evaluate(X)
            tau *= 1.0 - self.evaporation
            good = np.isfinite(F) & (F > 0)
            dep = np.where(good, self.q / np.where(good, F, 1.0), 0.0)
            for d in range(D):
                np.add.at(tau[d], pick[:, d], dep)
            tau = np.maximum(tau, 1e-300)
            ev.end_iteration()
        return f"{self.iterations} iterations"

    # ---- 3D paths through slices ----------------------------------------------------------
    def layers(self, scene, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Node positions ``(n_slices, grid * grid, 3)`` of the slice lattices (mm)."""
        axis = goal - start
        length = float(np.linalg.norm(axis))
        e = axis / length
        helper = np.array([1.0, 0, 0]) if abs(e[0]) < 0.9 else np.array([0, 1.0, 0])
        u = np.cross(e, helper)
        u /= np.linalg.norm(u)
        v = np.cross(e, u)
        corners = np.array([[x, y, z] for x in (scene.lower[0], scene.upper[0])
                            for y in (scene.lower[1], scene.upper[1])
                            for z in (scene.lower[2], scene.upper[2])])
        wu = float(np.max(np.abs((corners - start) @ u)))
        wv = float(np.max(np.abs((corners - start) @ v)))
        a = np.linspace(-wu, wu, self.grid)
        b = np.linspace(-wv, wv, self.grid)
        A, B = np.meshgrid(a, b, indexing="ij")
        offsets = A.reshape(-1, 1) * u + B.reshape(-1, 1) * v  # (G*G, 3)
        s = np.arange(1, self.n_slices + 1) / (self.n_slices + 1)
        return start + s[:, None, None] * axis + offsets[None]

    def plan_layers(self, enc, rng: np.random.Generator, *, margin: float | None = None,
                    max_evaluations: int | None = None,
                    progress: ProgressFn | None = None) -> OptimResult:
        """Best ant path from ``enc.start`` to ``enc.goal`` (mm) through the slices of
        ``enc.scene``.

        ``enc``: the path encoding (``planning.paths.PathEncoding`` with ``k = n_slices``
        waypoints): its ``scene``, ``start``, ``goal``, ``planning_margin``, ``decode`` and
        ``problem`` (the penalised length the ants are scored by). Returns an
        ``OptimResult`` whose ``x`` is the slice nodes ``(3 n_slices,)`` and whose
        ``extra["path"]`` is the full polyline ``(n_slices + 2, 3)`` (None if no ant ever
        arrived). ``margin`` defaults to the encoding's planning margin (the scene's safety
        margin plus the encoding's slack).
        """
        if enc.k != self.n_slices:
            raise ValueError(f"the encoding has {enc.k} waypoints, the colony "
                             f"{self.n_slices} slices")
        scene = enc.scene
        start, goal = np.asarray(enc.start, float), np.asarray(enc.goal, float)
        margin = enc.planning_margin if margin is None else margin
        nodes = self.layers(scene, start, goal)
        L, M, G, w = self.n_slices, self.grid ** 2, self.grid, self.window
        free = scene.in_bounds(nodes.reshape(-1, 3)).reshape(L, M)
        if scene.obstacles:
            free &= (scene.point_clearance(nodes.reshape(-1, 3)).min(axis=1)
                     >= margin).reshape(L, M)
        # Sideways moves allowed between planes: offsets within the window.
        di, dj = np.meshgrid(np.arange(-w, w + 1), np.arange(-w, w + 1), indexing="ij")
        di, dj = di.ravel(), dj.ravel()
        gi, gj = np.divmod(np.arange(M), G)
        ni, nj = gi[:, None] + di, gj[:, None] + dj
        inside = (ni >= 0) & (ni < G) & (nj >= 0) & (nj < G)
        nbr = np.where(inside, ni * G + nj, 0)  # (M, K)

        def clear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            if not scene.obstacles:
                return np.ones(a.shape[:-1], dtype=bool)
            c = scene.min_segment_clearance(a.reshape(-1, 3), b.reshape(-1, 3))
            return (c >= margin).reshape(a.shape[:-1])

        first_ok = free[0] & clear(np.broadcast_to(start, (M, 3)), nodes[0])
        last_ok = free[-1] & clear(nodes[-1], np.broadcast_to(goal, (M, 3)))
        step_ok = np.empty((L - 1, M, nbr.shape[1]), dtype=bool)
        for k in range(L - 1):
            ok = inside & free[k][:, None] & free[k + 1][nbr]
            ok[ok] = clear(np.broadcast_to(nodes[k][:, None], nbr.shape + (3,))[ok],
                           nodes[k + 1][nbr][ok])
            step_ok[k] = ok
        d_goal = np.linalg.norm(nodes - goal, axis=2)  # (L, M)
        log_eta0 = -np.log(np.linalg.norm(nodes[0] - start, axis=1) + d_goal[0])
        log_eta = [-np.log(np.linalg.norm(nodes[k + 1][nbr] - nodes[k][:, None], axis=2)
                           + d_goal[k + 1][nbr]) for k in range(L - 1)]
        best: dict = {"path": None}

        def body(ev: Budget) -> str:
            tau = np.ones((L, M))
            A = self.n_ants
            for _ in range(self.iterations):
                pick = np.empty((A, L), dtype=int)
                alive = np.ones(A, dtype=bool)
                logw = np.where(first_ok, self.alpha * np.log(tau[0]) + self.beta * log_eta0,
                                -np.inf)
                pick[:, 0] = _roulette(rng, np.broadcast_to(logw, (A, M)))
                alive &= pick[:, 0] >= 0
                for k in range(L - 1):
                    cur = np.where(alive, pick[:, k], 0)
                    cand = nbr[cur]  # (A, K)
                    lw = self.alpha * np.log(tau[k + 1][cand]) + self.beta * log_eta[k][cur]
                    lw = np.where(step_ok[k][cur] & alive[:, None], lw, -np.inf)
                    j = _roulette(rng, lw)
                    alive &= j >= 0
                    pick[:, k + 1] = cand[np.arange(A), np.maximum(j, 0)]
                alive &= last_ok[pick[:, -1]]
                idx = np.nonzero(alive)[0]
                tau *= 1.0 - self.evaporation
                if len(idx):
                    X = nodes[np.arange(L), pick[idx]].reshape(len(idx), -1)
                    F = ev.evaluate(X)
                    for a, f in zip(idx, F):
                        tau[np.arange(L), pick[a]] += self.q / f
                    if ev.best is not None:
                        best["path"] = enc.decode(ev.best)[0]
                tau = np.maximum(tau, 1e-300)
                ev.end_iteration()
            return f"{self.iterations} iterations"

        problem = enc.problem()
        try:
            res = run_with_budget(problem, body, max_evaluations=max_evaluations,
                                  progress=progress)
        except ValueError:  # no ant ever arrived
            return OptimResult(x=np.empty(0), fun=np.inf, evaluations=0,
                               iterations=self.iterations, history=np.full(self.iterations,
                                                                           np.inf),
                               runtime_s=0.0, message="no ant reached the goal",
                               extra={"path": None,
                                      "message": "aca: no ant found a clear way through the "
                                                 "slices (try a finer grid or wider window)"})
        res.extra["path"] = enc.decode(res.x)[0]
        return res
