"""Carried loads (planning.collision.attached): an object attached to a robot link moves with
it and collides like a link, in the sphere stage, the exact stage, the self pairs, the
compiled checker of planning.motion and the motion planner.

The arm is a UR5-like standard D-H model written here (capsules of 40 mm); the reference
is independent of the package: a D-H product written here for the frames, and python-fcl on
capsules between the frame origins, the attached box posed by the tool frame and the scene
boxes. A two-link URDF arm covers imported robots."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ur5_like import UR5_DH, ur5_model

from kinematics.errors import FieldError
from planning.collision import CollisionScene, RobotCollisionModel, check, collides
from planning.collision.attached import Attachment
from planning.motion import MotionChecker, MotionStatus, plan_motion

fcl = pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")

PI = math.pi
RADIUS = 40.0
LOAD = (400.0, 300.0, 250.0)
#: The load's pose in the tool frame: 10 mm below the flange, along the tool's z.
T_LOAD = np.eye(4)
T_LOAD[2, 3] = 10.0 + LOAD[2] / 2
#: Tool pointing straight down at (-486.9, -109.2, 431.9).
Q_DOWN = np.array([0.0, -PI / 2, PI / 2, -PI / 2, -PI / 2, 0.0])
#: Self pairs of the arm: every pair of links not joined by a joint.
ARM_PAIRS = [(a, b) for a in range(6) for b in range(a + 2, 6)]


def at(x, y, z) -> list:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T.tolist()


def table(oid: str, size, centre) -> dict:
    return {"type": "box", "id": oid, "size": list(size), "pose": at(*centre)}


def load(link: str = "tool", pose=T_LOAD, touch=(), oid: str = "load", size=LOAD) -> dict:
    return {"object": {"type": "box", "id": oid, "size": list(size)}, "link": link,
            "pose": np.asarray(pose).tolist(), "touch_links": list(touch)}


@pytest.fixture(scope="module")
def ur5():
    model = ur5_model()
    return model, RobotCollisionModel.from_model(model, link_radius=RADIUS)


# ---- the independent reference ------------------------------------------------------------------
def dh_frames(q) -> list[np.ndarray]:
    """Base, then the frame after each joint: RotZ(q) TransZ(d) TransX(a) RotX(alpha)."""
    T = np.eye(4)
    out = [T]
    for (a, alpha, d), th in zip(UR5_DH, q, strict=True):
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(alpha), math.sin(alpha)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        out.append(T)
    return out


def _posed(geom, T: np.ndarray):
    return fcl.CollisionObject(geom, fcl.Transform(T[:3, :3].copy(), T[:3, 3].copy()))


def _capsule(a: np.ndarray, b: np.ndarray):
    """An FCL capsule of ``RADIUS`` from ``a`` to ``b`` (its axis is its local z)."""
    d = b - a
    L = float(np.linalg.norm(d))
    z = d / L
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, 0.5 * (a + b)
    return _posed(fcl.Capsule(RADIUS, L), T)


def _touch(o1, o2) -> bool:
    return bool(fcl.collide(o1, o2, fcl.CollisionRequest(), fcl.CollisionResult()))


def reference(q, boxes, carried=True, pose=T_LOAD, size=LOAD, allowed=(5,)) -> bool:
    """Whether the arm at ``q`` (with the load at ``pose`` in the tool frame when
    ``carried``) touches the ``boxes`` (dicts) or itself; the load may touch the links in
    ``allowed``."""
    F = dh_frames(q)
    links = [_capsule(F[k][:3, 3], F[k + 1][:3, 3]) for k in range(6)]
    world = [_posed(fcl.Box(*b["size"]), np.array(b["pose"])) for b in boxes]
    if any(_touch(c, w) for c in links for w in world):
        return True
    if any(_touch(links[a], links[b]) for a, b in ARM_PAIRS):
        return True
    if not carried:
        return False
    body = _posed(fcl.Box(*size), F[6] @ pose)
    return any(_touch(body, w) for w in world) or \
        any(_touch(body, links[k]) for k in range(6) if k not in allowed)


def reference_distance(q, boxes, pose=T_LOAD, size=LOAD) -> float:
    """FCL's least distance (mm) over the pairs ``reference`` checks, the load carried."""
    F = dh_frames(q)
    links = [_capsule(F[k][:3, 3], F[k + 1][:3, 3]) for k in range(6)]
    world = [_posed(fcl.Box(*b["size"]), np.array(b["pose"])) for b in boxes]
    body = _posed(fcl.Box(*size), F[6] @ pose)
    pairs = [(c, w) for c in links + [body] for w in world]
    pairs += [(links[a], links[b]) for a, b in ARM_PAIRS] + [(body, links[k]) for k in range(5)]
    return min(fcl.distance(o1, o2, fcl.DistanceRequest(), fcl.DistanceResult())
               for o1, o2 in pairs)


