"""Multi-arm collision avoidance for the drilling jumbo (paper 002, sections 3.3, 3.4 and 4.2):
capsule envelopes and distances, the transfer space, IAPF (eqs. 8-13) and RRT-Connect,
smoothing with the quintic B-spline, and whole-face plans checked every 10 ms."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.drilling import drill_ik
from kinematics.errors import FieldError
from kinematics.rigs import builtin_rig
from planning.drilling.envelopes import (
    DRILL_ARM_RADII,
    capsule_distances,
    drill_arm_envelope,
    min_distance,
)
from planning.drilling.iapf import IAPF, ClassicAPF, follow_field
from planning.drilling.multiarm import (
    PAPER_ACCELERATION_BOUND,
    ROTATIONAL_JOINTS,
    FaceOptions,
    MotionLimits,
    make_planner,
    pair_distances,
    plan_face,
    plan_move,
    smooth_path,
)
from planning.drilling.rrt import RRTConnect
from planning.drilling.space import ArmSpace, Obstacles
from planning.status import PlanStatus

FACE_X = 9000.0
#: Four holes per arm, the middle arm's reaching towards both side arms' strips.
SMALL_FACE = {
    "left": [[FACE_X, 2600, 300], [FACE_X, 3400, 1500], [FACE_X, 2200, 3000],
             [FACE_X, 3800, 4200]],
    "middle": [[FACE_X, -1100, 800], [FACE_X, 0, 2400], [FACE_X, 1000, 4300],
               [FACE_X, 1200, 900]],
    "right": [[FACE_X, -2600, 500], [FACE_X, -3500, 2000], [FACE_X, -2200, 3600],
              [FACE_X, -3900, 200]],
}


@pytest.fixture(scope="module")
def rig():
    return builtin_rig("tunnel_jumbo")


@pytest.fixture(scope="module")
def env():
    return drill_arm_envelope()


@pytest.fixture(scope="module")
def blocked(rig, env):
    """The left arm moving from a hole below the parked middle arm's feed to one above it:
    the straight joint-space line goes through the middle arm."""
    q_mid = drill_ik(rig.arms["middle"], [FACE_X, 1400, 3000])[0].q
    obs = Obstacles.of_arms({"middle": (rig.arms["middle"], q_mid)}, env)
    space = ArmSpace(rig.arms["left"], env, FACE_X)
    qa = drill_ik(rig.arms["left"], [FACE_X, 1500, 1500])[0].q
    qb = drill_ik(rig.arms["left"], [FACE_X, 1500, 4500])[0].q
    return space, obs, qa, qb


@pytest.fixture(scope="module")
def small_plan(rig):
    from planning.drilling.allocation import assign_holes

    return plan_face(rig, None, allocation=assign_holes(rig, SMALL_FACE), seed=1)


# ---- envelopes -------------------------------------------------------------------------------
def test_capsule_distance_matches_dense_sampling():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(40, 3, 2, 3)) * 1000
    B = rng.normal(size=(40, 2, 2, 3)) * 1000
    ra, rb = np.array([100.0, 200, 50]), np.array([80.0, 10])
    d = capsule_distances(A, ra, B, rb)
    s = np.linspace(0, 1, 401)
    for k in range(5):
        for i in range(3):
            for j in range(2):
                P = A[k, i, 0] + s[:, None] * (A[k, i, 1] - A[k, i, 0])
                Q = B[k, j, 0] + s[:, None] * (B[k, j, 1] - B[k, j, 0])
                sampled = np.linalg.norm(P[:, None] - Q[None], axis=2).min() - ra[i] - rb[j]
                assert d[k, i, j] <= sampled + 1e-9
                assert d[k, i, j] == pytest.approx(sampled, abs=15.0)
    np.testing.assert_allclose(min_distance(A, ra, B, rb, chunk=7), d.min(axis=(1, 2)))


def test_envelope_radii_are_parameters():
    env = drill_arm_envelope({"feed": 300})
    assert dict(zip(env.names, env.radii))["feed"] == 300
    assert dict(zip(env.names, env.radii))["boom"] == DRILL_ARM_RADII["boom"]
    with pytest.raises(FieldError, match="radii.tail") as err:
        drill_arm_envelope({"tail": 10})
    assert err.value.loc == ("radii", "tail")
    with pytest.raises(FieldError, match="radii.boom") as err:
        drill_arm_envelope({"boom": -1})
    assert err.value.loc == ("radii", "boom")


# ---- the transfer space ----------------------------------------------------------------------
def test_transfer_space_keeps_the_drilling_posture(rig, env):
    space = ArmSpace(rig.arms["right"], env, FACE_X)
    holes = np.array(SMALL_FACE["right"])
    q = np.array([r.q for r in drill_ik(rig.arms["right"], holes)])
    np.testing.assert_allclose(space.full_q(q[:, :3]), q, atol=1e-6)  # rule + feed 4022
    np.testing.assert_allclose(space.tip_yz(q[:, :3]), holes[:, 1:], atol=1e-6)
    np.testing.assert_allclose(space.d7_face(q[:, :3], 300.0), q[:, 6] - 300.0, atol=1e-6)
    u = space.to_u(q[:, :3])
    assert np.all((u >= 0) & (u <= 1))
    np.testing.assert_allclose(space.from_u(u), q[:, :3])
    assert np.all(np.isinf(space.clearance(q[:, :3], Obstacles.none())))


# ---- IAPF (eqs. 8-13) ------------------------------------------------------------------------
def test_iapf_attraction_is_per_joint_with_a_threshold(blocked):
    space = blocked[0]
    iapf = IAPF(goal_threshold=0.1, attraction_gain=2.0)
    u, ug = np.array([0.5, 0.5, 0.5]), np.array([0.55, 0.2, 0.9])
    F = iapf.forces(space, Obstacles.none(), u, ug, np.full(6, np.inf))
    # eq. 9: delta (q_goal - q) inside the threshold, delta d* sign(...) beyond it
    np.testing.assert_allclose(F, [2.0 * 0.05, -2.0 * 0.1, 2.0 * 0.1])


def test_iapf_repulsion_vanishes_at_the_goal(blocked):
    """Eq. 13: F_rep1 is proportional to the distance to the goal, F_rep2 points at it; so
    next to an obstacle the force across the goal direction dies out at the goal."""
    space, obs, qa, _ = blocked
    iapf = IAPF()
    u = space.to_u(qa[None, :3])[0]
    c = space.link_clearance(qa[None, :3], obs)[0]
    assert c.min() < iapf.influence  # the obstacle acts here
    across = []
    for rho in (0.1, 0.01, 0.001):
        ug = u + rho * np.array([0.0, 0.6, 0.8])
        F = iapf.forces(space, obs, u, ug, c) - iapf.forces(space, Obstacles.none(), u, ug,
                                                            np.full(6, np.inf))
        w = (ug - u) / rho
        across.append(np.linalg.norm(F - (F @ w) * w))
        assert F @ w > -np.linalg.norm(F)  # never straight back from the goal
    assert across[0] > 0
    np.testing.assert_allclose(np.array(across[1:]) / across[0], [0.1, 0.01], rtol=0.05)


def test_iapf_reaches_a_goal_next_to_an_obstacle_where_the_classic_field_stalls(rig, env):
    """The failure IAPF's repulsion is built to remove (section 3.3.2): a goal inside the
    influence distance of the parked middle arm. Descending the fields alone (no
    safeguard), the classic repulsion, which does not vanish at the goal, holds the arm off
    it; IAPF's reaches it. Neither lets the envelopes meet."""
    q_mid = drill_ik(rig.arms["middle"], [FACE_X, 1400, 3000])[0].q
    obs = Obstacles.of_arms({"middle": (rig.arms["middle"], q_mid)}, env)
    space = ArmSpace(rig.arms["left"], env, FACE_X)
    qa = drill_ik(rig.arms["left"], [FACE_X, 3500, 3000])[0].q[:3]
    qb = drill_ik(rig.arms["left"], [FACE_X, 2100, 2600])[0].q[:3]
    goal_clearance = space.link_clearance(qb[None], obs).min()
    assert 0 < goal_clearance < IAPF().influence
    ug = space.to_u(qb[None])[0]
    runs = {}
    for field in (IAPF(), ClassicAPF()):
        run = follow_field(field, space, obs, qa, qb)
        assert space.link_clearance(space.from_u(run.u), obs).min() > 0
        runs[type(field).__name__] = run
    assert runs["IAPF"].reached
    np.testing.assert_allclose(runs["IAPF"].u[-1], ug)
    assert not runs["ClassicAPF"].reached
    assert np.linalg.norm(runs["ClassicAPF"].u[-1] - ug) > 10 * ClassicAPF().step


