"""URDF import: an independent URDF reader (yourdfpy) and our own D-H/PoE models agree with
the imported chains and link poses; archives, meshes, SRDF, persistence and export; every
input users can get wrong is a FieldError naming the field or URDF element.

Fixtures are made here: URDFs written by ``kinematics.urdf.to_urdf`` from the built-in
models, and a hand-written gantry picker (prismatic, continuous, fixed, floating and mimic
joints, an SRDF) with meshes made by trimesh, packed in zip and tar archives.
"""

from __future__ import annotations

import io
import json
import logging
import math
import stat
import tarfile
import zipfile

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import invert_pose, rot_x, rot_z, rotation_angle
from kinematics.urdf import (
    imported_mesh_files,
    imported_to_archive,
    imported_to_urdf,
    to_urdf,
)
from kinematics.urdf_import import (
    CONTINUOUS_LIMIT,
    MAX_ARCHIVE_BYTES,
    MAX_MESH_TRIANGLES_TOTAL,
    MAX_UNPACKED_BYTES,
    ImportedRobot,
    ImportLimits,
    MeshData,
    import_robot,
    mesh_from_bytes,
    mesh_to_bytes,
)

yourdfpy = pytest.importorskip("yourdfpy")
trimesh = pytest.importorskip("trimesh")
logging.getLogger("yourdfpy").setLevel(logging.ERROR)
logging.getLogger("trimesh").setLevel(logging.ERROR)

TOL_MM = 1e-9
TOL_RAD = 1e-12

# ---- the gantry picker -------------------------------------------------------------------
PICKER_URDF = """<?xml version="1.0"?>
<robot name="gantry_picker">
  <material name="steel"><color rgba="0.5 0.5 0.55 1"/></material>
  <link name="world"/>
  <joint name="world_to_base" type="fixed">
    <parent link="world"/><child link="base"/>
    <origin xyz="0.5 -0.2 0.9" rpy="0.1 -0.2 1.3"/>
  </joint>
  <link name="base">
    <visual>
      <geometry><box size="0.4 0.3 0.1"/></geometry>
      <material name="steel"/>
    </visual>
    <collision>
      <origin xyz="0 0 0.05" rpy="0 0 0.2"/>
      <geometry><mesh filename="package://picker_description/meshes/base.stl"/></geometry>
    </collision>
  </link>
  <joint name="rail" type="prismatic">
    <parent link="base"/><child link="carriage"/>
    <origin xyz="0.1 0 0.05" rpy="0 0 0.3"/>
    <axis xyz="1 0 0"/>
    <limit lower="-0.4" upper="0.6" effort="100" velocity="0.5"/>
  </joint>
  <link name="carriage">
    <visual>
      <geometry><cylinder radius="0.05" length="0.2"/></geometry>
      <material name="paint"><color rgba="0.9 0.2 0.1 1"/></material>
    </visual>
    <collision>
      <origin xyz="0 0 0.1" rpy="1.5707963267948966 0 0"/>
      <geometry><cylinder radius="0.05" length="0.2"/></geometry>
    </collision>
  </link>
  <joint name="swing" type="continuous">
    <parent link="carriage"/><child link="arm"/>
    <origin xyz="0 0.1 0.2" rpy="0.4 0 0"/>
    <axis xyz="0 1 1"/>
    <limit effort="10" velocity="2"/>
  </joint>
  <link name="arm">
    <visual><geometry><mesh filename="package://picker_description/meshes/arm.obj"
        scale="0.5 0.5 0.5"/></geometry><material name="paint"/></visual>
    <collision><geometry><mesh filename="package://picker_description/meshes/arm.obj"
        scale="0.5 0.5 0.5"/></geometry></collision>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="arm"/><child link="forearm"/>
    <origin xyz="0.3 0 0.05" rpy="0 1.2 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="10" velocity="1.5"/>
  </joint>
  <link name="forearm">
    <collision><geometry><sphere radius="0.04"/></geometry></collision>
    <collision><geometry><mesh filename="meshes/forearm.ply" scale="1 -1 1"/></geometry>
    </collision>
  </link>
  <joint name="wrist" type="revolute">
    <parent link="forearm"/><child link="hand"/>
    <origin xyz="0.25 0.02 -0.03" rpy="-0.3 0.2 0.1"/>
    <axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/>
  </joint>
  <link name="hand"><collision><geometry><box size="0.08 0.1 0.04"/></geometry></collision>
  </link>
  <joint name="tcp_joint" type="fixed">
    <parent link="hand"/><child link="tcp"/>
    <origin xyz="0 0 0.12" rpy="0 0 0.7"/>
  </joint>
  <link name="tcp"/>
  <joint name="finger_left_joint" type="prismatic">
    <parent link="hand"/><child link="finger_left"/>
    <origin xyz="0 0.03 0.06"/>
    <axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" effort="1" velocity="0.1"/>
    <mimic joint="wrist" multiplier="0.01" offset="0.005"/>
  </joint>
  <link name="finger_left"><collision><geometry><box size="0.01 0.01 0.05"/></geometry>
  </collision></link>
  <joint name="finger_left_tip_joint" type="fixed">
    <parent link="finger_left"/><child link="finger_left_tip"/>
    <origin xyz="0 0 0.03" rpy="0.2 0 0"/>
  </joint>
  <link name="finger_left_tip"><collision><geometry><sphere radius="0.006"/></geometry>
  </collision></link>
  <joint name="finger_right_joint" type="revolute">
    <parent link="hand"/><child link="finger_right"/>
    <origin xyz="0 -0.03 0.06" rpy="0 0.1 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="rail" multiplier="-2.0" offset="0.1"/>
  </joint>
  <link name="finger_right"/>
  <joint name="camera_pan" type="revolute">
    <parent link="base"/><child link="camera"/>
    <origin xyz="-0.15 0 0.1"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="camera"><visual><geometry><box size="0.05 0.05 0.05"/></geometry></visual>
  </link>
  <joint name="camera_tilt" type="revolute">
    <parent link="camera"/><child link="camera_head"/>
    <origin xyz="0 0 0.04"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="camera_pan" multiplier="0.5" offset="0.1"/>
  </joint>
  <link name="camera_head"/>
  <joint name="payload_float" type="floating">
    <parent link="world"/><child link="payload"/>
    <origin xyz="1 1 0" rpy="0 0 0.5"/>
  </joint>
  <link name="payload"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
</robot>
"""
PICKER_SRDF = """<?xml version="1.0"?>
<robot name="gantry_picker">
  <group name="arm"><chain base_link="base" tip_link="tcp"/></group>
  <group name="to_hand"><chain base_link="base" tip_link="hand"/></group>
  <group name="gripper"><link name="finger_left"/><link name="finger_right"/></group>
  <disable_collisions link1="base" link2="carriage" reason="Adjacent"/>
  <disable_collisions link1="finger_left" link2="finger_right" reason="Never"/>
  <disable_collisions link1="payload" link2="arm" reason="Never"/>
</robot>
"""
ONE_CHAIN_SRDF = """<robot name="gantry_picker">
  <group name="arm"><chain base_link="base" tip_link="tcp"/></group>
  <group name="gripper"><link name="finger_left"/></group>
</robot>
"""
CHAIN = ["rail", "swing", "elbow", "wrist"]


