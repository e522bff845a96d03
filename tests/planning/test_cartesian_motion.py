"""Cartesian segments of the motion planner (planning.motion.cartesian): lines and arcs of the
tool followed by damped least squares step by step, checked by the motion planner's checker.

The 6-joint arm is a UR5-like standard D-H model written here, its reached poses recomputed by
a D-H product written here too (not the kinematics package's FK); the redundant arm is the
built-in 9-joint arm; an imported 7-joint URDF covers imported robots."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from ur5_like import UR5_DH, box, off_line, ur5_fk, ur5_model

from kinematics.errors import FieldError
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.motion import MotionChecker
from planning.motion.cartesian import CartesianStatus, plan_arc, plan_line

pytestmark = pytest.mark.usefixtures("motion_kernels")

PI = math.pi
Q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.3])
TOL_P, TOL_R = 0.1, 1e-3


def rotation(axis, angle: float) -> np.ndarray:
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def angle_between(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    c = (np.trace(np.swapaxes(Ra, -1, -2) @ Rb, axis1=-2, axis2=-1) - 1) / 2
    return np.arccos(np.clip(c, -1.0, 1.0))


@pytest.fixture(scope="module")
def ur5():
    model = ur5_model()
    cm = RobotCollisionModel.from_model(model, link_radius=40.0)
    return model, cm, MotionChecker(cm)


def test_the_ur5_model_matches_the_test_fk(ur5):
    from kinematics.fk import fk

    model, _, _ = ur5
    Q = np.random.default_rng(0).uniform(-3, 3, (5, 6))
    np.testing.assert_allclose(fk(model, Q), ur5_fk(Q), atol=1e-9)


# ---- lines ---------------------------------------------------------------------------------------
def test_a_free_line_is_followed_to_the_end_on_the_line(ur5):
    model, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    target = np.eye(4)
    target[:3, :3] = rotation([1, 2, 0.5], 0.3) @ T0[:3, :3]
    target[:3, 3] = T0[:3, 3] + [60.0, -150.0, 80.0]
    res = plan_line(checker, Q0, target)
    assert res.status is CartesianStatus.OK and res.success, res.message
    assert res.fraction == 1.0
    n = math.ceil(np.linalg.norm([60.0, -150.0, 80.0]) / 5.0)
    assert res.steps == n and res.path.shape == (n + 1, 6) and res.path.dtype == np.float64
    np.testing.assert_array_equal(res.path[0], Q0)
    T = ur5_fk(res.path)
    np.testing.assert_allclose(T, res.poses, atol=1e-9)
    dist, t = off_line(T[:, :3, 3], T0[:3, 3], target[:3, 3])
    assert dist.max() <= TOL_P
    # Evenly along the line, at most 5 mm apart, from the start to the target.
    np.testing.assert_allclose(t, np.arange(n + 1) / n, atol=TOL_P / 180.0)
    assert np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1).max() <= 5.0 + TOL_P
    assert np.linalg.norm(T[-1, :3, 3] - target[:3, 3]) <= TOL_P
    assert angle_between(T[-1, :3, :3], target[:3, :3]) <= TOL_R
    assert res.position_error <= TOL_P and res.orientation_error <= TOL_R
    # Between two steps the arm moves straight in joint space: close to the line as well.
    assert res.deviation < 0.5
    assert np.abs(np.diff(res.path, axis=0)).max() <= 0.3
    with pytest.raises(ValueError):
        res.path[0, 0] = 1.0


def test_slerp_turns_the_tool_evenly_and_hold_keeps_it(ur5):
    model, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    target = np.eye(4)
    target[:3, :3] = rotation([0, 0, 1], 0.4) @ T0[:3, :3]
    target[:3, 3] = T0[:3, 3] + [0.0, -100.0, 0.0]
    slerp = plan_line(checker, Q0, target, orientation="slerp")
    hold = plan_line(checker, Q0, target, orientation="hold")
    assert slerp.status is CartesianStatus.OK and hold.status is CartesianStatus.OK
    Ts, Th = ur5_fk(slerp.path), ur5_fk(hold.path)
    # Held: every pose keeps the start's orientation; the position still reaches the target.
    assert angle_between(Th[:, :3, :3], T0[:3, :3]).max() <= TOL_R
    assert np.linalg.norm(Th[-1, :3, 3] - target[:3, 3]) <= TOL_P
    # Slerped: the tool turns about the world z axis, by 0.4 s at the place s along the line.
    _, t = off_line(Ts[:, :3, 3], T0[:3, 3], target[:3, 3])
    ideal = np.array([rotation([0, 0, 1], 0.4 * s) @ T0[:3, :3] for s in t])
    assert angle_between(Ts[:, :3, :3], ideal).max() <= TOL_R + 1e-6
    assert angle_between(Ts[-1, :3, :3], target[:3, :3]) <= TOL_R
    # 0.4 rad at 0.05 rad a step takes 8 steps although 100 mm would take 20 ...
    assert slerp.steps == 20 and slerp.rotation == pytest.approx(0.4)
    # ... and the rotation alone sets the count when it needs more.
    fine = plan_line(checker, Q0, target, max_rotation=0.01)
    assert fine.steps == 40 and fine.status is CartesianStatus.OK


def test_a_box_across_the_line_stops_it_before_the_box(ur5):
    model, cm, _ = ur5
    T0 = ur5_fk(Q0)[0]
    p0 = T0[:3, 3]
    # A plate 20 mm thick across the line, its near face 90 mm from the tool along -y.
    scene = CollisionScene.from_dicts([box("plate", (300, 20, 200), p0 + [0, -100, 0])])
    checker = MotionChecker(cm, scene)
    target = T0.copy()
    target[:3, 3] = p0 + [0, -200, 0]
    res = plan_line(checker, Q0, target)
    assert res.status is CartesianStatus.COLLISION, res.message
    assert 0.0 < res.fraction < 1.0
    assert "plate" in res.message and any("plate" in pair for pair in res.pairs)
    # The tool stopped short of the plate's face (y = p0 - 90 mm) ...
    T = ur5_fk(res.path)
    assert T[-1, 1, 3] > p0[1] - 90.0
    assert res.fraction == pytest.approx((p0[1] - T[-1, 1, 3]) / 200.0, abs=1e-3)
    # ... every reached state and the joint motion between them are free (exact check) ...
    states = np.concatenate([a + (b - a) * np.linspace(0, 1, 11)[:, None]
                             for a, b in zip(res.path[:-1], res.path[1:])])
    assert not collides(cm, states, scene, exact=True).any()
    # ... and the next step of the line (5 mm further, planned without the plate) is not.
    step = T[-1].copy()
    step[1, 3] -= 5.0
    nxt = plan_line(MotionChecker(cm), res.path[-1], step)
    assert nxt.status is CartesianStatus.OK
    assert collides(cm, nxt.path[-1], scene, exact=True)


def test_the_motion_between_two_steps_is_checked(ur5):
    """One 200 mm step across a 4 mm sheet: both ends are free, the motion between is not."""
    model, cm, checker = ur5
    T0 = ur5_fk(Q0)[0]
    scene = CollisionScene.from_dicts([box("sheet", (80, 4, 80), T0[:3, 3] + [0, -100, 0])])
    target = T0.copy()
    target[:3, 3] += [0.0, -200.0, 0.0]
    coarse = dict(max_step=250.0, max_rotation=1.0, jump_threshold=3.0)
    free = plan_line(checker, Q0, target, **coarse)
    assert free.status is CartesianStatus.OK and free.steps == 1
    assert not collides(cm, free.path, scene, exact=True).any()
    res = plan_line(MotionChecker(cm, scene), Q0, target, **coarse)
    assert res.status is CartesianStatus.COLLISION and res.fraction == 0.0
    assert "motion to the step" in res.message and ("link5", "sheet") in res.pairs
    np.testing.assert_array_equal(res.path, Q0[None])
    # The arm moving straight in joint space over 200 mm strays from the line: the
    # deviation says how far (at 5 mm steps it is far smaller).
    assert free.deviation > 1.0
    fine = plan_line(checker, Q0, target)
    assert fine.deviation < free.deviation / 50
    json.dumps(fine.to_dict(["j1", "j2", "j3", "j4", "j5", "j6"]))


def test_a_target_out_of_reach_ends_unreachable_with_the_fraction_done(ur5):
    model, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    p0 = T0[:3, 3]
    target = T0.copy()
    target[:3, 3] = p0 + [-1000.0, 0.0, 0.0]
    # The target is farther from the shoulder than the whole arm's length.
    shoulder = np.array([0.0, 0.0, UR5_DH[0][2]])
    arm = sum(abs(a) + abs(d) for a, _, d in UR5_DH[1:])
    assert np.linalg.norm(target[:3, 3] - shoulder) > arm
    res = plan_line(checker, Q0, target)
    assert res.status is CartesianStatus.UNREACHABLE, res.message
    assert 0.0 < res.fraction < 1.0
    T = ur5_fk(res.path)
    dist, t = off_line(T[:, :3, 3], p0, target[:3, 3])
    assert dist.max() <= TOL_P
    assert t[-1] == pytest.approx(res.fraction, abs=1e-4)
    assert res.fraction == pytest.approx(res.s[-1])


def test_a_wrist_flip_is_a_discontinuity(ur5):
    """Near the wrist singularity (joint 5 near 0) the held orientation makes joints 4 and 6
    turn fast: a line passing close to it needs joint 4 to turn by more than 2 rad while the
    tool moves 20 mm. At 5 mm steps that is a jump; at 1 mm steps the turn is followed."""
    _, _, checker = ur5
    q = np.array([0.3, -1.2, 1.5, -0.4, 0.1, 0.0])
    T0 = ur5_fk(q)[0]
    target = T0.copy()
    target[:3, 3] += [0.0, 300.0, 0.0]
    res = plan_line(checker, q, target, orientation="hold")
    assert res.status is CartesianStatus.DISCONTINUOUS, res.message
    assert 0.0 < res.fraction < 0.5
    assert "'j4'" in res.message or "'j6'" in res.message
    assert abs(math.sin(res.path[-1, 4])) < 0.05          # near the wrist singularity
    dist, _ = off_line(ur5_fk(res.path)[:, :3, 3], T0[:3, 3], target[:3, 3])
    assert dist.max() <= TOL_P
    fine = plan_line(checker, q, target, orientation="hold", max_step=1.0)
    assert fine.status is CartesianStatus.OK, fine.message
    y = fine.poses[:, 1, 3] - T0[1, 3]
    j4 = fine.path[:, 3]
    k = int(np.argmax(np.abs(np.diff(j4))))
    near = np.abs(y - y[k]) <= 10.0
    assert j4[near].max() - j4[near].min() > 2.0
    # A threshold above the largest step of the coarse line lets it through as well.
    assert plan_line(checker, q, target, orientation="hold",
                     jump_threshold=3.0).status is CartesianStatus.OK


def test_a_line_leaving_the_joint_limits_ends_out_of_limits(ur5):
    model, cm, _ = ur5
    lower, upper = model.lower.copy(), model.upper.copy()
    lower[0], upper[0] = -0.2, 0.2
    checker = MotionChecker(cm, lower=lower, upper=upper)
    T0 = ur5_fk(Q0)[0]
    target = T0.copy()
    target[:3, 3] += [0.0, -300.0, 0.0]   # swings the base (joint 1) past 0.2
    res = plan_line(checker, Q0, target)
    assert res.status is CartesianStatus.OUT_OF_LIMITS, res.message
    assert "'j1'" in res.message and 0.0 < res.fraction < 1.0
    assert np.all(res.path >= lower) and np.all(res.path <= upper)
    # It ran until joint 1 was close to its limit (within a step's motion of it).
    assert abs(res.path[-1, 0]) > 0.2 - 0.01


def test_start_out_of_limits_or_in_collision_answers_an_empty_path(ur5):
    model, cm, checker = ur5
    T0 = ur5_fk(Q0)[0]
    bad = Q0.copy()
    bad[2] = 7.0
    res = plan_line(checker, bad, T0)
    assert res.status is CartesianStatus.OUT_OF_LIMITS and res.path.shape == (0, 6)
    assert res.fraction == 0.0 and "'j3'" in res.message
    scene = CollisionScene.from_dicts([box("block", (100, 100, 100), T0[:3, 3])])
    res = plan_line(MotionChecker(cm, scene), Q0, T0)
    assert res.status is CartesianStatus.COLLISION and res.path.shape == (0, 6)
    assert "block" in res.message


@pytest.mark.parametrize("kwargs, loc", [
    (dict(target=np.eye(3)), ("target",)),
    (dict(target=[1.0, 2.0]), ("target",)),
    (dict(orientation="rotate"), ("orientation",)),
    (dict(max_step=0.0), ("max_step",)),
    (dict(max_rotation=-1.0), ("max_rotation",)),
    (dict(jump_threshold=math.nan), ("jump_threshold",)),
    (dict(position_tolerance=0), ("position_tolerance",)),
    (dict(resolution=1.0), ("resolution",)),
    (dict(limit_avoidance=2.0), ("limit_avoidance",)),
    (dict(q_start=[0.0] * 5), ("start",)),
    (dict(max_step=1e-6), ("max_step",)),
])
def test_bad_input_names_the_field(ur5, kwargs, loc):
    _, _, checker = ur5
    target = ur5_fk(Q0)[0]
    target[0, 3] += 100.0
    args = dict(q_start=Q0, target=target) | kwargs
    with pytest.raises(FieldError) as err:
        plan_line(checker, args.pop("q_start"), args.pop("target"), **args)
    assert err.value.loc == loc


# ---- arcs ----------------------------------------------------------------------------------------
def test_an_arc_through_a_via_point_stays_on_its_circle(ur5):
    _, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    p0 = T0[:3, 3]
    centre = p0 + [0.0, -80.0, 0.0]
    via = centre + [80.0, 0.0, 0.0]
    end = centre + [0.0, -80.0, 0.0]
    res = plan_arc(checker, Q0, end, via=via, orientation="rotate")
    assert res.status is CartesianStatus.OK, res.message
    assert res.kind == "arc" and res.length == pytest.approx(80.0 * PI)
    T = ur5_fk(res.path)
    P = T[:, :3, 3]
    assert np.abs(np.linalg.norm(P - centre, axis=1) - 80.0).max() <= TOL_P
    assert np.abs(P[:, 2] - p0[2]).max() <= TOL_P
    assert np.linalg.norm(P[-1] - end) <= TOL_P
    # It went round through the via point's side (x > centre), not the other way.
    assert P[:, 0].max() == pytest.approx(via[0], abs=1.0)
    # ``rotate``: the tool turned with the arc, half a turn about the circle's axis.
    axis = np.cross(p0 - centre, via - centre)
    ideal = rotation(axis, PI) @ T0[:3, :3]
    assert angle_between(T[-1, :3, :3], ideal) <= TOL_R


def test_an_arc_about_a_centre_holds_the_orientation(ur5):
    _, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    centre = T0[:3, 3] + [0.0, 0.0, 60.0]
    res = plan_arc(checker, Q0, centre=centre, axis=[1.0, 0.0, 0.0], angle=-PI / 2,
                   orientation="hold")
    assert res.status is CartesianStatus.OK, res.message
    T = ur5_fk(res.path)
    np.testing.assert_allclose(np.linalg.norm(T[:, :3, 3] - centre, axis=1), 60.0,
                               atol=TOL_P)
    # The start is 60 mm below the centre; a quarter turn about +x by -90 degrees takes
    # (0, 0, -60) to (0, -60, 0).
    np.testing.assert_allclose(T[-1, :3, 3], centre + [0.0, -60.0, 0.0], atol=TOL_P)
    assert angle_between(T[:, :3, :3], T0[:3, :3]).max() <= TOL_R
    with pytest.raises(FieldError) as err:       # a via point on the start: no circle
        plan_arc(checker, Q0, centre, via=T0[:3, 3])
    assert err.value.loc == ("via",)
    with pytest.raises(FieldError) as err:
        plan_arc(checker, Q0, centre=T0[:3, 3], axis=[0, 0, 1], angle=1.0)
    assert err.value.loc == ("centre",)


# ---- redundant and imported arms -----------------------------------------------------------------
def test_the_nine_joint_arm_uses_its_null_space_to_stay_off_its_limits():
    model = builtin_model("hyper_redundant_9dof")
    checker = MotionChecker(RobotCollisionModel.from_model(model, link_radius=30.0),
                            self_collision=False)
    q = np.array([0.6, -0.53, 1.95, 1.15, 1.11, 0.54, 0.1, -0.54, -0.81])
    from kinematics.fk import fk

    T0 = fk(model, q)
    target = T0.copy()
    target[:3, 3] += [200.0, 0.0, 0.0]
    on = plan_line(checker, q, target, orientation="hold")
    off = plan_line(checker, q, target, orientation="hold", limit_avoidance=0.0)
    lo, hi = np.asarray(model.lower), np.asarray(model.upper)
    start_margin = float(np.minimum(q - lo, hi - q).min())
    for res in (on, off):
        assert res.status is CartesianStatus.OK, res.message
        assert np.all(res.path >= lo) and np.all(res.path <= hi)
        T = fk(model, res.path)
        dist, _ = off_line(T[:, :3, 3], T0[:3, 3], target[:3, 3])
        assert dist.max() <= TOL_P
        assert angle_between(T[:, :3, :3], T0[:3, :3]).max() <= TOL_R
    margin_on = np.minimum(on.path - lo, hi - on.path).min(axis=1)
    margin_off = np.minimum(off.path - lo, hi - off.path).min(axis=1)
    # Without the null-space motion the line drives a joint onto its limit; with it no
    # joint comes closer to a limit than at the start, and the end is well clear.
    assert margin_off.min() < 0.01
    assert margin_on.min() >= start_margin - 1e-9
    assert margin_on[-1] > 0.3


ARM7_AXES = ["0 0 1", "0 1 0", "0 0 1", "0 -1 0", "0 0 1", "0 -1 0", "0 0 1"]
ARM7_LENGTHS = [0.33, 0.0, 0.316, 0.0, 0.384, 0.0, 0.107]


def arm7_urdf() -> str:
    """A 7-joint arm with a Panda-like layout (m); collision balls on three links."""
    parts = ['<?xml version="1.0"?><robot name="arm7"><link name="l0"/>']
    ball = {3: 0.05, 5: 0.05, 7: 0.04}
    prev, z = "l0", 0.0
    for i in range(7):
        k = i + 1
        geo = (f'<collision><geometry><sphere radius="{ball[k]}"/></geometry></collision>'
               if k in ball else "")
        parts.append(f'<link name="l{k}">{geo}</link>')
        parts.append(f'<joint name="j{k}" type="revolute"><parent link="{prev}"/>'
                     f'<child link="l{k}"/><origin xyz="0 0 {z}"/><axis xyz="{ARM7_AXES[i]}"/>'
                     '<limit lower="-2.8" upper="2.8" effort="1" velocity="1"/></joint>')
        prev, z = f"l{k}", ARM7_LENGTHS[i]
    parts.append('<link name="tool"/><joint name="flange" type="fixed"><parent link="l7"/>'
                 '<child link="tool"/><origin xyz="0 0 0.107"/></joint></robot>')
    return "".join(parts)


def test_an_imported_seven_joint_arm_follows_a_line():
    urdf_import = pytest.importorskip("kinematics.urdf_import")
    pytest.importorskip("fcl")
    robot = urdf_import.import_robot(arm7_urdf().encode(), "arm7.urdf", robot_id="arm7")
    cm = RobotCollisionModel.from_imported(robot, n_groups=1, spheres_per_group=1,
                                           pair_tables=False)
    model = robot.model
    assert model.dof == 7
    q = np.array([0.0, 0.5, 0.0, -1.5, 0.0, 1.2, 0.3])
    checker = MotionChecker(cm)
    from kinematics.fk import fk

    T0 = fk(model, q)
    target = T0.copy()
    target[:3, 3] += [100.0, 150.0, -100.0]
    res = plan_line(checker, q, target)
    assert res.status is CartesianStatus.OK, res.message
    # The model's tool frame is the chain's tip link (l7), posed by the URDF's own chain.
    assert robot.tip_link == "l7"
    T = robot.link_poses(res.path)[:, [link.name for link in robot.links].index("l7")]
    dist, t = off_line(T[:, :3, 3], T0[:3, 3], target[:3, 3])
    assert dist.max() <= TOL_P and t[-1] == pytest.approx(1.0, abs=1e-6)
    assert np.all(res.path >= -2.8) and np.all(res.path <= 2.8)
    # A ball in the way of the tool stops the line before it.
    mid = T0[:3, 3] + 0.5 * (target[:3, 3] - T0[:3, 3])
    scene = CollisionScene.from_dicts([{"type": "sphere", "id": "ball", "radius": 30.0,
                                        "pose": np.r_[np.c_[np.eye(3), mid],
                                                      [[0, 0, 0, 1]]].tolist()}])
    blocked = plan_line(MotionChecker(cm, scene), q, target)
    assert blocked.status is CartesianStatus.COLLISION and 0.0 < blocked.fraction < 0.5
    assert not collides(cm, blocked.path, scene, exact=True).any()


# ---- built-in robots ---------------------------------------------------------------------------
def test_the_palletizer_line_stays_on_one_closed_form_branch():
    """Each step of the GLT palletizer's line is one of the closed-form IK branches of its
    ideal pose (computed by the analytic solver, not by the steps' solver), the same branch
    all along."""
    from kinematics.fk import fk
    from kinematics.ik import solve_ik

    model = builtin_model("glt_palletizer")
    checker = MotionChecker(RobotCollisionModel.from_model(model), self_collision=False)
    q = np.radians([15, 30, 45, 60, 90, 160])
    T0 = fk(model, q)
    d = np.array([-120.0, 150.0, 90.0])
    target = T0.copy()
    target[:3, 3] += d
    res = plan_line(checker, q, target, orientation="hold")
    assert res.status is CartesianStatus.OK, res.message
    branch = []
    for qk, s in zip(res.path, res.s):
        pose = T0.copy()
        pose[:3, 3] += s * d
        (ik,) = solve_ik(model, pose, all_solutions=True)
        gaps = np.abs(np.atleast_2d(ik.solutions) - qk).max(axis=1)
        assert gaps.min() < 1e-3
        sol = np.atleast_2d(ik.solutions)[int(np.argmin(gaps))]
        branch.append(np.sign(sol[[2, 4]]))     # elbow and wrist signs
    assert all(np.array_equal(b, branch[0]) for b in branch)


@pytest.mark.parametrize("robot", ["tunnel_drill_arm", "tunnel_jumbo-left", "pile_driver"])
def test_built_in_arms_follow_a_held_line(robot):
    """A D-H arm with prismatic joints (the drilling arm, alone and mounted on the jumbo) and
    the pile driver follow a short line holding the orientation."""
    from kinematics.fk import fk
    from kinematics.rigs import builtin_rig

    model = (builtin_rig("tunnel_jumbo").arms["left"] if robot.startswith("tunnel_jumbo")
             else builtin_model(robot))
    checker = MotionChecker(RobotCollisionModel.from_model(model), self_collision=False)
    lo, hi = np.asarray(model.lower), np.asarray(model.upper)
    q = lo + 0.5 * (hi - lo)
    T0 = fk(model, q)
    d = np.array([0.0, 0.0, -100.0]) if robot == "pile_driver" else np.array([50.0, -80.0, 60.0])
    target = T0.copy()
    target[:3, 3] += d
    res = plan_line(checker, q, target, orientation="hold")
    assert res.status is CartesianStatus.OK, res.message
    T = fk(model, res.path)
    dist, t = off_line(T[:, :3, 3], T0[:3, 3], target[:3, 3])
    assert dist.max() <= TOL_P and t[-1] == pytest.approx(1.0, abs=1e-5)
    assert angle_between(T[:, :3, :3], T0[:3, :3]).max() <= TOL_R
    assert np.all(res.path >= lo) and np.all(res.path <= hi)


def test_a_time_limit_ends_the_segment_with_what_it_reached(ur5):
    _, _, checker = ur5
    T0 = ur5_fk(Q0)[0]
    target = T0.copy()
    target[:3, 3] += [0.0, -200.0, 0.0]
    res = plan_line(checker, Q0, target, time_limit=1e-9)
    assert res.status is CartesianStatus.TIMEOUT and res.fraction == 0.0
    np.testing.assert_array_equal(res.path, Q0[None])
    assert checker.deadline is None                    # restored
    same = plan_line(checker, Q0, T0)                  # no motion asked: done at once
    assert same.status is CartesianStatus.OK and same.fraction == 1.0
    assert np.abs(same.path - Q0).max() < 1e-6


def test_the_step_solver_never_answers_a_state_past_a_limit():
    """A step's solve within the limits starts from the predicted state moved in the null
    space, which may lie a little past a limit; when that state already reaches the pose,
    the answer is still within the limits (a benchmark found a 7-joint arm's line 0.0008 rad
    past a wrist limit). The 9-joint arm: a start 0.001 rad past joint 3's upper limit whose
    own pose is the goal."""
    from kinematics.fk import fk
    from planning.motion import cartesian

    model = builtin_model("hyper_redundant_9dof")
    checker = MotionChecker(RobotCollisionModel.from_model(model, link_radius=30.0),
                            self_collision=False)
    opts = cartesian._options(5.0, 0.05, 0.3, 0.1, 1e-3, 0.01, 0.1)
    solver = cartesian._Solver(model, checker.lower, checker.upper, checker.weights, opts)
    q = np.array([0.6, -0.53, 1.95, 1.15, 1.11, 0.54, 0.1, -0.54, -0.81])
    q[2] = checker.upper[2] + 1e-3
    q_new, ok, _, _ = solver.solve(q, fk(model, q), limits=True)
    assert np.all(q_new <= checker.upper) and np.all(q_new >= checker.lower)
    assert ok  # the pose is reached from within the limits
    # The null-space motion off the limits keeps within them too.
    moved = solver.null_step(q)
    assert np.all(moved <= checker.upper) and np.all(moved >= checker.lower)


def test_a_telescope_beside_a_parallel_feed_moves_little_in_a_step():
    """The drilling arm's telescope and feed are parallel: the null-space motion off the
    limits trades one for the other. Near the telescope's limit it moves at most half a
    step's length (2.5 mm) in one null-space step, and along a 1 m feed line the telescope's
    largest move between two states stays a few steps' length (82 mm before this bound)."""
    from kinematics.fk import fk
    from planning.motion import cartesian

    model = builtin_model("tunnel_drill_arm")
    checker = MotionChecker(RobotCollisionModel.from_model(model), self_collision=False)
    lo, hi = np.asarray(model.lower), np.asarray(model.upper)
    opts = cartesian._options(5.0, 0.05, 0.3, 0.1, 1e-3, 0.01, 0.1)
    solver = cartesian._Solver(model, checker.lower, checker.upper, checker.weights, opts)
    rng = np.random.default_rng(1)
    worst_null = worst_line = 0.0
    for _ in range(20):
        q = lo + rng.uniform(0.1, 0.9, 7) * (hi - lo)
        q[2] = lo[2] + rng.uniform(0.0, 0.05) * (hi[2] - lo[2])
        q[6] = lo[6] + rng.uniform(0.0, 0.1) * (hi[6] - lo[6])
        worst_null = max(worst_null, float(np.abs(solver.null_step(q) - q)[[2, 6]].max()))
        T0 = fk(model, q)
        target = T0.copy()
        target[:3, 3] += 1000.0 * T0[:3, 2]
        res = plan_line(checker, q, target, orientation="hold")
        if len(res.path) > 1:
            worst_line = max(worst_line, float(np.abs(np.diff(res.path[:, 2])).max()))
    assert 0.0 < worst_null <= 2.5 + 1e-9
    assert worst_line <= 30.0
