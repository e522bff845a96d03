"""Swept pair tables (planning.collision.tables): a link turned about a joint as a lathe's
stack of discs, tables over the two joints between links three chain joints apart, and the
first joint's bound taken from the inner link when it is the narrower.

The robot is a stand-in of the imported-robot interface (test_collision's) on three
revolute joints: a column about the first joint's axis, and on the last joint a flange
round that joint's axis and a finger off it. Distances are checked against FCL on the
meshes, posed by the robot's own link poses."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from test_collision import Geom, Link, Mesh, Robot

from kinematics.model import RobotModel
from planning.collision import RobotCollisionModel, check
from planning.collision.tables import sweep_ratio, swept_slabs

fcl = pytest.importorskip("fcl")
pytestmark = pytest.mark.slow


def _mesh(m: trimesh.Trimesh) -> Mesh:
    return Mesh(np.asarray(m.vertices, float), np.asarray(m.faces, np.int64))


def _pose(R=None, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.eye(3) if R is None else R
    T[:3, 3] = t
    return T


def _rot(axis, angle) -> np.ndarray:
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _arm() -> Robot:
    """Pan about z at the origin, lift about y at (0, 0, 400), roll about x at
    (300, 0, 400). ``column``: a cylinder of radius 50 mm round the pan axis with a 40 x 40
    x 60 mm box on its side out to x = 90 mm (frame 0);
    ``flange``: a disc of radius 60 mm, 20 mm thick, round the roll axis at x = 350;
    ``finger``: a 20 mm cube 80 mm off the roll axis (both on the last frame)."""
    model = RobotModel.from_dict({
        "id": "arm", "name": "arm", "convention": "poe",
        "joints": [
            {"name": "pan", "type": "revolute", "axis": [0, 0, 1], "point": [0, 0, 0],
             "lower": -math.pi, "upper": math.pi},
            {"name": "lift", "type": "revolute", "axis": [0, 1, 0], "point": [0, 0, 400],
             "lower": -2.5, "upper": 2.5},
            {"name": "roll", "type": "revolute", "axis": [1, 0, 0], "point": [300, 0, 400],
             "lower": -math.pi, "upper": math.pi}],
        "home": np.eye(4).tolist()})
    bump = trimesh.creation.box(extents=(40, 40, 60))
    bump.apply_translation((70, 0, 90))
    column = trimesh.util.concatenate([trimesh.creation.cylinder(radius=50, height=300,
                                                                 sections=48), bump])
    meshes = {
        "column": _mesh(column),
        "flange": _mesh(trimesh.creation.cylinder(radius=60, height=20, sections=48)),
        "finger": _mesh(trimesh.creation.box(extents=(20, 20, 20))),
    }
    roll_axis = _rot((0, 1, 0), math.pi / 2)        # z onto x
    links = (
        Link("column", 0, np.eye(4), (Geom("mesh", origin=_pose(t=(0, 0, 150)),
                                           mesh="column"),)),
        Link("flange", 3, np.eye(4), (Geom("mesh", origin=_pose(roll_axis, (350, 0, 400)),
                                           mesh="flange"),)),
        Link("finger", 3, np.eye(4), (Geom("mesh", origin=_pose(t=(380, 0, 480)),
                                           mesh="finger"),)),
    )
    adjacent = frozenset({frozenset(("flange", "finger"))})
    return Robot(model, links, adjacent, frozenset(), meshes)


def _fcl_distance(robot: Robot, q: np.ndarray, a: str, b: str) -> np.ndarray:
    """FCL's distance (0 in contact) of two links' meshes at configurations ``q``."""
    def obj(name):
        link = next(x for x in robot.links if x.name == name)
        m = robot.meshes[link.collision[0].mesh]
        bvh = fcl.BVHModel()
        bvh.beginModel(len(m.vertices), len(m.faces))
        bvh.addSubModel(m.vertices, m.faces)
        bvh.endModel()
        return fcl.CollisionObject(bvh, fcl.Transform()), link.collision[0].origin

    names = [x.name for x in robot.links]
    (oa, Ta), (ob, Tb) = obj(a), obj(b)
    P = robot.link_poses(q)
    out = []
    for Pq in P:
        for o, T, name in ((oa, Ta, a), (ob, Tb, b)):
            W = Pq[names.index(name)] @ T
            o.setTransform(fcl.Transform(W[:3, :3], W[:3, 3]))
        d = fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult())
        out.append(max(d, 0.0))
    return np.array(out)


def _table(cm: RobotCollisionModel, a: str, b: str):
    return next(t for t in cm.tables if (cm.names[t.a], cm.names[t.b]) == (a, b))


@pytest.fixture(scope="module")
def arm_models():
    robot = _arm()
    tabled = RobotCollisionModel.from_imported(robot, table_tolerance=4.0, table_nodes=3000)
    plain = RobotCollisionModel.from_imported(robot, pair_tables=False)
    return robot, tabled, plain


def test_swept_slabs_contain_the_turned_geometry():
    """Points on the triangles, turned by random angles about a random axis, lie inside
    one of the prisms (qhull's facets); a long thin triangle crosses slabs that hold none
    of its corners."""
    rng = np.random.default_rng(3)
    box = trimesh.creation.box(extents=(40, 70, 25))
    box.apply_translation((55, -20, 10))
    tri = np.concatenate([box.triangles, [[[0, 0, -200], [90, 0, -200], [10, 5, 300]]]])
    point, axis = np.array([5.0, -8.0, 3.0]), np.array([0.2, 0.1, 1.0])
    pieces = swept_slabs(tri, point, axis)
    from scipy.spatial import ConvexHull
    facets = [ConvexHull(V).equations for V in pieces]
    w = rng.dirichlet(np.ones(3), size=(len(tri), 20))
    pts = np.einsum("tsk,tkd->tsd", w, tri).reshape(-1, 3)
    pts = np.vstack([pts, tri.reshape(-1, 3)])
    for angle in rng.uniform(0, 2 * np.pi, 40):
        turned = (pts - point) @ _rot(axis, angle).T + point
        inside = np.zeros(len(turned), dtype=bool)
        for eq in facets:
            inside |= np.all(turned @ eq[:, :3].T + eq[:, 3] <= 1e-7, axis=1)
        assert inside.all(), f"{(~inside).sum()} points outside at angle {angle:.3f}"
    # A lathe, not a hull: the thin stem's slabs stay narrow beside the box's.
    radii = [np.linalg.norm(np.cross(V - point, axis / np.linalg.norm(axis)), axis=1).max()
             for V in pieces]
    assert min(radii) < 0.5 * max(radii)


def test_the_sweep_ratio_tells_round_from_off_axis_links():
    robot = _arm()
    from planning.collision.robot import _link_triangles

    flange = _link_triangles(robot.links[1], robot.meshes)
    finger = _link_triangles(robot.links[2], robot.meshes)
    assert sweep_ratio(robot, 1, 2, flange) < 1.1          # a disc round the roll axis
    assert sweep_ratio(robot, 2, 2, finger) > 10.0         # a cube 80 mm off it
    assert sweep_ratio(robot, 1, 1, flange) > 1.7          # the disc about the lift axis


def test_links_three_joints_apart_get_a_swept_table(arm_models):
    robot, tabled, _ = arm_models
    tables = {tuple(t["links"]): t for t in tabled.describe()["pair_tables"]}
    assert tables[("column", "flange")]["swept"] == ["flange"]
    assert tables[("column", "flange")]["joints"] == [0, 1]
    # The finger is not round the roll axis: it is never swept (the column, round its
    # own axis, may be).
    assert "finger" not in tables.get(("column", "finger"), {}).get("swept", [])
    table = _table(tabled, "column", "flange")
    # The pan's bound is the column's farthest point from its axis (the box's outer edge,
    # hypot(90, 20) mm), not the flange's reach (~400 mm).
    assert table.rho[0] == pytest.approx(math.hypot(90, 20), abs=1e-6)
    assert table.rho[1] > 300.0


def test_the_pans_bound_holds_along_the_pan(arm_models):
    """The table's premise for its first joint: turning the pan by dq changes the distance
    by at most rho[0] |dq| (FCL along a fine pan sweep where the box passes the flange),
    and the bound is not loose by half there."""
    robot, tabled, _ = arm_models
    rho = _table(tabled, "column", "flange").rho[0]
    pan = np.linspace(-math.pi, math.pi, 721)
    worst = 0.0
    for lift in (0.1, 0.3):
        q = np.column_stack([pan, np.full_like(pan, lift), np.zeros_like(pan)])
        d = _fcl_distance(robot, q, "column", "flange")
        assert d.min() > 0
        worst = max(worst, float((np.abs(np.diff(d)) / np.diff(pan)).max()))
    assert rho / 2 < worst <= rho + 1e-6


def test_a_swept_table_is_a_lower_bound_and_tighter_than_the_spheres(arm_models):
    robot, tabled, plain = arm_models
    table = _table(tabled, "column", "flange")
    rng = np.random.default_rng(17)
    m = robot.model
    q = rng.uniform(m.lower, m.upper, size=(2000, 3))
    exact = _fcl_distance(robot, q, "column", "flange")
    bound = table.lower_bound(q)
    assert np.all(bound <= exact + 1e-6), float((bound - exact).max())
    # Free and near contact, the table is within its slack (plus the polygon's 0.9 % of
    # the flange's 60 mm and the slabs' thickness) of FCL.
    near = (exact > 0) & (exact < 25)
    assert near.sum() >= 5
    assert np.all(bound[near] >= exact[near] - table.slack - 1.0)
    # The answers after the exact stage are the spheres' answers; the table flags fewer.
    a, b = check(tabled, q), check(plain, q)
    assert np.array_equal(a.collides, b.collides)
    sphere_flags = check(plain, q, exact=False).collides.sum()
    table_flags = check(tabled, q, exact=False).collides.sum()
    assert table_flags < sphere_flags


def test_a_stored_model_keeps_its_swept_tables(arm_models):
    robot, tabled, _ = arm_models
    back = RobotCollisionModel.from_bytes(tabled.to_bytes(), robot)
    assert [t.sweep for t in back.tables] == [t.sweep for t in tabled.tables]
    assert _table(back, "column", "flange").sweep == "b"
    for x, y in zip(back.tables, tabled.tables, strict=True):
        assert np.array_equal(x.values, y.values)
    assert back.describe()["pair_tables"] == tabled.describe()["pair_tables"]
