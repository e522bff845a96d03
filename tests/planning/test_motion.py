"""Joint-space motion planning (planning.motion): certified small problems, statuses,
reproducibility, the checking resolution, the time limit, and the compiled checker against
the collision package.

The certified robot is a gantry: two prismatic joints (x, y, mm) carrying a ball of radius
50 mm, imported from a URDF written here, so its configuration space is the plane and every
answer is known by construction (a wall with a gap must be passed through the gap; a gap
narrower than the ball cannot be passed). A two-link revolute arm and the GLT palletizer
with trimesh meshes cover revolute joints, self-collision and meshes."""

from __future__ import annotations

import io
import math
import zipfile

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.fk import fk
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.motion import MotionChecker, MotionStatus, plan_motion
from planning.motion.checker import bisection_order

urdf_import = pytest.importorskip("kinematics.urdf_import")
pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")

BALL = 50.0

GANTRY = """<?xml version="1.0"?>
<robot name="gantry">
  <link name="base"/>
  <link name="carriage"/>
  <link name="tool"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="carriage"/>
    <axis xyz="1 0 0"/><limit lower="-0.2" upper="1.2" effort="1" velocity="0.5"/></joint>
  <joint name="y" type="prismatic"><parent link="carriage"/><child link="tool"/>
    <axis xyz="0 1 0"/><limit lower="-1.0" upper="1.0" effort="1" velocity="0.5"/></joint>
</robot>"""

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


def _robot(xml: str, name: str):
    return urdf_import.import_robot(xml.encode(), f"{name}.urdf", robot_id=name)


@pytest.fixture(scope="module")
def gantry():
    robot = _robot(GANTRY, "gantry")
    return robot, RobotCollisionModel.from_imported(robot)


@pytest.fixture(scope="module")
def arm():
    robot = _robot(ARM, "arm2")
    return robot, RobotCollisionModel.from_imported(robot)


def box(oid: str, size, at) -> dict:
    T = np.eye(4)
    T[:3, 3] = at
    return {"type": "box", "id": oid, "size": list(size), "pose": T.tolist()}


def wall_with_gap(gap: float, thickness: float = 100.0, x: float = 450.0) -> CollisionScene:
    """A wall across the gantry's plane at ``x``, open for ``|y| < gap / 2``."""
    h = 2000.0
    return CollisionScene.from_dicts([
        box("upper", (thickness, h, 400), (x, gap / 2 + h / 2, 0)),
        box("lower", (thickness, h, 400), (x, -gap / 2 - h / 2, 0))])


def states(path: np.ndarray, step: float) -> np.ndarray:
    """Every segment of ``path`` at joint steps of at most ``step`` (joint units)."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def assert_valid(cm, scene, result, start, goal, step):
    assert result.status is MotionStatus.OK, result.message
    P = result.path
    assert np.allclose(P[0], start) and np.allclose(P[-1], goal)
    Q = states(P, step)
    assert not collides(cm, Q, scene, exact=True).any()
    assert result.length == pytest.approx(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


# ---- certified problems --------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("gap", [300.0, 2 * BALL + 10.0])
def test_gantry_passes_the_wall_through_its_gap(gantry, gap):
    """The only way from one side to the other is through the gap: some checked state sits
    inside the wall's thickness with the ball within the opening."""
    _, cm = gantry
    scene = wall_with_gap(gap)
    start, goal = np.array([0.0, 600.0]), np.array([900.0, 600.0])
    res = plan_motion(MotionChecker(cm, scene), start, goal, time_limit=5.0, seed=3)
    assert_valid(cm, scene, res, start, goal, step=0.25)
    Q = states(res.path, 1.0)
    inside = Q[(Q[:, 0] > 400.0) & (Q[:, 0] < 500.0)]
    assert len(inside) and np.all(np.abs(inside[:, 1]) <= gap / 2 - BALL + 1e-6)
    # The shortest way bends round the gap's edges: no path is shorter than the straight
    # lines to the opening and back.
    corner = gap / 2 - BALL
    bound = 2 * math.hypot(400.0, 600.0 - corner)
    assert res.length >= bound - 1e-6
    assert res.min_clearance is not None and res.min_clearance >= -1e-9