# ---- the load collides like a link --------------------------------------------------------------
TABLE = table("table", (800, 1200, 100), (-600, 0, 200))     # top at z = 250


def test_the_load_hits_the_table_where_the_arm_is_free(ur5):
    model, cm = ur5
    scene = CollisionScene.from_dicts([TABLE])
    cma = cm.with_attached([load()])
    # The reference: the arm alone clears the table, the box (bottom at 171.9) does not.
    assert not reference(Q_DOWN, [TABLE], carried=False)
    assert reference(Q_DOWN, [TABLE])
    assert not collides(cm, Q_DOWN, scene, exact=True)
    assert collides(cma, Q_DOWN, scene) and collides(cma, Q_DOWN, scene, exact=True)
    rep = check(cma, Q_DOWN, scene)
    assert rep.collides and ("load", "table") in rep.pairs
    assert not check(cm, Q_DOWN, scene).collides
    for mc in (MotionChecker(cma, scene), MotionChecker(cm, scene)):
        assert mc._k is not None
    assert not MotionChecker(cma, scene).free(Q_DOWN)
    assert MotionChecker(cm, scene).free(Q_DOWN)
    # Lifted 220 mm (elbow up, wrist level), the load clears the table too.
    q_up = Q_DOWN + np.array([0, 0, -0.6, 0.6, 0, 0])
    assert not reference(q_up, [TABLE])
    assert not collides(cma, q_up, scene, exact=True) and MotionChecker(cma, scene).free(q_up)
    # Its clearance, by the compiled checker and by the collision package, is FCL's.
    d = reference_distance(q_up, [TABLE])
    assert d > 0
    assert MotionChecker(cma, scene).clearance(q_up[None]) == pytest.approx(d, abs=1e-6)
    rep = check(cma, q_up, scene, exact_distance=True)
    assert rep.distance_exact and rep.distance == pytest.approx(d, abs=1e-6)


@pytest.mark.slow
def test_the_original_model_is_unchanged_and_describe_names_the_load(ur5):
    _, cm = ur5
    before = (cm.names, cm.pairs.copy(), cm.tree.leaf.shape)
    cma = cm.with_attached([load()])
    assert (cm.names, cm.tree.leaf.shape) == (before[0], before[2])
    assert np.array_equal(cm.pairs, before[1]) and cm.attached == ()
    assert cma.names == cm.names + ("load",) and cma.without_attached() is cm
    d = cma.describe()
    assert [a["id"] for a in d["attached"]] == ["load"]
    a = d["attached"][0]
    assert a["type"] == "box" and a["link"] == "tool" and a["spheres"] >= 1
    assert np.allclose(a["pose"], T_LOAD)
    assert ["link0", "load"] in d["self_collision_pairs"]
    assert ["link5", "load"] not in d["self_collision_pairs"]
    assert cm.describe()["attached"] == []
    # Attaching again adds to what the model carries.
    two = cma.with_attached([load(oid="second", pose=at(0, 0, 700), size=(100, 100, 100))])
    assert two.names[-2:] == ("load", "second") and two.without_attached() is cm
    assert ["load", "second"] in two.describe()["self_collision_pairs"]