def test_classic_field_is_khatibs(blocked):
    """Quadratic attraction everywhere; repulsion lambda (1/d - 1/d_A) / d^2 along the
    clearance gradient, the same at any distance to the goal."""
    space, obs, qa, _ = blocked
    apf = ClassicAPF()
    u = space.to_u(qa[None, :3])[0]
    ug = np.clip(u + np.array([0.4, -0.3, 0.2]), 0, 1)
    F = apf.forces(space, Obstacles.none(), u, ug, np.full(6, np.inf))
    np.testing.assert_allclose(F, apf.attraction_gain * (ug - u))
    c = space.link_clearance(qa[None, :3], obs)[0]
    rep = [apf.forces(space, obs, u, g, c) - apf.attraction_gain * (g - u)
           for g in (ug, u + 1e-3 * (ug - u))]
    np.testing.assert_allclose(rep[0], rep[1])  # does not fade near the goal
    assert np.linalg.norm(rep[0]) > 0


@pytest.mark.parametrize("planner", [IAPF(), RRTConnect()])
def test_planners_go_around_the_parked_middle_arm(blocked, planner):
    space, obs, qa, qb = blocked
    line = np.linspace(qa[:3], qb[:3], 60)
    assert space.clearance(line, obs).min() < -300  # the straight move would hit it
    mv = plan_move(space, obs, qa, qb, planner, np.random.default_rng(0),
                   limits=MotionLimits(), standoff=300.0)
    assert mv.success, mv.message
    assert mv.status is PlanStatus.OK and mv.path.status is PlanStatus.OK
    assert mv.path.min_clearance >= planner.safety - 1e-9
    np.testing.assert_allclose(mv.path.q[0], qa[:3])
    np.testing.assert_allclose(mv.path.q[-1], qb[:3])
    t = np.arange(0.0, mv.duration, 0.01)
    q = mv.evaluate(t)
    assert space.clearance(q[:, :3], obs).min() > 0  # clear at every 10 ms sample
    np.testing.assert_allclose(q[0], qa, atol=1e-9)
    np.testing.assert_allclose(mv.evaluate([mv.duration])[0], qb, atol=1e-6)
    # the compensation joints follow the rule: the drill stays perpendicular to the face
    np.testing.assert_allclose(q[:, 4], -q[:, 1], atol=1e-12)
    np.testing.assert_allclose(q[:, 5], np.pi / 2 - q[:, 0], atol=1e-12)
    cont = mv.traj.continuity()  # quintic B-spline: C4 at the knots
    assert cont["velocity"] < 1e-6 and cont["acceleration"] < 1e-6
    # The time scaling keeps the acceleration limit we set (MotionLimits: 0.24 rad/s^2, just
    # under the paper's 0.25): a limit imposed, not a result (see the next test).
    assert mv.traj.peaks(2)[0][:2].max() <= MotionLimits().acceleration[0] + 1e-9


