"""Sequencing by what the boom spends: joint-space travel time, IK branches chosen with the
order (a generalised TSP), against optima found by enumeration in the test."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from kinematics.cylinders import cylinder_set
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.rigs import builtin_rig
from planning.drilling.allocation import allocate_holes
from planning.drilling.boom_time import (
    DRILL_ARM_SPEEDS,
    BoomTime,
    drill_branches,
    order_time,
    sequence_arm,
    sequence_by_boom_time,
)
from planning.drilling.multiarm import FaceOptions, park_configuration
from planning.drilling.patterns import face_pattern
from planning.sequencing import sequence_holes
from planning.sequencing.branches import (
    EXACT_MAX,
    best_alternatives,
    path_cost,
    sequence_with_alternatives,
)


def linf(speeds):
    """The test's own time model: ``max_j |dq_j| / v_j`` between rows."""
    v = np.asarray(speeds, dtype=float)

    def cost(A, B):
        return (np.abs(A[:, None, :] - B[None, :, :]) / v).max(axis=2)

    return cost


def enumerate_best(F, f0, cost):
    """Cheapest (order, branches) by trying every order and every branch of every node (the
    branch choices of one order at once); without a start node 0 goes first."""
    N, B, K = F.shape
    T = cost(F.reshape(-1, K), F.reshape(-1, K)).reshape(N, B, N, B)
    T0 = np.zeros((N, B)) if f0 is None else cost(f0[None], F.reshape(-1, K)).reshape(N, B)
    T = np.where(np.isnan(T), np.inf, T)
    T0 = np.where(np.isnan(T0), np.inf, T0)
    choices = np.array(list(itertools.product(range(B), repeat=N)))  # (B^N, N)
    best = (math.inf, None, None)
    orders = itertools.permutations(range(N)) if f0 is not None else \
        ((0, *rest) for rest in itertools.permutations(range(1, N)))
    for order in orders:
        o = np.array(order)
        t = T0[o[0], choices[:, 0]].copy()
        for k in range(1, N):
            t += T[o[k - 1], choices[:, k - 1], o[k], choices[:, k]]
        i = int(np.argmin(t))
        if t[i] < best[0]:
            best = (float(t[i]), order, tuple(choices[i]))
    return best


# ---- the generalised TSP ---------------------------------------------------------------------
def test_three_holes_two_branches_match_enumeration():
    """Three holes, two IK branches each, two joints at 1 and 0.5 units/s. Branch 1 of hole
    2 lies far from everything else, so the cheapest tour is not the one on the least time
    between any branches of two holes alone; the alternation must find the enumerated
    optimum, branches included."""
    F = np.array([
        [[0.0, 0.0], [3.0, 0.2]],
        [[1.0, 1.0], [0.9, -2.0]],
        [[2.5, 0.1], [-5.0, 4.0]],
    ])
    f0 = np.array([0.4, 0.3])
    cost = linf([1.0, 0.5])
    t_best, order_best, branch_best = enumerate_best(F, f0, cost)
    res = sequence_with_alternatives(F, f0, cost, seed=0)
    assert res.cost == pytest.approx(t_best, rel=1e-12)
    assert res.order.tolist() == list(order_best)
    assert res.branch.tolist() == list(branch_best)
    assert path_cost(res.order, res.branch, F, f0, cost) == pytest.approx(res.cost)
    # without a start, node 0 first in whichever branch is best
    t0, o0, b0 = enumerate_best(F, None, cost)
    free = sequence_with_alternatives(F, None, cost, seed=0)
    assert free.order[0] == 0 and free.cost == pytest.approx(t0, rel=1e-12)