def picker_meshes() -> dict[str, bytes]:
    box = trimesh.creation.box(extents=[0.3, 0.2, 0.1])
    cylinder = trimesh.creation.cylinder(radius=0.04, height=0.5, sections=16)
    sphere = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
    return {
        "picker_description/meshes/base.stl": box.export(file_type="stl"),
        "picker_description/meshes/arm.obj": cylinder.export(file_type="obj").encode(),
        "picker_description/urdf/meshes/forearm.ply": sphere.export(file_type="ply"),
    }


def picker_files(urdf: str = PICKER_URDF, srdf: str | None = PICKER_SRDF) -> dict[str, bytes]:
    files = {"picker_description/urdf/picker.urdf": urdf.encode(), **picker_meshes()}
    if srdf is not None:
        files["picker_description/config/picker.srdf"] = srdf.encode()
    return files


def make_zip(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buffer.getvalue()


def make_tar(files: dict[str, bytes], mode: str = "w:gz") -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as tf:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    return buffer.getvalue()


def import_picker(**kwargs) -> ImportedRobot:
    kwargs.setdefault("group", "arm")
    return import_robot(make_zip(picker_files()), "picker.zip", robot_id="picker", **kwargs)


@pytest.fixture(scope="module")
def picker() -> ImportedRobot:
    return import_picker(fixed_joints={"camera_pan": 0.4})


def reference_poses(urdf_text: str, robot: ImportedRobot, qs: np.ndarray,
                    extra: dict[str, float] | None = None) -> np.ndarray:
    """yourdfpy's world poses (mm) of ``robot.links`` for configurations ``qs``."""
    urdf = yourdfpy.URDF.load(io.StringIO(urdf_text), load_meshes=False,
                              build_collision_scene_graph=False, load_collision_meshes=False)
    scale = np.where(robot.model.revolute, 1.0, 1e-3)
    out = np.empty((len(qs), len(robot.links), 4, 4))
    for n, q in enumerate(qs):
        cfg = {j.name: float(v) for j, v in zip(robot.model.joints, q * scale)}
        urdf.update_cfg({**cfg, **(extra or {})})
        for k, link in enumerate(robot.links):
            out[n, k] = urdf.get_transform(link.name, robot.root_link)
    out[..., :3, 3] *= 1000.0
    return out


def assert_poses_close(ours: np.ndarray, theirs: np.ndarray) -> None:
    dp = np.linalg.norm(ours[..., :3, 3] - theirs[..., :3, 3], axis=-1)
    dr = rotation_angle(np.swapaxes(ours[..., :3, :3], -1, -2) @ theirs[..., :3, :3])
    assert dp.max() <= TOL_MM, dp.max()
    assert dr.max() <= TOL_RAD, dr.max()


def field_error(loc_prefix: tuple, fragment: str, fn, *args, **kwargs) -> FieldError:
    with pytest.raises(FieldError) as info:
        fn(*args, **kwargs)
    error = info.value
    assert error.loc[:len(loc_prefix)] == loc_prefix, (error.loc, error.message)
    assert fragment in error.message, error.message
    return error


# ---- chains from our own models ----------------------------------------------------------
BUILTIN = [builtin_model(rid) for rid in BUILTIN_IDS]


@pytest.mark.parametrize("model", BUILTIN, ids=BUILTIN_IDS)
def test_builtin_models_through_urdf_keep_their_fk(model):
    """Our D-H / PoE FK of the original model, yourdfpy's FK of its URDF and the imported
    model's FK agree; links, limits, speeds and the default chain are as written."""
    text = to_urdf(model)
    robot = import_robot(text.encode(), f"{model.id}.urdf", robot_id=model.id,
                         tip_link="tool")
    imported = robot.model
    assert imported.convention == "poe"
    assert [j.name for j in imported.joints] == [j.name for j in model.joints]
    assert [j.type for j in imported.joints] == [j.type for j in model.joints]
    np.testing.assert_allclose(imported.lower, model.lower, rtol=0, atol=1e-12)
    np.testing.assert_allclose(imported.upper, model.upper, rtol=0, atol=1e-12)
    np.testing.assert_allclose(imported.velocity_limits, model.velocity_limits, rtol=1e-15)
    assert robot.root_link == robot.base_link == "base_link"
    assert robot.chain_links == ("base_link", *(f"link_{i}" for i in range(1, model.dof + 1)))
    qs = np.random.default_rng(11).uniform(model.lower, model.upper, (25, model.dof))
    assert_poses_close(fk(imported, qs), fk(model, qs))
    poses = robot.link_poses(qs)
    assert_poses_close(poses, reference_poses(text, robot, qs))
    tool = robot.link_names.index("tool")
    assert_poses_close(poses[:, tool], fk(model, qs))
    # Without tip_link the chain ends at the last movable joint's child.
    default = import_robot(text.encode(), "m.urdf", robot_id="m")
    assert default.tip_link == f"link_{model.dof}"


def test_prismatic_poe_model_through_urdf():
    model = RobotModel.from_dict({
        "id": "poe_slide", "convention": "poe",
        "joints": [
            {"axis": [0, 0, 1], "point": [10, 0, 0], "offset": 0.25, "lower": -3, "upper": 3},
            {"type": "prismatic", "axis": [0.6, 0, 0.8], "offset": 15, "lower": 0,
             "upper": 300, "velocity": 250},
            {"axis": [1, 0, 0], "point": [500, 0, 400], "lower": -3, "upper": 3},
        ],
        "home": [[0, 0, 1, 600], [0, 1, 0, 0], [-1, 0, 0, 400], [0, 0, 0, 1]],
        "base": [[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 1, 7], [0, 0, 0, 1]],
    })
    robot = import_robot(to_urdf(model).encode(), "m.urdf", robot_id="x", tip_link="tool")
    assert robot.model.joints[1].velocity == pytest.approx(250.0, rel=1e-15)
    qs = np.random.default_rng(3).uniform(model.lower, model.upper, (30, model.dof))
    assert_poses_close(fk(robot.model, qs), fk(model, qs))


# ---- the gantry picker against yourdfpy ---------------------------------------------------
def test_picker_chain_and_model(picker):
    model = picker.model
    assert [j.name for j in model.joints] == CHAIN
    assert [j.type for j in model.joints] == ["prismatic", "revolute", "revolute", "revolute"]
    assert (picker.root_link, picker.base_link, picker.tip_link) == ("world", "base", "tcp")
    assert picker.chain_links == ("base", "carriage", "arm", "forearm", "hand")
    # prismatic m -> mm (limits and speed), continuous -> ±2π, revolute as written
    assert model.joints[0].lower == -400.0 and model.joints[0].upper == 600.0
    assert model.joints[0].velocity == 500.0
    assert (model.joints[1].lower, model.joints[1].upper) == (-CONTINUOUS_LIMIT,
                                                              CONTINUOUS_LIMIT)
    assert CONTINUOUS_LIMIT == 2 * math.pi
    assert model.joints[1].velocity == 2.0
    assert (model.joints[2].lower, model.joints[2].upper) == (-2.0, 2.0)
    # the world frame is the URDF root: the base is the fixed world_to_base origin
    np.testing.assert_allclose(model.base[:3, 3], [500.0, -200.0, 900.0], atol=1e-12)
    np.testing.assert_array_equal(model.tool, np.eye(4))
    # screws in the base frame: the carriage is turned 0.3 rad about z, the swing joint's
    # frame 0.4 rad about x more, and its axis (0 1 1) is normalised
    R = rot_z(0.3)[:3, :3]
    np.testing.assert_allclose(model.joints[0].axis, R @ [1.0, 0.0, 0.0], atol=1e-15)
    axis = R @ rot_x(0.4)[:3, :3] @ (np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0))
    np.testing.assert_allclose(model.joints[1].axis, axis, atol=1e-15)
    assert np.linalg.norm(model.joints[1].axis) == 1.0
    np.testing.assert_allclose(model.joints[1].point, np.array([100.0, 0.0, 50.0]) + R @ [
        0.0, 100.0, 200.0], atol=1e-12)