@pytest.mark.slow
def test_the_papers_acceleration_bound_is_imposed_not_found(blocked):
    """Paper 002 reports joint accelerations below 0.25 rad/s^2. Ours stay below it only
    because the time scaling is given that limit: with the velocity limit alone the same
    move peaks far above it, and any other limit is kept as well."""
    space, obs, qa, qb = blocked
    peaks = {}
    for acc in (1e6, 0.1):
        limits = MotionLimits(acceleration=(acc, acc, 1e9))
        mv = plan_move(space, obs, qa, qb, IAPF(), np.random.default_rng(0), limits=limits,
                       standoff=300.0)
        assert mv.success, mv.message
        peaks[acc] = mv.traj.peaks(2)[0][:2].max()
    assert peaks[1e6] > 2 * PAPER_ACCELERATION_BOUND
    assert peaks[0.1] <= 0.1 + 1e-9


def test_an_unreachable_goal_is_a_failure_not_a_path(blocked, rig, env):
    space, obs, qa, _ = blocked
    q_hit = drill_ik(rig.arms["left"], [FACE_X, 1450, 3000])[0].q  # inside the middle feed
    for planner in (IAPF(), RRTConnect(max_iterations=50)):
        mv = plan_move(space, obs, qa, q_hit, planner, np.random.default_rng(0),
                       limits=MotionLimits(), standoff=300.0)
        assert not mv.success and mv.status is PlanStatus.COLLISION
        assert mv.path.status is PlanStatus.COLLISION and mv.traj is None


