"""Job limits: capped planner knobs (in the schema too), the params size, depth and NaN checks,
the per-job time limit, and the paginated job list."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import time
from dataclasses import dataclass

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs import planner_params
from app.jobs.caps import MAX_PARAMS_BYTES, MAX_PARAMS_DEPTH, check_params
from app.jobs.catalog import KINDS
from app.jobs.kinds import Params
from app.jobs.tracking_kinds import MAX_STEPS, MAX_TUNING_WORK
from app.main import create_app
from app.store import _MIGRATIONS, Store
from planning.registry import FAMILIES, Algorithm

from .conftest import wait_for

SCENE = {"bounds": [[0, 0, 0], [100, 100, 100]],
         "obstacles": [{"center": [50, 50, 50], "radius": 10}]}
FACE = [[9000, 0, 0], [9000, 1200, 300], [9000, -800, 900], [9000, 400, 2000]]
SIDES = {"left": [[9000, 2600, 300], [9000, 3400, 1500]],
         "middle": [[9000, 0, 300], [9000, 0, 1500]],
         "right": [[9000, -2600, 300], [9000, -3400, 1500]]}
LINE = {"kind": "line"}


@pytest.fixture
def client(tmp_path):
    """An app whose job backend does not run: submitted jobs stay queued."""
    return TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path)))


def post(client, kind: str, params: dict, **body):
    return client.post("/jobs", json={"kind": kind, "params": params, **body})


def raw_post(client, text: str):
    """A body as a careless client writes it: NaN and Infinity as bare tokens."""
    return client.post("/jobs", content=text, headers={"content-type": "application/json"})


def error(r, status: int = 422) -> dict:
    assert r.status_code == status, r.text
    return r.json()["detail"][0]


# ---- caps on every knob ------------------------------------------------------------------
@pytest.mark.parametrize("kind, params, loc, words", [
    ("path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99], "algorithm": "ga",
              "params": {"iterations": 1e12}}, ["params", "iterations"], "params.iterations"),
    ("path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99],
              "algorithm": "wolfpack", "params": {"n_wolves": 10**6}},
     ["params", "n_wolves"], "less than or equal to 1000"),
    ("path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99], "algorithm": "aca",
              "params": {"grid": 10**4}}, ["params", "grid"], "params.grid"),
    ("path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99], "algorithm": "auto",
              "params": {"samples": 10**7}}, ["params", "samples"], "params.samples"),
    ("path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99],
              "algorithm": "afsa", "params": {"visual": 1e300}},
     ["params", "visual"], "params.visual"),
    ("path_compare", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99],
                      "algorithms": ["ga", "wolfpack"],
                      "params": {"wolfpack": {"iterations": 1e12}}},
     ["params", "wolfpack", "iterations"], "params.wolfpack.iterations"),
    ("path_compare", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99],
                      "runs": 10**6}, ["runs"], "less than or equal"),
    ("sequence", {"holes": FACE, "algorithm": "iga", "params": {"population": 10**6}},
     ["params", "population"], "params.population"),
    ("sequence", {"holes": FACE, "algorithm": "aco", "params": {"ants": 10**9}},
     ["params", "ants"], "params.ants"),
    ("multiarm", {"holes": SIDES, "planner": "rrt", "planner_params": {"edge_resolution": 0}},
     ["planner_params", "edge_resolution"], "planner_params.edge_resolution"),
    ("multiarm", {"holes": SIDES, "sequencer": "iga",
                  "sequencer_params": {"iterations": 10**9}},
     ["sequencer_params", "iterations"], "sequencer_params.iterations"),
    ("workspace", {"robot": "pile_driver", "samples": 10**9}, ["samples"], "less than"),
    ("ik_train", {"robot": "glt_palletizer", "samples": 10**7}, ["samples"], "less than"),
    ("ik_train", {"robot": "glt_palletizer", "test_fraction": 0.9}, ["test_fraction"],
     "less than"),
    ("ik_train", {"robot": "glt_palletizer", "validation_samples": 10**6},
     ["validation_samples"], "less than"),
    ("calibrate", {"robot": "glt_palletizer", "parameters": ["base.z"],
                   "measurements": [{"q": [1e300] * 6, "position": [0, 0, 0]}]},
     ["measurements", 0, "q", 0], "less than"),
    ("tracking", {"task": LINE, "q0": [1e300] * 9}, ["q0", 0], "less than"),
    ("sleep", {"seconds": 1e12}, ["seconds"], "less than"),
])
def test_a_knob_over_its_cap_is_422_naming_it(checking_client, kind, params, loc, words):
    before = len(checking_client.get("/jobs").json())
    err = error(post(checking_client, kind, params))
    assert err["loc"] == ["body", "params", *loc], err
    assert words in err["msg"], err
    assert len(checking_client.get("/jobs").json()) == before  # nothing queued


def test_knobs_within_their_caps_are_kept_as_given(client):
    r = post(client, "path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99],
                              "algorithm": "ga", "params": {"iterations": 20.0}})
    assert r.status_code == 202, r.text
    assert r.json()["params"]["params"] == {"iterations": 20}  # coerced, nothing added


def test_cross_knob_checks_still_apply(client):
    err = error(post(client, "path", {"scene": SCENE, "start": [1, 1, 1],
                                      "goal": [99, 99, 99], "algorithm": "ga",
                                      "params": {"population": 4, "elite": 4}}))
    assert err["loc"] == ["body", "params", "params"] and "elite" in err["msg"]


def test_tracking_work_is_capped(client):
    steps = int(30 / 0.01)  # the default ellipse at dt 0.01
    err = error(post(client, "tracking", {"task": {"kind": "ellipse"}, "tune": "hgso",
                                          "runs": 30, "iterations": 200, "dt": 0.01}))
    assert err["loc"] == ["body", "params"] and f"{MAX_TUNING_WORK:,}" in err["msg"]
    assert steps * 201 * 30 > MAX_TUNING_WORK
    err = error(post(client, "tracking", {"task": {"kind": "line", "duration": 600},
                                          "dt": 0.01}))
    assert "dt" in err["msg"] and f"{MAX_STEPS:,}" in err["msg"]
    ok = post(client, "tracking", {"task": {"kind": "ellipse"}, "tune": "hgso", "runs": 30})
    assert ok.status_code == 202, ok.text  # the paper's 30 tuned runs fit


def test_tracking_step_cap_matches_the_simulator():
    from planning.tracking import simulator

    assert MAX_STEPS == simulator.MAX_STEPS


def test_arm_trajectory_samples_are_capped(client):
    err = error(post(client, "path", {"scene": SCENE, "start": [1, 1, 1],
                                      "goal": [99, 99, 99], "robot": "pile_driver",
                                      "arm": {"duration": 86_400, "dt": 0.001}}))
    assert err["loc"][:3] == ["body", "params", "arm"] and "samples" in err["msg"]


def test_one_batch_of_obstacle_checks_must_fit_in_memory(client):
    """500 boxes x wolfpack's 1000 candidate paths of 6 segments: ~10 GiB at once."""
    boxes = [{"type": "box", "center": [5 + 9 * (k % 10), 5 + 9 * (k // 10 % 10),
                                        20 + 12 * (k // 100)], "size": [2, 2, 2]}
             for k in range(500)]
    scene = {"bounds": [[0, 0, 0], [100, 100, 100]], "obstacles": boxes}
    params = {"scene": scene, "start": [1, 1, 1], "goal": [99, 99, 99],
              "algorithm": "wolfpack"}
    err = error(post(client, "path", params))
    assert err["loc"] == ["body", "params"] and "GiB" in err["msg"], err
    params["params"] = {"n_wolves": 20, "directions": 5}  # a smaller pack fits
    assert post(client, "path", params).status_code == 202


def test_every_planner_dataclass_field_has_a_cap(monkeypatch):
    @dataclass(frozen=True)
    class Planner:
        iterations: int = dataclasses.field(default=10, metadata={"ge": 1, "le": 100})
        fresh_knob: int = 3

    monkeypatch.setitem(FAMILIES["path"].algorithms, "x", Algorithm("path", "x", Planner))
    with pytest.raises(TypeError, match="fresh_knob"):
        planner_params.knobs_model("path", "x")


def _unbounded(schema: dict) -> list[str]:
    """Paths of the numbers in a JSON schema without both a lower and an upper bound."""
    defs, out, seen = schema.get("$defs", {}), [], set()

    def walk(node, path):
        if isinstance(node, list):
            for i, item in enumerate(node):
                walk(item, [*path, i])
            return
        if not isinstance(node, dict):
            return
        if "$ref" in node:
            name = node["$ref"].rsplit("/", 1)[-1]
            if name not in seen:
                seen.add(name)
                walk(defs[name], [*path, name])
            return
        if node.get("type") in ("number", "integer"):
            low = "minimum" in node or "exclusiveMinimum" in node
            high = "maximum" in node or "exclusiveMaximum" in node
            if not (low and high):
                out.append(".".join(map(str, path)))
        for key, value in node.items():
            if key not in ("$defs", "default", "examples"):
                walk(value, [*path, key])

    walk(schema, [])
    return out


def test_every_number_of_every_kind_is_bounded_in_the_schema(client):
    kinds = {k["kind"]: k["params"] for k in client.get("/jobs/kinds").json()}
    assert set(kinds) >= {"sleep", "echo", "workspace", "calibrate", "ik_train", "path",
                          "path_compare", "tracking", "sequence", "multiarm"}
    assert set(kinds) == set(KINDS)
    for name, schema in kinds.items():
        assert _unbounded(schema) == [], name


def test_the_caps_show_in_the_published_schemas(client):
    kinds = {k["kind"]: k["params"] for k in client.get("/jobs/kinds").json()}
    planners = {s["title"]: s for s in kinds["path"]["properties"]["params"]["anyOf"]
                if s.get("type") == "object"}
    assert planners["ga params"]["properties"]["iterations"]["maximum"] == 20_000
    assert planners["ga params"]["properties"]["population"]["default"] == 5  # paper 000
    assert planners["wolfpack params"]["additionalProperties"] is False
    compare = kinds["path_compare"]["properties"]["params"]["anyOf"][0]["properties"]
    assert compare["aca"]["properties"]["grid"]["maximum"] == 101
    sequencers = {s["title"]: s for s in kinds["sequence"]["properties"]["params"]["anyOf"]
                  if s.get("type") == "object"}
    assert sequencers["iga params"]["properties"]["iterations"]["maximum"] == 5000
    doc = client.get("/openapi.json").json()
    body = doc["components"]["schemas"]["JobRequest"]["properties"]
    assert body["time_limit_s"]["anyOf"][0]["maximum"] == 7 * 86_400
    query = {p["name"]: p for p in doc["paths"]["/jobs"]["get"]["parameters"]}
    assert query["limit"]["schema"]["maximum"] == 1000
    assert query["limit"]["schema"]["default"] == 100


# ---- params: size, depth, finite numbers --------------------------------------------------
def test_params_over_the_size_cap_are_413_before_validation(client, monkeypatch):
    class Exploding(Params):
        @classmethod
        def model_validate(cls, *args, **kwargs):
            raise AssertionError("validated an oversized submission")

    monkeypatch.setitem(KINDS, "echo", dataclasses.replace(KINDS["echo"], params=Exploding))
    err = error(post(client, "echo", {"value": "x" * 2_000_000}), 413)
    assert err["loc"] == ["body", "params"] and err["type"] == "too_large"
    assert f"{MAX_PARAMS_BYTES:,}" in err["msg"]
    assert client.get("/jobs").json() == []


@pytest.mark.slow
def test_calibration_takes_more_params_than_other_kinds(client):
    """10,000 measured positions are about 2 MiB of JSON: within calibrate's own cap."""
    kinds = {k["kind"]: k for k in client.get("/jobs/kinds").json()}
    assert kinds["echo"]["max_params_bytes"] == MAX_PARAMS_BYTES
    assert kinds["calibrate"]["max_params_bytes"] == 4 << 20
    rng = np.random.default_rng(0)
    meas = [{"q": q.tolist(), "position": p.tolist()}
            for q, p in zip(rng.uniform(-1, 1, (10_000, 6)), rng.uniform(-900, 900, (10_000, 3)))]
    params = {"robot": "glt_palletizer", "parameters": ["base.z"], "measurements": meas}
    assert len(json.dumps(params)) > 1.9 * MAX_PARAMS_BYTES
    assert post(client, "calibrate", params).status_code == 202
    err = error(post(client, "echo", {"value": meas}), 413)
    assert err["loc"] == ["body", "params"]


def test_params_just_under_the_size_cap_are_accepted(client):
    value = "x" * (MAX_PARAMS_BYTES - 100)
    assert post(client, "echo", {"value": value}).status_code == 202


def nested(depth: int):
    value: object = 1
    for _ in range(depth):
        value = [value]
    return value


def test_deeply_nested_params_are_422_naming_the_field(client):
    for depth in (100, 256):
        err = error(post(client, "echo", {"value": nested(depth)}))
        assert err["loc"][:4] == ["body", "params", "value", 0], err
        assert f"deeper than {MAX_PARAMS_DEPTH}" in err["msg"]
    # params is level 1, so its value may hold 31 more levels
    assert post(client, "echo", {"value": nested(MAX_PARAMS_DEPTH - 1)}).status_code == 202
    assert post(client, "echo", {"value": nested(MAX_PARAMS_DEPTH)}).status_code == 422


@pytest.mark.parametrize("text, loc", [
    ('{"kind": "echo", "params": {"value": NaN}}', ["value"]),
    ('{"kind": "echo", "params": {"value": [1, {"a": Infinity}]}}', ["value", 1, "a"]),
    ('{"kind": "echo", "params": {"value": {"b": -Infinity}}}', ["value", "b"]),
    ('{"kind": "echo", "params": {"value": 1e999}}', ["value"]),
    ('{"kind": "sequence", "params": {"holes": [[0, 0, 0], [1000, 0, 0]], "algorithm": "iga",'
     ' "params": {"cooling": NaN}}}', ["params", "cooling"]),
])
def test_non_finite_numbers_anywhere_are_422_naming_the_field(client, text, loc):
    err = error(raw_post(client, text))
    assert err["loc"] == ["body", "params", *loc], err
    assert "finite" in err["msg"]
    assert client.get("/jobs").json() == []


def test_check_params_alone():
    check_params({"a": [1, 2.5, {"b": None}], "c": "NaN"})  # the string is fine
    with pytest.raises(ValueError, match="finite"):
        check_params({"a": [0.0, float("-inf")]})
    with pytest.raises(ValueError, match="deeper"):
        check_params({"a": nested(5)}, max_depth=5)


# ---- time limit ------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_job_over_its_time_limit_fails_saying_so(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1)
    with TestClient(create_app(settings)) as client:
        # A first job starts the worker processes' server (seconds on a loaded machine,
        # not what this test measures).
        assert wait_for(client, post(client, "echo", {}).json()["id"])["status"] == "succeeded"
        r = post(client, "sleep", {"seconds": 30, "steps": 300}, time_limit_s=1)
        assert r.status_code == 202 and r.json()["time_limit_s"] == 1
        job_id = r.json()["id"]
        wait_for(client, job_id, statuses=("running",))
        t0 = time.monotonic()
        job = wait_for(client, job_id, timeout=25)
        assert job["status"] == "failed", job
        assert job["error"] == "time limit of 1 s exceeded"
        # Within seconds of the limit, not the 30 s the job would sleep (a loaded machine
        # took 3.7 s once; the test tier running beside the cluster tier gets little CPU).
        assert time.monotonic() - t0 < 15.0
        # The worker is free again.
        echo = post(client, "echo", {"value": 1}).json()["id"]
        assert wait_for(client, echo)["status"] == "succeeded"


@pytest.mark.slow
def test_a_job_within_its_time_limit_succeeds(tmp_path):
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path))) as client:
        r = post(client, "sleep", {"seconds": 0.3, "steps": 3}, time_limit_s=5)
        assert wait_for(client, r.json()["id"])["status"] == "succeeded"


def test_the_service_time_limit_is_the_default_and_the_most(tmp_path):
    client = TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path,
                                            job_time_limit_s=120)))
    assert post(client, "echo", {}).json()["time_limit_s"] == 120
    assert post(client, "echo", {}, time_limit_s=60).json()["time_limit_s"] == 60
    err = error(post(client, "echo", {}, time_limit_s=121))
    assert err["loc"] == ["body", "time_limit_s"] and "120" in err["msg"]
    err = error(post(client, "echo", {}, time_limit_s=0.5))
    assert err["loc"] == ["body", "time_limit_s"]
    job_id = client.get("/jobs").json()[0]["id"]
    assert client.get(f"/jobs/{job_id}").json()["time_limit_s"] == 120


