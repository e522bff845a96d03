"""VAMP (Kavraki Lab, Apache-2.0), run in the benchmark's process on the same problems.

``bench_motion.py --vamp`` (on by default when ``vamp`` imports) plans every problem with
VAMP's RRT-Connect and simplification, the way VAMP's own ``scripts/evaluate_mbm.py`` does:
``vamp.configure_robot_and_planner_with_kwargs(robot, "rrtc")`` (its default settings: range
1.0 rad for the Panda, 1.5 for the UR5, at most 10^6 iterations), a Halton sampler reset
before each problem, ``planner(start, goal, env, settings, sampler)`` then
``robot.simplify(path, env, simplify_settings, sampler)``. The scene goes to a
``vamp.Environment`` as VAMP's ``resources/problem_tar_to_pkl_json.py`` and
``vamp.problem_dict_to_vamp`` convert a MoveIt scene: each primitive's pose = the object's
``pose`` @ the primitive's pose, orientation as ``sxyz`` Euler angles
(``vamp.transformations.euler_from_matrix``); boxes -> cuboids (half extents), spheres ->
spheres, cylinders -> capsules (``add_capsule``), except in the ``box`` family, where VAMP
over-approximates cylinders by cuboids (half extents r, r, L / 2), "because that family
grasps the can from above". VAMP's converter keeps only the first primitive of an object;
here every primitive is kept (the MotionBenchMaker scenes have one per object).

VAMP works in float32: its paths' ends differ from the float64 start and goal by float32
rounding (~1e-7 rad), so its paths are verified with an end and limit tolerance of 1e-6 rad;
everything else is ``bench_motion.verify``: the exact mesh check (python-fcl), 0.01 rad.

A failing path's *depth*: over every state of every segment sampled as the verifier does
(largest joint step 0.01 rad), the largest penetration depth fcl reports for a contact
(``CollisionRequest(enable_contact=True)``; mesh triangles against the scene's primitives
and against other links' triangles, mm). It is fcl's local depth of a contact, not the
distance the bodies must move apart, but it tells grazes (< 5 mm) from real intrusions.

The import is probed in a subprocess first: a VAMP binary built with ``-march=native`` on a
CPU with AVX-512 dies with SIGILL on one without, which would kill the benchmark.
"""

from __future__ import annotations

import importlib.util
import math
import signal
import subprocess
import sys
import time
from dataclasses import dataclass

import fcl
import numpy as np

#: VAMP's joint tolerance for ends and limits (float32 rounding).
F32_TOL = 1e-6
#: Cap on VAMP's samples and iterations (its default is 10^6): a VAMP built with the linear
#: nearest-neighbour stand-in of build_vamp_wheel.sh costs O(n) per query, so a search that
#: fails would take hours at 10^6 nodes; solved MotionBenchMaker problems use far fewer.
MAX_SAMPLES = 50_000
INSTALL_HINT = ("install a wheel built for this CPU: benchmarks/README.md, "
                "benchmarks/build_vamp_wheel.sh")


def load_vamp():
    """``(vamp module, "")`` or ``(None, why not)``; never crashes the caller."""
    if importlib.util.find_spec("vamp") is None:
        return None, f"VAMP is not installed ({INSTALL_HINT})"
    probe = subprocess.run([sys.executable, "-c", "import vamp; vamp.panda; vamp.ur5"],
                           capture_output=True, text=True, timeout=120)
    if probe.returncode == -signal.SIGILL:
        return None, ("VAMP is installed but its binary uses instructions this CPU lacks "
                      "(illegal instruction: built with -march=native on an AVX-512 CPU); "
                      "rebuild it on this machine (benchmarks/README.md)")
    if probe.returncode != 0:
        last = (probe.stderr.strip().splitlines() or ["?"])[-1]
        return None, f"VAMP is installed but does not import: {last}"
    import vamp

    return vamp, ""


def version() -> str:
    from importlib.metadata import version as dist_version

    try:
        return dist_version("vamp-planner")
    except Exception:  # a report, whatever the install
        return "?"


