"""Work cycles in the viewer: a drilling round (every boom on its own clock, the holes
recoloured as they are drilled), a pallet (each box carried on the tool, then resting where it
was placed) and a pile plan (per set-up its carrier, piles and the arm at its first pile).

The round's and the pallet's results are made here and checked with the kinds' own
``load_result``; the pile plan is planned (a small one, under a second). References are the
kinematics library's forward kinematics at configurations interpolated here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.jobs.catalog import KINDS
from app.jobs.kinds import JobPayload, execute
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.rigs import builtin_rig
from web.results import plan_from_result
from web.timed import TimedSegments

RIG = builtin_rig("tunnel_jumbo")
RIGS = {"tunnel_jumbo": RIG}

# ---- a round: three holes, one per boom, and one behind the rig ----------------------------
HOLES = [
    {"id": "L1", "collar": [9000, 3000, 1500], "toe": [10200, 3000, 1500]},
    {"id": "M1", "collar": [9000, 0, 2500], "toe": [10200, 0, 2500]},
    {"id": "R1", "collar": [9000, -3000, 1500], "toe": [10200, -3000, 1500]},
    {"id": "X", "collar": [-1000, 0, 2000], "toe": [0, 0, 2000]},
]
#: Per boom: its hole, the hole's start and end, the boom's last sample time.
TIMES = {"left": ("L1", 2.0, 12.0, 20.0), "middle": ("M1", 3.0, 25.0, 30.0),
         "right": ("R1", 1.5, 9.0, 14.0)}


def _boom_q(boom: str) -> tuple[list[float], list[list[float]]]:
    """Times and joint rows of a boom: 6 samples between two configurations, different per
    boom (within no particular limits: the drawer only plays them)."""
    end = TIMES[boom][3]
    t = np.linspace(0.0, end, 6)
    k = list(TIMES).index(boom)
    a = np.full(7, 0.05 * (k + 1))
    b = a + np.array([0.2, -0.1, 300.0, 0.3, 0.1, -0.1, 500.0]) * (1 + 0.5 * k)
    s = (t / end)[:, None] ** 2
    return t.tolist(), (a + (b - a) * s).tolist()


def round_job() -> tuple[dict, dict]:
    params = KINDS["round"].load_params({"holes": HOLES}).model_dump(mode="json")
    booms = {}
    for boom, (hole, start, end, last) in TIMES.items():
        t, q = _boom_q(boom)
        booms[boom] = {"holes": [hole], "priority": 0, "t": t, "q": q, "phases": [
            {"kind": "drill", "start_s": start, "end_s": end, "hole": hole}],
            "wait_s": 0.0, "end_s": last}
    result = {"rig": "tunnel_jumbo", "booms": booms,
              "holes": [{"id": h, "boom": b, "start_s": s, "end_s": e, "depth_mm": 1200.0,
                         "drill_s": e - s} for b, (h, s, e, _) in TIMES.items()],
              "unreachable": [{"id": "X", "reason": "out_of_reach", "detail": "behind"}],
              "cycle_time_s": 30.0, "lower_bound_s": 20.0, "ratio": 1.5,
              "min_boom_clearance_mm": 900.0, "clearance_pair": "left-middle",
              "clearance_t_s": 0.0, "checked_instants": 10, "max_step_mm": 5.0,
              "priority": ["middle", "left", "right"], "notes": [], "planning_time_s": 1.0}
    KINDS["round"].load_result(result)   # a result the kind itself accepts
    return params, result


def _interp(t: float, times, rows) -> np.ndarray:
    rows = np.asarray(rows, dtype=float)
    return np.array([np.interp(t, times, rows[:, j]) for j in range(rows.shape[1])])


# ---- a pallet: two boxes -----------------------------------------------------------------
PICK = [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]]
BOX = [400.0, 300.0, 250.0]
GRIP_OFFSET = 65.0
CLEARANCE = 5.0
Q_PICK = [1.5707963, 0.1019165, 0.1569564, 0.0, 1.3119234, 1.5707963]
Q_PLACE = [[0.41, 0.431, 0.4418, 0.0, 0.698, 3.5516],
           [0.16, 0.50, 0.35, 0.0, 0.72, 3.30]]
CARRY = [5.5, 6.0]
RETURN = [5.0, 4.5]


def _grip() -> np.ndarray:
    """T_tool_box: the box's top face GRIP_OFFSET below the tool point, turned half about x."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[2, 3] = GRIP_OFFSET + BOX[2] / 2
    return T