def test_direction_dependent_costs_are_solved_exactly():
    """A cost that depends on the direction (joint 0 slower going up, as a cylinder that
    extends slower than it retracts): the exact programme and the layered shortest path
    use the directed costs; enumeration agrees."""
    rng = np.random.default_rng(8)
    F = rng.uniform(0, 4, (6, 2, 2))
    f0 = rng.uniform(0, 4, 2)

    def cost(A, B):
        up = np.maximum(B[None, :, 0] - A[:, None, 0], 0.0) / 0.5
        down = np.maximum(A[:, None, 0] - B[None, :, 0], 0.0) / 2.0
        other = np.abs(B[None, :, 1] - A[:, None, 1])
        return np.maximum(np.maximum(up, down), other)

    t_best, order_best, branch_best = enumerate_best(F, f0, cost)
    res = sequence_with_alternatives(F, f0, cost, seed=0)
    assert res.cost == pytest.approx(t_best, rel=1e-12)
    assert path_cost(res.order, res.branch, F, f0, cost) == pytest.approx(t_best)
    branch, total = best_alternatives(np.array(order_best), F, f0, cost)
    assert total == pytest.approx(t_best) and tuple(branch) == tuple(branch_best)


def test_branches_for_an_order_are_the_layered_shortest_path():
    rng = np.random.default_rng(3)
    F = rng.uniform(-2, 2, (6, 3, 4))
    F[2, 1] = np.nan  # a hole without its second branch
    f0 = rng.uniform(-2, 2, 4)
    cost = linf([1.0, 2.0, 0.5, 1.5])
    order = rng.permutation(6)
    branch, total = best_alternatives(order, F, f0, cost)
    brute = min(
        (sum(float(cost(G[k - 1 : k], G[k : k + 1])[0, 0]) for k in range(1, 6))
         + float(cost(f0[None], G[:1])[0, 0]), b)
        for b in itertools.product(range(3), repeat=6)
        if np.all(np.isfinite(G := np.array([F[o, x] for o, x in zip(order, b)])))
    )
    assert total == pytest.approx(brute[0], rel=1e-12)
    assert tuple(branch) == brute[1]


def test_a_seven_node_instance_matches_enumeration():
    rng = np.random.default_rng(11)
    F = rng.uniform(0, 3, (7, 2, 3))
    f0 = rng.uniform(0, 3, 3)
    cost = linf([1.0, 1.0, 2.0])
    t_best, _, _ = enumerate_best(F, f0, cost)
    res = sequence_with_alternatives(F, f0, cost, seed=1)
    assert res.cost == pytest.approx(t_best, rel=1e-9)


def test_above_the_exact_size_the_alternation_only_improves():
    """Past ``EXACT_MAX`` nodes: the answer's alternatives are the best for its order, it
    costs no more than a given order with its best alternatives, nor less than its order on
    the optimistic table."""
    rng = np.random.default_rng(5)
    N = EXACT_MAX + 8
    F = rng.uniform(0, 10, (N, 3, 3))
    F[::4, 2] = np.nan
    f0 = rng.uniform(0, 10, 3)
    cost = linf([1.0, 2.0, 0.5])
    given = rng.permutation(N)
    res = sequence_with_alternatives(F, f0, cost, seed=2, candidates=[given])
    branch, total = best_alternatives(res.order, F, f0, cost)
    assert res.cost == pytest.approx(total) and np.array_equal(res.branch, branch)
    assert res.cost <= best_alternatives(given, F, f0, cost)[1] + 1e-9
    assert res.lower_bound_cost <= res.cost + 1e-9
    assert np.all(np.diff(res.history) < 0)  # each round kept only if it gains