def _pose(p: dict | None) -> np.ndarray:
    from vamp.transformations import quaternion_matrix, translation_matrix

    if not p:
        return np.eye(4)
    return translation_matrix(p["position"]) @ quaternion_matrix(p["orientation"])


def scene_env(vamp, data: dict, family: str):
    """A ``vamp.Environment`` of a MoveIt PlanningScene dict (metres), VAMP's conversion."""
    from vamp.transformations import euler_from_matrix

    env = vamp.Environment()
    for co in data["world"]["collision_objects"]:
        base = _pose(co.get("pose"))
        for prim, ppose in zip(co.get("primitives", []), co.get("primitive_poses", [])):
            T = base @ _pose(ppose)
            pos = [float(v) for v in T[:3, 3]]
            euler = [float(v) for v in euler_from_matrix(T)]
            d = [float(v) for v in prim["dimensions"]]
            if prim["type"] == "sphere":
                env.add_sphere(vamp.Sphere(pos, d[0]))
            elif prim["type"] == "cylinder":
                length, radius = d[0], d[1]
                if family == "box":
                    env.add_cuboid(vamp.Cuboid(pos, euler, [radius, radius, length / 2]))
                else:
                    env.add_capsule(vamp.Cylinder(pos, euler, radius, length))
            elif prim["type"] == "box":
                env.add_cuboid(vamp.Cuboid(pos, euler, [v / 2 for v in d]))
            else:
                raise ValueError(f"primitive type {prim['type']!r} unknown")
    return env


@dataclass
class VampRobot:
    """VAMP's robot module with the planner, settings and sampler of evaluate_mbm.py."""

    vamp: object
    name: str
    module: object
    planner: object
    plan_settings: object
    simplify_settings: object
    sampler: object

    @classmethod
    def make(cls, vamp, name: str, max_samples: int | None = None) -> VampRobot:
        """``max_samples`` caps the planner's samples and iterations (VAMP's default 10^6):
        see ``MAX_SAMPLES``."""
        module, planner, plan_s, simp_s = vamp.configure_robot_and_planner_with_kwargs(
            name, "rrtc")
        if max_samples:
            plan_s.max_samples = min(plan_s.max_samples, max_samples)
            plan_s.max_iterations = min(plan_s.max_iterations, max_samples)
        return cls(vamp, name, module, planner, plan_s, simp_s, module.halton())


def model_report(vr: VampRobot, robot) -> list[str]:
    """Lines comparing VAMP's joints, limits and end-effector frame with our model's."""
    m = robot.model
    names = list(vr.module.joint_names())
    ours = [j.name for j in m.joints]
    lines = [f"VAMP {vr.name}: {vr.module.dimension()} joints, {vr.module.n_spheres()} spheres"]
    lines.append("  joint order: " + ("same as the URDF's" if names == ours
                                      else f"DIFFERS: VAMP {names} vs ours {ours}"))
    lo = np.asarray(vr.module.lower_bounds(), float)
    hi = np.asarray(vr.module.upper_bounds(), float)
    dev = max(float(np.max(np.abs(lo - m.lower))), float(np.max(np.abs(hi - m.upper))))
    lines.append(f"  joint limits: largest difference from the URDF's {dev:.2e} rad"
                 + ("" if dev < 1e-4 else f" (VAMP {lo.round(4)} .. {hi.round(4)})"))
    # VAMP's end-effector frame against every link of ours, at a few configurations (world
    # frame, metres): the link that matches tells whether both models place the arm alike
    rng = np.random.default_rng(7)
    Q = rng.uniform(m.lower, m.upper, size=(5, m.dof))
    P_v = np.array([np.asarray(vr.module.eefk([float(v) for v in q]), float)[:3, 3] for q in Q])
    P_o = robot.link_poses(Q)[:, :, :3, 3] / 1000.0            # (5, links, 3)
    worst = np.max(np.linalg.norm(P_o - P_v[:, None, :], axis=2), axis=0)
    k = int(np.argmin(worst))
    lines.append(f"  VAMP's end-effector frame: nearest to our link {robot.link_names[k]} "
                 f"(largest distance {1000 * worst[k]:.2f} mm over 5 random configurations)")
    return lines