def test_picker_link_poses_match_yourdfpy(picker):
    """Every link, the mimic fingers (driven by a revolute and by a prismatic chain joint),
    the held camera joints and the floating payload, on random in-limit configurations."""
    qs = np.random.default_rng(20261129).uniform(picker.model.lower, picker.model.upper,
                                                 (60, picker.model.dof))
    ours = picker.link_poses(qs)
    theirs = reference_poses(PICKER_URDF, picker, qs, {"camera_pan": 0.4})
    assert_poses_close(ours, theirs)
    assert_poses_close(ours[:, picker.link_names.index("tcp")], fk(picker.model, qs))


def test_picker_link_frames_follow_the_contract(picker):
    """Links without mimic steps: pose = fk_frames(model, q)[frame] @ offset, with the
    frame of the chain joint they ride after."""
    frames = {link.name: link.frame for link in picker.links}
    assert frames["world"] == frames["base"] == frames["camera"] == frames["payload"] == 0
    assert frames["carriage"] == 1 and frames["arm"] == 2 and frames["forearm"] == 3
    assert frames["hand"] == frames["tcp"] == frames["finger_left"] == 4
    q = np.array([120.0, 0.7, -0.4, 1.1])
    F = fk_frames(picker.model, q)
    poses = picker.link_poses(q)
    for k, link in enumerate(picker.links):
        if not link.mimic:
            np.testing.assert_allclose(F[link.frame] @ link.offset, poses[k], atol=1e-9)
    mimics = {link.name: [s.joint for s in link.mimic] for link in picker.links if link.mimic}
    assert mimics == {"finger_left": ["finger_left_joint"],
                      "finger_left_tip": ["finger_left_joint"],
                      "finger_right": ["finger_right_joint"]}


