"""Collision checking of two real robots against python-fcl, in the same run.

Imports ``../shared/robots/panda`` and ``../shared/robots/ur5`` (zipped in memory with their
SRDF; ``kinematics.urdf_import``), builds their collision models
(``planning.collision.RobotCollisionModel.from_imported``) and draws ``--configs`` random
in-limit configurations (seed ``--seed``, shared with nothing else). Self-collision at the
SRDF's rules, then the Panda in MotionBenchMaker scenes (``../shared/mbm-dev/panda``).

The reference is written here, independently of ``planning.collision``: an
``fcl.BVHModel`` per link mesh (``fcl.Box`` / ``Cylinder`` / ``Sphere`` for primitives),
posed by the robot's ``link_poses``; every link pair checked except those the robot lists as
adjacent or SRDF-disabled; scene primitives built from the YAML (quaternions by scipy) and
checked against every link. It answers yes/no per configuration, stopping at the first
contact.

Reported: false "free" of the sphere stage (must be 0), the share of free configurations the
spheres alone flag (target <= 2 %), agreement after the exact stage, and times per
configuration, ours vs the reference: one configuration at a time (``--single`` of them) and
in a batch of ``--configs`` (ours: one call; reference: poses batched, then one FCL query per
configuration). Also the motion planner's compiled checker (``planning.motion.MotionChecker``,
the one a planner calls): its answers against the reference and its times, on the spheres alone
and with the exact stage, in a batch and one at a time. The machine has 2 cores shared by
everyone: timings are noisy.

Run: ``.venv/bin/python benchmarks/bench_collision.py [--configs 1000] [--seed 8675309]``
(needs python-fcl, pyyaml and trimesh). Also prints each model's build time, its stored
size (``to_bytes``) and its load time (``from_bytes``), for the GLT palletizer with bone
meshes too (``--robots glt panda ur5``). A report: the exit
status is 0 in any case.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import fcl
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from kinematics.urdf_import import import_robot

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_urdf_import import zip_folder  # noqa: E402

from planning.collision import CollisionScene, RobotCollisionModel, check, collides
from planning.motion import MotionChecker

SHARED = Path(__file__).resolve().parents[2] / "shared"
ROBOTS = (("panda", "panda_arm"), ("ur5", "manipulator"))
SCENES = ("table_pick", "table_under_pick", "bookshelf_small", "bookshelf_tall", "cage", "box")


# ---- the reference (python-fcl only) --------------------------------------------------------
class Reference:
    """FCL objects of every link geometry, the link pairs to check, and scene objects."""

    def __init__(self, robot) -> None:
        self.robot = robot
        self.objects = []       # (link index, T_link_geometry, CollisionObject)
        for k, link in enumerate(robot.links):
            for g in link.collision:
                if g.kind == "mesh":
                    data = robot.meshes[g.mesh]
                    geom = fcl.BVHModel()
                    geom.beginModel(len(data.vertices), len(data.faces))
                    geom.addSubModel(np.asarray(data.vertices, float),
                                     np.asarray(data.faces, np.int64))
                    geom.endModel()
                elif g.kind == "box":
                    geom = fcl.Box(*g.size)
                elif g.kind == "cylinder":
                    geom = fcl.Cylinder(g.radius, g.length)
                else:
                    geom = fcl.Sphere(g.radius)
                self.objects.append((k, np.asarray(g.origin), fcl.CollisionObject(geom)))
        names = [link.name for link in robot.links]
        skip = set(robot.adjacent_pairs) | set(robot.disabled_pairs)
        self.pairs = [(i, j) for i in range(len(self.objects))
                      for j in range(i + 1, len(self.objects))
                      if self.objects[i][0] != self.objects[j][0]
                      and frozenset((names[self.objects[i][0]],
                                     names[self.objects[j][0]])) not in skip]
        self.world: list = []

    def set_scene(self, objects: list) -> None:
        self.world = objects

    def collides(self, poses: np.ndarray) -> bool:
        for k, T, obj in self.objects:
            W = poses[k] @ T
            obj.setTransform(fcl.Transform(W[:3, :3], W[:3, 3]))
        request = fcl.CollisionRequest()
        for _, _, obj in self.objects:
            for other in self.world:
                if fcl.collide(obj, other, request, fcl.CollisionResult()):
                    return True
        for i, j in self.pairs:
            if fcl.collide(self.objects[i][2], self.objects[j][2], request,
                           fcl.CollisionResult()):
                return True
        return False


def mbm_scene(path: Path) -> tuple[list, dict]:
    """FCL objects of a MotionBenchMaker scene (mm), and the YAML's PlanningScene dict."""
    data = yaml.safe_load(path.read_text())
    objects = []
    for co in data["world"]["collision_objects"]:
        base = np.eye(4)
        if co.get("pose"):
            base[:3, :3] = Rotation.from_quat(co["pose"]["orientation"]).as_matrix()
            base[:3, 3] = np.asarray(co["pose"]["position"]) * 1000
        for prim, pose in zip(co.get("primitives", []), co.get("primitive_poses", [])):
            T = np.eye(4)
            T[:3, :3] = Rotation.from_quat(pose["orientation"]).as_matrix()
            T[:3, 3] = np.asarray(pose["position"]) * 1000
            T = base @ T
            d = np.asarray(prim["dimensions"]) * 1000
            if prim["type"] == "box":
                geom = fcl.Box(*d)
            elif prim["type"] == "sphere":
                geom = fcl.Sphere(d[0])
            else:
                geom = fcl.Cylinder(d[1], d[0])
            objects.append(fcl.CollisionObject(geom, fcl.Transform(T[:3, :3], T[:3, 3])))
    return objects, data


