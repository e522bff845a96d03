"""Joint-space motion of the heavy machines: the ``path`` job's fallback, and site problems.

1. **The path job with a robot, in open space** (``app.jobs.path_kinds.run_path``, as the
   service runs it): ``--cases`` (10) moves per machine (pile_driver, glt_palletizer)
   between the tool points of random in-limit configurations (seed ``--seed`` + 1000,
   shared with nothing else), planned with ``arm.joint_space: "never"`` (the tool path only,
   as before) and with the default ``"fallback"``. Printed: successes of each, how many the
   joint-space planner produced, the tool-space failure reasons, median wall time of a job.

2. **Site problems** (``planning.motion.sites``): ``--problems`` (20) moves of pile_driver
   in ``pile_driver_site`` (over the wall, into the trench), of tunnel_drill_arm in
   ``tunnel_site`` (between collaring poses 300 mm before the face's holes) and
   ``--pallet-problems`` (10) of glt_palletizer in ``pallet_station`` (conveyor to
   pallet), and ``--problems`` of the tunnel_jumbo's right arm between collaring poses in
   ``jumbo_site``: the tunnel with the left and middle arms parked
   (``planning.drilling.multiarm.park_configuration``, 300 mm before the face) as link
   capsules; drawn with seed ``--seed`` + 2000 (the tests use others), planned by
   ``plan_motion(MotionChecker(RobotCollisionModel.from_model(model), scene), start, goal,
   time_limit=--time-limit (5 s), seed=k)`` after one untimed warm-up plan per machine.
   *Direct*: the straight joint-space move is free (the problem needs no detour).

Verification, outside ``planning.motion``: a path must start at the start and end at the
goal exactly, stay within the joint limits, and every straight segment between consecutive
waypoints, stepped at joint steps <= ``--step`` (0.005 rad, x 100 mm on prismatic joints;
half the planner's resolution), must be free by ``planning.collision.collides(cm, Q, scene,
exact=True)`` (the sphere stage, then FCL on the capsules and the scene's shapes); so must
the timed trajectory on 400 samples. A path that fails is not counted as verified.

Printed per machine: problems, direct, solved, verified, median and 95th-percentile planning
time (``planning_time_s``: search + simplification), median joint-space length (rad, mm / 100
on prismatic joints ... as ``MotionResult.length``: rad + mm), median least clearance (mm),
median trajectory duration (s), median states checked per plan (``stats["checks"]``, a
stretch proved by its sweep counting its one or two) and exact checks; failures with their
messages. The machine has 2 cores shared by everyone: times are noisy.

Run: ``.venv/bin/python benchmarks/bench_motion_heavy.py [--cases 10] [--problems 20]
[--pallet-problems 10] [--time-limit 5] [--seed 0] [--skip-jobs] [--skip-sites]
[--json out.json]``. A report: the exit status is 0 in any case.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import Counter

import numpy as np

from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.collision import RobotCollisionModel, collides
from planning.motion import PRISMATIC_STEP, MotionChecker, plan_motion
from planning.motion.sites import (
    jumbo_site,
    pallet_problems,
    pallet_station,
    pile_driver_problems,
    pile_driver_site,
    tunnel_problems,
    tunnel_site,
)


def _median(xs):
    return statistics.median(xs) if xs else float("nan")


def _p95(xs):
    return float(np.percentile(xs, 95)) if xs else float("nan")


# ---- 1. the path job ----------------------------------------------------------------------
def path_jobs(cases: int, seed: int) -> dict:
    from app.jobs.path_kinds import PathParams, run_path

    out = {}
    for robot in ("pile_driver", "glt_palletizer"):
        model = builtin_model(robot)
        rng = np.random.default_rng(seed + 1000)
        rows = []
        for _ in range(cases):
            Q = rng.uniform(model.lower, model.upper, size=(2, model.dof))
            start, goal = fk(model, Q)[:, :3, 3]
            row = {}
            for mode in ("never", "fallback"):
                params = PathParams.model_validate({
                    "scene": {"bounds": [[-5000] * 3, [5000] * 3]}, "robot": robot,
                    "start": start.tolist(), "goal": goal.tolist(),
                    "arm": {"joint_space": mode}})
                t0 = time.perf_counter()
                res = run_path(params, lambda f, m: None)
                row[mode] = {"success": res.success, "planner": res.planner,
                             "message": res.message, "wall_s": time.perf_counter() - t0}
                if mode == "fallback" and res.success:
                    tool = np.asarray(res.tool_samples)
                    row["ends_mm"] = float(max(np.linalg.norm(tool[0] - start),
                                               np.linalg.norm(tool[-1] - goal)))
            rows.append(row)
        never = sum(r["never"]["success"] for r in rows)
        fallback = sum(r["fallback"]["success"] for r in rows)
        joint = sum(r["fallback"]["planner"] == "joint_space" for r in rows)
        reasons = Counter(r["never"]["message"].split(" at ")[0].split(":")[0]
                          for r in rows if not r["never"]["success"])
        out[robot] = {"cases": cases, "tool_space_only": never, "with_fallback": fallback,
                      "joint_space": joint, "reasons": dict(reasons),
                      "median_wall_s": _median([r["fallback"]["wall_s"] for r in rows]),
                      "max_end_error_mm": max((r.get("ends_mm", 0.0) for r in rows),
                                              default=0.0)}
        print(f"{robot:15s} tool path only {never:2d}/{cases}  with fallback "
              f"{fallback:2d}/{cases}  (joint space: {joint})  median job "
              f"{out[robot]['median_wall_s']:.2f} s  ends within "
              f"{out[robot]['max_end_error_mm']:.4f} mm")
        for why, n in reasons.items():
            print(f"{'':15s}   tool path failed {n}x: {why}")
    return out


# ---- 2. site problems -------------------------------------------------------------------------
def verify(cm, scene, model, res, start, goal, step: float) -> tuple[bool, str]:
    """The path's promises, checked with ``planning.collision.collides`` (module
    docstring)."""
    path = res.path
    if not (np.array_equal(path[0], start) and np.array_equal(path[-1], goal)):
        return False, "ends differ from start/goal"
    if not np.all(model.within_limits(path)):
        return False, "out of limits"
    w = np.where(model.revolute, 1.0, 1.0 / PRISMATIC_STEP)
    states = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a) * w) / step)))
        states.append(a + np.arange(1, n + 1)[:, None] / n * (b - a))
    Q = np.vstack(states)
    if np.any(collides(cm, Q, scene, exact=True)):
        return False, "a segment collides"
    if res.trajectory is not None:
        Qt = res.trajectory.evaluate(np.linspace(0.0, res.trajectory.duration, 400))
        if np.any(collides(cm, Qt, scene, exact=True)):
            return False, "the trajectory collides"
        if not np.all(model.within_limits(Qt, tol=1e-6)):
            return False, "the trajectory leaves the limits"
    return True, ""


def _jumbo():
    """The jumbo's right arm and its site: the left and middle arms parked."""
    from kinematics.rigs import builtin_rig
    from planning.drilling.multiarm import park_configuration
    from planning.drilling.patterns import FACE_X

    rig = builtin_rig("tunnel_jumbo")
    parked = {a: park_configuration(rig, a, FACE_X - 300.0) for a in ("left", "middle")}
    return rig.arms["right"], jumbo_site(rig, parked)