def test_the_balls_contain_the_load(ur5):
    """Points on and inside the box, in the world, are inside some ball of the load."""
    _, cm = ur5
    cma = cm.with_attached([load()])
    rng = np.random.default_rng(4)
    Q = rng.uniform(-PI, PI, (5, 6))
    S = cma.spheres(Q)
    mine = np.array(cma.sphere_links) == "load"
    h = 0.5 * np.array(LOAD)
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    P = np.vstack([corners, rng.uniform(-h, h, (2000, 3))])
    for b, q in enumerate(Q):
        T = dh_frames(q)[6] @ T_LOAD
        W = P @ T[:3, :3].T + T[:3, 3]
        balls = S[b, mine]
        d = np.linalg.norm(W[:, None] - balls[None, :, :3], axis=-1) - balls[None, :, 3]
        assert np.all(d.min(axis=1) <= 1e-9)


@pytest.mark.slow
def test_compiled_and_python_paths_agree_with_the_reference(ur5, monkeypatch):
    """A few hundred random configurations: the compiled checker, the collision package
    (sphere stage and exact) and the reference give one answer; the spheres never call a
    colliding configuration free."""
    import planning.motion.checker as checker_module

    _, cm = ur5
    boxes = [TABLE, table("post", (150, 150, 900), (300, 300, 450))]
    scene = CollisionScene.from_dicts(boxes)
    cma = cm.with_attached([load()])
    Q = np.random.default_rng(11).uniform(-PI, PI, (300, 6))
    ref = np.array([reference(q, boxes) for q in Q])
    plain = np.array([reference(q, boxes, carried=False) for q in Q])
    assert (ref & ~plain).sum() >= 10 and (~ref).sum() >= 10
    assert np.array_equal(collides(cma, Q, scene, exact=True), ref)
    assert np.array_equal(check(cma, Q, scene).collides, ref)
    assert not np.any(~collides(cma, Q, scene) & ref)
    fast = MotionChecker(cma, scene)
    assert fast._k is not None
    assert np.array_equal(fast.free(Q), ~ref)
    fast.exact = False
    assert np.array_equal(fast.free(Q), ~collides(cma, Q, scene))
    monkeypatch.setattr(checker_module, "_kernels", lambda: None)
    slow = MotionChecker(cma, scene)
    assert slow._k is None
    assert np.array_equal(slow.free(Q), ~ref)


# ---- allowed contacts ---------------------------------------------------------------------------
def test_touch_links_allow_contact_with_the_named_links(ur5):
    """A box on the tool reaching back over the wrist: it overlaps link5 (its own link,
    always allowed) and link4, which it may touch only when named."""
    _, cm = ur5
    pose = np.eye(4)
    pose[2, 3] = -40.0     # centred 40 mm behind the flange, along the tool's axis
    size = (80.0, 80.0, 100.0)
    q = np.array([0.67, 1.44, 0.27, 2.73, 1.98, -3.12])
    assert not reference(q, [], carried=False)
    assert reference(q, [], pose=pose, size=size)
    assert not reference(q, [], pose=pose, size=size, allowed=(4, 5))
    strict = cm.with_attached([load(pose=pose, size=size)])
    rep = check(strict, q)
    assert rep.collides and rep.pairs == [("link4", "load")]
    assert not MotionChecker(strict).free(q)
    loose = cm.with_attached([load(pose=pose, size=size, touch=["link4"])])
    assert not check(loose, q).collides and MotionChecker(loose).free(q)
    # On link4 itself ("link4" is then its own link), named by the tool alias as touch link.
    T4 = np.linalg.inv(dh_frames(q)[5]) @ dh_frames(q)[6] @ pose
    own = cm.with_attached([load(link="link4", pose=T4, size=size, touch=["tool"])])
    assert not check(own, q).collides and MotionChecker(own).free(q)
    assert ["link4", "load"] not in own.describe()["self_collision_pairs"]
    assert ["link5", "load"] not in own.describe()["self_collision_pairs"]


