"""Collision scenes (planning.collision): the object format and its errors, mesh files,
MoveIt planning scenes, and the scene's distances."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from kinematics.errors import FieldError
from planning.collision import (
    MAX_OBJECTS,
    MAX_POINTS,
    OBJECT_TYPES,
    CollisionScene,
    load_mesh_file,
    scene_from_moveit,
    scene_to_moveit,
)


def rz(angle: float, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = t
    return T


OBJECTS = [
    {"type": "box", "id": "table", "size": [1200, 800, 40], "pose": rz(0.3, (600, 0, 380))},
    {"type": "sphere", "radius": 50, "pose": rz(0.0, (0, 500, 100))},
    {"type": "cylinder", "id": "post", "radius": 60, "height": 1500},
    {"type": "capsule", "id": "rail", "a": [0, 0, 0], "b": [500, 0, 0], "radius": 25,
     "pose": rz(1.0, (-300, 0, 200))},
    {"type": "mesh", "id": "fixture", "vertices": [[0, 0, 0], [100, 0, 0], [0, 100, 0],
                                                   [0, 0, 100]],
     "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], "scale": [2, 1, 1],
     "pose": rz(0.5, (200, -400, 0))},
    {"type": "points", "id": "scan", "points": [[0, 0, 0], [10, 0, 0], [500, 0, 0]],
     "radius": 5, "pose": rz(0.0, (0, 0, 900))},
]


def _objects():
    return [{k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in o.items()}
            for o in OBJECTS]


# ---- the object format ----------------------------------------------------------------------
def test_objects_round_trip_through_dicts():
    scene = CollisionScene.from_dicts(_objects())
    assert scene.ids == ("table", "sphere1", "post", "rail", "fixture", "scan")
    again = CollisionScene.from_dicts(scene.to_dicts())
    assert again.to_dicts() == scene.to_dicts()
    P = np.random.default_rng(0).uniform(-1000, 1000, size=(200, 3))
    assert np.array_equal(scene.compiled().object_distance(P),
                          again.compiled().object_distance(P))
    assert scene.to_dict() == {"objects": scene.to_dicts()}


def test_distances_to_primitives_are_exact():
    cs = CollisionScene.from_dicts(_objects()[:4]).compiled()
    T = rz(0.3, (600, 0, 380))
    # Points along the table's local axes: 100 mm above its top, 30 mm inside its end.
    above = T @ [100, 50, 20 + 100, 1]
    inside = T @ [600 - 30, 0, 0, 1]
    d = cs.object_distance(np.array([above[:3], inside[:3]]))
    assert d[:, 0] == pytest.approx([100.0, -20.0])   # inside: minus the depth to the top
    rail_mid = rz(1.0, (-300, 0, 200)) @ [250, 0, 0, 1]
    d = cs.object_distance((rail_mid[:3] + [0, 0, 100])[None])
    assert d[0, 3] == pytest.approx(75.0)
    # A point 40 mm off the post's side, level with its middle; 10 mm above its top.
    d = cs.object_distance(np.array([[100.0, 0, 0], [0, 0, 760.0]]))
    assert d[:, 2] == pytest.approx([40.0, 10.0])
    # The grid's bound never exceeds the exact distance.
    P = np.random.default_rng(1).uniform(-1500, 1500, size=(2000, 3))
    assert np.all(cs.lower_bound(P) <= cs.object_distance(P).min(axis=1) + 1e-9)


def test_mesh_and_points_are_covered_by_their_balls():
    scene = CollisionScene.from_dicts(_objects()[4:])
    cs = scene.compiled()
    fixture, scan = scene.objects
    tri = fixture.world_vertices()[fixture.faces]
    rng = np.random.default_rng(2)
    u, v = rng.random((2, 500))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    k = rng.integers(0, len(tri), 500)
    on = tri[k, 0] + u[:, None] * (tri[k, 1] - tri[k, 0]) + v[:, None] * (tri[k, 2] - tri[k, 0])
    assert np.all(cs.object_distance(on)[:, 0] <= 1e-9)
    offsets = rng.normal(size=(300, 3))
    offsets *= 5 * rng.random((300, 1)) / np.linalg.norm(offsets, axis=1, keepdims=True)
    near = scan.world_points()[rng.integers(0, 3, 300)] + offsets
    assert np.all(cs.object_distance(near)[:, 1] <= 1e-9)
    assert np.all(cs.lower_bound(near) <= 1e-9)


@pytest.mark.parametrize("index, change, loc, message", [
    (1, {"radius": -5}, ("objects", 1, "radius"), "positive"),
    (2, {"radius": 0}, ("objects", 2, "radius"), "positive"),
    (0, {"type": "cone"}, ("objects", 0, "type"), "known types: box, sphere"),
    (0, {"size": [1, 2]}, ("objects", 0, "size"), "3 numbers"),
    (3, {"b": None}, ("objects", 3, "b"), "3 numbers"),
    (0, {"pose": [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ("objects", 0, "pose"), "rigid"),
    (0, {"pose": [[1, 0, 0], [0, 1, 0]]}, ("objects", 0, "pose"), "4x4"),
    (4, {"faces": [[0, 1, 9]]}, ("objects", 4, "faces"), "index"),
    (5, {"resolution": -1}, ("objects", 5, "resolution"), "positive"),
    (2, {"colour": "red"}, ("objects", 2, "colour"), "unknown field"),
])
def test_errors_name_the_object_and_field(index, change, loc, message):
    objects = _objects()
    objects[index] = {**objects[index], **change}
    with pytest.raises(FieldError, match=message) as err:
        CollisionScene.from_dicts(objects)
    assert err.value.loc == loc


def test_missing_fields_duplicates_and_caps():
    with pytest.raises(FieldError) as err:
        CollisionScene.from_dicts([{"type": "cylinder", "radius": 5}])
    assert err.value.loc == ("objects", 0, "height")
    with pytest.raises(FieldError) as err:
        CollisionScene.from_dicts([{"type": "box", "id": "a", "size": [1, 1, 1]},
                                   {"type": "sphere", "id": "a", "radius": 1}])
    assert err.value.loc == ("objects", 1, "id")
    with pytest.raises(FieldError, match=str(MAX_OBJECTS)) as err:
        CollisionScene.from_dicts([{"type": "sphere", "radius": 1}] * (MAX_OBJECTS + 1))
    assert err.value.loc == ("objects",)
    cloud = np.zeros((MAX_POINTS + 1, 3))
    with pytest.raises(FieldError, match="cap") as err:
        CollisionScene.from_dicts([{"type": "points", "points": cloud, "radius": 1}])
    assert err.value.loc == ("objects", 0, "points")
    with pytest.raises(FieldError, match="no stored mesh named 'nope'") as err:
        CollisionScene.from_dicts([{"type": "mesh", "mesh": "nope"}],
                                  resolve_mesh=lambda name: {}[name])
    assert err.value.loc == ("objects", 0, "mesh")
    assert set(OBJECT_TYPES) == {"box", "sphere", "cylinder", "capsule", "mesh", "points"}


def test_stored_meshes_are_resolved_by_name_and_stay_references():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    F = np.array([[0, 1, 2]])
    store = {"bracket": (V, F)}
    scene = CollisionScene.from_dicts([{"type": "mesh", "mesh": "bracket", "scale": 1000}],
                                      resolve_mesh=store.__getitem__)
    assert scene.to_dicts()[0]["mesh"] == "bracket"
    assert "vertices" not in scene.to_dicts()[0]
    assert np.array_equal(scene.objects[0].world_vertices(), V * 1000)


# ---- mesh files -----------------------------------------------------------------------------
@pytest.mark.parametrize("ext", ["stl", "obj", "ply"])
def test_mesh_files_load(ext):
    m = trimesh.creation.box(extents=(10, 20, 30))
    data = m.export(file_type=ext)
    V, F = load_mesh_file(data if isinstance(data, bytes) else data.encode(), f"part.{ext}")
    assert F.shape == (12, 3) and V.shape[1] == 3
    assert np.allclose(V.min(axis=0), [-5, -10, -15]) and np.allclose(V.max(axis=0),
                                                                      [5, 10, 15])


@pytest.mark.parametrize("data, name, message", [
    (b"not a mesh at all", "part.stl", "could not be read|no triangles"),
    (b"solid x\nendsolid x\n", "part.stl", "no triangles|could not be read"),
    (b"v 0 0 0\n", "part.obj", "no triangles|could not be read"),
    (b"anything", "part.step", "not a mesh file"),
])
def test_bad_mesh_files_are_field_errors(data, name, message):
    with pytest.raises(FieldError, match=message) as err:
        load_mesh_file(data, name)
    assert err.value.loc == ("file",)


# ---- MoveIt ---------------------------------------------------------------------------------
def _quat_z(angle: float) -> list[float]:
    return [0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2)]


MOVEIT = {
    "name": "cell",
    "robot_state": {"joint_state": {"name": ["j1"], "position": [0.3]}},
    "world": {"collision_objects": [
        {"id": "shelf",
         "pose": {"position": [1.0, 0.0, 0.5], "orientation": _quat_z(math.pi / 2)},
         "primitives": [{"type": "box", "dimensions": [0.4, 0.2, 0.1]},
                        {"type": "cylinder", "dimensions": [0.3, 0.05]}],
         "primitive_poses": [
             {"position": {"x": 0.1, "y": 0.0, "z": 0.0},
              "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
             {"position": [0.0, 0.2, 0.0], "orientation": _quat_z(math.pi / 2)}]},
        {"id": "Can1", "primitives": [{"type": "sphere", "dimensions": [0.03]}],
         "primitive_poses": [{"position": [0.3, 0.8, 0.3], "orientation": [0, 0, 0, 2]}]},
        {"id": "cone", "primitives": [{"type": 4, "dimensions": [0.2, 0.1]}],
         "primitive_poses": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 1]}]},
        {"id": "tri", "meshes": [{"vertices": [{"x": 0, "y": 0, "z": 0}, [0.1, 0, 0],
                                               [0, 0.1, 0]],
                                  "triangles": [{"vertex_indices": [0, 1, 2]}]}],
         "mesh_poses": [{"position": [0, 0, 1], "orientation": [0, 0, 0, 1]}]},
    ]},
}


def test_moveit_objects_compose_object_and_shape_poses():
    objects = scene_from_moveit(MOVEIT)
    assert [o["id"] for o in objects] == ["shelf/0", "shelf/1", "Can1", "cone", "tri"]
    box, cyl, can, cone, tri = objects
    # The object turns 90 degrees about z at (1, 0, 0.5) m; the box sits 0.1 m along the
    # object's x, which is the world's y: (1, 0.1, 0.5) m.
    assert np.allclose(np.array(box["pose"])[:3, 3], [1000, 100, 500])
    assert np.allclose(np.array(box["pose"])[:3, :3], rz(math.pi / 2)[:3, :3])
    assert box["size"] == pytest.approx([400, 200, 100])
    # The cylinder 0.2 m along the object's y (the world's -x), turned 90 + 90 degrees.
    assert np.allclose(np.array(cyl["pose"])[:3, 3], [800, 0, 500])
    assert np.allclose(np.array(cyl["pose"])[:3, :3], rz(math.pi)[:3, :3])
    assert (cyl["height"], cyl["radius"]) == pytest.approx((300, 50))
    # No object pose: the identity; the quaternion (0, 0, 0, 2) normalised.
    assert np.allclose(np.array(can["pose"]), rz(0, (300, 800, 300)))
    assert can["radius"] == pytest.approx(30)
    assert (cone["type"], cone["height"], cone["radius"]) == ("cylinder", 200, 100)
    assert tri["vertices"] == [[0, 0, 0], [100, 0, 0], [0, 100, 0]]
    assert tri["faces"] == [[0, 1, 2]]


def test_moveit_round_trips():
    scene = CollisionScene.from_moveit(MOVEIT)
    again = CollisionScene.from_dicts(scene.to_dicts())
    P = np.random.default_rng(3).uniform(-500, 1500, size=(300, 3))
    assert np.allclose(scene.compiled().object_distance(P), again.compiled().object_distance(P))
    back = CollisionScene.from_moveit(scene_to_moveit(scene, name="cell"))
    assert np.allclose(back.compiled().object_distance(P), scene.compiled().object_distance(P))
    both = CollisionScene.from_request({"objects": _objects()[:1], "moveit": MOVEIT})
    assert both.ids[0] == "table" and len(both) == 6


@pytest.mark.parametrize("change, loc, message", [
    ({"orientation": [0, 0, 0, 0]},
     ("world", "collision_objects", 1, "primitive_poses", 0, "orientation"), "zero"),
    ({"orientation": [0, 0, 1]},
     ("world", "collision_objects", 1, "primitive_poses", 0, "orientation"), "x, y, z, w"),
])
def test_moveit_pose_errors(change, loc, message):
    bad = {"world": {"collision_objects": [
        MOVEIT["world"]["collision_objects"][0],
        {"id": "Can1", "primitives": [{"type": "sphere", "dimensions": [0.03]}],
         "primitive_poses": [{"position": [0.3, 0.8, 0.3], **change}]}]}}
    with pytest.raises(FieldError, match=message) as err:
        scene_from_moveit(bad)
    assert err.value.loc == loc


def test_moveit_shape_errors():
    def one(obj):
        return {"world": {"collision_objects": [obj]}}

    with pytest.raises(FieldError, match="prism") as err:
        scene_from_moveit(one({"id": "x", "primitives": [{"type": "prism", "dimensions": [1]}]}))
    assert err.value.loc == ("world", "collision_objects", 0, "primitives", 0, "type")
    with pytest.raises(FieldError, match="2 dimensions") as err:
        scene_from_moveit(one({"id": "x", "primitives": [{"type": "cylinder",
                                                          "dimensions": [1]}]}))
    assert err.value.loc == ("world", "collision_objects", 0, "primitives", 0, "dimensions")
    with pytest.raises(FieldError, match="planes") as err:
        scene_from_moveit(one({"id": "x", "planes": [{"coef": [0, 0, 1, 0]}]}))
    assert err.value.loc == ("world", "collision_objects", 0, "planes")
    with pytest.raises(FieldError) as err:
        CollisionScene.from_request({"moveit": one({"id": "x", "primitives": [
            {"type": "box", "dimensions": [1, -1, 1]}]})})
    assert err.value.loc[:3] == ("moveit", "world", "collision_objects")
    assert scene_from_moveit({"robot_state": {}}) == []
