"""Benchmark paper 002's drilling planners: hole sequencing (IGA vs ACO vs AGA, and our
``auto``) and the multi-arm face plan (IAPF vs RRT).

1. Sequencing, 30 seeds per algorithm (``--seeds``), on the paper's hole counts: a
   9.8 m x 7.8 m horseshoe face of 132 holes allocated 40 / 52 / 40 to the left, middle and
   right arms (section 5), each sequenced from its arm's park position; and a 200-hole face
   sequenced as one. Mean, best, worst and standard deviation of the path length per
   algorithm, how much longer ACO and AGA are than IGA next to the paper's figures (ACO
   +3.03 / +4.21 / +2.85 %, AGA +7.14 / +6.99 / +6.75 %), and ``auto`` against the best path
   any run found.
2. ``auto`` against the exact optimum (Held-Karp) on random faces of 8-12 holes.
3. The whole 132-hole face planned with IAPF and with RRT-Connect (raw, and with 50 random
   shortcuts): success, collisions at the 10 ms check, the minimum envelope distance per arm
   pair (paper: 984.6 mm middle-left, 580.8 mm middle-right), total tool path (paper: IAPF
   155.64 m, RRT 166.48 m) and the peak rotational joint acceleration (paper: below
   0.25 rad/s^2).

4. ``auto`` beside LKH (``elkai``, the ``bench`` extra) on random holes on a 10 m x 7 m face
   (200, 1,000 and 2,000 holes; instance seeds ``LKH_SEEDS``, never used while tuning the
   search), each from a start 0.5 m below the face: path length ratio and time of both.
   The open path goes to LKH as a matrix with a dummy node tied to the start.
5. Boom time on a jumbo face (``face_pattern()``, allocated to the three arms): each arm's
   holes ordered by tool path and by boom travel time (IK branches at five roll values
   chosen with the order; ``planning.drilling.boom_time``), from its park pose: the boom
   time of both orders and the saving, also with the roll held at 0 and with the
   multi-arm planner's transfer limits.

A report: it exits 0 whatever the numbers. Runs the seeds on ``--workers`` processes.
``.venv/bin/python benchmarks/bench_sequencing.py [--seeds 30] [--workers 2] [--quick]
[--sections paper,exact,multiarm,lkh,boom]``. Timing figures depend on the machine's load.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from kinematics.fk import fk
from kinematics.rigs import builtin_rig
from planning.drilling.allocation import allocate_holes
from planning.drilling.multiarm import (
    PAPER_ACCELERATION_BOUND,
    ROTATIONAL_JOINTS,
    park_configuration,
    plan_face,
)
from planning.drilling.patterns import face_pattern
from planning.sequencing import SequencingProblem, held_karp, sequence_holes
from planning.sequencing.auto import default_time_limit
from planning.sequencing.oropt import HAVE_NUMBA, warm_up

PAPER_FACE = {"width": 9_800.0, "height": 7_800.0, "spacing": 470.0}  # 132 holes
PAPER_COUNTS = {"left": 40, "middle": 52, "right": 40}
PAPER_LENGTH_M = {"iga": {"left": 46.94, "middle": 64.09, "right": 44.61},
                  "aco": {"left": 48.36, "middle": 66.79, "right": 45.88}}
PAPER_AGA_PCT = {"left": 7.14, "middle": 6.99, "right": 6.75}
PAPER_MIN_DISTANCE = {"left-middle": 984.6, "middle-right": 580.8}
PAPER_PATH_M = {"iapf": 155.64, "rrt": 166.48}
ALGORITHMS = ("iga", "aco", "aga")
#: Random-hole instances compared with LKH: size -> instance seeds (never used in tuning).
LKH_SEEDS = {200: (7201, 7202, 7203), 1000: (7301, 7302), 2000: (7401,)}
#: LKH runs per instance (its own restarts): ten on 200 holes, one above (minutes each).
LKH_RUNS = {200: 10, 1000: 1, 2000: 1}
SECTIONS = ("paper", "exact", "multiarm", "lkh", "boom")


def _run(job):
    holes, start, alg, seed, params = job
    r = sequence_holes(holes, start, alg, seed, params)
    return r.length, r.runtime_s


def faces() -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, holes, start) of every sequencing problem."""
    rig = builtin_rig("tunnel_jumbo")
    face = face_pattern(**PAPER_FACE)
    alloc = allocate_holes(rig, face.holes, counts=PAPER_COUNTS)
    out = []
    for arm in ("left", "middle", "right"):
        start = fk(rig.arms[arm], park_configuration(rig, arm, face.spec.face_x))[:3, 3]
        out.append((arm, face.holes[alloc.indices[arm]], start))
    spacing = min(range(330, 420, 5), key=lambda s: abs(len(face_pattern(spacing=s).holes) - 200))
    big = face_pattern(spacing=float(spacing))
    start = fk(rig.arms["middle"], park_configuration(rig, "middle", 9000.0))[:3, 3]
    out.append((f"whole face ({spacing} mm)", big.holes, start))
    return out


