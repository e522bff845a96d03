"""A job kind whose graph fans out, for the backends' tests.

The test process registers it with ``monkeypatch``; a worker process (the local backend's
forkserver children, a Dask worker's step runner) imports this module when it unpickles a
step's function, and registers it here, as the catalog would.
"""

from __future__ import annotations

import os
import sys
import time

from pydantic import Field

from app.jobs.graph import Ref, Step, run_inline
from app.jobs.kinds import KINDS, JobKind, Params, Result

NAME = "fanout_test"


class FanParams(Params):
    parts: int = Field(4, ge=1, le=64)
    part_s: float = Field(0.5, ge=0, le=60)
    #: A part that raises after its first tenth (-1: none).
    fail: int = -1
    #: Burn CPU instead of sleeping.
    busy: bool = False


class PartOut(Result):
    index: int
    value: int
    pid: int
    ppid: int
    start: float
    end: float


class FanResult(Result):
    total: int
    parts: list[PartOut]


def part(params: FanParams, index: int, progress) -> dict:
    start = time.time()
    steps = 10
    for k in range(steps):
        if params.busy:
            until = time.monotonic() + params.part_s / steps
            while time.monotonic() < until:
                sum(i * i for i in range(1000))
        else:
            time.sleep(params.part_s / steps)
        progress((k + 1) / steps, f"{k + 1} of {steps}")
        if index == params.fail:
            raise RuntimeError(f"part {index} was asked to fail")
    return {"index": index, "value": (index + 1) ** 2, "pid": os.getpid(),
            "ppid": os.getppid(), "start": start, "end": time.time()}


def merge(params: FanParams, parts: list, progress) -> FanResult:
    progress(1.0, "merged")
    return FanResult(total=sum(p["value"] for p in parts), parts=parts)


def graph(params: FanParams) -> list[Step]:
    steps = [Step(part, (k,), label=f"part {k + 1}") for k in range(params.parts)]
    return [*steps, Step(merge, ([Ref(k) for k in range(params.parts)],), weight=0.1)]


def run(params: FanParams, progress) -> FanResult:
    return run_inline(graph(params), params, progress)


KIND = JobKind(NAME, FanParams, FanResult, run, "Parts and a merge (tests)", graph=graph)

if "pytest" not in sys.modules:  # a worker process: known as the catalog's kinds are
    KINDS.setdefault(NAME, KIND)
