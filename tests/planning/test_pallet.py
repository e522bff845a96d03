"""The palletizing cycle (``planning.cycles.pallet``): patterns worked out by hand, boxes that
do not fit reported, and a small pallet planned for the GLT palletizer whose placed poses,
carried-box tilt and clearance from the boxes already placed are re-checked here with FK
and python-fcl, independently of the planner's own checker."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.library import builtin_model
from planning.cycles.pallet import Box, Pallet, pallet_pattern, plan_pallet

EUR = (1200.0, 800.0, 144.0)


def _yaws(places) -> list[float]:
    return [math.remainder(p.yaw, math.pi) for p in places]


# ---- patterns ------------------------------------------------------------------------------
def test_column_is_the_same_grid_on_every_layer():
    # 400 x 300 on 1200 x 800 without gaps: turned (300 along the 1200) fits 4 x 2 = 8,
    # along (400 along the 1200) 3 x 2 = 6: the column takes the 8.
    pat = pallet_pattern(Pallet(EUR), Box((400, 300, 250)), "column", layers=2, gap=0.0)
    assert pat.per_layer == [8, 8] and not pat.rejected
    for k in (0, 1):
        layer = [p for p in pat.places if p.layer == k]
        xy = sorted((round(p.position[0], 6), round(p.position[1], 6)) for p in layer)
        assert xy == sorted((x, y) for x in (-450.0, -150.0, 150.0, 450.0)
                            for y in (-200.0, 200.0))
        assert all(p.position[2] == pytest.approx(144 + 250 * k + 125) for p in layer)
        assert all(abs(abs(y) - math.pi / 2) < 1e-9 for y in _yaws(layer))


def test_interlocked_alternates_its_orientation_layer_by_layer():
    # 600 x 400: along fits 2 x 2 = 4, turned 400 along the 1200 and 600 along the 800: 3.
    pat = pallet_pattern(Pallet(EUR), Box((600, 400, 300)), "interlocked", layers=3, gap=0.0)
    assert pat.per_layer == [4, 3, 4]
    for k, want in ((0, 0.0), (1, math.pi / 2), (2, 0.0)):
        yaws = _yaws([p for p in pat.places if p.layer == k])
        assert all(abs(abs(y) - want) < 1e-9 for y in yaws), (k, yaws)
    turned = sorted(round(p.position[0], 6) for p in pat.places if p.layer == 1)
    assert turned == [-400.0, 0.0, 400.0]
    # The column keeps one orientation throughout.
    col = pallet_pattern(Pallet(EUR), Box((600, 400, 300)), "column", layers=3, gap=0.0)
    assert col.per_layer == [4, 4, 4] and len(set(np.round(_yaws(col.places), 9))) == 1


def test_boxes_that_do_not_fit_are_reported_with_why_not_placed():
    pallet = Pallet(EUR, overhang=10.0, max_height=600.0)
    box = Box((400, 300, 250))
    pat = pallet_pattern(pallet, box, [
        [0, -200, 269, 0.0],            # fits
        [0, 200, 269, math.pi],         # fits beside it
        [0, 0, 269, 0.0],               # overlaps both
        [700, 0, 269, 0.0],             # 300 mm past the end of the pallet
        [0, -200, 519, 0.0],            # second layer: fits (top 500 <= 600)
        [0, -200, 769, 0.0],            # third layer: top 750 over the 600 limit
    ])
    assert [p.index for p in pat.places] == [0, 1, 4]
    reasons = {r.index: r.reason for r in pat.rejected}
    assert set(reasons) == {2, 3, 5}
    assert reasons[2].startswith("overlaps box 0")
    assert "off the pallet" in reasons[3] and "300.0 mm past" in reasons[3]
    assert "stack height" in reasons[5]
    # More boxes than the pattern holds: the rest reported as beyond capacity.
    full = pallet_pattern(Pallet(EUR), Box((600, 400, 300)), "column", layers=1, count=6,
                          gap=0.0)
    assert len(full.places) == 4 and [r.index for r in full.rejected] == [4, 5]
    assert all("full" in r.reason for r in full.rejected)
    # A box larger than the pallet: nothing placed, the reason says so.
    big = pallet_pattern(Pallet(EUR), Box((1300, 900, 200)), "column", count=2)
    assert not big.places and len(big.rejected) == 2
    assert "does not fit" in big.rejected[0].reason
    # The stack height limit cuts whole layers of a pattern.
    low = pallet_pattern(Pallet(EUR, max_height=500.0), box, "column", layers=3, gap=0.0)
    assert low.per_layer == [8, 8, 0] and len(low.rejected) == 8


def test_bad_input_names_the_field():
    with pytest.raises(FieldError) as e:
        pallet_pattern(Pallet(EUR), Box((400, 300, 250)), "pinwheel")
    assert e.value.loc == ("pattern",)
    with pytest.raises(FieldError) as e:
        Box((400, -1, 250))
    assert e.value.loc == ("box", "size")
    with pytest.raises(FieldError) as e:
        pallet_pattern(Pallet(EUR), Box((40, 40, 10)), "column", layers=100)
    assert e.value.loc == ("count",)   # 30 x 20 per layer: past 2,000 boxes


# ---- planning ------------------------------------------------------------------------------
#: The GLT cell: the pallet 850 mm in front, turned 90°; the pick on the floor to the right,
#: so a box lifted 150 mm there is lower than a box already on the pallet.
PALLET_POSE = np.array([[0.0, -1, 0, 850], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
BOX = (400.0, 300.0, 250.0)
PICK = np.array([[1.0, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 125], [0, 0, 0, 1]])
PLACES = [[850.0, -400.0, 269.0, 0.0],          # the side of the pick
          [850.0, 400.0, 269.0, math.pi / 2],   # the far side: past box 0
          [2000.0, 0.0, 269.0, 0.0]]            # off the pallet
GRIP, CLEAR, TILT = 65.0, 5.0, 0.05


@pytest.fixture(scope="module")
def planned(motion_kernels):
    model = builtin_model("glt_palletizer")
    result = plan_pallet(model, PICK, Box(BOX), Pallet(EUR, PALLET_POSE), PLACES,
                         approach_mm=150.0, retreat_mm=150.0, tilt_tolerance=TILT,
                         grip_offset_mm=GRIP, clearance_mm=CLEAR, time_limit=10.0)
    return model, result


def _grasp() -> np.ndarray:
    """T_tool_box written out here: the box's top face GRIP below the tool point along the
    tool's z (pointing down), the box turned half a turn about x."""
    G = np.diag([1.0, -1.0, -1.0, 1.0])
    G[2, 3] = GRIP + BOX[2] / 2
    return G