def test_jobs_submitted_in_process_get_the_manager_limit(tmp_path):
    from app.jobs.manager import JobManager, JobParamsError
    from app.registry import RobotRegistry

    store = Store(tmp_path / "s.sqlite3")
    jobs = JobManager(store, RobotRegistry(store), "local", 1, 10, time_limit_s=30)
    assert jobs.submit("echo", {"value": 1}).time_limit_s == 30
    with pytest.raises(JobParamsError, match="at most 30 s"):
        jobs.submit("echo", {}, time_limit_s=31)


def test_time_limit_setting_reads_the_environment_and_the_flag(monkeypatch):
    from app.__main__ import parse_args

    monkeypatch.setenv("KINOPLAN_JOB_TIME_LIMIT_S", "90")
    assert parse_args([]).job_time_limit_s == 90
    assert parse_args(["--job-time-limit-s", "45"]).job_time_limit_s == 45
    assert Settings.model_fields["job_time_limit_s"].default == 3600


# ---- GET /jobs: pages and filters -----------------------------------------------------------
def test_jobs_are_listed_a_page_at_a_time(client):
    ids = [post(client, kind, {}).json()["id"]
           for kind in ("echo", "echo", "sleep", "echo", "echo", "echo")]
    r = client.get("/jobs", params={"limit": 2})
    assert r.status_code == 200 and isinstance(r.json(), list)
    assert r.headers["X-Total-Count"] == "6"
    seen, url = [], "/jobs?limit=2"
    while url:
        r = client.get(url)
        seen += [j["id"] for j in r.json()]
        link = r.headers.get("Link")
        url = link[1:link.index(">")] if link else None
        assert not link or link.endswith('>; rel="next"')
    assert seen == ids  # oldest first, each once
    r = client.get("/jobs", params={"limit": 2, "offset": 4})
    assert [j["id"] for j in r.json()] == ids[4:] and "Link" not in r.headers


