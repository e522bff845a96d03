"""URDF import of two real robots, checked link by link against yourdfpy.

Zips ``../shared/robots/ur5`` and ``../shared/robots/panda`` in memory (folder and all, so the
URDF sits in a sub-folder of the archive and its ``package://meshes/...`` references go
through the lookup rules), imports them with their SRDF groups (UR5: ``manipulator``,
``base_link`` -> ``ee_link``; Panda: ``panda_arm``, ``panda_link0`` -> ``panda_link8``) and
prints the import time (median of ``--repeats`` runs), the chain, the links, the meshes and
their triangle counts. Then, over ``--configs`` random in-limit configurations (seeded), it
compares with yourdfpy, an independent URDF reader loading the same URDF file: the tip
link's pose (our ``fk`` of the model) and the pose of every link (``link_poses``) against
yourdfpy's ``get_transform(link, root)``, position error in mm and rotation error in rad.
Target: position error <= 1e-9 mm everywhere.

Run: ``.venv/bin/python benchmarks/bench_urdf_import.py [--configs 1000] [--seed 20261129]``
(about half a minute; needs yourdfpy from the ``test`` extra). It is a report: the exit
status is 0 in any case.
"""

from __future__ import annotations

import argparse
import io
import logging
import statistics
import time
import zipfile
from pathlib import Path

import numpy as np
import yourdfpy

from kinematics.fk import fk
from kinematics.transforms import rotation_angle
from kinematics.urdf_import import ImportedRobot, import_robot

ROBOTS = Path(__file__).resolve().parents[2] / "shared" / "robots"
CASES = (("ur5", "ur5.urdf", "manipulator"), ("panda", "panda.urdf", "panda_arm"))
TARGET_MM = 1e-9


def zip_folder(folder: Path) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                zf.write(path, path.relative_to(folder.parent).as_posix())
    return buffer.getvalue()


def describe(robot: ImportedRobot) -> None:
    model = robot.model
    print(f"  chain {robot.base_link} -> {robot.tip_link}: {model.dof} joints "
          f"({', '.join(j.name for j in model.joints)})")
    print(f"  links {len(robot.links)}, adjacent pairs {len(robot.adjacent_pairs)}, "
          f"SRDF-disabled pairs {len(robot.disabled_pairs)}")
    used = {}
    for link in robot.links:
        for kind, shapes in (("collision", link.collision), ("visual", link.visual)):
            for g in shapes:
                if g.kind == "mesh":
                    used.setdefault(g.mesh, set()).add(kind)
    print(f"  meshes {len(robot.meshes)}, {robot.triangles:,} triangles in all:")
    for key in sorted(robot.meshes):
        mesh = robot.meshes[key]
        print(f"    {key:<48} {mesh.triangles:>7,} triangles  "
              f"({'/'.join(sorted(used.get(key, ())))})")


def compare(robot: ImportedRobot, urdf_path: Path, configs: int, seed: int) -> None:
    model = robot.model
    reference = yourdfpy.URDF.load(str(urdf_path), load_meshes=False,
                                   build_collision_scene_graph=False,
                                   load_collision_meshes=False)
    rng = np.random.default_rng(seed)
    qs = rng.uniform(model.lower, model.upper, (configs, model.dof))
    scale = np.where(model.revolute, 1.0, 1e-3)  # our q (rad, mm) as URDF values (rad, m)

    robot.link_poses(qs[:2])  # first-call costs (imports, caches) are not the batch's
    fk(model, qs[:2])
    start = time.perf_counter()
    ours = robot.link_poses(qs)
    ours_tip = fk(model, qs)
    ours_s = time.perf_counter() - start

    names = robot.link_names
    theirs = np.empty_like(ours)
    start = time.perf_counter()
    for n, q in enumerate(qs):
        reference.update_cfg({j.name: float(v) for j, v in zip(model.joints, q * scale)})
        for k, name in enumerate(names):
            theirs[n, k] = reference.get_transform(name, robot.root_link)
    theirs_s = time.perf_counter() - start
    theirs[..., :3, 3] *= 1000.0

    tip = names.index(robot.tip_link)
    tip_dp = np.linalg.norm(ours_tip[:, :3, 3] - theirs[:, tip, :3, 3], axis=-1)
    tip_dr = rotation_angle(np.swapaxes(ours_tip[:, :3, :3], -1, -2) @ theirs[:, tip, :3, :3])
    dp = np.linalg.norm(ours[..., :3, 3] - theirs[..., :3, 3], axis=-1)
    dr = rotation_angle(np.swapaxes(ours[..., :3, :3], -1, -2) @ theirs[..., :3, :3])
    worst = names[int(np.argmax(dp.max(axis=0)))]
    print(f"  FK vs yourdfpy over {configs} random in-limit configurations (seed {seed}):")
    print(f"    tip '{robot.tip_link}' (fk):  max position error {tip_dp.max():.3e} mm, "
          f"max rotation error {tip_dr.max():.3e} rad  "
          f"{'PASS' if tip_dp.max() <= TARGET_MM else 'FAIL'}")
    print(f"    all {len(names)} links (link_poses): max position error {dp.max():.3e} mm "
          f"(at '{worst}'), max rotation error {dr.max():.3e} rad  "
          f"{'PASS' if dp.max() <= TARGET_MM else 'FAIL'}")
    print(f"    time: ours {ours_s * 1e3:.1f} ms for all links and the tip of {configs} "
          f"configurations (one batch); "
          f"yourdfpy {theirs_s:.2f} s (one configuration at a time)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=20261129)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    # yourdfpy warns on every update about the Panda's mimic finger joint declared fixed.
    logging.getLogger("yourdfpy").setLevel(logging.ERROR)
    print("Timings are wall-clock on a shared machine: expect noise.")
    for folder, urdf_file, group in CASES:
        data = zip_folder(ROBOTS / folder)
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            robot = import_robot(data, f"{folder}.zip", robot_id=folder, group=group)
            times.append(time.perf_counter() - start)
        print(f"\n{folder}: {len(data) / 2**20:.1f} MiB zip, import "
              f"{statistics.median(times):.2f} s (median of {args.repeats}; first "
              f"{times[0]:.2f} s), group '{group}'")
        describe(robot)
        compare(robot, ROBOTS / folder / urdf_file, args.configs, args.seed)


if __name__ == "__main__":
    main()