def test_link_poses_batch_shapes(picker):
    rng = np.random.default_rng(5)
    q = rng.uniform(picker.model.lower, picker.model.upper, (2, 3, 4))
    poses = picker.link_poses(q)
    n = len(picker.links)
    assert poses.shape == (2, 3, n, 4, 4)
    assert picker.link_poses(q[0, 0]).shape == (n, 4, 4)
    np.testing.assert_array_equal(poses[1, 2], picker.link_poses(q[1, 2]))
    with pytest.raises(ValueError):
        picker.link_poses(np.zeros(3))


def test_picker_geometry_meshes_and_colours(picker):
    links = {link.name: link for link in picker.links}
    base = links["base"]
    assert base.visual[0].kind == "box" and base.visual[0].size == (400.0, 300.0, 100.0)
    assert base.visual[0].color == (0.5, 0.5, 0.55, 1.0)  # a top-level material by name
    carriage = links["carriage"]
    assert carriage.visual[0].color == (0.9, 0.2, 0.1, 1.0)
    assert links["arm"].visual[0].color == (0.9, 0.2, 0.1, 1.0)  # named after its definition
    cyl = carriage.collision[0]
    assert (cyl.kind, cyl.radius, cyl.length) == ("cylinder", 50.0, 200.0)
    np.testing.assert_allclose(cyl.origin[:3, 3], [0.0, 0.0, 100.0], atol=1e-12)
    assert links["forearm"].collision[0].radius == 40.0
    # one mesh per (file, scale); visual and collision share it
    arm = links["arm"]
    assert arm.visual[0].mesh == arm.collision[0].mesh
    assert set(picker.meshes) == {g.mesh for link in picker.links
                                  for g in (*link.collision, *link.visual) if g.kind == "mesh"}
    box = picker.meshes[base.collision[0].mesh]
    assert box.triangles == 12
    np.testing.assert_allclose(box.vertices.min(axis=0), [-150.0, -100.0, -50.0], atol=1e-9)
    cylinder = picker.meshes[arm.collision[0].mesh]
    np.testing.assert_allclose(np.ptp(cylinder.vertices, axis=0), [40.0, 40.0, 250.0],
                               atol=1e-6)  # radius 0.04 m, height 0.5 m, scale 0.5
    assert cylinder.faces.dtype == np.int64 and cylinder.vertices.dtype == np.float64
    # a mirroring scale turns the faces over: the mesh keeps a positive volume
    sphere = picker.meshes[links["forearm"].collision[1].mesh]
    mirrored = trimesh.Trimesh(sphere.vertices, sphere.faces, process=False)
    assert mirrored.volume > 0


def test_pairs(picker):
    pair = frozenset
    assert picker.disabled_pairs == {pair(("base", "carriage")),
                                     pair(("finger_left", "finger_right")),
                                     pair(("payload", "arm"))}
    adjacent = picker.adjacent_pairs
    for a, b in [("world", "base"), ("base", "carriage"), ("carriage", "arm"),
                 ("hand", "tcp"), ("hand", "finger_left"), ("finger_left", "finger_left_tip"),
                 ("world", "payload"),  # floating, held: rigid
                 ("base", "camera_head"),  # held joints: one rigid body with base
                 ("carriage", "camera"),  # the rail joins that body to the carriage
                 ("tcp", "finger_right"),  # the finger's joint joins it to hand's body
                 ("hand", "finger_left_tip")]:  # rigid on finger_left, which hand moves
        assert pair((a, b)) in adjacent, (a, b)
    for a, b in [("base", "arm"), ("carriage", "forearm"), ("finger_left", "finger_right"),
                 ("finger_left_tip", "forearm"), ("payload", "arm")]:
        assert pair((a, b)) not in adjacent, (a, b)


# ---- archives, layouts, SRDF choice ------------------------------------------------------
def test_tar_archives_and_plain_tar_give_the_same_robot(picker):
    q = np.array([-50.0, 2.0, 1.0, -2.5])
    for data, name in [(make_tar(picker_files()), "picker.tar.gz"),
                       (make_tar(picker_files()), "picker.tgz"),
                       (make_tar(picker_files(), "w"), "picker.tar")]:
        robot = import_robot(data, name, robot_id="picker", group="arm",
                             fixed_joints={"camera_pan": 0.4})
        np.testing.assert_array_equal(robot.link_poses(q), picker.link_poses(q))
        assert robot.meshes.keys() == picker.meshes.keys()
        for key, mesh in robot.meshes.items():
            assert mesh.same_as(picker.meshes[key])


def test_single_chain_group_is_taken_and_urdf_srdf_pairing():
    files = picker_files(srdf=ONE_CHAIN_SRDF)
    robot = import_robot(make_zip(files), "p.zip", robot_id="p")
    assert (robot.base_link, robot.tip_link) == ("base", "tcp")
    # several SRDF files: the one named like the URDF
    files["picker_description/config/other.srdf"] = PICKER_SRDF.encode()
    files["picker_description/config/picker.srdf"] = ONE_CHAIN_SRDF.encode()
    robot = import_robot(make_zip(files), "p.zip", robot_id="p")
    assert robot.tip_link == "tcp" and not robot.disabled_pairs
    # an SRDF given on its own wins over the archive's
    robot = import_robot(make_zip(files), "p.zip", robot_id="p", srdf=PICKER_SRDF.encode(),
                         group="to_hand")
    assert robot.tip_link == "hand" and len(robot.disabled_pairs) == 3