# ---- the time model --------------------------------------------------------------------------
def test_move_time_is_the_slowest_joint():
    model = builtin_rig("tunnel_jumbo").arms["middle"]
    timing = BoomTime.for_model(model)
    v = np.array([DRILL_ARM_SPEEDS[j.name] for j in model.joints])
    qa = np.array([0.1, -1.6, 5000.0, 0.0, 1.6, 1.47, 4022.0])
    qb = np.array([-0.3, -1.5, 5600.0, 1.2, 1.5, 1.87, 4022.0])
    assert timing.move_times(qa, qb)[0, 0] == pytest.approx((np.abs(qb - qa) / v).max())
    # an override by joint name, and an acceleration: a rest-to-rest trapezoid
    fast = BoomTime.for_model(model, velocity={"roll": 100.0},
                              acceleration={"telescope": 200.0})
    x = 600.0
    ramp = x / 400.0 + 400.0 / 200.0 if x >= 400.0**2 / 200.0 else 2 * math.sqrt(x / 200.0)
    expect = max(0.4 / 0.2, 0.1 / 0.2, ramp, 1.2 / 100.0, 0.1 / 0.3, 0.4 / 0.3)
    assert fast.move_times(qa, qb)[0, 0] == pytest.approx(expect)
    with pytest.raises(FieldError, match="velocity.elbow"):
        BoomTime.for_model(model, velocity={"elbow": 1.0})
    with pytest.raises(FieldError, match="cylinder_speeds"):
        BoomTime.for_model(model, cylinder_speeds={"boom": 50.0})


def test_cylinder_driven_joints_are_timed_by_their_cylinders():
    """The pile driver declares cylinders: with a speed for the boom cylinder the boom joint
    takes |dL| / v_cyl (lengths from kinematics.cylinders), the others their joint speeds."""
    model = builtin_model("pile_driver")
    speeds = {j.name: 0.5 for j in model.joints}
    timing = BoomTime.for_model(model, velocity=speeds, cylinder_speeds={"boom": 20.0})
    qa = np.array([0.0, 0.2, -0.5, -0.5, 0.0, 0.0])
    qb = np.array([0.05, 0.9, -0.45, -0.5, 0.0, 0.0])
    L = cylinder_set(model).lengths(np.stack([qa, qb]))["boom"]
    expect = max(abs(L[1] - L[0]) / 20.0, 0.05 / 0.5, 0.05 / 0.5)
    assert timing.move_times(qa, qb)[0, 0] == pytest.approx(expect)
    assert abs(L[1] - L[0]) / 20.0 > 0.7 / 0.5  # the cylinder, not the joint, decides
    joint_only = BoomTime.for_model(model, velocity=speeds, hydraulics=False)
    assert joint_only.move_times(qa, qb)[0, 0] == pytest.approx(0.7 / 0.5)
    # two speeds: extending and retracting
    two = BoomTime.for_model(model, velocity=speeds, cylinder_speeds={"boom": (20.0, 40.0)})
    back = abs(L[1] - L[0]) / (40.0 if L[1] > L[0] else 20.0)
    assert two.move_times(qb, qa)[0, 0] == pytest.approx(max(back, 0.1))
    with pytest.raises(FieldError, match="cylinder_speeds.bucket"):
        BoomTime.for_model(model, cylinder_speeds={"bucket": 10.0})


def test_declared_cylinder_speeds_time_each_direction():
    """A model whose cylinder data gives extension and retraction speeds is timed by them
    (a move and its reverse differ); the reported path time is the directed one."""
    model = builtin_model("pile_driver")
    boom = next(c for c in model.extras["cylinders"] if c["name"] == "boom")
    if "max_extension_speed" not in boom:
        pytest.skip("this model's cylinder data gives no speeds")
    ext, ret = boom["max_extension_speed"], boom["max_retraction_speed"]
    slow = {j.name: 100.0 for j in model.joints}  # joints never the limit
    timing = BoomTime.for_model(model, velocity=slow)
    qa = np.array([0.0, 0.2, -0.5, -0.5, 0.0, 0.0])
    qb = np.array([0.0, 0.9, -0.5, -0.5, 0.0, 0.0])
    L = cylinder_set(model).lengths(np.stack([qa, qb]))["boom"]
    grow = L[1] > L[0]
    there = timing.move_times(qa, qb)[0, 0]
    back = timing.move_times(qb, qa)[0, 0]
    assert there == pytest.approx(abs(L[1] - L[0]) / (ext if grow else ret))
    assert back == pytest.approx(abs(L[1] - L[0]) / (ret if grow else ext))
    assert timing.path_time([qb, qa], qa) == pytest.approx(there + back)


