"""MotionBenchMaker problems for ``bench_motion.py``: read a shipped set, generate a UR5 set.

**Reading** (``load_problems``): a folder of family folders, each holding MoveIt YAML pairs
``sceneNNNN.yaml`` (a ``PlanningScene``, metres) and ``requestNNNN.yaml`` (a
``MotionPlanRequest``: ``start_state.joint_state`` names and positions, and
``goal_constraints[0].joint_constraints``, one per arm joint). Start and goal come back in the
robot model's joint order; joints that are not the model's (the Panda's fingers) are returned
beside them and must equal the robot's fixed values (the caller checks them).

**Generating** (``generate_ur5``), "like MotionBenchMaker's" for the UR5 with its Robotiq 85
gripper, since the UR5 problems MotionBenchMaker ships are not in the shared folder. For
problem ``k`` of a family:

1. *Scene*: the Panda scene ``((k - 1) mod 20) + 1`` of the same family, every object moved
   rigidly by ``T_world_scene = T_world_base @ Trans(0, 0, UR5_SHOULDER - PANDA_SHOULDER)``:
   ``T_world_base`` is the UR5's base link in the world (the URDF's ``offset_joint`` puts it
   0.9144 m above the world origin, turned 1.57 rad about z) and the drop of 0.2438 m keeps
   every object at the height above the shoulder joint that it has for the Panda (shoulder
   axes 0.333 m and 0.0892 m above the bases); the Panda's front (+x of ``panda_link0``)
   becomes the UR5's (+x of ``base_link``, where its arm points at q = 0). Both arms reach
   about 0.85 m from the shoulder, so the objects stay within reach.
2. *Target*: the object the Panda's goal grasps (the one whose centre is nearest to
   ``panda_grasptarget`` at the Panda's goal configuration of that scene).
3. *Goal*: a grasp of the target near its top, as the Panda's goals hold theirs (their grasp
   point is 17-35 mm under the can's top, approaching horizontally; in the box family from
   above, at the top; 5 mm under the cage cube's top). The grasp point goes between the
   finger tips, ``GRASP_DEPTH`` (190 mm) ahead of ``ee_link`` along its approach axis (x)
   plus a standoff drawn in [0, 20] mm, the fingers closing along a horizontal axis.
   Cylinders from a side: heading within +-50 deg of the direction from the shoulder axis
   to the object, grasp point 15-45 mm under the top; from above (the box family): any
   heading, 15-35 mm under the top. Boxes (the cage's cube): along a face normal within
   +-70 deg of that direction (any, from above), jittered by up to 4 deg, the fingers
   across two opposite faces, 5-20 mm above the centre. ``ee_link`` targets go to the
   project's numeric IK (``kinematics.ik.solve_ik``, method ``numeric``, 8 restarts, the
   first seed configuration drawn uniformly within the limits, so any IK branch can come
   out); a solution is kept
   when it is within the joint limits, reaches the pose (1e-3 mm, 1e-5 rad) and is free under
   the exact mesh check (python-fcl, ``bench_collision.Reference``) against the scene, the
   target included, and the SRDF's self-collision rules. At most ``ATTEMPTS`` (200) draws;
   if none succeeds the scene's other objects of the same kind are tried in a drawn order,
   then the number ``k`` is left out (printed) and the next one takes its place, so a family
   has ``per_family`` problems whose numbers may skip (the cage's cube is out of the UR5's
   reach in some scenes).
4. *Start*: ``Q_READY`` (tool 0.24 m in front of the base at shoulder height + 0.26 m,
   pointing down, like the Panda's ready pose), the same for every problem, as
   MotionBenchMaker's Panda problems do; if it collides in the scene, a free configuration
   drawn around it (normal, 0.3 rad per joint). ``table_under_pick`` starts, as the Panda's
   do, from a grasp-like pose under the table top: a horizontal approach at a point drawn
   120-320 mm below the top's underside, inside its footprint and within 0.8 m of the
   shoulder, solved and checked as in 3.

Every random draw comes from ``numpy.random.default_rng(SeedSequence([seed, family number,
k]))``: a problem depends only on ``seed`` (``UR5_SEED``, used nowhere else), its family and
``k``, not on which other problems are generated, so ``--families`` and ``--limit`` runs see
the same problems as the full set. The generated pairs are written in the same MoveIt YAML
format, so they are read back by ``load_problems`` like the shipped ones.

Run alone to write a set: ``.venv/bin/python benchmarks/mbm_problems.py OUT_DIR
[--problems-per-family 20] [--seed 5318008]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_collision import SHARED, Reference, mbm_scene  # noqa: E402
from bench_urdf_import import zip_folder  # noqa: E402

from kinematics.urdf_import import import_robot  # noqa: E402

FAMILIES = ("bookshelf_small", "bookshelf_tall", "bookshelf_thin", "box", "cage",
            "table_pick", "table_under_pick")
PANDA_FOLDER = SHARED / "mbm-dev" / "panda"
ROBOTS = {"panda": "panda_arm", "ur5": "manipulator"}

#: Seed of the UR5 problem generator; shared with nothing in the planner.
UR5_SEED = 5318008
#: Height of the shoulder (second) joint's axis above the base link (m), from the URDFs.
PANDA_SHOULDER = 0.333
UR5_SHOULDER = 0.089159
#: The UR5's start configuration (rad), tool in front of and above the base, pointing down.
Q_READY = np.array([0.0, -2.2, 2.2, -1.571, -1.571, 0.0])
#: Object centre ahead of ``ee_link`` (mm) when grasped: between the Robotiq finger tips (the
#: pads span 137-194 mm, the palm's inner knuckles end at 156 mm).
GRASP_DEPTH = 190.0
ATTEMPTS = 200
#: Families whose Panda goals grasp from above (the others approach horizontally).
FROM_ABOVE = ("box",)
#: Problems numbers tried per problem asked for, when some scenes give no grasp.
MAX_DRAWS = 3


@dataclass(frozen=True)
class Problem:
    """One planning problem: joint values in the robot model's order (rad)."""

    robot: str
    family: str
    index: int                       # NNNN of the file names, from 1
    scene_path: Path
    scene: dict = field(repr=False)  # the PlanningScene as parsed (metres)
    start: np.ndarray = field(repr=False)
    goal: np.ndarray = field(repr=False)
    other_joints: dict = field(default_factory=dict, repr=False)  # start-state joints off the arm

    @property
    def name(self) -> str:
        return f"{self.family}/{self.index:04d}"


