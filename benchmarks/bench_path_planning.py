"""Benchmark the path planners of paper 000 (section 4) side by side, with OMPL's RRT*.

For each scene, in one run:

1. improved vs basic wolf pack with Table 2's parameters over ``--runs`` seeds (paper: the
   improved one's average path is 16.575 % shorter, Table 4): mean length of the optimisers'
   own paths (what the paper compares) and after our shortcutting, mean time;
2. the paper's baselines (GA, ACA, AFSA) with its printed parameters, same seeds;
3. ``auto`` (visibility graph + tightening) against the certified shortest path (a fine
   visibility graph), and our RRT*;
4. OMPL's RRT* (``pip install ompl``, the ``bench`` extra) given the same wall time as
   ``auto`` and as our RRT*, with our exact segment check as its motion validator; its path
   is verified with the same exact check;
5. ``many``: ``auto`` among 10, 100 and 1,000 spheres (radius 10-30 mm, jittered +-30 mm)
   on a 1 m cube's diagonal, from [40, 40, 40] to [960, 960, 960] mm, margin 1 mm: wall and
   CPU time, length, peak traced memory of the call (tracemalloc, a second run) and the
   process's peak resident memory, against OMPL's InformedRRT* given ``--ompl-seconds`` (5)
   with the same exact checks. Goals: 100 spheres within 1 s, 1,000 within 10 s, each path
   within 1 % of OMPL's. The detour (length over the straight line) is printed too: the
   paths differ from the straight line by about 1 %, so the detour ratio says more.

Scenes: paper 000's toy setup (100 mm cube, start [1, 1, 1], goal [100, 100, 100], five
spheres; the paper does not print where, ours are the tests' seeded layouts across the
diagonal) and a tool-only arm scene at pile_driver's scale (the tests' reachable endpoints,
two spheres). It is a report: the exit status is 0 whatever the numbers.

Run: ``.venv/bin/python benchmarks/bench_path_planning.py [--runs 30] [--scenes toy0,arm,many]
[--many 10,100,1000] [--ompl-seconds 5]``
"""

from __future__ import annotations

import argparse
import platform
import resource
import time
import tracemalloc

import numpy as np

from planning.paths import path_length, plan_path
from planning.paths.auto import certified_shortest_path
from planning.paths.compare import toy_scene
from planning.paths.scene import Scene

START, GOAL = np.array([1.0, 1.0, 1.0]), np.array([100.0, 100.0, 100.0])
PAPER_TABLE4 = {"improved": 3832.23, "basic": 4593.62}  # average path, mm



def arm_scene() -> tuple[Scene, np.ndarray, np.ndarray]:
    """pile_driver tool positions at q = (-0.9, 0.5, -0.6, -0.4, 0, 0) and (0, 0.5, ...),
    one sphere under the line between them, one below the start (tests/planning)."""
    a = np.array([1125.2917429, -1418.04563696, 267.5709755])
    b = np.array([1810.28587111, 0.0, 267.5709755])
    mid = (a + b) / 2
    scene = Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]], [
        {"center": (mid + [0, 0, -130]).tolist(), "radius": 200},
        {"center": [1200, -1500, -300], "radius": 200}], safety_margin=10)
    return scene, a, b


