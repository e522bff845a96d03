"""``python -m app.worker tcp://HOST:PORT [dask worker options]``: a Dask worker for the
job cluster that outlives its scheduler.

A ``dask worker`` ends when it loses its scheduler (its nanny closes: "worker-handle-
scheduler-connection-broken"), so a scheduler restarted at the same address would find no
workers. This command runs ``dask worker`` with the options given (default ``--nworkers 1
--nthreads 1``: one job step at a time; always ``--preload app.jobs.dask_preload``, which
imports the job kinds and starts the step runners up front), and whenever it ends without
being asked to, waits
until the scheduler's port answers again and starts a fresh one. SIGTERM or SIGINT stop the
worker and this loop. Under systemd or Docker a restart policy does the same; this is for
machines without one.
"""

from __future__ import annotations

import logging
import signal
import socket
import subprocess
import sys
import threading
import time
from urllib.parse import urlsplit

__all__ = ["main", "reachable"]

log = logging.getLogger("app.worker")

#: Seconds between two probes of a lost scheduler's port.
PROBE_EVERY_S = 1.0
#: Least seconds between two starts of ``dask worker`` (a worker that cannot start at all
#: is not restarted in a tight loop).
MIN_RESTART_S = 2.0


def reachable(address: str, timeout: float = 1.0) -> bool:
    """Whether the scheduler's TCP port at ``address`` (``tcp://`` or ``tls://``) accepts a
    connection."""
    parts = urlsplit(address)
    if not parts.hostname or not parts.port:
        return False
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=timeout):
            return True
    except OSError:
        return False


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    if not argv or argv[0].startswith("-"):
        print(__doc__.split("\n\n")[0], file=sys.stderr)
        return 2
    address, options = argv[0], argv[1:]
    if "://" not in address:
        address = "tcp://" + address
    if "--nworkers" not in options and not any(o.startswith("--nworkers=") for o in options):
        options += ["--nworkers", "1"]
    if "--nthreads" not in options and not any(o.startswith("--nthreads=") for o in options):
        options += ["--nthreads", "1"]
    options += ["--preload", "app.jobs.dask_preload"]
    command = [sys.executable, "-m", "distributed.cli.dask_worker", address, *options]
    stop = threading.Event()
    child: list[subprocess.Popen] = []

    def ask_to_stop(signum: int, _frame: object) -> None:
        stop.set()
        for proc in child:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)

    signal.signal(signal.SIGTERM, ask_to_stop)
    signal.signal(signal.SIGINT, ask_to_stop)
    code = 0
    while not stop.is_set():
        if not reachable(address):
            log.info("waiting for the scheduler at %s", address)
            while not stop.is_set() and not reachable(address):
                stop.wait(PROBE_EVERY_S)
            if stop.is_set():
                break
        started = time.monotonic()
        proc = subprocess.Popen(command)
        child[:] = [proc]
        code = proc.wait()
        if stop.is_set():
            break
        log.warning("dask worker ended (exit code %s); starting a new one once the scheduler "
                    "at %s answers", code, address)
        stop.wait(max(0.0, MIN_RESTART_S - (time.monotonic() - started)))
    return code


if __name__ == "__main__":
    sys.exit(main())
