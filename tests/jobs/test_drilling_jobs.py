"""The ``sequence`` and ``multiarm`` job kinds (paper 002) through the API: 422s naming the
field and the hole, a drilling order and a small whole-face plan run by the job pool."""

from __future__ import annotations

import json

import numpy as np
import pytest

from .conftest import wait_for

FACE = [[9000, 0, 0], [9000, 1200, 300], [9000, -800, 900], [9000, 400, 2000],
        [9000, -1500, 2500], [9000, 2000, 1500]]
SIDES = {"left": [[9000, 2600, 300], [9000, 3400, 1500]],
         "middle": [[9000, 0, 2400], [9000, 1000, 4300], [9000, -1100, 800]],
         "right": [[9000, -2600, 500], [9000, -3500, 2000]]}


@pytest.fixture
def client(tmp_path):
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path))) as c:
        yield c


def submit(client, kind: str, params: dict):
    # json.dumps writes NaN as a bare token, as a careless client would
    return client.post("/jobs", content=json.dumps({"kind": kind, "params": params}),
                       headers={"content-type": "application/json"})


def run(client, kind: str, params: dict) -> dict:
    r = submit(client, kind, params)
    assert r.status_code == 202, r.text
    job = wait_for(client, r.json()["id"], timeout=180)
    assert job["status"] == "succeeded", job
    return client.get(f"/jobs/{job['id']}/result").json()


@pytest.mark.parametrize(("kind", "params", "loc", "words"), [
    ("sequence", {"holes": [[0, 0, 0], [1000, 0, 0], [0, 0, 0.5]]}, ["holes"],
     "holes[2]: duplicate of holes[0]"),
    ("sequence", {"holes": [[0, 0, 0]]}, ["holes"], "at least 2"),
    ("sequence", {"holes": [[0, 0, 0], [1, 2, float("nan")]]}, ["holes", 1, 2], "finite"),
    ("sequence", {"holes": FACE, "algorithm": "lkh"}, ["algorithm"], "iga"),
    ("sequence", {"holes": FACE, "algorithm": "aco", "params": {"wolves": 3}}, ["params"],
     "params.wolves"),
    ("sequence", {"holes": FACE, "params": {"kicks": 10**9}}, ["params"], "kicks"),
    ("multiarm", {"holes": {"left": [[9000, -7000, 1000]], "middle": [[9000, 0, 1000]]}},
     ["holes"], "holes.left[0]"),
    ("multiarm", {"holes": {"left": [[9000, 0, 1000]], "middle": [[9000, 0, 1000]]}},
     ["holes"], "holes.middle[0]: duplicate of holes.left[0]"),
    ("multiarm", {"holes": {"left": [[9000, 3000, 1000]]}}, ["holes"], "at least 2"),
    ("multiarm", {"holes": SIDES, "face": {}}, [], "exactly one"),
    ("multiarm", {"rig": "nope", "holes": SIDES}, ["rig"], "unknown rig"),
    ("multiarm", {"holes": SIDES, "planner_params": {"lam": 1}}, ["planner_params"],
     "planner_params.lam"),
    ("multiarm", {"face": {"width": 10000, "height": 3000}}, ["face"], "height"),
    ("sequence", {"holes": FACE, "cost": "energy"}, ["cost"], "'distance' or 'time'"),
    ("multiarm", {"holes": SIDES, "cost": "fast"}, ["cost"], "'distance' or 'time'"),
    ("sequence", {"holes": FACE, "cost": "time", "arm": "top"}, ["arm"], "no arm 'top'"),
    ("sequence", {"holes": FACE, "cost": "time", "rig": "nope"}, ["rig"], "unknown rig"),
    ("sequence", {"holes": [[9000, 0, 0], [9000, 0, 40000]], "cost": "time"}, ["holes", 1],
     "holes[1]: out of reach of the middle arm"),
    ("sequence", {"holes": FACE, "cost": "time", "start": [9000, 0, 40000]}, ["start"],
     "start: the middle arm cannot drill there"),
])
def test_bad_params_are_422_naming_the_field(checking_client, kind, params, loc, words):
    r = submit(checking_client, kind, params)
    assert r.status_code == 422, r.text
    err = r.json()["detail"][0]
    assert err["loc"][: 2 + len(loc)] == ["body", "params", *loc], err
    assert words in err["msg"], err