def test_explicit_base_and_tip_without_srdf():
    files = picker_files(srdf=None)
    robot = import_robot(make_zip(files), "p.zip", robot_id="p", base_link="carriage",
                         tip_link="forearm", fixed_joints={"rail": 40.0})  # mm
    assert [j.name for j in robot.model.joints] == ["swing", "elbow"]
    # the world frame stays the URDF root: with the rail held where the full picker has it,
    # forearm's pose matches
    full = import_picker()
    q_full = np.array([40.0, 0.3, -0.8, 0.0])
    np.testing.assert_allclose(robot.link_pose("forearm", q_full[1:3]),
                               full.link_pose("forearm", q_full), atol=1e-9)


def test_mesh_lookup_rules():
    """package:// with the package folder stripped (archive = the package's contents),
    file:// absolute paths by their trailing parts, names that match only ignoring case."""
    urdf = PICKER_URDF.replace(
        "package://picker_description/meshes/base.stl",
        "file:///home/someone/ws/src/picker_description/meshes/BASE.STL")
    files = {name.split("/", 1)[1]: data for name, data in picker_files(urdf).items()}
    assert "meshes/base.stl" in files and "urdf/picker.urdf" in files
    robot = import_robot(make_zip(files), "p.zip", robot_id="p", group="arm")
    assert robot.meshes[robot.links[1].collision[0].mesh].triangles == 12


def test_macos_resource_forks_are_ignored():
    files = picker_files()
    files["__MACOSX/picker_description/urdf/._picker.urdf"] = b"\x00\x05junk"
    files["picker_description/urdf/._picker.urdf"] = b"\x00\x05junk"
    robot = import_robot(make_zip(files), "p.zip", robot_id="p", group="arm")
    assert robot.model.dof == 4


def test_two_urdfs_need_urdf_to_choose():
    files = picker_files()
    files["picker_description/urdf/other.urdf"] = to_urdf(builtin_model("pile_driver")).encode()
    data = make_zip(files)
    error = field_error(("urdf",), "picker_description/urdf/other.urdf", import_robot, data,
                        "p.zip", robot_id="p")
    assert "picker_description/urdf/picker.urdf" in error.message
    robot = import_robot(data, "p.zip", robot_id="p", urdf="other.urdf")
    assert robot.model.dof == 6
    robot = import_robot(data, "p.zip", robot_id="p", urdf="picker_description/urdf/picker.urdf",
                         group="arm")
    assert robot.model.dof == 4
    field_error(("urdf",), "no single URDF", import_robot, data, "p.zip", robot_id="p",
                urdf="nope.urdf")


# ---- persistence and export --------------------------------------------------------------
def test_to_dict_from_dict_round_trip_is_exact(picker):
    text = json.dumps(picker.to_dict())
    stored = {key: mesh_to_bytes(mesh) for key, mesh in picker.meshes.items()}
    assert all(isinstance(b, bytes) for b in stored.values())
    again = ImportedRobot.from_dict(json.loads(text),
                                    {k: mesh_from_bytes(b) for k, b in stored.items()})
    qs = np.random.default_rng(8).uniform(picker.model.lower, picker.model.upper, (40, 4))
    np.testing.assert_array_equal(again.link_poses(qs), picker.link_poses(qs))
    np.testing.assert_array_equal(fk(again.model, qs), fk(picker.model, qs))
    assert again.model.to_dict() == picker.model.to_dict()
    assert again.link_names == picker.link_names
    assert again.adjacent_pairs == picker.adjacent_pairs
    assert again.disabled_pairs == picker.disabled_pairs
    for key, mesh in picker.meshes.items():
        assert again.meshes[key].same_as(mesh)
    with pytest.raises(FieldError) as info:
        ImportedRobot.from_dict(json.loads(text), {})
    assert info.value.loc[0] == "meshes"


def test_mesh_bytes_are_lossless_and_checked():
    rng = np.random.default_rng(2)
    mesh = MeshData(rng.normal(size=(30, 3)) * 1e3, rng.integers(0, 30, (40, 3)))
    again = mesh_from_bytes(mesh_to_bytes(mesh))
    assert again.same_as(mesh) and again.faces.dtype == np.int64
    for bad in (b"", b"not a mesh", mesh_to_bytes(MeshData(np.zeros((2, 3)),
                                                           np.array([[0, 1, 5]])))):
        with pytest.raises(ValueError):
            mesh_from_bytes(bad)


def test_export_reimports_to_the_same_poses_and_yourdfpy_agrees(picker):
    text = imported_to_urdf(picker)
    files = imported_mesh_files(picker)
    assert set(files) == {f"meshes/{key}.stl" for key in picker.meshes}
    again = import_robot(imported_to_archive(picker), "export.zip", robot_id="picker",
                         base_link=picker.base_link, tip_link=picker.tip_link)
    assert [j.name for j in again.model.joints] == CHAIN
    assert set(picker.link_names) <= set(again.link_names)
    qs = np.random.default_rng(9).uniform(picker.model.lower, picker.model.upper, (40, 4))
    order = [again.link_names.index(name) for name in picker.link_names]
    ours = picker.link_poses(qs)
    assert_poses_close(again.link_poses(qs)[:, order], ours)
    assert_poses_close(fk(again.model, qs), fk(picker.model, qs))
    # The archive's SRDF keeps the chain and the disabled pairs.
    assert again.disabled_pairs == picker.disabled_pairs
    assert picker.disabled_pairs  # the fixture has some
    # geometry survives (meshes as float32 STL in metres)
    for link in picker.links:
        other = again.links[again.link_names.index(link.name)]
        assert [g.kind for g in other.collision] == [g.kind for g in link.collision]
        for g, h in zip(link.visual, other.visual):
            assert g.color == h.color
    for key, mesh in picker.meshes.items():
        other = again.meshes[key]
        assert other.triangles == mesh.triangles
        np.testing.assert_allclose(other.vertices[other.faces], mesh.vertices[mesh.faces],
                                   atol=1e-4)
    # an independent reader of the export agrees with the original import
    theirs = reference_poses(text, picker, qs[:10])
    assert_poses_close(ours[:10], theirs)


