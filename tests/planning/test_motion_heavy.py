"""Joint-space motion of the heavy machines in their sites (``planning.motion.sites``): the
scenes sit where the machines reach, the typical moves are what they say, and every path
``plan_motion`` returns for them is checked here independently: its ends are the start and
the goal, its joints stay within limits, and each straight segment, stepped at half the
planner's resolution, is collision-free by ``planning.collision.collides(..., exact=True)``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.drilling import drill_ik
from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.drilling.patterns import FacePattern, face_pattern
from planning.motion import DEFAULT_RESOLUTION, PRISMATIC_STEP, MotionChecker, plan_motion
from planning.motion.sites import (
    arm_capsules,
    jumbo_site,
    pallet_problems,
    pallet_station,
    pile_driver_problems,
    pile_driver_site,
    tunnel_problems,
    tunnel_site,
)

pytestmark = pytest.mark.usefixtures("motion_kernels")


def _at_site(robot: str, site):
    """The robot's model, capsule collision model, its site (``site(model)``) and a
    checker of the two."""
    model = builtin_model(robot)
    cm = RobotCollisionModel.from_model(model)
    scene = site(model)
    return model, cm, scene, MotionChecker(cm, scene)


@pytest.fixture(scope="module")
def pile():
    return _at_site("pile_driver", pile_driver_site)


@pytest.fixture(scope="module")
def drill():
    return _at_site("tunnel_drill_arm", lambda model: tunnel_site())


@pytest.fixture(scope="module")
def palletizer():
    return _at_site("glt_palletizer", pallet_station)


def _objects(scene) -> dict:
    return {o.id: o for o in scene.objects}


def _tool_points(model, n: int = 5000, seed: int = 99) -> np.ndarray:
    Q = np.random.default_rng(seed).uniform(model.lower, model.upper, size=(n, model.dof))
    return Q, fk(model, Q)[:, :3, 3]


def _dense(model, path: np.ndarray, step: float) -> np.ndarray:
    w = np.where(model.revolute, 1.0, 1.0 / PRISMATIC_STEP)
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a) * w) / step)))
        out.append(a + np.arange(1, n + 1)[:, None] / n * (b - a))
    return np.vstack(out)


def _verified(model, cm, scene, problem, res) -> None:
    assert res.success, res.message
    path = res.path
    np.testing.assert_array_equal(path[0], problem.start)
    np.testing.assert_array_equal(path[-1], problem.goal)
    assert np.all(model.within_limits(path))
    states = _dense(model, path, DEFAULT_RESOLUTION / 2)
    assert not np.any(collides(cm, states, scene, exact=True))
    if res.trajectory is not None:
        Qt = res.trajectory.evaluate(np.linspace(0, res.trajectory.duration, 300))
        assert np.all(model.within_limits(Qt, tol=1e-6))
        assert not np.any(collides(cm, Qt, scene, exact=True))


# ---- the sites ------------------------------------------------------------------------------
def test_the_pile_drivers_site_lies_where_its_tool_goes(pile):
    model, cm, scene, _ = pile
    obj = _objects(scene)
    assert set(obj) == {"ground_near", "ground_far", "trench_bottom", "wall"}
    Q, P = _tool_points(model)
    radial = np.hypot(P[:, 0], P[:, 1])
    bottom = obj["trench_bottom"]
    x0 = bottom.pose[0, 3] - bottom.size[0] / 2
    x1 = bottom.pose[0, 3] + bottom.size[0] / 2
    assert radial.min() < x0 < x1 < radial.max()  # the trench is within reach
    ground = obj["ground_near"].pose[2, 3] + obj["ground_near"].size[2] / 2
    assert P[:, 2].min() < ground < P[:, 2].max()
    # The tool reaches into the trench, below the ground, without touching anything.
    inside = (P[:, 0] > x0 + 60) & (P[:, 0] < x1 - 60) & (P[:, 2] < ground)
    assert inside.any()
    assert not np.all(collides(cm, Q[inside], scene, exact=True))
    # The wall stands along +y from inside the inner reach to beyond the outer reach.
    wall = obj["wall"]
    corners = wall.pose[:3, :3] @ (np.array([[-1, 0, 0], [1, 0, 0]]) * wall.size).T
    ends = corners.T + wall.pose[:3, 3]
    assert np.allclose(ends[:, 0], 0.0, atol=1e-6)
    assert min(ends[:, 1]) < radial.min() and max(ends[:, 1]) > radial.max()


@pytest.mark.slow
def test_the_tunnel_surrounds_the_drilling_arm_and_closes_at_the_face(drill):
    model, cm, scene, _ = drill
    face = face_pattern(FacePattern())
    holes = face.holes[np.array(face.kinds) == "helper"][::8]
    collar = holes.copy()
    collar[:, 0] -= 300.0
    q_collar = np.array([r.q for r in drill_ik(model, collar)])
    assert not np.any(collides(cm, q_collar, scene, exact=True))
    # Through the face: the drill tip 200 mm into the rock.
    deep = holes.copy()
    deep[:, 0] += 200.0
    q_deep = np.array([r.q for r in drill_ik(model, deep)])
    assert np.all(collides(cm, q_deep, scene, exact=True))
    # The boom raised into the roof: the same swing, the telescope run out.
    up = q_collar[:1].copy()
    up[0, 1] = model.lower[1]
    up[0, 2] = model.upper[2]
    assert fk(model, up)[0, 2, 3] > FacePattern().floor_z + FacePattern().height
    assert collides(cm, up, scene, exact=True)[0]


def test_the_pallet_station_holds_what_the_palletizer_must_not_touch(palletizer):
    model, cm, scene, _ = palletizer
    obj = _objects(scene)
    assert {"floor", "conveyor", "pallet_0", "load_0", "pallet_1", "load_1"} <= set(obj)
    Q, P = _tool_points(model)
    for name in ("conveyor", "load_0", "load_1"):
        o = obj[name]
        L = (P - o.pose[:3, 3]) @ o.pose[:3, :3]
        inside = np.all(np.abs(L) < np.asarray(o.size) / 2, axis=1)
        assert inside.any(), name  # within reach
        assert np.all(collides(cm, Q[inside], scene, exact=True)), name


# ---- the moves ------------------------------------------------------------------------------
def test_pile_driver_moves_are_what_they_say(pile):
    model, cm, scene, checker = pile
    problems = pile_driver_problems(checker, 4, seed=11)
    assert [p.kind for p in problems] == ["over_wall", "into_trench"] * 2
    obj = _objects(scene)
    ground = obj["ground_near"].pose[2, 3] + obj["ground_near"].size[2] / 2
    for p in problems:
        ends = np.stack([p.start, p.goal])
        assert not np.any(collides(cm, ends, scene, exact=True))
        assert np.all(model.within_limits(ends))
        if p.kind == "over_wall":  # both sides of the wall (at +y), the straight way blocked
            assert (p.start[0] - math.pi / 2) * (p.goal[0] - math.pi / 2) < 0
            assert np.any(collides(cm, _dense(model, ends, 0.005), scene, exact=True))
        else:
            assert fk(model, p.goal)[2, 3] < ground < fk(model, p.start)[2, 3]


def test_pile_driver_motions_are_verified(pile):
    model, cm, scene, checker = pile
    for k, p in enumerate(pile_driver_problems(checker, 4, seed=3)):
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k)
        _verified(model, cm, scene, p, res)
        if p.kind == "over_wall":
            assert len(res.path) > 2  # it had to go round (over) the wall


@pytest.mark.slow
def test_drill_arm_motions_inside_the_tunnel_are_verified(drill):
    model, cm, scene, checker = drill
    problems = tunnel_problems(checker, 2, seed=5)
    for k, p in enumerate(problems):
        assert "lifter" not in p.kind  # lifters' collaring poses put the boom in the floor
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k)
        _verified(model, cm, scene, p, res)


def test_palletizer_motions_are_verified(palletizer):
    model, cm, scene, checker = palletizer
    for k, p in enumerate(pallet_problems(checker, 2, seed=8)):
        assert fk(model, p.start)[2, 2] < -0.8 and fk(model, p.goal)[2, 2] < -0.8
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k)
        _verified(model, cm, scene, p, res)


@pytest.mark.slow
def test_one_jumbo_arm_moves_round_the_others_parked(drill):
    """The jumbo's right arm between collaring poses with the left and middle arms standing
    in the tunnel: the parked arms are the capsules of their collision models."""
    from kinematics.rigs import builtin_rig
    from planning.drilling.multiarm import park_configuration

    rig = builtin_rig("tunnel_jumbo")
    parked = {a: park_configuration(rig, a, FacePattern().face_x - 300.0)
              for a in ("left", "middle")}
    scene = jumbo_site(rig, parked)
    ids = {o.id for o in scene.objects}
    assert "tunnel" in ids and {"left_link2", "middle_link6"} <= ids
    # A parked arm's capsules are where its own collision model is.
    middle = rig.arms["middle"]
    cm_middle = RobotCollisionModel.from_model(middle)
    alone = CollisionScene.from_dicts(arm_capsules(middle, parked["middle"]))
    assert collides(cm_middle, parked["middle"], alone, exact=True)
    model = rig.arms["right"]
    cm = RobotCollisionModel.from_model(model)
    checker = MotionChecker(cm, scene)
    for k, p in enumerate(tunnel_problems(checker, 2, seed=21)):
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k)
        _verified(model, cm, scene, p, res)