def bench_sequencing(seeds: int, workers: int, quick: bool) -> None:
    print("== 1. Sequencing: open path from the arm's park position, mean of "
          f"{seeds} seeds ==")
    problems = faces()
    if quick:
        problems = problems[:3]
    for name, holes, start in problems:
        n = len(holes)
        t0 = time.perf_counter()
        stats = {}
        with ProcessPoolExecutor(workers) as pool:
            for alg in ALGORITHMS:
                res = list(pool.map(_run, [(holes, start, alg, s, None) for s in range(seeds)]))
                L = np.array([r[0] for r in res]) / 1000.0
                stats[alg] = (L, np.mean([r[1] for r in res]))
            auto = list(pool.map(_run, [(holes, start, "auto", s, None)
                                        for s in range(min(seeds, 5))]))
        La = np.array([r[0] for r in auto]) / 1000.0
        best = min(La.min(), *(v[0].min() for v in stats.values()))
        print(f"\n{name}: {n} holes ({time.perf_counter() - t0:.0f} s wall)")
        print(f"  {'algorithm':9s} {'mean m':>8s} {'best m':>8s} {'worst m':>8s} {'std m':>6s} "
              f"{'vs IGA':>7s} {'vs best':>8s} {'time s':>7s}")
        iga = stats["iga"][0].mean()
        for alg, (L, rt) in stats.items():
            print(f"  {alg:9s} {L.mean():8.2f} {L.min():8.2f} {L.max():8.2f} {L.std():6.2f} "
                  f"{100 * (L.mean() / iga - 1):+6.2f}% {100 * (L.mean() / best - 1):+7.2f}% "
                  f"{rt:7.2f}")
        rt = np.mean([r[1] for r in auto])
        print(f"  {'auto':9s} {La.mean():8.2f} {La.min():8.2f} {La.max():8.2f} {La.std():6.2f} "
              f"{100 * (La.mean() / iga - 1):+6.2f}% {100 * (La.mean() / best - 1):+7.2f}% "
              f"{rt:7.2f}   ({len(La)} seeds)")
        if name in PAPER_AGA_PCT:
            p_iga, p_aco = PAPER_LENGTH_M["iga"][name], PAPER_LENGTH_M["aco"][name]
            print(f"  paper ({name} arm, its own face): IGA {p_iga} m, ACO {p_aco} m "
                  f"({100 * (p_aco / p_iga - 1):+.2f}%), AGA {PAPER_AGA_PCT[name]:+.2f}%; "
                  f"ours: ACO {100 * (stats['aco'][0].mean() / iga - 1):+.2f}%, AGA "
                  f"{100 * (stats['aga'][0].mean() / iga - 1):+.2f}%")


