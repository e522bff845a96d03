"""Triangles against solid boxes and cylinders (planning.geometry.triangles), compiled,
against FCL's mesh-box and mesh-cylinder collision on random triangle soups and poses near
contact: the same answers; and the motion planner's checker settling such pairs with them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planning.geometry.registry import KERNEL_CODES
from planning.geometry.triangles import CHUNK, MeshTriangles

fcl = pytest.importorskip("fcl")
BOX = KERNEL_CODES["box"]


def triangles_meet_box(mt, k, Mk, T_inv, half):
    """``triangles_meet_object`` of link ``k`` of ``mt`` for a box of half sides ``half``."""
    return mt.meets(k, Mk, T_inv, BOX, np.r_[half, 0.0])


def _bvh(tri: np.ndarray):
    """FCL's bounding volume tree of a triangle soup ``(T, 3, 3)``."""
    bvh = fcl.BVHModel()
    bvh.beginModel(len(tri) * 3, len(tri))
    bvh.addSubModel(tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3))
    bvh.endModel()
    return bvh


def _fcl_hit(tri: np.ndarray, link_pose: np.ndarray, box_pose: np.ndarray, size) -> bool:
    a = fcl.CollisionObject(_bvh(tri), fcl.Transform(link_pose[:3, :3], link_pose[:3, 3]))
    b = fcl.CollisionObject(fcl.Box(*size), fcl.Transform(box_pose[:3, :3], box_pose[:3, 3]))
    return bool(fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()))


def _fcl_cylinder_hit(tri, link_pose, cyl_pose, radius, height) -> bool:
    a = fcl.CollisionObject(_bvh(tri), fcl.Transform(link_pose[:3, :3], link_pose[:3, 3]))
    b = fcl.CollisionObject(fcl.Cylinder(radius, height),
                            fcl.Transform(cyl_pose[:3, :3], cyl_pose[:3, 3]))
    return bool(fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult()))


