"""The synchronous motion endpoint over HTTP: what the service adds to the planner's own time.

Starts the service (a fresh data directory, a free port, ``--no-viewer``), imports the Panda
(``../shared/robots/panda`` as a zip archive with its SRDF, group ``panda_arm``,
``POST /robots/import``) and stores the MotionBenchMaker scene of every problem it runs as a
MoveIt planning scene (``POST /scenes``). Then, for the first ``--problems-per-family`` (3)
problems of each of the 7 families of ``../shared/mbm-dev/panda`` (start and goal read as
``mbm_problems.read_request`` reads them), it posts ``POST /robots/panda/motion`` with
``{"start", "goal": {"q"}, "scene", "time_limit": 2, "resolution": 0.01, "trajectory":
false}`` over one persistent ``httpx.Client``: ``--warm-up`` (1) untimed calls per problem,
then ``--repeat`` (3) calls with the scene stored (its id) and ``--repeat`` with the same
scene inline (the MoveIt body). Per call it takes the wall time seen by the client, the planner's
own time (``planning_time_s`` of the answer, of which ``simplify_time_s``) and the overhead
``wall - planning_time_s``: the request's parsing and validation, the scene's resolution,
the hand-over to a compute worker, the checker's preparation, the work after the planner's
clock stops (clearance of the path) and the answer's encoding and transfer.

Prints one line per problem (medians of its calls, stored and inline side by side), then the
median and p95 over every call and how many of the distinct paths answered are free on the
Panda's meshes (verified outside the service with python-fcl, as ``bench_motion.py`` does);
the goals of the product are a median wall of at most 10 ms
and an overhead of at most 5 ms with a stored scene. Equal seeds give equal answers unless
the search ends near the time limit (the planner's phases switch on the clock): the
benchmark reports whether every call of a problem answered the same path (``same``).

With one warm-up call, the first timed call on the service's other compute worker still
prepares the scene there; ``--warm-up 2`` (the default two workers) shows the steady state.

Run: ``.venv/bin/python benchmarks/bench_motion_http.py [--problems-per-family 3]
[--repeat 3] [--warm-up 1] [--families box,cage] [--compute-workers 2]``. A report: the
exit status is 0 in any case; about a minute.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_collision import Reference, mbm_scene  # noqa: E402
from bench_import_http import free_port, start_service  # noqa: E402
from bench_motion import verify  # noqa: E402
from bench_urdf_import import zip_folder  # noqa: E402
from mbm_problems import (  # noqa: E402
    FAMILIES,
    PANDA_FOLDER,
    SHARED,
    import_named,
    read_request,
    scene_ids,
)

ROOT = Path(__file__).resolve().parents[1]
#: The body's settings besides start, goal and scene.
SETTINGS = {"time_limit": 2.0, "resolution": 0.01, "trajectory": False}


def p95(values: list[float]) -> float:
    return float(np.percentile(values, 95)) if values else float("nan")


def timed(client: httpx.Client, body: dict) -> tuple[float, dict]:
    """Wall time (s) of one motion request and its answer."""
    t0 = time.perf_counter()
    r = client.post("/robots/panda/motion", json=body)
    wall = time.perf_counter() - t0
    if r.status_code != 200:
        raise RuntimeError(f"motion answered {r.status_code}: {r.text[:300]}")
    return wall, r.json()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--problems-per-family", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per problem and mode")
    ap.add_argument("--warm-up", type=int, default=1,
                    help="untimed calls per problem first (as many as the service has compute "
                    "workers: every worker has prepared the scene before the timed calls)")
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--compute-workers", type=int, default=None,
                    help="the service's compute workers (default: the service's)")
    args = ap.parse_args()

    # Every distinct path answered is verified here, outside the service: python-fcl on the
    # Panda's meshes (bench_motion.verify: ends, limits, every segment at 0.01 rad).
    robot = import_named("panda")
    ref = Reference(robot)
    checked: dict[str, str] = {}     # problem/path -> '' (free) or why not
    data_dir = tempfile.mkdtemp(prefix="kinoplan-bench-")
    port = free_port()
    proc = start_service(data_dir, port, args.compute_workers)
    client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=600)
    rows = []   # (name, mode, wall, planning, simplify, same)
    try:
        r = client.post("/robots/import",
                        files={"file": ("panda.zip", zip_folder(SHARED / "robots" / "panda"))},
                        data={"id": "panda", "group": "panda_arm"})
        if r.status_code != 201:
            print(f"panda: import failed {r.status_code}: {r.text[:300]}")
            return
        names = [j["name"] for j in r.json()["joints"]]
        print(f"panda imported ({len(names)} joints); {args.problems_per_family} problems per "
              f"family, {args.repeat} timed calls each with the scene stored and inline; "
              f"{SETTINGS}")
        print(f"{'problem':<26} {'objects':>7} | {'stored: wall':>12} {'plan':>6} "
              f"{'simpl':>6} {'over':>6} | {'inline: wall':>12} {'plan':>6} {'over':>6} "
              f"| same  (ms, medians)")
        for family in args.families.split(","):
            requests = sorted((PANDA_FOLDER / family).glob("request*.yaml"))
            for req in requests[:args.problems_per_family]:
                index = int(req.stem.removeprefix("request"))
                moveit = yaml.safe_load((PANDA_FOLDER / family /
                                         f"scene{index:04d}.yaml").read_text())
                scene_id = f"{family}-{index:04d}"
                stored = client.post("/scenes", json={"id": scene_id, "moveit": moveit})
                if stored.status_code != 201:
                    print(f"{scene_id}: scene not stored {stored.status_code}")
                    continue
                n_objects = len(stored.json()["objects"])
                start, goal, _ = read_request(req, names)
                body = {"start": start.tolist(), "goal": {"q": goal.tolist()}, **SETTINGS}
                for _ in range(max(1, args.warm_up)):                  # untimed
                    _, first = timed(client, {**body, "scene": scene_id})
                line = {}
                paths = [first["path"]]
                for mode, scene in (("stored", scene_id), ("inline", {"moveit": moveit})):
                    calls = []
                    for _ in range(args.repeat):
                        wall, ans = timed(client, {**body, "scene": scene})
                        paths.append(ans["path"])
                        calls.append((wall, ans["planning_time_s"], ans["simplify_time_s"]))
                        rows.append((scene_id, mode, *calls[-1], ans["status"]))
                    line[mode] = [statistics.median(c[k] for c in calls) for k in range(3)]
                same = all(p == paths[0] for p in paths)
                objects, scene_data = mbm_scene(PANDA_FOLDER / family / f"scene{index:04d}.yaml")
                ref.set_scene(objects)
                ids = scene_ids(scene_data)
                for k, path in enumerate(p for i, p in enumerate(paths) if p not in paths[:i]):
                    checked[f"{scene_id}#{k}"] = verify(robot, ref, ids, np.array(path), start,
                                                        goal, 0.01) if path else "no path"
                s, i = line["stored"], line["inline"]
                print(f"{family + '/' + f'{index:04d}':<26} {n_objects:>7} | "
                      f"{s[0] * 1e3:12.2f} {s[1] * 1e3:6.2f} {s[2] * 1e3:6.2f} "
                      f"{(s[0] - s[1]) * 1e3:6.2f} | {i[0] * 1e3:12.2f} {i[1] * 1e3:6.2f} "
                      f"{(i[0] - i[1]) * 1e3:6.2f} | {'yes' if same else 'NO'}  "
                      f"({first['status']})")
    finally:
        client.close()
        proc.terminate()
        proc.wait(10)

    print()
    for mode in ("stored", "inline"):
        sel = [r for r in rows if r[1] == mode]
        if not sel:
            continue
        wall = [r[2] for r in sel]
        plan = [r[3] for r in sel]
        simp = [r[4] for r in sel]
        over = [r[2] - r[3] for r in sel]
        print(f"scene {mode:<6} ({len(sel)} calls), ms median / p95: wall "
              f"{statistics.median(wall) * 1e3:.2f} / {p95(wall) * 1e3:.2f}, planner "
              f"{statistics.median(plan) * 1e3:.2f} / {p95(plan) * 1e3:.2f} (simplify "
              f"{statistics.median(simp) * 1e3:.2f} / {p95(simp) * 1e3:.2f}), overhead "
              f"{statistics.median(over) * 1e3:.2f} / {p95(over) * 1e3:.2f}")
    bad = {k: why for k, why in checked.items() if why}
    print(f"distinct paths answered: {len(checked)}, free on the meshes (python-fcl, 0.01 rad): "
          f"{len(checked) - len(bad)}" + "".join(f"\n  NOT FREE {k}: {why}"
                                               for k, why in bad.items()))
    stored = [r for r in rows if r[1] == "stored"]
    if stored:
        wall = statistics.median(r[2] for r in stored)
        over = statistics.median(r[2] - r[3] for r in stored)
        print(f"goals (stored scene): median wall {wall * 1e3:.2f} ms "
              f"{'PASS' if wall <= 0.010 else 'over'} (<= 10 ms); median overhead "
              f"{over * 1e3:.2f} ms {'PASS' if over <= 0.005 else 'over'} (<= 5 ms)")


if __name__ == "__main__":
    main()
