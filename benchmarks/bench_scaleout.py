"""Scale-out: one big job on 1, 2 and 4 workers, through the service as a user runs it.

Two jobs, each submitted with ``POST /jobs`` to a service built in this process
(``TestClient(create_app(Settings(no_viewer=True, data_dir=<tmp>, jobs_backend=...,
workers=N)))``), followed with ``GET /jobs/{id}`` every 50 ms until it ends, its result read
with ``GET /jobs/{id}/result``:

* ``workspace``: ``--samples`` (20,000,000) Monte Carlo samples of ``--robot``
  (glt_palletizer), seed 271828 (no test uses it), the kind's defaults otherwise;
* ``motion``: a batch of ``--problems`` (200) moves of ``--motion-robot`` in its site of
  ``planning.motion.sites``: the pile driver in ``pile_driver_site`` (over the wall, into
  the trench; ``pile_driver_problems``) or the GLT palletizer in ``pallet_station``
  (``pallet_problems``), drawn with seed 161803 (the tests use others), the scene inline,
  planner ``rrt_connect`` (seeded; ``auto`` past 10 s and ``rrt_star`` refine until a
  clock runs out, so their paths depend on the load), 5 s per problem, problem k seeded k.

Backends (``--backends``): ``local`` with ``--workers N`` process slots; ``dask`` with a real
cluster per N: ``dask scheduler`` on a loopback port and ``python -m app.worker tcp://...
--nworkers N --nthreads 1`` (``dask worker`` with the job kinds preloaded) started as
subprocesses, waited for until N workers are connected, each
worker process warmed (the job kinds imported, the compiled kernels loaded, one step runner
of ``app.jobs.runner`` started), and both stopped afterwards; the service with
``--jobs-backend dask://127.0.0.1:PORT``. Before the timed jobs each service runs one small
job of each kind (untimed).

Printed per job and configuration:

* ``wall``: submit to succeeded, as the client sees it (50 ms polling); the median of
  ``--repeats`` (1) runs, each compared with the reference;
* ``speed-up``: wall on 1 worker of the same backend / wall;
* ``steps``: ``len(kind.steps(params))``, and ``width``: the most steps that can run at once
  (the largest level of the graph); the speed-up can reach min(workers, cores, width);
* ``overhead/step`` (1 worker only): (wall on 1 worker - inline) / steps, where inline is
  the same job run in this process by ``app.jobs.graph.run_inline(kind.steps(params),
  params, progress)`` after ``app.jobs.kinds.load_job`` (the robot model attached as the
  service does), warm, with the result checked by ``kind.result_json`` as a worker does;
* ``same``: the result against the result of the local backend with 1 worker (run even when
  not asked for: it is the reference). workspace: the whole result JSON (every key, every
  number exactly equal). motion: the number of problems and, per problem in order,
  ``status``, ``path`` (the waypoints), ``goal`` and ``trajectory.q``; nothing else is
  compared (the timing fields ``planning_time_s``, ``simplify_time_s`` and
  ``summary.median_planning_time_s`` vary from run to run; ``message``, ``length``,
  ``min_clearance``, ``stats`` and the rest of ``trajectory`` are left out too). The inline
  result is compared the same way.

A one-line verdict follows per configuration. Cores are ``os.cpu_count()``: N worker
processes on fewer than N cores cannot beat as many workers as there are cores. The machine
is shared: times are noisy.

Run: ``.venv/bin/python benchmarks/bench_scaleout.py [--samples 20000000] [--problems 200]
[--workers 1,2,4] [--backends dask,local] [--robot glt_palletizer] [--motion-robot
pile_driver] [--repeats 1] [--quick] [--json out.json]``. ``--quick``: 3,000,000 samples
and 20 problems. Unlike the other benchmarks, the exit status is 1 when a result differs
from the reference or a job does not succeed (0 otherwise).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fastapi.testclient import TestClient

# Only the standard library at import time: every process the local backend starts for a
# step (multiprocessing's forkserver) runs this file again as ``__mp_main__`` before the step,
# which ``python -m kinoplan`` does not cost; the service's and the kinds' modules are imported
# where they are used.

ROOT = Path(__file__).resolve().parents[1]
#: Seeds no test or table uses.
WORKSPACE_SEED = 271828
PROBLEM_SEED = 161803
#: Seconds of planning per problem, and the planner (seeded, not clock-bound).
MOTION_TIME_LIMIT = 5.0
MOTION_PLANNER = "rrt_connect"
#: Seconds between two GET /jobs/{id} of the client.
POLL_S = 0.05
#: Per motion problem, the fields compared (and ``trajectory.q``).
MOTION_COMPARED = ("status", "path", "goal")
#: Seconds to wait for a cluster to come up, and for its processes to stop.
CLUSTER_START_S = 120.0
STOP_GRACE_S = 10.0


# ---- the jobs ------------------------------------------------------------------------------
def workspace_params(robot: str, samples: int) -> dict:
    return {"robot": robot, "samples": samples, "seed": WORKSPACE_SEED}


def motion_params(robot: str, n: int) -> dict:
    """A batch of ``n`` site problems of ``robot`` as the params of a motion job."""
    from kinematics.library import builtin_model
    from planning.collision import RobotCollisionModel
    from planning.motion import MotionChecker
    from planning.motion.sites import (
        pallet_problems,
        pallet_station,
        pile_driver_problems,
        pile_driver_site,
    )

    model = builtin_model(robot)
    site, draw = {"pile_driver": (pile_driver_site, pile_driver_problems),
                  "glt_palletizer": (pallet_station, pallet_problems)}[robot]
    scene = site(model)
    problems = draw(MotionChecker(RobotCollisionModel.from_model(model), scene), n,
                    PROBLEM_SEED)
    return {"robot": robot, "scene": scene.to_dict(), "planner": MOTION_PLANNER,
            "time_limit": MOTION_TIME_LIMIT,
            "problems": [{"start": p.start.tolist(), "goal": {"q": p.goal.tolist()},
                          "seed": k} for k, p in enumerate(problems)]}


def shrunk(kind: str, params: dict) -> dict:
    """A small job of the same kind (the untimed warm-up)."""
    if kind == "workspace":
        return {**params, "samples": 10_000}
    return {**params, "problems": params["problems"][:2]}


# ---- comparing results ---------------------------------------------------------------------
def _motion_key(data: dict) -> list[dict]:
    return [{**{f: p.get(f) for f in MOTION_COMPARED},
             "trajectory.q": (p.get("trajectory") or {}).get("q")}
            for p in data.get("problems") or []]


def same_result(kind: str, text: str, reference: str) -> tuple[bool, str]:
    """Whether ``text`` is the same result as ``reference`` (module docstring: what is
    compared), and where it differs."""
    a, b = json.loads(text), json.loads(reference)
    if kind == "workspace":
        if a == b:
            return True, ""
        keys = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        return False, "differs in " + ", ".join(keys)
    ka, kb = _motion_key(a), _motion_key(b)
    if len(ka) != len(kb):
        return False, f"{len(ka)} problems against {len(kb)}"
    bad = [i for i, (x, y) in enumerate(zip(ka, kb)) if x != y]
    if not bad:
        return True, ""
    fields = sorted({f for i in bad for f in ka[i] if ka[i][f] != kb[i][f]})
    return False, (f"{len(bad)} problems differ (first {bad[:8]}) in "
                   f"{', '.join(fields)}")


# ---- the graph -----------------------------------------------------------------------------
def graph_shape(kind_name: str, params: dict, robot: str) -> tuple[int, int]:
    """``(steps, width)`` of the job: its step count and the most steps of one level of its
    graph (steps whose inputs are all ready at the same time)."""
    import app.jobs.catalog  # noqa: F401 - every kind registered
    from app.jobs.graph import refs_of
    from app.jobs.kinds import load_job
    from kinematics.library import builtin_model

    kind, p = load_job(kind_name, {"params": params,
                                   "robot_model": builtin_model(robot).to_dict()})
    steps = kind.steps(p)
    level: list[int] = []
    for s in steps:
        level.append(1 + max((level[j] for j in refs_of(s)), default=-1))
    return len(steps), max(Counter(level).values())


def inline(kind_name: str, params: dict, robot: str) -> tuple[float, str]:
    """The job run in this process: seconds and the result's JSON text."""
    import app.jobs.catalog  # noqa: F401 - every kind registered
    from app.jobs.graph import run_inline
    from app.jobs.kinds import load_job
    from kinematics.library import builtin_model

    t0 = time.perf_counter()
    kind, p = load_job(kind_name, {"params": params,
                                   "robot_model": builtin_model(robot).to_dict()})
    text = kind.result_json(run_inline(kind.steps(p), p, lambda f, m: None))
    return time.perf_counter() - t0, text