def _dense(path: np.ndarray, step: float = 0.005) -> np.ndarray:
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * np.linspace(0, 1, n + 1)[1:, None])
    return np.concatenate(out)


def _box_pose(x, y, z, yaw) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                 [0, 0, 1]]
    T[:3, 3] = (x, y, z)
    return T


@pytest.mark.slow
def test_every_box_that_fits_is_placed_and_the_other_reported(planned):
    _, result = planned
    assert [b.status for b in result.boxes] == ["placed", "placed", "not_fitting"]
    off = result.boxes[2]
    assert "off the pallet" in off.reason and off.q_place is None and off.carry is None
    assert result.placed == 2 and result.pallet_s > 0
    assert result.boxes_per_hour == pytest.approx(3600 * 2 / result.pallet_s)
    for b in result.boxes[:2]:
        assert b.cycle_s == pytest.approx(b.carry_s + b.return_s) and b.carry_s > 1.0
        assert b.carry.trajectory.duration == pytest.approx(b.carry_s)


@pytest.mark.slow
def test_each_placed_box_rests_where_it_was_asked_to(planned):
    model, result = planned
    G = _grasp()
    for b, (x, y, z, yaw) in zip(result.boxes[:2], PLACES):
        held = fk(model, b.q_place) @ G                 # the box where it is let go
        want = _box_pose(x, y, z + CLEAR, yaw)
        assert np.linalg.norm(held[:3, 3] - want[:3, 3]) < 0.5
        assert np.abs(held[:3, :3] - want[:3, :3]).max() < 1e-3
        # The configuration at the place is the carry's last state.
        assert np.array_equal(b.q_place, b.carry.path[-1])


