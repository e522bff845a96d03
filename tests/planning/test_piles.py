"""Pile plans (``planning.cycles.piles``): the plan's rows, the set-up grid, reach with the
mast along the pile axis (checked by FK here), the exact cover against a brute-force
minimum, and a whole plan with an out-of-reach pile and an obstacle."""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.collision import CollisionScene
from planning.cycles.piles import (
    cover_setups,
    parse_plan,
    plan_piles,
    reach_table,
    setup_grid,
)

H = 500.0   # the arm's base above the ground at a set-up (mm)
MAST = np.array([0.0, 1.0, 0.0])   # the mast: the tool's y axis


@pytest.fixture(scope="module")
def model():
    return builtin_model("pile_driver")


def pile_at(model, q, setup=(0.0, 0.0, 0.0), pid="R") -> dict:
    """A plan row whose pile the arm at ``q`` holds exactly from ``setup``: head = tool
    point, axis = the mast's direction (both by FK, in the site frame)."""
    x, y, h = setup
    T = fk(model, np.asarray(q, dtype=float))
    c, s = math.cos(h), math.sin(h)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    d = R @ T[:3, :3] @ MAST
    p = R @ T[:3, 3] + np.array([x, y, H])
    return {"id": pid, "x": p[0], "y": p[1], "z": p[2],
            "inclination": math.acos(-d[2]), "azimuth": math.atan2(d[1], d[0])}


def fk_errors(model, q, setup, row) -> tuple[float, float]:
    """Mast angle (rad) and position error (mm) of ``q`` at ``setup`` for plan ``row``,
    by FK and the row's own numbers (not the library's conventions)."""
    x, y, h = setup
    T = fk(model, np.asarray(q, dtype=float))
    c, s = math.cos(h), math.sin(h)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    mast = R @ T[:3, :3] @ MAST
    tip = R @ T[:3, 3] + np.array([x, y, H])
    i, a = row.get("inclination", 0.0), row.get("azimuth", 0.0)
    axis = np.array([math.sin(i) * math.cos(a), math.sin(i) * math.sin(a), -math.cos(i)])
    angle = math.acos(min(1.0, float(mast @ axis)))
    return angle, float(np.linalg.norm(tip - [row["x"], row["y"], row["z"]]))


# ---- the plan ---------------------------------------------------------------------------
def test_a_rake_reads_as_one_horizontal_per_n_vertical():
    plan = parse_plan([{"id": "a", "x": 0, "y": 0, "z": 0, "rake": "1:4", "azimuth": 0.0},
                       {"id": "b", "x": 1, "y": 0, "z": 0, "rake": 10, "azimuth": math.pi / 2},
                       {"id": "c", "x": 2, "y": 0, "z": 0}])
    assert plan.inclination[0] == pytest.approx(math.atan(0.25))
    assert plan.inclination[1] == pytest.approx(math.atan(0.1))
    # The toe of "a" leans towards +x by 1 per 4 down; "b" towards +y; "c" is vertical.
    np.testing.assert_allclose(plan.axes[0], np.array([1.0, 0, -4.0]) / math.sqrt(17))
    np.testing.assert_allclose(plan.axes[1], np.array([0, 1.0, -10.0]) / math.sqrt(101),
                               atol=1e-15)
    np.testing.assert_allclose(plan.axes[2], [0, 0, -1.0])
    assert plan.tol_position[2] == 50.0 and plan.tol_angle[2] == 0.02


@pytest.mark.parametrize("rows, loc", [
    ([{"id": "a", "x": 0, "y": 0, "z": 0}, {"id": "b", "x": "east", "y": 0, "z": 0}],
     ("plan", 1, "x")),
    ([{"id": "a", "x": 0, "y": 0}], ("plan", 0, "z")),
    ([{"id": "a", "x": 0, "y": 0, "z": 0, "rake": "2:5"}], ("plan", 0, "rake")),
    ([{"id": "a", "x": 0, "y": 0, "z": 0, "rake": "1:5", "inclination": 0.1}],
     ("plan", 0, "rake")),
    ([{"id": "a", "x": 0, "y": 0, "z": 0}, {"id": "a", "x": 1, "y": 0, "z": 0}],
     ("plan", 1, "id")),
    ([{"id": "a", "x": 0, "y": 0, "z": 0, "tol_angle": -1}], ("plan", 0, "tol_angle")),
    ([{"id": "a", "x": 0, "y": 0, "z": 0, "depth": 3}], ("plan", 0, "depth")),
])
def test_a_malformed_row_names_its_row_and_column(rows, loc):
    with pytest.raises(FieldError) as err:
        parse_plan(rows)
    assert err.value.loc == loc


