"""Speed goals of the planners, timed on this machine.

The unit tests check what these calls return; how fast they return depends on the machine
and its load, so the time goals live here:

* the improved wolf pack with Table 2's parameters on the toy scene (paper 000): under 5 s;
* ``auto`` on the toy scenes of tests/planning/test_path_planners.py: under 1 s each;
* one tracking fitness evaluation of a population of 50 PI gains (line task, 200 steps),
  what each tuner iteration costs (paper 003): under 1 s;
* ``auto`` hole sequencing of 52 holes (paper 002): under 1 s of CPU time;
* one pose per call (the compiled fast path, ``kinematics.fast``): FK of one configuration
  under 10 µs, closed-form IK of one GLT pose under 30 µs, numeric IK of one unseen pose
  under 0.5 ms (GLT) and 0.3 ms (9-DOF arm), each timed over a batch of calls.

Each case is warmed up once (imports, caches), then timed ``--repeats`` times; the median
is compared with its goal. It is a report: the exit status is 0 whatever the numbers.

Run: ``.venv/bin/python benchmarks/bench_speed_goals.py [--repeats 3]``
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np

from kinematics.fk import fk
from kinematics.ik import solve_ik
from kinematics.library import builtin_model
from planning.paths import plan_path
from planning.paths.compare import toy_scene
from planning.sequencing import sequence_holes
from planning.tracking import GainBounds, LineTask, tracking_fitness

START, GOAL = [1.0, 1.0, 1.0], [100.0, 100.0, 100.0]
#: Seed of the kinematics cases' configurations: neither of the numeric IK's own seeds
#: (``kinematics.ik.numeric.TABLE_SEED``, ``NumericOptions().seed``).
KINEMATICS_SEED = 2027
#: Calls per kinematics case: the goal is this many times the per-call goal.
KINEMATICS_CALLS = 200



def random_face(n: int, seed: int) -> np.ndarray:
    """``n`` holes on the face plane x = 9000 mm, 6 m x 6 m, seeded (as in the tests)."""
    rng = np.random.default_rng(seed)
    return np.c_[np.full(n, 9000.0), rng.uniform(-3000, 3000, n), rng.uniform(0, 6000, n)]


def one_per_call(fn: Callable, inputs) -> Callable[[], None]:
    def run() -> None:
        for x in inputs:
            fn(x)
    return run


def kinematics_cases() -> list[tuple[str, Callable[[], object], float, Callable[[], float]]]:
    """One pose per call, ``KINEMATICS_CALLS`` calls per case, on unseen inputs."""
    n = KINEMATICS_CALLS
    glt, arm = builtin_model("glt_palletizer"), builtin_model("hyper_redundant_9dof")
    rng = np.random.default_rng(KINEMATICS_SEED)
    q_glt = rng.uniform(glt.lower, glt.upper, (n, glt.dof))
    T_glt = fk(glt, q_glt)
    T_arm = fk(arm, rng.uniform(arm.lower, arm.upper, (n, arm.dof)))
    return [
        (f"FK, one configuration per call, {n} calls (< 10 us each)",
         one_per_call(lambda q: fk(glt, q), q_glt), n * 10e-6, time.perf_counter),
        (f"closed-form IK GLT, one pose per call, {n} (< 30 us)",
         one_per_call(lambda T: solve_ik(glt, T, method="analytic"), T_glt), n * 30e-6,
         time.perf_counter),
        (f"numeric IK GLT, one pose per call, {n} (< 0.5 ms)",
         one_per_call(lambda T: solve_ik(glt, T, method="numeric"), T_glt), n * 0.5e-3,
         time.perf_counter),
        (f"numeric IK 9-DOF, one pose per call, {n} (< 0.3 ms)",
         one_per_call(lambda T: solve_ik(arm, T, method="numeric"), T_arm), n * 0.3e-3,
         time.perf_counter),
    ]


def cases() -> list[tuple[str, Callable[[], object], float, Callable[[], float]]]:
    """``(name, call, goal in s, clock)`` for every speed goal."""
    arm = builtin_model("hyper_redundant_9dof")
    fitness = tracking_fitness(arm, LineTask())
    population = np.random.default_rng(0).uniform(GainBounds().lower, GainBounds().upper,
                                                  (50, 3))
    holes = random_face(52, 7)
    out = [
        ("improved wolf pack, Table 2 parameters, toy scene 0",
         lambda: plan_path(toy_scene(0), START, GOAL, "wolfpack_improved", seed=0),
         5.0, time.perf_counter),
    ]
    for layout in (0, 1):
        scene = toy_scene(layout, margin=0.5)
        out.append((f"auto path, toy scene {layout}",
                    lambda scene=scene: plan_path(scene, START, GOAL, "auto", seed=0),
                    1.0, time.perf_counter))
    out += [
        ("tracking fitness, population of 50, line task", lambda: fitness(population),
         1.0, time.perf_counter),
        ("auto sequencing, 52 holes (CPU time)",
         lambda: sequence_holes(holes, [9000, 0, 0], "auto", seed=0), 1.0, time.process_time),
    ]
    return out + kinematics_cases()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per case (default 3)")
    args = ap.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}, numpy {np.__version__}")
    print(f"{'case':<55}{'median':>10}{'best':>10}{'goal':>8}  verdict")
    for name, call, goal, clock in cases():
        call()  # warm-up
        times = []
        for _ in range(max(1, args.repeats)):
            t0 = clock()
            call()
            times.append(clock() - t0)
        median = statistics.median(times)
        verdict = "PASS" if median < goal else "over"
        print(f"{name:<55}{median:>9.3f}s{min(times):>9.3f}s{goal:>7.3g}s  {verdict}")


if __name__ == "__main__":
    main()
