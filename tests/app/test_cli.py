"""``python -m app``: flags, environment variables, and a real start."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

from app.__main__ import parse_args

REPO = Path(__file__).resolve().parents[2]


def test_defaults_flags_and_environment(monkeypatch, tmp_path):
    s = parse_args([])
    assert (s.host, s.port, s.viewer_port, s.no_viewer) == ("127.0.0.1", 8000, 8080, False)
    assert s.jobs_backend == "local" and s.workers >= 1
    monkeypatch.setenv("KINOPLAN_PORT", "9123")
    monkeypatch.setenv("KINOPLAN_NO_VIEWER", "true")
    s = parse_args([])
    assert s.port == 9123 and s.no_viewer
    s = parse_args(["--port", "9200", "--data-dir", str(tmp_path), "--workers", "3",
                    "--jobs-backend", "dask://127.0.0.1:8786", "--viewer-port", "9201"])
    assert s.port == 9200 and s.data_dir == tmp_path and s.workers == 3
    assert s.jobs_backend == "dask://127.0.0.1:8786" and s.viewer_port == 9201


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_python_m_app_serves_health(tmp_path):
    port = _free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "--port", str(port), "--no-viewer",
         "--data-dir", str(tmp_path)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                r = httpx.get(f"http://127.0.0.1:{port}/health", timeout=1)
                break
            except httpx.TransportError:
                assert proc.poll() is None, proc.stdout.read().decode()
                assert time.monotonic() < deadline, "service did not start in 30 s"
                time.sleep(0.2)
        assert r.json()["status"] == "ok"
        assert httpx.get(f"http://127.0.0.1:{port}/robots").status_code == 200
    finally:
        proc.terminate()
        proc.wait(timeout=10)
