"""POST /drill-plans/read and /drill-plans/write: plan files in and out over REST, 422s
naming the element, row and column or field at fault, the hole cap and the body caps."""

from __future__ import annotations

import re
import zlib

import numpy as np
import pytest

from app.limits import ROUTE_BODY_CAPS
from planning.drilling.plans import MAX_HOLES, DrillPlan, Hole, to_csv, write_iredes

XML = {"content-type": "application/xml"}
CSV = {"content-type": "text/csv"}


@pytest.fixture(scope="module")
def plan() -> DrillPlan:
    holes = (
        Hole("1", "C001", [512_000.0, -3_300.0, 20_300.0], [516_494.0, -3_536.0, 20_300.0],
             "Contour", 45.0),
        Hole("2", "R001", [512_000.0, 150.0, 21_000.0], [516_700.0, 150.0, 21_000.0],
             "Reamer", 102.0),
    )
    return DrillPlan("R-1", "Round 1", np.eye(4), "site", holes)


@pytest.fixture(scope="module")
def iredes(plan) -> bytes:
    return write_iredes(plan, created="2026-11-30T07:00:00").encode()


def test_reads_an_iredes_file_as_json_in_mm(ro_client, iredes):
    r = ro_client.post("/drill-plans/read", content=iredes, headers=XML)
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["hole_count"] == 2 and len(body["holes"]) == 2
    assert (body["plan_id"], body["name"], body["frame_name"]) == ("R-1", "Round 1", "site")
    assert body["holes"][0] == {"id": "1", "name": "C001", "collar": [512000.0, -3300.0, 20300.0],
                                "toe": [516494.0, -3536.0, 20300.0], "type": "Contour",
                                "diameter_mm": 45.0}
    assert body["frame"] == np.eye(4).tolist()
    assert body["assignments"] == {}


def test_a_checksum_mismatch_is_422_naming_chksum(ro_client, iredes):
    changed = iredes.replace(b"<IR:PointY>-3.536</IR:PointY>", b"<IR:PointY>-3.537</IR:PointY>")
    r = ro_client.post("/drill-plans/read", content=changed, headers=XML)
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "GenTrailer", "ChkSum"]
    assert "ChkSum" in detail["msg"]
    r = ro_client.post("/drill-plans/read?verify_checksum=false", content=changed, headers=XML)
    assert r.status_code == 200
    assert r.json()["holes"][0]["toe"][1] == -3537.0


def test_northing_in_x_is_a_query_option(ro_client, iredes):
    r = ro_client.post("/drill-plans/read?northing_in_x=true", content=iredes, headers=XML)
    assert r.status_code == 200
    assert r.json()["holes"][0]["collar"] == [-3300.0, 512000.0, 20300.0]


def test_a_bad_element_is_422_naming_the_hole_and_element(ro_client, iredes):
    text = iredes.replace(b"<IR:PointZ>21.000</IR:PointZ>", b"<IR:PointZ>21,0</IR:PointZ>", 1)
    r = ro_client.post("/drill-plans/read?verify_checksum=false", content=text, headers=XML)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "DrillPlan", "Hole[2]", "StartPoint",
                                            "PointZ"]


def test_a_doctype_is_refused(ro_client, iredes):
    text = iredes.replace(b"<DRPPlan ", b'<!DOCTYPE DRPPlan [<!ENTITY a "x">]>\r\n<DRPPlan ', 1)
    r = ro_client.post("/drill-plans/read?verify_checksum=false", content=text, headers=XML)
    assert r.status_code == 422 and "DOCTYPE" in r.json()["detail"][0]["msg"]


def test_reads_csv_and_names_a_malformed_row_and_column(ro_client, plan):
    text = to_csv(plan)
    r = ro_client.post("/drill-plans/read", content=text.encode(), headers=CSV)
    assert r.status_code == 200 and r.json()["hole_count"] == 2
    bad = text.replace("516700.0", "5167OO.0")
    r = ro_client.post("/drill-plans/read", content=bad.encode(), headers=CSV)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "row", 3, "toe_x"]


def test_reads_json_and_names_a_zero_depth_hole(ro_client, plan):
    data = plan.to_json()
    r = ro_client.post("/drill-plans/read", json=data)
    assert r.status_code == 200 and r.json()["holes"] == data["holes"]
    data["holes"][1]["toe"] = data["holes"][1]["collar"]
    r = ro_client.post("/drill-plans/read?format=json", json=data)
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "holes", 1] and "'2'" in detail["msg"]


def test_the_format_query_wins_over_the_content_type(ro_client, plan):
    r = ro_client.post("/drill-plans/read?format=csv", content=to_csv(plan).encode(),
                       headers=XML)
    assert r.status_code == 200 and r.json()["hole_count"] == 2
    r = ro_client.post("/drill-plans/read?format=xlsx", content=b"x", headers=XML)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["query", "format"]


def test_other_content_types_are_415(ro_client, iredes):
    r = ro_client.post("/drill-plans/read", content=iredes, headers={"content-type":
                                                                     "text/plain"})
    assert r.status_code == 415
    assert r.json()["detail"][0]["loc"] == ["header", "content-type"]


