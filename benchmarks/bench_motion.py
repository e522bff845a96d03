"""Joint-space motion planning on MotionBenchMaker problems, against OMPL, every path verified.

Problems: the Panda's MotionBenchMaker set (``--folder``, default ``../shared/mbm-dev/panda``:
7 families x 20 problems, MoveIt ``sceneNNNN.yaml`` + ``requestNNNN.yaml``) and a UR5 set
generated like it (``benchmarks/mbm_problems.py``: the Panda family scenes re-placed in front
of the UR5, grasp goals by IK, seed ``--ur5-seed``; its docstring gives the method). The
robots are ``../shared/robots/panda`` (group ``panda_arm``) and ``../shared/robots/ur5``
(``manipulator``), imported with ``kinematics.urdf_import.import_robot``. The Panda's
requests carry finger joints at 0.065 m, beyond the 0.04 m limit of Franka's description;
this URDF declares both finger joints ``fixed`` with origins at +-0.065 m, so the import
already holds the fingers where the requests put them (``fixed_joints`` applies to movable
joints only, and is not used); the script checks that every request says 0.065 and prints it.

Ours: ``planning.motion.plan_motion(MotionChecker(model, scene), start, goal,
time_limit=--time-limit (2 s), seed=..., trajectory=False)`` with the collision model
``RobotCollisionModel.from_imported`` (built once per robot) and the scene
``CollisionScene.from_moveit`` (metres in the YAML, mm in the product). The planner's seed is
``--seed`` plus the problem's family number x 1000 plus its index (shared with nothing
else). One untimed call first (first-use costs). Time = the result's ``planning_time_s``
(wall clock, search + simplification); the wall time of the whole call and the scene +
checker set-up are printed beside it.

Verification, independent of ``planning.collision`` and ``planning.motion``: every returned
path must start at the start and end at the goal (1e-9 rad), stay within the joint limits,
and every straight joint-space segment between consecutive waypoints, sampled at a largest
joint step <= ``--step`` (0.01 rad) with both ends, must be free under the exact mesh check
of ``bench_collision.Reference`` (python-fcl on the robot's collision meshes; self-collision
at the SRDF's rules, and every link against every scene shape). A path that fails is not
solved; its failure names the segment, the state and the touching pair, and says what the
planner's own checker (``MotionChecker.path_free``) makes of the path, which tells a search or
simplification fault (it says "not free" too) from a false "free" of the collision model. A
problem is *valid* when its start and goal are within the limits and free under the same
check; *direct* counts the valid problems whose straight segment start-goal is free.
``--retry-time T`` plans the problems ours fails again with a limit of T s (hard or
infeasible?; the generated UR5 problems are only known to have free ends).

Reference, in the same run: OMPL's RRT-Connect (python ``ompl``) in the joint space (bounds
= the joint limits), the state validity checker = the same exact check, a motion validator
that samples exactly as the verification does (largest joint step <= ``--step``, checking
the states in bisection order), ``--ompl-time`` (2 s), then ``PathSimplifier.simplifyMax``;
planning and simplification timed apart, the simplified path's Euclidean joint-space length,
and the path verified like ours. OMPL spends its time in python-fcl, so it runs on the first
``--ompl-problems`` (5) valid problems of each family (``--skip-ompl`` for none); the ratio
of median times OMPL / ours is taken on the problems both solved.

VAMP in the same run (``benchmarks/vamp_reference.py``; on when ``vamp`` imports,
``--skip-vamp`` for none; install it by hand, benchmarks/README.md): every problem planned by
VAMP's RRT-Connect + simplification as its ``scripts/evaluate_mbm.py`` does, the scene
converted as VAMP's own scripts convert a MoveIt scene (like evaluate_mbm.py, a problem whose
start or goal collides in VAMP's model is not planned; samples capped at
``--vamp-max-samples``, 50,000, see vamp_reference.MAX_SAMPLES); VAMP's times (its nanoseconds
and the wall clock of each call), its simplified path's length, and the path verified like ours
(ends and limits within 1e-6 rad: VAMP is float32); a path that fails gets the deepest fcl
contact along it. Its joint order, limits and end-effector frame are checked against the
URDF's, and its collision check alone is timed (``validate``, ``validate_motion``). Printed in
a section of its own: ours, VAMP measured here and OMPL side by side, per robot, with the
ratios ours / VAMP of median time and length on the problems both solved, and the machine's
load.

Printed per family and overall: problems, valid, direct, solved by ours, verified, median
and 95th-percentile planning time (over the problems ours solved), median simplified length
(over the verified paths); the same for OMPL; VAMP's published figures (Thomason, Kingston,
Kavraki, ICRA 2024: Panda 699/700 solved, median 99 us planning + simplification, median
length 4.90 rad; UR5 608/700 valid, median 112 us, 6.55 rad; AMD Ryzen 9 7950X, SIMD C++,
its own non-conservative sphere model; our UR5 problems are generated, not MotionBenchMaker's,
so its UR5 figures are only indicative); then the verdicts: every valid problem solved within
the limit, every path verified, median time >= 10x below OMPL's, median length within 10 % of
VAMP's. Failures are listed by family, index, status and message. The machine has 2 cores
shared by everyone: timings are noisy.

Run: ``.venv/bin/python benchmarks/bench_motion.py [--robot panda|ur5|both] [--families box
cage] [--limit 20] [--problems-per-family 20] [--ompl-problems 5 | --skip-ompl]
[--time-limit 2] [--retry-time 20] [--ur5-folder DIR] [--skip-vamp] [--json out.json]``
(needs python-fcl, pyyaml, trimesh and ompl; vamp optional). The collision models take
about 10 s (Panda) and 30 s (UR5) to build; both robots with the defaults take about 10
minutes on 2 cores, most of it OMPL. A report: the exit status is 0 in any case.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path

import fcl
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mbm_problems as mbm  # noqa: E402
import vamp_reference as vref  # noqa: E402
from bench_collision import Reference, mbm_scene  # noqa: E402

from planning.collision import CollisionScene, RobotCollisionModel  # noqa: E402

#: VAMP's published figures (resources/README.md of KavrakiLab/vamp; ICRA 2024).
VAMP = {"panda": {"solved": "699/700 solved", "median_us": 99, "length": 4.90},
        "ur5": {"solved": "608/700 valid, all solved", "median_us": 112, "length": 6.55}}
FINGER_M = 0.065
#: VAMP's collision check alone, per robot (``vamp_reference.check_timing``).
VAMP_CHECK: dict[str, dict] = {}


# ---- the exact check along paths ------------------------------------------------------------
def segment_states(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """States on the straight segment a-b, ends included, largest joint step <= ``step``:
    ``(n + 1, dof)`` with ``n = max(1, ceil(max |b - a| / step))``."""
    n = max(1, math.ceil(float(np.max(np.abs(b - a))) / step - 1e-12))
    t = np.arange(n + 1)[:, None] / n
    return a + t * (b - a)


def first_contact(ref: Reference, ids: list[str], robot) -> tuple[str, str]:
    """Names of a colliding pair at the poses last set in ``ref`` (after ``collides``)."""
    names = robot.link_names
    request = fcl.CollisionRequest()
    for k, _, obj in ref.objects:
        for j, other in enumerate(ref.world):
            if fcl.collide(obj, other, request, fcl.CollisionResult()):
                return names[k], ids[j] if j < len(ids) else f"object {j}"
    for i, j in ref.pairs:
        if fcl.collide(ref.objects[i][2], ref.objects[j][2], request, fcl.CollisionResult()):
            return names[ref.objects[i][0]], names[ref.objects[j][0]]
    return "?", "?"


def verify(robot, ref: Reference, ids: list[str], path, start, goal, step: float,
           tol: float = 1e-9) -> str:
    """'' when the path passes, else why it fails (the first failure)."""
    m = robot.model
    path = np.asarray(path, float)
    if path.ndim != 2 or path.shape[1] != m.dof or len(path) < 2:
        return f"path of shape {list(path.shape)}, expected (K >= 2, {m.dof})"
    if not np.all(np.isfinite(path)):
        return "path has a NaN or infinite value"
    if np.max(np.abs(path[0] - start)) > tol:
        return f"path[0] differs from the start by {np.max(np.abs(path[0] - start)):.3g} rad"
    if np.max(np.abs(path[-1] - goal)) > tol:
        return f"path[-1] differs from the goal by {np.max(np.abs(path[-1] - goal)):.3g} rad"
    low, high = path < m.lower - tol, path > m.upper + tol
    if np.any(low | high):
        k, j = np.argwhere(low | high)[0]
        return (f"waypoint {k} joint {m.joints[j].name} = {path[k, j]:.6f} outside "
                f"[{m.lower[j]:.4f}, {m.upper[j]:.4f}]")
    for i in range(len(path) - 1):
        Q = segment_states(path[i], path[i + 1], step)
        first = 0 if i == 0 else 1           # the shared end was checked with the last segment
        for k, P in enumerate(robot.link_poses(Q[first:]), start=first):
            if ref.collides(P):
                a, b = first_contact(ref, ids, robot)
                return (f"segment {i} (of {len(path) - 1}), state {k}/{len(Q) - 1}: "
                        f"{a} touches {b}")
    return ""


def state_free(robot, ref: Reference, q: np.ndarray) -> bool:
    return not ref.collides(robot.link_poses(q))


def path_length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


# ---- OMPL ------------------------------------------------------------------------------------
@lru_cache(maxsize=4096)
def bisection_order(n: int) -> tuple[int, ...]:
    """1..n, the far end first, then midpoints level by level (finds contacts sooner)."""
    order, seen, spans = [n], {0, n}, [(0, n)]
    while spans:
        nxt = []
        for lo, hi in spans:
            if hi - lo > 1:
                mid = (lo + hi) // 2
                if mid not in seen:
                    seen.add(mid)
                    order.append(mid)
                nxt += [(lo, mid), (mid, hi)]
        spans = nxt
    return tuple(order)


def ompl_plan(robot, ref: Reference, start, goal, seconds: float, step: float) -> dict:
    """OMPL RRT-Connect + simplifyMax with the exact check; solved, times, path."""
    from ompl import base as ob
    from ompl import geometric as og

    m = robot.model
    dof = m.dof
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(m.lower[i]))
        bounds.setHigh(i, float(m.upper[i]))
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)

    def vec(s) -> np.ndarray:
        return np.array([s[i] for i in range(dof)])

    def valid(s) -> bool:
        return state_free(robot, ref, vec(s))

    ss.setStateValidityChecker(valid)

    class ExactMotion(ob.MotionValidator):
        """The verification's sampling; the first end is valid by OMPL's convention."""

        def checkMotion(self, s1, s2):  # noqa: N802 - OMPL's name
            Q = segment_states(vec(s1), vec(s2), step)
            poses = robot.link_poses(Q)
            return not any(ref.collides(poses[k]) for k in bisection_order(len(Q) - 1))

    si = ss.getSpaceInformation()
    validator = ExactMotion(si)
    si.setMotionValidator(validator)
    s0, s1 = space.allocState(), space.allocState()
    for i in range(dof):
        s0[i], s1[i] = float(start[i]), float(goal[i])
    ss.setStartAndGoalStates(s0, s1)
    ss.setPlanner(og.RRTConnect(si))
    t = time.perf_counter()
    ss.solve(seconds)
    t_plan = time.perf_counter() - t
    out = {"solved": bool(ss.haveExactSolutionPath()), "plan_s": t_plan, "simplify_s": 0.0,
           "path": None}
    if out["solved"]:
        p = ss.getSolutionPath()
        t = time.perf_counter()
        og.PathSimplifier(si).simplifyMax(p)
        out["simplify_s"] = time.perf_counter() - t
        out["path"] = np.array([vec(p.getState(i)) for i in range(p.getStateCount())])
    return out


# ---- one robot ------------------------------------------------------------------------------
@dataclass
class Row:
    robot: str
    family: str
    index: int
    valid: bool = False
    invalid_why: str = ""
    direct: bool | None = None
    status: str = "-"
    message: str = ""
    time_s: float | None = None
    call_s: float | None = None
    simplify_s: float | None = None
    setup_s: float | None = None
    length: float | None = None
    waypoints: int | None = None
    verified: bool | None = None
    verify_why: str = ""
    ompl: bool = False
    ompl_solved: bool | None = None
    ompl_plan_s: float | None = None
    ompl_simplify_s: float | None = None
    ompl_length: float | None = None
    ompl_verified: bool | None = None
    ompl_why: str = ""
    retry_status: str = ""
    retry_s: float | None = None
    vamp: bool = False
    vamp_solved: bool | None = None
    vamp_plan_ns: int | None = None
    vamp_simplify_ns: int | None = None
    vamp_plan_wall_s: float | None = None
    vamp_simplify_wall_s: float | None = None
    vamp_iterations: int | None = None
    vamp_tree: int | None = None
    vamp_ends_valid: bool | None = None     # VAMP's own check of start and goal
    vamp_waypoints: int | None = None
    vamp_length: float | None = None        # of every solved path, verified or not
    vamp_verified: bool | None = None
    vamp_why: str = ""
    vamp_depth_mm: float | None = None      # deepest contact of a path that failed

    @property
    def name(self) -> str:
        return f"{self.family}/{self.index:04d}"

    @property
    def solved(self) -> bool:
        return self.status == "ok"

    @property
    def ompl_s(self) -> float | None:
        return None if self.ompl_plan_s is None else self.ompl_plan_s + self.ompl_simplify_s

    @property
    def vamp_s(self) -> float | None:
        """VAMP's own planning + simplification time (its nanoseconds), s."""
        return None if self.vamp_plan_ns is None \
            else (self.vamp_plan_ns + self.vamp_simplify_ns) * 1e-9

    @property
    def vamp_wall_s(self) -> float | None:
        return None if self.vamp_plan_wall_s is None \
            else self.vamp_plan_wall_s + self.vamp_simplify_wall_s