# ---- fixed_joints ------------------------------------------------------------------------
def test_fixed_joints_move_held_joints_and_their_mimics():
    held = import_picker(fixed_joints={"camera_pan": -0.6})
    rest = import_picker()
    q = np.zeros(4)
    T_base = held.link_pose("base", q)
    pan = invert_pose(T_base) @ held.link_pose("camera", q)
    pan0 = invert_pose(T_base) @ rest.link_pose("camera", q)
    assert rotation_angle(pan0[:3, :3].T @ pan[:3, :3]) == pytest.approx(0.6, abs=1e-12)
    tilt = invert_pose(held.link_pose("camera", q)) @ held.link_pose("camera_head", q)
    assert rotation_angle(tilt[:3, :3]) == pytest.approx(abs(0.5 * -0.6 + 0.1), abs=1e-12)


@pytest.mark.parametrize("name, value, fragment", [
    ("nope", 0.0, "unknown joint"),
    ("elbow", 0.1, "on the chain"),
    ("camera_tilt", 0.1, "mimics 'camera_pan'"),
    ("tcp_joint", 0.0, "fixed joint"),
    ("payload_float", 0.0, "held at identity"),
    ("camera_pan", 1.5, "outside the limits"),
    ("camera_pan", float("nan"), "finite number"),
])
def test_fixed_joints_errors(name, value, fragment):
    field_error(("fixed_joints", name), fragment, import_picker, fixed_joints={name: value})


# ---- every error names its field ---------------------------------------------------------
def picker_with(old: str, new: str, **kwargs):
    urdf = PICKER_URDF.replace(old, new)
    assert urdf != PICKER_URDF
    kwargs.setdefault("group", "arm")
    return import_robot(make_zip(picker_files(urdf)), "p.zip", robot_id="p", **kwargs)


def test_missing_mesh_in_a_bare_urdf_names_link_and_file():
    error = field_error(
        ("file", "link[base]", "collision", 0, "geometry", "mesh", "filename"),
        "package://picker_description/meshes/base.stl", import_robot, PICKER_URDF.encode(),
        "picker.urdf", robot_id="p", group="arm", srdf=PICKER_SRDF.encode())
    assert "link 'base'" in error.message and "archive" in error.message


def test_missing_mesh_in_an_archive_names_link_and_file():
    files = picker_files()
    del files["picker_description/urdf/meshes/forearm.ply"]
    error = field_error(("file", "link[forearm]", "collision", 1, "geometry", "mesh",
                         "filename"), "meshes/forearm.ply", import_robot, make_zip(files),
                        "p.zip", robot_id="p", group="arm")
    assert "not in the archive" in error.message


def test_a_file_that_is_not_a_mesh():
    files = picker_files()
    files["picker_description/meshes/base.stl"] = b"solid? no, a shopping list\nmilk\n"
    error = field_error(("file", "link[base]", "collision", 0), "base.stl", import_robot,
                        make_zip(files), "p.zip", robot_id="p", group="arm")
    assert "no triangles" in error.message or "not a readable" in error.message
    files["picker_description/meshes/base.stl"] = trimesh.creation.box().export(
        file_type="stl")
    files["picker_description/urdf/meshes/forearm.ply"] = b"ply\nformat nonsense\n"
    field_error(("file", "link[forearm]", "collision", 1), "forearm.ply", import_robot,
                make_zip(files), "p.zip", robot_id="p", group="arm")


def test_unsupported_mesh_format_and_remote_mesh():
    files = picker_files(PICKER_URDF.replace("meshes/base.stl", "meshes/base.3ds"))
    files["picker_description/meshes/base.3ds"] = files["picker_description/meshes/base.stl"]
    field_error(("file", "link[base]", "collision", 0), "unsupported format", import_robot,
                make_zip(files), "p.zip", robot_id="p", group="arm")
    field_error(("file", "link[base]", "collision", 0), "remote", picker_with,
                "package://picker_description/meshes/base.stl", "https://example.com/b.stl")


def test_a_cycle_of_joints():
    cyclic = PICKER_URDF.replace("</robot>", """
      <link name="loop_a"/><link name="loop_b"/>
      <joint name="ab" type="fixed"><parent link="loop_a"/><child link="loop_b"/></joint>
      <joint name="ba" type="fixed"><parent link="loop_b"/><child link="loop_a"/></joint>
    </robot>""")
    error = field_error(("file",), "cycle", import_robot, cyclic.encode(), "c.urdf",
                        robot_id="c")
    assert error.loc[1] in ("link[loop_a]", "link[loop_b]")
    assert "loop_a -> loop_b" in error.message or "loop_b -> loop_a" in error.message


def test_a_link_with_two_parents():
    looped = PICKER_URDF.replace("</robot>", """
      <joint name="closing" type="fixed"><parent link="base"/><child link="hand"/></joint>
    </robot>""")
    error = field_error(("file", "link[hand]"), "two parent joints", import_robot,
                        looped.encode(), "l.urdf", robot_id="l")
    assert "'wrist'" in error.message and "'closing'" in error.message


def test_several_roots():
    text = PICKER_URDF.replace("</robot>", '<link name="stray"/></robot>')
    field_error(("file", "link[stray]"), "not connected", import_robot, text.encode(),
                "s.urdf", robot_id="s", base_link="base", tip_link="tcp")


