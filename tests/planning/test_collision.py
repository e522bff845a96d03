"""Collision checking (planning.collision): certified small cases, the spheres'
conservativeness, self-collision pairs, batches, and the exact stage.

Robots here are small stand-ins of the imported-robot interface (links riding chain frames,
their collision geometry, adjacent and disabled pairs, ``link_poses``) built on
product-of-exponentials models with prismatic joints, so that every distance has a closed
form."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.fk import fk_frames
from kinematics.model import RobotModel
from planning.collision import CollisionScene, RobotCollisionModel, check, collides
from planning.geometry.spheres import box_solid, cover_link, cylinder_solid, sphere_solid

fcl = pytest.importorskip("fcl")


# ---- a stand-in imported robot ----------------------------------------------------------------
@dataclass(frozen=True)
class Mesh:
    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class Geom:
    kind: str
    origin: np.ndarray = field(default_factory=lambda: np.eye(4))
    size: tuple = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    mesh: str | None = None


@dataclass(frozen=True)
class Link:
    name: str
    frame: int
    offset: np.ndarray
    collision: tuple


@dataclass(frozen=True, eq=False)
class Robot:
    model: RobotModel
    links: tuple
    adjacent_pairs: frozenset = frozenset()
    disabled_pairs: frozenset = frozenset()
    meshes: dict = field(default_factory=dict)

    def link_poses(self, q):
        F = fk_frames(self.model, q)
        frames = [link.frame for link in self.links]
        offsets = np.stack([link.offset for link in self.links])
        return F[..., frames, :, :] @ offsets


def translation(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def slider(axes=((1, 0, 0),), limit=2000.0) -> RobotModel:
    """Prismatic joints along ``axes`` (mm), home at the origin."""
    return RobotModel.from_dict({
        "id": "slider", "name": "slider", "convention": "poe",
        "joints": [{"name": f"j{k}", "type": "prismatic", "axis": list(a), "lower": -limit,
                    "upper": limit} for k, a in enumerate(axes)],
        "home": np.eye(4).tolist()})


def one_link(geom: Geom, meshes=None, axes=((1, 0, 0),)) -> Robot:
    model = slider(axes)
    return Robot(model, (Link("body", model.dof, np.eye(4), (geom,)),), meshes=meshes or {})


def box_mesh(size) -> Mesh:
    m = trimesh.creation.box(extents=size)
    return Mesh(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))


def box(size, at, oid="box") -> dict:
    return {"type": "box", "id": oid, "size": list(size), "pose": translation(*at).tolist()}


# ---- certified small cases ----------------------------------------------------------------------
def test_sphere_link_against_a_box_at_known_distances():
    """A ball of radius 50 sliding along x towards a 100 mm cube centred at x = 300: the gap
    is 200 - q."""
    cm = RobotCollisionModel.from_imported(one_link(Geom("sphere", radius=50.0)))
    scene = CollisionScene.from_dicts([box((100, 100, 100), (300, 0, 0), "cube")])
    q = np.array([[0.0], [100.0], [199.0], [200.0], [201.0], [400.0]])
    rep = check(cm, q, scene, exact_distance=True)
    assert rep.collides.tolist() == [False, False, False, True, True, True]
    assert rep.distance[:3] == pytest.approx([200.0, 100.0, 1.0], abs=1e-6)
    assert rep.distance_exact[:3].all()
    assert rep.pairs[1] == [("body", "cube")]
    lower = check(cm, q[:3], scene).distance      # spheres only: a lower bound, close
    assert np.all(lower <= [200.0, 100.0, 1.0]) and np.all(lower >= [190.0, 90.0, -9.0])
    assert collides(cm, q, scene, exact=True).tolist() == rep.collides.tolist()
    spheres = collides(cm, q, scene)
    assert spheres[:2].tolist() == [False, False] and spheres[3:].all()   # q = 199: either


def test_capsule_link_against_a_cylinder():
    """A D-H / PoE capsule of radius 20 from the origin to (500 + q, 0, 0) and an upright
    cylinder of radius 30 at x = 700: gap 150 - q; one beside it at y = 100: gap 50."""
    model = RobotModel.from_dict({
        "id": "reach", "name": "reach", "convention": "poe",
        "joints": [{"name": "feed", "type": "prismatic", "axis": [1, 0, 0], "lower": 0,
                    "upper": 300}],
        "home": translation(500).tolist()})
    cm = RobotCollisionModel.from_model(model, link_radius=20.0)
    ahead = CollisionScene.from_dicts([{"type": "cylinder", "id": "post", "radius": 30,
                                        "height": 200, "pose": translation(700).tolist()}])
    q = np.array([[0.0], [100.0], [149.0], [151.0]])
    rep = check(cm, q, ahead, exact_distance=True)
    assert rep.distance[:3] == pytest.approx([150.0, 50.0, 1.0], abs=1e-4)
    assert rep.collides.tolist() == [False, False, False, True]
    beside = CollisionScene.from_dicts([{"type": "cylinder", "id": "post", "radius": 30,
                                         "height": 200, "pose": translation(300, 100).tolist()}])
    rep = check(cm, q, beside, exact_distance=True)
    assert rep.distance == pytest.approx([50.0] * 4, abs=1e-4)


def test_link_mesh_box_against_a_scene_box():
    """A 100 mm cube mesh on the link, a 100 mm scene cube at x = 400: gap 300 - q."""
    robot = one_link(Geom("mesh", mesh="cube"), {"cube": box_mesh((100, 100, 100))})
    cm = RobotCollisionModel.from_imported(robot)
    scene = CollisionScene.from_dicts([box((100, 100, 100), (400, 0, 0))])
    q = np.array([[0.0], [250.0], [299.5], [300.5]])
    rep = check(cm, q, scene, exact_distance=True)
    assert rep.distance[:3] == pytest.approx([300.0, 50.0, 0.5], abs=1e-6)
    assert rep.collides.tolist() == [False, False, False, True]
    assert not collides(cm, q[:2], scene).any()
    assert collides(cm, q, scene, exact=True).tolist() == [False, False, False, True]


def test_point_cloud():
    """Points at x = 300 inflated by 10 mm, a ball of radius 50 sliding along x: gap
    240 - q; the cloud's spheres never miss a point."""
    cm = RobotCollisionModel.from_imported(one_link(Geom("sphere", radius=50.0)))
    pts = [[300, 0, 0], [300, 40, 0], [320, -40, 5], [900, 900, 900]]
    scene = CollisionScene.from_dicts([{"type": "points", "id": "scan", "points": pts,
                                        "radius": 10, "resolution": 25}])
    q = np.array([[0.0], [200.0], [239.0], [241.0]])
    rep = check(cm, q, scene, exact_distance=True)
    assert rep.distance[:3] == pytest.approx([240.0, 40.0, 1.0], abs=1e-6)
    assert rep.collides.tolist() == [False, False, False, True]
    assert rep.pairs[3] == [("body", "scan")]