def own_check(checker, path: np.ndarray, step: float) -> str:
    """What the planner's own checker says of a path that failed verification: tells a
    search or simplification fault (it says not free) from a false "free" of the checker."""
    try:
        return f" (the planner's own checker: path_free = {checker.path_free(path, step)})"
    except Exception as e:  # a report, whatever the path's shape
        return f" (the planner's own checker refuses the path: {e})"


def load_motion():
    """``planning.motion``'s names, or None when the package is not there."""
    try:
        from planning.motion import MotionChecker, plan_motion
    except ImportError as e:
        print(f"planning.motion cannot be imported ({e}): ours is skipped")
        return None
    # As the service's processes do before their first request: every kernel loaded (or,
    # with an empty numba cache, compiled) now, not inside the first problems' time limits.
    from planning.warm import warm_up

    report = warm_up()
    print(f"kernels loaded in {report.total_seconds:.1f} s")
    return MotionChecker, plan_motion


def problems_for(name: str, robot, panda, args, workdir: Path) -> list[mbm.Problem]:
    joint_names = [j.name for j in robot.model.joints]
    if name == "panda":
        problems = mbm.load_problems(args.folder, "panda", joint_names, args.families,
                                     args.limit)
        fingers = sorted({round(v, 9) for p in problems for v in p.other_joints.values()})
        print(f"  start-state finger joints: {fingers} m in {len(problems)} requests; the "
              f"URDF fixes the fingers at +-{FINGER_M} m (as imported)")
        if fingers and fingers != [FINGER_M]:
            print("  NOTE: some requests hold the fingers elsewhere; the import does not")
        return problems
    folder = args.ur5_folder or workdir / "ur5"
    if not args.ur5_folder or not folder.exists():
        t = time.perf_counter()
        mbm.generate_ur5(folder, robot, panda, args.families or mbm.FAMILIES,
                         args.problems_per_family, args.ur5_seed, log=print)
        print(f"  UR5 problems generated in {time.perf_counter() - t:.1f} s (seed "
              f"{args.ur5_seed}) into {folder}")
    return mbm.load_problems(folder, "ur5", joint_names, args.families, args.limit)


