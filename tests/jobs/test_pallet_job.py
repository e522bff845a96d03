"""The ``pallet`` job kind over REST: a small pallet planned end to end through the job
backend, its result valid against the published schema, its layer map served as a PNG, and
422s naming the field at fault (the caps included)."""

from __future__ import annotations

import math
import time

import jsonschema
import pytest

PICK = [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]]
PARAMS = {"robot": "glt_palletizer", "box": {"size": [400, 300, 250], "mass": 12.5},
          "pick": PICK, "pattern": "interlocked", "layers": 2, "count": 3,
          "pallet": {"overhang": 10}, "time_limit": 10}


@pytest.mark.slow
def test_a_pallet_job_runs_end_to_end_and_its_result_validates(jobs_client):
    c = jobs_client
    r = c.post("/jobs", json={"kind": "pallet", "params": PARAMS})
    assert r.status_code == 202, r.text
    seen = set()
    deadline = time.monotonic() + 180.0
    while (job := c.get(f"/jobs/{r.json()['id']}").json())["status"] in ("queued", "running"):
        seen.add((job["progress"], job["message"]))
        assert time.monotonic() < deadline
        time.sleep(0.05)
    assert job["status"] == "succeeded", job
    # Progress is reported box by box.
    boxes = {m.split(":")[0] for _, m in seen if m.startswith("box ")}
    assert {"box 1 of 3", "box 2 of 3"} <= boxes, seen
    result = c.get(f"/jobs/{job['id']}/result").json()
    schema = next(k for k in c.get("/jobs/kinds").json() if k["kind"] == "pallet")
    jsonschema.validate(result, schema["result_schema"], cls=jsonschema.Draft202012Validator)
    assert result["placed"] == result["total"] == 3
    assert [b["status"] for b in result["boxes"]] == ["placed"] * 3
    assert result["mass"] == pytest.approx(3 * 12.5)
    assert result["pallet_s"] == pytest.approx(sum(b["cycle_s"] for b in result["boxes"]))
    assert result["boxes_per_hour"] == pytest.approx(3 * 3600 / result["pallet_s"])
    # Interlocked, 400 x 300 on the EUR pallet with 10 mm of overhang: 8 turned boxes on
    # the first layer, 6 along on the second; three boxes fill part of the first.
    assert result["per_layer"] == [3]
    for b in result["boxes"]:
        assert b["tilt"] <= 0.05 and len(b["q_place"]) == 6
        assert b["placed_pose"][2][3] == pytest.approx(144 + 125, abs=0.5)
    png = c.get(f"/jobs/{job['id']}/plot")
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content[:8] == b"\x89PNG\r\n\x1a\n" and len(png.content) > 5000


@pytest.mark.parametrize("change, loc", [
    ({"count": 2001}, ["count"]),
    ({"box": {"size": [40, 40, 10]}, "count": None, "layers": 100}, ["layers"]),
    ({"pattern": [[850, 0, 269, 0]] * 2001}, ["pattern"]),
    ({"pattern": "pinwheel"}, ["pattern"]),
    ({"pallet": {"pose": [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]]}},
     ["pallet", "pose"]),
    ({"obstacles": [{"type": "box", "id": "post", "size": [1, 2]}]},
     ["obstacles", 0, "size"]),
    ({"tilt_tolerance": 0}, ["tilt_tolerance"]),
    ({"time_limit": 61}, ["time_limit"]),
    ({"pick": [PICK] * 17}, ["pick"]),
    ({"box": {"size": [400, 300]}}, ["box", "size"]),
])
def test_bad_params_are_422_naming_the_field(checking_client, change, loc):
    params = {k: v for k, v in {**PARAMS, **change}.items() if v is not None}
    r = checking_client.post("/jobs", json={"kind": "pallet", "params": params})
    assert r.status_code in (413, 422), r.text
    assert r.json()["detail"][0]["loc"][:2 + len(loc)] == ["body", "params", *loc], r.text


def test_the_kind_is_published_with_its_plot_and_caps(checking_client):
    kinds = {k["kind"]: k for k in checking_client.get("/jobs/kinds").json()}
    pallet = kinds["pallet"]
    assert pallet["plot"] is True
    props = pallet["params_schema"]["properties"]
    assert props["count"]["anyOf"][0]["maximum"] == 2000
    assert math.isclose(props["tilt_tolerance"]["default"], 0.05)