# ---- timing ---------------------------------------------------------------------------------
def per_config(seconds: float, n: int) -> str:
    return f"{seconds / n * 1e6:8.1f} us"


def compare(name: str, robot, cm, Q: np.ndarray, single: int, scene=None, ref=None) -> dict:
    """Answers and times of ours and the reference on ``Q``."""
    ref = ref or Reference(robot)
    t = time.perf_counter()
    poses = robot.link_poses(Q)
    truth = np.array([ref.collides(P) for P in poses])
    t_ref_batch = time.perf_counter() - t
    t = time.perf_counter()
    for q in Q[:single]:
        ref.collides(robot.link_poses(q))
    t_ref_single = time.perf_counter() - t

    collides(cm, Q[:8], scene)                      # first use builds the scene's structures
    check(cm, Q[:8], scene)
    t = time.perf_counter()
    spheres = collides(cm, Q, scene)
    t_sph = time.perf_counter() - t
    t = time.perf_counter()
    exact = collides(cm, Q, scene, exact=True)
    t_exact = time.perf_counter() - t
    t = time.perf_counter()
    report = check(cm, Q, scene)
    t_check = time.perf_counter() - t
    t = time.perf_counter()
    for q in Q[:single]:
        collides(cm, q, scene)
    t_sph1 = time.perf_counter() - t
    t = time.perf_counter()
    for q in Q[:single]:
        collides(cm, q, scene, exact=True)
    t_exact1 = time.perf_counter() - t
    t = time.perf_counter()
    robot.link_poses(Q)
    t_poses = time.perf_counter() - t
    # The motion planner's compiled checker (planning.motion.MotionChecker), same answers.
    mc = MotionChecker(cm, scene)
    mc.free(Q[:8])
    mc.exact = False
    t = time.perf_counter()
    m_sph = mc.free(Q)
    t_msph = time.perf_counter() - t
    mc.exact = True
    t = time.perf_counter()
    m_exact = mc.free(Q)
    t_mexact = time.perf_counter() - t
    t = time.perf_counter()
    for q in Q[:single]:
        mc.free(q)
    t_mexact1 = time.perf_counter() - t

    free = ~truth
    row = {
        "case": name, "configs": len(Q), "colliding": float(truth.mean()),
        "false_free": int(np.sum(truth & ~spheres)),
        "flagged_free": float(np.sum(spheres & free) / max(free.sum(), 1)),
        "agree_exact": float(np.mean(exact == truth)),
        "agree_check": float(np.mean(report.collides == truth)),
        "t_ref_single": t_ref_single / single, "t_ref_batch": t_ref_batch / len(Q),
        "t_sph_single": t_sph1 / single, "t_exact_single": t_exact1 / single,
        "t_sph_batch": t_sph / len(Q), "t_exact_batch": t_exact / len(Q),
        "t_check_batch": t_check / len(Q), "t_poses_batch": t_poses / len(Q),
        "motion_false_free": int(np.sum(truth & m_sph)) + int(np.sum(truth & m_exact)),
        "motion_agree_exact": float(np.mean(m_exact == ~truth)),
        "t_motion_spheres_batch": t_msph / len(Q), "t_motion_exact_batch": t_mexact / len(Q),
        "t_motion_exact_single": t_mexact1 / single,
    }
    print(f"  {name}: reference collides in {row['colliding']:.1%}; spheres: false free "
          f"{row['false_free']} (must be 0), flag {row['flagged_free']:.2%} of the free "
          f"(target <= 2 %); after the exact stage: collides(exact) agrees "
          f"{row['agree_exact']:.2%}, check agrees {row['agree_check']:.2%}")
    print(f"    per configuration, one at a time: ours spheres {per_config(t_sph1, single)}, "
          f"ours exact {per_config(t_exact1, single)}, fcl {per_config(t_ref_single, single)}")
    print(f"    per configuration, batch of {len(Q)}: ours spheres "
          f"{per_config(t_sph, len(Q))}, ours exact {per_config(t_exact, len(Q))}, "
          f"check {per_config(t_check, len(Q))}, fcl {per_config(t_ref_batch, len(Q))} "
          f"(link_poses alone {per_config(t_poses, len(Q))})")
    print(f"    motion planner's compiled checker: false free {row['motion_false_free']}, "
          f"exact agrees {row['motion_agree_exact']:.2%}; batch of {len(Q)}: spheres "
          f"{per_config(t_msph, len(Q))}, exact {per_config(t_mexact, len(Q))} "
          f"(1,000 in {t_mexact / len(Q) * 1e6:.1f} ms); one at a time exact "
          f"{per_config(t_mexact1, single)}")
    return row