def run_vamp(vr, row: Row, robot, ref: Reference, ids: list[str], data: dict, p, args):
    """VAMP on one problem (scene converted as VAMP's own scripts do), its path verified
    by the same exact check at the same step; returns VAMP's environment and its simplified
    path (None if not planned or unsolved)."""
    env = vref.scene_env(vr.vamp, data, p.family)
    o = vref.plan(vr, env, p.start, p.goal)
    row.vamp = o["planned"]
    row.vamp_ends_valid = o["start_valid"] and o["goal_valid"]
    if not o["planned"]:
        return env, None
    row.vamp_solved, row.vamp_plan_ns = o["solved"], o["plan_ns"]
    row.vamp_simplify_ns, row.vamp_plan_wall_s = o["simplify_ns"], o["plan_wall_s"]
    row.vamp_simplify_wall_s = o["simplify_wall_s"]
    row.vamp_iterations, row.vamp_tree = o["iterations"], o["tree"]
    if o["solved"]:
        path = o["path"]
        row.vamp_waypoints, row.vamp_length = len(path), path_length(path)
        row.vamp_why = verify(robot, ref, ids, path, p.start, p.goal, args.step,
                              tol=vref.F32_TOL)
        row.vamp_verified = row.vamp_why == ""
        if not row.vamp_verified and np.all(np.isfinite(path)):
            row.vamp_depth_mm = vref.contact_depth_mm(ref, robot, path, args.step,
                                                      segment_states)
    return env, o["path"]