# ---- planning with the load ---------------------------------------------------------------------
@pytest.mark.slow
def test_a_plan_carries_the_load_round_the_block(ur5):
    _, cm = ur5
    boxes = [table("table", (1600, 1600, 100), (-500, 0, -100)),       # top at z = -50
             table("block", (200, 200, 350), (-500, -100, 125))]      # top at z = 300
    scene = CollisionScene.from_dicts(boxes)
    cma = cm.with_attached([load()])
    start = Q_DOWN + np.array([1.0, 0, 0, 0, 0, 0])
    goal = Q_DOWN - np.array([1.0, 0, 0, 0, 0, 0])
    assert not reference(start, boxes) and not reference(goal, boxes)
    assert MotionChecker(cm, scene).segment_free(start, goal)      # the arm alone passes
    mc = MotionChecker(cma, scene)
    assert not mc.segment_free(start, goal)                        # the load would not
    res = plan_motion(mc, start, goal, time_limit=10.0, seed=3, trajectory=False)
    assert res.status is MotionStatus.OK, res.message
    P = res.path
    assert np.allclose(P[0], start) and np.allclose(P[-1], goal)
    for i in range(len(P) - 1):
        n = max(1, math.ceil(float(np.abs(P[i + 1] - P[i]).max()) / 0.01))
        for s in np.linspace(0.0, 1.0, n + 1):
            assert not reference(P[i] + s * (P[i + 1] - P[i]), boxes)


# ---- persistence --------------------------------------------------------------------------------
@pytest.mark.slow
def test_bytes_keep_the_attachments(ur5):
    model, cm = ur5
    scene = CollisionScene.from_dicts([TABLE])
    cma = cm.with_attached([load(touch=["link3"])])
    back = RobotCollisionModel.from_bytes(cma.to_bytes(), model)
    assert back.names == cma.names and np.array_equal(back.pairs, cma.pairs)
    assert back.attached[0].touch_links == ("link3",)
    Q = np.random.default_rng(2).uniform(-PI, PI, (100, 6))
    assert np.array_equal(collides(back, Q, scene, exact=True),
                          collides(cma, Q, scene, exact=True))
    plain = RobotCollisionModel.from_bytes(cm.to_bytes(), model)
    assert plain.attached == () and plain.names == cm.names


# ---- imported robots ----------------------------------------------------------------------------
ARM = """<?xml version="1.0"?>
<robot name="arm2">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0.2 0 0" rpy="0 1.5707963 0"/>
    <geometry><cylinder radius="0.03" length="0.4"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0.15 0 0" rpy="0 1.5707963 0"/>
    <geometry><cylinder radius="0.03" length="0.3"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="1" velocity="1.5"/></joint>
</robot>"""


@pytest.mark.slow
def test_imported_robot_carries_a_cylinder():
    urdf_import = pytest.importorskip("kinematics.urdf_import")
    robot = urdf_import.import_robot(ARM.encode(), "arm2.urdf", robot_id="arm2")
    cm = RobotCollisionModel.from_imported(robot, pair_tables=False)
    # A cylinder hanging 300 mm below the end of the forearm (its frame: the elbow).
    drum = {"object": {"type": "cylinder", "id": "drum", "radius": 50, "height": 300},
            "link": "tool", "pose": at(300, 0, -150)}
    cma = cm.with_attached([drum])
    assert cma.names == ("base", "upper", "fore", "drum")
    post = table("post", (100, 100, 100), (700, 0, 0))      # top at z = 50
    scene = CollisionScene.from_dicts([post])
    q = np.zeros(2)
    # The drum's axis: x = 700, z from 200 - 300 = -100 to 200: it goes through the post.
    assert not collides(cm, q, scene, exact=True)
    rep = check(cma, q, scene)
    assert rep.collides and rep.pairs == [("drum", "post")]
    q_away = np.array([0.6, 0.0])
    assert not check(cma, q_away, scene).collides
    Q = np.random.default_rng(5).uniform(robot.model.lower, robot.model.upper, (300, 2))
    exact = collides(cma, Q, scene, exact=True)
    assert exact.any() and (~exact).any()
    assert np.array_equal(MotionChecker(cma, scene).free(Q), ~exact)
    back = RobotCollisionModel.from_bytes(cma.to_bytes(), robot)
    assert np.array_equal(collides(back, Q, scene, exact=True), exact)