def _pose(rng, spread: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def test_triangles_meet_boxes_as_fcl_says():
    rng = np.random.default_rng(2024)
    agree = hits = 0
    for case in range(600):
        n = int(rng.integers(1, 12))
        # Triangles of sizes from slivers to ones larger than the box, near the origin.
        centre = rng.uniform(-60, 60, (n, 1, 3))
        tri = centre + rng.normal(0, rng.choice([2.0, 20.0, 80.0]), (n, 3, 3))
        size = rng.uniform(5, 80, 3)
        link_pose, box_pose = _pose(rng, 40), _pose(rng, 40)
        mt = MeshTriangles([tri])
        T_inv = np.linalg.inv(box_pose)[:3]
        ours = triangles_meet_box(mt, 0, link_pose[:3], T_inv, 0.5 * size)
        ref = _fcl_hit(tri, link_pose, box_pose, size)
        assert ours == ref, f"case {case}: ours {ours}, fcl {ref}"
        agree += 1
        hits += ref
    # Both answers occur often enough to mean something.
    assert 150 < hits < 450, hits


def test_triangles_meet_cylinders_as_fcl_says():
    rng = np.random.default_rng(4048)
    hits = 0
    code = KERNEL_CODES["cylinder"]
    for case in range(600):
        n = int(rng.integers(1, 12))
        centre = rng.uniform(-60, 60, (n, 1, 3))
        tri = centre + rng.normal(0, rng.choice([2.0, 20.0, 80.0]), (n, 3, 3))
        radius, height = rng.uniform(5, 50), rng.uniform(10, 150)
        link_pose, cyl_pose = _pose(rng, 40), _pose(rng, 40)
        mt = MeshTriangles([tri])
        par = np.array([radius, 0.5 * height, 0.0, 0.0])
        ours = mt.meets(0, link_pose[:3], np.linalg.inv(cyl_pose)[:3], code, par)
        ref = _fcl_cylinder_hit(tri, link_pose, cyl_pose, radius, height)
        assert ours == ref, f"case {case}: ours {ours}, fcl {ref}"
        hits += ref
    assert 150 < hits < 450, hits


def test_a_triangle_pierced_by_a_thin_cylinder():
    """A cylinder through the middle of a large triangle, every edge and corner far from it:
    a hit; moved off the triangle's plane beyond its half height: none."""
    tri = np.array([[[-100, -100, 0], [100, -100, 0], [0, 150, 0]]], float)
    mt = MeshTriangles([tri])
    code = KERNEL_CODES["cylinder"]
    par = np.array([2.0, 10.0, 0.0, 0.0])
    eye = np.ascontiguousarray(np.eye(4)[:3])
    assert mt.meets(0, eye, eye, code, par)
    T = np.eye(4)
    T[2, 3] = 10.5                                  # the cylinder from z 0.5 to 20.5
    assert not mt.meets(0, eye, np.linalg.inv(T)[:3], code, par)
    # Lying along the triangle's plane, through it, edges far: a hit too.
    R = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R
    assert mt.meets(0, eye, np.linalg.inv(T)[:3], code, par)


def test_a_triangle_inside_a_box_and_one_beside_it():
    """Inside a solid box is a hit (the box is solid); 0.01 mm beside a face is not; one
    lying on the face touches, and touching counts."""
    half = np.array([10.0, 20.0, 30.0])
    inside = np.array([[[1, 1, 1], [2, 1, 1], [1, 2, 1]]], float)
    beside = np.array([[[10.01, 0, 0], [10.01, 5, 0], [10.01, 0, 5]]], float)
    on = np.array([[[10.0, 0, 0], [10.0, 5, 0], [10.0, 0, 5]]], float)
    eye = np.ascontiguousarray(np.eye(4)[:3])
    for tri, expected in ((inside, True), (beside, False), (on, True)):
        mt = MeshTriangles([tri])
        assert triangles_meet_box(mt, 0, eye, eye, half) is expected


def test_a_mesh_of_thousands_of_triangles_in_chunks_meets_what_fcl_says():
    """A link of 3,000 small triangles scattered over a 400 mm shell (Morton ordered,
    chunked) and a second link before it: against 300 boxes and cylinders placed near the
    shell, the chunked test answers as FCL on the whole mesh, and as the test of every
    triangle one by one (a chunk is skipped only when its box misses the object's)."""
    rng = np.random.default_rng(77)
    n = 3000
    u = rng.normal(size=(n, 3))
    centre = 200.0 * u / np.linalg.norm(u, axis=1, keepdims=True)
    tri = centre[:, None, :] + rng.normal(0, 6.0, (n, 3, 3))
    other = rng.normal(0, 30.0, (5, 3, 3)) + 1000.0
    mt = MeshTriangles([other, tri])
    assert mt.cfirst[2] - mt.cfirst[1] == -(-n // CHUNK)
    assert sorted(map(tuple, mt.tri[mt.first[1]:].reshape(n, 9))) \
        == sorted(map(tuple, tri.reshape(n, 9)))          # the same triangles, reordered
    one_by_one = MeshTriangles([t[None] for t in tri])
    hits = 0
    for case in range(300):
        link_pose = _pose(rng, 20)
        obj_pose = _pose(rng, 0)
        d = rng.normal(size=3)
        obj_pose[:3, 3] = 200.0 * d / np.linalg.norm(d) + rng.normal(0, 15, 3)
        T_inv = np.linalg.inv(obj_pose)[:3]
        if case % 2:
            size = rng.uniform(2, 25, 3)
            ours = triangles_meet_box(mt, 1, link_pose[:3], T_inv, 0.5 * size)
            ref = _fcl_hit(tri, link_pose, obj_pose, size)
            each = any(triangles_meet_box(one_by_one, k, link_pose[:3], T_inv, 0.5 * size)
                       for k in range(n))
        else:
            code = KERNEL_CODES["cylinder"]
            radius, height = rng.uniform(2, 15), rng.uniform(4, 40)
            par = np.array([radius, 0.5 * height, 0.0, 0.0])
            ours = mt.meets(1, link_pose[:3], T_inv, code, par)
            ref = _fcl_cylinder_hit(tri, link_pose, obj_pose, radius, height)
            each = any(one_by_one.meets(k, link_pose[:3], T_inv, code, par)
                       for k in range(n))
        assert ours == ref == each, f"case {case}: ours {ours}, fcl {ref}, each {each}"
        hits += ref
    assert 60 < hits < 240, hits


def test_only_the_links_rows_are_tested():
    """``MeshTriangles`` keeps each link's rows apart; a link without triangles has none."""
    far = np.array([[[500, 0, 0], [501, 0, 0], [500, 1, 0]]], float)
    near = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    mt = MeshTriangles([far, None, near])
    assert mt.whole.tolist() == [True, False, True]
    assert mt.first.tolist() == [0, 1, 1, 2]
    eye = np.ascontiguousarray(np.eye(4)[:3])
    half = np.array([5.0, 5.0, 5.0])
    assert not triangles_meet_box(mt, 0, eye, eye, half)
    assert not triangles_meet_box(mt, 1, eye, eye, half)
    assert triangles_meet_box(mt, 2, eye, eye, half)


# ---- in the motion planner's checker --------------------------------------------------------
def _mesh_robot():
    """A cone mesh on three prismatic joints (x, y, z), turned so no face is axis-aligned."""
    import trimesh
    from test_collision import Geom, Link, Mesh, Robot, slider

    cone = trimesh.creation.cone(radius=60, height=150, sections=24)
    cone.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1, 1, 0]))
    mesh = {"cone": Mesh(np.asarray(cone.vertices, float), np.asarray(cone.faces, np.int64))}
    model = slider(((1, 0, 0), (0, 1, 0), (0, 0, 1)), limit=400.0)
    return Robot(model, (Link("cone", 3, np.eye(4), (Geom("mesh", mesh="cone"),)),),
                 meshes=mesh), cone


