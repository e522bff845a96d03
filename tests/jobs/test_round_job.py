"""The ``round`` job kind: 422s naming the field, a small round run as a worker runs it whose
result validates against the published result schema, the rig pose applied to the holes,
and the Gantt chart served by ``GET /jobs/{id}/plot``."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs.catalog import KINDS
from app.jobs.kinds import JobPayload, execute
from app.jobs.round_kinds import MAX_ROUND_HOLES
from app.main import create_app

from .conftest import wait_for

#: Three short holes, one per boom, and one behind the rig; in a plan frame 9 m behind the
#: face (``rig_pose`` moves it 9 m forward).
HOLES = [
    {"id": "L1", "collar": [0, 3000, 1500], "toe": [1200, 3000, 1500]},
    {"id": "M1", "collar": [0, 0, 2500], "toe": [1200, 0, 2500], "type": "cut"},
    {"id": "R1", "collar": [0, -3000, 1500], "toe": [1200, -3000, 1500]},
    {"id": "X", "collar": [-10000, 0, 2000], "toe": [-9000, 0, 2000]},
]
PARAMS = {"holes": HOLES, "rig_pose": [9000, 0, 0], "collaring_s": 2.0, "retract_s": 8.0,
          "penetration_rate_m_min": 4.0, "penetration_rate_by_type": {"cut": 2.0},
          "output_dt": 2.0}


def submit(client, params: dict):
    return client.post("/jobs", content=json.dumps({"kind": "round", "params": params}),
                       headers={"content-type": "application/json"})


@pytest.fixture(scope="module")
def result() -> dict:
    params = KINDS["round"].load_params(PARAMS)
    payload = JobPayload(params=params.model_dump(mode="json")).model_dump(mode="json")
    return json.loads(execute("round", payload, lambda f, m: None))


@pytest.mark.parametrize(("params", "loc", "words"), [
    ({**PARAMS, "holes": HOLES + [HOLES[0]]}, ["holes", 4, "id"], "used twice"),
    ({**PARAMS, "holes": [{**HOLES[0], "toe": HOLES[0]["collar"]}]}, ["holes", 0, "toe"],
     "at least 1 mm"),
    ({**PARAMS, "holes": []}, ["holes"], "at least 1"),
    ({**PARAMS, "rig": "nope"}, ["rig"], "unknown rig"),
    ({**PARAMS, "booms": ["top"]}, ["booms", 0], "no boom 'top'"),
    ({**PARAMS, "limits": {"velocity": {"elbow": 1.0}}}, ["limits", "velocity", "elbow"],
     "no such joint"),
    ({**PARAMS, "rig_pose": [1, 2]}, ["rig_pose"], "4x4"),
    ({**PARAMS, "rig_pose": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ["rig_pose"], "rigid"),
    ({**PARAMS, "penetration_rate_m_min": 0}, ["penetration_rate_m_min"], "greater than"),
    ({**PARAMS, "scene": [{"type": "box", "size": [1, 1]}]}, ["scene", 0], "size"),
])
def test_bad_params_are_422_naming_the_field(checking_client, params, loc, words):
    r = submit(checking_client, params)
    assert r.status_code == 422, r.text
    err = r.json()["detail"][0]
    assert err["loc"][: 2 + len(loc)] == ["body", "params", *loc], err
    assert words in err["msg"], err


def test_more_holes_than_the_cap_are_422(checking_client):
    holes = [{"id": str(k), "collar": [9000, k, 0], "toe": [9500, k, 0]}
             for k in range(MAX_ROUND_HOLES + 1)]
    r = submit(checking_client, {"holes": holes})
    assert r.status_code in (413, 422), r.text
    if r.status_code == 422:
        assert r.json()["detail"][0]["loc"][:3] == ["body", "params", "holes"]


@pytest.mark.slow
def test_a_round_result_validates_against_its_published_schema(result):
    client = TestClient(create_app(Settings(no_viewer=True)))
    published = {k["kind"]: k for k in client.get("/jobs/kinds").json()}
    schema = published["round"]["result_schema"]
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(result, schema, cls=jsonschema.Draft202012Validator)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**result, "unexpected": 1}, schema)


@pytest.mark.slow
def test_a_round_drills_each_hole_with_its_own_boom_after_the_rig_pose(result):
    assert {h["id"]: h["boom"] for h in result["holes"]} == \
        {"L1": "left", "M1": "middle", "R1": "right"}
    assert result["unreachable"] == [{"id": "X", "reason": "out_of_reach",
                                      "detail": result["unreachable"][0]["detail"]}]
    # the cut hole drills at 2 m/min, the others at 4; retract_s is above the feed's own
    # least time (1,500 mm at 500 mm/s in a quintic: 5.6 s), so it is what counts
    drill = {h["id"]: h["drill_s"] for h in result["holes"]}
    assert drill["M1"] == pytest.approx(2.0 + 1200 / (2000 / 60) + 8.0)
    assert drill["L1"] == pytest.approx(2.0 + 1200 / (4000 / 60) + 8.0)
    assert result["lower_bound_s"] == pytest.approx(sum(drill.values()) / 3)
    assert result["cycle_time_s"] >= result["lower_bound_s"]
    assert result["min_boom_clearance_mm"] > 0
    for boom in result["booms"].values():
        assert len(boom["t"]) == len(boom["q"]) and all(len(q) == 7 for q in boom["q"])
        assert np.all(np.diff(boom["t"]) > 0)
        assert boom["end_s"] == pytest.approx(boom["t"][-1])


@pytest.mark.slow
def test_the_plot_is_a_gantt_png(jobs_client):
    r = submit(jobs_client, {**PARAMS, "holes": HOLES[:2], "booms": ["left", "middle"]})
    assert r.status_code == 202, r.text
    job = wait_for(jobs_client, r.json()["id"], timeout=180)
    assert job["status"] == "succeeded", job
    png = jobs_client.get(f"/jobs/{job['id']}/plot")
    assert png.status_code == 200
    assert png.headers["content-type"] == "image/png"
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n"


def _iredes(holes: list[dict]) -> str:
    from planning.drilling.plans import DrillPlan, Hole, write_iredes

    plan = DrillPlan("R-1", "test round", np.eye(4), "site",
                     tuple(Hole(h["id"], h["id"], np.array(h["collar"], dtype=float),
                                np.array(h["toe"], dtype=float), h.get("type", ""))
                           for h in holes))
    return write_iredes(plan)


def test_an_iredes_plan_gives_the_same_holes_as_the_list():
    listed = KINDS["round"].load_params(PARAMS)
    params = {k: v for k, v in PARAMS.items() if k != "holes"}
    read = KINDS["round"].load_params({**params, "plan_iredes": _iredes(HOLES)})
    C1, T1, ids1, types1 = listed.rig_holes()
    C2, T2, ids2, types2 = read.rig_holes()
    assert ids1 == ids2 and types1 == types2
    assert np.allclose(C1, C2) and np.allclose(T1, T2)
    assert C2[0].tolist() == [9000, 3000, 1500]   # rig_pose applied


@pytest.mark.parametrize(("edit", "loc", "words"), [
    (lambda text: text.replace("<IR:PointX>", "<IR:PointX>x", 1), ["plan_iredes"],
     "plan_iredes"),
    (lambda text: "<NotAPlan/>", ["plan_iredes"], "DRPPlan"),
])
def test_a_bad_iredes_plan_is_422_at_plan_iredes(checking_client, edit, loc, words):
    params = {k: v for k, v in PARAMS.items() if k != "holes"}
    r = submit(checking_client, {**params, "plan_iredes": edit(_iredes(HOLES)),
                                 "plan_verify_checksum": False})
    assert r.status_code == 422, r.text
    err = r.json()["detail"][0]
    assert err["loc"][: 2 + len(loc)] == ["body", "params", *loc], err
    assert words in err["msg"], err


def test_holes_and_a_plan_together_are_422(checking_client):
    r = submit(checking_client, {**PARAMS, "plan_iredes": _iredes(HOLES)})
    assert r.status_code == 422, r.text
    assert "exactly one" in r.json()["detail"][0]["msg"]
