"""The Docker image, built and run for real: its containers run the first jobs on the
kernels built into the image, compiling none.

Needs a Docker engine and the network (the build installs from the package index; about
10 minutes with the kernels compiled), so it runs only with ``KINOPLAN_DEPLOY_TESTS=1`` and
``docker`` on PATH. tests/deploy/test_kernel_cache.py shows the same without Docker.

* A fresh container, as the image's user, starts as a job step does and runs a workspace, a
  motion and a sequence job (tests/deploy/kernel_probe.py): numba's counters must show no
  kernel compiled. (The cache must be writable by that user: numba ignores a cache directory
  it cannot write, and compiles into one of its own.)
* The service itself (the image's entry point) runs a workspace and a motion job over REST;
  afterwards numba's cache in the container holds exactly the files the image shipped, and
  the user's own numba cache is empty: nothing was compiled by the API, its compute
  workers or the job steps.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import time
import urllib.request
import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PROBE = Path(__file__).with_name("kernel_probe.py")
BUILD_TIMEOUT_S = 3600
START_TIMEOUT_S = 120
JOB_TIMEOUT_S = 300
#: Where numba keeps a user's cache when the configured one is unusable.
USER_CACHE = "/home/kinoplan/.cache/numba"

pytestmark = [
    pytest.mark.skipif(os.environ.get("KINOPLAN_DEPLOY_TESTS") != "1",
                       reason="builds the Docker image (network, minutes); set "
                              "KINOPLAN_DEPLOY_TESTS=1"),
    pytest.mark.skipif(shutil.which("docker") is None, reason="no docker command here"),
    pytest.mark.slow,
]


def docker(*args: str, timeout: float = 300, check: bool = True) -> str:
    done = subprocess.run(["docker", *args], capture_output=True, text=True, timeout=timeout)
    if check:
        assert done.returncode == 0, f"docker {' '.join(args[:3])}: {done.stderr[-3000:]}"
    return done.stdout


@pytest.fixture(scope="module")
def image() -> str:
    tag = f"kinoplan-test:{uuid.uuid4().hex[:12]}"
    docker("build", "-t", tag, str(ROOT), timeout=BUILD_TIMEOUT_S)
    yield tag
    docker("image", "rm", "-f", tag, check=False)


def cache_listing(*run: str) -> list[str]:
    """``path size`` of every file in the image's numba cache and in the user's own, from a
    ``docker run``/``docker exec`` prefix ``run``."""
    script = ('find "$NUMBA_CACHE_DIR" ' + USER_CACHE +
              ' -type f -printf "%p %s\\n" 2>/dev/null | sort; true')
    return docker(*run, "sh", "-c", script).splitlines()


def test_a_fresh_container_runs_the_first_jobs_without_compiling(image):
    out = docker("run", "--rm", "--entrypoint", "python", image, "-c", PROBE.read_text(),
                 timeout=JOB_TIMEOUT_S)
    probe = json.loads(out.strip().splitlines()[-1])
    assert probe["jobs"] == ["workspace", "motion", "sequence"]
    assert probe["compiled"] == {}, json.dumps(probe["compiled"], indent=1)
    assert probe["loaded"], "no kernel loaded from the image's cache"


def http(method: str, url: str, body: dict | None = None) -> tuple[int, dict]:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method,
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=10) as resp:
        return resp.status, json.loads(resp.read())


def test_the_service_compiles_nothing_for_its_first_jobs(image):
    shipped = cache_listing("run", "--rm", "--entrypoint", "", image)
    assert any(line.split()[0].endswith(".nbi") for line in shipped), "no kernels shipped"
    assert not any(line.startswith(USER_CACHE) for line in shipped)
    name = f"kinoplan-test-{uuid.uuid4().hex[:12]}"
    docker("run", "-d", "--name", name, "-p", "127.0.0.1::8000", image, "--no-viewer")
    try:
        port = docker("port", name, "8000").splitlines()[0].rsplit(":", 1)[1]
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:
            with contextlib.suppress(OSError):
                if http("GET", f"{base}/health")[0] == 200:
                    break
            assert time.monotonic() < deadline, docker("logs", name)[-3000:]
            time.sleep(1)
        jobs = [{"kind": "workspace", "params": {"robot": "glt_palletizer", "samples": 20000}},
                {"kind": "motion", "params": {
                    "robot": "glt_palletizer", "start": [0, 0, 0, 0, 0.5, 0],
                    "goal": {"q": [1, 0.3, -0.3, 0, 0.5, 0]}, "time_limit": 5}}]
        ids = [http("POST", f"{base}/jobs", job)[1]["id"] for job in jobs]
        for job_id in ids:
            deadline = time.monotonic() + JOB_TIMEOUT_S
            while (record := http("GET", f"{base}/jobs/{job_id}")[1])["status"] in {
                    "queued", "running"}:
                assert time.monotonic() < deadline, record
                time.sleep(0.5)
            assert record["status"] == "succeeded", record
        assert cache_listing("exec", name) == shipped, "the service compiled kernels"
    finally:
        docker("rm", "-f", name, check=False)
