"""Fixtures of the viewer tests: the GLT palletizer as a URDF with meshes, made here.

``to_urdf`` writes the built-in GLT palletizer; each chain link then gets a trimesh "bone"
(a cylinder from the link's origin to the next link's, with a ball at the joint), written as
STL in metres and referenced by ``package://`` paths as the link's visual and collision
geometry, with URDF materials (orange arm, dark grey base). The bones' end points come from
the bare URDF imported once (the next link's origin in each link's frame), so the meshes sit
on the arm whatever the model's frames are.
"""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from kinematics.library import builtin_model
from kinematics.urdf import to_urdf

MATERIALS = ('<material name="arm_orange"><color rgba="0.93 0.5 0.12 1"/></material>'
             '<material name="base_grey"><color rgba="0.3 0.32 0.36 1"/></material>')
#: Bone radius (m) of each link that gets a mesh, and its material.
BONES = {"base_link": (0.16, "base_grey"), "link_1": (0.11, "base_grey"),
         "link_2": (0.08, "arm_orange"), "link_3": (0.065, "arm_orange"),
         "link_4": (0.06, "arm_orange"), "link_6": (0.045, "base_grey")}


def _bone(end_m: np.ndarray, radius: float):
    """A cylinder from the origin to ``end_m (3,)`` with a ball at the origin (trimesh)."""
    import trimesh

    parts = [trimesh.creation.icosphere(subdivisions=2, radius=1.15 * radius)]
    if np.linalg.norm(end_m) > 1e-6:
        parts.append(trimesh.creation.cylinder(radius=radius, segment=[np.zeros(3), end_m],
                                               sections=24))
    return trimesh.util.concatenate(parts)


def glt_urdf_with_meshes(collision: bool = True, visual: bool = True
                         ) -> tuple[str, dict[str, bytes]]:
    """The URDF text and its STL files (path in the archive -> bytes)."""
    from kinematics.urdf_import import import_robot

    text = to_urdf(builtin_model("glt_palletizer"))
    bare = import_robot(text.encode(), "glt.urdf", robot_id="bare")
    names = list(bare.link_names)
    poses = bare.link_poses(np.zeros(bare.model.dof))
    chain = [*bare.chain_links, "tool"]
    files = {}
    for link, (radius, material) in BONES.items():
        k = chain.index(link)
        # The next link in the chain whose origin differs (the wrist's links coincide).
        nxt = chain[k + 1]
        T_link = poses[names.index(link)]
        T_next = poses[names.index(nxt)]
        end_m = (np.linalg.inv(T_link) @ T_next)[:3, 3] / 1000.0
        if link == "base_link":
            end_m = (np.linalg.inv(T_link) @ poses[names.index("link_1")])[:3, 3] / 1000.0
        path = f"glt_description/meshes/{link}.stl"
        files[path] = _bone(end_m, radius).export(file_type="stl")
        mesh = f'<geometry><mesh filename="package://{path}"/></geometry>'
        body = ""
        if visual:
            body += f'<visual>{mesh}<material name="{material}"/></visual>'
        if collision:
            body += f"<collision>{mesh}</collision>"
        text = text.replace(f'<link name="{link}" />', f'<link name="{link}">{body}</link>')
    text = text.replace('<robot name="glt_palletizer">',
                        f'<robot name="glt_palletizer">{MATERIALS}')
    return text, files


def glt_archive(collision: bool = True, visual: bool = True) -> bytes:
    """A zip of the URDF (``glt_description/urdf/glt.urdf``) and its meshes."""
    text, files = glt_urdf_with_meshes(collision, visual)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt_description/urdf/glt.urdf", text)
        for path, data in files.items():
            z.writestr(path, data)
    return buf.getvalue()


@pytest.fixture(scope="session")
def glt_meshed_zip() -> bytes:
    """The meshed GLT palletizer archive (visual and collision meshes)."""
    pytest.importorskip("trimesh")
    return glt_archive()


@pytest.fixture(scope="session")
def glt_collision_only_zip() -> bytes:
    """The same robot with collision meshes only (no ``<visual>``)."""
    pytest.importorskip("trimesh")
    return glt_archive(visual=False)


@pytest.fixture
def api(tmp_path):
    """An application without processes started (jobs stay queued) and a viewer on port 0."""
    from app.config import Settings
    from app.main import create_app
    from web.viewer import Viewer

    app = create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))
    app.state.viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
    yield app
    app.state.viewer.stop()


@pytest.fixture(scope="module")
def viewer(tmp_path_factory):
    """A viewer on port 0 over an application without processes started (one per test
    module; a module that needs another defines its own ``viewer``)."""
    from app.config import Settings
    from app.main import create_app
    from web.viewer import Viewer

    app = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("data"),
                              workers=1))
    v = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
    yield v
    v.stop()
