"""A child process that runs job steps for a Dask worker, so that a cancel can kill them.

A Dask worker runs tasks on threads, and a thread cannot be stopped from outside: a cancelled
step that does not check in would run on. So each step runs in a ``Runner``: a child process
(``python -m app.jobs.runner``, started with ``subprocess`` because a Dask worker process is
daemonic and may not fork ``multiprocessing`` children) that imports the job kinds once, then
takes steps one at a time over a socket: ``run`` loads the job's params (kept for the next
step of the same job), calls the step and sends back progress and its value. ``Runner.kill``
ends the process at once (SIGKILL): its CPU is free the moment the cancel is seen, and the next
step starts a fresh runner. A runner dies with the worker (Linux ``PR_SET_PDEATHSIG``, and a
watchdog thread that exits when the worker is gone: ``app.lifetime``).
"""

from __future__ import annotations

import logging
import os
import pickle
import signal
import socket
import subprocess
import sys
import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from multiprocessing.connection import Connection
from typing import Any

from ..lifetime import die_with_parent, spawn

__all__ = ["Runner", "StepFailed", "StepCancelled", "take_runner", "give_back", "prestart"]

log = logging.getLogger(__name__)

#: Least seconds between two progress messages of a step.
PROGRESS_EVERY_S = 0.2
#: Seconds a runner waits for a stop request between checks while a step runs.
CHECK_EVERY_S = 0.2
#: Seconds a new runner may take to import the job kinds and say it is ready.
START_TIMEOUT_S = 120.0


class StepFailed(RuntimeError):
    """A step raised: the message is the step's ``Type: message``."""


class StepCancelled(RuntimeError):
    """The step was stopped because its job was cancelled or ran out of time."""


class RunnerDied(RuntimeError):
    """The runner process ended without an answer."""