def bench_exact(count: int) -> None:
    print("\n== 2. auto vs the exact optimum (Held-Karp), random faces ==")
    rng = np.random.default_rng(0)
    gaps, ils_gaps, times = [], [], []
    for k in range(count):
        n = int(rng.integers(8, 13))
        H = np.c_[np.full(n, 9000.0), rng.uniform(-3000, 3000, n), rng.uniform(0, 6000, n)]
        p = SequencingProblem.from_holes(H, [9000.0, 0.0, 0.0])
        _, opt = held_karp(p)
        t0 = time.process_time()
        a = sequence_holes(H, [9000.0, 0.0, 0.0], "auto", seed=k)
        times.append(time.process_time() - t0)
        b = sequence_holes(H, [9000.0, 0.0, 0.0], "auto", seed=k, params={"exact_max": 0})
        gaps.append(a.length / opt - 1)
        ils_gaps.append(b.length / opt - 1)
    print(f"  {count} faces of 8-12 holes: auto (exact DP) max gap {100 * max(gaps):.4f} %, "
          f"mean CPU {1000 * np.mean(times):.1f} ms; its local search alone: max gap "
          f"{100 * max(ils_gaps):.4f} %, optimal on "
          f"{sum(g < 1e-9 for g in ils_gaps)}/{count}")
    H = np.c_[np.full(52, 9000.0), rng.uniform(-3000, 3000, 52), rng.uniform(0, 6000, 52)]
    t0 = time.process_time()
    sequence_holes(H, [9000.0, 0.0, 0.0], "auto", seed=0)
    print(f"  auto on 52 random holes: {time.process_time() - t0:.2f} s CPU (target < 1 s)")


def bench_multiarm() -> None:
    print("\n== 3. Whole face, 132 holes (40 / 52 / 40), three arms ==")
    rig = builtin_rig("tunnel_jumbo")
    face = face_pattern(**PAPER_FACE)
    alloc = allocate_holes(rig, face.holes, counts=PAPER_COUNTS)
    totals = {}
    for label, planner, params in (("IAPF", "iapf", None), ("RRT-Connect", "rrt", None),
                                   ("RRT-Connect + 50 shortcuts", "rrt", {"shortcut": 50})):
        fp = plan_face(rig, None, allocation=alloc, planner=planner, planner_params=params,
                       seed=0)
        totals[label] = fp.tool_path_m()
        acc = max(fp.accelerations[a][list(ROTATIONAL_JOINTS)].max() for a in fp.arms)
        print(f"\n  {label}: success {fp.success}, collisions {fp.total_collisions} "
              f"(10 ms check, {len(fp.t)} samples), {fp.runtime_s:.1f} s, middle arm parks: "
              f"{fp.middle_park}")
        for msg in fp.messages[:5]:
            print(f"    ! {msg}")
        for pair, d in fp.min_distance.items():
            paper = PAPER_MIN_DISTANCE.get(pair)
            extra = f" (paper {paper} mm)" if paper else ""
            print(f"    min distance {pair}: {d.min():7.1f} mm{extra}")
        for a, ap in fp.arms.items():
            print(f"    {a:6s}: {len(ap.order)} holes, straight sequence "
                  f"{ap.sequence_length_m:6.2f} m, tool path {ap.tool_path_m:6.2f} m, "
                  f"planners {ap.planner_counts}, "
                  f"peak rotational acc {fp.accelerations[a][list(ROTATIONAL_JOINTS)].max():.3f}"
                  f" rad/s^2, feed {fp.accelerations[a][6]:.0f} mm/s^2")
        print(f"    total tool path {fp.tool_path_m():.2f} m; peak rotational acceleration "
              f"{acc:.3f} rad/s^2 (paper bound {PAPER_ACCELERATION_BOUND})")
    base = totals["IAPF"]
    print(f"\n  total tool path: IAPF {base:.2f} m, RRT {totals['RRT-Connect']:.2f} m "
          f"({100 * (totals['RRT-Connect'] / base - 1):+.1f} %), RRT + shortcuts "
          f"{totals['RRT-Connect + 50 shortcuts']:.2f} m "
          f"({100 * (totals['RRT-Connect + 50 shortcuts'] / base - 1):+.1f} %); paper: IAPF "
          f"{PAPER_PATH_M['iapf']} m, RRT {PAPER_PATH_M['rrt']} m "
          f"({100 * (PAPER_PATH_M['rrt'] / PAPER_PATH_M['iapf'] - 1):+.1f} %)")