def pallet_job() -> tuple[dict, dict]:
    model = builtin_model("glt_palletizer")
    params = KINDS["pallet"].load_params({
        "box": {"size": BOX}, "pick": PICK, "pattern": "column", "count": 3,
        "grip_offset_mm": GRIP_OFFSET, "clearance_mm": CLEARANCE}).model_dump(mode="json")
    boxes = []
    for k in range(2):
        rest = fk(model, np.array(Q_PLACE[k])) @ _grip()
        rest[2, 3] -= CLEARANCE
        boxes.append({"index": k, "layer": 0, "status": "placed", "reason": "",
                      "position": rest[:3, 3].tolist(), "yaw": 0.0,
                      "placed_pose": rest.tolist(), "q_pick": Q_PICK, "q_place": Q_PLACE[k],
                      "carry_s": CARRY[k], "return_s": RETURN[k],
                      "cycle_s": CARRY[k] + RETURN[k], "tilt": 0.0, "planning_time_s": 1.0,
                      "attempts": 1, "carry_states": 10, "return_states": 10})
    boxes.append({"index": 2, "layer": 0, "status": "failed", "reason": "carry: no path",
                  "position": [850.0, 0.0, 269.0], "yaw": 0.0, "placed_pose": None,
                  "q_pick": Q_PICK, "q_place": None, "carry_s": 0.0, "return_s": 0.0,
                  "cycle_s": 0.0, "tilt": None, "planning_time_s": 1.0, "attempts": 2,
                  "carry_states": 0, "return_states": 0})
    result = {"robot": "glt_palletizer", "joints": [j.name for j in model.joints],
              "pattern": "column", "per_layer": [3], "boxes": boxes, "placed": 2, "total": 3,
              "layer_s": [sum(CARRY) + sum(RETURN)], "pallet_s": sum(CARRY) + sum(RETURN),
              "boxes_per_hour": 2 * 3600 / (sum(CARRY) + sum(RETURN)), "mass": None,
              "tilt_tolerance": 0.05, "pallet_size": [1200.0, 800.0, 144.0],
              "pallet_pose": params["pallet"]["pose"], "box_size": BOX,
              "planning_time_s": 2.0}
    KINDS["pallet"].load_result(result)
    return params, result


# ---- piles: two set-ups, one pile out of reach -------------------------------------------
BASE_HEIGHT = 500.0
#: Pile -> (configuration that holds it, set-up it is made from).
PILES = {"A": ([0.0, 0.2, -0.8, -0.8, 0.0, -1.3], (0.0, 0.0, 0.0)),
         "B": ([0.7, 0.3, -0.8, -0.6, 0.1, -1.2], (0.0, 0.0, 0.0)),
         "C": ([0.0, 0.2, -0.8, -0.8, 0.0, -1.3], (5000.0, 0.0, 0.0))}


def _pile_row(pid: str) -> dict:
    """A plan row the pile driver at its q holds exactly from its set-up (the mast is the
    tool's y axis)."""
    q, setup = PILES[pid]
    T = fk(builtin_model("pile_driver"), np.asarray(q, dtype=float))
    c, s = math.cos(setup[2]), math.sin(setup[2])
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    d = R @ T[:3, 1]
    p = R @ T[:3, 3] + np.array([setup[0], setup[1], BASE_HEIGHT])
    return {"id": pid, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
            "inclination": math.acos(-d[2]), "azimuth": math.atan2(d[1], d[0])}


@pytest.fixture(scope="module")
def piles_job() -> tuple[dict, dict]:
    body = {"plan": [_pile_row(p) for p in PILES] + [{"id": "far", "x": 30_000, "y": 0,
                                                      "z": 0}],
            "setups": {"positions": [[0, 0, 0], [5000, 0, 0]]}, "drive_time": 20.0,
            "base_height": BASE_HEIGHT}
    params = KINDS["piles"].load_params(body)
    payload = JobPayload(params=params.model_dump(mode="json"),
                         robot_model=builtin_model("pile_driver").to_dict())
    import json
    result = json.loads(execute("piles", payload.model_dump(mode="json"), lambda f, m: None))
    return params.model_dump(mode="json"), result