def test_gap_narrower_than_the_ball_cannot_be_passed(gantry):
    """No path exists: the planner stops at its time limit and says so."""
    _, cm = gantry
    scene = wall_with_gap(2 * BALL - 10.0)
    res = plan_motion(MotionChecker(cm, scene), [0.0, 600.0], [900.0, 600.0],
                      time_limit=0.4, seed=1)
    assert res.status is MotionStatus.TIMEOUT and len(res.path) == 0
    assert "time limit" in res.message
    assert res.planning_time_s < 0.4 + 0.5


def test_resolution_is_honoured_by_every_segment(gantry):
    """A thin wall (6 mm) with a gap: at 5 mm steps (resolution 0.05 = 5 mm on prismatic
    joints) no straight segment can jump it; rechecked at 0.5 mm, every segment is free."""
    _, cm = gantry
    scene = wall_with_gap(200.0, thickness=6.0)
    for seed in range(3):
        res = plan_motion(MotionChecker(cm, scene), [0.0, 600.0], [900.0, -600.0],
                          time_limit=5.0, seed=seed, resolution=0.05, trajectory=False)
        assert_valid(cm, scene, res, [0.0, 600.0], [900.0, -600.0], step=0.5)


def test_checker_steps_never_coarser_than_asked(gantry):
    _, cm = gantry
    mc = MotionChecker(cm)
    a, b = np.array([0.0, 0.0]), np.array([37.0, -5.0])
    for res in (0.01, 0.05, 0.1):
        n = mc.steps(a, b, res)
        assert 37.0 / n <= res * 100.0 + 1e-9      # prismatic: resolution x 100 mm
        assert 37.0 / (n - 1) > res * 100.0 if n > 1 else True
    order = bisection_order(16)
    assert sorted(order.tolist()) == list(range(1, 16)) and order[0] == 8


# ---- statuses ----------------------------------------------------------------------------------
def test_start_or_goal_in_collision_names_the_pair(gantry):
    _, cm = gantry
    scene = wall_with_gap(300.0)
    mc = MotionChecker(cm, scene)
    res = plan_motion(mc, [450.0, 600.0], [0.0, 0.0])
    assert res.status is MotionStatus.START_IN_COLLISION
    assert ["tool", "upper"] in [list(p) for p in res.pairs] and "tool - upper" in res.message
    res = plan_motion(mc, [0.0, 0.0], [430.0, -500.0])
    assert res.status is MotionStatus.GOAL_IN_COLLISION
    assert [list(p) for p in res.pairs] == [["tool", "lower"]]


def test_out_of_limits_names_the_joint(gantry):
    _, cm = gantry
    res = plan_motion(MotionChecker(cm), [0.0, 0.0], [1300.0, 0.0])
    assert res.status is MotionStatus.OUT_OF_LIMITS
    assert "joint 'x'" in res.message and "the goal" in res.message
    res = plan_motion(MotionChecker(cm), [0.0, -1500.0], [0.0, 0.0])
    assert res.status is MotionStatus.OUT_OF_LIMITS and "the start" in res.message


@pytest.mark.slow
def test_pose_goals(arm):
    """Every IK branch of the pose is a goal: the path ends on one that reaches the pose;
    a pose out of reach is goal_unreachable."""
    robot, cm = arm
    model = robot.model
    scene = CollisionScene.from_dicts([box("post", (80, 80, 600), (650, -130, 0))])
    mc = MotionChecker(cm, scene)
    goal_q = np.array([0.9, -1.2])
    target = fk(model, goal_q)
    res = plan_motion(mc, [-1.0, 0.5], goal_pose=target, time_limit=5.0, seed=4)
    assert res.status is MotionStatus.OK, res.message
    assert np.allclose(fk(model, res.path[-1]), target, atol=1e-6)
    assert not collides(cm, states(res.path, 0.002), scene, exact=True).any()
    far = target.copy()
    far[:3, 3] = [2000.0, 0.0, 200.0]
    res = plan_motion(mc, [-1.0, 0.5], goal_pose=far, time_limit=1.0)
    assert res.status is MotionStatus.GOAL_UNREACHABLE and "unreachable" in res.message


