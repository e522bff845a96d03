"""The ``path`` and ``path_compare`` job kinds through the API: 422s naming the scene field,
a planned path, an arm path with joints and cylinders, and the paper's unreachable goal."""

from __future__ import annotations

import math

import pytest

SCENE = {"bounds": [[0, 0, 0], [100, 100, 100]],
         "obstacles": [{"center": [30, 30, 30], "radius": 12},
                       {"center": [55, 50, 55], "radius": 12},
                       {"type": "box", "lower": [70, 70, 60], "upper": [85, 85, 80]}]}
START, GOAL = [1, 1, 1], [100, 100, 100]


@pytest.fixture
def client(tmp_path):
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=2))) as c:
        yield c


def submit(client, kind: str, params: dict):
    return client.post("/jobs", json={"kind": kind, "params": params})


@pytest.mark.slow
@pytest.mark.parametrize("change, loc, words", [
    (lambda p: p["scene"]["obstacles"][2].pop("upper") and
     p["scene"]["obstacles"][1].update(radius=-3),
     ["body", "params", "scene", "obstacles", 1, "radius"], "greater than 0"),
    (lambda p: p.update(start=[30, 30, 35]), ["body", "params", "start"],
     "inside obstacles[0]"),
    (lambda p: p.update(goal=[100, 100, 101]), ["body", "params", "goal"], "outside bounds"),
    (lambda p: p["scene"]["obstacles"][2].update(upper=[60, 90, 90]),
     ["body", "params", "scene", "obstacles", 2, "upper"], "must exceed lower"),
    (lambda p: p.update(algorithm="wolfpack", params={"wolves": 3}),
     ["body", "params", "params", "wolves"], "not a parameter of wolfpack"),
    (lambda p: p.update(algorithm="ga", params={"iterations": 1e12}),
     ["body", "params", "params", "iterations"], "less than or equal to 20000"),
    (lambda p: p.update(algorithm="rrt_star", params={"samples": 10**9}),
     ["body", "params", "params", "samples"], "params.samples"),
])
def test_bad_scenes_are_422_naming_the_field(client, change, loc, words):
    import copy

    params = {"scene": copy.deepcopy(SCENE), "start": START, "goal": GOAL}
    change(params)
    r = submit(client, "path", params)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"] == loc and words in detail["msg"]


ARM_SCENE = {"bounds": [[-2500, -2500, -1500], [2500, 2500, 2000]],
             "obstacles": [{"center": [1467.8, -709.0, 37.6], "radius": 200}],
             "safety_margin": 10}
#: Tool positions of pile_driver at q = (-0.9, 0.5, -0.6, -0.4, 0, 0) and (0, 0.5, ...).
ARM_START = [1125.2917429, -1418.04563696, 267.5709755]
ARM_GOAL = [1810.28587111, 0.0, 267.5709755]


@pytest.mark.slow
def test_path_jobs_through_the_api(client):
    """Four jobs at once (two workers): a path, an arm path, the paper's unreachable goal and
    a comparison. Each worker process pays the planning imports, so they share one test."""
    from planning.paths.scene import Scene

    from .conftest import wait_for

    jobs = {
        "path": ("path", {"scene": SCENE, "start": START, "goal": GOAL, "algorithm": "auto"}),
        "arm": ("path", {"scene": ARM_SCENE, "start": ARM_START, "goal": ARM_GOAL,
                         "robot": "pile_driver", "arm": {"dt": 0.5}}),
        "far": ("path", {"scene": ARM_SCENE, "start": ARM_START, "goal": [1800, 1800, 800],
                         "robot": "pile_driver"}),
        "compare": ("path_compare", {
            "scene": SCENE, "start": START, "goal": GOAL, "runs": 2,
            "algorithms": ["wolfpack_improved", "auto"],
            "params": {"wolfpack_improved": {"iterations": 5, "n_wolves": 20}}}),
    }
    ids = {}
    for name, (kind, params) in jobs.items():
        r = submit(client, kind, params)
        assert r.status_code == 202, r.text
        ids[name] = r.json()["id"]
    out = {}
    for name, job_id in ids.items():
        job = wait_for(client, job_id, timeout=120)
        assert job["status"] == "succeeded", job
        out[name] = client.get(f"/jobs/{job_id}/result").json()

    path = out["path"]
    assert path["success"] and path["path"][0] == START and path["path"][-1] == GOAL
    assert Scene.from_dict(SCENE).path_is_clear(path["path"])
    assert path["length"] > 0 and path["min_clearance"] >= 0 and path["joint_path"] is None

    arm = out["arm"]
    assert arm["success"], arm["message"]
    t = arm["trajectory"]["t"]  # every 0.5 s, the end included
    assert len(arm["joint_path"][0]) == 6 and len(t) == math.floor(t[-1] / 0.5 + 1e-9) + 2
    assert set(arm["cylinders"]["lengths"]) >= {"boom", "stick", "four_bar"}
    assert arm["cylinders"]["within_stroke"] is True

    assert out["far"]["success"] is False and "unreachable" in out["far"]["message"]
    assert out["far"]["path"] == []

    rows = {r["algorithm"]: r for r in out["compare"]["rows"]}
    assert set(rows) == {"wolfpack_improved", "auto"} and rows["auto"]["successes"] == 2
    assert rows["auto"]["best_length"] <= rows["wolfpack_improved"]["best_length"] + 1e-6