# ---- bad attachments ----------------------------------------------------------------------------
@pytest.mark.parametrize("bad, loc", [
    (load(link="link9"), ("attached", 0, "link")),
    ({**load(), "pose": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ("attached", 0, "pose")),
    ({**load(), "pose": [[1, 0, 0]]}, ("attached", 0, "pose")),
    ({"object": {"type": "cone", "radius": 3}}, ("attached", 0, "object", "type")),
    ({"object": {"type": "points", "points": [[0, 0, 0]], "radius": 5}},
     ("attached", 0, "object", "type")),
    ({"object": {"type": "box"}}, ("attached", 0, "object", "size")),
    ({"object": {"type": "box", "size": [1, -2, 3]}}, ("attached", 0, "object", "size", 1)),
    ({"object": {"type": "mesh", "mesh": "nowhere"}}, ("attached", 0, "object", "mesh")),
    ({"object": "box"}, ("attached", 0, "object")),
    ({"link": "tool"}, ("attached", 0, "object")),
    ({**load(), "colour": "red"}, ("attached", 0, "colour")),
    (load(touch=["wrist"]), ("attached", 0, "touch_links", 0)),
    ({**load(), "touch_links": "link4"}, ("attached", 0, "touch_links")),
    (load(oid="link2"), ("attached", 0, "object", "id")),
])
def test_bad_attachments_name_the_field(ur5, bad, loc):
    _, cm = ur5
    with pytest.raises(FieldError) as err:
        cm.with_attached([bad])
    assert err.value.loc == loc


def test_ids_must_be_unique(ur5):
    _, cm = ur5
    with pytest.raises(FieldError) as err:
        cm.with_attached([load(), load(pose=at(0, 0, 600))])
    assert err.value.loc == ("attached", 1, "object", "id")
    with pytest.raises(FieldError) as err:
        cm.with_attached([load()]).with_attached([load(pose=at(0, 0, 600))])
    assert err.value.loc == ("attached", 0, "object", "id")
    a = Attachment.from_dict({"object": {"type": "sphere", "radius": 20}}, index=3)
    assert a.id == "attached3" and a.link == "tool" and np.allclose(a.pose, np.eye(4))


def test_a_prismatic_robot_with_a_load_is_checked_by_the_python_path():
    """A capsule link of a prismatic joint has its ends on two bodies, which the kernels'
    frame layout cannot carry once the model holds attachments: the checker runs on the
    collision package, with its answers."""
    from kinematics.fk import fk
    from kinematics.library import builtin_model

    model = builtin_model("tunnel_drill_arm")
    assert any(not j.revolute for j in model.joints)
    cma = RobotCollisionModel.from_model(model).with_attached(
        [{"object": {"type": "sphere", "id": "bit", "radius": 150}, "pose": at(0, 0, 300)}])
    tip = fk(model, model.mid_configuration())[:3, 3]
    scene = CollisionScene.from_dicts([{"type": "sphere", "id": "rock", "radius": 2500,
                                        "pose": at(*tip)}])
    mc = MotionChecker(cma, scene, self_collision=False)
    assert mc._k is None
    Q = np.random.default_rng(8).uniform(model.lower, model.upper, (100, model.dof))
    exact = collides(cma, Q, scene, self_collision=False, exact=True)
    assert exact.any() and (~exact).any()
    assert np.array_equal(mc.free(Q), ~exact)


# ---- every attachable type ----------------------------------------------------------------------
def _crate() -> tuple[np.ndarray, np.ndarray]:
    """A closed triangle mesh: a 300 x 200 x 160 mm box, 12 triangles."""
    h = np.array([150.0, 100.0, 80.0])
    V = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return V, F


def _inside(kind: str, rng) -> np.ndarray:
    """Points ``(K, 3)`` of each object below, in its own frame (for meshes, on its
    surface: FCL's and the covers' mesh is its triangles)."""
    n = 3000
    if kind == "box":
        return rng.uniform(-1, 1, (n, 3)) * [100, 60, 40]
    if kind in ("sphere", "capsule"):
        d = rng.normal(size=(n, 3))
        P = d / np.linalg.norm(d, axis=1, keepdims=True) * 80 * rng.random((n, 1)) ** (1 / 3)
        if kind == "capsule":
            P = P + np.outer(rng.random(n), [0, 0, 300]) + [0, 0, -150]
        return P
    if kind == "cylinder":
        a, r = rng.uniform(0, 2 * PI, n), 70 * np.sqrt(rng.random(n))
        return np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(-120, 120, n)])
    V, F = _crate()
    T = V[F[rng.integers(0, len(F), n)]]
    u, v = rng.random((2, n))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return np.vstack([V, T[:, 0] + u[:, None] * (T[:, 1] - T[:, 0])
                      + v[:, None] * (T[:, 2] - T[:, 0])])