def test_malformed_input_names_the_field(gantry):
    _, cm = gantry
    mc = MotionChecker(cm)
    cases = [
        (dict(start=[0.0], goal=[0.0, 0.0]), ("start",)),
        (dict(start=[0.0, 0.0], goal=[0.0, math.nan]), ("goal", "q")),
        (dict(start=[0.0, 0.0], goal=[1.0, 0.0], planner="astar"), ("planner",)),
        (dict(start=[0.0, 0.0], goal=[1.0, 0.0], resolution=0.0), ("resolution",)),
        (dict(start=[0.0, 0.0], goal=[1.0, 0.0], resolution=0.6), ("resolution",)),
        (dict(start=[0.0, 0.0], goal=[1.0, 0.0], time_limit=-1), ("time_limit",)),
        (dict(start=[0.0, 0.0]), ("goal",)),
        (dict(start=[0.0, 0.0], goal_pose=np.eye(3)), ("goal", "pose")),
    ]
    for kwargs, loc in cases:
        with pytest.raises(FieldError) as err:
            plan_motion(mc, **kwargs)
        assert tuple(err.value.loc) == loc, kwargs


# ---- reproducibility, planners, time -------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("planner", ["auto", "rrt_connect", "rrt_star"])
def test_same_seed_same_path(gantry, planner):
    _, cm = gantry
    scene = wall_with_gap(250.0)
    limit = 0.6 if planner == "rrt_star" else 5.0
    runs = [plan_motion(MotionChecker(cm, scene), [0.0, 600.0], [900.0, 500.0],
                        planner=planner, time_limit=limit, seed=s, trajectory=False)
            for s in (7, 7, 8)]
    assert all(r.status is MotionStatus.OK for r in runs)
    if planner != "rrt_star":   # rrt_star runs for its time: its result depends on speed
        assert np.array_equal(runs[0].path, runs[1].path)
    for r in runs:
        assert_valid(cm, scene, r, [0.0, 600.0], [900.0, 500.0], step=0.25)


@pytest.mark.slow
def test_rrt_star_uses_its_time_and_stays_near_the_shortest(gantry):
    """The asymptotically optimal mode keeps improving until the time limit; on the gap
    problem its simplified path is within 10 % of the shortest (by construction at least
    the two straight lines to the gap's edge)."""
    _, cm = gantry
    scene = wall_with_gap(300.0)
    res = plan_motion(MotionChecker(cm, scene), [0.0, 600.0], [900.0, 600.0],
                      planner="rrt_star", time_limit=1.5, seed=2, trajectory=False)
    assert_valid(cm, scene, res, [0.0, 600.0], [900.0, 600.0], step=0.25)
    assert res.planner == "rrt_star" and res.planning_time_s >= 1.5
    shortest = 2 * math.hypot(400.0, 500.0)
    assert shortest - 1e-6 <= res.length <= 1.10 * (shortest + 100.0)


@pytest.mark.slow
def test_without_compiled_kernels_the_answers_are_the_same(gantry, monkeypatch):
    import planning.motion.checker as checker_module

    _, cm = gantry
    scene = wall_with_gap(300.0)
    Q = np.random.default_rng(3).uniform([-200, -1000], [1200, 1000], size=(300, 2))
    fast = MotionChecker(cm, scene).free(Q)
    monkeypatch.setattr(checker_module, "_kernels", lambda: None)
    slow_checker = MotionChecker(cm, scene)
    assert slow_checker._k is None
    assert np.array_equal(slow_checker.free(Q), fast)
    res = plan_motion(slow_checker, [0.0, 600.0], [900.0, 600.0], time_limit=5.0, seed=1,
                      trajectory=False)
    assert_valid(cm, scene, res, [0.0, 600.0], [900.0, 600.0], step=0.25)


# ---- the trajectory ------------------------------------------------------------------------------
def test_trajectory_is_within_limits_and_free(arm):
    robot, cm = arm
    scene = CollisionScene.from_dicts([box("post", (80, 80, 600), (480, 480, 0))])
    mc = MotionChecker(cm, scene)
    start, goal = np.array([-0.3, 0.4]), np.array([2.2, -0.8])
    res = plan_motion(mc, start, goal, time_limit=5.0, seed=5)
    assert_valid(cm, scene, res, start, goal, step=0.002)
    T = res.trajectory
    assert T is not None
    t = np.linspace(0, T.duration, 2001)
    q, qd = T.evaluate(t), T.evaluate(t, 1)
    assert np.allclose(q[0], start, atol=1e-9) and np.allclose(q[-1], goal, atol=1e-9)
    assert np.all(np.abs(qd) <= robot.model.velocity_limits * (1 + 1e-6))
    assert not collides(cm, q, scene, exact=True).any()
    d = res.to_dict(joint_names=["shoulder", "elbow"], samples=50)
    assert d["status"] == "ok" and len(d["trajectory"]["t"]) == 50
    assert d["path"][0] == pytest.approx(start.tolist()) and d["joints"] == ["shoulder", "elbow"]