def test_unknown_links_list_candidates():
    error = field_error(("tip_link",), "unknown tip_link 'flange'", import_picker, group=None,
                        base_link="base", tip_link="flange")
    assert "tcp" in error.message and "finger_left" in error.message
    field_error(("base_link",), "unknown base_link", import_picker, group=None,
                base_link="bse", tip_link="tcp")
    field_error(("tip_link",), "not below base_link 'hand'", import_picker, group=None,
                base_link="hand", tip_link="arm")


def test_default_tip_is_ambiguous_when_movable_joints_branch():
    error = field_error(("tip_link",), "candidates", import_robot,
                        make_zip(picker_files(srdf=None)), "p.zip", robot_id="p")
    assert "hand" in error.message and "camera" in error.message


def test_floating_joint_on_the_chain():
    field_error(("file", "joint[payload_float]", "type"), "floating", import_picker,
                group=None, base_link="world", tip_link="payload")
    text = PICKER_URDF.replace('name="elbow" type="revolute"', 'name="elbow" type="planar"')
    field_error(("file", "joint[elbow]", "type"), "planar", import_robot,
                make_zip(picker_files(text)), "p.zip", robot_id="p", group="arm")


def test_mimic_joint_on_the_chain_is_refused():
    field_error(("file", "joint[finger_left_joint]", "mimic"), "not supported", import_picker,
                group=None, base_link="base", tip_link="finger_left")


def test_mimic_errors():
    field_error(("file", "joint[camera_tilt]", "mimic", "joint"), "not another joint",
                picker_with, 'mimic joint="camera_pan"', 'mimic joint="ghost"')
    field_error(("file", "joint[camera_tilt]", "mimic", "joint"), "chains of mimic",
                picker_with, 'mimic joint="camera_pan"', 'mimic joint="finger_right_joint"')


def test_srdf_groups():
    error = field_error(("group",), "unknown group 'manipulator'", import_picker,
                        group="manipulator")
    assert "arm" in error.message and "gripper" in error.message
    field_error(("group",), "has 0 <chain>", import_picker, group="gripper")
    field_error(("group",), "either group or base_link", import_picker, tip_link="hand")
    field_error(("group",), "no SRDF", import_robot, make_zip(picker_files(srdf=None)),
                "p.zip", robot_id="p", group="arm")
    bad = PICKER_SRDF.replace('link2="finger_right"', 'link2="finger_rihgt"')
    field_error(("srdf", "disable_collisions", 1, "link2"), "finger_rihgt", import_picker,
                srdf=bad.encode())
    bad = PICKER_SRDF.replace('tip_link="tcp"', 'tip_link="flange"')
    field_error(("srdf", "group[arm]", "chain", 0, "tip_link"), "flange", import_picker,
                srdf=bad.encode())


@pytest.mark.parametrize("old, new, loc, fragment", [
    ('<axis xyz="0 0 1"/>\n    <limit lower="-2"', '<axis xyz="0 0 0"/>\n    <limit lower="-2"',
     ("file", "joint[elbow]", "axis", "xyz"), "zero"),
    ('<axis xyz="1 0 0"/>\n    <limit lower="-3"', '<axis xyz="1 0"/>\n    <limit lower="-3"',
     ("file", "joint[wrist]", "axis", "xyz"), "3 numbers"),
    ('xyz="0.3 0 0.05" rpy="0 1.2 0"', 'xyz="0.3 zero 0.05" rpy="0 1.2 0"',
     ("file", "joint[elbow]", "origin", "xyz"), "numbers"),
    ('lower="-2" upper="2"', 'lower="2" upper="-2"', ("file", "joint[elbow]", "limit",
                                                      "upper"), "above"),
    ('<limit lower="-3" upper="3" effort="10" velocity="3"/>', "",
     ("file", "joint[wrist]", "limit"), "needs <limit"),
    ('type="continuous"', 'type="screw"', ("file", "joint[swing]", "type"), "unknown type"),
    ('<parent link="arm"/>', '<parent link="arn"/>', ("file", "joint[elbow]", "parent"),
     "unknown parent link 'arn'"),
    ('<sphere radius="0.04"/>', '<capsule radius="0.04" length="1"/>',
     ("file", "link[forearm]", "collision", 0, "geometry", "capsule"), "unsupported geometry"),
    ('<sphere radius="0.04"/>', '<sphere radius="-0.04"/>',
     ("file", "link[forearm]", "collision", 0, "geometry", "sphere", "radius"), "between"),
    ('<link name="tcp"/>', '<link name="hand"/>', ("file", "link[hand]", "name"),
     "two links"),
    ('<joint name="tcp_joint" type="fixed">', '<joint type="fixed">', ("file", "joint", 5,
                                                                       "name"), "no name"),
])
def test_urdf_errors_name_the_element(old, new, loc, fragment):
    error = field_error(loc, fragment, picker_with, old, new)
    assert error.loc == loc


def test_xml_safety():
    laughs = ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
              '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]><robot name="&b;"/>')
    field_error(("file",), "DOCTYPE", import_robot, laughs.encode(), "x.urdf", robot_id="x")
    external = ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
                '<robot name="&e;"><link name="a"/></robot>')
    field_error(("file",), "DOCTYPE", import_robot, external.encode(), "x.urdf", robot_id="x")
    field_error(("file",), "not well-formed", import_robot, b"<robot><link></robot>", "x.urdf",
                robot_id="x")
    deep = "<robot>" + "<gazebo>" * 40 + "</gazebo>" * 40 + "</robot>"
    field_error(("file",), "deep", import_robot, deep.encode(), "x.urdf", robot_id="x")
    xacro = '<robot xmlns:xacro="x"><xacro:macro name="m"/></robot>'
    field_error(("file",), "xacro", import_robot, xacro.encode(), "x.urdf", robot_id="x")
    field_error(("file",), "not <robot>", import_robot, b"<html/>", "x.urdf", robot_id="x")
    dae = (b'<?xml version="1.0"?><!DOCTYPE c [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
           b'<COLLADA>&x;</COLLADA>')
    files = picker_files(PICKER_URDF.replace("meshes/base.stl", "meshes/base.dae"))
    files["picker_description/meshes/base.dae"] = dae
    field_error(("file", "link[base]", "collision", 0), "DOCTYPE", import_robot,
                make_zip(files), "p.zip", robot_id="p", group="arm")