def read_request(path: Path, joint_names: list[str]) -> tuple[np.ndarray, np.ndarray, dict]:
    """Start ``(dof,)``, goal ``(dof,)`` in ``joint_names``' order, and the start state's other
    joints ``{name: value}``."""
    data = yaml.safe_load(path.read_text())
    js = data["start_state"]["joint_state"]
    values = dict(zip(js["name"], js["position"], strict=True))
    goals = {c["joint_name"]: c["position"]
             for c in data["goal_constraints"][0]["joint_constraints"]}
    missing = [n for n in joint_names if n not in values or n not in goals]
    if missing:
        raise ValueError(f"{path}: no start or goal value for joints {missing}")
    start = np.array([values[n] for n in joint_names], float)
    goal = np.array([goals[n] for n in joint_names], float)
    other = {n: float(v) for n, v in values.items() if n not in joint_names}
    return start, goal, other


def load_problems(folder: Path, robot: str, joint_names: list[str],
                  families: list[str] | None = None, limit: int | None = None) -> list[Problem]:
    """Problems of ``folder/<family>/`` (families in ``FAMILIES`` order, then any other
    folder), the first ``limit`` of each, by index."""
    folder = Path(folder)
    present = [p.name for p in sorted(folder.iterdir()) if p.is_dir()]
    order = [f for f in FAMILIES if f in present] + [f for f in present if f not in FAMILIES]
    problems = []
    for family in order:
        if families and family not in families:
            continue
        requests = sorted((folder / family).glob("request*.yaml"))[:limit]
        for req in requests:
            index = int(req.stem.removeprefix("request"))
            scene_path = folder / family / f"scene{index:04d}.yaml"
            start, goal, other = read_request(req, joint_names)
            problems.append(Problem(robot, family, index, scene_path,
                                    yaml.safe_load(scene_path.read_text()), start, goal, other))
    return problems