def test_jobs_are_filtered_by_kind_and_status(client):
    echoes = [post(client, "echo", {"value": k}).json()["id"] for k in range(3)]
    sleeper = post(client, "sleep", {"seconds": 0}).json()["id"]
    client.delete(f"/jobs/{echoes[1]}")  # queued: cancelled at once
    r = client.get("/jobs", params={"kind": "echo"})
    assert [j["id"] for j in r.json()] == echoes and r.headers["X-Total-Count"] == "3"
    r = client.get("/jobs", params={"kind": "echo", "status": "queued"})
    assert [j["id"] for j in r.json()] == [echoes[0], echoes[2]]
    r = client.get("/jobs", params={"status": "cancelled"})
    assert [j["id"] for j in r.json()] == [echoes[1]]
    r = client.get("/jobs", params={"kind": "sleep", "status": "queued", "limit": 1})
    assert [j["id"] for j in r.json()] == [sleeper] and "Link" not in r.headers
    assert client.get("/jobs", params={"status": "succeeded"}).json() == []


@pytest.mark.parametrize("query, field", [
    ({"limit": 1001}, "limit"), ({"limit": 0}, "limit"), ({"offset": -1}, "offset"),
    ({"status": "done"}, "status"), ({"kind": "nope"}, "kind"),
])
def test_bad_list_queries_are_422(client, query, field):
    assert error(client.get("/jobs", params=query))["loc"] == ["query", field]