def test_request_fields():
    data = make_zip(picker_files())
    field_error(("robot_id",), "ASCII", import_robot, data, "p.zip", robot_id="no spaces")
    field_error(("name",), "printable", import_robot, data, "p.zip", robot_id="p",
                name="bell\x07")
    field_error(("file",), "unsupported file", import_robot, data, "p.rar", robot_id="p")
    field_error(("file",), "not a zip", import_robot, b"hello", "p.zip", robot_id="p")
    field_error(("file",), "not a gzip", import_robot, b"hello", "p.tgz", robot_id="p")
    field_error(("file",), "empty", import_robot, b"", "p.urdf", robot_id="p")
    field_error(("file",), "no .urdf", import_robot, make_zip({"a.txt": b"x"}), "p.zip",
                robot_id="p")
    robot = import_robot(data, "p.zip", robot_id="p", group="arm")
    assert robot.model.name == "gantry_picker" and robot.model.id == "p"


# ---- caps and hostile archives -----------------------------------------------------------
def test_the_default_caps_fit_real_robots():
    assert MAX_ARCHIVE_BYTES == 64 * 2**20
    assert MAX_UNPACKED_BYTES >= 4 * MAX_ARCHIVE_BYTES
    assert MAX_MESH_TRIANGLES_TOTAL >= 1_000_000


def test_caps():
    files = picker_files()
    data = make_zip(files)
    field_error(("file",), "at most 1,000 allowed", import_robot, data, "p.zip", robot_id="p",
                group="arm", limits=ImportLimits(max_archive_bytes=1000))
    field_error(("file",), "entries", import_robot, data, "p.zip", robot_id="p", group="arm",
                limits=ImportLimits(max_archive_members=3))
    field_error(("file",), "entries", import_robot, make_tar(files), "p.tgz", robot_id="p",
                group="arm", limits=ImportLimits(max_archive_members=3))
    field_error(("file",), "bytes", import_robot, data, "p.zip", robot_id="p", group="arm",
                limits=ImportLimits(max_xml_bytes=500))
    field_error(("file", "link[base]", "collision", 0), "at most 10 per mesh", import_robot,
                data, "p.zip", robot_id="p", group="arm",
                limits=ImportLimits(max_mesh_triangles=10))
    field_error(("file",), "in all", import_robot, data, "p.zip", robot_id="p", group="arm",
                limits=ImportLimits(max_mesh_triangles_total=50))
    field_error(("file",), "distinct mesh files", import_robot, data, "p.zip", robot_id="p",
                group="arm", limits=ImportLimits(max_mesh_files=1))
    field_error(("file",), "links", import_robot, data, "p.zip", robot_id="p", group="arm",
                limits=ImportLimits(max_links=5))


def test_zip_and_tar_bombs_stop_at_the_unpacked_cap():
    files = picker_files()
    files["picker_description/meshes/padding.stl"] = bytes(3_000_000)  # compresses to ~3 kB
    limits = ImportLimits(max_unpacked_bytes=1_000_000)
    zipped = make_zip(files)
    assert len(zipped) < 100_000
    field_error(("file",), "unpacks to", import_robot, zipped, "p.zip", robot_id="p",
                group="arm", limits=limits)
    field_error(("file",), "1,000,000", import_robot, make_tar(files), "p.tgz", robot_id="p",
                group="arm", limits=limits)
    assert import_robot(zipped, "p.zip", robot_id="p", group="arm").model.dof == 4


def test_traversal_names_and_links_are_never_followed(tmp_path):
    """Names are only looked up inside the upload: climbing names are dropped, links
    ignored, and a path to a real file on this machine is not read."""
    secret = tmp_path / "secret.stl"
    secret.write_bytes(trimesh.creation.box().export(file_type="stl"))
    urdf = PICKER_URDF.replace("package://picker_description/meshes/base.stl",
                               f"file://{secret}")
    files = picker_files(urdf)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
        zf.writestr("../../secret.stl", b"climbing")
        link = zipfile.ZipInfo("picker_description/meshes/secret.stl")
        link.external_attr = (stat.S_IFLNK | 0o777) << 16
        zf.writestr(link, str(secret))
    error = field_error(("file", "link[base]", "collision", 0), "not in the archive",
                        import_robot, buffer.getvalue(), "p.zip", robot_id="p", group="arm")
    assert str(secret) in error.message
    # the same in a tar archive: a symbolic link and a climbing name
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tf:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
        sym = tarfile.TarInfo("picker_description/meshes/secret.stl")
        sym.type = tarfile.SYMTYPE
        sym.linkname = str(secret)
        tf.addfile(sym)
        climb = tarfile.TarInfo("../secret.stl")
        climb.size = 3
        tf.addfile(climb, io.BytesIO(b"abc"))
    field_error(("file", "link[base]", "collision", 0), "not in the archive", import_robot,
                buffer.getvalue(), "p.tgz", robot_id="p", group="arm")
    # a URDF whose only copy climbs out is no URDF at all
    field_error(("file",), "no .urdf", import_robot,
                make_zip({"../robot.urdf": PICKER_URDF.encode()}), "p.zip", robot_id="p")