def _draw(kind: str, params: dict, result: dict):
    return plan_from_result(kind, params, result, job="j", models=builtin_model, rigs=RIGS)


# ---- round -----------------------------------------------------------------------------------
def test_the_round_plays_every_boom_on_its_own_clock(viewer):
    params, result = round_job()
    plan = _draw("round", params, result)
    shown = viewer.show_plan(plan)
    for name in ("holes", "left/tool_path", "middle/tool_path", "right/tool_path"):
        assert f"/plan/round/{name}" in shown["nodes"], name
    assert plan.duration == pytest.approx(30.0)
    # Mid-round, and after the right boom's end (it holds its last sample).
    for t in (7.3, 17.0, 29.0):
        viewer.set_time(t)
        for boom in TIMES:
            times, rows = _boom_q(boom)
            q = _interp(t, times, rows)
            expected = fk(RIG.arms[boom], q)[:3, 3]
            np.testing.assert_allclose(viewer.q(boom), q, atol=1e-9)
            np.testing.assert_allclose(viewer.tool_position(boom), expected, atol=1e-6)
    last = np.asarray(_boom_q("right")[1][-1])
    np.testing.assert_allclose(viewer.q("right"), last, atol=1e-12)


def test_a_hole_is_grey_then_its_booms_colour_then_dark(viewer):
    params, result = round_job()
    plan = _draw("round", params, result)
    viewer.show_plan(plan)
    node = viewer._plan_handles["/plan/round/holes"]
    # The drawn segments run collar to toe, in the plan's order.
    collars = np.array([h["collar"] for h in HOLES]) / 1000.0
    toes = np.array([h["toe"] for h in HOLES]) / 1000.0
    np.testing.assert_allclose(np.asarray(node.points)[:, 0], collars, atol=1e-6)
    np.testing.assert_allclose(np.asarray(node.points)[:, 1], toes, atol=1e-6)
    grey, seen = None, []
    for t in (1.0, 2.5, 11.9, 12.5, 29.0):   # L1 (left) is drilled from 2 s to 12 s
        viewer.set_time(t)
        seen.append(tuple(int(c) for c in np.asarray(node.colors)[0, 0]))
        if t == 1.0:
            grey = tuple(int(c) for c in np.asarray(node.colors)[1, 0])  # M1: not yet
    planned, drilling, drilling_late, done, done_late = seen
    assert planned == grey                       # planned: the same grey as every hole
    assert drilling == drilling_late != planned  # drilling: another colour, throughout
    assert done == done_late not in (planned, drilling)
    assert sum(done) < sum(drilling)             # done is darker than drilling
    # The boom's colour: the left hole drilling is bluish, the right one (1.5-9 s) reddish.
    viewer.set_time(5.0)
    colors = np.asarray(node.colors, dtype=int)
    left, right = colors[0, 0], colors[2, 0]
    assert left[2] > left[0] and right[0] > right[2]
    # The hole no boom drills stays in its own colour all round.
    colours = set()
    for t in (0.0, 15.0, 30.0):
        viewer.set_time(t)
        colours.add(tuple(np.asarray(node.colors)[3, 0]))
    assert len(colours) == 1 and colours != {planned}


def test_timed_segments_count_their_change_times():
    seg = TimedSegments("s", np.zeros((2, 2, 3)), [[1.0, 2.0], [np.inf, np.inf]],
                        [[[1, 1, 1], [2, 2, 2], [3, 3, 3]], [[9, 9, 9]] * 3])
    assert seg.colors_at(0.5)[:, 0].tolist() == [1, 9]
    assert seg.colors_at(1.0)[:, 0].tolist() == [2, 9]
    assert seg.colors_at(2.0)[:, 0].tolist() == [3, 9]
    with pytest.raises(ValueError, match="colours"):
        TimedSegments("s", np.zeros((1, 2, 3)), [[1.0]], [[[1, 1, 1]]])
    with pytest.raises(ValueError, match="decrease"):
        TimedSegments("s", np.zeros((1, 2, 3)), [[2.0, 1.0]], [[[1, 1, 1]] * 3])