def import_named(name: str):
    """``../shared/robots/<name>`` imported with its SRDF group (``ROBOTS``)."""
    return import_robot(zip_folder(SHARED / "robots" / name), f"{name}.zip", robot_id=name,
                        group=ROBOTS[name])


def scene_ids(data: dict) -> list[str]:
    """Names of the shapes ``bench_collision.mbm_scene`` builds, in its order."""
    ids = []
    for co in data["world"]["collision_objects"]:
        prims = co.get("primitives", [])
        for j in range(min(len(prims), len(co.get("primitive_poses", [])))):
            ids.append(co["id"] if len(prims) == 1 else f"{co['id']}/{j}")
    return ids


# ---- writing MoveIt YAML ----------------------------------------------------------------------
def _pose_dict(T_m: np.ndarray) -> dict:
    q = Rotation.from_matrix(T_m[:3, :3]).as_quat()
    return {"position": [float(v) for v in T_m[:3, 3]], "orientation": [float(v) for v in q]}


def _pose_matrix(pose: dict | None) -> np.ndarray:
    T = np.eye(4)
    if pose:
        T[:3, :3] = Rotation.from_quat(pose["orientation"]).as_matrix()
        T[:3, 3] = pose["position"]
    return T


def moved_scene(data: dict, T_world_scene_m: np.ndarray, robot_name: str) -> dict:
    """The PlanningScene's collision objects moved rigidly by ``T_world_scene_m`` (metres)."""
    objects = []
    for co in data["world"]["collision_objects"]:
        objects.append({
            "id": co["id"],
            "pose": _pose_dict(T_world_scene_m @ _pose_matrix(co.get("pose"))),
            "primitives": co.get("primitives", []),
            "primitive_poses": co.get("primitive_poses", []),
        })
    return {"name": data.get("name", ""), "robot_model_name": robot_name,
            "world": {"collision_objects": objects}}


def request_dict(group: str, joint_names: list[str], start, goal) -> dict:
    return {
        "group_name": group,
        "start_state": {"joint_state": {"name": list(joint_names),
                                        "position": [float(v) for v in start]}},
        "goal_constraints": [{"joint_constraints": [
            {"joint_name": n, "position": float(v)} for n, v in zip(joint_names, goal)]}],
    }


# ---- UR5 generation ---------------------------------------------------------------------------
@dataclass
class _Grasping:
    """What the generator needs of the UR5: model, exact check, fixed transforms."""

    robot: object
    ref: Reference
    p_shoulder: np.ndarray      # (3,) mm, the shoulder joint's axis point in the world

    @property
    def model(self):
        return self.robot.model

    def free(self, q: np.ndarray) -> bool:
        return not self.ref.collides(self.robot.link_poses(q))

    def solve(self, T_world_ee: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        from kinematics.ik import NumericOptions, solve_ik

        m = self.model
        q0 = rng.uniform(m.lower, m.upper)
        opts = NumericOptions(seed=int(rng.integers(2**31)), restarts=8)
        result = solve_ik(m, T_world_ee, method="numeric", q0=q0, options=opts)[0]
        if not result.success:
            return None
        q = np.asarray(result.q, float)
        T = self.robot.link_pose(self.robot.tip_link, q)
        if np.any(q < m.lower) or np.any(q > m.upper) \
                or np.linalg.norm(T[:3, 3] - T_world_ee[:3, 3]) > 1e-3 \
                or np.linalg.norm(Rotation.from_matrix(
                    T[:3, :3].T @ T_world_ee[:3, :3]).as_rotvec()) > 1e-5:
            return None
        return q if self.free(q) else None


def _approach_pose(center_mm: np.ndarray, heading: float, pitch: float, standoff: float,
                   flip: bool) -> np.ndarray:
    """``T_world_ee`` whose finger tips hold ``center_mm``: approach (ee x) at ``heading``
    (rad about the world z) tilted down by ``pitch`` (rad; pi/2 = from above), closing axis
    (ee y) horizontal, across the heading (``flip``: the other way round)."""
    x = np.array([math.cos(heading) * math.cos(pitch), math.sin(heading) * math.cos(pitch),
                  -math.sin(pitch)])
    y = np.array([-math.sin(heading), math.cos(heading), 0.0]) * (-1.0 if flip else 1.0)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, np.cross(x, y)])
    T[:3, 3] = center_mm - (GRASP_DEPTH + standoff) * x
    return T


