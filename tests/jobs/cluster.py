"""A real Dask cluster for the fault tests: ``dask scheduler`` and ``dask worker`` processes.

Dask workers do not reconnect (distributed 2026.8): a worker that loses its scheduler closes,
and its ``dask worker`` command exits with status 0 once the task it is running has returned
(or after 30 s); one started while no scheduler answers exits with status 1 after
``distributed.comm.timeouts.connect``. The workers here run as a deployment runs them,
under ``python -m app.worker``, which starts ``dask worker`` again once the lost scheduler's
port answers.

Every process runs in a session of its own, so that ``close`` (or a kill in a test) reaches
its whole tree: the nanny, the worker process it starts and that worker's children.
"""

from __future__ import annotations

import atexit
import contextlib
import faulthandler
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import psutil

from .conftest import REPO, free_port

__all__ = ["Cluster", "DASK", "cpu_by_process", "cpu_seconds", "describe", "descendants",
           "hang_guard", "kill_tree", "process_group", "wait_gone"]

HOST = "127.0.0.1"
#: The ``dask`` command next to the interpreter running the tests.
DASK = Path(sys.executable).with_name("dask")
#: For the workers: one attempt to reach the scheduler lasts at most this long (Dask backs
#: off exponentially within an attempt; ``app.worker`` starts ``dask worker`` only once the
#: scheduler's port answers, so this only bounds a scheduler lost again meanwhile).
WORKER_ENV = {"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "5s"}


def _env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """The test's environment, with this checkout first on the workers' import path."""
    path = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, **(extra or {})}


def process_group(pgid: int) -> list[psutil.Process]:
    """The live processes of process group ``pgid`` (a group id is not reused while it has
    members, so this never reaches a stranger)."""
    members = []
    for p in psutil.process_iter():
        with contextlib.suppress(psutil.Error, OSError):
            if os.getpgid(p.pid) == pgid:
                members.append(p)
    return members


def kill_tree(proc: subprocess.Popen, grace: float = 0.0) -> list[str]:
    """SIGKILL the process group ``proc`` leads and any descendant that left it, after
    ``grace`` seconds for the processes to end on their own; reap ``proc``. The command lines
    of the processes that had not ended by then, other than ``proc``."""
    # Descendants only of a live (so not reaped) leader: a reaped pid may be someone else's.
    doomed = {*process_group(proc.pid), *(descendants(proc.pid) if proc.poll() is None else [])}
    alive = wait_gone(doomed, grace) if grace else list(doomed)
    for p in alive:
        with contextlib.suppress(psutil.Error):
            p.kill()
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=10)
    psutil.wait_procs(alive, timeout=5)
    return [describe(p) for p in alive if p.pid != proc.pid]


def describe(p: psutil.Process) -> str:
    try:
        return f"{p.pid}: {' '.join(p.cmdline())[:200]}"
    except psutil.Error:
        return f"{p.pid}: (gone)"