def _boxes(rng) -> list[dict]:
    """Three rotated boxes and two cylinders."""
    out = []
    for i in range(5):
        T = np.eye(4)
        T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        T[:3, 3] = rng.uniform(-250, 250, 3)
        if i < 3:
            out.append({"type": "box", "id": f"b{i}", "size": rng.uniform(40, 160, 3).tolist(),
                        "pose": T.tolist()})
        else:
            out.append({"type": "cylinder", "id": f"c{i}", "radius": float(rng.uniform(20, 60)),
                        "height": float(rng.uniform(60, 200)), "pose": T.tolist()})
    return out


def _fcl_object(b: dict):
    T = np.asarray(b["pose"], dtype=float)
    geom = fcl.Box(*b["size"]) if b["type"] == "box" else fcl.Cylinder(b["radius"], b["height"])
    return fcl.CollisionObject(geom, fcl.Transform(T[:3, :3], T[:3, 3]))


@pytest.mark.usefixtures("motion_kernels")
def test_the_checker_settles_mesh_box_hits_without_fcl(monkeypatch):
    """A mesh link among rotated boxes and cylinders: the checker's answers equal FCL's on
    the mesh, and with margin 0 the exact stage's FCL is never asked."""
    import planning.collision as collision
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion import MotionChecker

    rng = np.random.default_rng(11)
    robot, cone = _mesh_robot()
    scene_dicts = _boxes(rng)
    cm = RobotCollisionModel.from_imported(robot)
    checker = MotionChecker(cm, CollisionScene.from_dicts(scene_dicts))
    Q = rng.uniform(-400, 400, (600, 3))

    def no_fcl(*args, **kwargs):
        raise AssertionError("FCL asked for a mesh-box or mesh-cylinder pair")

    monkeypatch.setattr(collision, "exact_stage", no_fcl)
    ours = checker.free(Q)
    monkeypatch.undo()
    tri = np.asarray(cone.triangles)
    bvh = _bvh(tri)
    objects = [_fcl_object(b) for b in scene_dicts]
    ref = []
    for q in Q:
        a = fcl.CollisionObject(bvh, fcl.Transform(np.eye(3), q))
        ref.append(not any(fcl.collide(a, o, fcl.CollisionRequest(), fcl.CollisionResult())
                           for o in objects))
    ref = np.array(ref)
    assert np.array_equal(ours, ref)
    assert 0.2 < ref.mean() < 0.95
    assert checker.exact_checks > 20        # the spheres flagged states the test settled


@pytest.mark.usefixtures("motion_kernels")
def test_with_a_margin_the_checker_measures_by_fcl():
    """With a margin the answer is a distance question: FCL settles it, as before."""
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion import MotionChecker

    rng = np.random.default_rng(12)
    robot, cone = _mesh_robot()
    scene_dicts = _boxes(rng)
    checker = MotionChecker(RobotCollisionModel.from_imported(robot),
                            CollisionScene.from_dicts(scene_dicts), margin=15.0)
    Q = rng.uniform(-400, 400, (300, 3))
    ours = checker.free(Q)
    bvh = fcl.BVHModel()
    tri = np.asarray(cone.triangles)
    bvh.beginModel(len(tri) * 3, len(tri))
    bvh.addSubModel(tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3))
    bvh.endModel()
    objects = [_fcl_object(b) for b in scene_dicts]
    ref = []
    for q in Q:
        a = fcl.CollisionObject(bvh, fcl.Transform(np.eye(3), q))
        d = min(fcl.distance(a, o, fcl.DistanceRequest(), fcl.DistanceResult())
                for o in objects)
        ref.append(d > 15.0)
    assert np.array_equal(ours, np.array(ref))


@pytest.mark.usefixtures("motion_kernels")
def test_a_sweeps_proof_never_accepts_a_state_within_its_margin():
    """A sweep's proof (the exact stage asked with ``extra`` mm more margin) may refuse
    what is clear, never accept what FCL finds within the margin; most clear states pass."""
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion import MotionChecker

    rng = np.random.default_rng(13)
    robot, cone = _mesh_robot()
    scene_dicts = _boxes(rng)
    checker = MotionChecker(RobotCollisionModel.from_imported(robot),
                            CollisionScene.from_dicts(scene_dicts))
    tri = np.asarray(cone.triangles)
    bvh = _bvh(tri)
    objects = [_fcl_object(b) for b in scene_dicts]
    accepted = clear = 0
    for q in rng.uniform(-400, 400, (400, 3)):
        a = fcl.CollisionObject(bvh, fcl.Transform(np.eye(3), q))
        d = min(fcl.distance(a, o, fcl.DistanceRequest(), fcl.DistanceResult())
                for o in objects)
        ok = checker._exact_free(q, 10.0)
        assert not (ok and d <= 10.0), (q, d)
        accepted += ok
        clear += d > 10.0
    assert accepted > 0.8 * clear
