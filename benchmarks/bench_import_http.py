"""The UR5 and the Panda imported over HTTP, checked against independent references.

Starts the service (a fresh data directory, a free port), uploads ``../shared/robots/ur5``
and ``../shared/robots/panda`` as zip archives with their SRDFs (``POST /robots/import``),
then on ``--configs`` random in-limit configurations (seed ``--seed``, used nowhere else):

* FK through ``POST /robots/{id}/fk`` against yourdfpy reading the same URDF (root link to
  the chain's tip), in mm;
* self-collision at the SRDF's rules through ``POST /robots/{id}/collision`` against
  python-fcl on the meshes (the reference of ``bench_collision.py``, written without the
  service's checker): false "free" answers (must be 0), false "collides" answers, and the
  time per query, one configuration per request and in one request of all of them;
* every MotionBenchMaker scene of ``../shared/mbm-dev`` stored as a MoveIt planning scene
  (``POST /scenes``), read back as MoveIt (``GET /scenes/{id}?format=moveit``), stored again:
  the largest difference between the two object lists (poses and sizes, mm);
* a restart: the service started again on the same data directory answers the same FK.

Run: ``.venv/bin/python benchmarks/bench_import_http.py [--configs 1000] [--seed 20261201]``.
A report: the exit status is 0 in any case.
"""

from __future__ import annotations

import argparse
import logging
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import yaml
import yourdfpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_collision import Reference, zip_folder  # noqa: E402

from kinematics.urdf_import import import_robot  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared"
ROBOTS = (("ur5", "manipulator"), ("panda", "panda_arm"))
ROOT = Path(__file__).resolve().parents[1]
logging.getLogger("yourdfpy").setLevel(logging.ERROR)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_service(data_dir: str, port: int, workers: int | None = None) -> subprocess.Popen:
    """``python -m kinoplan`` on ``port`` (no viewer; ``workers`` compute workers, default
    the service's), once ``/health`` answers."""
    cmd = [sys.executable, "-m", "kinoplan", "--port", str(port), "--no-viewer",
           "--data-dir", data_dir]
    if workers is not None:
        cmd += ["--compute-workers", str(workers)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env={**os.environ, "PYTHONPATH": str(ROOT)})
    for _ in range(1200):   # a first start on a machine compiles kernels: up to minutes
        try:
            if httpx.get(f"http://127.0.0.1:{port}/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    proc.kill()
    raise RuntimeError("the service did not start")


def reference_fk(urdf: Path, names: list[str], scale: np.ndarray, root: str, tip: str,
                 Q: np.ndarray) -> np.ndarray:
    robot = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_collision_scene_graph=False,
                               load_collision_meshes=False)
    out = np.empty((len(Q), 4, 4))
    for k, q in enumerate(Q):
        robot.update_cfg({n: float(v) for n, v in zip(names, q * scale)})
        out[k] = robot.get_transform(tip, root)
    out[:, :3, 3] *= 1000.0
    return out