class Cluster:
    """A scheduler on a fixed port of 127.0.0.1 and ``workers`` single-threaded workers, each
    ``python -m app.worker`` (a ``dask worker`` command: nanny and worker process, started
    again after a lost scheduler). Logs go to ``workdir``."""

    def __init__(self, workdir: Path, workers: int = 2) -> None:
        self.workdir = Path(workdir)
        self.port = free_port()
        self.address = f"tcp://{HOST}:{self.port}"
        self.n_workers = workers
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []
        self._spawned: list[subprocess.Popen] = []  # not yet killed and reaped
        self._started = 0
        self._lock = threading.Lock()
        atexit.register(self.close)

    # ---- processes ------------------------------------------------------------------------
    def _spawn(self, name: str, argv: list[str], env: dict | None = None) -> subprocess.Popen:
        self._started += 1
        log = self.workdir / f"{self._started:02d}-{name}.log"
        with open(log, "wb") as out:
            proc = subprocess.Popen(argv, cwd=REPO, stdin=subprocess.DEVNULL,
                                    stdout=out, stderr=subprocess.STDOUT, env=_env(env),
                                    start_new_session=True)
        self._spawned.append(proc)
        return proc

    def start(self, timeout: float = 90.0) -> None:
        """Scheduler and workers up, every worker connected."""
        self.start_scheduler()
        with self._lock:
            while len(self.workers) < self.n_workers:
                self.workers.append(self._start_worker())
        self.wait_for_workers(self.n_workers, timeout)

    def start_scheduler(self, timeout: float = 60.0) -> None:
        """A scheduler on ``port`` (again), once it accepts connections."""
        assert not self.scheduler_alive(), "a scheduler is running already"
        self.scheduler = self._spawn("scheduler", [str(DASK), "scheduler", "--host", HOST,
                                                   "--port", str(self.port), "--no-dashboard"])
        deadline = time.monotonic() + timeout
        while True:
            with contextlib.suppress(OSError), socket.create_connection((HOST, self.port), 1):
                return
            assert self.scheduler.poll() is None, \
                f"the scheduler exited ({self.scheduler.returncode}):\n{self.logs('scheduler')}"
            assert time.monotonic() < deadline, "the scheduler did not start listening"
            time.sleep(0.05)

    def scheduler_alive(self) -> bool:
        return self.scheduler is not None and self.scheduler.poll() is None

    def kill_scheduler(self) -> None:
        """SIGKILL the scheduler (as a crash or an OOM kill would)."""
        with self._lock:
            if self.scheduler is not None and self.scheduler in self._spawned:
                kill_tree(self.scheduler)
                self._spawned.remove(self.scheduler)

    def _start_worker(self) -> subprocess.Popen:
        scratch = self.workdir / "scratch"
        scratch.mkdir(exist_ok=True)
        return self._spawn("worker", [sys.executable, "-m", "app.worker", self.address,
                                      "--nworkers", "1", "--nthreads", "1", "--no-dashboard",
                                      "--local-directory", str(scratch)], WORKER_ENV)

    def workers_alive(self) -> bool:
        """Every worker command still runs (``app.worker`` outlives its scheduler)."""
        return all(proc.poll() is None for proc in self.workers)

    def ensure(self, timeout: float = 90.0) -> None:
        """The scheduler running (started again if a test killed it) and every worker connected
        (``app.worker`` starts a new ``dask worker`` once the scheduler answers)."""
        if not self.scheduler_alive():
            self.start_scheduler()
        self.wait_for_workers(self.n_workers, timeout)

    def close(self) -> None:
        """Kill every process of the cluster (also at exit, should a finalizer not run)."""
        with self._lock:
            while self._spawned:
                kill_tree(self._spawned.pop())

    def logs(self, name: str = "", lines: int = 15) -> str:
        """The last ``lines`` of each log whose file name has ``name`` (for failure messages)."""
        out = []
        for path in sorted(self.workdir.glob(f"*{name}*.log")):
            tail = path.read_text(errors="replace").splitlines()[-lines:]
            out.append(f"--- {path.name}\n" + "\n".join(tail))
        return "\n".join(out)

    # ---- looking at the cluster through a client of the test --------------------------------
    @contextlib.contextmanager
    def client(self, timeout: float = 10.0) -> Iterator:
        """A ``distributed.Client`` of the scheduler, closed after. Hold one for repeated
        looks: each new client costs the scheduler a connection and a registration."""
        from distributed import Client

        client = Client(self.address, timeout=timeout, set_as_default=False)
        try:
            yield client
        finally:
            client.close()

    @contextlib.contextmanager
    def _using(self, client) -> Iterator:
        if client is not None:
            yield client
        else:
            with self.client() as own:
                yield own

    def wait_for_workers(self, n: int, timeout: float = 90.0) -> list[str]:
        """The addresses of the workers, once ``n`` are connected and running."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            try:
                with self.client(timeout=min(max(left, 1.0), 10.0)) as c:
                    c.wait_for_workers(n, timeout=max(left, 1.0))
                    return list(c.scheduler_info()["workers"])
            except (OSError, TimeoutError):
                if time.monotonic() >= deadline:
                    raise AssertionError(f"{n} Dask workers did not connect within {timeout:g} "
                                         f"s\n{self.logs()}") from None
                time.sleep(0.2)

    def worker_pids(self, client=None) -> dict[str, int]:
        """``{worker address: pid}`` of the worker processes (not their nannies)."""
        with self._using(client) as c:
            return c.run(os.getpid)

    def processing(self, client=None) -> dict[str, list[str]]:
        """``{worker address: keys of the tasks it runs or has been given}``."""
        with self._using(client) as c:
            return {address: [str(key) for key in keys]
                    for address, keys in c.processing().items()}

    def executing(self, client=None) -> dict[str, list[str]]:
        """``{worker address: the tasks its threads run}``, cancelled ones included: Dask
        cannot stop a thread, so a task cancelled while it runs holds its thread until it
        returns."""
        def running(dask_worker) -> list[str]:  # nested: pickled by value, not by name
            return [str(ts) for ts in dask_worker.state.executing]

        with self._using(client) as c:
            return c.run(running)

    def worker_running(self, text: str, timeout: float = 30.0,
                       client=None) -> tuple[str, int]:
        """``(address, pid)`` of the worker processing a task whose key holds ``text`` (a job
        id); failing that, of the only worker processing anything."""
        deadline = time.monotonic() + timeout
        with self._using(client) as c:
            while True:
                tasks = self.processing(c)
                named = [a for a, keys in tasks.items() if any(text in k for k in keys)]
                busy = [a for a, keys in tasks.items() if keys]
                found = named[0] if len(named) == 1 else busy[0] if len(busy) == 1 else None
                if found is not None:
                    return found, c.run(os.getpid, workers=[found])[found]
                assert time.monotonic() < deadline, f"no worker runs a task of {text}: {tasks}"
                time.sleep(0.1)


# ---- processes and their CPU ----------------------------------------------------------------
def descendants(pid: int) -> list[psutil.Process]:
    """The live descendants of ``pid`` (none if it has gone)."""
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.Error:
        return []


def _tree_times(pid: int) -> dict[psutil.Process, float]:
    """CPU seconds (user + system) used so far by each live process of the tree of ``pid``."""
    try:
        procs = [psutil.Process(pid), *descendants(pid)]
    except psutil.Error:
        return {}
    times = {}
    for p in procs:
        with contextlib.suppress(psutil.Error):
            used = p.cpu_times()
            times[p] = used.user + used.system
    return times


def cpu_by_process(pids: Iterable[int], window: float = 0.5) -> dict[int, dict[str, float]]:
    """``{pid: {"pid: command": CPU seconds}}``: what each process of the trees of ``pids``
    uses in the same next ``window`` seconds. A process that starts during the window counts
    with all of its time; one that ends during it is not seen (its last moments are lost)."""
    pids = list(pids)
    before = {pid: _tree_times(pid) for pid in pids}
    time.sleep(window)
    out = {}
    for pid in pids:
        then = before[pid]
        out[pid] = {describe(p)[:80]: round(t - then.get(p, 0.0), 3)
                    for p, t in _tree_times(pid).items()}
    return out


def cpu_seconds(pids: Iterable[int], window: float = 0.5) -> dict[int, float]:
    """``{pid: CPU seconds}`` the process ``pid`` and its descendants use in the same next
    ``window`` seconds (``cpu_by_process`` summed by tree)."""
    return {pid: sum(used.values()) for pid, used in cpu_by_process(pids, window).items()}


def wait_gone(procs: Iterable[psutil.Process], timeout: float) -> list[psutil.Process]:
    """Those of ``procs`` still alive after ``timeout`` seconds (an empty list: all ended)."""
    _, alive = psutil.wait_procs(list(procs), timeout=timeout)
    return alive


@contextlib.contextmanager
def hang_guard(seconds: float, cleanup: Callable[[], None], stacks: Path) -> Iterator[None]:
    """Should the block still run after ``seconds``: write every thread's stack to
    ``stacks``, run ``cleanup`` (kill the cluster: whatever waits on it wakes up) and
    interrupt the test run (SIGINT) rather than hang it."""
    def fire() -> None:
        with open(stacks, "w") as out:
            faulthandler.dump_traceback(file=out, all_threads=True)
        print(f"\n*** still running after {seconds:g} s; stacks in {stacks}", file=sys.stderr)
        cleanup()
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(seconds, fire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