@pytest.mark.slow
def test_sequence_job(client):
    out = run(client, "sequence", {"holes": FACE, "start": [9000, 0, -1000],
                                   "algorithm": "iga", "seed": 3,
                                   "params": {"iterations": 40}})
    assert sorted(out["order"]) == list(range(len(FACE)))
    H = np.array(FACE, dtype=float)[out["order"]]
    length = np.linalg.norm(H[0] - [9000, 0, -1000]) + np.linalg.norm(np.diff(H, axis=0),
                                                                       axis=1).sum()
    assert out["length"] == pytest.approx(length)
    assert len(out["convergence"]) == 40 and out["convergence"][-1] == pytest.approx(length)
    assert out["runtime_s"] >= 0 and out["algorithm"] == "iga"
    # auto is exact on six holes and no worse
    best = run(client, "sequence", {"holes": FACE, "start": [9000, 0, -1000]})
    assert best["length"] <= out["length"] + 1e-6


@pytest.mark.slow
def test_multiarm_job(client):
    out = run(client, "multiarm", {"holes": SIDES, "planner": "iapf", "seed": 0,
                                   "output_dt": 1.0})
    assert out["success"], out["messages"]
    assert out["collisions"] == 0 and out["check_dt"] == pytest.approx(0.01)
    n = len(out["t"])
    assert set(out["min_distance"]) == {"left-middle", "left-right", "middle-right"}
    for pair, d in out["min_distance"].items():
        assert len(d) == n and min(d) > 0
        assert out["min_distance_overall"][pair] == pytest.approx(min(d))
    for arm, a in out["arms"].items():
        assert len(a["q"]) == n and len(a["q"][0]) == 7
        assert len(a["holes"]) == len(SIDES[arm])
        assert a["max_rotational_acceleration"] <= out["acceleration_bound"] == 0.25
        assert a["travel_m"] > 0
    assert out["total_travel_m"] == pytest.approx(sum(out["travel_m"].values()))


def test_sequence_job_by_boom_time(client):
    """Cost 'time': the order of least boom travel time (IK branches chosen with it), its
    time beside the shortest-path order's, and the saving; the default stays 'distance'."""
    start = [9000, 0, -500]
    out = run(client, "sequence", {"holes": FACE, "start": start, "cost": "time", "seed": 1})
    assert out["cost"] == "time" and sorted(out["order"]) == list(range(len(FACE)))
    assert out["boom_time_s"] <= out["boom_time_distance_order_s"] + 1e-9
    assert out["boom_time_saved_s"] == pytest.approx(
        out["boom_time_distance_order_s"] - out["boom_time_s"])
    assert len(out["q"]) == len(out["rolls"]) == len(FACE)
    assert out["rolls"] == [q[3] for q in out["q"]]
    H = np.array(FACE, dtype=float)
    for name, order in (("length", out["order"]),
                        ("distance_order_length", out["distance_order"])):
        path = np.vstack([start, H[order]])
        assert out[name] == pytest.approx(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    plain = run(client, "sequence", {"holes": FACE, "start": start, "seed": 1})
    assert plain["cost"] == "distance" and "boom_time_s" not in plain
    assert plain["order"] == out["distance_order"]


@pytest.mark.slow
def test_multiarm_job_by_boom_time(client):
    out = run(client, "multiarm", {"holes": SIDES, "cost": "time", "seed": 0,
                                   "output_dt": 1.0})
    assert out["success"], out["messages"]
    assert out["cost"] == "time"
    arms = out["arms"].values()
    assert out["boom_time_s"] == pytest.approx(sum(a["boom_time_s"] for a in arms))
    assert out["boom_time_distance_order_s"] == pytest.approx(
        sum(a["boom_time_distance_order_s"] for a in arms))
    assert out["boom_time_saved_s"] >= -1e-9
    for a in arms:
        assert 0 < a["boom_time_s"] <= a["boom_time_distance_order_s"] + 1e-9