def test_csv_rows_count_from_the_first_data_row():
    text = "id,x,y,z,rake,azimuth\nP1,0,0,0,1:6,0.5\nP2,10,0,0,,\nP3,20,zero,0,,\n"
    with pytest.raises(FieldError) as err:
        parse_plan(text, loc=("plan_csv",))
    assert err.value.loc == ("plan_csv", 2, "y")
    plan = parse_plan(text.replace("zero", "0"))
    assert plan.ids == ("P1", "P2", "P3") and plan.inclination[1] == 0.0


def test_setup_grid_keeps_the_points_inside_the_polygon():
    L_shape = [[0, 0], [4000, 0], [4000, 2000], [2000, 2000], [2000, 4000], [0, 4000]]
    G = setup_grid(L_shape, 1000.0, headings=(0.0, 1.0))
    xy = {(x, y) for x, y, _ in G}
    assert (500.0, 500.0) in xy and (3500.0, 1500.0) in xy and (500.0, 3500.0) in xy
    assert (3500.0, 3500.0) not in xy and (2500.0, 2500.0) not in xy
    assert len(G) == 2 * 12 and set(G[:, 2]) == {0.0, 1.0}


# ---- reach -------------------------------------------------------------------------------
def test_raked_piles_are_reached_with_the_mast_within_tolerance(model):
    setup = (1000.0, -500.0, 0.4)
    rows = [pile_at(model, q, setup, f"R{k}") for k, q in enumerate([
        [0.3, 0.4, -0.7, -0.6, 0.15, -1.0],     # closed form
        [1.0, 0.25, -0.85, -0.75, 0.12, -1.35],  # found by the numeric pass
    ])]
    assert all(r["inclination"] > math.radians(5) for r in rows)
    plan = parse_plan(rows)
    table = reach_table(model, plan, np.array([setup]), base_height=H)
    assert table.reach.all()
    for k, row in enumerate(rows):
        q = table.q[k, 0]
        assert np.all(q >= model.lower - 1e-12) and np.all(q <= model.upper + 1e-12)
        angle, dist = fk_errors(model, q, setup, row)
        assert angle <= 0.02 and dist <= 0.5


def test_tolerance_lets_a_pile_just_past_the_limits_in(model):
    """Piles leaning sideways (across the arm) more and more: past some lean the joint
    limits refuse the exact axis (at the pile head, or at the approach point up the axis).
    The first refused one, with an angle tolerance looser than the step between them, is
    reached, the mast within that tolerance (FK)."""
    leans = np.radians(np.arange(20.0, 45.0, 0.25))
    rows = [{"id": f"L{k}", "x": 1650.0, "y": 0.0, "z": 0.0, "inclination": float(i),
             "azimuth": math.pi / 2, "tol_angle": 1e-4} for k, i in enumerate(leans)]
    table = reach_table(model, parse_plan(rows), np.zeros((1, 3)), base_height=H)
    ok = table.reach[:, 0]
    assert ok[0] and not ok[-1]
    first_out = int(np.argmin(ok))
    assert not ok[first_out:].any()   # one boundary: all in below it, all out above
    row = {**rows[first_out], "tol_angle": 0.02}   # the step is 0.0044 rad
    loose = reach_table(model, parse_plan([row]), np.zeros((1, 3)), base_height=H)
    assert loose.reach[0, 0]
    angle, dist = fk_errors(model, loose.q[0, 0], (0.0, 0.0, 0.0), row)
    assert angle <= 0.02 and dist <= 0.5


# ---- the cover ---------------------------------------------------------------------------
def brute_force_minimum(A: np.ndarray) -> int:
    rows = A.any(axis=1)
    for k in range(1, A.shape[1] + 1):
        for cols in combinations(range(A.shape[1]), k):
            if A[rows][:, list(cols)].any(axis=1).all():
                return k
    return 0


@pytest.mark.parametrize("seed", range(6))
def test_the_exact_cover_is_the_brute_force_minimum(seed):
    rng = np.random.default_rng(seed)
    A = rng.random((14, 11)) < 0.22
    A[3] = False                        # a pile no set-up reaches: left out of the cover
    res = cover_setups(A, exact_max=100)
    assert res.method == "milp" and res.optimal
    covered = A[:, res.chosen].any(axis=1)
    assert np.array_equal(covered, A.any(axis=1))
    assert len(res.chosen) == brute_force_minimum(A) == res.lower_bound