# ---- conservativeness ----------------------------------------------------------------------------
def _random_mesh(kind: int, a: float, b: float, seed: int) -> trimesh.Trimesh:
    if kind == 0:
        return trimesh.creation.box(extents=(a, b, 0.5 * (a + b)))
    if kind == 1:
        return trimesh.creation.cylinder(radius=0.5 * a, height=b, sections=24)
    if kind == 2:
        return trimesh.creation.icosphere(subdivisions=2, radius=0.5 * a)
    rng = np.random.default_rng(seed)
    return trimesh.convex.convex_hull(rng.normal(size=(30, 3)) * [a, b, 0.5 * a])


def _triangles(m: trimesh.Trimesh) -> np.ndarray:
    return np.asarray(m.vertices)[np.asarray(m.faces)]


def _bvh(m: trimesh.Trimesh):
    g = fcl.BVHModel()
    g.beginModel(len(m.vertices), len(m.faces))
    g.addSubModel(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))
    g.endModel()
    return g


def _pose(rot, shift) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rot).as_matrix()
    T[:3, 3] = shift
    return T


shape = st.tuples(st.integers(0, 3), st.floats(10, 200), st.floats(10, 200), st.integers(0, 99))
vec = st.tuples(*[st.floats(-2.0, 2.0)] * 3)


