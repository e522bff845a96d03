"""The project's own near-optimal sequencer (``algorithm="auto"``).

* Up to ``exact_max`` holes to order: the exact answer by dynamic programming (Held-Karp for
  open paths, ``base.held_karp``).
* Above: iterated local search, ``restarts`` runs sharing ``kicks`` kicks. A run starts from
  a nearest-neighbour path (from the start, then from random first holes), descends with
  2-opt and Or-opt (segments of 1-3 holes moved, either way round; at each step the best move
  of either kind over all candidates, vectorised as slices of the distance matrix reordered
  along the path; above 120 holes only moves at holes a kick touched, don't-look bits),
  then repeats: kick the current path with a double bridge (``A B C D -> A C B D``, segments
  at most ``kick_segment`` holes), descend again, keep the result if it is no longer (or
  within ``threshold`` of the best, record-to-record travel; 0 by default). A run ends after
  its share of kicks or ``stall`` kicks in a row without improvement. Restarts matter on
  faces of rings, whose best paths differ from a greedy one by 6-edge rearrangements a
  single run rarely finds. Deterministic for a given seed (no wall-clock limits).

Why not OR-Tools' routing solver: it would add a large binary dependency for problems of a
few hundred holes at most, and this search already matches the exact optimum on every small
face we tried and every other sequencer's best over 30 seeds on 40-200 holes
(``benchmarks/bench_sequencing.py``), in well under a second for 52 holes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import ProgressFn, SequenceResult, SequencingProblem, bad_param
from .exact import EXACT_MAX, held_karp
from .iterative import Budget, run_sequencing, sequencing_budget
from .local import double_bridge, local_search, nearest_neighbour

__all__ = ["Auto"]


@dataclass(frozen=True)
class Auto:
    """Exact up to ``exact_max`` holes to order, iterated 2-opt/Or-opt search above."""

    exact_max: int = field(default=12, metadata={
        "ge": 0, "le": 16, "description": "most holes solved exactly"})
    kicks: int = field(default=1200, metadata={"ge": 0, "le": 100_000})
    stall: int = field(default=100, metadata={"ge": 0, "le": 100_000})
    kick_segment: int = field(default=15, metadata={"ge": 0, "le": 1000})
    threshold: float = field(default=0.0, metadata={
        "ge": 0.0, "le": 1.0, "description": "fraction longer than the best accepted"})
    restarts: int = field(default=12, metadata={"ge": 1, "le": 200})

    def __post_init__(self) -> None:
        if not 0 <= self.exact_max <= EXACT_MAX:
            raise bad_param("exact_max", f"must be in [0, {EXACT_MAX}]")
        for name in ("kicks", "stall", "kick_segment", "threshold"):
            if getattr(self, name) < 0:
                raise bad_param(name, "must be >= 0")
        if self.restarts < 1:
            raise bad_param("restarts", "must be >= 1")

    def solve(self, problem: SequencingProblem, rng: np.random.Generator, *,
              progress: ProgressFn | None = None,
              max_evaluations: int | None = None) -> SequenceResult:
        """Solve; ``history`` has one entry after each run's first descent and one per
        kick."""
        exact = problem.n <= max(self.exact_max, 3)
        tr = sequencing_budget(problem, 1 if exact else self.kicks + self.restarts, progress,
                               max_evaluations)
        return run_sequencing(tr, lambda: self._body(problem, rng, tr, exact), "auto")

    def _body(self, problem: SequencingProblem, rng: np.random.Generator, tr: Budget,
              exact: bool) -> str:
        if exact:
            order, _ = held_karp(problem)
            tr.evaluate(order[None])
            tr.end_iteration()
            return "exact (dynamic programming)"
        best_len = np.inf
        per_run = self.kicks // self.restarts
        total = 0
        for run in range(self.restarts):
            if run == 0:
                start = nearest_neighbour(problem)
            else:  # another greedy path: nearest neighbour from a random first hole
                start = nearest_neighbour(problem, first=int(rng.integers(problem.n)))
            cur = local_search(problem, start)
            cur_len = float(tr.evaluate(cur[None])[0])
            best_len = min(best_len, cur_len)
            tr.end_iteration()
            quiet = 0
            for _ in range(per_run):
                kicked, touched = double_bridge(cur, rng, self.kick_segment)
                cand = local_search(problem, kicked, active=touched)
                cand_len = float(tr.evaluate(cand[None])[0])
                total += 1
                if cand_len < cur_len - 1e-9:
                    quiet = 0
                else:
                    quiet += 1
                best_len = min(best_len, cand_len)
                # record-to-record travel: take the kick unless it is more than
                # ``threshold`` (a fraction) longer than the best path so far
                if cand_len <= max(cur_len, best_len * (1.0 + self.threshold)) + 1e-9:
                    cur, cur_len = cand, cand_len
                tr.end_iteration()
                if quiet >= self.stall:
                    break
        return f"{total} kicks in {self.restarts} runs"