def test_greedy_covers_and_reports_a_bound_below_the_optimum():
    rng = np.random.default_rng(7)
    A = rng.random((40, 30)) < 0.12
    exact = cover_setups(A, exact_max=1000)
    greedy = cover_setups(A, exact_max=0)
    assert greedy.method == "greedy"
    assert np.array_equal(A[:, greedy.chosen].any(axis=1), A.any(axis=1))
    assert greedy.lower_bound <= len(exact.chosen) <= len(greedy.chosen)
    assert greedy.lp_value <= len(exact.chosen) + 1e-9


# ---- the whole plan ----------------------------------------------------------------------
def test_a_plan_reports_the_pile_out_of_reach_and_times_the_rest(model):
    a = pile_at(model, [0.0, 0.2, -0.8, -0.8, 0.0, -1.3], pid="A")
    b = pile_at(model, [0.8, 0.3, -0.8, -0.6, 0.1, -1.2], pid="B")
    c = pile_at(model, [0.2, 0.3, -0.8, -0.6, 0.0, -1.2], (6000.0, 0.0, 0.0), "C")
    far = {"id": "far", "x": 40_000.0, "y": 0.0, "z": 0.0}
    plan = parse_plan([a, b, c, far])
    cands = np.array([[0.0, 0.0, 0.0], [6000.0, 0.0, 0.0], [3000.0, 3000.0, 0.0]])
    # A post next to pile B but clear of the arm's poses over A and B.
    scene = CollisionScene.from_request({"objects": [{"type": "cylinder", "id": "post",
                                                      "radius": 100, "height": 3000,
                                                      "pose": [[1, 0, 0, -2500],
                                                               [0, 1, 0, 0],
                                                               [0, 0, 1, 1500],
                                                               [0, 0, 0, 1]]}]})
    out = plan_piles(model, plan, cands, base_height=H, scene=scene, drive_time=40.0,
                     travel_speed=1000.0)
    by_id = {plan.ids[p.index]: p for p in out.piles}
    assert by_id["far"].setup == -1 and "out of the arm's reach" in by_id["far"].reason
    assert [plan.ids[p.index] for p in out.unreached] == ["far"]
    assert len(out.setups) == 2 and out.cover.optimal
    for pid in "ABC":
        p = by_id[pid]
        su = out.setups[p.setup]
        angle, dist = fk_errors(model, p.q, su, {"A": a, "B": b, "C": c}[pid])
        assert angle <= 0.02 and dist <= 0.5
        assert p.drive_s == 40.0 and p.lower_s > 0 and p.end > p.start
    # Relocation: the 6 m between the set-ups at 1 m/s.
    assert out.relocation_s == pytest.approx(6.0)
    assert out.total_s == pytest.approx(out.work_s + out.relocation_s)
    assert out.total_s >= 3 * 40.0 + 6.0


def test_an_obstacle_over_a_pile_keeps_the_arm_off_it(model):
    a = pile_at(model, [0.0, 0.2, -0.8, -0.8, 0.0, -1.3], pid="A")
    plan = parse_plan([a])
    cands = np.zeros((1, 3))
    assert plan_piles(model, plan, cands, base_height=H).piles[0].setup == 0
    crate = CollisionScene.from_request({"objects": [{
        "type": "box", "id": "crate", "size": [400, 400, 400],
        "pose": [[1, 0, 0, a["x"]], [0, 1, 0, a["y"]], [0, 0, 1, a["z"] + 250],
                 [0, 0, 0, 1]]}]})
    out = plan_piles(model, plan, cands, base_height=H, scene=crate)
    assert out.piles[0].setup == -1
    assert out.piles[0].reason == "from every candidate set-up: the arm would hit the site"


def test_the_carrier_keeps_its_radius_off_the_obstacles():
    from planning.cycles.piles import carrier_clear

    # A 1 m box on the ground, 2 m tall: 300 mm from x = 800 at every height.
    hut = CollisionScene.from_request({"objects": [{
        "type": "box", "id": "hut", "size": [1000, 1000, 2000],
        "pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1000], [0, 0, 0, 1]]}]})
    S = np.array([[0.0, 0.0, 0.0], [800.0, 0.0, 1.0], [3000.0, 0.0, 0.0]])
    assert carrier_clear(hut, S, H, 200.0).tolist() == [False, True, True]
    assert carrier_clear(hut, S, H, 400.0).tolist() == [False, False, True]
    assert carrier_clear(hut, S, H, 0.0).all() and carrier_clear(None, S, H, 400.0).all()
