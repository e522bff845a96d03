"""Exact segment–obstacle distances and scene validation (planning.paths.scene)."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from kinematics.errors import FieldError
from planning.geometry.obstacles import obstacle_from_dict
from planning.geometry.segments import (
    segment_box_distance,
    segment_point_distance,
    segment_segment_distance,
)
from planning.paths import scene as scene_module
from planning.paths.broadphase import BlockedGrid, BroadPhase
from planning.paths.scene import Scene

RNG_SEED = 20240601


def brute_min(f, n: int = 1001) -> float:
    """Minimum of a 1-D function on [0, 1]: a grid, then a bounded polish around the best."""
    s = np.linspace(0, 1, n)
    v = np.array([f(x) for x in s])
    k = int(np.argmin(v))
    r = minimize_scalar(f, bounds=(s[max(k - 1, 0)], s[min(k + 1, n - 1)]), method="bounded",
                        options={"xatol": 1e-13})
    return min(float(r.fun), float(v[k]))


def box_sdf(p, lo, hi) -> float:
    q = np.maximum(lo - p, p - hi)
    out = np.linalg.norm(np.maximum(q, 0))
    return out if out > 0 else float(q.max())


@pytest.fixture
def segments():
    rng = np.random.default_rng(RNG_SEED)
    P0 = rng.uniform(-3, 3, (60, 3))
    P1 = rng.uniform(-3, 3, (60, 3))
    P1[:10] = P0[:10]  # zero-length segments
    P1[10:20, 1:] = P0[10:20, 1:]  # axis-parallel segments
    return P0, P1


# ---- kernels against brute force ---------------------------------------------------------
def test_segment_point_matches_brute_force(segments):
    P0, P1 = segments
    c = np.array([0.3, -0.2, 0.5])
    d, t = segment_point_distance(P0, P1, c)
    for i in range(len(P0)):
        ref = brute_min(lambda s, i=i: np.linalg.norm(P0[i] + s * (P1[i] - P0[i]) - c))
        assert d[i] == pytest.approx(ref, abs=1e-9)
        assert np.linalg.norm(P0[i] + t[i] * (P1[i] - P0[i]) - c) == pytest.approx(d[i])


def test_segment_box_is_exact_inside_and_outside(segments):
    P0, P1 = segments
    lo, hi = np.array([-1.0, -0.5, -0.7]), np.array([0.8, 1.2, 0.4])
    d, t = segment_box_distance(P0, P1, lo, hi)
    assert (d < 0).sum() > 5 and (d > 0).sum() > 5  # both regimes are exercised
    for i in range(len(P0)):
        f = lambda s, i=i: box_sdf(P0[i] + s * (P1[i] - P0[i]), lo, hi)  # noqa: E731
        ref = brute_min(f)  # a numeric search: never below the exact minimum
        assert ref - 1e-6 <= d[i] <= ref + 1e-12
        assert f(t[i]) == pytest.approx(d[i], abs=1e-12)  # t is where it happens


def test_segment_segment_matches_brute_force(segments):
    P0, P1 = segments
    Q0, Q1 = np.array([0.1, 0.2, -1.0]), np.array([0.5, -0.3, 2.0])
    d, s, t = segment_segment_distance(P0, P1, Q0, Q1)
    grid = np.linspace(0, 1, 401)
    for i in range(0, len(P0), 3):
        p = P0[i] + grid[:, None] * (P1[i] - P0[i])
        q = Q0 + grid[:, None] * (Q1 - Q0)
        ref = np.linalg.norm(p[:, None] - q[None], axis=2).min()
        assert d[i] <= ref + 1e-12 and d[i] == pytest.approx(ref, abs=2e-2)
        cp = P0[i] + s[i] * (P1[i] - P0[i])
        cq = Q0 + t[i] * (Q1 - Q0)
        assert np.linalg.norm(cp - cq) == pytest.approx(d[i])


@pytest.mark.parametrize("q0, q1, expected", [
    ([0.5, 1, 0], [2, 1, 0], 1.0),  # parallel, overlapping
    ([5, 1, 0], [6, 1, 0], math.hypot(4, 1)),  # parallel, apart
    ([5, 1, 0], [5, 1, 0], math.hypot(4, 1)),  # a point
    ([0.5, -1, 0], [0.5, 1, 0], 0.0),  # crossing
])
def test_segment_segment_edge_cases(q0, q1, expected):
    d, _, _ = segment_segment_distance(np.zeros(3), np.array([1.0, 0, 0]), np.array(q0, float),
                                       np.array(q1, float))
    assert float(d) == pytest.approx(expected, abs=1e-12)


# ---- the scene's clearance ---------------------------------------------------------------
@pytest.fixture
def scene():
    return Scene.create([[-10] * 3, [10] * 3], [
        {"center": [0, 0, 0], "radius": 1},
        {"type": "box", "lower": [2, 2, 2], "upper": [3, 3, 3]},
        {"type": "capsule", "a": [-3, -3, -3], "b": [-3, 3, -3], "radius": 0.5},
    ], safety_margin=0.1)


def test_tangent_segment_touches_sphere_exactly(scene):
    c = scene.segment_clearance(np.array([[-5.0, 1.0, 0]]), np.array([[5.0, 1.0, 0]]))
    assert c[0, 0] == pytest.approx(0.0, abs=1e-15)
    assert scene.path_is_clear([[-5, 1, 0], [5, 1, 0]], margin=0.0)  # touching is clear
    assert not scene.path_is_clear([[-5, 1, 0], [5, 1, 0]])  # but not with the margin


def test_grazing_by_less_than_the_margin_fails(scene):
    y = 1.0 + 0.1 - 1e-9  # 1e-9 mm short of the margin
    assert not scene.path_is_clear([[-5, y, 0], [5, y, 0]])
    assert scene.path_is_clear([[-5, y + 2e-9, 0], [5, y + 2e-9, 0]])


def test_inside_is_negative_penetration_depth(scene):
    c = scene.point_clearance([[0, 0, 0.25], [2.5, 2.5, 2.9], [-3, 0, -3]])
    assert c[0, 0] == pytest.approx(-0.75)
    assert c[1, 1] == pytest.approx(-0.1)
    assert c[2, 2] == pytest.approx(-0.5)
    # A segment through the sphere's centre is as deep as the radius.
    assert scene.segment_clearance([[-5, 0, 0]], [[5, 0, 0]])[0, 0] == pytest.approx(-1.0)


def test_segment_passing_a_box_edge(scene):
    # p(s) = (1.5 - s, 4 - s, 2.5) passes the box edge x = 2, y = 3 closest at s = 1/4.
    a, b = np.array([[1.5, 4.0, 2.5]]), np.array([[0.5, 3.0, 2.5]])
    assert scene.segment_clearance(a, b)[0, 1] == pytest.approx(0.75 * math.sqrt(2), rel=1e-14)


def test_zero_length_segment_is_a_point(scene):
    p = np.array([[0.0, 0.0, 2.0]])
    np.testing.assert_allclose(scene.segment_clearance(p, p), scene.point_clearance(p))
    assert scene.point_clearance(p)[0, 0] == pytest.approx(1.0)


def test_vectorised_equals_one_by_one(scene):
    rng = np.random.default_rng(RNG_SEED)
    A, B = rng.uniform(-10, 10, (300, 3)), rng.uniform(-10, 10, (300, 3))
    all_at_once = scene.segment_clearance(A, B)
    one_by_one = np.vstack([scene.segment_clearance(A[i:i + 1], B[i:i + 1])
                            for i in range(len(A))])
    np.testing.assert_array_equal(all_at_once, one_by_one)


def test_details_give_the_clearance_gradient(scene):
    rng = np.random.default_rng(RNG_SEED)
    A, B = rng.uniform(-10, 10, (40, 3)), rng.uniform(-10, 10, (40, 3))
    c, t, n = scene.segment_clearance(A, B, details=True)
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        g0 = (scene.segment_clearance(A + e, B) - scene.segment_clearance(A - e, B)) / (2 * h)
        outside = c > 1e-3  # inside a box the clearance has kinks
        np.testing.assert_allclose(g0[outside], ((1 - t) * n[..., k])[outside], atol=1e-5)


def test_surface_points_lie_at_the_offset(scene):
    for i in range(3):
        S = scene.surface_points(i, 300, 0.2)
        c = scene.point_clearance(S)[:, i]
        assert c.min() >= 0.2 - 1e-12
        if i != 1:  # boxes use the sharp grown box: corners are farther
            np.testing.assert_allclose(c, 0.2, atol=1e-12)


# ---- validation --------------------------------------------------------------------------
@pytest.mark.parametrize("obstacles, loc, message", [
    ([{"center": [0, 0, 0], "radius": 1}, {"center": [1, 1, 1], "radius": 0}],
     ("obstacles", 1, "radius"), r"obstacles\[1\]\.radius must be positive"),
    ([{"center": [0, 0, math.nan], "radius": 1}], ("obstacles", 0, "center"),
     r"obstacles\[0\]\.center has a NaN"),
    ([{"center": [0, 0], "radius": 1}], ("obstacles", 0, "center"),
     r"obstacles\[0\]\.center must be 3 numbers"),
    ([{"type": "box", "lower": [0, 0, 0], "upper": [1, 0, 1]}], ("obstacles", 0, "upper"),
     r"obstacles\[0\]\.upper must exceed obstacles\[0\]\.lower"),
    ([{"type": "capsule", "a": [0, 0, 0], "radius": 1}], ("obstacles", 0, "b"),
     r"obstacles\[0\]\.b is required"),
    ([{"type": "cone", "center": [0, 0, 0]}], ("obstacles", 0, "type"),
     r"obstacles\[0\]\.type must be"),
    ([{"center": [0, 0, 0], "radius": 1, "lower": [0, 0, 0]}], ("obstacles", 0, "lower"),
     r"obstacles\[0\]\.lower is not a field of a sphere"),
    ([{"center": [0, 0, 0], "radius": 1}, "ball"], ("obstacles", 1),
     r"obstacles\[1\] must be an object"),
])
def test_invalid_obstacles_name_the_field(obstacles, loc, message):
    with pytest.raises(FieldError, match=message) as err:
        Scene.create([[-5] * 3, [5] * 3], obstacles)
    assert err.value.loc == loc


def test_an_obstacle_alone_names_its_own_fields():
    with pytest.raises(FieldError) as err:
        obstacle_from_dict({"type": "box", "lower": [0, 0, 0]})
    assert err.value.loc == ("upper",) and err.value.message == "upper is required for a box"


def test_invalid_bounds_and_margin():
    with pytest.raises(FieldError, match=r"bounds\[1\] must exceed") as err:
        Scene.create([[0, 0, 0], [1, 0, 1]])
    assert err.value.loc == ("bounds", 1)
    with pytest.raises(FieldError, match="bounds must be") as err:
        Scene.create([[0, 0, 0]])
    assert err.value.loc == ("bounds",)
    with pytest.raises(FieldError, match="safety_margin must be non-negative") as err:
        Scene.create([[0] * 3, [1] * 3], safety_margin=-1)
    assert err.value.loc == ("safety_margin",)
    with pytest.raises(FieldError, match="safety_margin must be finite"):
        Scene.create([[0] * 3, [1] * 3], safety_margin=math.nan)
    with pytest.raises(FieldError) as err:
        Scene.from_dict({"bounds": [[0] * 3, [1] * 3], "obstacles": {"center": [0, 0, 0]}})
    assert err.value.loc == ("obstacles",)


@pytest.mark.parametrize("point, name, loc, message", [
    ([0, 0, 0.5], "start", ("start",), r"start is inside obstacles\[0\]"),
    ([0, 0, 11], "goal", ("goal",), "goal is outside bounds"),
    ([0, 0, 1.05], "start", ("start",), r"start is within safety_margin .* obstacles\[0\]"),
    ([0, math.nan, 5], "goal", ("goal",), "goal has a NaN"),
    ([0, 0, 0.5], "tasks[3].start", ("tasks", 3, "start"), r"tasks\[3\]\.start is inside"),
])
def test_endpoints_are_checked(scene, point, name, loc, message):
    with pytest.raises(FieldError, match=message) as err:
        scene.check_endpoint(point, name)
    assert err.value.loc == loc


def test_a_clear_endpoint_passes(scene):
    np.testing.assert_array_equal(scene.check_endpoint([5, 5, 5], "goal"), [5, 5, 5])


def test_field_errors_pickle_with_their_loc(scene):
    """What a worker process raises reaches the service whole: class, loc and message."""
    with pytest.raises(FieldError) as err:
        scene.check_endpoint([0, 0, 0.5], "start")
    again = pickle.loads(pickle.dumps(err.value))
    assert type(again) is FieldError and isinstance(again, ValueError)
    assert again.loc == ("start",) and again.message == err.value.message
    assert str(again) == str(err.value) == "start is inside obstacles[0]"
    one = FieldError("durations", "durations: every duration must be positive")
    assert one.loc == ("durations",) and pickle.loads(pickle.dumps(one)).loc == ("durations",)


def test_round_trip_through_dict(scene):
    again = Scene.from_dict(scene.to_dict())
    X = np.random.default_rng(0).uniform(-10, 10, (50, 3))
    np.testing.assert_array_equal(again.point_clearance(X), scene.point_clearance(X))
    box = Scene.create([[-5] * 3, [5] * 3], [{"type": "box", "center": [0, 0, 0],
                                              "size": [2, 4, 6]}])
    np.testing.assert_array_equal(box.obstacles[0].lower, [-1, -2, -3])


# ---- the broad phase -------------------------------------------------------------------

def random_scene(seed: int, n: int, margin: float = 0.3) -> Scene:
    """``n`` obstacles of all three kinds, overlapping, in a 20 mm cube (enough of them that
    the scene's checks go through the broad phase)."""
    rng = np.random.default_rng(seed)
    obstacles = []
    for i in range(n):
        c = rng.uniform(-10, 10, 3)
        kind = i % 3
        if kind == 0:
            obstacles.append({"center": c.tolist(), "radius": float(rng.uniform(0.1, 2.5))})
        elif kind == 1:
            obstacles.append({"type": "box", "center": c.tolist(),
                              "size": rng.uniform(0.1, 4.0, 3).tolist()})
        else:
            obstacles.append({"type": "capsule", "a": c.tolist(),
                              "b": (c + rng.uniform(-4, 4, 3)).tolist(),
                              "radius": float(rng.uniform(0.05, 1.0))})
    return Scene.create([[-12] * 3, [12] * 3], obstacles, margin)


def random_segments(seed: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Short, long and zero-length segments, some leaving the bounds."""
    rng = np.random.default_rng(seed)
    P0 = rng.uniform(-14, 14, (m, 3))
    P1 = P0 + rng.normal(size=(m, 3)) * rng.choice([0.0, 0.5, 4.0, 15.0], size=(m, 1))
    return P0, P1


@pytest.mark.slow
@settings(derandomize=True, database=None, max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(scene_module.BROAD_PHASE_MIN_OBSTACLES, 90),
       margin=st.floats(0.0, 1.5))
def test_broad_phase_checks_equal_brute_force(seed, n, margin):
    scene = random_scene(seed, n, margin)
    assert scene.broad_phase is not None
    P0, P1 = random_segments(seed + 1, 300)
    dense = scene.segment_clearance(P0, P1)  # every pair, computed directly
    np.testing.assert_allclose(scene.min_segment_clearance(P0, P1), dense.min(axis=1),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(scene.segments_clear(P0, P1), dense.min(axis=1) >= margin)
    reach = margin + 0.5
    seg, obs, c = scene.near_pairs(P0, P1, reach)
    want_seg, want_obs = np.nonzero(dense <= reach)
    np.testing.assert_array_equal(seg, want_seg)
    np.testing.assert_array_equal(obs, want_obs)
    np.testing.assert_allclose(c, dense[seg, obs], rtol=0, atol=1e-12)
    np.testing.assert_allclose(scene.pair_clearance(P0[seg], P1[seg], obs), c, atol=1e-12)


@settings(derandomize=True, database=None, max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31), reach=st.floats(-1.0, 3.0))
def test_broad_phase_pairs_hold_every_near_pair(seed, reach):
    """The candidates are a superset of the pairs within reach, whatever the reach."""
    scene = random_scene(seed, 40)
    bp = BroadPhase(*scene.bounding_spheres(), *scene.bounding_boxes())
    P0, P1 = random_segments(seed + 2, 200)
    seg, obs = bp.pairs(P0, P1, reach)
    found = set(zip(seg.tolist(), obs.tolist()))
    dense = scene.segment_clearance(P0, P1)
    need = set(zip(*(x.tolist() for x in np.nonzero(dense <= reach))))
    assert need <= found
    assert np.all(bp.lower_bounds(P0, P1, seg, obs) <= dense[seg, obs] + 1e-9)


@settings(derandomize=True, database=None, max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31), margin=st.floats(0.0, 1.0))
def test_blocked_grid_rejects_only_blocked_segments(seed, margin):
    scene = random_scene(seed, 45, margin)
    rng = np.random.default_rng(seed)
    axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # a turned frame (rows), centred at 0
    grid = BlockedGrid(scene, -15.0 * axes.sum(axis=0), axes, [30, 30, 30], margin, 40_000)
    P0, P1 = random_segments(seed + 3, 400)
    hit = grid.hits(P0, P1)
    assert hit.any()  # the test exercises rejections
    assert np.all(scene.min_segment_clearance(P0[hit], P1[hit]) < margin)


def test_chunked_clearance_equals_one_batch(scene, monkeypatch):
    rng = np.random.default_rng(RNG_SEED)
    A, B = rng.uniform(-10, 10, (200, 3)), rng.uniform(-10, 10, (200, 3))
    whole, t_whole, n_whole = scene.segment_clearance(A, B, details=True)
    monkeypatch.setattr(scene_module, "CHUNK_BYTES", 5000)  # a handful of rows per chunk
    assert scene._dense_rows() < 10
    part, t_part, n_part = scene.segment_clearance(A, B, details=True)
    np.testing.assert_array_equal(part, whole)
    np.testing.assert_array_equal(t_part, t_whole)
    np.testing.assert_array_equal(n_part, n_whole)


def test_segments_clear_without_obstacles_and_points():
    empty = Scene.create([[0] * 3, [1] * 3])
    assert empty.segments_clear(np.zeros((3, 3)), np.ones((3, 3))).all()
    assert np.isinf(empty.min_segment_clearance(np.zeros((2, 3)), np.ones((2, 3)))).all()
    scene = random_scene(5, 30)
    X = np.random.default_rng(0).uniform(-12, 12, (500, 3))
    np.testing.assert_allclose(scene.pair_clearance(X, X, np.arange(500) % 30),
                               scene.point_clearance(X)[np.arange(500), np.arange(500) % 30],
                               atol=1e-12)