def warm_process() -> None:
    """Load the compiled kernels in this process (each Dask worker does the same)."""
    from kinematics.fast import warm_up as warm_kinematics
    from planning.motion import warm_up as warm_motion

    warm_kinematics()
    warm_motion()


def prime_runner() -> bool:
    """On a Dask worker: start one step runner (``app.jobs.runner``: the child process a
    step runs in) and leave it in the worker's pool, so that the first timed step does not
    wait for its start; False when this version runs steps without one."""
    try:
        from app.jobs.runner import give_back, take_runner
    except ImportError:
        return False
    give_back(take_runner())
    return True


# ---- a Dask cluster of subprocesses ---------------------------------------------------------
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_command() -> str:
    here = Path(sys.executable).parent / "dask"
    found = str(here) if here.exists() else shutil.which("dask")
    if found is None:
        raise RuntimeError("no 'dask' command: install the dask extra (pip install '.[dask]')")
    return found


def _tail(log: Path, lines: int = 15) -> str:
    try:
        return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def _start(argv: list[str], log: Path) -> subprocess.Popen:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    with open(log, "wb") as out:
        # A session of its own: stopping it reaches the worker processes its nanny started.
        return subprocess.Popen(argv, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    """SIGTERM the process group this script started, SIGKILL what is left after a grace."""
    for sig, wait in ((signal.SIGTERM, STOP_GRACE_S), (signal.SIGKILL, 5.0)):
        if proc.poll() is not None:
            break
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(wait)
        except subprocess.TimeoutExpired:
            continue
    try:  # the nanny's children, should they outlive it
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


@contextmanager
def dask_cluster(n: int, workdir: Path) -> Iterator[str]:
    """A scheduler and ``n`` single-threaded worker processes on loopback; ``HOST:PORT``."""
    from distributed import Client

    from kinematics.fast import warm_up as warm_kinematics
    from planning.motion import warm_up as warm_motion

    if __name__ != "__main__":  # imported: workers cannot import this file by name
        import cloudpickle

        cloudpickle.register_pickle_by_value(sys.modules[__name__])
    dask = _dask_command()
    port = free_port()
    address = f"127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    logs = {"scheduler": workdir / "scheduler.log", "worker": workdir / "worker.log"}
    try:
        procs.append(_start([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                             "--no-dashboard"], logs["scheduler"]))
        deadline = time.monotonic() + CLUSTER_START_S
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
                break
            except OSError:
                if procs[0].poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError("the scheduler did not start:\n"
                                       + _tail(logs["scheduler"])) from None
                time.sleep(0.2)
        # kinoplan's worker command: `dask worker` with the kinds preloaded, the step
        # runners started up front.
        procs.append(_start([sys.executable, "-m", "app.worker", f"tcp://{address}",
                             "--nworkers", str(n), "--nthreads", "1", "--no-dashboard",
                             "--local-directory", str(workdir / "dask-worker")],
                            logs["worker"]))
        with Client(f"tcp://{address}", timeout="30s", set_as_default=False) as client:
            try:
                client.wait_for_workers(n, timeout=CLUSTER_START_S)
            except TimeoutError:
                raise RuntimeError(f"{n} workers did not connect:\n"
                                   + _tail(logs["worker"])) from None
            # Package functions (pickled by reference): what warm_process does, on each.
            client.run(importlib.import_module, "app.jobs.catalog")
            client.run(warm_kinematics)
            client.run(warm_motion)
            client.run(prime_runner)
            pids = client.run(os.getpid)
        if len(set(pids.values())) != n:
            raise RuntimeError(f"expected {n} worker processes, found {len(pids)}")
        yield address
    finally:
        for proc in reversed(procs):
            _stop(proc)


# ---- the service ---------------------------------------------------------------------------
@dataclass
class Run:
    kind: str
    backend: str
    workers: int | None  # None: inline
    wall_s: float
    status: str
    text: str | None = field(default=None, repr=False)
    error: str | None = None
    attempts: int = 1
    same: bool | None = None
    diff: str = ""
    #: Every repeat's wall time and result (``wall_s``, ``text``: the median, the first).
    walls: list[float] = field(default_factory=list)
    texts: list[str] = field(default_factory=list, repr=False)


def merged(runs: list[Run]) -> Run:
    """The repeats of one job as one run: median wall time; the first failure if any."""
    bad = [r for r in runs if r.status != "succeeded"]
    if bad:
        return bad[0]
    out = runs[0]
    out.walls = [r.wall_s for r in runs]
    out.wall_s = statistics.median(out.walls)
    out.texts = [r.text for r in runs]
    out.attempts = max(r.attempts for r in runs)
    return out


@contextmanager
def service(backend: str, address: str | None, n: int, data_dir: Path
            ) -> Iterator[TestClient]:
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    jobs_backend = "local" if backend == "local" else f"dask://{address}"
    settings = Settings(no_viewer=True, data_dir=data_dir, jobs_backend=jobs_backend,
                        workers=n, api_key=None)
    # The address a user on this machine calls (the service answers loopback names only).
    with TestClient(create_app(settings), base_url="http://127.0.0.1:8000") as client:
        yield client


def submit_and_wait(client: TestClient, kind: str, params: dict, backend: str,
                    n: int) -> Run:
    """POST /jobs, poll GET /jobs/{id} until the job ends, GET its result."""
    t0 = time.perf_counter()
    for _ in range(10):
        r = client.post("/jobs", json={"kind": kind, "params": params})
        if r.status_code != 503:
            break
        time.sleep(float(r.headers.get("Retry-After", "1")))
    if r.status_code != 202:
        return Run(kind, backend, n, time.perf_counter() - t0, "rejected",
                   error=f"POST /jobs answered {r.status_code}: {r.text[:300]}")
    job_id = r.json()["id"]
    while True:
        record = client.get(f"/jobs/{job_id}").json()
        if record["status"] in ("succeeded", "failed", "cancelled"):
            break
        time.sleep(POLL_S)
    wall = time.perf_counter() - t0
    run = Run(kind, backend, n, wall, record["status"], error=record.get("error"),
              attempts=record.get("attempts", 1))
    if record["status"] == "succeeded":
        run.text = client.get(f"/jobs/{job_id}/result").text
    return run


def configuration(backend: str, n: int, jobs: dict[str, dict], repeats: int) -> list[Run]:
    """Both jobs ``repeats`` times on ``backend`` with ``n`` workers (a warm-up of each
    first)."""
    with tempfile.TemporaryDirectory(prefix="kinoplan-scaleout-") as tmp:
        tmp_path = Path(tmp)

        def run_all(address: str | None) -> list[Run]:
            with service(backend, address, n, tmp_path / "data") as client:
                for kind, params in jobs.items():
                    warm = submit_and_wait(client, kind, shrunk(kind, params), backend, n)
                    if warm.status != "succeeded":
                        return [warm]
                return [merged([submit_and_wait(client, kind, params, backend, n)
                                for _ in range(repeats)])
                        for kind, params in jobs.items()]

        if backend == "local":
            return run_all(None)
        with dask_cluster(n, tmp_path) as address:
            return run_all(address)


# ---- report --------------------------------------------------------------------------------
def verdict(run: Run, speedup: float | None, width: int, cores: int) -> str:
    """One line: failed, differs, or the speed-up against what the cores and the graph
    allow."""
    head = f"{run.kind:9s} {run.backend:6s} {run.workers} worker(s): "
    if run.status != "succeeded":
        return head + f"FAILED ({run.status}: {run.error})"
    if not run.same:
        return head + f"DIFFERS from local 1 worker: {run.diff}"
    parts = ["result identical to local 1 worker"]
    n = run.workers or 1
    if n == 1:
        parts.append("baseline")
    elif speedup is None:
        parts.append("no 1-worker run of this backend to compare with")
    else:
        ideal = min(n, cores, width)
        if width == 1:
            parts.append(f"{speedup:.2f}x: the job is one step, nothing to spread")
        elif speedup >= 0.8 * ideal:
            parts.append(f"scales: {speedup:.2f}x of at most {ideal}x")
        elif speedup >= 1.2:
            parts.append(f"partial: {speedup:.2f}x of at most {ideal}x")
        else:
            parts.append(f"no speed-up: {speedup:.2f}x of at most {ideal}x")
        if n > cores:
            parts.append(f"{n} workers on {cores} cores cannot beat {cores}")
    if run.attempts > 1:
        parts.append(f"{run.attempts} attempts")
    return head + "; ".join(parts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=20_000_000)
    ap.add_argument("--problems", type=int, default=200)
    ap.add_argument("--workers", default="1,2,4")
    ap.add_argument("--backends", default="dask,local")
    ap.add_argument("--robot", default="glt_palletizer", choices=("glt_palletizer",
                                                                   "pile_driver"))
    ap.add_argument("--motion-robot", default="pile_driver",
                    choices=("pile_driver", "glt_palletizer"))
    ap.add_argument("--repeats", type=int, default=1,
                    help="runs of each timed job per configuration (the median is shown)")
    ap.add_argument("--quick", action="store_true",
                    help="3,000,000 samples and 20 problems (a smoke run)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    if args.quick:
        args.samples, args.problems = 3_000_000, 20
    counts = sorted({int(w) for w in args.workers.split(",")})
    backends = [b.strip() for b in args.backends.split(",") if b.strip()]
    unknown = set(backends) - {"dask", "local"}
    if unknown or not counts or min(counts) < 1:
        ap.error(f"--backends takes dask and/or local, --workers positive counts "
                 f"(got {sorted(unknown) or args.workers})")
    cores = os.cpu_count() or 1

    print(f"cores (os.cpu_count()): {cores}; workers {counts}; backends {backends}")
    print(f"{cores} cores: N worker processes on {cores} cores cannot beat {cores} workers; "
          "the machine is shared, times are noisy")
    jobs = {"workspace": workspace_params(args.robot, args.samples),
            "motion": motion_params(args.motion_robot, args.problems)}
    robots = {"workspace": args.robot, "motion": args.motion_robot}
    print(f"workspace: {args.robot}, {args.samples:,} samples, seed {WORKSPACE_SEED}")
    print(f"motion:    {args.motion_robot} in its site, {len(jobs['motion']['problems'])} "
          f"problems (seed {PROBLEM_SEED}), {MOTION_PLANNER}, {MOTION_TIME_LIMIT:g} s each")
    print("compared with local 1 worker: workspace the whole result JSON; motion per problem "
          f"{', '.join(MOTION_COMPARED)}, trajectory.q (not the timing fields)")

    shape = {k: graph_shape(k, p, robots[k]) for k, p in jobs.items()}
    for k, (steps, width) in shape.items():
        print(f"{k}: {steps} step(s), at most {width} at once")

    warm_process()
    inline_runs: dict[str, Run] = {}
    for kind, params in jobs.items():
        inline(kind, shrunk(kind, params), robots[kind])  # first-use costs
        repeats = []
        for _ in range(args.repeats):
            wall, text = inline(kind, params, robots[kind])
            repeats.append(Run(kind, "inline", None, wall, "succeeded", text=text))
        inline_runs[kind] = merged(repeats)
        print(f"inline {kind}: {inline_runs[kind].wall_s:.2f} s")

    plan = [("local", n) for n in counts if "local" in backends]
    if ("local", 1) not in plan:
        plan.insert(0, ("local", 1))  # the reference
    plan += [("dask", n) for n in counts if "dask" in backends]
    runs: list[Run] = []
    for backend, n in plan:
        print(f"... {backend}, {n} worker(s)", flush=True)
        try:
            got = configuration(backend, n, jobs, args.repeats)
        except (RuntimeError, ImportError, OSError) as exc:
            got = [Run(kind, backend, n, float("nan"), "error", error=str(exc))
                   for kind in jobs]
        runs += got
        for r in got:
            note = f"{r.wall_s:.2f} s" if r.status == "succeeded" else \
                f"{r.status}: {r.error}"
            print(f"    {r.kind}: {note}", flush=True)

    reference = {r.kind: r for r in runs if r.backend == "local" and r.workers == 1}
    failed = False
    for r in [*inline_runs.values(), *runs]:
        ref = reference.get(r.kind)
        if r.status != "succeeded" or ref is None or ref.status != "succeeded":
            r.same = None
            failed = True
            continue
        checks = [same_result(r.kind, text, ref.text) for text in r.texts]
        r.same = all(ok for ok, _ in checks)
        r.diff = next((why for ok, why in checks if not ok), "")
        failed |= not r.same

    one = {(r.kind, r.backend): r.wall_s for r in runs
           if r.workers == 1 and r.status == "succeeded"}
    print(f"\n{'job':9s} {'backend':7s} {'workers':>7s} {'wall s':>8s} {'speed-up':>8s} "
          f"{'steps':>5s} {'width':>5s} {'overhead/step s':>15s}  same as local 1")
    rows = []
    for r in [*inline_runs.values(), *runs]:
        steps, width = shape[r.kind]
        base = one.get((r.kind, r.backend))
        speedup = base / r.wall_s if base and r.status == "succeeded" and r.workers else None
        overhead = ((r.wall_s - inline_runs[r.kind].wall_s) / steps
                    if r.workers == 1 and r.status == "succeeded" else None)
        same = {True: "yes", False: "NO", None: "-"}[r.same]
        if r.backend == "local" and r.workers == 1:
            same = "(reference)"
        print(f"{r.kind:9s} {r.backend:7s} {r.workers or '-':>7} {r.wall_s:8.2f} "
              f"{f'{speedup:.2f}x' if speedup else '-':>8s} {steps:5d} {width:5d} "
              f"{f'{overhead:+.3f}' if overhead is not None else '-':>15s}  {same}")
        rows.append({"kind": r.kind, "backend": r.backend, "workers": r.workers,
                     "wall_s": r.wall_s, "walls_s": r.walls, "status": r.status, "error": r.error,
                     "speedup": speedup, "steps": steps, "width": width,
                     "overhead_per_step_s": overhead, "same": r.same, "diff": r.diff,
                     "attempts": r.attempts, "result_bytes": len(r.text or "")})
        rows[-1]["verdict"] = verdict(r, speedup, width, cores) if r.workers else None

    print()
    for r, row in zip([*inline_runs.values(), *runs], rows):
        if r.workers is None:
            said = {True: "same as local 1 worker", None: "not compared (no local 1-worker "
                    "result)", False: f"DIFFERS from local 1 worker: {r.diff}"}[r.same]
            print(f"{r.kind:9s} inline: {said}")
        else:
            print(row["verdict"])
    outcome = "a result differs or a job failed" if failed else "every result identical"
    print(f"\n{cores} cores, shared: times are noisy; exit status {int(failed)} ({outcome})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cores": cores, "samples": args.samples, "problems": args.problems,
                       "robot": args.robot, "motion_robot": args.motion_robot,
                       "runs": rows}, f, indent=1, default=float)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
