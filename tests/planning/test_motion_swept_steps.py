"""Segments proved free by the distance they sweep (``planning.motion._rrt._segment_free``):
a long telescope move costs far fewer checked states than its joint grid, the bound on the
sweep holds (checked against forward kinematics), a thin plate the long proved stretches
would jump is still found (the margin of the proof is what finds it), and the heavy
machines' plans stay free at twice the planner's resolution by the collision package's
exact check."""

from __future__ import annotations

import numpy as np
import pytest
from test_motion_heavy import _verified

from kinematics.fk import fk_frames
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.motion import DEFAULT_RESOLUTION, MotionChecker, plan_motion
from planning.motion.sites import (
    pallet_problems,
    pallet_station,
    pile_driver_problems,
    pile_driver_site,
    tunnel_problems,
    tunnel_site,
)

urdf_import = pytest.importorskip("kinematics.urdf_import")
pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")

#: A telescope: one prismatic joint of 6 m carrying a ball of 5 mm radius along x.
TELESCOPE = """<?xml version="1.0"?>
<robot name="telescope">
  <link name="base"/>
  <link name="tip"><collision><geometry><sphere radius="0.005"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="tip"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="6.0" effort="1" velocity="0.5"/></joint>
</robot>"""


def _box(oid: str, size, at) -> dict:
    T = np.eye(4)
    T[:3, 3] = at
    return {"type": "box", "id": oid, "size": list(size), "pose": T.tolist()}


@pytest.fixture(scope="module")
def telescope():
    robot = urdf_import.import_robot(TELESCOPE.encode(), "telescope.urdf",
                                     robot_id="telescope")
    return RobotCollisionModel.from_imported(robot)


@pytest.fixture(scope="module")
def drill_arm():
    model = builtin_model("tunnel_drill_arm")
    return model, RobotCollisionModel.from_model(model)


def test_a_long_telescope_move_checks_far_fewer_states_than_its_grid(drill_arm):
    """The boom run out by 5.9 m in open space (one box far off): 5900 grid states at the
    default resolution (1 mm), of which the sweep proof checks a few dozen."""
    model, cm = drill_arm
    far = CollisionScene.from_dicts([_box("far", (500, 500, 500), (-30000, 0, 0))])
    checker = MotionChecker(cm, far)
    a = np.array([0.0, -1.5, 4000.0, 0.0, 1.5, 1.5, 0.0])
    b = a.copy()
    b[2] = 9900.0
    assert checker.free(np.stack([a, b])).all()
    n = checker.steps(a, b, DEFAULT_RESOLUTION)
    assert n == 5900                                 # the grid: 1 mm on prismatic joints
    c0 = checker.checks
    assert checker.segment_free(a, b, DEFAULT_RESOLUTION)
    used = checker.checks - c0
    assert 0 < used <= n // 20
    # Every grid state is indeed free (the collision package, spheres then exact).
    Q = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
    assert not collides(cm, Q[::7], far, exact=True).any()


def test_the_sweep_bound_holds_along_random_segments(drill_arm):
    """``sweeps``: no capsule end of the arm moves farther than the bound times the part
    of the segment travelled (forward kinematics at 64 states of each segment)."""
    import planning.motion._rrt as rr

    model, cm = drill_arm
    checker = MotionChecker(cm)
    rng = np.random.default_rng(41)
    cum = np.empty(model.dof + 1)
    for _ in range(30):
        a, b = rng.uniform(model.lower, model.upper, size=(2, model.dof))
        b = a + (b - a) * rng.uniform(0.05, 1.0)
        scene_bound, self_bound = rr.sweeps(checker._robot, a, b, cum)
        t = np.linspace(0.0, 1.0, 64)
        P = fk_frames(model, a + t[:, None] * (b - a))[:, :, :3, 3]   # (64, E, 3)
        moved = np.linalg.norm(P - P[:1], axis=2).max(axis=1)
        assert np.all(moved <= scene_bound * t + 1e-6)
        assert self_bound >= 0.0


def _plate_scene(x: float, thickness: float = 2.0) -> CollisionScene:
    return CollisionScene.from_dicts([_box("plate", (thickness, 400, 400), (x, 0, 0))])


@pytest.mark.parametrize("x", [1337.0, 2861.0, 4423.0])
def test_a_thin_plate_across_a_telescope_move_is_found(telescope, x):
    """A 2 mm plate across the 5 mm ball's 6 m run: stretches of up to ~200 mm are proved
    at once, so a plate between their middle states is met only because each middle state
    is checked clear by the stretch's sweep (without that margin the move passes)."""
    checker = MotionChecker(telescope, _plate_scene(x))
    a, b = np.array([0.0]), np.array([6000.0])
    assert checker.free(np.stack([a, b])).all()
    assert not checker.segment_free(a, b, DEFAULT_RESOLUTION)
    # The same move beside the plate is free, and cheap.
    clear = MotionChecker(telescope, _plate_scene(-1000.0))
    c0 = clear.checks
    assert clear.segment_free(a, b, DEFAULT_RESOLUTION)
    assert clear.checks - c0 <= 6000 // 20


def test_the_planner_goes_round_a_thin_plate_it_could_jump(telescope):
    """A plate across the telescope's run with nothing to go round it by: the compiled
    search and its segment checks find no path (the straight move is never proved)."""
    checker = MotionChecker(telescope, _plate_scene(2861.0))
    res = plan_motion(checker, [0.0], [6000.0], time_limit=0.3, seed=1, trajectory=False)
    assert not res.success


@pytest.mark.parametrize("robot", ["pile_driver", "glt_palletizer"])
def test_heavy_machine_plans_are_free_at_half_the_resolution(robot):
    model = builtin_model(robot)
    cm = RobotCollisionModel.from_model(model)
    scene = pile_driver_site(model) if robot == "pile_driver" else pallet_station(model)
    checker = MotionChecker(cm, scene)
    problems = (pile_driver_problems if robot == "pile_driver" else pallet_problems)(
        checker, 2, 77)
    for k, p in enumerate(problems):
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k,
                          trajectory=False)
        _verified(model, cm, scene, p, res)


@pytest.mark.slow
def test_drill_arm_plans_in_the_tunnel_are_free_at_half_the_resolution(drill_arm):
    model, cm = drill_arm
    scene = tunnel_site()
    checker = MotionChecker(cm, scene)
    for k, p in enumerate(tunnel_problems(checker, 2, 77)):
        res = plan_motion(checker, p.start, p.goal, time_limit=5.0, seed=k,
                          trajectory=False)
        _verified(model, cm, scene, p, res)


def test_proofs_are_tried_while_they_pay():
    """A checker tries proofs for its first 16, then while a quarter succeed, else on every
    64th checked state; the counts are halved every 256 tries (recent ones weigh more)."""
    from planning.motion._rrt import PROOF_TRIALS, PROOF_WINDOW, _proving

    def tries(checked, tried, proved):
        count = np.array([checked, tried, proved], dtype=np.int64)
        return bool(_proving(count)), count.tolist()

    assert tries(1, 0, 0)[0]
    assert tries(1, PROOF_TRIALS - 1, 0)[0]
    assert not tries(1, PROOF_TRIALS, 0)[0]             # 16 failures: stop
    assert tries(64, PROOF_TRIALS, 0)[0]                # but look again now and then
    assert tries(1, 40, 10)[0] and not tries(1, 40, 9)[0]
    ok, after = tries(1, PROOF_WINDOW, 60)
    assert after == [1, PROOF_WINDOW // 2, 30] and not ok
