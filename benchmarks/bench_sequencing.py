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

A report: it exits 0 whatever the numbers. Runs the seeds on ``--workers`` processes.
``.venv/bin/python benchmarks/bench_sequencing.py [--seeds 30] [--workers 2] [--quick]``
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

PAPER_FACE = {"width": 9_800.0, "height": 7_800.0, "spacing": 470.0}  # 132 holes
PAPER_COUNTS = {"left": 40, "middle": 52, "right": 40}
PAPER_LENGTH_M = {"iga": {"left": 46.94, "middle": 64.09, "right": 44.61},
                  "aco": {"left": 48.36, "middle": 66.79, "right": 45.88}}
PAPER_AGA_PCT = {"left": 7.14, "middle": 6.99, "right": 6.75}
PAPER_MIN_DISTANCE = {"left-middle": 984.6, "middle-right": 580.8}
PAPER_PATH_M = {"iapf": 155.64, "rrt": 166.48}
ALGORITHMS = ("iga", "aco", "aga")


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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--quick", action="store_true", help="skip the 200-hole face")
    ap.add_argument("--exact-faces", type=int, default=20)
    args = ap.parse_args()
    print(f"python {platform.python_version()}, numpy {np.__version__}, "
          f"{os.cpu_count()} CPUs, {args.workers} workers")
    t0 = time.perf_counter()
    bench_sequencing(args.seeds, args.workers, args.quick)
    bench_exact(args.exact_faces)
    bench_multiarm()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