def moveit_round_trips(client: httpx.Client) -> None:
    """Every MotionBenchMaker scene in, out as MoveIt, in again: the largest difference."""
    files = sorted((SHARED / "mbm-dev").glob("*/*/scene*.yaml"))
    worst, t0 = 0.0, time.perf_counter()
    for k, path in enumerate(files):
        moveit = yaml.safe_load(path.read_text())
        first = client.post("/scenes", json={"id": f"mbm{k}", "moveit": moveit})
        back = client.get(f"/scenes/mbm{k}", params={"format": "moveit"})
        again = client.post("/scenes", json={"id": f"mbm{k}b", "moveit": back.json()})
        if first.status_code != 201 or again.status_code != 201:
            print(f"{path}: {first.status_code} / {again.status_code}")
            continue
        for a, b in zip(first.json()["objects"], again.json()["objects"], strict=True):
            assert a["type"] == b["type"] and a["id"] == b["id"]
            for key in ("pose", "size", "radius", "height"):
                if key in a:
                    worst = max(worst, float(np.abs(np.subtract(a[key], b[key])).max()))
    print(f"MoveIt scenes over HTTP: {len(files)} MotionBenchMaker scenes stored, read back as "
          f"MoveIt and stored again in {time.perf_counter() - t0:.1f} s; largest difference "
          f"{worst:.1e} mm")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--configs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=20261201)
    ap.add_argument("--sections", default="scenes,robots",
                    help="comma-separated: scenes (MoveIt round trips), robots")
    ap.add_argument("--single", type=int, default=100,
                    help="configurations sent one per request for the single-query time")
    args = ap.parse_args()

    data_dir = tempfile.mkdtemp(prefix="kinoplan-bench-")
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    proc = start_service(data_dir, port)
    client = httpx.Client(base_url=base, timeout=600)
    fk_answers = {}
    sections = set(args.sections.split(","))
    try:
        if "scenes" in sections:
            moveit_round_trips(client)
        for name, group in (ROBOTS if "robots" in sections else ()):
            folder = SHARED / "robots" / name
            archive = zip_folder(folder)
            t0 = time.perf_counter()
            r = client.post("/robots/import", files={"file": (f"{name}.zip", archive)},
                            data={"id": name, "group": group})
            import_s = time.perf_counter() - t0
            if r.status_code != 201:
                print(f"{name}: import failed {r.status_code}: {r.text[:300]}")
                continue
            model = r.json()
            joints = model["joints"]
            lo = np.array([j["lower"] for j in joints])
            hi = np.array([j["upper"] for j in joints])
            scale = np.array([1.0 if j["type"] == "revolute" else 1e-3 for j in joints])
            rng = np.random.default_rng(args.seed)
            Q = rng.uniform(lo, hi, (args.configs, len(joints)))
            print(f"\n{name}: imported over HTTP in {import_s:.2f} s, {len(joints)} joints "
                  f"({', '.join(j['name'] for j in joints)})")

            poses = np.asarray(client.post(f"/robots/{name}/fk",
                                           json={"q": Q.tolist()}).json()["poses"])
            fk_answers[name] = (Q, poses)
            robot = import_robot(archive, f"{name}.zip", robot_id=name, group=group)
            ref = reference_fk(folder / f"{name}.urdf", [j["name"] for j in joints], scale,
                               robot.root_link, robot.tip_link, Q)
            dp = np.linalg.norm(poses[:, :3, 3] - ref[:, :3, 3], axis=1).max()
            dR = np.abs(poses[:, :3, :3] - ref[:, :3, :3]).max()
            print(f"  FK over HTTP vs yourdfpy ({robot.root_link} -> {robot.tip_link}), "
                  f"{args.configs} configurations: max position error {dp:.2e} mm, max "
                  f"rotation entry error {dR:.2e}  {'PASS' if dp <= 1e-9 else 'FAIL'} (1e-9 mm)")

            # Self-collision: one request for the whole batch (the first builds the model).
            t0 = time.perf_counter()
            client.post(f"/robots/{name}/collision", json={"q": Q[0].tolist()})
            first_s = time.perf_counter() - t0
            t0 = time.perf_counter()
            res = client.post(f"/robots/{name}/collision", json={"q": Q.tolist()}).json()
            batch_s = time.perf_counter() - t0
            ours = np.array([x["collides"] for x in res["results"]])
            t0 = time.perf_counter()
            for q in Q[:args.single]:
                client.post(f"/robots/{name}/collision", json={"q": q.tolist()})
            single_s = (time.perf_counter() - t0) / args.single

            reference = Reference(robot)
            link_poses = robot.link_poses(Q)
            t0 = time.perf_counter()
            theirs = np.array([reference.collides(P) for P in link_poses])
            fcl_s = (time.perf_counter() - t0) / len(Q)
            false_free = int(np.sum(theirs & ~ours))
            false_hit = int(np.sum(~theirs & ours))
            print(f"  self-collision at the SRDF rules: {theirs.mean():.1%} collide (FCL); "
                  f"false free {false_free} {'PASS' if false_free == 0 else 'FAIL'}, "
                  f"false collides {false_hit} ({false_hit / max(1, (~theirs).sum()):.2%} "
                  f"of free; at most 2 %)")
            print(f"  time per configuration: HTTP one per request {single_s * 1e3:.2f} ms, "
                  f"HTTP batch of {len(Q)} {batch_s / len(Q) * 1e6:.0f} us; python-fcl "
                  f"in-process {fcl_s * 1e6:.0f} us; first query (model load or build) "
                  f"{first_s:.1f} s")
    finally:
        client.close()
        proc.terminate()
        proc.wait(10)

    proc = start_service(data_dir, port)
    try:
        with httpx.Client(base_url=base, timeout=600) as client:
            for name, (Q, poses) in fk_answers.items():
                again = np.asarray(client.post(f"/robots/{name}/fk",
                                               json={"q": Q.tolist()}).json()["poses"])
                same = "identical" if np.array_equal(again, poses) else "DIFFERS"
                print(f"{name} after a restart: FK {same}")
    finally:
        proc.terminate()
        proc.wait(10)


if __name__ == "__main__":
    main()
