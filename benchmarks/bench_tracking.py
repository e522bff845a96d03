"""Paper 003's Table 3 on our 9-DOF arm: PI and PI tuned by PSO, GA, ACO, GWO and HGSO.

For the line and the ellipse task (``planning.tracking``), each tuner tunes the PI gains 30
times (seeds 0..29, Table 2 parameters: population 50, 50 iterations); the table gives the
worst-case max error, the mean of eq. 24, the mean error std, and the Wilcoxon rank-sum test
of the 30 eq. 24 values against the untuned PI, printed beside the paper's values (converted
to mm). The default controller (PI + velocity feed-forward) is shown below each table.

The paper's numbers come from its own (unprinted) task sizes, step and units, so they are a
reference for the shape of the table, not targets for the values.

Run: ``.venv/bin/python benchmarks/bench_tracking.py [--runs 30] [--workers 2]``
(about 16 minutes on 2 cores). It is a report: the exit status is 0 in any case.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

from kinematics.library import builtin_model
from planning.tracking import (
    DEFAULT_GAINS,
    EllipseTask,
    LineTask,
    simulate,
)
from planning.tracking.stats import TrackingTable, format_table3, tracking_table

ROBOT = "hyper_redundant_9dof"
TASKS = {"line": LineTask(), "ellipse": EllipseTask()}
TUNERS = ("pso", "ga", "aco", "gwo", "hgso")

#: Paper 003 Table 3 (metres). Its "curve" is our ellipse.
PAPER_TABLE3 = {
    "line": {
        "No PI": {"max": 1.42e-3, "mean": 1.11e-3, "std": 1.56e-4},
        "PI": {"max": 1.23e-3, "mean": 1.07e-3, "std": 1.80e-4},
        "PI-PSO": {"max": 8.42e-3, "mean": 2.75e-3, "std": 7.32e-4},
        "PI-GA": {"max": 1.44e-3, "mean": 4.67e-4, "std": 5.83e-4},
        "PI-ACO": {"max": 5.60e-3, "mean": 1.00e-3, "std": 3.67e-4},
        "PI-GWO": {"max": 4.06e-4, "mean": 2.44e-4, "std": 8.30e-5},
        "PI-HGSO": {"max": 3.38e-4, "mean": 2.15e-4, "std": 8.47e-5},
    },
    "ellipse": {
        "No PI": {"max": 1.61e-3, "mean": 1.12e-3, "std": 1.87e-4},
        "PI": {"max": 1.60e-3, "mean": 1.16e-3, "std": 2.11e-4},
        "PI-PSO": {"max": 4.86e-3, "mean": 1.27e-4, "std": 7.07e-4},
        "PI-GA": {"max": 5.53e-3, "mean": 4.76e-4, "std": 9.32e-4},
        "PI-ACO": {"max": 5.33e-3, "mean": 1.40e-4, "std": 7.72e-4},
        "PI-GWO": {"max": 1.55e-3, "mean": 8.99e-5, "std": 1.61e-4},
        "PI-HGSO": {"max": 3.55e-4, "mean": 8.32e-5, "std": 3.35e-5},
    },
}


def one(task_name: str, tuner: str, runs: int) -> TrackingTable:
    return tracking_table(builtin_model(ROBOT), TASKS[task_name], [tuner], runs=runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    model = builtin_model(ROBOT)
    t0 = time.perf_counter()
    jobs = [(task, tuner) for task in TASKS for tuner in TUNERS]
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {job: pool.submit(one, *job, args.runs) for job in jobs}
        parts = {job: f.result() for job, f in futures.items()}
    print(f"{args.runs} tunings per tuner (seeds 0..{args.runs - 1}); errors in mm; "
          f"{time.perf_counter() - t0:.0f} s\n")
    for task_name, task in TASKS.items():
        rows = tuple(parts[(task_name, t)].rows[0] for t in TUNERS)
        table = TrackingTable(task_name, parts[(task_name, TUNERS[0])].baseline, rows)
        print(format_table3(table, PAPER_TABLE3[task_name]))
        for row in rows:
            g = row.gains[row.best_run]
            print(f"  best {row.name:<5} run {row.best_run:2d}: kp = ({g.kp[0]:.4g}, "
                  f"{g.kp[1]:.4g}) /s, ki = {g.ki:.4g} /s^2, eq. 24 = "
                  f"{row.fitness[row.best_run]:.5f} mm; runs: median "
                  f"{sorted(row.fitness)[len(row.fitness) // 2]:.5f}, worst "
                  f"{row.fitness.max():.5f} mm")
        d = simulate(model, task, DEFAULT_GAINS, controller="default")
        hg = rows[TUNERS.index("hgso")]
        print(f"  default controller (PI + feed-forward, fixed gains): mean "
              f"{d.mean_error[0]:.6f}, max {d.max_error[0]:.6f}, std {d.std_error[0]:.6f} mm, "
              f"peak joint speed {d.joint_speed_max[0]:.4f} rad/s; PI-HGSO best run max "
              f"{hg.run_max[hg.best_run]:.5f} mm\n")


if __name__ == "__main__":
    main()
