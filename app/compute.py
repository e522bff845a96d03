"""Heavy synchronous requests run in worker processes, never in the API's process.

A large FK or IK batch, a two-million-sample workspace, a long trajectory or a plot holds the
interpreter lock for up to seconds while it computes and encodes its answer. Run in the API
process, eight of them at once stall every other request, ``/health`` included. Here such
work runs in a small pool of worker processes (``compute_workers``, forked from a server that
has numpy and the kinematics imported) and comes back as encoded bytes; the event loop only
waits. Small requests (one pose, a few configurations) stay in the API's thread pool, where
they cost microseconds instead of a round trip to another process.

At most ``max_waiting`` heavy requests wait for a worker; beyond that the service answers
503 with ``Retry-After`` instead of queueing without bound (anything bigger belongs in a
job). A worker that dies (killed for memory, say) fails only the requests it held: they
answer 503 and the pool is started afresh.
"""

from __future__ import annotations

import asyncio
import json
import logging
import pickle
import threading
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from starlette.concurrency import run_in_threadpool

from .lifetime import forkserver_context

__all__ = ["ComputePool", "ComputeBusy", "ComputeFailed", "encode_json"]

log = logging.getLogger(__name__)

#: Modules a compute worker imports once, before its first request.
PRELOAD = ["numpy", "scipy", "kinematics.fk", "kinematics.ik", "kinematics.workspace"]


class ComputeBusy(RuntimeError):
    """Too many heavy requests are waiting already (answered 503 with Retry-After)."""


class ComputeFailed(RuntimeError):
    """The worker process running the request died (answered 503)."""


def encode_json(content: Any) -> bytes:
    """JSON as the service answers it (compact, UTF-8, no NaN)."""
    return json.dumps(content, ensure_ascii=False, allow_nan=False,
                      separators=(",", ":")).encode()


def _call(fn: Callable[..., Any], *args: Any) -> Any:
    """Run in the worker: ``fn(*args)``, with an exception that cannot travel back (one that
    does not survive pickling) replaced by a RuntimeError saying what it was, so it fails
    this request alone instead of breaking the pool."""
    try:
        return fn(*args)
    except Exception as exc:
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:
            raise RuntimeError(f"{type(exc).__name__}: {exc}") from None
        raise


#: The compiled kernels (``planning.warm.PARTS``) a worker's requests run: kinematics and the
#: motion planner (``POST /robots/{id}/motion``); the sequencing search runs only in jobs.
KERNELS = ["kinematics", "motion"]


def _warm() -> None:
    """Run once in each new worker: import what requests use, and start loading the
    compiled kernels they run in the background (``planning.warm``)."""
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    from planning.warm import start_warm_up

    start_warm_up(KERNELS)


def _ready() -> None:
    """In a worker: return once its compiled kernels are loaded (``prestart``)."""
    from planning.warm import warm_up

    warm_up(KERNELS)


class ComputePool:
    """Runs ``fn(*args)`` in a worker process (``heavy``) or in the thread pool."""

    def __init__(self, workers: int, max_waiting: int) -> None:
        self.workers = max(1, int(workers))
        self.max_waiting = max(1, int(max_waiting))
        self._executor: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self._waiting = 0
        #: By token, the workers (process ids) that said they keep its value
        #: (``app.collision_models.run_kept``); forgotten with the workers.
        self.holders: OrderedDict[str, set[int]] = OrderedDict()

    @property
    def waiting(self) -> int:
        """Heavy requests submitted and not yet answered."""
        return self._waiting

    def _pool(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._executor is None:
                # Workers die with the service, even a killed one (app.lifetime).
                self._executor = ProcessPoolExecutor(self.workers,
                                                     mp_context=forkserver_context(),
                                                     initializer=_warm)
            return self._executor

    def prestart(self) -> None:
        """Start every worker now and load its kernels, without waiting for them: a worker
        starts on demand otherwise, and the first plans a fresh service was asked for waited
        seconds beyond their time limit for it (one task a worker: the pool starts a new
        process for each task while none is idle)."""
        pool = self._pool()
        for _ in range(self.workers):
            pool.submit(_ready)

    def _discard(self, broken: ProcessPoolExecutor) -> None:
        with self._lock:
            if self._executor is broken:
                self._executor = None
                self.holders.clear()
        broken.shutdown(wait=False, cancel_futures=True)

    async def run(self, heavy: bool, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)``: in a worker process when ``heavy``, else in the thread pool.
        ``fn`` and its arguments must pickle (module-level function, plain data, models)."""
        if not heavy:
            return await run_in_threadpool(fn, *args)
        if self._waiting >= self.max_waiting:
            raise ComputeBusy(f"{self._waiting} large requests are being computed already; "
                              "retry shortly, or submit a job")
        self._waiting += 1
        pool = self._pool()
        try:
            return await asyncio.wrap_future(pool.submit(_call, fn, *args))
        except BrokenProcessPool:
            log.warning("a compute worker died; starting the pool afresh")
            self._discard(pool)
            raise ComputeFailed("the worker computing this request died (out of memory?); "
                                "retry with a smaller request, or submit a job") from None
        finally:
            self._waiting -= 1

    def shutdown(self) -> None:
        """Stop the workers now, whatever they are computing (their requests are gone)."""
        with self._lock:
            executor, self._executor = self._executor, None
            self.holders.clear()
        if executor is None:
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join(2.0)
            if process.is_alive():
                process.kill()