@pytest.mark.slow
@settings(derandomize=True, database=None, max_examples=12, deadline=None)
@given(shape, shape, vec, st.tuples(*[st.floats(-250, 250)] * 3))
def test_spheres_free_means_exact_free(sa, sb, rot, shift):
    """For random meshes and relative poses: every triangle lies in the balls, and when no
    ball of one mesh meets a ball of the other, FCL finds no contact either."""
    ma, mb = _random_mesh(*sa), _random_mesh(*sb)
    A = cover_link(_triangles(ma), [], 2, 4).unique
    B = cover_link(_triangles(mb), [], 2, 4).unique
    for m, balls in ((ma, A), (mb, B)):
        pts = np.vstack([m.vertices, trimesh.sample.sample_surface(m, 300, seed=1)[0]])
        gap = np.linalg.norm(pts[:, None] - balls[None, :, :3], axis=-1) - balls[None, :, 3]
        assert (gap.min(axis=1) <= 1e-9).all()
    T = _pose(rot, shift)
    Bw = B[:, :3] @ T[:3, :3].T + T[:3, 3]
    sphere_free = (np.linalg.norm(A[:, None, :3] - Bw[None], axis=-1)
                   - A[:, None, 3] - B[None, :, 3]).min() > 0
    exact = fcl.collide(fcl.CollisionObject(_bvh(ma), fcl.Transform()),
                        fcl.CollisionObject(_bvh(mb), fcl.Transform(T[:3, :3], T[:3, 3])),
                        fcl.CollisionRequest(), fcl.CollisionResult())
    if sphere_free:
        assert not exact


@pytest.mark.slow
@settings(derandomize=True, database=None, max_examples=5, deadline=None)
@given(st.floats(5, 120), st.floats(5, 120), st.floats(5, 120), vec)
def test_primitive_solids_are_covered(a, b, c, rot):
    """Boxes, cylinders and spheres are covered as solids: points inside them lie in the
    balls."""
    T = _pose(rot, (a, -b, c))
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.5, 0.5, size=(400, 3))
    cases = [(box_solid((a, b, c), T), u * (a, b, c)),
             (cylinder_solid(0.5 * a, b, T), None),
             (sphere_solid(0.5 * c, T), None)]
    cyl = u[np.hypot(u[:, 0], u[:, 1]) <= 0.5] * (a, a, b)
    ball = u[np.linalg.norm(u, axis=1) <= 0.5] * c
    for (solid, local), fallback in zip(cases, (None, cyl, ball)):
        pts = (local if local is not None else fallback) @ T[:3, :3].T + T[:3, 3]
        balls = cover_link(np.empty((0, 3, 3)), [solid], 2, 2).unique
        gap = np.linalg.norm(pts[:, None] - balls[None, :, :3], axis=-1) - balls[None, :, 3]
        assert (gap.min(axis=1) <= 1e-9).all()


def test_no_false_free_against_primitives_in_random_configurations():
    """A mesh link moving in x, y, z among boxes, a cylinder, a capsule and a sphere: the
    spheres never call a configuration free that the exact stage finds colliding, and the
    exact stage agrees with FCL run here directly."""
    robot = one_link(Geom("mesh", origin=_pose((0.3, 0.2, 0.1), (5, 0, 0)), mesh="m"),
                     {"m": Mesh(*(lambda m: (np.asarray(m.vertices, float),
                                             np.asarray(m.faces)))(
                         trimesh.creation.cylinder(radius=40, height=160, sections=16)))},
                     axes=((1, 0, 0), (0, 1, 0), (0, 0, 1)))
    cm = RobotCollisionModel.from_imported(robot)
    scene = CollisionScene.from_dicts([
        box((100, 300, 50), (250, 0, 0), "slab"),
        {"type": "cylinder", "id": "post", "radius": 40, "height": 400,
         "pose": _pose((0.5, 0, 0), (-200, 150, 0)).tolist()},
        {"type": "capsule", "id": "bar", "a": [-300, -300, 100], "b": [300, -200, 150],
         "radius": 30},
        {"type": "sphere", "id": "ball", "radius": 60, "pose": translation(0, 0, -250).tolist()},
    ])
    q = np.random.default_rng(3).uniform(-350, 350, size=(300, 3))
    spheres = collides(cm, q, scene)
    rep = check(cm, q, scene)
    objs = [fcl.CollisionObject(fcl.Box(100, 300, 50), fcl.Transform(np.array([250.0, 0, 0]))),
            fcl.CollisionObject(fcl.Cylinder(40, 400), fcl.Transform(
                _pose((0.5, 0, 0), (0, 0, 0))[:3, :3], np.array([-200.0, 150, 0]))),
            fcl.CollisionObject(fcl.Sphere(60), fcl.Transform(np.array([0.0, 0, -250])))]
    m = trimesh.creation.cylinder(radius=40, height=160, sections=16)
    body = fcl.CollisionObject(_bvh(m), fcl.Transform())
    G = _pose((0.3, 0.2, 0.1), (5, 0, 0))
    reference = []
    for x in q:
        W = translation(*x) @ G
        body.setTransform(fcl.Transform(W[:3, :3], W[:3, 3]))
        hit = any(fcl.collide(body, o, fcl.CollisionRequest(), fcl.CollisionResult())
                  for o in objs)
        # the capsule: exact distance from the cylinder's triangles to the bar's segment
        tri = np.asarray(m.vertices)[np.asarray(m.faces)] @ W[:3, :3].T + W[:3, 3]
        hit = hit or _segment_hits_triangles(tri, np.array([-300, -300, 100.0]),
                                             np.array([300, -200, 150.0]), 30.0)
        reference.append(hit)
    reference = np.array(reference)
    assert reference.any() and not reference.all()
    assert not np.any(reference & ~spheres)
    assert np.array_equal(rep.collides, reference)
    assert np.array_equal(rep.sphere_collides, spheres)