def test_the_default_page_is_100_jobs(client, tmp_path):
    store: Store = client.app.state.store
    for k in range(150):
        store.add_job(f"job{k:03d}", "echo", {"value": k}, {"value": k})
    r = client.get("/jobs")
    assert len(r.json()) == 100 and r.headers["X-Total-Count"] == "150"
    assert "offset=100" in r.headers["Link"]
    assert len(client.get("/jobs", params={"limit": 1000}).json()) == 150


def test_an_older_store_gains_the_time_limit_column(tmp_path):
    path = tmp_path / "old.sqlite3"
    conn = sqlite3.connect(path)
    for migration in _MIGRATIONS[:2]:  # the schema before time limits
        conn.executescript(migration)
    conn.execute("PRAGMA user_version = 2")
    conn.execute("INSERT INTO jobs (id, kind, params_json, payload_json, status, created) "
                 "VALUES ('old', 'echo', '{}', '{}', 'queued', 'then')")
    conn.commit()
    conn.close()
    store = Store(path)
    (job,) = store.list_jobs()
    assert job.id == "old" and job.time_limit_s is None
    store.add_job("new", "sleep", {}, {}, time_limit_s=5.0)
    assert store.get_job("new").time_limit_s == 5.0
    assert store.count_jobs(kind="sleep") == 1 and store.count_jobs() == 2
    assert [j.id for j in store.list_jobs(kind="echo", offset=0, limit=5)] == ["old"]
    assert json.loads(json.dumps(job.to_dict()))["time_limit_s"] is None


def test_the_service_setting_is_the_limit_of_jobs_submitted_in_process(tmp_path):
    # The viewer submits through the manager directly: it gets the service's limit too.
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, job_time_limit_s=42))
    job = api.state.jobs.submit("sleep", {"seconds": 0})
    assert job.time_limit_s == 42