def test_every_branch_puts_the_drill_on_its_hole():
    model = builtin_rig("tunnel_jumbo").arms["middle"]
    H = np.array([[9000, 0, 1500], [9000, -3000, 3000], [9000, 2500, -500.0]])
    Q = drill_branches(model, H)
    assert Q.shape == (3, 5, 7) and np.all(np.isfinite(Q))
    T = fk(model, Q.reshape(-1, 7)).reshape(3, 5, 4, 4)
    assert np.abs(T[..., :3, 3] - H[:, None]).max() < 1e-6
    assert np.abs(T[..., :3, 2] - [1.0, 0.0, 0.0]).max() < 1e-9  # perpendicular
    assert len({round(float(r), 6) for r in Q[0, :, 3]}) == 5  # five roll values
    with pytest.raises(FieldError, match=r"holes\[1\]"):
        drill_branches(model, [[9000, 0, 1500], [9000, 0, 40000]])


# ---- on a face -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def middle_arm_face():
    rig = builtin_rig("tunnel_jumbo")
    face = face_pattern()
    alloc = allocate_holes(rig, face.holes)
    park = park_configuration(rig, "middle", face.spec.face_x)
    return rig.arms["middle"], face.holes[alloc.indices["middle"]], park


@pytest.mark.slow
def test_time_order_saves_boom_time_on_a_face(middle_arm_face):
    model, H, park = middle_arm_face
    res = sequence_by_boom_time(model, H, q_start=park, seed=0)
    assert sorted(res.order.tolist()) == list(range(len(H)))
    assert res.time_s <= res.distance_time_s + 1e-9 and res.saved_s >= 0
    # the reported time is that of the configurations returned, by the test's own model
    v = np.array([DRILL_ARM_SPEEDS[j.name] for j in model.joints])
    q = np.vstack([park[None], res.q])
    assert res.time_s == pytest.approx((np.abs(np.diff(q, axis=0)) / v).max(axis=1).sum())
    T = fk(model, res.q)
    assert np.abs(T[:, :3, 3] - H[res.order]).max() < 1e-6
    path = np.vstack([fk(model, park)[None, :3, 3], H[res.order]])
    assert res.length == pytest.approx(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    again = sequence_by_boom_time(model, H, q_start=park, seed=0)
    assert np.array_equal(again.order, res.order) and again.time_s == res.time_s


@pytest.mark.slow
def test_sequence_arm_keeps_the_distance_order_by_default(middle_arm_face):
    model, H, park = middle_arm_face
    q = np.array([r.q for r in __import__("kinematics.drilling", fromlist=["drill_ik"])
                  .drill_ik(model, H)])
    start = fk(model, park)[:3, 3]
    timing = BoomTime.planned_joints(model, (0.2, 0.2, 400.0), (0.24, 0.24, 300.0))
    dist = sequence_arm(H, q, park, start, timing, seed=2)
    plain = sequence_holes(H, start, "auto", 2)
    assert np.array_equal(dist.order, plain.order)
    assert dist.extra["boom_time_s"] == dist.extra["boom_time_distance_order_s"]
    _, t = order_time(dist.order, q[:, None], park, timing)
    assert dist.extra["boom_time_s"] == pytest.approx(t)
    fast = sequence_arm(H, q, park, start, timing, cost="time", seed=2)
    assert fast.extra["boom_time_s"] <= fast.extra["boom_time_distance_order_s"] + 1e-9
    with pytest.raises(FieldError, match="cost"):
        sequence_arm(H, q, park, start, timing, cost="energy")
    with pytest.raises(FieldError, match="cost"):
        FaceOptions(cost="energy")
