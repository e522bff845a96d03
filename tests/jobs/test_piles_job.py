"""The ``piles`` job over REST: params refused naming the field (a plan row and column, the
set-ups, the caps), and a small plan end to end through the job backend, its result checked
by FK and its site map drawn."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.library import builtin_model

from .conftest import wait_for

H = 500.0


def pile_at(q, setup=(0.0, 0.0, 0.0), pid="P") -> dict:
    """A plan row the pile driver at ``q`` holds exactly from ``setup`` (FK, site frame;
    the mast is the tool's y axis)."""
    model = builtin_model("pile_driver")
    T = fk(model, np.asarray(q, dtype=float))
    c, s = math.cos(setup[2]), math.sin(setup[2])
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    d = R @ T[:3, 1]
    p = R @ T[:3, 3] + np.array([setup[0], setup[1], H])
    return {"id": pid, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
            "inclination": math.acos(-d[2]), "azimuth": math.atan2(d[1], d[0])}


def params(**extra) -> dict:
    plan = [pile_at([0.0, 0.2, -0.8, -0.8, 0.0, -1.3], pid="A"),
            pile_at([0.7, 0.3, -0.8, -0.6, 0.1, -1.2], pid="B"),
            {"id": "far", "x": 30_000, "y": 0, "z": 0}]
    return {"plan": plan, "setups": {"positions": [[0, 0, 0], [5000, 0, 0]]},
            "drive_time": 20.0, **extra}


@pytest.mark.parametrize("change, loc", [
    (lambda p: p["plan"][1].update(x="north"), ["body", "params", "plan", 1, "x"]),
    (lambda p: p["plan"][0].update(rake="1:3", inclination=0.1),
     ["body", "params", "plan", 0, "rake"]),
    (lambda p: p["plan"][2].pop("z"), ["body", "params", "plan", 2, "z"]),
    (lambda p: p.update(plan=None, plan_csv="id,x,y,z\nA,0,0,0\nB,1,1,1:5\n"),
     ["body", "params", "plan_csv", 1, "z"]),
    (lambda p: p.update(setups={"polygon": [[0, 0], [10, 0], [0, 10]]}),
     ["body", "params", "setups", "spacing"]),
    (lambda p: p.update(setups={"polygon": [[0, 0], [1e6, 0], [0, 1e6]], "spacing": 100}),
     ["body", "params", "setups", "spacing"]),
    (lambda p: p.update(plan=[{"id": str(k), "x": k, "y": 0, "z": 0} for k in range(2001)]),
     ["body", "params", "plan"]),
    (lambda p: p.update(plan_csv="id,x,y,z\nA,0,0,0\n"), ["body", "params", "plan"]),
])
def test_bad_params_are_a_422_naming_the_field(checking_client, change, loc):
    body = params()
    change(body)
    r = checking_client.post("/jobs", json={"kind": "piles", "params": body})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == loc


@pytest.mark.slow
def test_a_pile_plan_job_end_to_end(jobs_client):
    body = params(scene={"objects": [{"type": "box", "id": "shed", "size": [600, 600, 2500],
                                      "pose": [[1, 0, 0, -2500], [0, 1, 0, 0],
                                               [0, 0, 1, 1250], [0, 0, 0, 1]]}]})
    r = jobs_client.post("/jobs", json={"kind": "piles", "params": body})
    assert r.status_code == 202, r.text
    job = wait_for(jobs_client, r.json()["id"], timeout=120)
    assert job["status"] == "succeeded", job
    assert job["progress"] == 1.0
    res = jobs_client.get(f"/jobs/{job['id']}/result").json()
    assert res["piles_total"] == 3 and res["piles_reached"] == 2
    assert res["unreached"] == [{"id": "far", "reason": "from every candidate set-up: out "
                                 "of the arm's reach"}]
    assert len(res["setups"]) == 1 and res["setups"][0]["candidate"] == 0
    assert res["cover"]["method"] == "milp" and res["cover"]["optimal"]
    model = builtin_model("pile_driver")
    rows = {p["id"]: p for p in body["plan"]}
    for k, pile in enumerate(res["piles"]):
        assert pile["order"] == k
        T = fk(model, np.array(pile["q"]))
        row = rows[pile["id"]]
        i, a = row["inclination"], row["azimuth"]
        axis = np.array([math.sin(i) * math.cos(a), math.sin(i) * math.sin(a), -math.cos(i)])
        assert math.acos(min(1.0, float(T[:3, 1] @ axis))) <= 0.02
        assert np.linalg.norm(T[:3, 3] + [0, 0, H] - [row["x"], row["y"], row["z"]]) <= 0.5
        assert pile["drive_s"] == 20.0 and pile["end"] > pile["start"]
    assert res["cycle_time_s"] == pytest.approx(res["piles"][-1]["end"])
    plot = jobs_client.get(f"/jobs/{job['id']}/plot")
    assert plot.status_code == 200 and plot.headers["content-type"] == "image/png"
    assert plot.content[:8] == b"\x89PNG\r\n\x1a\n"
