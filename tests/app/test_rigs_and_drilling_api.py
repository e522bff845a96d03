"""GET /rigs and POST /robots/{id}/drill-ik."""

from __future__ import annotations

import numpy as np


def test_rigs_list_the_jumbo_and_its_arms(ro_client):
    rigs = ro_client.get("/rigs").json()
    jumbo = next(r for r in rigs if r["id"] == "tunnel_jumbo")
    assert [a["name"] for a in jumbo["arms"]] == ["left", "middle", "right"]
    ids = [a["robot"] for a in jumbo["arms"]]
    listed = {r["id"]: r for r in ro_client.get("/robots").json()}
    for robot_id in ids:
        assert listed[robot_id]["builtin"] and listed[robot_id]["dof"] == 7
    # Same joints, base shifted by the mount.
    q = [0.1, -1.6, 6000, 0, 1.6, 1.47, 4022]
    middle = np.asarray(ro_client.post("/robots/tunnel_jumbo-middle/fk", json={"q": q})
                        .json()["poses"][0])
    left = np.asarray(ro_client.post("/robots/tunnel_jumbo-left/fk", json={"q": q})
                      .json()["poses"][0])
    mount = np.asarray(jumbo["arms"][0]["base"])
    np.testing.assert_allclose(left, mount @ middle, atol=1e-6)
    assert ro_client.get("/rigs/tunnel_jumbo").json()["robots"]["left"] == ids[0]
    assert ro_client.get("/rigs/nope").status_code == 404


def test_drill_ik_reproduces_table3(ro_client, paper_tables):
    row = paper_tables["tunnel_drill_arm"]["table3"][1]
    r = ro_client.post("/robots/tunnel_drill_arm/drill-ik", json={"holes": [row["xyz"]]})
    assert r.status_code == 200, r.text
    res = r.json()["results"][0]
    assert res["success"] and res["position_error"] < 1e-6
    q = np.asarray(res["q"])
    expected = [row["q"]["theta1_deg"], row["q"]["theta2_deg"], row["q"]["theta4_deg"],
                row["q"]["theta5_deg"], row["q"]["theta6_deg"]]
    np.testing.assert_allclose(np.degrees(q[[0, 1, 3, 4, 5]]), expected, atol=0.05)
    assert abs(q[2] - row["q"]["d3_mm"]) < 1.0


def test_drill_ik_errors(ro_client):
    far = ro_client.post("/robots/tunnel_drill_arm/drill-ik", json={"holes": [[20000, 0, 0]]})
    res = far.json()["results"][0]
    assert far.status_code == 200 and not res["success"] and "telescope" in res["message"]
    r = ro_client.post("/robots/glt_palletizer/drill-ik", json={"holes": [[1, 2, 3]]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["path", "robot_id"]
    r = ro_client.post("/robots/tunnel_drill_arm/drill-ik", json={"holes": [[1, 2]]})
    assert r.status_code == 422 and "holes" in r.json()["detail"][0]["loc"]
    # beyond 10 km: refused before any arithmetic could overflow
    r = ro_client.post("/robots/tunnel_drill_arm/drill-ik", json={"holes": [[1e8, 0, 1e300]]})
    assert r.status_code == 422
    assert [e["loc"] for e in r.json()["detail"]] == [["body", "holes", 0, 0],
                                                     ["body", "holes", 0, 2]]