def ompl_rrt_star(scene: Scene, start, goal, seconds: float, seed: int,
                  planner: str = "RRTstar"):
    """OMPL's ``planner`` (RRT*, or e.g. InformedRRTstar) for ``seconds`` with our exact
    checks; returns (path or None, seconds)."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(seed)
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for i in range(3):
        bounds.setLow(i, float(scene.lower[i]))
        bounds.setHigh(i, float(scene.upper[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)
    margin = scene.safety_margin

    def xyz(s) -> np.ndarray:
        return np.array([[s[0], s[1], s[2]]])

    def valid(s) -> bool:
        p = xyz(s)
        return bool(scene.segments_clear(p, p, margin)[0])

    ss.setStateValidityChecker(valid)

    class ExactMotion(ob.MotionValidator):
        def checkMotion(self, a, b):  # noqa: N802 - OMPL's name
            return bool(scene.segments_clear(xyz(a), xyz(b), margin)[0])

    si = ss.getSpaceInformation()
    validator = ExactMotion(si)
    si.setMotionValidator(validator)
    s0, s1 = space.allocState(), space.allocState()
    s0[0:3], s1[0:3] = [float(v) for v in start], [float(v) for v in goal]
    ss.setStartAndGoalStates(s0, s1)
    ss.setPlanner(getattr(og, planner)(si))
    ss.getProblemDefinition().setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    t0 = time.perf_counter()
    ss.solve(seconds)
    elapsed = time.perf_counter() - t0
    if not ss.haveExactSolutionPath():
        return None, elapsed
    p = ss.getSolutionPath()
    return np.array([[p.getState(i)[k] for k in range(3)]
                     for i in range(p.getStateCount())]), elapsed


MANY_START, MANY_GOAL = np.array([40.0, 40.0, 40.0]), np.array([960.0, 960.0, 960.0])


def diagonal_scene(n: int, seed: int = 1) -> Scene:
    """``n`` spheres (radius 10-30 mm) jittered +-30 mm about a 1 m cube's diagonal; from a
    few hundred on they merge into a tube."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.15, 0.85, n)
    centres = MANY_START + t[:, None] * (MANY_GOAL - MANY_START) + rng.uniform(-30, 30, (n, 3))
    radii = rng.uniform(10, 30, n)
    return Scene.create([[0, 0, 0], [1000, 1000, 1000]],
                        [{"center": c.tolist(), "radius": float(r)}
                         for c, r in zip(centres, radii)], 1.0)


def bench_many(counts: list[int], ompl_seconds: float) -> None:
    print(f"\n== auto among many spheres on a 1 m cube's diagonal (OMPL InformedRRT* "
          f"{ompl_seconds:g} s, the same exact checks)")
    print(f"  {'spheres':>7}{'wall s':>8}{'cpu s':>8}{'length':>10}{'OMPL':>10}{'vs OMPL':>9}"
          f"{'detour':>8}{'OMPL det.':>10}{'peak MiB':>9}  method")
    straight = float(np.linalg.norm(MANY_GOAL - MANY_START))
    plan_path(diagonal_scene(10), MANY_START, MANY_GOAL, "auto", 0)  # warm: imports
    for n in counts:
        scene = diagonal_scene(n)
        w0, c0 = time.perf_counter(), time.process_time()
        res = plan_path(scene, MANY_START, MANY_GOAL, "auto", 0)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        tracemalloc.start()
        plan_path(scene, MANY_START, MANY_GOAL, "auto", 0)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        ok = res.success and scene.path_is_clear(res.path)
        try:
            path, _ = ompl_rrt_star(scene, MANY_START, MANY_GOAL, ompl_seconds, 1,
                                    "InformedRRTstar")
        except ImportError:
            path = None
        ompl = path_length(path) if path is not None and scene.path_is_clear(path) else None
        vs = f"{100 * (res.length / ompl - 1):+8.3f}%" if ompl and ok else f"{'-':>9}"
        det = f"{res.length - straight:8.2f}" if ok else f"{'-':>8}"
        odet = f"{ompl - straight:10.2f}" if ompl else f"{'-':>10}"
        length = f"{res.length:10.2f}" if ok else f"{'failed':>10}"
        omplf = f"{ompl:10.2f}" if ompl else f"{'-':>10}"
        print(f"  {n:>7}{wall:8.2f}{cpu:8.2f}{length}{omplf}{vs}{det}{odet}{peak:9.0f}  "
              f"{res.extra.get('method', res.status.value)}")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  goals: 100 spheres <= 1 s, 1,000 <= 10 s, length within 1 % of OMPL's; "
          f"peak resident memory of this process {rss:.0f} MiB (OMPL included)")


def row(name: str, lengths, raw, times, ok: int, runs: int) -> str:
    lengths = np.asarray(lengths, float)
    fmt = (lambda x: f"{x:10.2f}") if len(lengths) else (lambda x: f"{'-':>10}")
    best = fmt(lengths.min()) if len(lengths) else fmt(0)
    mean = fmt(lengths.mean()) if len(lengths) else fmt(0)
    mraw = fmt(np.mean(raw)) if len(raw) else fmt(0)
    return f"  {name:<22}{best}{mean}{mraw}{np.mean(times):9.3f}   {ok}/{runs}"


