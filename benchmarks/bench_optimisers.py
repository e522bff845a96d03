"""Cross-check kinoplan's gain tuners (HGSO, PSO, GA, ACO_R, GWO) against mealpy's.

On four standard test functions (sphere, Rastrigin, Rosenbrock, Ackley; D = 10 by default)
each algorithm runs at the same evaluation budget (default 2550 = N (Nc + 1) for paper 003's
N = 50, Nc = 50) for 30 seeds; the table gives the median (and the interquartile range) of
the best value found, ours beside mealpy's, and the verdict: ``ok`` when ours is no worse in
median; otherwise ``tie`` when a Wilcoxon rank-sum test of the 30 values finds no difference
(p >= 0.05) and ``WORSE`` when it does. (The p column is that test's.)

mealpy counterparts, set to the same parameters where they have them:
``HGSO.OriginalHGSO(n_clusters=5)``, ``PSO.LDW_PSO(c1=c2=2, w 0.9 -> 0.4)``,
``GWO.OriginalGWO``, ``ACOR.OriginalACOR(sample_count=50, intent_factor=q, zeta=xi)`` (our
mapped q and xi), ``GA.BaseGA(pc=0.8, pm=0.5)``. mealpy is in the ``bench`` extra.

Run: ``.venv/bin/python benchmarks/bench_optimisers.py [--seeds 30] [--budget 2550] [--dim 10]``.
It is a report: the exit status is 0 even when a check fails.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from mealpy import ACOR, GA, GWO, HGSO, PSO, FloatVar
from scipy.stats import ranksums

from planning.optimisers.acor import ACOR as OurACOR
from planning.optimisers.base import Problem
from planning.optimisers.ga import GeneticAlgorithm
from planning.optimisers.gwo import GWO as OurGWO
from planning.optimisers.hgso import HGSO as OurHGSO
from planning.optimisers.pso import PSO as OurPSO


def sphere(X: np.ndarray) -> np.ndarray:
    return np.sum(X**2, axis=1)


def rastrigin(X: np.ndarray) -> np.ndarray:
    return 10.0 * X.shape[1] + np.sum(X**2 - 10.0 * np.cos(2 * np.pi * X), axis=1)


def rosenbrock(X: np.ndarray) -> np.ndarray:
    return np.sum(100.0 * (X[:, 1:] - X[:, :-1] ** 2) ** 2 + (1.0 - X[:, :-1]) ** 2, axis=1)


def ackley(X: np.ndarray) -> np.ndarray:
    return (-20.0 * np.exp(-0.2 * np.sqrt(np.mean(X**2, axis=1)))
            - np.exp(np.mean(np.cos(2 * np.pi * X), axis=1)) + 20.0 + np.e)


#: name -> (batched function, half-width of the box centred on 0)
FUNCTIONS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], float]] = {
    "sphere": (sphere, 5.12),
    "rastrigin": (rastrigin, 5.12),
    "rosenbrock": (rosenbrock, 5.0),
    "ackley": (ackley, 32.768),
}


def ours(name: str, iterations: int):
    acor = OurACOR(iterations=iterations)
    return {
        "hgso": OurHGSO(iterations=iterations),
        "pso": OurPSO(iterations=iterations),
        "ga": GeneticAlgorithm(iterations=iterations),
        "aco": acor,
        "gwo": OurGWO(iterations=iterations),
    }[name]


def theirs(name: str, epochs: int):
    acor = OurACOR()
    return {
        "hgso": lambda: HGSO.OriginalHGSO(epoch=epochs, pop_size=50, n_clusters=5),
        "pso": lambda: PSO.LDW_PSO(epoch=epochs, pop_size=50, c1=2.0, c2=2.0, w_min=0.4,
                                   w_max=0.9),
        "ga": lambda: GA.BaseGA(epoch=epochs, pop_size=50, pc=0.8, pm=0.5),
        "aco": lambda: ACOR.OriginalACOR(epoch=epochs, pop_size=50, sample_count=50,
                                         intent_factor=acor.q, zeta=acor.xi),
        "gwo": lambda: GWO.OriginalGWO(epoch=epochs, pop_size=50),
    }[name]()


def run_ours(alg: str, fn: str, dim: int, budget: int, seed: int) -> float:
    f, b = FUNCTIONS[fn]
    pb = Problem(f, -b * np.ones(dim), b * np.ones(dim))
    opt = ours(alg, iterations=budget // 50)  # the budget ends the run
    return opt.minimize(pb, np.random.default_rng(seed), max_evaluations=budget).fun


def run_mealpy(alg: str, fn: str, dim: int, budget: int, seed: int) -> float:
    f, b = FUNCTIONS[fn]
    model = theirs(alg, epochs=budget // 50)
    problem = {"obj_func": lambda x: float(f(np.asarray(x)[None])[0]),
               "bounds": FloatVar(lb=[-b] * dim, ub=[b] * dim), "minmax": "min",
               "log_to": None}
    g = model.solve(problem, termination={"max_fe": budget}, seed=seed)
    return float(g.target.fitness)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--budget", type=int, default=2550)
    ap.add_argument("--dim", type=int, default=10)
    ap.add_argument("--algorithms", default="hgso,pso,ga,aco,gwo")
    args = ap.parse_args()
    algs = args.algorithms.split(",")
    print(f"D = {args.dim}, budget {args.budget} evaluations, {args.seeds} seeds; "
          "median [IQR] of the best value; ok = ours <= mealpy in median")
    print(f"{'function':<11}{'alg':<6}{'ours':>26}{'mealpy':>26}{'p':>9}  verdict  "
          "time ours/mealpy (s)")
    fails, ties = 0, 0
    for fn in FUNCTIONS:
        for alg in algs:
            t0 = time.perf_counter()
            a = np.array([run_ours(alg, fn, args.dim, args.budget, s) for s in range(args.seeds)])
            t1 = time.perf_counter()
            m = np.array([run_mealpy(alg, fn, args.dim, args.budget, s)
                          for s in range(args.seeds)])
            t2 = time.perf_counter()
            p = float(ranksums(a, m).pvalue)
            verdict = "ok" if np.median(a) <= np.median(m) else "tie" if p >= 0.05 else "WORSE"
            fails += verdict == "WORSE"
            ties += verdict == "tie"

            def cell(v: np.ndarray) -> str:
                q1, med, q3 = np.percentile(v, [25, 50, 75])
                return f"{med:9.3g} [{q1:8.2g},{q3:8.2g}]"

            print(f"{fn:<11}{alg:<6}{cell(a):>26}{cell(m):>26}{p:9.2g}  {verdict:<7}"
                  f"{t1 - t0:6.1f} / {t2 - t1:6.1f}")
    print(f"\n{fails} case(s) significantly worse than mealpy, {ties} worse in median but "
          "not significantly (p >= 0.05)")


if __name__ == "__main__":
    main()
