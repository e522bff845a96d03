"""Helpers for job tests: a served app (lifespan on) and a real service process."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def jobs_client(tmp_path):
    """A TestClient whose app runs its job backend (2 local workers)."""
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=2))) as c:
        yield c


@pytest.fixture(scope="module")
def checking_client(tmp_path_factory):
    """A TestClient whose job backend does not run (no lifespan), shared by a module's tests:
    for what a submission answers (422, 404), when nothing is queued."""
    data_dir = tmp_path_factory.mktemp("checking")
    return TestClient(create_app(Settings(no_viewer=True, data_dir=data_dir)))


def wait_for(client, job_id: str, statuses=("succeeded", "failed", "cancelled"),
             timeout: float = 60.0) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in statuses:
            return job
        assert time.monotonic() < deadline, f"job {job_id} still {job['status']}"
        time.sleep(0.05)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Service:
    """``python -m kinoplan`` in a subprocess on a free port, with its own data dir."""

    def __init__(self, data_dir: Path, *args: str, env: dict | None = None) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "kinoplan", "--port", str(self.port), "--no-viewer",
             "--data-dir", str(data_dir), *args],
            cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            env={**os.environ, **(env or {})}, start_new_session=True,
        )
        deadline = time.monotonic() + 60
        while True:
            try:
                httpx.get(self.url + "/health", timeout=1)
                return
            except httpx.TransportError:
                assert self.proc.poll() is None, "service exited at start"
                assert time.monotonic() < deadline, "service did not start"
                time.sleep(0.1)

    def kill(self) -> None:
        """SIGKILL the service and its whole process group (as a crash or OOM kill would)."""
        os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.kill()