OBJECTS = {
    "box": {"type": "box", "size": [200, 120, 80]},
    "sphere": {"type": "sphere", "radius": 80},
    "cylinder": {"type": "cylinder", "radius": 70, "height": 240},
    "capsule": {"type": "capsule", "a": [0, 0, -150], "b": [0, 0, 150], "radius": 80},
    "mesh": {"type": "mesh", "mesh": "crate"},
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(OBJECTS))
def test_every_attachable_type(ur5, kind):
    """Each type (a mesh through the mesh lookup): its balls contain it, and the compiled
    checker, the numpy sphere stage and the exact stage agree, in a scene with a box and a
    point cloud."""
    model, cm = ur5

    def lookup(name):
        if name != "crate":
            raise KeyError(name)
        return _crate()

    cma = cm.with_attached([{"object": {**OBJECTS[kind], "id": "thing"}, "link": "link5",
                             "pose": at(0, 0, 250)}], resolve_mesh=lookup)
    rng = np.random.default_rng(21)
    Q = rng.uniform(-PI, PI, (150, 6))
    S = cma.spheres(Q[:3])
    mine = np.array(cma.sphere_links) == "thing"
    P = _inside(kind, rng)
    for b, q in enumerate(Q[:3]):
        T = dh_frames(q)[6] @ np.array(at(0, 0, 250))
        W = P @ T[:3, :3].T + T[:3, 3]
        d = np.linalg.norm(W[:, None] - S[b, mine][None, :, :3], axis=-1) - S[b, mine][:, 3]
        assert np.all(d.min(axis=1) <= 1e-9)
    g = np.linspace(-300, 300, 7)
    cloud = np.column_stack([np.repeat(g, 7) - 400, np.tile(g, 7), np.full(49, 300.0)])
    scene = CollisionScene.from_dicts([TABLE, {"type": "points", "id": "scan",
                                               "points": cloud.tolist(), "radius": 20.0}])
    exact = collides(cma, Q, scene, exact=True)
    assert exact.any() and (~exact).any()
    assert not np.any(~collides(cma, Q, scene) & exact)
    mc = MotionChecker(cma, scene)
    assert np.array_equal(mc.free(Q), ~exact)
    if kind == "mesh":
        with pytest.raises(FieldError) as err:
            cm.with_attached([{"object": {"type": "mesh", "mesh": "other"}}],
                             resolve_mesh=lookup)
        assert err.value.loc == ("attached", 0, "object", "mesh")
        with pytest.raises(ValueError):    # a stored mesh needs the lookup to load again
            RobotCollisionModel.from_bytes(cma.to_bytes(), model)
        back = RobotCollisionModel.from_bytes(cma.to_bytes(), model, resolve_mesh=lookup)
        assert np.array_equal(collides(back, Q, scene, exact=True), exact)
