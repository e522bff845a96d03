"""Every child process of the service dies with it, even when the service is killed.

A graceful stop ends the children (the job backend and the compute pool stop theirs); a
SIGKILL or an out-of-memory kill runs no code, and a child that waits on a pipe it holds both
ends of (a compute worker) or computes without reporting (a job step, a collision-model
build) would run on, reparented to PID 1. So each child watches its parent twice:

* Linux's ``PR_SET_PDEATHSIG``: the kernel SIGKILLs the child when the *thread* that forked
  it exits, even while the child holds the interpreter lock in compiled code;
* a watchdog thread that exits the child once its parent has changed (every
  ``WATCH_EVERY_S``): the fallback where ``prctl`` is missing.

``die_with_parent`` does both (the Dask step runners call it, ``app.jobs.runner``). The
service's other children come from multiprocessing's forkserver (``forkserver_context``): the
server imports ``app.forkserver_preload`` first, which makes the server die with the service
and each process it forks (compute workers, job steps) die with the server. The server is
started by ``spawn``, on a thread that lives as long as the process, so that no thread that
ends (a request's, a stopped job backend's) takes the server and its workers with it.
multiprocessing's resource tracker ends on its own once the last of these processes has gone
(it exits when the last write end of its pipe closes, and each forked child holds one).
"""

from __future__ import annotations

import multiprocessing.context
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import Future
from multiprocessing import forkserver
from typing import Any

__all__ = ["WATCH_EVERY_S", "die_with_parent", "forkserver_context", "guard_forkserver",
           "spawn"]

#: Seconds between two checks of the watchdog thread on its process's parent.
WATCH_EVERY_S = 0.5

_PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int) -> None:
    """In a child: be SIGKILLed when the thread of ``parent`` (its pid) that started it
    exits (Linux), and exit within ``WATCH_EVERY_S`` once ``parent`` is no longer its
    parent; exit now if that happened already."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        except (OSError, AttributeError):  # the watchdog thread is the fallback
            pass
    # Checked after prctl: a parent that died in between is seen here.
    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=_watch, args=(parent,), name="kinoplan-parent-watch",
                     daemon=True).start()


def _watch(parent: int) -> None:
    while True:
        time.sleep(WATCH_EVERY_S)
        if os.getppid() != parent:
            os._exit(1)


# ---- the thread that starts children ----------------------------------------------------
_REQUESTS: queue.SimpleQueue = queue.SimpleQueue()
_SPAWNER: list[threading.Thread] = []
_SPAWNER_LOCK = threading.Lock()


def _spawner() -> None:
    while True:
        start, done = _REQUESTS.get()
        try:
            done.set_result(start())
        except BaseException as exc:  # noqa: BLE001 - handed to whoever asked
            done.set_exception(exc)


def spawn(start: Callable[[], Any]) -> Future:
    """``start()`` (which starts a child process), run on a thread that lives as long as this
    process: a child's ``PR_SET_PDEATHSIG`` fires when the *thread* that started it ends, so
    a child started by a request's thread or a stopped job backend's would die with it."""
    with _SPAWNER_LOCK:
        if not _SPAWNER:
            thread = threading.Thread(target=_spawner, name="kinoplan-spawner", daemon=True)
            thread.start()
            _SPAWNER.append(thread)
    done: Future = Future()
    _REQUESTS.put((start, done))
    return done


# ---- the forkserver ------------------------------------------------------------------------
#: Modules the forkserver imports: the guard first (the server dies with the service even
#: while it imports the rest), then what the users of ``forkserver_context`` asked for.
_PRELOAD = ["app.forkserver_preload", "__main__"]
_PRELOAD_LOCK = threading.Lock()
_forker = 0  # in the forkserver and its children: the pid of the process calling fork()


def guard_forkserver() -> None:
    """In the forkserver: die with the service that started it, and make every process it
    forks die with it in turn (they cannot watch the service: their parent is the server)."""
    # A service gone before this line is not seen, but then nothing holds the server's
    # "alive" pipe any more: the server exits as soon as it has imported its modules.
    die_with_parent(os.getppid())
    os.register_at_fork(before=_note_forker, after_in_child=lambda: die_with_parent(_forker))


def _note_forker() -> None:
    global _forker
    _forker = os.getpid()


class _Process(multiprocessing.context.ForkServerProcess):
    @staticmethod
    def _Popen(process_obj):  # noqa: N802 - multiprocessing's name
        # The server, if it is not running (first use, or it was killed), starts on the
        # long-lived thread, not on whichever thread starts this process.
        spawn(forkserver.ensure_running).result()
        return multiprocessing.context.ForkServerProcess._Popen(process_obj)


class _Context(multiprocessing.context.ForkServerContext):
    Process = _Process


_CONTEXT = _Context()


def forkserver_context(preload: Iterable[str] = ()) -> multiprocessing.context.BaseContext:
    """multiprocessing's forkserver context whose server and children die with this process.
    The server imports ``preload`` too (with the modules asked for before: the server is
    shared by every user of the context); it must be given before the server starts."""
    with _PRELOAD_LOCK:
        _PRELOAD.extend(m for m in preload if m not in _PRELOAD)
        _CONTEXT.set_forkserver_preload(list(_PRELOAD))
    return _CONTEXT