def test_move_planner_failures_are_told_apart_by_status(blocked):
    space, obs, qa, qb = blocked
    rng = np.random.default_rng(0)
    # Out of iterations or steps before reaching the goal around the parked arm.
    assert RRTConnect(max_iterations=1).plan(space, obs, qa[:3], qb[:3], rng).status \
        is PlanStatus.BUDGET_SPENT
    assert IAPF(max_steps=3).plan(space, obs, qa[:3], qb[:3], rng).status \
        is PlanStatus.BUDGET_SPENT
    # A goal the telescope cannot take: not a collision, an input beyond the limits.
    q_far = qb[:3].copy()
    q_far[2] = space.model.joints[2].upper + 1000.0
    res = RRTConnect().plan(space, obs, qa[:3], q_far, rng)
    assert res.status is PlanStatus.INVALID_INPUT and not res.success
    # Smoothing a raw path straight through the parked arm, or beyond the telescope's stop.
    line = np.linspace(qa[:3], qb[:3], 20)
    traj, _, status, _ = smooth_path(space, line, obs, MotionLimits())
    assert traj is None and status is PlanStatus.COLLISION
    traj, _, status, _ = smooth_path(space, np.linspace(qa[:3], q_far, 20), Obstacles.none(),
                                     MotionLimits())
    assert traj is None and status is PlanStatus.OUT_OF_LIMITS
    traj, _, status, why = smooth_path(space, np.array([qa[:3], qa[:3]]), obs, MotionLimits())
    assert traj is None and status is PlanStatus.OK and why == "no motion"


@pytest.mark.parametrize("name, params, loc", [
    ("iapf", {"lam": 1}, ("planner_params", "lam")),
    ("prm", None, ("planner",)),
    ("iapf", {"step": 0}, ("planner_params", "step")),
    ("iapf", {"safety": -1}, ("planner_params", "safety")),
    ("rrt", {"max_iterations": 0}, ("planner_params", "max_iterations")),
    ("rrt", {"shortcut": -1}, ("planner_params", "shortcut")),
])
def test_planner_params_name_the_field(name, params, loc):
    with pytest.raises(FieldError) as err:
        make_planner(name, params)
    assert err.value.loc == loc


# ---- whole faces -----------------------------------------------------------------------------
def test_small_face_plan_is_collision_free(rig, small_plan, capsys):
    fp = small_plan
    assert fp.success, fp.messages
    assert fp.status is PlanStatus.OK and fp.total_collisions == 0
    assert set(fp.min_distance) == {"left-middle", "left-right", "middle-right"}
    # Every pair keeps more than the planners' 100 mm margin at every 10 ms sample (measured:
    # 913 mm middle-left, 1025 mm middle-right), not merely clear of overlap.
    assert all(d.min() > IAPF().safety for d in fp.min_distance.values())
    dt = np.diff(fp.t)
    assert dt.max() <= 0.01 + 1e-9  # checked every 10 ms
    for a, ap in fp.arms.items():
        assert len(ap.order) == 4 and ap.planner_counts.get("iapf", 0) >= 4
        assert ap.tool_path_m >= ap.sequence_length_m * 0.98
        # each move ends drilling the next hole of the order
        ends = np.array([mv.q_goal for mv in ap.timeline.moves[:4]])
        q_holes = [r.q for r in drill_ik(rig.arms[a], fp.allocation.holes[ap.order])]
        np.testing.assert_allclose(ends, q_holes, atol=1e-6)
        # The limit we impose, measured on the 10 ms samples by finite differences (within
        # 1 %): the paper's 0.25 rad/s^2 holds because of it, not of the plan.
        limit = MotionLimits().acceleration[0]
        assert fp.accelerations[a][list(ROTATIONAL_JOINTS)].max() <= 1.01 * limit
    # middle first; the side arms start when it has finished and parked
    mid_end = fp.arms["middle"].timeline.end
    assert fp.arms["left"].timeline.starts[0] == pytest.approx(mid_end)
    with capsys.disabled():
        print("\nsmall face, IAPF: min distance " + ", ".join(
            f"{p} {d.min():.0f} mm" for p, d in fp.min_distance.items())
            + f"; tool path {fp.tool_path_m():.2f} m; middle parks: {fp.middle_park}")


@pytest.mark.slow
def test_rrt_face_plan_and_reproducibility(rig, small_plan):
    from planning.drilling.allocation import assign_holes

    alloc = assign_holes(rig, SMALL_FACE)
    rrt = plan_face(rig, None, allocation=alloc, planner="rrt", seed=1)
    assert rrt.success and rrt.total_collisions == 0, rrt.messages
    again = plan_face(rig, None, allocation=alloc, planner="rrt", seed=1)
    for a in rrt.q:
        np.testing.assert_array_equal(rrt.q[a], again.q[a])
    # RRT's raw paths wander; IAPF's follow the attraction
    assert rrt.tool_path_m() >= small_plan.tool_path_m() - 1e-6