def glt_robot():
    """The GLT palletizer as a URDF with six bone meshes (2,400 triangles), as the viewer's
    tests write it."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.web.conftest import glt_archive

    return import_robot(glt_archive(), "glt.zip", robot_id="glt")


def build_and_store(name: str, robot, builds: list) -> RobotCollisionModel:
    """Build the robot's collision model, store it and load it back (timed)."""
    t = time.perf_counter()
    cm = RobotCollisionModel.from_imported(robot)
    built = time.perf_counter() - t
    data = cm.to_bytes()
    t = time.perf_counter()
    loaded = RobotCollisionModel.from_bytes(data, robot)
    t_load = time.perf_counter() - t
    assert len(loaded.tables) == len(cm.tables)
    info = cm.describe()
    print(f"{name}: {len(cm.names)} links with geometry, {info['spheres']} spheres, "
          f"{len(cm.pairs)} self pairs ({len(cm.tables)} by table), model built in "
          f"{built:.1f} s, {len(data) / 1024:.0f} kB stored, loaded in {t_load * 1e3:.0f} ms")
    builds.append((name, built, t_load, len(data)))
    return cm


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--configs", type=int, default=1000)
    parser.add_argument("--single", type=int, default=200)
    parser.add_argument("--seed", type=int, default=8675309)
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--robots", nargs="*", default=["glt", *(r for r, _ in ROBOTS)])
    args = parser.parse_args()
    rows = []
    builds: list[tuple[str, float, float, int]] = []
    rng = np.random.default_rng(args.seed)
    if "glt" in args.robots:
        build_and_store("glt (meshed, tests/web/conftest.py)", glt_robot(), builds)
    for name, group in ROBOTS:
        if name not in args.robots:
            continue
        folder = SHARED / "robots" / name
        robot = import_robot(zip_folder(folder), f"{name}.zip", robot_id=name, group=group)
        cm = build_and_store(name, robot, builds)
        m = robot.model
        Q = rng.uniform(m.lower, m.upper, size=(args.configs, m.dof))
        rows.append(compare(f"{name} self", robot, cm, Q, args.single))
        if name == "panda":
            ref = Reference(robot)
            for family in args.scenes:
                objects, data = mbm_scene(SHARED / "mbm-dev" / "panda" / family /
                                          "scene0001.yaml")
                ref.set_scene(objects)
                t = time.perf_counter()
                scene = CollisionScene.from_moveit(data)
                scene.compiled()
                print(f"  {family}: {len(scene)} objects, scene built in "
                      f"{time.perf_counter() - t:.2f} s")
                rows.append(compare(f"panda {family}", robot, cm, Q, args.single, scene, ref))
    print()
    print("| robot | build (s) | load from bytes (ms) | stored size (kB) |")
    print("|---|---|---|---|")
    for name, built, loaded, size in builds:
        print(f"| {name} | {built:.1f} | {loaded * 1e3:.0f} | {size / 1024:.0f} |")
    print()
    print("| case | colliding | false free | spheres flag (of free) | agreement after exact "
          "| single: ours spheres / exact / fcl (us) | batch: ours spheres / exact / check / "
          "fcl (us per config) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['colliding']:.1%} | {r['false_free']} | "
              f"{r['flagged_free']:.2%} | {r['agree_exact']:.2%} | "
              f"{r['t_sph_single'] * 1e6:.0f} / {r['t_exact_single'] * 1e6:.0f} / "
              f"{r['t_ref_single'] * 1e6:.0f} | {r['t_sph_batch'] * 1e6:.1f} / "
              f"{r['t_exact_batch'] * 1e6:.1f} / {r['t_check_batch'] * 1e6:.1f} / "
              f"{r['t_ref_batch'] * 1e6:.1f} |")


if __name__ == "__main__":
    main()