def bench_scene(label: str, scene: Scene, start, goal, runs: int) -> dict:
    print(f"\n== {label}: {len(scene.obstacles)} obstacles, straight line "
          f"{np.linalg.norm(goal - start):.2f} mm, margin {scene.safety_margin} mm")
    print(f"  {'algorithm':<22}{'best':>10}{'mean':>10}{'mean raw':>10}{'time s':>9}   ok")
    out = {}
    for algorithm in ("wolfpack_improved", "wolfpack", "aca", "ga", "afsa"):
        res = [plan_path(scene, start, goal, algorithm, seed) for seed in range(runs)]
        good = [r for r in res if r.success]
        out[algorithm] = good
        print(row(algorithm, [r.length for r in good], [r.raw_length for r in good],
                  [r.runtime_s for r in res], len(good), runs))
    auto = plan_path(scene, start, goal, "auto", 0)
    auto = plan_path(scene, start, goal, "auto", 0)  # warm (imports, caches)
    rrt = [plan_path(scene, start, goal, "rrt_star", seed) for seed in range(min(runs, 10))]
    rrt_ok = [r for r in rrt if r.success]
    print(row("auto", [auto.length], [auto.raw_length], [auto.runtime_s], int(auto.success),
              1))
    print(row("rrt_star (ours)", [r.length for r in rrt_ok], [r.raw_length for r in rrt_ok],
              [r.runtime_s for r in rrt], len(rrt_ok), len(rrt)))
    t0 = time.perf_counter()
    cert = certified_shortest_path(scene, start, goal, samples=800)
    t_cert = time.perf_counter() - t0
    if cert is not None:
        L = path_length(cert)
        print(f"  certified (800 samples/obstacle): {L:.3f} mm in {t_cert:.1f} s; auto is "
              f"{100 * (auto.length / L - 1):+.3f} % of it")
    for name, budget in (("auto's time", auto.runtime_s),
                         ("our RRT*'s time", float(np.mean([r.runtime_s for r in rrt])))):
        try:
            lengths, clear = [], 0
            for seed in range(min(runs, 10)):
                path, _ = ompl_rrt_star(scene, start, goal, max(budget, 0.01), seed + 1)
                if path is not None and scene.path_is_clear(path):
                    clear += 1
                    lengths.append(path_length(path))
            mean = f"{np.mean(lengths):.2f}" if lengths else "-"
            print(f"  OMPL RRT* at {name} ({budget:.3f} s): mean {mean} mm, "
                  f"{clear}/{min(runs, 10)} verified clear")
        except ImportError:
            print("  OMPL RRT*: the ompl package is not installed (pip install ompl)")
            break
    imp = np.mean([r.length for r in out["wolfpack_improved"]])
    bas = np.mean([r.length for r in out["wolfpack"]])
    imp_raw = np.mean([r.raw_length for r in out["wolfpack_improved"]])
    bas_raw = np.mean([r.raw_length for r in out["wolfpack"]])
    paper = 100 * (1 - PAPER_TABLE4["improved"] / PAPER_TABLE4["basic"])
    print(f"  improved vs basic wolf pack, mean over {runs} seeds: "
          f"{100 * (1 - imp_raw / bas_raw):.1f} % shorter (optimisers' paths), "
          f"{100 * (1 - imp / bas):.1f} % after shortcutting; paper (Table 4): {paper:.1f} %")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30, help="seeds per algorithm")
    ap.add_argument("--scenes", default="toy0,toy1,toy2,arm,many",
                    help="comma-separated: toy0, toy1, toy2, arm, many")
    ap.add_argument("--many", default="10,100,1000",
                    help="sphere counts of the 'many' scenes, comma-separated")
    ap.add_argument("--ompl-seconds", type=float, default=5.0,
                    help="OMPL InformedRRT*'s time on the 'many' scenes")
    args = ap.parse_args()
    print(f"kinoplan path-planning benchmark; python {platform.python_version()}, "
          f"numpy {np.__version__}, {platform.machine()}")
    for label in args.scenes.split(","):
        if label.startswith("toy"):
            bench_scene(f"toy scene, layout {label[3:]}", toy_scene(int(label[3:])), START,
                        GOAL, args.runs)
        elif label == "arm":
            scene, a, b = arm_scene()
            bench_scene("pile_driver arm scene (tool path only)", scene, a, b, args.runs)
        elif label == "many":
            bench_many([int(n) for n in args.many.split(",")], args.ompl_seconds)
        else:
            raise SystemExit(f"--scenes: unknown scene {label!r}")


if __name__ == "__main__":
    main()