def _segment_hits_triangles(tri, a, b, r) -> bool:
    cap = fcl.CollisionObject(fcl.Capsule(r, float(np.linalg.norm(b - a))), fcl.Transform(
        _z_to(b - a), 0.5 * (a + b)))
    mesh = fcl.BVHModel()
    mesh.beginModel(len(tri) * 3, len(tri))
    mesh.addSubModel(tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3))
    mesh.endModel()
    return bool(fcl.collide(cap, fcl.CollisionObject(mesh, fcl.Transform()),
                            fcl.CollisionRequest(), fcl.CollisionResult()))


def _z_to(v) -> np.ndarray:
    z = v / np.linalg.norm(v)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


# ---- self-collision --------------------------------------------------------------------------
def _three_links(disabled=()) -> Robot:
    """Three 100 mm cubes: ``base`` fixed at the origin, ``mid`` on joint 1 (along x) and
    ``tip`` on joint 2 (along x again, so the tip moves by q1 + q2); base-mid and mid-tip
    are adjacent (touching at q = 0)."""
    model = slider(((1, 0, 0), (1, 0, 0)), limit=300.0)
    mesh = {"cube": box_mesh((100, 100, 100))}
    g = (Geom("mesh", mesh="cube"),)
    links = (Link("base", 0, np.eye(4), g), Link("mid", 1, translation(100), g),
             Link("tip", 2, translation(200), g))
    adjacent = frozenset({frozenset(("base", "mid")), frozenset(("mid", "tip"))})
    return Robot(model, links, adjacent, frozenset(frozenset(p) for p in disabled), mesh)


@pytest.mark.slow
def test_self_collision_skips_adjacent_and_disabled_pairs():
    cm = RobotCollisionModel.from_imported(_three_links(), pair_tables=False)
    assert [(cm.names[a], cm.names[b]) for a, b in cm.pairs] == [("base", "tip")]
    # Adjacent cubes overlap at q = (0, 0) and (-50, 0), yet nothing collides there.
    q = np.array([[0.0, 0.0], [-50.0, 0.0], [-150.0, 0.0], [0.0, -150.0], [-100.0, -99.0]])
    rep = check(cm, q)
    assert rep.collides.tolist() == [False, False, True, True, True]
    assert rep.pairs[2] == [("base", "tip")]
    assert 0.0 < rep.distance[0] <= 100.0        # spheres: a lower bound
    exact = check(cm, q[:1], exact_distance=True)
    assert exact.distance[0] == pytest.approx(100.0, abs=1e-6)
    off = RobotCollisionModel.from_imported(_three_links([("base", "tip")]))
    assert len(off.pairs) == 0
    assert not check(off, q).collides.any()
    assert not check(cm, q, self_collision=False).collides.any()


@pytest.mark.slow
def test_pair_tables_agree_with_spheres_and_the_exact_stage():
    """base and tip are two joints apart: with tables (the default) the pair is looked up
    instead of spheres, and the answers after the exact stage are the same."""
    tabled = RobotCollisionModel.from_imported(_three_links(), table_tolerance=5.0)
    plain = RobotCollisionModel.from_imported(_three_links(), pair_tables=False)
    assert len(tabled.tables) == 1 and tabled.tables[0].slack <= 5.0 + 1e-9
    q = np.random.default_rng(5).uniform(-300, 300, size=(200, 2))
    a, b = check(tabled, q), check(plain, q)
    assert np.array_equal(a.collides, b.collides)
    gap = np.abs(200 + q.sum(axis=1)) - 100         # the cubes' exact distance along x
    assert np.array_equal(a.collides, gap <= 0)
    assert not np.any((gap <= 0) & ~collides(tabled, q))
    free = gap > 0
    assert np.all(tabled.tables[0].lower_bound(q)[free] <= gap[free] + 1e-9)
    # Near contact the table holds FCL's distance (within its slack); farther than
    # 2 slack + 10 mm, a certified bound of at least 10 mm.
    lower = tabled.tables[0].lower_bound(q)[free]
    assert np.all(lower >= np.minimum(gap[free] - 5.0, 10.0) - 1e-9)


