"""``GET /jobs/{id}/plan``: a finished round's drill plan written back with each hole's boom,
drilling order and planned times, as IREDES (checksum verified on reading back), CSV and
JSON; 404, 409 and 422 like the trajectory files. The jobs are stored finished (no planning
here): a constructed round result, its values written out by hand."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from stored_jobs import store_job

from planning.drilling.plans import (
    DrillPlan,
    Hole,
    read_iredes,
    read_iredes_with_assignments,
    write_iredes,
)

#: Three holes (mm, the plan's frame); two drilled by the left boom in the order L2, L1,
#: one by the middle boom, and one no boom reached.
HOLES = [{"id": "L1", "collar": [9000.0, 2000.0, 1500.0], "toe": [10000.0, 2000.0, 1500.0],
          "type": "Contour"},
         {"id": "L2", "collar": [9000.0, 2500.0, 2000.0], "toe": [10000.0, 2500.0, 2000.0]},
         {"id": "M1", "collar": [9000.0, 0.0, 2500.0], "toe": [10000.0, 0.0, 2500.0],
          "type": "Cut"},
         {"id": "X1", "collar": [9000.0, 0.0, 9000.0], "toe": [10000.0, 0.0, 9000.0]}]
#: What the plan must say of each drilled hole.
EXPECTED = {"L2": {"boom": "left", "order": 1, "start_s": 12.5, "end_s": 80.25},
            "L1": {"boom": "left", "order": 2, "start_s": 95.0, "end_s": 170.75},
            "M1": {"boom": "middle", "order": 1, "start_s": 20.0, "end_s": 99.5}}


def _boom(holes: list[str], end: float) -> dict:
    t = [0.0, end]
    q = [[0.1, 0.2, 100.0, 0.0, 0.0, 0.0, 4000.0]] * 2
    return {"holes": holes, "priority": 0, "t": t, "q": q,
            "phases": [{"kind": "transfer", "start_s": 0.0, "end_s": end, "hole": None}],
            "wait_s": 0.0, "end_s": end}


def _result() -> dict:
    holes = [{"id": h, "boom": e["boom"], "start_s": e["start_s"], "end_s": e["end_s"],
              "depth_mm": 1000.0, "drill_s": 50.0} for h, e in EXPECTED.items()]
    return {"rig": "tunnel_jumbo", "booms": {"left": _boom(["L2", "L1"], 180.0),
                                             "middle": _boom(["M1"], 110.0)},
            "holes": holes,
            "unreachable": [{"id": "X1", "reason": "out_of_reach", "detail": "left: far"}],
            "cycle_time_s": 180.0, "lower_bound_s": 75.0, "ratio": 2.4,
            "min_boom_clearance_mm": 500.0, "clearance_pair": "left-middle",
            "clearance_t_s": 2.0, "checked_instants": 600, "max_step_mm": 4.0,
            "priority": ["left", "middle"], "notes": [], "planning_time_s": 1.0}


def _plan() -> DrillPlan:
    frame = np.eye(4)
    frame[:3, 3] = [503000.0, 0.0, 21500.0]
    return DrillPlan("face-7", "Face 7", frame, "site",
                     tuple(Hole(h["id"], f"hole {h['id']}", h["collar"], h["toe"],
                                h.get("type", ""), 45.0) for h in HOLES))


@pytest.fixture
def stored(client):
    store_job(client, "by-list", "round", {"holes": HOLES}, _result())
    store_job(client, "by-plan", "round", {"plan_iredes": write_iredes(_plan())}, _result())
    return client


@pytest.mark.parametrize("job", ["by-list", "by-plan"])
def test_the_iredes_plan_carries_every_holes_boom_order_and_times(stored, job):
    r = stored.get(f"/jobs/{job}/plan")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/xml")
    plan = read_iredes(r.content)                      # the checksum is verified
    given = read_iredes(r.content, verify_checksum=True)
    assert plan.ids() == [h["id"] for h in HOLES] == given.ids()
    np.testing.assert_allclose(plan.collars(), [h["collar"] for h in HOLES], atol=1e-6)
    np.testing.assert_allclose(plan.toes(), [h["toe"] for h in HOLES], atol=1e-6)
    assert [h.type for h in plan.holes] == ["Contour", "", "Cut", ""]
    back, assignments = read_iredes_with_assignments(r.content)
    assert assignments == EXPECTED                     # X1, not drilled, has none
    if job == "by-plan":                               # the given plan's own fields stay
        assert back.plan_id == "face-7" and back.name == "Face 7"
        np.testing.assert_allclose(back.frame, _plan().frame)
        assert [h.diameter_mm for h in back.holes] == [45.0] * 4


def test_csv_and_json_carry_the_same_schedule(stored):
    r = stored.get("/jobs/by-list/plan?format=csv")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [row["id"] for row in rows] == ["L1", "L2", "M1", "X1"]
    for row in rows:
        e = EXPECTED.get(row["id"])
        got = ({"boom": row["boom"], "order": int(row["order"]),
                "start_s": float(row["start_s"]), "end_s": float(row["end_s"])}
               if row["boom"] else None)
        assert got == e
    r = stored.get("/jobs/by-plan/plan?format=json")
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["job"] == "by-plan" and body["plan"]["plan_id"] == "face-7"
    assert body["assignments"] == EXPECTED
    assert body["unreachable"][0]["id"] == "X1"


def test_unknown_unfinished_other_kinds_and_bad_formats_are_refused(stored):
    assert stored.get("/jobs/nope/plan").status_code == 404
    store_job(stored, "queued", "round", {"holes": HOLES}, None, status="queued")
    r = stored.get("/jobs/queued/plan")
    assert r.status_code == 409 and "queued" in r.text
    r = stored.get("/jobs/by-list/plan?format=pdf")
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "format"]
    store_job(stored, "fail", "round", {"holes": HOLES}, None, status="failed", error="boom")
    assert stored.get("/jobs/fail/plan").status_code == 409


def test_a_job_of_another_kind_is_422_at_the_job_id(stored):
    from kinematics.library import builtin_model

    robot = "glt_palletizer"
    names = [j.name for j in builtin_model(robot).joints]
    q0, q1 = [0.0] * len(names), [0.1] * len(names)
    result = {"robot": robot, "joints": names, "status": "ok", "message": "ok",
              "path": [q0, q1], "length": 0.1, "planning_time_s": 0.1,
              "simplify_time_s": 0.0, "min_clearance": 100.0, "goal": q1, "pairs": [],
              "planner": "rrt_connect", "resolution": 0.01, "stats": {}, "trajectory": None}
    store_job(stored, "mot", "motion", {"robot": robot, "start": q0, "goal": {"q": q1}},
              result)
    r = stored.get("/jobs/mot/plan")
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["path", "job_id"]