def test_write_iredes_with_assignments_reads_back(ro_client, plan):
    body = {**plan.to_json(), "assignments": {"1": {"boom": "left", "order": 1,
                                                    "start_s": 0.0, "end_s": 95.5}}}
    r = ro_client.post("/drill-plans/write", json=body)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/xml")
    assert r.headers["content-disposition"] == 'attachment; filename="R-1.xml"'
    text = r.content
    written = int(re.search(rb"<IR:ChkSum>(\d+)</IR:ChkSum>", text).group(1))
    zeroed = text.replace(f"<IR:ChkSum>{written}</IR:ChkSum>".encode(),
                          b"<IR:ChkSum>0</IR:ChkSum>")
    assert written == zlib.crc32(zeroed)
    back = ro_client.post("/drill-plans/read", content=text, headers=XML).json()
    assert back["holes"] == plan.to_json()["holes"]
    assert back["assignments"] == {"1": {"boom": "left", "order": 1, "start_s": 0.0,
                                         "end_s": 95.5}}


def test_write_csv(ro_client, plan):
    r = ro_client.post("/drill-plans/write?format=csv", json=plan.to_json())
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/csv")
    assert r.text.splitlines()[0] == ("id,name,collar_x,collar_y,collar_z,toe_x,toe_y,toe_z,"
                                      "type,diameter_mm")
    body = {**plan.to_json(), "assignments": {"1": {"boom": "left"}}}
    r = ro_client.post("/drill-plans/write?format=csv", json=body)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "assignments"]


def test_write_names_a_bad_assignment_and_field(ro_client, plan):
    body = {**plan.to_json(), "assignments": {"9": {"boom": "left"}}}
    r = ro_client.post("/drill-plans/write", json=body)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "assignments", "9"]
    body = plan.to_json()
    body["holes"][0]["collar"] = [1.0, "x", 3.0]
    r = ro_client.post("/drill-plans/write", json=body)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "holes", 0, "collar", 1]


def test_more_than_max_holes_is_413(ro_client):
    holes = [{"id": str(k), "collar": [0, 0, 0], "toe": [1, 0, 0]}
             for k in range(MAX_HOLES + 1)]
    r = ro_client.post("/drill-plans/write", json={"plan_id": "p", "holes": holes})
    assert r.status_code == 413
    assert r.json()["detail"][0]["loc"] == ["body", "holes"]


def test_body_caps_are_published(ro_client):
    doc = ro_client.get("/openapi.json").json()
    for path in ("/drill-plans/read", "/drill-plans/write"):
        assert doc["paths"][path]["post"]["x-max-body-bytes"] == ROUTE_BODY_CAPS[path]
    content = doc["paths"]["/drill-plans/read"]["post"]["requestBody"]["content"]
    assert {"application/xml", "text/csv", "application/json"} <= set(content)


def test_the_published_examples_answer_200(ro_client):
    doc = ro_client.get("/openapi.json").json()
    content = doc["paths"]["/drill-plans/read"]["post"]["requestBody"]["content"]
    for media in ("application/xml", "text/csv"):
        r = ro_client.post("/drill-plans/read", content=content[media]["example"].encode(),
                           headers={"content-type": media})
        assert r.status_code == 200, (media, r.text)
    r = ro_client.post("/drill-plans/read", json=content["application/json"]["example"])
    assert r.status_code == 200, r.text
    write = doc["paths"]["/drill-plans/write"]["post"]["requestBody"]["content"]
    r = ro_client.post("/drill-plans/write", json=write["application/json"]["example"])
    assert r.status_code == 200, r.text


@pytest.mark.slow
def test_large_files_are_read_in_a_compute_worker_with_the_same_answers(client):
    """Over HEAVY_BYTES the body goes to a worker process: the same plan comes back, and a
    PlanTooLargeError raised there still answers 413 at its field."""
    from app.api.routes.drill_plans import HEAVY_BYTES

    rng = np.random.default_rng(7)
    collars = np.round(rng.uniform(-3000, 3000, (2500, 3)), 3)
    holes = tuple(Hole(str(k), f"H{k}", c, c + [4500.0, 0.0, 0.0], "Stoping", 45.0)
                  for k, c in enumerate(collars))
    big = DrillPlan("big", "", np.eye(4), "site", holes)
    data = write_iredes(big).encode()
    assert len(data) > HEAVY_BYTES
    r = client.post("/drill-plans/read", content=data, headers=XML)
    assert r.status_code == 200, r.text
    assert r.json()["holes"] == big.to_json()["holes"]
    too_many = DrillPlan("big", "", np.eye(4), "site", holes + tuple(
        Hole(f"x{k}", "", [0.0, 0.0, float(k)], [1.0, 0.0, float(k)])
        for k in range(MAX_HOLES + 1 - len(holes))))
    r = client.post("/drill-plans/read", content=write_iredes(too_many).encode(), headers=XML)
    assert r.status_code == 413
    assert r.json()["detail"][0]["loc"] == ["body", "DrillPlan"]