def test_a_round_result_naming_another_hole_or_boom_is_refused():
    params, result = round_job()
    result["holes"][1]["id"] = "Z9"
    with pytest.raises(ValueError, match=r"result\.holes\.1\.id"):
        _draw("round", params, result)
    params, result = round_job()
    result["booms"]["top"] = result["booms"].pop("left")
    with pytest.raises(ValueError, match=r"result\.booms\.top"):
        _draw("round", params, result)


def test_holes_from_an_iredes_plan_are_drawn_in_the_rig_frame():
    from pathlib import Path

    # As written: CRLF line ends, which its checksum covers.
    text = (Path(__file__).parents[2] / "examples" / "drill_round.xml").read_bytes().decode()
    from planning.drilling.plans import read_iredes
    holes = read_iredes(text).holes[:2]
    params = KINDS["round"].load_params({"plan_iredes": text, "rig_pose": [9000, 0, 0, 90]}
                                        ).model_dump(mode="json")
    _, result = round_job()
    result["holes"] = [{"id": h.id, "boom": "left", "start_s": 1.0, "end_s": 2.0,
                        "depth_mm": 1.0, "drill_s": 1.0} for h in holes]
    result["unreachable"] = []
    plan = _draw("round", params, result)
    drawn = plan.timed[0].points
    # rig_pose [x, y, z, yaw°]: turned 90° about z, then moved 9 m along x.
    for k, h in enumerate(holes):
        expect = np.array([9000.0 - h.collar[1], h.collar[0], h.collar[2]])
        np.testing.assert_allclose(drawn[k, 0], expect, atol=1e-6)
    assert plan.timed[0].colors_at(1.5)[0].tolist() != plan.timed[0].colors_at(0.5)[0].tolist()


# ---- pallet ----------------------------------------------------------------------------------
def test_a_box_rides_on_the_tool_during_its_carry_and_rests_once_placed(viewer):
    params, result = pallet_job()
    plan = _draw("pallet", params, result)
    shown = viewer.show_plan(plan)
    assert "/plan/pallet/pallet" in shown["nodes"]
    assert {"/plan/pallet/loads/box0", "/plan/pallet/loads/box1"} <= set(shown["nodes"])
    assert "/plan/pallet/loads/box2" not in shown["nodes"]   # never placed
    model = builtin_model("glt_palletizer")
    pick1 = CARRY[0] + RETURN[0]          # box 1 is taken when the arm is back (no dwell)
    place1 = pick1 + CARRY[1]
    times = [0.0, CARRY[0], pick1, place1]
    rows = [Q_PICK, Q_PLACE[0], Q_PICK, Q_PLACE[1]]
    rest1 = np.asarray(result["boxes"][1]["placed_pose"])
    for t in (1.0, pick1 - 0.1):
        viewer.set_time(t)
        assert viewer.loads["box1"] is None, t   # not yet taken
    for t in (pick1 + 0.5, place1 - 0.01):
        viewer.set_time(t)
        q = _interp(t, times, rows)
        np.testing.assert_allclose(viewer.q(), q, atol=1e-9)
        np.testing.assert_allclose(viewer.loads["box1"], fk(model, q) @ _grip(), atol=1e-6)
    for t in (place1, plan.duration):
        viewer.set_time(t)
        # where it rests: the placed pose, above it by the clearance it is let go at
        np.testing.assert_allclose(viewer.loads["box1"][:3, :3], rest1[:3, :3], atol=1e-6)
        np.testing.assert_allclose(viewer.loads["box1"][:3, 3],
                                   rest1[:3, 3] + [0, 0, CLEARANCE], atol=1e-6)
    viewer.set_time(pick1 + 0.5)                  # box 0 stays where it was placed
    rest0 = np.asarray(result["boxes"][0]["placed_pose"])
    np.testing.assert_allclose(viewer.loads["box0"][:3, 3], rest0[:3, 3] + [0, 0, CLEARANCE],
                               atol=1e-6)
    assert "straight in joint space" in plan.summary and "box 2 (failed)" in plan.summary


