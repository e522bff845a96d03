"""A job as a small graph of steps, so one big job can run on many workers at once.

A kind whose work divides (``JobKind.graph``) returns a list of ``Step``\\ s: each step is a
module-level function called as ``fn(params, *args, progress)``; an argument may be a
``Ref(i)`` (or a list or tuple of them), the value step ``i`` returned (``i`` less than the
step's own index). The last step's value is the job's result. Parts are sized by the job's
params only (never by the number of workers) and every random draw is seeded by the params and
the part's index, so a job gives the same result run inline (``run_inline``), on the local
backend's processes or on any Dask cluster.

Progress: step ``i`` reporting ``f`` counts as ``f * weight`` of the job's summed weights.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["Ref", "Step", "resolve", "refs_of", "run_inline", "whole", "Tracker", "throttled"]

#: Longest progress message a step sends.
MAX_MESSAGE = 200


@dataclass(frozen=True)
class Ref:
    """The value returned by step ``index`` of the same graph."""

    index: int


@dataclass(frozen=True)
class Step:
    """One task of a job: ``fn(params, *args, progress)`` (module-level, so a worker process
    can import it; its value must pickle)."""

    fn: Callable[..., Any]
    args: tuple = ()
    #: Share of the job's progress (any positive number; relative to the other steps).
    weight: float = 1.0
    #: What progress messages say while the step runs ("chunk 3 of 20").
    label: str = ""

    def __post_init__(self) -> None:
        if not self.weight > 0:
            raise ValueError(f"step weight must be positive, got {self.weight}")


def _map_refs(value: Any, fn: Callable[[Ref], Any]) -> Any:
    if isinstance(value, Ref):
        return fn(value)
    if isinstance(value, list | tuple) and any(isinstance(v, Ref) for v in value):
        return type(value)(fn(v) if isinstance(v, Ref) else v for v in value)
    return value


def refs_of(step: Step) -> set[int]:
    """The indices of the steps ``step`` depends on."""
    found: set[int] = set()

    def note(ref: Ref) -> None:
        found.add(ref.index)

    for arg in step.args:
        _map_refs(arg, note)
    return found


def resolve(args: tuple, values: Callable[[int], Any] | Sequence[Any]) -> tuple:
    """``args`` with every ``Ref(i)`` replaced by ``values[i]`` (or ``values(i)``)."""
    get = values if callable(values) else values.__getitem__
    return tuple(_map_refs(a, lambda r: get(r.index)) for a in args)


def check(steps: Sequence[Step]) -> None:
    """ValueError unless ``steps`` is a non-empty graph whose refs point backwards."""
    if not steps:
        raise ValueError("a job graph needs at least one step")
    for i, step in enumerate(steps):
        bad = [j for j in refs_of(step) if not 0 <= j < i]
        if bad:
            raise ValueError(f"step {i} refers to step(s) {bad}, not earlier ones")


def whole(run: Callable[[Any, Callable[[float, str], None]], Any]) -> list[Step]:
    """The graph of a kind that does not divide: one step, the kind's runner."""
    return [Step(run)]


class Tracker:
    """The job's progress out of its steps' own: ``update(i, f)`` → the job's fraction;
    ``report(i, f, text)`` also keeps the latest message (the step's label before it) and
    marks it for the store (``dirty``; ``last_write``: when it was last written)."""

    def __init__(self, steps: Sequence[Step]) -> None:
        self.weights = [s.weight for s in steps]
        self.labels = [s.label for s in steps]
        self.total = float(sum(self.weights))
        self.fractions = [0.0] * len(steps)
        self.message = ""
        self.dirty = False
        self.last_write = 0.0

    def report(self, index: int, fraction: float, text: str) -> tuple[float, str]:
        """Step ``index`` at ``fraction``, saying ``text``: the job's fraction and message."""
        label = self.labels[index]
        self.message = f"{label}: {text}" if label else text
        self.dirty = True
        return self.update(index, fraction), self.message

    def update(self, index: int, fraction: float) -> float:
        self.fractions[index] = min(max(float(fraction), 0.0), 1.0)
        return self.fraction()

    def fraction(self) -> float:
        return sum(w * f for w, f in zip(self.weights, self.fractions)) / self.total


def throttled(send: Callable[[float, str], None], every_s: float
              ) -> Callable[[float, str], None]:
    """A step's ``progress(fraction, message)`` that calls ``send`` at most every ``every_s``
    (and always at the end, fraction 1), the fraction within [0, 1] and the message cut to
    ``MAX_MESSAGE`` characters: what a step's process sends to its supervisor."""
    last = [-float("inf")]

    def progress(fraction: float, message: str) -> None:
        now = time.monotonic()
        if now - last[0] >= every_s or fraction >= 1.0:
            last[0] = now
            send(min(max(float(fraction), 0.0), 1.0), str(message)[:MAX_MESSAGE])

    return progress


def run_inline(steps: Sequence[Step], params: Any,
               progress: Callable[[float, str], None]) -> Any:
    """Run a graph in this process, in order; the last step's value. A value is dropped
    once no later step refers to it."""
    check(steps)
    last_use = {}
    for i, step in enumerate(steps):
        for j in refs_of(step):
            last_use[j] = i
    values: dict[int, Any] = {}
    tracker = Tracker(steps)
    for i, step in enumerate(steps):
        def report(fraction: float, message: str, i: int = i) -> None:
            progress(*tracker.report(i, fraction, message))

        values[i] = step.fn(params, *resolve(step.args, values.__getitem__), report)
        tracker.update(i, 1.0)
        for j in [j for j, at in last_use.items() if at == i]:
            values.pop(j, None)
    return values[len(steps) - 1]