@pytest.mark.slow
def test_the_carried_box_stays_level_within_the_tolerance(planned):
    model, result = planned
    for b in result.boxes[:2]:
        Q = _dense(b.carry.path)
        T = fk(model, Q) @ _grasp()
        tilt = np.arccos(np.clip(T[:, 2, 2], -1.0, 1.0))   # box z from the world's z
        assert tilt.max() <= TILT + 1e-4, tilt.max()
    yaw = [math.atan2(T[1, 0], T[0, 0]) for T in fk(model, result.boxes[1].carry.path[[0, -1]])]
    assert abs(abs(math.remainder(yaw[1] - yaw[0], math.pi)) - math.pi / 2) < 1e-3


def _fcl_box(size, T):
    import fcl

    return fcl.CollisionObject(fcl.Box(*size), fcl.Transform(T[:3, :3], T[:3, 3]))


def _distance(a, b) -> float:
    import fcl

    return fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())


def _robot_and_load(model, q) -> list:
    """python-fcl capsules of the GLT's links (60 mm, between consecutive frames, as its
    collision model wraps them; the zero-length ones left out) and the carried box."""
    import fcl

    F = fk_frames(model, q)
    out = []
    for k in range(model.dof):
        a, b = F[k, :3, 3], F[k + 1, :3, 3]
        L = float(np.linalg.norm(b - a))
        if k == 0 or L < 1e-6:
            continue   # link0 holds no collision shape (the base turns in place)
        z = (b - a) / L
        x = np.cross(z, [1, 0, 0]) if abs(z[0]) < 0.9 else np.cross(z, [0, 1, 0])
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        out.append(fcl.CollisionObject(fcl.Capsule(60.0, L),
                                       fcl.Transform(R, (a + b) / 2)))
    return out, F[-1] @ _grasp()


@pytest.mark.slow
def test_a_later_box_goes_around_the_box_placed_before_it(planned):
    model, result = planned
    first = _fcl_box(BOX, _box_pose(*PLACES[0]))
    second = _fcl_box(BOX, _box_pose(*PLACES[1]))
    nearest = math.inf
    # Box 1's carry (the box held), and its return (empty), past box 0 and box 1 resting.
    for path, carrying, placed in ((result.boxes[1].carry.path, True, [first]),
                                   (result.boxes[1].back.path, False, [first, second]),
                                   (result.boxes[0].back.path, False, [first])):
        for q in _dense(path, 0.01):
            links, T_box = _robot_and_load(model, q)
            bodies = links + ([_fcl_box(BOX, T_box)] if carrying else [])
            for body in bodies:
                for obstacle in placed:
                    d = _distance(body, obstacle)
                    nearest = min(nearest, d)
                    assert d > 0.0
    assert nearest < 400.0   # it did pass near the boxes placed
    # The straight joint motion from above the pick to above the place would have carried
    # box 1 through box 0: the planner went around it.
    carry = result.boxes[1].carry
    lift_end, move_end = carry.steps[1].last, carry.steps[2].last
    straight = np.linspace(carry.path[lift_end], carry.path[move_end], 200)
    hits = [_distance(_fcl_box(BOX, fk(model, q) @ _grasp()), first) <= 0 for q in straight]
    assert any(hits)


@pytest.mark.slow
def test_a_margin_wider_than_the_release_height_stops_the_box_short(motion_kernels):
    """The box is let go 5 mm above the pallet: with 8 mm of margin the planner may not
    bring it there, and says where it stopped; with 3 mm it places it."""
    model = builtin_model("glt_palletizer")
    pallet = Pallet(EUR, PALLET_POSE)
    outcomes = {}
    for margin in (8.0, 3.0):
        res = plan_pallet(model, PICK, Box(BOX), pallet, PLACES[:1], clearance_mm=CLEAR,
                          grip_offset_mm=GRIP, margin_mm=margin, time_limit=10.0)
        outcomes[margin] = res.boxes[0]
    stopped = outcomes[8.0]
    assert stopped.status == "collision" and "pallet" in stopped.reason
    assert stopped.q_place is None and not stopped.placed
    assert outcomes[3.0].placed
