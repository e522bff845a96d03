"""Writes the sample files of ``examples/`` (run from the repository root:
``.venv/bin/python examples/make_examples.py``). The same code writes the same bytes.

* ``glt_meshed.zip``: the built-in GLT palletizer exported as URDF (``kinematics.urdf.to_urdf``)
  with one simple STL mesh per moving link (metres, as URDF wants), visual and collision.
  Each mesh stops short of the joints at its ends, so that no two links touch in every
  configuration: the arm can move, and motion planning finds free paths.
* ``crate.stl``: an open-top crate (mm), five thin boxes.
* ``cell_scene.json``: a scene as ``POST /scenes`` takes it: a pallet (box), the crate
  (``{"type": "mesh", "mesh": "crate"}``: upload ``crate.stl`` as mesh ``crate`` first) and a
  few points of a scanned wall.
* ``drill_face.csv``: a small tunnel face of 22 holes for the three-arm jumbo
  (``planning.face_pattern``, rig frame, mm): ``id``, collar ``x y z``, toe
  ``x y z``, ``type``, ``diameter``.
"""

from __future__ import annotations

import csv
import io
import json
import sys
import zipfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # the project's packages, when run as a script

#: Every zip member gets this time stamp, so the archive's bytes do not depend on the clock.
ZIP_TIME = (2026, 1, 1, 0, 0, 0)

MATERIALS = ('<material name="arm_orange"><color rgba="0.93 0.5 0.12 1"/></material>'
             '<material name="base_grey"><color rgba="0.3 0.32 0.36 1"/></material>')

#: Meshed links: radius (m) of the link's cylinder, the gap (m) it leaves at its start and at
#: its end joint, and its material. link_4 and link_5 share the wrist centre with link_6 and
#: get no mesh (three solids at one point would touch in every configuration).
LINKS = {"link_1": (0.05, 0.0, 0.0, "base_grey"),
         "link_2": (0.06, 0.07, 0.07, "arm_orange"),
         "link_3": (0.05, 0.07, 0.11, "arm_orange"),
         "link_6": (0.04, 0.07, 0.0, "base_grey")}
#: The pedestal (base_link): radius (m), and its top's gap (m) below the waist's link_1.
PEDESTAL = (0.16, 0.07)

#: Drilling depth (mm, along the face normal, +x of the rig) and hole diameters (mm).
DEPTH = 3200.0
DIAMETER = {"contour": 45.0, "lifter": 48.0, "cut": 51.0}


def _stl(mesh) -> bytes:
    """Binary STL of a trimesh mesh, vertices rounded to 0.1 µm (same bytes on any machine)."""
    import trimesh

    rounded = trimesh.Trimesh(np.round(mesh.vertices, 7), mesh.faces, process=False)
    return rounded.export(file_type="stl")


def _rod(a: np.ndarray, b: np.ndarray, radius: float):
    """A closed cylinder of ``radius`` from point ``a`` to point ``b`` (3,)."""
    import trimesh

    return trimesh.creation.cylinder(radius=radius, segment=[a, b], sections=20)


def robot_archive() -> bytes:
    """The zip: ``glt_meshed/urdf/glt_meshed.urdf`` and ``glt_meshed/meshes/<link>.stl``."""
    from kinematics.library import builtin_model
    from kinematics.urdf import to_urdf
    from kinematics.urdf_import import import_robot

    text = to_urdf(builtin_model("glt_palletizer"))
    bare = import_robot(text.encode(), "glt.urdf", robot_id="bare")
    names = list(bare.link_names)
    poses = bare.link_poses(np.zeros(bare.model.dof))   # (links, 4, 4), mm

    def in_frame(link: str, other: str) -> np.ndarray:
        """The origin of ``other`` in ``link``'s frame (m)."""
        T = np.linalg.inv(poses[names.index(link)]) @ poses[names.index(other)]
        return T[:3, 3] / 1000.0

    nxt = {"link_1": "link_2", "link_2": "link_3", "link_3": "link_4", "link_6": "tool"}
    meshes = {}
    radius, gap = PEDESTAL
    top = in_frame("base_link", "link_1")
    meshes["base_link"] = (_rod(np.zeros(3), top - [0.0, 0.0, gap], radius), "base_grey")
    for link, (r, start_gap, end_gap, material) in LINKS.items():
        end = in_frame(link, nxt[link])
        u = end / np.linalg.norm(end)
        meshes[link] = (_rod(start_gap * u, end - end_gap * u, r), material)
    files = {}
    for link, (mesh, material) in meshes.items():
        path = f"glt_meshed/meshes/{link}.stl"
        files[path] = _stl(mesh)
        geometry = f'<geometry><mesh filename="package://{path}"/></geometry>'
        body = (f'<visual>{geometry}<material name="{material}"/></visual>'
                f"<collision>{geometry}</collision>")
        text = text.replace(f'<link name="{link}" />', f'<link name="{link}">{body}</link>')
    text = text.replace('<robot name="glt_palletizer">', f'<robot name="glt_meshed">{MATERIALS}')
    buf = io.BytesIO()
    # Stored, not deflated: 24 kB either way, and the bytes do not depend on the zlib build.
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for path, data in [("glt_meshed/urdf/glt_meshed.urdf", text.encode()),
                           *sorted(files.items())]:
            info = zipfile.ZipInfo(path, ZIP_TIME)
            info.external_attr = 0o644 << 16
            z.writestr(info, data)
    return buf.getvalue()


