"""Bounded work and bounded storage, measured on real robots: the figures of the hardening.

1. **Plans at the finest resolution keep their time limit, and stay exact.** The Panda's
   MotionBenchMaker problems (``../shared/mbm-dev/panda``, the first ``--limit`` of each
   family; seeds from ``--seed``, which no table of the planner shares), planned in this
   process as the synchronous endpoint plans them (trajectory and clearance included) with
   ``time_limit`` ``--time-limit``: first at the default resolution 0.01 rad (the reference
   run), then at the floor 1e-4 rad (0.01 mm on prismatic joints). Printed for each: solved,
   median / p95 / largest answer time, how many answers came later than ``time_limit + 1 s``,
   and the fraction of answered paths that an independent python-fcl check on the exact
   meshes (``bench_motion.verify``: FK recomputed, every state at most ``--step`` rad apart,
   the end points and joint limits to 1e-9) finds free.
2. **A finished job keeps its result, not its payload.** The UR5 of ``../shared/robots`` is
   imported into a service in a scratch store, ``--jobs`` one-problem motion jobs run to the
   end, and the store is compacted: printed, the payload each job carried while it was queued
   (what every finished job kept before) beside what each finished job adds to the store
   now, and their ratio.

    .venv/bin/python benchmarks/bench_hardening.py            # both, about 2 minutes
    .venv/bin/python benchmarks/bench_hardening.py --limit 2  # fewer problems
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mbm_problems as mbm  # noqa: E402
from bench_collision import Reference, mbm_scene  # noqa: E402
from bench_motion import verify  # noqa: E402
from bench_urdf_import import zip_folder  # noqa: E402

from planning.collision import CollisionScene, RobotCollisionModel  # noqa: E402
from planning.motion import MIN_RESOLUTION, MotionChecker, plan_motion, warm_up  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared"


def plans(args) -> None:
    robot = mbm.import_named("panda")
    names = [j.name for j in robot.model.joints]
    problems = mbm.load_problems(SHARED / "mbm-dev" / "panda", "panda", names, None, args.limit)
    cm = RobotCollisionModel.from_imported(robot)
    ref = Reference(robot)
    warm_up()
    print(f"== 1. Panda, {len(problems)} MotionBenchMaker problems, time_limit "
          f"{args.time_limit} s, answers verified on the meshes at {args.step} rad ==")
    print(f"{'resolution':>10} {'solved':>8} {'median s':>9} {'p95 s':>7} {'max s':>7} "
          f"{'> limit+1s':>10} {'verified':>9}")
    for resolution in (0.01, MIN_RESOLUTION):
        walls, solved, verified = [], 0, 0
        for k, p in enumerate(problems):
            objects, data = mbm_scene(p.scene_path)
            ref.set_scene(objects)
            checker = MotionChecker(cm, CollisionScene.from_moveit(data))
            t0 = time.perf_counter()
            res = plan_motion(checker, p.start, p.goal, time_limit=args.time_limit,
                              seed=args.seed + k, resolution=resolution)
            walls.append(time.perf_counter() - t0)
            if res.success:
                solved += 1
                why = verify(robot, ref, mbm.scene_ids(data), res.path, p.start, p.goal,
                             args.step)
                verified += why == ""
                if why:
                    print(f"  {p.family} {p.index}: NOT FREE: {why}")
        w = np.array(walls)
        late = int(np.sum(w > args.time_limit + 1.0))
        print(f"{resolution:>10g} {solved:>4}/{len(problems):<3} {np.median(w):>9.3f} "
              f"{np.percentile(w, 95):>7.3f} {w.max():>7.3f} {late:>10} "
              f"{verified}/{solved:<6}")


def _store_bytes(st) -> int:
    """The store's files once compacted (every free page given back)."""
    st.compact(0)
    st.health(max_age_s=0)
    return st.usage.bytes


def store(args) -> None:
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    os.environ.setdefault("KINOPLAN_ALLOWED_HOSTS", "*")
    print(f"\n== 2. UR5 (meshed, imported): {args.jobs} finished motion jobs ==")
    data_dir = Path(tempfile.mkdtemp(prefix="kinoplan-bench-"))
    api = create_app(Settings(no_viewer=True, data_dir=data_dir, workers=2,
                              prestart_compute=False))
    st = api.state.store
    with TestClient(api) as client:
        r = client.post("/robots/import", files={"file": ("ur5.zip", zip_folder(
            SHARED / "robots" / "ur5"))}, data={"id": "ur5", "group": mbm.ROBOTS["ur5"]})
        assert r.status_code == 201, r.text
        start = [0.0, -1.2, 1.2, -1.5, -1.57, 0.0]
        rng = np.random.default_rng(args.seed)
        # The collision model is built (and stored with the robot) after the import: wait for
        # it, so that the growth measured below is the jobs' alone.
        while client.post("/robots/ur5/motion", json={
                "start": start, "goal": {"q": start}, "time_limit": 0.1}).status_code == 409:
            time.sleep(0.5)
        # Both workers busy first, so every motion job waits queued with its payload.
        busy = [client.post("/jobs", json={"kind": "sleep", "params": {"seconds": 2.0}})
                .json()["id"] for _ in range(2)]
        before = _store_bytes(st)
        ids, payloads = [], []
        while len(ids) < args.jobs:
            goal = (np.array(start) + rng.uniform(-0.4, 0.4, 6)).tolist()
            r = client.post("/jobs", json={"kind": "motion", "params": {
                "robot": "ur5", "start": start, "goal": {"q": goal},
                "seed": args.seed + len(ids), "time_limit": 2}})
            assert r.status_code == 202, r.text
            ids.append(r.json()["id"])
            try:
                payloads.append(len(json.dumps(st.job_payload(ids[-1]))))
            except KeyError:           # it ended already: its payload has gone
                pass
        results = 0
        for job_id in busy + ids:
            for _ in range(1200):
                if client.get(f"/jobs/{job_id}").json()["status"] not in ("queued",
                                                                           "running"):
                    break
                time.sleep(0.1)
        for job_id in ids:
            got = client.get(f"/jobs/{job_id}/result")
            results += len(got.content) if got.status_code == 200 else 0
        after = _store_bytes(st)
        import sqlite3

        with sqlite3.connect(st.path) as conn:
            marks = ",".join("?" * len(ids))
            records = conn.execute(
                "SELECT sum(length(params_json) + length(coalesce(result_json, ''))) "
                f"FROM jobs WHERE id IN ({marks})", ids).fetchone()[0]
    per_payload = float(np.median(payloads)) if payloads else float("nan")
    per_job = (after - before) / args.jobs
    print(f"  payload a job carries while queued (kept by every finished job before): "
          f"{per_payload / 1e6:.2f} MB (median of {len(payloads)})")
    print(f"  store growth per finished job now: {per_job:,.0f} B; its record (params and "
          f"result as stored) {records / args.jobs:,.0f} B, its result as served "
          f"{results / args.jobs:,.0f} B; the payload is {per_payload / per_job:,.0f}x the growth")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=3, help="problems per family")
    ap.add_argument("--time-limit", type=float, default=0.5)
    ap.add_argument("--step", type=float, default=0.01, help="verification step, rad")
    ap.add_argument("--seed", type=int, default=73421)
    ap.add_argument("--jobs", type=int, default=20)
    ap.add_argument("--sections", default="plans,store")
    args = ap.parse_args()
    sections = args.sections.split(",")
    if "plans" in sections:
        plans(args)
    if "store" in sections:
        store(args)


if __name__ == "__main__":
    main()
