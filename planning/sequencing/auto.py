"""The project's own near-optimal sequencer (``algorithm="auto"``).

* Up to ``exact_max`` holes to order: the exact answer by dynamic programming (Held-Karp for
  open paths, ``exact.held_karp``).
* Above: iterated local search (``oropt``, compiled): a nearest-neighbour path from the
  start, a descent with 2-opt, Or-opt and Lin-Kernighan chains over each hole's
  ``neighbours`` nearest holes (``candidates``) with don't-look bits, then kicks (a double
  bridge within ``kick_span`` places along the path) each followed by a descent from the
  kicked holes only, the result kept when it is no longer. A run that goes ``stall`` kicks
  without a shorter path ends, and the next starts from a nearest-neighbour path begun at a
  random hole (at most ``restarts`` runs); the shortest path of all is the answer.

The search ends at the first of: ``kicks`` kicks in all (default ``KICKS_PER_HOLE`` per hole
to order), ``restarts`` runs, the time limit (``time_limit``; default ``default_time_limit``:
0.95 s for 200 holes, 4.75 s for 1,000, 19 s for 2,000, at most a minute) or the evaluation
budget
(one evaluation per kick and per descent from a start). Stopped by kicks, runs or
evaluations it is reproducible for a given seed; cut short by its time limit it says so in
``message`` and ``extra["stopped"]`` (how far it got then depends on the machine). Every
order it answers with is a local optimum of the moves over the candidate lists.

Measured against LKH (``benchmarks/bench_sequencing.py``): see the README's sequencing speed
table. Why not LKH or OR-Tools themselves: a large binary dependency (and LKH's licence is
for research only) for what this search does within a fraction of a per cent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..budget import BudgetExhausted
from .base import ProgressFn, SequenceResult, SequencingProblem, bad_param
from .candidates import DEFAULT_K, nearest_by_costs, nearest_by_points
from .exact import EXACT_MAX, held_karp
from .iterative import Budget, run_sequencing, sequencing_budget
from .oropt import KICK_SPAN, LK_BREADTH, MIN_NODES, Engine, greedy_order

__all__ = [
    "Auto",
    "KICKS_PER_HOLE",
    "STALL_PER_HOLE",
    "default_time_limit",
    "engine_for",
    "improve_order",
]

#: Default kick budget per hole to order (the reproducible stop).
KICKS_PER_HOLE = 100
#: Default stall (kicks in a row without a shorter path that end a run) per hole, at
#: least ``MIN_STALL``.
STALL_PER_HOLE = 10
MIN_STALL = 2_000
#: Default number of runs at most.
RESTARTS = 100
#: Wall time one compiled call of the search aims at, s: progress, cancellation and the time
#: limit are looked at between calls.
CHUNK_S = 0.02


def default_time_limit(n: int) -> float:
    """Seconds ``auto`` may search ``n`` holes by default: ``0.00475 n`` up to 1,000 holes
    (0.95 s for 200, 4.75 s for 1,000), growing as ``n^2`` above (19 s for 2,000), at
    least 0.5 s and at most 60 s: the whole answer, set-up and final descent included,
    within 1 s, 5 s and 20 s."""
    return float(min(60.0, max(0.5, 0.00475 * n * max(1.0, n / 1000.0))))


def lk_breadth(depth: int) -> tuple[int, ...]:
    """Candidates tried at each step of an LK chain of ``depth`` steps (0: no chains)."""
    return tuple(LK_BREADTH[k] if k < len(LK_BREADTH) else 1 for k in range(depth))


def engine_for(problem: SequencingProblem, neighbours: int, seed: int,
               first: int | None = None, order=None, lk_depth: int = len(LK_BREADTH)
               ) -> Engine:
    """The search engine of ``problem`` from the free-node ``order (n,)`` (default: the
    nearest-neighbour path from the start, or from free node ``first``): points and a KD-tree
    for hole problems, the cost table and partial sorts of its rows otherwise."""
    n = problem.n
    if problem.euclidean:
        costs = {"X": problem.points}
        nbr = nearest_by_points(problem.points, neighbours)
    else:
        costs = {"C": problem.E}
        nbr = nearest_by_costs(problem.E[: n + 1, : n + 1], neighbours)
    if order is None:
        order = greedy_order(n, nbr, first=first, **costs)
    return Engine(n, nbr, order, seed=seed, lk=lk_breadth(lk_depth), **costs)


def improve_order(problem: SequencingProblem, order, *, kicks: int, seed: int,
                  stall: int | None = None, span: int = KICK_SPAN,
                  neighbours: int = DEFAULT_K, lk_depth: int = len(LK_BREADTH),
                  deadline: float | None = None,
                  clock: Callable[[], float] = time.perf_counter) -> np.ndarray:
    """``order (n,)`` (free nodes) improved by one run of the iterated local search: a
    descent, then up to ``kicks`` kicks (fewer after ``stall`` kicks without improvement,
    default as ``Auto``'s, or once ``clock()`` passes ``deadline``). Never longer than
    ``order``; problems of three nodes or fewer are solved exactly instead."""
    n = problem.n
    order = np.asarray(order, dtype=np.int64)
    if n + 2 < MIN_NODES or n <= 3:
        best, length = held_karp(problem)
        return best if length < problem.length(order) else order
    eng = engine_for(problem, neighbours, seed, order=order, lk_depth=lk_depth)
    eng.descend()
    stall = max(MIN_STALL, STALL_PER_HOLE * n) if stall is None else stall
    left, chunk = kicks, 256
    while left > 0 and (deadline is None or clock() < deadline):
        ran = eng.kick(min(chunk, left), span=span, stall=stall)
        left -= ran
        if ran < min(chunk, left + ran):
            break
        chunk = min(4 * chunk, 1 << 16)
    eng.polish()
    best = eng.best_order()
    return best if problem.length(best) <= problem.length(order) else order


@dataclass(frozen=True)
class Auto:
    """Exact up to ``exact_max`` holes to order, iterated 2-opt / Or-opt / Lin-Kernighan
    search above (module docstring)."""

    exact_max: int = field(default=12, metadata={
        "ge": 0, "le": 16, "description": "most holes solved exactly"})
    kicks: int | None = field(default=None, metadata={
        "ge": 0, "le": 100_000_000,
        "description": f"kicks in all; default {KICKS_PER_HOLE} per hole"})
    stall: int | None = field(default=None, metadata={
        "ge": 1, "le": 100_000_000,
        "description": f"kicks without a shorter path that end a run; default "
                       f"{STALL_PER_HOLE} per hole, at least {MIN_STALL}"})
    restarts: int = field(default=RESTARTS, metadata={
        "ge": 1, "le": 10_000, "description": "most runs (a run ends when it stalls)"})
    kick_span: int = field(default=KICK_SPAN, metadata={
        "ge": 3, "le": 10_000, "description": "places along the path a kick spans"})
    neighbours: int = field(default=DEFAULT_K, metadata={
        "ge": 2, "le": 50, "description": "candidates per hole"})
    lk_depth: int = field(default=len(LK_BREADTH), metadata={
        "ge": 0, "le": 50, "description": "steps of a Lin-Kernighan chain (0: none)"})
    threshold: float = field(default=0.0, metadata={
        "ge": 0.0, "le": 1.0, "description": "fraction longer than the best accepted"})
    time_limit: float | None = field(default=None, metadata={
        "gt": 0.0, "le": 3600.0,
        "description": "s; default 0.95 s for 200 holes, 4.75 s for 1,000, 19 s for 2,000"})

    def __post_init__(self) -> None:
        if not 0 <= self.exact_max <= EXACT_MAX:
            raise bad_param("exact_max", f"must be in [0, {EXACT_MAX}]")
        if self.kicks is not None and self.kicks < 0:
            raise bad_param("kicks", "must be >= 0")
        if self.stall is not None and self.stall < 1:
            raise bad_param("stall", "must be >= 1")
        if self.kick_span < 3:
            raise bad_param("kick_span", "must be >= 3")
        if self.lk_depth < 0:
            raise bad_param("lk_depth", "must be >= 0")
        if self.neighbours < 2:
            raise bad_param("neighbours", "must be >= 2")
        if not self.threshold >= 0:
            raise bad_param("threshold", "must be >= 0")
        if self.restarts < 1:
            raise bad_param("restarts", "must be >= 1")
        if self.time_limit is not None and not (
                math.isfinite(self.time_limit) and self.time_limit > 0):
            raise bad_param("time_limit", "must be a positive number of seconds")

    # ---- the budgets -------------------------------------------------------------------------
    def kick_budget(self, n: int) -> int:
        """Kicks in all for ``n`` holes to order."""
        return KICKS_PER_HOLE * n if self.kicks is None else self.kicks

    def stall_budget(self, n: int) -> int:
        """Kicks without improvement that end a run."""
        return max(MIN_STALL, STALL_PER_HOLE * n) if self.stall is None else self.stall

    def time_budget(self, n: int) -> float:
        """Seconds the search may take for ``n`` holes to order."""
        return default_time_limit(n) if self.time_limit is None else self.time_limit

    def solve(self, problem: SequencingProblem, rng: np.random.Generator, *,
              progress: ProgressFn | None = None, max_evaluations: int | None = None,
              clock: Callable[[], float] = time.perf_counter) -> SequenceResult:
        """Solve. ``history`` has one entry per descent from a start and one per chunk of
        kicks (about ``CHUNK_S`` s each); ``extra`` says what stopped the search
        (``"stopped"``: ``kicks``, ``stall``, ``time limit`` or ``evaluations``) and how
        many kicks ran. ``clock`` (s) measures the time limit."""
        exact = problem.n <= max(self.exact_max, 3) or problem.n + 2 < MIN_NODES
        tr = sequencing_budget(problem, 1, None, max_evaluations)
        extra: dict = {}
        res = run_sequencing(
            tr, lambda: self._body(problem, rng, tr, exact, progress, clock, extra), "auto")
        if res.budget_spent:
            extra["stopped"] = "evaluations"
        return SequenceResult(**{**res.__dict__, "extra": extra})

    def _body(self, problem: SequencingProblem, rng: np.random.Generator, tr: Budget,
              exact: bool, progress: ProgressFn | None, clock: Callable[[], float],
              extra: dict) -> str:
        if exact:
            order, _ = held_karp(problem)
            tr.evaluate(order[None])
            tr.end_iteration()
            if progress is not None:
                progress(1.0)
            extra.update(stopped="exact", kicks=0)
            return "exact (dynamic programming)"
        n = problem.n
        t0 = clock()
        limit = self.time_budget(n)
        total = self.kick_budget(n)
        stall = self.stall_budget(n)
        done = 0
        runs = 0
        stopped = "runs"
        extra.update(stopped=stopped, kicks=0, runs=0)

        def report() -> None:
            if progress is not None:
                by_kicks = done / total if total else 1.0
                progress(min(1.0, max(by_kicks, (clock() - t0) / limit)))

        timed_out = False
        while runs < self.restarts and not timed_out:
            if runs and done >= total:
                break
            if runs and clock() - t0 >= limit:
                timed_out = True
                break
            first = None if runs == 0 else int(rng.integers(n))
            eng = engine_for(problem, self.neighbours, int(rng.integers(2**63)), first,
                             lk_depth=self.lk_depth)
            eng.descend()
            runs += 1
            extra["runs"] = runs
            self._offer(tr, problem, eng, 1)
            report()
            chunk, last = 256, 0.0
            while done < total:
                if clock() - t0 + last >= limit:  # another chunk like the last would overrun
                    timed_out = True
                    break
                k = min(chunk, total - done)
                if tr.max_evaluations is not None:
                    k = min(k, max(1, tr.max_evaluations - tr.evaluations))
                c0, w0 = time.perf_counter(), clock()
                ran = eng.kick(k, span=self.kick_span, threshold=self.threshold, stall=stall)
                spent = time.perf_counter() - c0
                last = clock() - w0
                done += ran
                extra["kicks"] = done
                self._offer(tr, problem, eng, ran)
                report()
                if ran < k:  # stalled: the next run
                    break
                # aim each call at CHUNK_S s (how many kicks that is varies; the course of
                # the search does not: the generator and tour carry over between calls)
                chunk = int(min(max(64, 2 * chunk), max(64, chunk * CHUNK_S / max(spent, 1e-6))))
            eng.polish()  # a strict local optimum, whatever the don't-look bits missed
            self._offer(tr, problem, eng, 0)
        if done >= total:
            stopped = "kicks"
        elif timed_out:
            stopped = "time limit"
        extra["stopped"] = stopped
        extra["time_limit_s"] = limit
        msg = f"{done} kicks in {runs} run{'s' if runs > 1 else ''}"
        return msg + (", stopped by the time limit" if stopped == "time limit" else "")

    @staticmethod
    def _offer(tr: Budget, problem: SequencingProblem, eng: Engine, evaluations: int) -> None:
        """Charge ``evaluations`` to the budget (each kick's descent scores one path) and
        offer the engine's best order, scored exactly; ``BudgetExhausted`` once spent."""
        order = eng.best_order()
        tr.offer(order, float(problem.lengths(order[None])[0]))
        tr.evaluations += evaluations
        tr.end_iteration()
        if tr.max_evaluations is not None and tr.evaluations >= tr.max_evaluations:
            raise BudgetExhausted()
