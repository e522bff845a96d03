"""The whole drilling round (``planning.cycles.round``): reach of the whole hole, every hole
drilled once along its axis (by FK here), unreachable holes named with a reason, two booms on
crossing holes kept apart by waits (the same moves without the waits touch), the cycle time
against its lower bound. Distances are re-computed here with an independent closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.fk import fk, fk_frames
from kinematics.rigs import builtin_rig
from planning.collision import CollisionScene
from planning.cycles.round import REASONS, RoundOptions, hole_poses, plan_round
from planning.cycles.round_timeline import BoomTimeline, Phase, pair_clearance

RADII = np.array([300.0, 250.0, 200.0, 250.0, 250.0, 250.0, 200.0])
COLLARING_S, RETRACT_S, RATE = 3.0, 8.0, 3.0   # s, s, m/min
#: Two crossing holes between the left and right booms, one more hole each, and holes
#: no boom can drill: behind the rig, pointing away from the face, deeper than the feed,
#: and one whose toe lies inside a rock in the scene.
HOLES = {
    "cross-l": ([9000, 300, 2500], [10400, -400, 2500]),
    "cross-r": ([9000, -300, 2500], [10400, 400, 2500]),
    "side-l": ([9000, 2800, 1000], [10500, 2800, 1000]),
    "side-r": ([9000, -2800, 1000], [10500, -2800, 1000]),
    "behind": ([-1500, 0, 2000], [0, 0, 2000]),
    "backwards": ([9000, 2500, 3000], [7500, 2500, 3000]),
    "too-deep": ([9000, -2500, 3000], [16500, -2500, 3000]),
    "rock": ([9000, 3000, 3500], [10500, 3000, 3500]),
}
ROCK = {"type": "box", "id": "rock", "size": [600, 600, 600],
        "pose": [[1, 0, 0, 10400], [0, 1, 0, 3000], [0, 0, 1, 3500], [0, 0, 0, 1]]}


def options(**kw) -> RoundOptions:
    base = dict(booms=("left", "right"), penetration_rate_m_min=RATE,
                collaring_s=COLLARING_S, retract_s=RETRACT_S, scene_check_states=100,
                scene=CollisionScene.from_dicts([ROCK]), seed=1)
    base.update(kw)
    return RoundOptions(**base)


@pytest.fixture(scope="module")
def rig():
    return builtin_rig("tunnel_jumbo")


@pytest.fixture(scope="module")
def planned(rig):
    ids = list(HOLES)
    C = np.array([HOLES[i][0] for i in ids], dtype=float)
    T = np.array([HOLES[i][1] for i in ids], dtype=float)
    return plan_round(rig, C, T, ids, options())


# ---- an independent distance between capsules -------------------------------------------------
def _point_segment(P, A, B):
    """Distance of points ``P`` to segments ``A``-``B`` (broadcast ``(..., 3)``)."""
    d = B - A
    L2 = np.maximum(np.einsum("...i,...i", d, d), 1e-300)
    s = np.clip(np.einsum("...i,...i", P - A, d) / L2, 0.0, 1.0)
    return np.linalg.norm(P - (A + s[..., None] * d), axis=-1)


def _segment_distance(P0, P1, Q0, Q1):
    """Least distance of two segments: the interior stationary point of |P(s) - Q(t)|^2
    when it lies in the unit square, else the least of the four end point distances (the
    minimum of a convex function over a square is inside or on its edges)."""
    u, v, w = P1 - P0, Q1 - Q0, P0 - Q0
    a = np.einsum("...i,...i", u, u)
    b = np.einsum("...i,...i", u, v)
    c = np.einsum("...i,...i", v, v)
    d = np.einsum("...i,...i", u, w)
    e = np.einsum("...i,...i", v, w)
    det = a * c - b * b
    ok = det > 1e-9 * np.maximum(a * c, 1e-300)
    s = np.where(ok, (b * e - c * d) / np.where(ok, det, 1.0), -1.0)
    t = np.where(ok, (a * e - b * d) / np.where(ok, det, 1.0), -1.0)
    inside = ok & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    interior = np.linalg.norm((P0 + s[..., None] * u) - (Q0 + t[..., None] * v), axis=-1)
    edges = np.minimum.reduce([_point_segment(P0, Q0, Q1), _point_segment(P1, Q0, Q1),
                               _point_segment(Q0, P0, P1), _point_segment(Q1, P0, P1)])
    return np.where(inside, np.minimum(interior, edges), edges)


def _capsules(model, q):
    """Link capsules of the drilling arm: frame origins k -> k+1 (``(S, 7, 2, 3)``)."""
    P = fk_frames(model, q)[:, :, :3, 3]
    return np.stack([P[:, :-1], P[:, 1:]], axis=2)


def _clearance(rig, timelines: dict[str, BoomTimeline], dt: float = 0.01):
    """Least surface distance between two booms over the timelines sampled every ``dt``, and
    the largest motion of any capsule end point between two samples (mm)."""
    (a, ta), (b, tb) = timelines.items()
    end = max(ta.end, tb.end)
    t = np.arange(0.0, end + dt, dt)
    Ca, Cb = _capsules(rig.arms[a], ta.evaluate(t)), _capsules(rig.arms[b], tb.evaluate(t))
    step = max(np.linalg.norm(np.diff(C, axis=0), axis=-1).max() for C in (Ca, Cb))
    keep = np.linalg.norm(np.diff(fk_frames(rig.arms[a], np.zeros((1, 7)))[0, :, :3, 3],
                                  axis=0), axis=1) > 1e-6   # links of non-zero length
    best = math.inf
    for s0 in range(0, len(t), 2000):
        A, B = Ca[s0:s0 + 2000][:, keep], Cb[s0:s0 + 2000][:, keep]
        d = _segment_distance(A[:, :, None, 0], A[:, :, None, 1], B[:, None, :, 0],
                              B[:, None, :, 1])
        d = d - RADII[keep][None, :, None] - RADII[keep][None, None, :]
        best = min(best, float(d.min()))
    return best, step


def _without_waits(tl: BoomTimeline) -> BoomTimeline:
    """The same phases back to back from time 0: the round as if no boom ever waited."""
    out, t = [], 0.0
    for p in tl.phases:
        if p.kind == "wait":
            continue
        out.append(Phase(p.kind, t, p.duration, p.evaluate, p.hole, p.q_end))
        t += p.duration
    return BoomTimeline(tl.q0, out)


def test_the_independent_segment_distance_agrees_with_simple_cases():
    P0, P1 = np.array([0.0, 0, 0]), np.array([10.0, 0, 0])
    assert _segment_distance(P0, P1, np.array([5.0, -5, 3]), np.array([5.0, 5, 3])) == \
        pytest.approx(3.0)
    assert _segment_distance(P0, P1, np.array([12.0, 0, 4]), np.array([20.0, 0, 4])) == \
        pytest.approx(math.hypot(2, 4))
    assert _segment_distance(P0, P1, np.array([0.0, 1, 0]), np.array([10.0, 1, 0])) == \
        pytest.approx(1.0)


def test_the_pruned_boom_distance_is_exact_below_its_limit_and_a_bound_above():
    """Two sets of capsules moving past each other (one crossing the other, one far off):
    with ``below`` the distance is the independent closed form wherever that is under
    ``below`` and at least ``below`` elsewhere; without it, exact everywhere."""
    rng = np.random.default_rng(3)
    S, L = 203, 4                                   # not a whole number of blocks
    t = np.linspace(0.0, 1.0, S)[:, None, None, None]
    base_a = rng.uniform(-500, 500, (1, L, 2, 3))
    base_b = rng.uniform(-500, 500, (1, L, 2, 3))
    Ea = base_a + t * np.array([3000.0, 0.0, 0.0]) - np.array([1500.0, 0.0, 0.0])
    Eb = np.repeat(base_b, S, axis=0)
    Eb[:, 2:] += np.array([0.0, 8000.0, 0.0])       # two capsules far off all the time
    ra, rb = rng.uniform(50, 200, L), rng.uniform(50, 200, L)
    d = _segment_distance(Ea[:, :, None, 0], Ea[:, :, None, 1], Eb[:, None, :, 0],
                          Eb[:, None, :, 1]) - ra[None, :, None] - rb[None, None, :]
    truth = d.reshape(S, -1).min(axis=1)
    assert truth.min() < 0 < truth.max()            # they overlap at some instants only
    np.testing.assert_allclose(pair_clearance(Ea, ra, Eb, rb), truth, atol=1e-6)
    for below in (-50.0, 0.0, 300.0, float(np.median(truth)), truth.max() + 1.0):
        got = pair_clearance(Ea, ra, Eb, rb, below=below)
        under = truth < below
        np.testing.assert_allclose(got[under], truth[under], atol=1e-6)
        assert np.all(got[~under] >= below - 1e-9)
        assert np.all(got <= truth + 1e-6)           # a lower bound everywhere


# ---- reach ------------------------------------------------------------------------------------
def test_the_collar_pose_puts_the_tip_on_the_collar_along_a_tilted_hole_axis(rig):
    model = rig.arms["middle"]
    C = np.array([[9000.0, 500, 2000]])
    T = np.array([[10500.0, 300, 2300]])
    q, d7, why = hole_poses(model, C, T, 300.0)
    assert why == [None]
    F = fk(model, q[0])
    axis = (T[0] - C[0]) / np.linalg.norm(T[0] - C[0])
    assert np.linalg.norm(F[:3, 3] - C[0]) < 0.01
    assert math.degrees(math.acos(min(1.0, F[:3, 2] @ axis))) < 1e-3
    assert model.within_limits(q[0])
    # the feed reaches the toe
    assert d7[0] + np.linalg.norm(T[0] - C[0]) <= model.upper[6]


@pytest.mark.slow
def test_unreachable_holes_are_reported_by_id_with_their_reason(planned):
    got = {u["id"]: u["reason"] for u in planned.unreachable}
    assert got == {"behind": "out_of_reach", "backwards": "axis_not_alignable",
                   "too-deep": "out_of_reach", "rock": "blocked"}
    assert set(got.values()) <= set(REASONS)
    assert all(u["detail"] for u in planned.unreachable)


@pytest.mark.slow
def test_every_reachable_hole_is_drilled_once_along_its_axis(rig, planned):
    drilled = [h.id for h in planned.holes]
    assert len(drilled) == len(set(drilled))
    assert set(drilled) | {u["id"] for u in planned.unreachable} == set(HOLES)
    assert set(drilled) == {"cross-l", "cross-r", "side-l", "side-r"}
    for name, bp in planned.booms.items():
        assert set(bp.holes) == {h.id for h in planned.holes if h.boom == name}
        model = rig.arms[name]
        for p in bp.timeline.phases:
            if p.kind != "drill":
                continue
            collar, toe = (np.array(x, dtype=float) for x in HOLES[p.hole])
            axis = (toe - collar) / np.linalg.norm(toe - collar)
            t = np.linspace(p.t0, p.t1, 200)
            F = fk(model, bp.timeline.evaluate(t))
            angle = np.degrees(np.arccos(np.clip(F[:, :3, 2] @ axis, -1.0, 1.0)))
            assert angle.max() < 0.5, (p.hole, angle.max())
            tip = F[:, :3, 3]
            off_line = np.linalg.norm(np.cross(tip - collar, axis), axis=1)
            assert off_line.max() < 1.0
            assert np.linalg.norm(tip[0] - collar) < 1.0
            assert np.linalg.norm(tip[-1] - toe) < 1.0
            # at the penetration rate
            speed = np.linalg.norm(np.diff(tip, axis=0), axis=1) / np.diff(t)
            assert speed == pytest.approx(np.full(len(speed), RATE * 1000 / 60), rel=0.02)
            assert np.all(model.within_limits(bp.timeline.evaluate(t), tol=1e-6))


# ---- booms apart ------------------------------------------------------------------------------
@pytest.mark.slow
def test_crossing_holes_touch_without_the_waits_and_stay_clear_with_them(rig, planned):
    timelines = {a: bp.timeline for a, bp in planned.booms.items()}
    assert sum(bp.wait_s for bp in planned.booms.values()) > 0
    naive, _ = _clearance(rig, {a: _without_waits(tl) for a, tl in timelines.items()})
    assert naive < 0, naive   # the booms' capsules overlap
    least, step = _clearance(rig, timelines)
    assert step < 40.0   # motion between the 10 ms samples bounds what they can miss
    assert least - step > 0, (least, step)
    assert least >= options().clearance - step - 1.0
    # and the planner's own figure agrees with the independent one
    assert planned.min_boom_clearance_mm == pytest.approx(least, abs=step + 1.0)
    assert planned.max_step_mm <= 5.0
    assert planned.min_scene_clearance_mm is not None and planned.min_scene_clearance_mm > 0


@pytest.mark.slow
def test_the_cycle_time_is_at_least_the_lower_bound(planned):
    depth = {i: float(np.linalg.norm(np.subtract(HOLES[i][1], HOLES[i][0])))
             for i in HOLES}
    # retract_s is above the feed's own least time for these depths, so it is what counts
    drilling = sum(COLLARING_S + depth[h.id] / (RATE * 1000 / 60) + RETRACT_S
                   for h in planned.holes)
    assert planned.lower_bound_s == pytest.approx(drilling / 2)
    assert planned.cycle_time_s >= planned.lower_bound_s
    assert planned.ratio == pytest.approx(planned.cycle_time_s / planned.lower_bound_s)
    ends = [bp.timeline.end for bp in planned.booms.values()]
    assert planned.cycle_time_s == pytest.approx(max(ends))


@pytest.mark.slow
def test_each_boom_ends_at_its_park_pose_and_phases_follow_on(planned):
    for bp in planned.booms.values():
        tl = bp.timeline
        assert np.allclose(tl.q_final, bp.park, atol=1e-6)
        for a, b in zip(tl.phases, tl.phases[1:]):
            assert b.t0 == pytest.approx(a.t1)
        kinds = [p.kind for p in tl.phases if p.hole == bp.holes[0]]
        assert kinds[-4:] == ["collar", "collar", "drill", "retract"]


def test_bad_input_names_the_field(rig):
    from kinematics.errors import FieldError

    with pytest.raises(FieldError) as e:
        plan_round(rig, [[9000, 0, 0], [9000, 10, 0]], [[9500, 0, 0], [9500, 10, 0]],
                   ["a", "a"])
    assert "holes[1].id" in str(e.value)
    with pytest.raises(FieldError) as e:
        plan_round(rig, [[9000, 0, 0]], [[9000, 0, 0]], ["a"])
    assert "holes[0].toe" in str(e.value)
    with pytest.raises(FieldError) as e:
        RoundOptions(penetration_rate_m_min=0)
    assert "penetration_rate_m_min" in str(e.value)