def run_robot(name: str, args, motion, panda, workdir: Path, vamp=None) -> list[Row]:
    print(f"\n== {name} ==")
    t = time.perf_counter()
    robot = panda if name == "panda" else mbm.import_named(name)
    print(f"  imported in {time.perf_counter() - t:.1f} s: {robot.model.dof} joints "
          f"({', '.join(j.name for j in robot.model.joints)})")
    problems = problems_for(name, robot, panda, args, workdir)
    ref = Reference(robot)
    m = robot.model
    cm = None
    if motion is not None:
        t = time.perf_counter()
        cm = RobotCollisionModel.from_imported(robot)
        print(f"  collision model built in {time.perf_counter() - t:.1f} s")
        MotionChecker, plan_motion = motion
    rows: list[Row] = []
    ompl_left = {}
    warmed = False
    vr = None
    if vamp is not None:
        vr = vref.VampRobot.make(vamp, name, args.vamp_max_samples)
        for line in vref.model_report(vr, robot):
            print("  " + line)
        VAMP_CHECK.pop(name, None)
    for p in problems:
        row = Row(name, p.family, p.index)
        rows.append(row)
        objects, data = mbm_scene(p.scene_path)
        ids = mbm.scene_ids(data)
        ref.set_scene(objects)
        why = []
        for label, q in (("start", p.start), ("goal", p.goal)):
            if np.any(q < m.lower) or np.any(q > m.upper):
                why.append(f"{label} outside the joint limits")
            elif not state_free(robot, ref, q):
                a, b = first_contact(ref, ids, robot)
                why.append(f"{label} in collision ({a} touches {b})")
        row.valid, row.invalid_why = not why, "; ".join(why)
        if row.valid:
            row.direct = verify(robot, ref, ids, np.stack([p.start, p.goal]), p.start,
                                p.goal, args.step) == ""
        if cm is not None:
            seed = args.seed + 1000 * mbm.FAMILIES.index(p.family) + p.index \
                if p.family in mbm.FAMILIES else args.seed + p.index
            t = time.perf_counter()
            checker = MotionChecker(cm, CollisionScene.from_moveit(data))
            row.setup_s = time.perf_counter() - t
            if not warmed:
                plan_motion(checker, p.start, p.goal, time_limit=args.time_limit, seed=seed,
                            trajectory=False)
                warmed = True
            t = time.perf_counter()
            res = plan_motion(checker, p.start, p.goal, time_limit=args.time_limit,
                              seed=seed, trajectory=False)
            row.call_s = time.perf_counter() - t
            row.status, row.message = str(res.status), res.message
            row.time_s, row.simplify_s = res.planning_time_s, res.simplify_time_s
            if res.success:
                path = np.asarray(res.path, float)
                row.waypoints = len(path)
                row.verify_why = verify(robot, ref, ids, path, p.start, p.goal, args.step)
                row.verified = row.verify_why == ""
                if not row.verified:
                    row.verify_why += own_check(checker, path, args.step)
                if row.verified:
                    row.length = path_length(path)
            if row.valid and not res.success and args.retry_time > 0:
                again = plan_motion(checker, p.start, p.goal, time_limit=args.retry_time,
                                    seed=seed, trajectory=False)
                row.retry_status, row.retry_s = str(again.status), again.planning_time_s
        if vr is not None:
            if not rows[:-1]:                         # first-use costs, untimed
                vref.plan(vr, vref.scene_env(vamp, data, p.family), p.start, p.goal)
            env, vpath = run_vamp(vr, row, robot, ref, ids, data, p, args)
            if name not in VAMP_CHECK and row.valid and vpath is not None and len(vpath) > 1 \
                    and np.linalg.norm(vpath[1] - vpath[0]) < 8.0:
                VAMP_CHECK[name] = vref.check_timing(vr, env, vpath[0], vpath[1])
        if row.valid and not args.skip_ompl \
                and ompl_left.setdefault(p.family, args.ompl_problems) > 0:
            ompl_left[p.family] -= 1
            row.ompl = True
            o = ompl_plan(robot, ref, p.start, p.goal, args.ompl_time, args.step)
            row.ompl_solved, row.ompl_plan_s = o["solved"], o["plan_s"]
            row.ompl_simplify_s = o["simplify_s"]
            if o["solved"]:
                row.ompl_why = verify(robot, ref, ids, o["path"], p.start, p.goal, args.step)
                row.ompl_verified = row.ompl_why == ""
                if row.ompl_verified:
                    row.ompl_length = path_length(o["path"])
        print("  " + progress(row), flush=True)
    return rows