# ---- the compiled checker against the collision package ------------------------------------------
def _meshed_arm():
    """The GLT palletizer as URDF with two trimesh meshes (as the import tests)."""
    trimesh = pytest.importorskip("trimesh")
    from kinematics.library import builtin_model
    from kinematics.urdf import to_urdf

    text = to_urdf(builtin_model("glt_palletizer"))
    meshes = {"link_2": "upper.stl", "link_3": "fore.stl"}
    for link, mesh in meshes.items():
        text = text.replace(f'<link name="{link}" />',
                            f'<link name="{link}"><collision><geometry><mesh '
                            f'filename="meshes/{mesh}"/></geometry></collision></link>')
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt/glt.urdf", text)
        z.writestr("glt/meshes/upper.stl",
                   trimesh.creation.box(extents=(0.6, 0.12, 0.12)).export(file_type="stl"))
        z.writestr("glt/meshes/fore.stl",
                   trimesh.creation.cylinder(radius=0.05, height=0.5).export(file_type="stl"))
    return urdf_import.import_robot(buf.getvalue(), "glt.zip", robot_id="glt")


def test_compiled_checker_agrees_with_the_collision_package():
    """Random configurations of a meshed robot in a scene of every object type: the
    compiled sphere stage says what the numpy sphere stage says, and with the exact stage
    what the exact check says."""
    trimesh = pytest.importorskip("trimesh")
    robot = _meshed_arm()
    cm = RobotCollisionModel.from_imported(robot)
    tri = trimesh.creation.icosphere(subdivisions=1, radius=150.0)
    T = np.eye(4)
    scene = CollisionScene.from_dicts([
        box("table", (2000, 2000, 100), (0, 0, -50)),
        {"type": "sphere", "id": "ball", "radius": 200, "pose": _at(900, 300, 900)},
        {"type": "cylinder", "id": "post", "radius": 100, "height": 1500,
         "pose": _at(-700, 600, 750)},
        {"type": "capsule", "id": "bar", "radius": 60, "a": [0, -900, 1200],
         "b": [800, -900, 1200], "pose": T.tolist()},
        {"type": "mesh", "id": "rock", "vertices": tri.vertices.tolist(),
         "faces": tri.faces.tolist(), "pose": _at(-600, -600, 500)},
        {"type": "points", "id": "scan", "points": _cloud(), "radius": 10.0}])
    model = robot.model
    Q = np.random.default_rng(17).uniform(model.lower, model.upper, size=(400, model.dof))
    mc = MotionChecker(cm, scene)
    exact = mc.free(Q)
    assert np.array_equal(exact, ~collides(cm, Q, scene, exact=True))
    mc.exact = False
    spheres = mc.free(Q)
    assert np.array_equal(spheres, ~collides(cm, Q, scene))
    assert exact.any() and (~exact).any() and np.all(exact[spheres])


def _at(x, y, z) -> list:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T.tolist()


def _cloud() -> list:
    g = np.linspace(-200, 200, 9)
    X, Y = np.meshgrid(g, g)
    return np.column_stack([X.ravel() + 700, Y.ravel() - 700, np.full(X.size, 400)]).tolist()


def test_capsule_robot_plans_round_an_obstacle():
    """A built-in robot (capsule model) moves round a post between two configurations."""
    from kinematics.library import builtin_model

    model = builtin_model("glt_palletizer")
    cm = RobotCollisionModel.from_model(model)
    start = np.array([-1.2, 0.3, -0.6, 0.0, 0.5, 0.0])
    goal = np.array([1.2, 0.3, -0.6, 0.0, 0.5, 0.0])
    mid = fk(model, 0.5 * (start + goal))[:3, 3]
    scene = CollisionScene.from_dicts([{"type": "cylinder", "id": "post", "radius": 150,
                                        "height": 6000, "pose": _at(*mid)}])
    mc = MotionChecker(cm, scene)
    assert not mc.segment_free(start, goal)
    res = plan_motion(mc, start, goal, time_limit=5.0, seed=9)
    assert_valid(cm, scene, res, start, goal, step=0.002)
    assert len(res.path) >= 3