def _grasp(g: _Grasping, obj: dict, from_above: bool,
           rng: np.random.Generator) -> np.ndarray | None:
    """A free configuration grasping the object dict (``scene_from_moveit`` form, mm) near
    its top: from a side (horizontal approach) or ``from_above``."""
    T_obj = np.asarray(obj["pose"], float)
    up = T_obj[:3, 2]
    top = obj["height"] / 2 if obj["type"] == "cylinder" else obj["size"][2] / 2
    shoulder = g.p_shoulder
    toward = math.atan2(T_obj[1, 3] - shoulder[1], T_obj[0, 3] - shoulder[0])
    for _ in range(ATTEMPTS):
        standoff = rng.uniform(0.0, 20.0)
        flip = bool(rng.integers(2))
        if obj["type"] == "box":
            # the fingers across two opposite faces: headings along the face normals
            normals = math.atan2(T_obj[1, 0], T_obj[0, 0]) + np.arange(4) * math.pi / 2
            gap = (normals - toward + math.pi) % (2 * math.pi) - math.pi
            facing = normals if from_above else normals[np.abs(gap) <= math.radians(70)]
            heading = rng.choice(facing) + math.radians(rng.uniform(-4.0, 4.0))
        elif from_above:
            heading = rng.uniform(-math.pi, math.pi)
        else:
            heading = toward + math.radians(rng.uniform(-50.0, 50.0))
        if from_above:
            depth = rng.uniform(15.0, 35.0)
        elif obj["type"] == "box":
            depth = top - rng.uniform(5.0, 20.0)
        else:
            depth = rng.uniform(15.0, 45.0)
        center = T_obj[:3, 3] + up * max(top - depth, 0.0)
        pitch = math.pi / 2 if from_above else 0.0
        q = g.solve(_approach_pose(center, heading, pitch, standoff, flip), rng)
        if q is not None:
            return q
    return None


def _under_table(g: _Grasping, table: dict, rng: np.random.Generator) -> np.ndarray | None:
    """A free configuration with the finger tips under the table top (``table_under_pick``)."""
    T = np.asarray(table["pose"], float)
    sx, sy, sz = table["size"]
    shoulder = g.p_shoulder
    for _ in range(ATTEMPTS):
        local = np.array([rng.uniform(-sx / 2, sx / 2), rng.uniform(-sy / 2, sy / 2),
                          -sz / 2 - rng.uniform(120.0, 320.0)])
        p = T[:3, :3] @ local + T[:3, 3]
        if np.linalg.norm(p - shoulder) > 800.0:
            continue
        toward = math.atan2(p[1] - shoulder[1], p[0] - shoulder[0])
        heading = toward + math.radians(rng.uniform(-50.0, 50.0))
        q = g.solve(_approach_pose(p, heading, 0.0, 0.0, bool(rng.integers(2))), rng)
        if q is not None:
            return q
    return None


def _start(g: _Grasping, rng: np.random.Generator) -> np.ndarray | None:
    if g.free(Q_READY):
        return Q_READY.copy()
    m = g.model
    for _ in range(ATTEMPTS):
        q = np.clip(Q_READY + rng.normal(0.0, 0.3, m.dof), m.lower, m.upper)
        if g.free(q):
            return q
    return None