def ms(v: float | None) -> str:
    return "-" if v is None else f"{v * 1e3:.2f}"


def progress(r: Row) -> str:
    parts = [f"{r.name:<22}"]
    if not r.valid:
        parts.append(f"invalid: {r.invalid_why};")
    else:
        parts.append(f"direct {'yes' if r.direct else 'no '};")
    if r.status != "-":
        parts.append(f"ours {r.status} {ms(r.time_s)} ms (call {ms(r.call_s)}, set-up "
                     f"{ms(r.setup_s)})")
        if r.solved:
            parts.append(f"{r.waypoints} waypoints, "
                         + (f"length {r.length:.3f}, verified" if r.verified
                            else f"NOT VERIFIED: {r.verify_why}"))
        elif r.valid:
            parts.append(f"({r.message})")
        if r.retry_status:
            parts.append(f"[given more time: {r.retry_status} in {fmt(r.retry_s, 1, 1)} s]")
    if r.vamp_ends_valid is False:
        parts.append("| vamp not run: start or goal collides in VAMP's model")
    if r.vamp:
        parts.append(f"| vamp {'ok' if r.vamp_solved else 'unsolved'} "
                     f"{fmt(r.vamp_plan_ns, 1e-3, 0)} + {fmt(r.vamp_simplify_ns, 1e-3, 0)} us")
        if r.vamp_solved:
            parts.append(f"length {r.vamp_length:.3f}, "
                         + ("verified" if r.vamp_verified else
                            f"NOT FREE ({fmt(r.vamp_depth_mm, 1, 1)} mm deep): {r.vamp_why}"))
    if r.ompl:
        parts.append(f"| ompl {'ok' if r.ompl_solved else 'unsolved'} {ms(r.ompl_plan_s)} + "
                     f"{ms(r.ompl_simplify_s)} ms")
        if r.ompl_solved:
            parts.append(f"length {r.ompl_length:.3f}, verified" if r.ompl_verified
                         else f"NOT VERIFIED: {r.ompl_why}")
    return " ".join(parts)


