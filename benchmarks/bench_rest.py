"""REST batch kinematics over real HTTP: orjson answers and ``.npy`` answers against the
standard library's JSON encoder, in one run.

The script starts the service twice as a user would (``python -m kinoplan --no-viewer`` on a
loopback port, data in a temporary directory): once with ``KINOPLAN_JSON_ENCODER=stdlib``
(answers encoded by ``json.dumps`` after ``tolist`` and bodies decoded by ``json.loads``, as
the service did before) and once as it ships (orjson both ways). Against each, with httpx:

* FK of ``--configs`` (10,000) configurations of glt_palletizer: round trip median and best
  of ``--repeats`` calls, the request body encoded beforehand and the answer decoded by the
  client (``orjson.loads``; the same client decoder for both, so only the server differs),
  plus the same call with ``Accept: application/x-npy`` decoded by ``np.load``;
* the CPU time one such JSON call costs the server process and the client (from
  ``/proc/<pid>/stat`` and ``time.process_time``): on a loaded machine, wall times add the
  wait for a core, CPU times do not;
* single-configuration FK against ``GET /health``, interleaved, ``--singles`` calls each:
  p50 and p90 and their ratio (goal: FK p50 at most 1.2 x /health p50).

Goals: FK of 10,000 configurations in JSON within 80 ms. Timings on a shared machine are
noisy; the report says what it measured. It exits 0 whatever the numbers.

Run: ``.venv/bin/python benchmarks/bench_rest.py [--configs 10000] [--repeats 15]``
"""

from __future__ import annotations

import argparse
import io
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import orjson

ROOT = Path(__file__).resolve().parents[1]
ROBOT = "glt_palletizer"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """``python -m kinoplan`` on a loopback port, stopped on exit."""

    def __init__(self, encoder: str) -> None:
        self.port = free_port()
        self.dir = tempfile.TemporaryDirectory(prefix="kinoplan-bench-rest-")
        env = dict(os.environ, KINOPLAN_JSON_ENCODER=encoder)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "kinoplan", "--port", str(self.port), "--no-viewer",
             "--data-dir", self.dir.name], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        self.client = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=120)
        deadline = time.monotonic() + 60
        while True:
            try:
                if self.client.get("/health").status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline or self.proc.poll() is not None:
                self.stop()
                raise SystemExit(f"the service did not start on port {self.port}")
            time.sleep(0.2)

    def stop(self) -> None:
        self.client.close()
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.dir.cleanup()


def timed(fn, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def process_cpu(pid: int) -> float:
    """CPU seconds (user + system) the process ``pid`` has used so far (Linux)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_per_call(fn, n: int, pid: int) -> tuple[float, float]:
    """CPU seconds per call of ``fn`` in the server process ``pid`` and in this client: what
    a call costs whatever else the machine runs (wall times on a loaded machine add the wait
    for a core)."""
    s0, c0 = process_cpu(pid), time.process_time()
    for _ in range(n):
        fn()
    return (process_cpu(pid) - s0) / n, (time.process_time() - c0) / n


def ms(values: list[float], q: float = 0.5) -> float:
    return 1000 * float(np.quantile(values, q))


def measure(encoder: str, q: np.ndarray, repeats: int, singles: int) -> dict:
    server = Server(encoder)
    try:
        c = server.client
        url = f"/robots/{ROBOT}/fk"
        body = orjson.dumps({"q": q}, option=orjson.OPT_SERIALIZE_NUMPY)
        headers = {"content-type": "application/json"}

        def fk_json() -> np.ndarray:
            r = c.post(url, content=body, headers=headers)
            r.raise_for_status()
            return np.asarray(orjson.loads(r.content)["poses"])

        def fk_npy() -> np.ndarray:
            r = c.post(url, content=body, headers=headers | {"accept": "application/x-npy"})
            r.raise_for_status()
            return np.load(io.BytesIO(r.content))

        poses_json, poses_npy = fk_json(), fk_npy()  # warm: imports, the worker pool
        one = orjson.dumps({"q": q[0]}, option=orjson.OPT_SERIALIZE_NUMPY)
        fk_times = timed(fk_json, repeats)
        npy_times = timed(fk_npy, repeats)
        answer_bytes = len(c.post(url, content=body, headers=headers).content)
        cpu = cpu_per_call(fk_json, repeats, server.proc.pid)
        health, single = [], []
        for _ in range(singles):
            t0 = time.perf_counter()
            c.get("/health").raise_for_status()
            health.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            c.post(url, content=one, headers=headers).raise_for_status()
            single.append(time.perf_counter() - t0)
        return {"fk": fk_times, "npy": npy_times, "health": health, "single": single,
                "cpu": cpu,
                "bytes": answer_bytes, "same": bool(np.array_equal(poses_json, poses_npy)),
                "shape": poses_npy.shape}
    finally:
        server.stop()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=10_000)
    ap.add_argument("--repeats", type=int, default=15, help="timed calls per batch case")
    ap.add_argument("--singles", type=int, default=300, help="single FK and /health calls")
    ap.add_argument("--seed", type=int, default=20250611)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    q = rng.uniform(-1.0, 1.0, (args.configs, 6))
    print(f"kinoplan REST benchmark; python {platform.python_version()}, {os.cpu_count()} cpus, "
          f"load {os.getloadavg()[0]:.2f}; FK of {args.configs} configurations of {ROBOT}")
    results = {}
    for label, encoder in (("stdlib json (before)", "stdlib"), ("orjson (now)", "orjson")):
        r = measure(encoder, q, args.repeats, args.singles)
        results[label] = r
        print(f"\n== {label}")
        print(f"  FK x{args.configs} JSON round trip: median {ms(r['fk']):7.1f} ms, best "
              f"{1000 * min(r['fk']):7.1f} ms ({r['bytes'] / 2**20:.1f} MiB answer)")
        print(f"  FK x{args.configs} JSON CPU per call: server {1000 * r['cpu'][0]:.1f} ms + "
              f"client {1000 * r['cpu'][1]:.1f} ms = {1000 * sum(r['cpu']):.1f} ms")
        print(f"  FK x{args.configs} .npy round trip: median {ms(r['npy']):7.1f} ms, best "
              f"{1000 * min(r['npy']):7.1f} ms; array {r['shape']}, equal to the JSON "
              f"answer: {r['same']}")
        ratio = ms(r["single"]) / ms(r["health"])
        print(f"  single FK p50 {ms(r['single']):.2f} ms (p90 {ms(r['single'], 0.9):.2f}), "
              f"/health p50 {ms(r['health']):.2f} ms (p90 {ms(r['health'], 0.9):.2f}): "
              f"ratio {ratio:.2f}")
    now = results["orjson (now)"]
    before = results["stdlib json (before)"]
    print("\n== goals (orjson)")
    print(f"  FK x{args.configs} JSON median {ms(now['fk']):.1f} ms <= 80 ms: "
          f"{'PASS' if ms(now['fk']) <= 80 else 'over'} "
          f"(stdlib encoder {ms(before['fk']):.1f} ms, "
          f"{ms(before['fk']) / ms(now['fk']):.1f}x); CPU per call {1000 * sum(now['cpu']):.1f} "
          f"ms (stdlib {1000 * sum(before['cpu']):.1f} ms)")
    ratio = ms(now["single"]) / ms(now["health"])
    print(f"  single FK p50 / health p50 = {ratio:.2f} <= 1.2: "
          f"{'PASS' if ratio <= 1.2 else 'over'}")
    print(f"  load average at the end {os.getloadavg()[0]:.2f} (2 cores shared: figures noisy)")


if __name__ == "__main__":
    main()