def plan(vr: VampRobot, env, start: np.ndarray, goal: np.ndarray) -> dict:
    """One problem as evaluate_mbm.py runs it: times (VAMP's ns and wall), path (float64).
    Like evaluate_mbm.py, a problem whose start or goal collides in VAMP's own model is not
    planned (``planned`` False): VAMP's RRT-Connect does not check its ends and would grow
    its tree to ``max_samples``."""
    s, g = [float(v) for v in start], [float(v) for v in goal]
    out = {"solved": False, "planned": False, "plan_ns": None, "plan_wall_s": None,
           "simplify_ns": None, "simplify_wall_s": None, "iterations": None, "tree": None,
           "path": None, "start_valid": bool(vr.module.validate(s, env)),
           "goal_valid": bool(vr.module.validate(g, env))}
    if not (out["start_valid"] and out["goal_valid"]):
        return out
    vr.sampler.reset()
    t = time.perf_counter()
    result = vr.planner(s, g, env, vr.plan_settings, vr.sampler)
    out["plan_wall_s"] = time.perf_counter() - t
    out.update(planned=True, solved=bool(result.solved), plan_ns=int(result.nanoseconds),
               simplify_ns=0, simplify_wall_s=0.0, iterations=int(result.iterations),
               tree=int(sum(result.size)))
    if result.solved:
        t = time.perf_counter()
        simple = vr.module.simplify(result.path, env, vr.simplify_settings, vr.sampler)
        out["simplify_wall_s"] = time.perf_counter() - t
        out["simplify_ns"] = int(simple.nanoseconds)
        out["path"] = np.asarray(simple.path.numpy(), float).reshape(len(simple.path), -1)
    return out


def check_timing(vr: VampRobot, env, q: np.ndarray, q_next: np.ndarray,
                 calls: int = 20000) -> dict:
    """VAMP's collision check alone, through its Python binding: ``validate(q)`` (one
    configuration; VAMP fills one SIMD block with it) and ``validate_motion(q, q_next)``
    (a segment shorter than 8 rad: one block of 8 distinct configurations). Mean of
    ``calls`` calls each; the binding's call overhead is included."""
    mod, qs, qn = vr.module, [float(v) for v in q], [float(v) for v in q_next]
    free_motion = bool(mod.validate_motion(qs, qn, env))
    t = time.perf_counter()
    for _ in range(calls):
        mod.validate(qs, env)
    single = (time.perf_counter() - t) / calls
    t = time.perf_counter()
    for _ in range(calls):
        mod.validate_motion(qs, qn, env)
    motion = (time.perf_counter() - t) / calls
    return {"single_us": single * 1e6, "motion_us": motion * 1e6,
            "motion_per_config_us": motion * 1e6 / 8, "motion_free": free_motion}


def contact_depth_mm(ref, robot, path: np.ndarray, step: float, segment_states) -> float:
    """Largest fcl contact penetration depth (mm) over the verifier's states of ``path``."""
    request = fcl.CollisionRequest(num_max_contacts=64, enable_contact=True)
    deepest = 0.0
    states = [path[:1]] + [segment_states(path[i], path[i + 1], step)[1:]
                           for i in range(len(path) - 1)]
    for P in robot.link_poses(np.concatenate(states)):
        if not ref.collides(P):          # cheap test first; poses are set by it
            continue
        for _, _, obj in ref.objects:
            for other in ref.world:
                res = fcl.CollisionResult()
                if fcl.collide(obj, other, request, res):
                    deepest = max([deepest] + [c.penetration_depth for c in res.contacts])
        for i, j in ref.pairs:
            res = fcl.CollisionResult()
            if fcl.collide(ref.objects[i][2], ref.objects[j][2], request, res):
                deepest = max([deepest] + [c.penetration_depth for c in res.contacts])
    return deepest if math.isfinite(deepest) else float("nan")