# ---- the report ------------------------------------------------------------------------------
def median(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def p95(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.percentile(values, 95)) if values else None


def fmt(v: float | None, scale: float = 1.0, digits: int = 2) -> str:
    return "-" if v is None else f"{v * scale:.{digits}f}"


def summary(rows: list[Row], time_limit: float) -> dict:
    valid = [r for r in rows if r.valid]
    solved = [r for r in rows if r.solved]
    both = [r for r in rows if r.solved and r.verified and r.ompl_verified]
    om = [r for r in rows if r.ompl]
    ratio = None
    if both:
        ours_m, ompl_m = median(r.time_s for r in both), median(r.ompl_s for r in both)
        ratio = ompl_m / ours_m if ours_m else None
    return {
        "problems": len(rows), "valid": len(valid),
        "direct": sum(bool(r.direct) for r in valid),
        "solved": len(solved), "solved_valid": sum(r.solved for r in valid),
        "verified": sum(bool(r.verified) for r in solved),
        "within_limit": sum(r.solved and r.verified and r.time_s is not None
                            and r.time_s <= time_limit for r in valid),
        "within_1s": sum(r.solved and r.verified and r.time_s is not None
                         and r.time_s <= 1.0 for r in valid),
        "median_s": median(r.time_s for r in solved), "p95_s": p95(r.time_s for r in solved),
        "median_call_s": median(r.call_s for r in solved),
        "median_len": median(r.length for r in solved if r.verified),
        "ompl_n": len(om), "ompl_solved": sum(bool(r.ompl_solved) for r in om),
        "ompl_verified": sum(bool(r.ompl_verified) for r in om),
        "ompl_median_s": median(r.ompl_s for r in om if r.ompl_solved),
        "ompl_median_plan_s": median(r.ompl_plan_s for r in om if r.ompl_solved),
        "ompl_median_simplify_s": median(r.ompl_simplify_s for r in om if r.ompl_solved),
        "ompl_p95_s": p95(r.ompl_s for r in om if r.ompl_solved),
        "ompl_median_len": median(r.ompl_length for r in om if r.ompl_verified),
        "both": len(both), "ours_median_on_both_s": median(r.time_s for r in both),
        "ompl_median_on_both_s": median(r.ompl_s for r in both),
        "ours_len_on_both": median(r.length for r in both),
        "ompl_len_on_both": median(r.ompl_length for r in both),
        "ratio": ratio,
    }


def print_tables(rows: list[Row], args) -> None:
    robots = [r for r in ("panda", "ur5") if any(x.robot == r for x in rows)]
    print("\n| robot | family | problems | valid | direct | ours solved | verified | median ms "
          "| p95 ms | median length (rad) | OMPL run | OMPL solved | OMPL verified | OMPL "
          "median ms (median plan + median simplify) | OMPL p95 ms | OMPL median length | "
          "both solved | ours / OMPL median ms on both | OMPL / ours |")
    print("|" + "---|" * 19)
    for robot in robots:
        mine = [r for r in rows if r.robot == robot]
        groups = [(f, [r for r in mine if r.family == f])
                  for f in dict.fromkeys(r.family for r in mine)] + [("**all**", mine)]
        for family, group in groups:
            s = summary(group, args.time_limit)
            print(f"| {robot} | {family} | {s['problems']} | {s['valid']} | {s['direct']} | "
                  f"{s['solved']} | {s['verified']} | {fmt(s['median_s'], 1e3)} | "
                  f"{fmt(s['p95_s'], 1e3)} | {fmt(s['median_len'])} | {s['ompl_n']} | "
                  f"{s['ompl_solved']} | {s['ompl_verified']} | {fmt(s['ompl_median_s'], 1e3, 0)}"
                  f" ({fmt(s['ompl_median_plan_s'], 1e3, 0)} + "
                  f"{fmt(s['ompl_median_simplify_s'], 1e3, 0)}) | {fmt(s['ompl_p95_s'], 1e3, 0)}"
                  f" | {fmt(s['ompl_median_len'])} | {s['both']} | "
                  f"{fmt(s['ours_median_on_both_s'], 1e3)} / "
                  f"{fmt(s['ompl_median_on_both_s'], 1e3, 0)} | {fmt(s['ratio'], 1, 1)} |")
    print(f"\nOMPL: RRT-Connect + simplifyMax, {args.ompl_time:g} s, on the first "
          f"{args.ompl_problems} valid problems of each family" if not args.skip_ompl
          else "\nOMPL: skipped (--skip-ompl)")
    print("median and p95 times over the problems ours solved; lengths over verified paths; "
          "the ratio on the problems both solved (verified). 2 shared cores: timings noisy.")

    print("\n| robot | VAMP (published) | ours |")
    print("|---|---|---|")
    for robot in robots:
        s = summary([r for r in rows if r.robot == robot], args.time_limit)
        v = VAMP[robot]
        print(f"| {robot} | {v['solved']}, median {v['median_us']} us, length "
              f"{v['length']:.2f} rad | {s['solved_valid']}/{s['valid']} valid solved "
              f"({s['verified']} verified), median {fmt(s['median_s'], 1e3, 1)} ms, length "
              f"{fmt(s['median_len'])} rad |")
    print("VAMP: Thomason, Kingston, Kavraki, ICRA 2024; AMD Ryzen 9 7950X, SIMD C++, its own "
          "non-conservative sphere model; 700 problems per robot (ours: the problems above; "
          "the UR5's are generated, not MotionBenchMaker's).")

    print("\nVerdicts (must show):")
    for robot in robots:
        mine = [r for r in rows if r.robot == robot]
        s = summary(mine, args.time_limit)
        ok1 = s["within_limit"] == s["valid"] and s["valid"] > 0
        ok2 = s["verified"] == s["solved"] and s["solved"] > 0
        ok3 = s["ratio"] is not None and s["ratio"] >= 10
        vl = VAMP[robot]["length"]
        ok4 = s["median_len"] is not None and abs(s["median_len"] / vl - 1) <= 0.10
        print(f"  {robot}: every valid problem solved and verified within "
              f"{args.time_limit:g} s: {verdict(ok1)} ({s['within_limit']}/{s['valid']})")
        print(f"  {robot}: every returned path verified: {verdict(ok2)} "
              f"({s['verified']}/{s['solved']})")
        ok_1s = s["within_1s"] == s["valid"] and s["valid"] > 0
        print(f"  {robot}: every valid problem solved and verified within 1 s: "
              f"{verdict(ok_1s)} ({s['within_1s']}/{s['valid']})")
        for what, value, goal in (("median", s["median_s"], 0.005),
                                  ("p95", s["p95_s"], 0.100)):
            print(f"  {robot}: {what} planner time <= {goal * 1e3:g} ms: "
                  f"{verdict(value is not None and value <= goal)} ({fmt(value, 1e3)} ms)")
        print(f"  {robot}: median time >= 10x below OMPL's (same problems): "
              f"{verdict(ok3) if s['ratio'] is not None else 'n/a'} (OMPL / ours = "
              f"{fmt(s['ratio'], 1, 1)} on the {s['both']} problems both solved; OMPL solved "
              f"{s['ompl_solved']}/{s['ompl_n']} within {args.ompl_time:g} s)")
        print(f"  {robot}: median length within 10 % of VAMP's {vl:.2f} rad: {verdict(ok4)} "
              f"({fmt(s['median_len'])} rad"
              + (f", {100 * (s['median_len'] / vl - 1):+.1f} %" if s["median_len"] else "")
              + (")" if robot == "panda" else "; generated problems: indicative only)"))

    failures = [r for r in rows if (r.valid and r.status != "-" and not r.solved)
                or (r.solved and not r.verified) or (not r.valid and r.solved)]
    print(f"\nFailures of ours ({len(failures)}):")
    for r in failures:
        what = f"{r.status}: {r.message}" if not r.solved else f"NOT VERIFIED: {r.verify_why}"
        if not r.valid:
            what = f"solved an invalid problem ({r.invalid_why}); {what}"
        if r.retry_status:
            what += f" [given {args.retry_time:g} s: {r.retry_status} in {fmt(r.retry_s, 1, 1)} s]"
        print(f"  {r.robot} {r.name}: {what}")
    invalid = [r for r in rows if not r.valid]
    if invalid:
        print(f"Invalid problems ({len(invalid)}; ours' status in brackets):")
        for r in invalid:
            print(f"  {r.robot} {r.name}: {r.invalid_why} [{r.status}]")
    ompl_fail = [r for r in rows if r.ompl and not (r.ompl_solved and r.ompl_verified)]
    if ompl_fail:
        print(f"OMPL unsolved or unverified ({len(ompl_fail)}): "
              + ", ".join(f"{r.robot} {r.name}"
                          + ("" if not r.ompl_solved else f" ({r.ompl_why})")
                          for r in ompl_fail))


def print_vamp(rows: list[Row], args, load: tuple[float, float]) -> None:
    """The ``--vamp`` section: ours, VAMP measured in this run and OMPL, side by side."""
    robots = [r for r in ("panda", "ur5")
              if any(x.robot == r and x.vamp_ends_valid is not None for x in rows)]
    print("\n### Ours, VAMP (measured in this run) and OMPL on the same problems\n")
    print("| robot | planner | valid problems run | solved | exact-free (verified / "
          "solved) | median ms | p95 ms | median length (rad) |")
    print("|" + "---|" * 8)
    ratios = []
    for robot in robots:
        valid = [r for r in rows if r.robot == robot and r.valid]
        ours = [r for r in valid if r.solved]
        vs = [r for r in valid if r.vamp_solved]
        om = [r for r in valid if r.ompl]
        oms = [r for r in om if r.ompl_solved]
        vlen_ok = median(r.vamp_length for r in vs if r.vamp_verified)
        print(f"| {robot} | ours | {len(valid)} | {len(ours)} | "
              f"{frac(sum(bool(r.verified) for r in ours), len(ours))} | "
              f"{fmt(median(r.time_s for r in ours), 1e3, 3)} | "
              f"{fmt(p95(r.time_s for r in ours), 1e3, 3)} | "
              f"{fmt(median(r.length for r in ours if r.verified))} |")
        print(f"| {robot} | VAMP, its own ns | {sum(r.vamp for r in valid)} (its model: "
              f"{sum(not r.vamp_ends_valid for r in valid)} with colliding ends) | {len(vs)} | "
              f"{frac(sum(bool(r.vamp_verified) for r in vs), len(vs))} | "
              f"{fmt(median(r.vamp_s for r in vs), 1e3, 3)} | "
              f"{fmt(p95(r.vamp_s for r in vs), 1e3, 3)} | "
              f"{fmt(median(r.vamp_length for r in vs))} (free ones: {fmt(vlen_ok)}) |")
        print(f"| {robot} | VAMP, wall clock | | | | "
              f"{fmt(median(r.vamp_wall_s for r in vs), 1e3, 3)} | "
              f"{fmt(p95(r.vamp_wall_s for r in vs), 1e3, 3)} | |")
        print(f"| {robot} | OMPL RRT-Connect | {len(om)} | {len(oms)} | "
              f"{frac(sum(bool(r.ompl_verified) for r in oms), len(oms))} | "
              f"{fmt(median(r.ompl_s for r in oms), 1e3, 1)} | "
              f"{fmt(p95(r.ompl_s for r in oms), 1e3, 1)} | "
              f"{fmt(median(r.ompl_length for r in oms if r.ompl_verified))} |")
        both = [r for r in valid if r.solved and r.vamp_solved]
        blen = [r for r in both if r.verified]
        t_ours, t_v = median(r.time_s for r in both), median(r.vamp_s for r in both)
        t_w = median(r.vamp_wall_s for r in both)
        l_ours, l_v = median(r.length for r in blen), median(r.vamp_length for r in blen)
        ratios.append(
            f"  {robot}: on the {len(both)} valid problems both solved: ours / VAMP median "
            f"time = {fmt(t_ours, 1e3, 3)} / {fmt(t_v, 1e3, 4)} ms = "
            f"{fmt(t_ours / t_v if t_ours and t_v else None, 1, 0)}x (against VAMP's wall "
            f"clock {fmt(t_w, 1e3, 4)} ms: "
            f"{fmt(t_ours / t_w if t_ours and t_w else None, 1, 0)}x); ours / VAMP median "
            f"length = {fmt(l_ours)} / {fmt(l_v)} rad = "
            f"{fmt(l_ours / l_v if l_ours and l_v else None, 1, 3)} (on the {len(blen)} of "
            f"them ours verified; VAMP's paths counted whether free or not): <= 1.05 "
            f"{verdict(bool(l_ours and l_v and l_ours / l_v <= 1.05))}")
    print("\nRatios:")
    print("\n".join(ratios))
    print("\nVAMP's simplified paths that are not free on the meshes, by the deepest fcl "
          "contact along the path (states every <= "
          f"{args.step:g} rad):")
    for robot in robots:
        bad = [r for r in rows if r.robot == robot and r.valid and r.vamp_solved
               and not r.vamp_verified]
        d = [r.vamp_depth_mm for r in bad]
        n5 = sum(x is not None and x < 5 for x in d)
        n10 = sum(x is not None and 5 <= x < 10 for x in d)
        nbig = sum(x is not None and x >= 10 for x in d)
        deepest = max((x for x in d if x is not None), default=None)
        print(f"  {robot}: {len(bad)} not free: {n5} < 5 mm, {n10} 5-10 mm, {nbig} >= 10 mm "
              f"(deepest {fmt(deepest, 1, 1)} mm); the touching pairs, first failure each: "
              + "; ".join(f"{r.name}: {r.vamp_why.split(': ', 1)[-1]}" for r in bad[:8])
              + (" ..." if len(bad) > 8 else ""))
        valid = [r for r in rows if r.robot == robot and r.vamp_ends_valid is not None]
        a = sum(r.valid and not r.vamp_ends_valid for r in valid)
        b = sum(not r.valid and bool(r.vamp_ends_valid) for r in valid)
        print(f"  {robot}: VAMP's own check of the ends disagrees with the exact one on "
              f"{a + b} problems ({a} free on the meshes but colliding for VAMP, {b} the "
              "other way round)")
    print("\nVAMP's collision check alone (its Python binding, mean of 20000 calls, call "
          "overhead included):")
    for robot in robots:
        c = VAMP_CHECK.get(robot)
        if c:
            print(f"  {robot}: validate(q), one configuration: {c['single_us']:.2f} us; "
                  f"validate_motion over a segment < 8 rad (one SIMD block of 8 "
                  f"configurations{'' if c['motion_free'] else ', not free'}): "
                  f"{c['motion_us']:.2f} us = {c['motion_per_config_us']:.2f} us per "
                  "configuration (the API has no batch call)")
    cores = os.cpu_count() or 1
    print(f"\nVAMP {vref.version()} (RRT-Connect + simplify, Halton sampler, "
          "evaluate_mbm.py's settings), float32 paths verified with 1e-6 rad tolerance on "
          "ends and limits. Ours: time limit "
          f"{args.time_limit:g} s; OMPL on the first {args.ompl_problems} valid problems "
          "of each family. Median and p95 over the solved problems; lengths = joint-space "
          f"Euclidean length of the simplified path. Load average {load[0]:.1f} at the start "
          f"and {load[1]:.1f} at the end on {cores} cores"
          + (": timings on a loaded machine, noisy." if max(load) > 0.5 * cores else "."))


def frac(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else "-"


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robot", choices=("panda", "ur5", "both"), default="both")
    parser.add_argument("--folder", type=Path, default=mbm.PANDA_FOLDER,
                        help="the Panda's MotionBenchMaker folder (family folders)")
    parser.add_argument("--families", nargs="*", default=None)
    parser.add_argument("--limit", type=int, default=None, help="problems per family")
    parser.add_argument("--problems-per-family", type=int, default=20,
                        help="UR5 problems generated per family")
    parser.add_argument("--ur5-seed", type=int, default=mbm.UR5_SEED)
    parser.add_argument("--ur5-folder", type=Path, default=None,
                        help="read (or, when missing, write) the UR5 problems here")
    parser.add_argument("--time-limit", type=float, default=2.0)
    parser.add_argument("--seed", type=int, default=8128)
    parser.add_argument("--step", type=float, default=0.01,
                        help="largest joint step (rad) of the checks along segments")
    parser.add_argument("--retry-time", type=float, default=0.0,
                        help="plan the problems ours fails again with this limit (s): "
                             "tells hard problems from infeasible ones (0: no)")
    parser.add_argument("--ompl-problems", type=int, default=5,
                        help="OMPL runs on this many valid problems per family")
    parser.add_argument("--ompl-time", type=float, default=2.0)
    parser.add_argument("--ompl-seed", type=int, default=4242)
    parser.add_argument("--skip-ompl", action="store_true")
    parser.add_argument("--vamp", action="store_true",
                        help="VAMP in the same run (the default when vamp imports)")
    parser.add_argument("--skip-vamp", action="store_true", help="no VAMP run")
    parser.add_argument("--vamp-max-samples", type=int, default=vref.MAX_SAMPLES,
                        help="cap on VAMP's samples and iterations (0: VAMP's 10^6)")
    parser.add_argument("--json", type=Path, default=None, help="write every row here")
    args = parser.parse_args()
    load0 = os.getloadavg()[0]
    vamp = None
    if not args.skip_vamp:
        vamp, why = vref.load_vamp()
        if vamp is None:
            print(f"VAMP: {why}; only its published figures are printed")
    if not args.skip_ompl:
        from ompl import util as ou

        ou.setLogLevel(ou.LOG_NONE)
        ou.RNG.setSeed(args.ompl_seed)
    motion = load_motion()
    robots = ("panda", "ur5") if args.robot == "both" else (args.robot,)
    panda = mbm.import_named("panda")
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="mbm-") as tmp:
        for name in robots:
            rows += run_robot(name, args, motion, panda, Path(tmp), vamp)
    print_tables(rows, args)
    if vamp is not None:
        print_vamp(rows, args, (load0, os.getloadavg()[0]))
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in rows], indent=1))
        print(f"rows written to {args.json}")


if __name__ == "__main__":
    main()