def crate() -> bytes:
    """An open-top crate 600 x 400 x 350 mm, walls 20 mm, its base's centre at the origin."""
    import trimesh

    L, W, H, t = 600.0, 400.0, 350.0, 20.0
    parts = [((L, W, t), (0, 0, t / 2)),                                  # floor
             ((t, W, H), (L / 2 - t / 2, 0, H / 2)), ((t, W, H), (-L / 2 + t / 2, 0, H / 2)),
             ((L - 2 * t, t, H), (0, W / 2 - t / 2, H / 2)),
             ((L - 2 * t, t, H), (0, -W / 2 + t / 2, H / 2))]
    boxes = []
    for extents, centre in parts:
        T = np.eye(4)
        T[:3, 3] = centre
        boxes.append(trimesh.creation.box(extents=extents, transform=T))
    return _stl(trimesh.util.concatenate(boxes))


def scene() -> dict:
    """A work cell for the meshed palletizer: pallet, crate on it, points of a wall."""
    wall = [[x, -1400.0, z] for x in (200.0, 700.0, 1200.0) for z in (0.0, 800.0, 1600.0)]
    return {
        "id": "cell", "name": "pallet, crate and a wall",
        "objects": [
            {"type": "box", "id": "pallet", "size": [1200, 800, 150],
             "pose": [[1, 0, 0, 1300], [0, 1, 0, 0], [0, 0, 1, 75], [0, 0, 0, 1]]},
            {"type": "mesh", "id": "crate", "mesh": "crate",
             "pose": [[1, 0, 0, 1300], [0, 1, 0, 0], [0, 0, 1, 150], [0, 0, 0, 1]]},
            {"type": "points", "id": "wall", "radius": 30, "points": wall},
        ],
    }


def drill_face() -> str:
    """The face's holes as CSV: contour and lifters of a 4.5 m x 3.8 m horseshoe face, and
    every other hole of its cut."""
    from planning import face_pattern

    face = face_pattern(width=4500, height=3800, spacing=900, floor_z=-1500)
    kinds = np.array(face.kinds)
    cut = np.flatnonzero(kinds == "cut")[::2]
    keep = np.concatenate([np.flatnonzero(kinds != "cut"), cut])
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(["id", "collar_x", "collar_y", "collar_z", "toe_x", "toe_y", "toe_z",
                  "type", "diameter_mm"])
    for n, k in enumerate(keep, start=1):
        collar = np.round(face.holes[k], 1) + 0.0   # no -0.0
        toe = collar + [DEPTH, 0.0, 0.0]
        out.writerow([f"H{n:02d}", *(f"{v:.1f}" for v in collar), *(f"{v:.1f}" for v in toe),
                      kinds[k], f"{DIAMETER[kinds[k]]:.0f}"])
    return buf.getvalue()


def drill_round() -> str:
    """The face of ``drill_face`` as an IREDES drill plan (fixed creation date: the same
    bytes every time)."""
    from planning.drilling.plans import read_csv, write_iredes

    plan = read_csv(drill_face(), plan_id="FACE-22", name="Sample face, 22 holes",
                    frame_name="tunnel_jumbo")
    return write_iredes(plan, created="2026-01-05T08:00:00")


def main(out: Path = HERE) -> None:
    """Write the five sample files into ``out``."""
    (out / "glt_meshed.zip").write_bytes(robot_archive())
    (out / "crate.stl").write_bytes(crate())
    (out / "cell_scene.json").write_text(json.dumps(scene(), indent=1) + "\n")
    (out / "drill_face.csv").write_text(drill_face())
    (out / "drill_round.xml").write_bytes(drill_round().encode("utf-8"))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