def test_a_colliding_goal_makes_the_plan_fail(rig):
    """A left-arm hole right on the middle arm's parked feed: reported, never returned as a
    success."""
    from planning.drilling.allocation import assign_holes

    alloc = assign_holes(rig, {"left": [[FACE_X, 3000, 1000], [FACE_X, 1000, 614]]})
    fp = plan_face(rig, None, allocation=alloc)
    assert not fp.success and fp.status is PlanStatus.COLLISION, fp.messages
    failed = [mv for mv in fp.arms["left"].timeline.moves if not mv.success]
    assert failed and all(mv.status is PlanStatus.COLLISION for mv in failed)


def test_the_final_check_sees_overlaps(rig, env):
    """Two arms driven into each other (no planner): the 10 ms check finds the overlap."""
    q_mid = drill_ik(rig.arms["middle"], [FACE_X, 1400, 3000])[0].q
    qa = drill_ik(rig.arms["left"], [FACE_X, 1500, 1500])[0].q
    qb = drill_ik(rig.arms["left"], [FACE_X, 1500, 4500])[0].q
    s = np.linspace(0, 1, 300)[:, None]
    q_left = qa + s * (qb - qa)
    q = {"left": q_left, "middle": np.repeat(q_mid[None], 300, axis=0),
         "right": np.repeat(drill_ik(rig.arms["right"], [FACE_X, -3000, 1000])[0].q[None],
                            300, axis=0)}
    moving = {"left": np.ones(300, bool), "middle": np.zeros(300, bool),
              "right": np.zeros(300, bool)}
    d = pair_distances(rig, env, q, moving)
    assert d["left-middle"].min() < -300 and d["left-middle"][0] > 0
    np.testing.assert_allclose(d["left-middle"], pair_distances(rig, env, q)["left-middle"])
    assert np.all(d["middle-right"] == d["middle-right"][0])


# ---- the steps of a face plan ----------------------------------------------------------------
@pytest.mark.parametrize("options, loc", [
    ({"middle_park": "away"}, ("middle_park",)),
    ({"standoff": -1.0}, ("standoff",)),
    ({"standoff": 2001.0}, ("standoff",)),
    ({"drill_time_s": -0.5}, ("drill_time_s",)),
    ({"check_dt": 0.5}, ("check_dt",)),
])
def test_face_options_name_the_field_at_fault(rig, options, loc):
    from planning.drilling.allocation import assign_holes

    with pytest.raises(FieldError) as err:
        FaceOptions(**options)
    assert err.value.loc == loc
    with pytest.raises(FieldError) as err:
        plan_face(rig, None, allocation=assign_holes(rig, SMALL_FACE), **options)
    assert err.value.loc == loc


def test_the_fallback_is_the_other_planner_with_the_same_safety_margin():
    main, backup = FaceOptions(planner="iapf", planner_params={"safety": 123.0}).move_planners()
    assert isinstance(main, IAPF) and isinstance(backup, RRTConnect)
    assert main.safety == backup.safety == 123.0
    main, backup = FaceOptions(planner="rrt").move_planners()
    assert isinstance(main, RRTConnect) and isinstance(backup, IAPF)
    main, backup = FaceOptions(planner="rrt", fallback=False).move_planners()
    assert isinstance(main, RRTConnect) and backup is None


def test_side_arms_that_would_meet_run_one_after_the_other(rig):
    """Left and right holes on each other's side, no middle holes: running at once the side
    arms cross, so the right arm waits until the left arm is done (and the plan, whose
    right-arm holes the parked left arm blocks, is reported as failing, never as clear)."""
    from planning.drilling.allocation import assign_holes

    crossing = {"left": [[FACE_X, 1500, 5000], [FACE_X, -1500, 5200]],
                "right": [[FACE_X, -1500, 4800], [FACE_X, 1500, 5100]]}
    fp = plan_face(rig, None, allocation=assign_holes(rig, crossing), seed=1)
    assert fp.extras["notes"] == ["right waits for left: running at once they would meet"]
    assert fp.middle_park == "none" and not fp.arms["middle"].timeline.moves
    left, right = fp.arms["left"].timeline, fp.arms["right"].timeline
    assert left.starts[0] == 0.0
    assert right.starts[0] == pytest.approx(left.end)
    assert set(fp.min_distance) == set(fp.collisions) == {"left-middle", "left-right",
                                                          "middle-right"}
    assert not fp.success and fp.collisions["left-right"] > 0
    assert any(m.startswith("left-right: envelopes overlap") for m in fp.messages)
    # the right arm's failed moves are those of its final (waiting) plan
    right_moves = [m for m in fp.messages if m.startswith("right move ")]
    assert len(right_moves) == len(set(right_moves)) == sum(
        not mv.success for mv in right.moves)