def generate_ur5(out: Path, ur5, panda, families=FAMILIES, per_family: int = 20,
                 seed: int = UR5_SEED, log=print) -> list[str]:
    """Write ``out/<family>/sceneNNNN.yaml`` and ``requestNNNN.yaml`` for the UR5 (imported
    robot ``ur5``; ``panda`` to find the Panda goals' grasped objects). Returns the names of
    the problems left out (no grasp found)."""
    from planning.collision.moveit import scene_from_moveit

    names = [j.name for j in ur5.model.joints]
    panda_names = [j.name for j in panda.model.joints]
    T_world_base_m = np.array(ur5.model.base, float)
    T_world_base_m[:3, 3] /= 1000.0
    drop = np.eye(4)
    drop[2, 3] = UR5_SHOULDER - PANDA_SHOULDER
    T_world_scene_m = T_world_base_m @ drop
    T_world_scene = T_world_scene_m.copy()
    T_world_scene[:3, 3] *= 1000.0
    p_shoulder = (T_world_base_m @ np.array([0.0, 0.0, UR5_SHOULDER, 1.0]))[:3] * 1000.0
    g = _Grasping(ur5, Reference(ur5), p_shoulder)
    grasp_link = panda.link_names.index("panda_grasptarget")
    left_out = []
    for f_number, family in enumerate(FAMILIES):
        if family not in families:
            continue
        (out / family).mkdir(parents=True, exist_ok=True)
        made = 0
        for k in range(1, MAX_DRAWS * per_family + 1):
            if made == per_family:
                break
            rng = np.random.default_rng(np.random.SeedSequence([seed, f_number, k]))
            source = ((k - 1) % 20) + 1
            panda_scene = yaml.safe_load(
                (PANDA_FOLDER / family / f"scene{source:04d}.yaml").read_text())
            _, panda_goal, _ = read_request(PANDA_FOLDER / family / f"request{source:04d}.yaml",
                                            panda_names)
            scene = moved_scene(panda_scene, T_world_scene_m, "ur5")
            scene_path = out / family / f"scene{k:04d}.yaml"
            scene_path.write_text(yaml.safe_dump(scene, sort_keys=False))
            g.ref.set_scene(mbm_scene(scene_path)[0])
            objects = scene_from_moveit(scene)
            p_grasp = panda.link_poses(panda_goal)[grasp_link][:3, 3]
            p_grasp = (T_world_scene @ np.append(p_grasp, 1.0))[:3]
            ranked = sorted(objects, key=lambda o: np.linalg.norm(
                np.asarray(o["pose"])[:3, 3] - p_grasp))
            target = ranked[0]
            alike = [o for o in objects if o is not target and o["type"] == target["type"]
                     and o["id"].rstrip("0123456789") == target["id"].rstrip("0123456789")]
            candidates = [target] + [alike[i] for i in rng.permutation(len(alike))]
            goal = None
            for obj in candidates:
                goal = _grasp(g, obj, family in FROM_ABOVE, rng)
                if goal is not None:
                    break
            if family == "table_under_pick":
                table = next(o for o in objects if o["id"] == "table_top")
                start = _under_table(g, table, rng)
            else:
                start = _start(g, rng)
            if goal is None or start is None:
                left_out.append(f"{family}/{k:04d}")
                log(f"  ur5 {family}/{k:04d}: no free {'goal' if goal is None else 'start'} "
                    "found; left out (the next number takes its place)")
                scene_path.unlink()
                continue
            if family != "table_under_pick" and not np.array_equal(start, Q_READY):
                log(f"  ur5 {family}/{k:04d}: the ready configuration collides; start drawn "
                    "around it")
            (out / family / f"request{k:04d}.yaml").write_text(yaml.safe_dump(
                request_dict(ROBOTS["ur5"], names, start, goal), sort_keys=False))
            made += 1
    return left_out


def main() -> None:
    parser = argparse.ArgumentParser(description="Write the UR5 problem set (MoveIt YAML).")
    parser.add_argument("out", type=Path)
    parser.add_argument("--problems-per-family", type=int, default=20)
    parser.add_argument("--families", nargs="*", default=list(FAMILIES))
    parser.add_argument("--seed", type=int, default=UR5_SEED)
    args = parser.parse_args()
    left_out = generate_ur5(args.out, import_named("ur5"), import_named("panda"),
                            args.families, args.problems_per_family, args.seed)
    print(f"written to {args.out}; left out: {left_out or 'none'}")


if __name__ == "__main__":
    main()