# ---- piles -----------------------------------------------------------------------------------
def test_a_pile_plan_draws_one_carrier_and_arm_per_setup(piles_job):
    params, result = piles_job
    plan = _draw("piles", params, result)
    setups = result["setups"]
    assert len(setups) == 2
    carriers = sorted(n for n in plan.names if n.endswith("/carrier"))
    assert carriers == [f"setups/{k}/carrier" for k in range(len(setups))]
    arms = {p.name: p.points for p in plan.polylines if p.name.endswith("/arm")}
    assert sorted(arms) == [f"setups/{k}/arm" for k in range(len(setups))]
    rows = {p: _pile_row(p) for p in PILES}
    for k, s in enumerate(setups):
        mine = sorted((p for p in result["piles"] if p["setup"] == k), key=lambda p: p["order"])
        head = np.array([rows[mine[0]["id"]][c] for c in "xyz"])
        # The arm drawn at its first pile: its tool point at the pile's head.
        tip = arms[f"setups/{k}/arm"][-1]
        assert np.linalg.norm(tip - head) <= mine[0]["position_error"] + 1e-6
        cap = next(c for c in plan.capsules if c.name == f"setups/{k}/carrier")
        np.testing.assert_allclose(cap.b, [s["x"], s["y"], BASE_HEIGHT], atol=1e-9)
    # Piles coloured by set-up: A and B (set-up of A) alike, C apart; the far one unreached.
    strokes = next(t for t in plan.timed if t.name == "piles")
    colours = [tuple(c) for c in strokes.colors_at(0.0)]
    by_id = dict(zip([p["id"] for p in result["piles"]] + ["far"], colours, strict=True))
    setup_of = {p["id"]: p["setup"] for p in result["piles"]}
    assert (by_id["A"] == by_id["B"]) == (setup_of["A"] == setup_of["B"])
    assert by_id["C"] != by_id["A"] and by_id["far"] not in (by_id["A"], by_id["C"])


def test_the_viewer_shows_a_pile_plan(viewer, piles_job):
    params, result = piles_job
    shown = viewer.show_plan(_draw("piles", params, result))
    for name in ("piles", "route", "setups/0/arm", "setups/1/carrier"):
        assert f"/plan/piles/{name}" in shown["nodes"], name


# ---- planned results -------------------------------------------------------------------------
def _planned(kind: str, body: dict, robot: str | None) -> tuple[dict, dict]:
    import json

    params = KINDS[kind].load_params(body)
    payload = JobPayload(params=params.model_dump(mode="json"),
                         robot_model=builtin_model(robot).to_dict() if robot else None)
    result = json.loads(execute(kind, payload.model_dump(mode="json"), lambda f, m: None))
    return params.model_dump(mode="json"), result


@pytest.mark.slow
def test_planned_rounds_and_pallets_are_drawn(viewer):
    params, result = _planned("round", {"holes": HOLES[:3], "collaring_s": 2.0,
                                        "penetration_rate_m_min": 4.0, "output_dt": 2.0}, None)
    plan = _draw("round", params, result)
    viewer.show_plan(plan)
    hole = result["holes"][0]
    boom = result["booms"][hole["boom"]]
    t = 0.5 * (hole["start_s"] + hole["end_s"])
    viewer.set_time(t)
    q = _interp(t, boom["t"], boom["q"])
    np.testing.assert_allclose(viewer.tool_position(hole["boom"]),
                               fk(RIG.arms[hole["boom"]], q)[:3, 3], atol=1e-6)
    k = [h["id"] for h in HOLES].index(hole["id"])
    assert tuple(plan.timed[0].colors_at(t)[k]) != tuple(plan.timed[0].colors_at(0.0)[k])

    params, result = _planned("pallet", {"box": {"size": BOX}, "pick": PICK,
                                         "pattern": "column", "count": 2, "time_limit": 10},
                              "glt_palletizer")
    assert result["placed"] == 2
    viewer.show_plan(_draw("pallet", params, result))
    first = result["boxes"][0]
    viewer.set_time(first["carry_s"] + 0.01)
    rest = np.asarray(first["placed_pose"])
    np.testing.assert_allclose(viewer.loads["box0"][:3, 3],
                               rest[:3, 3] + [0, 0, params["clearance_mm"]], atol=1e-3)
    viewer.set_time(first["carry_s"] + first["return_s"] - 0.01)
    assert viewer.loads["box1"] is None