def random_holes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` holes uniform on a 10 m x 7 m face at x = 9000 mm, and a start 0.5 m below it."""
    rng = np.random.default_rng(seed)
    H = np.c_[np.full(n, 9000.0), rng.uniform(-5000, 5000, n), rng.uniform(-3500, 3500, n)]
    return H, np.array([9000.0, 0.0, -4000.0])


def lkh_open_path(holes: np.ndarray, start: np.ndarray, runs: int) -> tuple[float, float]:
    """LKH (elkai) on the open path from ``start``: a dummy node at a large cost from every
    hole and 0 from the start closes the tour. Distances in 0.01 mm integers (LKH's
    precision factor keeps them well inside 32 bits). Returns (length mm, seconds)."""
    import elkai

    Y = np.vstack([start[None], holes])
    N = len(Y)
    D = np.linalg.norm(Y[:, None] - Y[None], axis=-1)
    M = np.zeros((N + 1, N + 1))
    M[:N, :N] = D
    M[N, :] = M[:, N] = 3.0 * D.max()
    M[N, 0] = M[0, N] = M[N, N] = 0.0
    t0 = time.perf_counter()
    tour = elkai.DistanceMatrix(np.rint(M * 100).astype(np.int64).tolist()).solve_tsp(runs=runs)
    dt = time.perf_counter() - t0
    tour = tour[:-1] if tour[0] == tour[-1] else tour
    k = tour.index(0)
    tour = tour[k:] + tour[:k]
    if tour[1] == N:
        tour = [tour[0]] + tour[1:][::-1]
    if tour[-1] != N:
        raise RuntimeError("LKH broke the start's tie to the dummy node")
    path = Y[tour[:-1]]
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()), dt


def bench_lkh(sizes: tuple[int, ...]) -> list[tuple[int, int, float, float, float, float]]:
    print("\n== 4. auto vs LKH (elkai) on random holes, 10 m x 7 m face ==")
    try:
        import elkai  # noqa: F401
    except ImportError:
        print("  elkai is not installed (pip install elkai): skipped")
        return []
    t0 = time.perf_counter()
    compiled = warm_up()
    print(f"  numba {'on' if HAVE_NUMBA else 'MISSING (plain Python)'}; compiled or loaded "
          f"the search in {compiled:.2f} s (first run on a machine compiles, later ones load "
          f"numba's cache); process start to ready {time.perf_counter() - t0:.2f} s")
    print(f"  {'holes':>5s} {'seed':>5s} {'auto m':>9s} {'auto s':>7s} {'limit s':>7s} "
          f"{'stopped':>10s} {'LKH m':>9s} {'LKH s':>7s} {'runs':>4s} {'ratio':>8s}")
    rows = []
    for n in sizes:
        for seed in LKH_SEEDS[n]:
            H, start = random_holes(n, seed)
            t = time.perf_counter()
            res = sequence_holes(H, start, "auto", seed=0)
            ours_s = time.perf_counter() - t
            lkh, lkh_s = lkh_open_path(H, start, LKH_RUNS[n])
            rows.append((n, seed, res.length, ours_s, lkh, lkh_s))
            print(f"  {n:5d} {seed:5d} {res.length / 1000:9.3f} {ours_s:7.2f} "
                  f"{default_time_limit(n):7.1f} {res.extra['stopped']:>10s} "
                  f"{lkh / 1000:9.3f} {lkh_s:7.1f} {LKH_RUNS[n]:4d} {res.length / lkh:8.5f}",
                  flush=True)
    targets = {200: (1.001, 1.0), 1000: (1.01, 5.0), 2000: (1.02, 20.0)}
    for n in sizes:
        r = [x for x in rows if x[0] == n]
        worst = max(x[2] / x[4] for x in r)
        slowest = max(x[3] for x in r)
        goal, secs = targets[n]
        print(f"  {n} holes: worst ratio {worst:.5f} (target <= {goal}), slowest "
              f"{slowest:.2f} s (target <= {secs:g} s)")
    return rows


def bench_boom(seed: int = 0) -> None:
    print("\n== 5. Boom travel time on a jumbo face (face_pattern(), 3 arms) ==")
    from planning.drilling.boom_time import BoomTime, drill_branches, sequence_by_boom_time
    from planning.drilling.multiarm import MotionLimits

    rig = builtin_rig("tunnel_jumbo")
    face = face_pattern()
    alloc = allocate_holes(rig, face.holes)
    limits = MotionLimits()
    print(f"  {len(face.holes)} holes; boom time = max over joints of |dq| / v (swing, pitch "
          "0.2 rad/s, telescope 400 mm/s, roll 0.5 rad/s, compensation 0.3 rad/s); "
          "'planner' = swing, pitch, telescope at the multi-arm transfer limits with "
          "accelerations, roll 0")
    print(f"  {'arm':6s} {'holes':>5s} {'model':>14s} {'distance s':>10s} {'time s':>8s} "
          f"{'saved s':>8s} {'saved':>7s} {'path +':>7s} {'run s':>6s}")
    totals: dict[str, list[float]] = {}
    for arm in rig.arms:
        model = rig.arms[arm]
        H = face.holes[alloc.indices[arm]]
        park = park_configuration(rig, arm, face.spec.face_x)
        Q = drill_branches(model, H)
        cases = (("5 roll branches", Q, BoomTime.for_model(model)),
                 ("roll 0", Q[:, :1], BoomTime.for_model(model)),
                 ("planner", Q[:, :1], BoomTime.planned_joints(model, limits.velocity,
                                                               limits.acceleration)))
        for label, branches, timing in cases:
            t = time.perf_counter()
            r = sequence_by_boom_time(model, H, q_start=park, branches=branches,
                                      timing=timing, seed=seed)
            dt = time.perf_counter() - t
            acc = totals.setdefault(label, [0.0, 0.0])
            acc[0] += r.distance_time_s
            acc[1] += r.time_s
            print(f"  {arm:6s} {len(H):5d} {label:>14s} {r.distance_time_s:10.1f} "
                  f"{r.time_s:8.1f} {r.saved_s:8.1f} {100 * r.saved_s / r.distance_time_s:6.1f}%"
                  f" {100 * (r.length / r.distance_length - 1):6.1f}% {dt:6.2f}")
    for label, (d, t) in totals.items():
        print(f"  all arms, {label}: {d:.1f} s by the shortest paths, {t:.1f} s by boom time: "
              f"{d - t:.1f} s ({100 * (d - t) / d:.1f} %) saved")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--quick", action="store_true", help="skip the 200-hole face and, in "
                    "the LKH comparison, the 2,000-hole instance")
    ap.add_argument("--exact-faces", type=int, default=20)
    ap.add_argument("--sections", default=",".join(SECTIONS),
                    help=f"comma-separated, of {', '.join(SECTIONS)}")
    args = ap.parse_args()
    sections = [x.strip() for x in args.sections.split(",") if x.strip()]
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        ap.error(f"unknown sections {sorted(unknown)}; known: {', '.join(SECTIONS)}")
    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"{os.cpu_count()} CPUs, {args.workers} workers")
    t0 = time.perf_counter()
    if "paper" in sections:
        bench_sequencing(args.seeds, args.workers, args.quick)
    if "exact" in sections:
        bench_exact(args.exact_faces)
    if "multiarm" in sections:
        bench_multiarm()
    if "lkh" in sections:
        bench_lkh((200, 1000) if args.quick else (200, 1000, 2000))
    if "boom" in sections:
        bench_boom()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