def test_a_table_of_links_that_always_touch_costs_its_coarse_levels_only(monkeypatch):
    """A 1.7 m bar on the tip overlaps the base cube at every configuration: the table
    computes the distance at its coarse nodes, not at every node, and still says contact
    everywhere (the exact stage then decides, as for any pair in contact)."""
    import planning.collision.tables as tables

    model = slider(((1, 0, 0), (1, 0, 0)), limit=300.0)
    meshes = {"cube": box_mesh((100, 100, 100)), "bar": box_mesh((1700, 100, 100))}
    links = (Link("base", 0, np.eye(4), (Geom("mesh", mesh="cube"),)),
             Link("mid", 1, translation(100), (Geom("mesh", mesh="cube"),)),
             Link("tip", 2, translation(200), (Geom("mesh", mesh="bar"),)))
    adjacent = frozenset({frozenset(("base", "mid")), frozenset(("mid", "tip"))})
    robot = Robot(model, links, adjacent, frozenset(), meshes)
    calls = [0]
    distance = tables._distance

    def counted(*args):
        calls[0] += 1
        return distance(*args)

    monkeypatch.setattr(tables, "_distance", counted)
    cm = RobotCollisionModel.from_imported(robot, table_tolerance=1.0)
    (table,) = cm.tables
    nodes = int(np.prod(table.shape))
    assert nodes > 10_000
    assert 0 < calls[0] < 0.02 * nodes
    q = np.random.default_rng(11).uniform(-300, 300, size=(100, 2))
    assert np.all(table.lower_bound(q) <= 0.0)
    assert check(cm, q).collides.all()


def test_capsule_robots_skip_neighbours_and_links_held_in_contact():
    """pile_driver's capsules: neighbours and capsules joined by short links are never
    checked; zero-length links are left out."""
    from kinematics.library import builtin_model

    model = builtin_model("pile_driver")
    cm = RobotCollisionModel.from_model(model, link_radius=60.0)
    info = cm.describe()
    assert info["kind"] == "capsules" and len(info["links"]) == len(cm.names)
    idx = {n: int(n[4:]) for n in cm.names}
    lengths = dict(zip(cm.names, cm.capsule_length))
    for a, b in cm.pairs:
        j, k = sorted((idx[cm.names[a]], idx[cm.names[b]]))
        between = sum(lengths.get(f"link{i}", 0.0) for i in range(j + 1, k))
        assert k - j >= 2 and between >= 120.0
    assert all(length > 0 for length in cm.capsule_length)
    q = np.random.default_rng(2).uniform(model.lower, model.upper, size=(50, model.dof))
    rep = check(cm, q)
    assert np.array_equal(rep.sphere_collides, collides(cm, q))


# ---- batches and the fast path -----------------------------------------------------------------
@pytest.mark.slow
def test_batch_equals_one_by_one():
    robot = _three_links()
    cm = RobotCollisionModel.from_imported(robot)
    scene = CollisionScene.from_dicts([box((80, 80, 80), (450, 0, 0), "block"),
                                       {"type": "sphere", "id": "ball", "radius": 40,
                                        "pose": translation(-300, 0, 0).tolist()}])
    q = np.random.default_rng(11).uniform(-300, 300, size=(40, 2))
    batch = check(cm, q, scene)
    fast = collides(cm, q, scene, exact=True)
    for i, qi in enumerate(q):
        one = check(cm, qi, scene)
        assert one.collides == batch.collides[i]
        assert one.distance == pytest.approx(batch.distance[i], abs=1e-9)
        assert one.pairs == batch.pairs[i]
        assert collides(cm, qi, scene, exact=True) == fast[i] == batch.collides[i]
    assert batch.collides.any() and not batch.collides.all()
    d = batch.to_dict()
    assert len(d["collides"]) == 40 and d["pairs"][0] == [list(p) for p in batch.pairs[0]]