def sites(n: int, n_pallet: int, time_limit: float, seed: int, step: float) -> dict:
    cases = [
        ("pile_driver", lambda: (m := builtin_model("pile_driver"), pile_driver_site(m)),
         pile_driver_problems, n),
        ("tunnel_drill_arm", lambda: (builtin_model("tunnel_drill_arm"), tunnel_site()),
         tunnel_problems, n),
        ("glt_palletizer", lambda: (m := builtin_model("glt_palletizer"), pallet_station(m)),
         pallet_problems, n_pallet),
        ("jumbo right arm", _jumbo, tunnel_problems, n),
    ]
    out = {}
    print(f"\n{'machine':17s} {'n':>3s} {'direct':>6s} {'solved':>6s} {'verif':>5s} "
          f"{'med t s':>8s} {'p95 t s':>8s} {'med len':>8s} {'med clr':>8s} {'med dur':>8s} "
          f"{'med chk':>8s} {'exact':>6s}")
    for robot, site, problems_of, count in cases:
        t0 = time.perf_counter()
        model, scene = site()
        cm = RobotCollisionModel.from_model(model)
        checker = MotionChecker(cm, scene)
        problems = problems_of(checker, count, seed + 2000)
        setup = time.perf_counter() - t0
        plan_motion(checker, problems[0].start, problems[0].goal, time_limit=1.0,
                    seed=10**6)  # first-use costs
        direct = 0
        times, lengths, clear, durations, failures = [], [], [], [], []
        checks, exact_checks = [], []
        solved = verified = 0
        for k, p in enumerate(problems):
            direct += bool(checker.segment_free(p.start, p.goal))
            res = plan_motion(checker, p.start, p.goal, time_limit=time_limit, seed=k)
            if not res.success:
                failures.append((k, p.kind, res.status.value, res.message))
                continue
            solved += 1
            times.append(res.planning_time_s)
            checks.append(res.stats.get("checks", 0))
            exact_checks.append(res.stats.get("exact_checks", 0))
            ok, why = verify(cm, scene, model, res, p.start, p.goal, step)
            if not ok:
                failures.append((k, p.kind, "unverified", why))
                continue
            verified += 1
            lengths.append(res.length)
            if res.min_clearance is not None:
                clear.append(res.min_clearance)
            if res.trajectory is not None:
                durations.append(res.trajectory.duration)
        kinds = Counter(p.kind for p in problems)
        out[robot] = {"problems": len(problems), "kinds": dict(kinds), "direct": direct,
                      "solved": solved, "verified": verified,
                      "median_time_s": _median(times), "p95_time_s": _p95(times),
                      "median_length": _median(lengths), "median_clearance_mm":
                      _median(clear), "median_duration_s": _median(durations),
                      "median_checks": _median(checks),
                      "median_exact_checks": _median(exact_checks),
                      "setup_s": setup, "failures": failures}
        r = out[robot]
        print(f"{robot:17s} {len(problems):3d} {direct:6d} {solved:6d} {verified:5d} "
              f"{r['median_time_s']:8.3f} {r['p95_time_s']:8.3f} {r['median_length']:8.2f} "
              f"{r['median_clearance_mm']:8.1f} {r['median_duration_s']:8.2f} "
              f"{r['median_checks']:8.0f} {r['median_exact_checks']:6.0f}")
        for k, kind, status, msg in failures:
            print(f"    problem {k} ({kind}): {status}: {msg}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=10)
    ap.add_argument("--problems", type=int, default=20)
    ap.add_argument("--pallet-problems", type=int, default=10)
    ap.add_argument("--time-limit", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--step", type=float, default=0.005)
    ap.add_argument("--skip-jobs", action="store_true")
    ap.add_argument("--skip-sites", action="store_true")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    report = {}
    if not args.skip_jobs:
        print("path job with a robot, open space, random in-limit endpoints")
        report["path_jobs"] = path_jobs(args.cases, args.seed)
    if not args.skip_sites:
        report["sites"] = sites(args.problems, args.pallet_problems, args.time_limit,
                                args.seed, args.step)
    print("\n(2 shared cores: times are noisy)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1, default=str)


if __name__ == "__main__":
    main()