class Runner:
    """One child process running steps; not thread-safe (one step at a time)."""

    def __init__(self) -> None:
        parent, child = socket.socketpair()
        # The child sees the modules this process sees (as multiprocessing's spawn does).
        env = dict(os.environ, PYTHONUNBUFFERED="1", KINOPLAN_RUNNER_PARENT=str(os.getpid()),
                   PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        self.process = subprocess.Popen(
            [sys.executable, "-m", "app.jobs.runner", str(child.fileno())],
            pass_fds=[child.fileno()], env=env, stdin=subprocess.DEVNULL,
        )
        child.close()
        self.conn = Connection(parent.detach())
        self.loaded: str | None = None  # the job whose params the child holds
        if not self.conn.poll(START_TIMEOUT_S):
            self.kill()
            raise RunnerDied(f"the step runner did not start within {START_TIMEOUT_S:g} s")
        self._expect(self.conn.recv(), "ready")

    @staticmethod
    def _expect(msg: Any, tag: str) -> None:
        if not (isinstance(msg, tuple) and msg and msg[0] == tag):
            raise RunnerDied(f"the step runner answered {msg!r:.200}, expected {tag!r}")

    def alive(self) -> bool:
        return self.process.poll() is None

    def kill(self) -> None:
        """End the child now (SIGKILL) and reap it."""
        try:
            self.process.kill()
        except OSError:
            pass
        try:
            self.process.wait(5)
        except subprocess.TimeoutExpired:  # pragma: no cover - a process SIGKILL left alive
            log.warning("step runner %s did not exit after SIGKILL", self.process.pid)
        self.conn.close()

    def run(self, job_key: str, kind: str, payload: Any, fn: Callable, args: tuple,
            final: bool, progress: Callable[[float, str], None],
            should_stop: Callable[[], bool]) -> Any:
        """Run one step in the child; its value (``final``: the result's JSON text).
        ``progress`` gets the step's reports; ``should_stop()`` is asked every
        ``CHECK_EVERY_S`` and, once true, the child is killed and ``StepCancelled`` raised.
        ``StepFailed`` if the step raised, ``RunnerDied`` if the child died."""
        send_payload = self.loaded != job_key
        try:
            self.conn.send(("run", job_key, kind, payload if send_payload else None, fn,
                            args, final))
        except (OSError, pickle.PicklingError) as exc:
            self.kill()
            raise RunnerDied(f"could not hand the step to its runner: {exc}") from None
        self.loaded = job_key
        while True:
            try:
                ready = self.conn.poll(CHECK_EVERY_S)
                msg = self.conn.recv() if ready else None
            except (EOFError, OSError):
                code = self.process.wait()
                raise RunnerDied(f"the step's process died (exit code {code})") from None
            tag = None if msg is None else msg[0]
            if tag is None or tag == "progress":
                if tag is not None:
                    progress(msg[1], msg[2])
                if should_stop():
                    self.kill()
                    raise StepCancelled("cancelled")
            elif tag == "value":
                return msg[1]
            elif tag == "error":
                self.loaded = None
                raise StepFailed(msg[1])
            elif tag == "cancelled":
                raise StepCancelled("cancelled")
            else:  # pragma: no cover - a protocol error
                self.kill()
                raise RunnerDied(f"unexpected message from the step runner: {tag!r}")


# ---- a pool of runners per worker process ----------------------------------------------
#: Runners waiting for a step: each a Future, done (idle) or still starting (prestarted).
_POOL: deque[Future] = deque()
_POOL_LOCK = threading.Lock()


def _new_runner() -> Future:
    return spawn(Runner)


def take_runner() -> Runner:
    """A live runner of this process: an idle one, one still starting, or a new one."""
    while True:
        with _POOL_LOCK:
            pending = _POOL.popleft() if _POOL else None
        if pending is None:
            return _new_runner().result()
        try:
            runner = pending.result()
        except Exception:  # noqa: BLE001 - a prestart that failed: try the next
            continue
        if runner.alive():
            return runner
        runner.kill()


def give_back(runner: Runner) -> None:
    """Return a runner that finished a step (a killed one is dropped)."""
    if runner.alive():
        done: Future = Future()
        done.set_result(runner)
        with _POOL_LOCK:
            _POOL.append(done)


def prestart(count: int) -> None:
    """Start ``count`` runners in the background for the steps to come (a worker's first
    step then waits at most for the rest of a start already under way)."""
    futures = [_new_runner() for _ in range(count)]
    with _POOL_LOCK:
        _POOL.extend(futures)


# ---- the child ------------------------------------------------------------------------
def child_main(fd: int) -> None:
    """The child's loop: take ``run`` messages until the socket closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C in a terminal is the worker's
    parent = int(os.environ.get("KINOPLAN_RUNNER_PARENT", os.getppid()))
    die_with_parent(parent)
    conn = Connection(fd)
    from . import warm_kernels  # noqa: F401 - every kind registered, kernels loaded
    from .graph import throttled
    from .kinds import JobCancelled, load_job

    conn.send(("ready",))
    loaded: tuple[str, Any, Any] | None = None
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        _, job_key, kind_name, payload, fn, args, final = msg
        progress = throttled(lambda f, m: conn.send(("progress", f, m)), PROGRESS_EVERY_S)
        try:
            if payload is not None or loaded is None or loaded[0] != job_key:
                if payload is None:
                    raise RuntimeError("the step runner lost the job's params")
                kind, params = load_job(kind_name, payload)
                loaded = (job_key, kind, params)
            _, kind, params = loaded
            value = fn(params, *args, progress)
            conn.send(("value", kind.result_json(value) if final else value))
        except JobCancelled:
            conn.send(("cancelled",))
        except BaseException as exc:  # noqa: BLE001 - everything a step raises is its failure
            loaded = None
            try:
                conn.send(("error", f"{type(exc).__name__}: {exc}"))
            except (OSError, pickle.PicklingError):
                return


if __name__ == "__main__":
    child_main(int(sys.argv[1]))