def test_margin_counts_near_misses():
    cm = RobotCollisionModel.from_imported(one_link(Geom("sphere", radius=50.0)))
    scene = CollisionScene.from_dicts([box((100, 100, 100), (300, 0, 0))])
    q = np.array([[180.0], [195.0]])      # gaps 20 and 5
    assert check(cm, q, scene, margin=10.0).collides.tolist() == [False, True]
    assert collides(cm, q, scene, margin=10.0, exact=True).tolist() == [False, True]


def test_real_importer_when_present():
    """A URDF with primitive collision shapes through ``kinematics.urdf_import``."""
    urdf_import = pytest.importorskip("kinematics.urdf_import")
    xml = """<?xml version="1.0"?>
<robot name="duo">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0.25 0 0"/>
    <geometry><cylinder radius="0.04" length="0.5"/></geometry></collision></link>
  <link name="hand"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="turn" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="arm"/><child link="hand"/>
    <origin xyz="0.5 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="1" velocity="1"/></joint>
</robot>"""
    robot = urdf_import.import_robot(xml.encode(), "duo.urdf", robot_id="duo")
    cm = RobotCollisionModel.from_imported(robot)
    assert set(cm.names) == {"base", "arm", "hand"}
    wall = CollisionScene.from_dicts([box((100, 2000, 2000), (1000, 0, 0), "wall")])
    # The hand's centre is at x = 500 + q2 (turn 0): the wall's face at 950, radius 50.
    q = np.array([[0.0, 0.0], [0.0, 300.0], [math.pi, 300.0]])
    rep = check(cm, q, wall, self_collision=False, exact_distance=True)
    assert rep.distance[0] == pytest.approx(400.0, abs=1e-6)
    assert rep.distance[1] == pytest.approx(100.0, abs=1e-6)
    assert not rep.collides.any() and rep.pairs[0] == [("hand", "wall")]
    # base and hand: the box's edge (100, 0, 50) to the ball at (500, 0, 200), radius 50.
    own = check(cm, q[0], exact_distance=True)
    assert own.distance == pytest.approx(math.hypot(400, 150) - 50, abs=1e-6)
    assert own.pairs == [("base", "hand")]


# ---- persistence -------------------------------------------------------------------------------
def test_stored_model_gives_the_same_answers():
    """``to_bytes`` / ``from_bytes``: the same spheres, tables and answers; refused for
    another robot and for bytes that are not a model."""
    robot = _three_links()
    cm = RobotCollisionModel.from_imported(robot, table_tolerance=5.0)
    data = cm.to_bytes()
    assert data[:2] == b"PK"                         # an npz (zip), no pickle
    back = RobotCollisionModel.from_bytes(data, robot)
    assert back.names == cm.names and np.array_equal(back.pairs, cm.pairs)
    assert len(back.tables) == len(cm.tables) == 1
    assert np.array_equal(back.tables[0].values, cm.tables[0].values)
    scene = CollisionScene.from_dicts([box((80, 80, 80), (450, 0, 0), "block")])
    q = np.random.default_rng(23).uniform(-300, 300, size=(120, 2))
    for exact in (False, True):
        assert np.array_equal(collides(back, q, scene, exact=exact),
                              collides(cm, q, scene, exact=exact))
    a, b = check(cm, q, scene), check(back, q, scene)
    assert np.array_equal(a.collides, b.collides) and a.pairs == b.pairs
    assert np.array_equal(a.distance, b.distance)
    assert np.array_equal(back.spheres(q[:3]), cm.spheres(q[:3]))
    assert back.describe() == cm.describe()
    other = _three_links()
    moved = Robot(other.model, (*other.links[:2], Link("tip", 2, translation(250),
                                                        other.links[2].collision)),
                  other.adjacent_pairs, other.disabled_pairs, other.meshes)
    with pytest.raises(ValueError, match="another robot"):
        RobotCollisionModel.from_bytes(data, moved)
    with pytest.raises(ValueError, match="not a stored collision model"):
        RobotCollisionModel.from_bytes(b"not a model", robot)
    from kinematics.library import builtin_model

    model = builtin_model("pile_driver")
    capsules = RobotCollisionModel.from_model(model, link_radius=60.0)
    again = RobotCollisionModel.from_bytes(capsules.to_bytes(), model)
    qm = np.random.default_rng(29).uniform(model.lower, model.upper, size=(50, model.dof))
    assert np.array_equal(check(again, qm).distance, check(capsules, qm).distance)
    with pytest.raises(ValueError):
        RobotCollisionModel.from_bytes(data, model)
