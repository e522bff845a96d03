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

The runs can also be computed apart (a job's steps, on several machines): ``search_run``
makes run ``i`` on its own, with the start hole and generator ``solve`` would draw for it and
the most kicks it could be given (``run_cap``); ``combine`` makes ``solve``'s answer of such
runs, running again the one the kick budget cuts short (and any it lacks). Each run then has
the time limit of its own.

Measured against LKH (``benchmarks/bench_sequencing.py``): see the sequencing speed table in
docs/drilling.md. Why not LKH or OR-Tools themselves: a large binary dependency (and LKH's
licence is for research only) for what this search does within a fraction of a per cent.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..budget import BudgetExhausted
from .base import IMPROVE_EPS, ProgressFn, SequenceResult, SequencingProblem, bad_param
from .candidates import DEFAULT_K, nearest_by_costs, nearest_by_points
from .exact import EXACT_MAX, held_karp
from .iterative import Budget, run_sequencing, sequencing_budget
from .oropt import KICK_SPAN, LK_BREADTH, MIN_NODES, Engine, greedy_order

__all__ = [
    "Auto",
    "SearchRun",
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
#: Kicks of the first compiled call of a run's search, and of every later one (about 10 and
#: 20 ms at some 40 us a kick): progress, cancellation and the time limit are looked at
#: between calls. Fixed, so a run's history does not depend on the machine's speed.
FIRST_CHUNK, CHUNK_KICKS = 256, 512


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
class SearchRun:
    """One run of ``Auto``'s search on its own (``Auto.search_run``): its ``index``, the
    kicks it could run (``cap``) and ran, what stopped it (``stall``, ``cap``, ``time
    limit``), how many orders it offered (one after its descent, one per compiled call, one
    after its polish) and ``records``: ``(offer, length mm, free-node order (n,) or None)``
    of each offer shorter than every earlier one of the run (the only ones that can become
    the search's best; the order kept only where it can be the answer: within
    ``IMPROVE_EPS`` of the run's shortest), and the seconds it took."""

    index: int
    cap: int
    kicks: int
    stop: str
    offers: int
    records: tuple[tuple[int, float, np.ndarray | None], ...]
    seconds: float

    def as_with(self, left: int) -> bool:
        """Whether the run is the one the search makes when ``left`` kicks are left for it:
        the same cap, or a stop (stall, time limit) before it had run ``left`` kicks."""
        return self.cap == left or (self.stop != "cap" and self.kicks < left)


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
        """Solve. ``history`` has one entry per descent from a start, per compiled call of
        kicks (``FIRST_CHUNK``, then ``CHUNK_KICKS`` kicks) and per polish; ``extra`` says
        what stopped the search
        (``"stopped"``: ``kicks``, ``stall``, ``time limit`` or ``evaluations``) and how
        many kicks ran. ``clock`` (s) measures the time limit."""
        exact = self.exact_for(problem)
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
        extra.update(stopped="runs", kicks=0, runs=0)
        starts = self._starts(n, rng)
        room = None if tr.max_evaluations is None else \
            (lambda: max(1, tr.max_evaluations - tr.evaluations))
        timed_out = False
        while runs < self.restarts:
            if runs and done >= total:
                break
            if runs and clock() - t0 >= limit:
                timed_out = True
                break
            first, seed = next(starts)
            runs += 1
            extra["runs"] = runs

            def offer(eng: Engine, evaluations: int, kicks: int, before: int = done) -> None:
                extra["kicks"] = before + kicks
                self._offer(tr, problem, eng, evaluations)
                if progress is not None:
                    by_kicks = (before + kicks) / total if total else 1.0
                    progress(min(1.0, max(by_kicks, (clock() - t0) / limit)))

            kicks, stop = self._search(problem, first, seed, total - done, stall, clock, t0,
                                       limit, offer, room)
            done += kicks
            if stop == "time limit":
                timed_out = True
                break
        stopped = "kicks" if done >= total else "time limit" if timed_out else "runs"
        extra.update(stopped=stopped, kicks=done, time_limit_s=limit)
        return self._message(done, runs, stopped)

    @staticmethod
    def _message(kicks: int, runs: int, stopped: str) -> str:
        msg = f"{kicks} kicks in {runs} run{'s' if runs > 1 else ''}"
        return msg + (", stopped by the time limit" if stopped == "time limit" else "")

    @staticmethod
    def _starts(n: int, rng: np.random.Generator):
        """``(first hole or None, engine seed)`` of each run in turn, drawn from ``rng``: run
        0 from the nearest-neighbour path of the start, later ones from a random hole."""
        yield None, int(rng.integers(2**63))
        while True:
            first = int(rng.integers(n))
            yield first, int(rng.integers(2**63))

    def _search(self, problem: SequencingProblem, first: int | None, seed: int, cap: int,
                stall: int, clock: Callable[[], float], t0: float, limit: float,
                offer: Callable[[Engine, int, int], None],
                room: Callable[[], int] | None = None) -> tuple[int, str]:
        """One run: a descent from the nearest-neighbour path begun at ``first``, then up to
        ``cap`` kicks (fewer after ``stall`` without a shorter path, or once another call
        like the last would pass ``t0 + limit`` on ``clock``), then a polish.
        ``offer(engine, evaluations, kicks so far)`` after the descent, each call and the
        polish; ``room()`` caps a call's kicks. Answers the kicks run and what stopped the
        run: ``stall``, ``cap`` or ``time limit``."""
        eng = engine_for(problem, self.neighbours, seed, first, lk_depth=self.lk_depth)
        eng.descend()
        offer(eng, 1, 0)
        done, chunk, last, stop = 0, FIRST_CHUNK, 0.0, "cap"
        while done < cap:
            if clock() - t0 + last >= limit:  # another call like the last would overrun
                stop = "time limit"
                break
            k = min(chunk, cap - done)
            if room is not None:
                k = min(k, room())
            w0 = clock()
            ran = eng.kick(k, span=self.kick_span, threshold=self.threshold, stall=stall)
            last = clock() - w0
            done += ran
            offer(eng, ran, done)
            if ran < k:  # stalled
                stop = "stall"
                break
            chunk = CHUNK_KICKS
        eng.polish()  # a strict local optimum, whatever the don't-look bits missed
        offer(eng, 0, done)
        return done, stop

    # ---- the runs one at a time (a job's steps) ----------------------------------------------
    def exact_for(self, problem: SequencingProblem) -> bool:
        """Whether ``problem`` is solved exactly (no runs)."""
        return problem.n <= max(self.exact_max, 3) or problem.n + 2 < MIN_NODES

    def max_runs(self, n: int) -> int:
        """Most runs the search of ``n`` holes makes (by its budgets; the time limit may end
        it sooner): every run but the last ends by stalling, after ``stall`` kicks at least,
        and none starts once ``kicks`` have run."""
        total, stall = self.kick_budget(n), self.stall_budget(n)
        if total <= 0:
            return 1
        return max(1, min(self.restarts, -(-total // stall)))

    def run_cap(self, n: int, index: int, earlier: Sequence[SearchRun] = ()) -> int | None:
        """Most kicks run ``index`` may be given, knowing runs ``0..len(earlier)-1`` (in
        order): the kicks left after them less ``stall`` per run between; None when the
        search ends before run ``index`` (budgets spent, a run cut short, a time limit)."""
        total, stall = self.kick_budget(n), self.stall_budget(n)
        if index == 0:
            return total
        if index >= self.restarts:
            return None
        done = 0
        for used, run in enumerate(earlier[:index]):
            if used and done >= total:
                return None
            left = total - done
            if run.as_with(left):
                if run.stop == "time limit":
                    return None
                done += run.kicks
            elif run.kicks >= left:  # the budget cuts it short: the search ends with it
                return None
            else:  # it used up a cap below what it had: how long it runs is not known
                return max(0, total - done - (index - used) * stall) or None
        if done >= total and earlier:
            return None
        return max(0, total - done - (index - min(len(earlier), index)) * stall) or None

    def search_run(self, problem: SequencingProblem, seed: int, index: int,
                   cap: int | None = None, *, clock: Callable[[], float] = time.perf_counter,
                   progress: ProgressFn | None = None) -> SearchRun:
        """Run ``index`` of the search ``solve`` makes with ``default_rng(seed)``, on its
        own: the same start hole and generator, up to ``cap`` kicks (default
        ``run_cap(n, index)``), with a time limit of its own (``time_budget``).
        ``combine`` makes ``solve``'s answer of such runs."""
        c0 = time.perf_counter()
        n = problem.n
        starts = self._starts(n, np.random.default_rng(seed))
        for _ in range(index):
            next(starts)
        first, engine_seed = next(starts)
        if cap is None:
            cap = self.run_cap(n, index)
            if cap is None:
                raise ValueError(f"the search of {n} holes makes no run {index}")
        limit = self.time_budget(n)
        t0 = clock()
        records: list[tuple[int, float, np.ndarray | None]] = []
        offers = 0

        def offer(eng: Engine, evaluations: int, kicks: int) -> None:
            nonlocal offers
            order = eng.best_order()
            length = float(problem.lengths(order[None])[0])
            if not records or length < records[-1][1]:
                records.append((offers, length, np.array(order, dtype=np.int64)))
            offers += 1
            if progress is not None:
                by_kicks = kicks / cap if cap else 1.0
                progress(min(1.0, max(by_kicks, (clock() - t0) / limit)))

        kicks, stop = self._search(problem, first, engine_seed, cap, self.stall_budget(n),
                                   clock, t0, limit, offer)
        # The run's last record the search can keep is within IMPROVE_EPS of its shortest
        # (a later, shorter one replaces it unless it is that close): only those orders
        # can be the answer.
        keep = records[-1][1] + IMPROVE_EPS
        kept = tuple((i, length, order if length <= keep else None)
                     for i, length, order in records)
        return SearchRun(index=index, cap=cap, kicks=kicks, stop=stop, offers=offers,
                         records=kept, seconds=time.perf_counter() - c0)

    def combine(self, problem: SequencingProblem, runs: Sequence[SearchRun | None], seed: int,
                *,
                clock: Callable[[], float] = time.perf_counter,
                progress: ProgressFn | None = None) -> SequenceResult:
        """``solve``'s answer (order, length, history, evaluations, message) made of runs
        computed on their own (``search_run``; ``runs[i]`` is run ``i``, or None if it was
        not computed): a run is used as it is when ``solve`` would have run it alike (the
        same kick cap, or a stop before the kicks ``solve`` had left for it), else it is run
        (again) with those kicks (``seed``: that of the runs). Stopped by kicks, runs or
        stalls, the answer is ``solve``'s; each run has its own time limit, where
        ``solve``'s is shared."""
        n = problem.n
        total = self.kick_budget(n)
        best, best_order = math.inf, None
        history: list[float] = []
        done = used = evaluations = 0
        seconds = sum(r.seconds for r in runs if r is not None)
        timed_out = False
        while used < self.restarts:
            if used and done >= total:
                break
            left = total - done
            run = runs[used] if used < len(runs) else None
            if run is None or run.index != used or not run.as_with(left):
                run = self.search_run(problem, seed, used, left, clock=clock)
                seconds += run.seconds
            records = {i: (length, order) for i, length, order in run.records}
            for i in range(run.offers):
                if i in records and records[i][0] < best - IMPROVE_EPS:
                    best, best_order = records[i]
                history.append(best)
            evaluations += 1 + run.kicks
            done += run.kicks
            used += 1
            if progress is not None:
                progress(min(1.0, done / total) if total else 1.0)
            if run.stop == "time limit":
                timed_out = True
                break
        stopped = "kicks" if done >= total else "time limit" if timed_out else "runs"
        return SequenceResult(
            order=problem.hole_order(best_order), length=float(best),
            history=np.array(history), runtime_s=seconds, evaluations=evaluations,
            iterations=len(history), algorithm="auto",
            message=self._message(done, used, stopped),
            extra={"stopped": stopped, "kicks": done, "runs": used,
                   "time_limit_s": self.time_budget(n)})

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
