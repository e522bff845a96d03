"""Typed job contracts: every kind's params and result models, published by ``GET /jobs/kinds``
and in the OpenAPI document; a small real job of every kind checked against the published
result schema; one registration per kind; results checked when stored; the worker's typed
params (robot model attached, scene and allocation built once)."""

from __future__ import annotations

import dataclasses
import json

import jsonschema
import numpy as np
import pytest
from fastapi.testclient import TestClient

import app.jobs.local as local
from app.config import Settings
from app.jobs.catalog import KINDS
from app.jobs.kinds import (
    EchoParams,
    JobKind,
    JobPayload,
    JobResultError,
    SleepResult,
    execute,
    register,
)
from app.main import create_app
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.model import RobotModel

from .conftest import wait_for

# A worker process imports this module to find ``_child_main_with_broken``.
_CHILD_MAIN = local._child_main

FACE = [[9000, 0, 0], [9000, 1200, 300], [9000, -800, 900], [9000, 400, 2000]]
SIDES = {"left": [[9000, 2600, 300], [9000, 3400, 1500]],
         "middle": [[9000, 0, 2400], [9000, 1000, 4300]],
         "right": [[9000, -2600, 500], [9000, -3500, 2000]]}
SCENE = {"bounds": [[0, 0, 0], [100, 100, 100]],
         "obstacles": [{"center": [30, 30, 30], "radius": 12},
                       {"type": "box", "lower": [70, 70, 60], "upper": [85, 85, 80]},
                       {"type": "capsule", "a": [10, 80, 10], "b": [30, 80, 40], "radius": 5}]}


def _calibration_measurements() -> list[dict]:
    """Poses and positions of a GLT palletizer whose upper arm is 3 mm longer."""
    glt = builtin_model("glt_palletizer")
    data = glt.to_dict()
    data["joints"][2]["a"] += 3.0
    truth = RobotModel.from_dict(data)
    q = np.random.default_rng(0).uniform(glt.lower, glt.upper, (8, 6))
    T = fk(truth, q)
    return ([{"q": qk.tolist(), "pose": Tk.tolist()} for qk, Tk in zip(q[:5], T[:5])]
            + [{"q": qk.tolist(), "position": Tk[:3, 3].tolist()} for qk, Tk in zip(q[5:], T[5:])])


def _arm_path() -> dict:
    model = builtin_model("pile_driver")
    start = fk(model, np.radians([10, 30, -30, -30, 0, 0]))[:3, 3]
    goal = fk(model, np.radians([60, 35, -25, -30, 0, 0]))[:3, 3]
    return {"scene": {"bounds": [[-2500, -2500, -1000], [2500, 2500, 2000]],
                      "obstacles": [{"center": ((start + goal) / 2).tolist(), "radius": 100}]},
            "start": start.tolist(), "goal": goal.tolist(), "robot": "pile_driver",
            "arm": {"dt": 1.0}}


#: (case, kind, params): small real jobs, every kind at least once.
CASES = [
    ("sleep", "sleep", {"seconds": 0, "steps": 1}),
    ("echo", "echo", {"value": {"a": [1, 2.5, None, "x", True]}}),
    ("workspace", "workspace", {"robot": "pile_driver", "samples": 500, "return_points": 20}),
    ("workspace_no_projections", "workspace", {"robot": "glt_palletizer", "samples": 300,
                                               "return_points": 5, "projections": False}),
    ("calibrate", "calibrate", {"robot": "glt_palletizer", "parameters": ["joints[2].a"],
                                "measurements": _calibration_measurements()}),
    ("ik_train", "ik_train", {"robot": "glt_palletizer", "samples": 40, "test_fraction": 0.1}),
    ("ik_train_drilling", "ik_train", {"robot": "tunnel_drill_arm", "samples": 40,
                                       "test_fraction": 0.1}),
    ("path", "path", {"scene": SCENE, "start": [1, 1, 1], "goal": [99, 99, 99]}),
    ("path_arm", "path", _arm_path()),
    ("path_compare", "path_compare", {"scene": SCENE, "start": [1, 1, 1],
                                      "goal": [99, 99, 99], "algorithms": ["auto"], "runs": 2}),
    ("tracking", "tracking", {"task": {"kind": "ellipse", "radii": [50.0, 30.0],
                                       "duration": 2.0}}),
    ("tracking_runs", "tracking", {"task": {"kind": "line", "length": 50.0, "duration": 2.0},
                                   "controller": {"kind": "pi"}, "tune": "pso",
                                   "iterations": 1, "runs": 2}),
    ("sequence", "sequence", {"holes": FACE, "start": [9000, 0, -1000]}),
    ("multiarm", "multiarm", {"holes": SIDES, "output_dt": 2.0}),
    ("motion", "motion", {"robot": "glt_palletizer", "start": [0, 0, 0, 0, 0.5, 0],
                          "goal": {"q": [1, 0.3, -0.3, 0, 0.5, 0]}, "time_limit": 2}),
    ("motion_batch", "motion", {"robot": "glt_palletizer", "time_limit": 2, "problems": [
        {"start": [0, 0, 0, 0, 0.5, 0], "goal": {"q": [1, 0.3, -0.3, 0, 0.5, 0]}}]}),
    ("pallet", "pallet", {"box": {"size": [400, 300, 250]}, "count": 1, "time_limit": 5,
                          "pick": [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825],
                                   [0, 0, 0, 1]]}),
    ("piles", "piles", {"plan": [{"id": "A", "x": 1600, "y": 0, "z": 0},
                                 {"id": "far", "x": 9000, "y": 0, "z": 0}],
                        "setups": {"positions": [[0, 0, 0]]}}),
    ("round", "round", {"holes": [{"id": "M1", "collar": [9000, 0, 2500],
                                   "toe": [10000, 0, 2500]}],
                        "booms": ["middle"], "collaring_s": 1, "retract_s": 5,
                        "penetration_rate_m_min": 6, "output_dt": 5.0}),
]


def payload_of(kind: str, params: dict) -> dict:
    """The payload the service would store for a submission (built-in robots only)."""
    spec = KINDS[kind]
    checked = spec.load_params(params)
    robot = spec.robot_id(checked)
    model = builtin_model(robot).to_dict() if robot is not None else None
    return JobPayload(params=checked.model_dump(mode="json"),
                      robot_model=model).model_dump(mode="json")


@pytest.fixture(scope="module")
def published() -> dict[str, dict]:
    client = TestClient(create_app(Settings(no_viewer=True)))
    return {k["kind"]: k for k in client.get("/jobs/kinds").json()}


@pytest.fixture(scope="module")
def results() -> dict[str, dict]:
    """The stored JSON of each case, run in this process as a worker runs it."""
    return {case: json.loads(execute(kind, payload_of(kind, params), lambda f, m: None))
            for case, kind, params in CASES}


def test_the_cases_cover_every_kind():
    assert {kind for _, kind, _ in CASES} == set(KINDS)


@pytest.mark.slow
@pytest.mark.parametrize("case, kind", [(case, kind) for case, kind, _ in CASES])
def test_a_real_job_result_matches_the_published_result_schema(published, results, case,
                                                                kind):
    schema = published[kind]["result_schema"]
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(results[case], schema, cls=jsonschema.Draft202012Validator)
    # ... and the schema is strict: a misspelt or missing field does not pass.
    first = next(iter(schema["required"]))
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**results[case], "unexpected": 1}, schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({k: v for k, v in results[case].items() if k != first}, schema)


@pytest.mark.slow
def test_results_keep_their_shapes(results):
    """Fields present only in some results are left out, not null, elsewhere."""
    assert "projections" in results["workspace"]
    assert "projections" not in results["workspace_no_projections"]
    plain, arm = results["path"], results["path_arm"]
    assert plain["joint_path"] is None and plain["trajectory"] is None
    assert not {"robot", "arm_min_clearance", "tool_samples"} & set(plain)
    assert arm["robot"] == "pile_driver" and len(arm["trajectory"]["t"]) >= 2
    assert "runs" not in results["tracking"] and "summary" not in results["tracking"]
    assert len(results["tracking_runs"]["runs"]) == 2
    assert results["tracking"]["task"]["kind"] == "ellipse"
    assert results["ik_train_drilling"]["fixed"] == {"6": 4022.0}
    assert results["calibrate"]["rotation_residuals"][-1] == [None, None, None]
    assert results["echo"] == {"value": {"a": [1, 2.5, None, "x", True]}}
    assert sorted(results["sequence"]["order"]) == list(range(len(FACE)))


def test_kinds_publish_params_and_result_schemas(published):
    assert set(published) == set(KINDS)
    for name, kind in published.items():
        assert kind["params"] == kind["params_schema"] == KINDS[name].params.model_json_schema()
        assert kind["result_schema"]["title"] == KINDS[name].result.__name__
        assert kind["plot"] is (name in {"tracking", "pallet", "piles", "round"})
    assert "samples" in published["workspace"]["params_schema"]["properties"]
    assert "x_desired" in published["tracking"]["result_schema"]["required"]


def test_openapi_documents_the_result_as_one_of_the_kinds_results():
    doc = TestClient(create_app(Settings(no_viewer=True))).get("/openapi.json").json()
    ok = doc["paths"]["/jobs/{job_id}/result"]["get"]["responses"]["200"]
    refs = {s["$ref"].rsplit("/", 1)[-1]
            for s in ok["content"]["application/json"]["schema"]["anyOf"]}
    assert refs == {k.result.__name__ for k in KINDS.values()}
    schemas = doc["components"]["schemas"]
    assert schemas["TrackingResult"]["properties"]["x_desired"]["type"] == "array"
    assert schemas["PathResult"]["additionalProperties"] is False
    kinds = doc["paths"]["/jobs/kinds"]["get"]["responses"]["200"]["content"]
    assert kinds["application/json"]["schema"]["items"]["$ref"].endswith("/JobKindOut")


def test_registering_a_kind_twice_raises():
    echo = KINDS["echo"]
    with pytest.raises(ValueError, match="'echo' is already registered"):
        register(dataclasses.replace(echo, description="another echo"))
    assert KINDS["echo"] is echo


def _broken_run(params: EchoParams, progress) -> dict:
    return {"slept": "a while", "pid": 1}


BROKEN = JobKind("broken", EchoParams, SleepResult, _broken_run, "returns a bad result")


def test_a_result_that_does_not_match_raises_naming_the_field(monkeypatch):
    monkeypatch.setitem(KINDS, "broken", BROKEN)
    with pytest.raises(JobResultError, match=r"broken.*SleepResult.*result\.slept: "):
        execute("broken", {"params": {"value": 1}, "robot_model": None}, lambda f, m: None)
    nan = dataclasses.replace(BROKEN, run=lambda p, progress: {"slept": float("nan"), "pid": 1})
    monkeypatch.setitem(KINDS, "broken", nan)
    with pytest.raises(JobResultError, match="no JSON data"):
        execute("broken", {"params": {"value": 1}, "robot_model": None}, lambda f, m: None)


def _child_main_with_broken(conn, kind, payload, *step):
    """Worker body that knows the ``broken`` kind (the forkserver imported only the
    catalog's kinds)."""
    KINDS.setdefault("broken", BROKEN)
    _CHILD_MAIN(conn, kind, payload, *step)


@pytest.mark.slow
def test_a_job_whose_result_does_not_match_fails_saying_where(tmp_path, monkeypatch):
    monkeypatch.setitem(KINDS, "broken", BROKEN)
    monkeypatch.setattr(local, "_child_main", _child_main_with_broken)
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))) as c:
        r = c.post("/jobs", json={"kind": "broken", "params": {"value": 1}})
        assert r.status_code == 202, r.text
        job = wait_for(c, r.json()["id"])
        assert job["status"] == "failed"
        assert job["error"].startswith("JobResultError: ") and "result.slept" in job["error"]
        assert c.get(f"/jobs/{job['id']}/result").status_code == 409


def test_the_worker_attaches_the_robot_model_of_the_payload():
    """The model travels with the job: a custom robot the worker could not look up."""
    data = builtin_model("glt_palletizer").to_dict() | {"id": "my_glt"}
    params = {"robot": "my_glt", "samples": 200, "return_points": 3, "projections": False}
    clean = KINDS["workspace"].load_params(params).model_dump(mode="json")
    out = json.loads(execute("workspace", {"params": clean, "robot_model": data},
                             lambda f, m: None))
    assert out["robot"] == "my_glt" and len(out["points"]) == 3
    # The layout of jobs queued by earlier versions: the params with the model under _model.
    older = json.loads(execute("workspace", {**clean, "_model": data}, lambda f, m: None))
    assert older == out
    with pytest.raises(ValueError, match="my_glt"):
        execute("workspace", {"params": clean, "robot_model": None}, lambda f, m: None)


def test_the_manager_stores_the_typed_payload(tmp_path):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path))
    job = api.state.jobs.submit("workspace", {"robot": "pile_driver", "samples": 10})
    payload = api.state.store.job_payload(job.id)
    assert set(payload) == {"params", "robot_model"}
    assert payload["params"] == job.params and payload["robot_model"]["id"] == "pile_driver"
    echo = api.state.jobs.submit("echo", {"value": [1]})
    assert api.state.store.job_payload(echo.id) == {"params": {"value": [1]},
                                                     "robot_model": None}


def test_a_path_job_builds_its_scene_once(monkeypatch):
    from app.jobs.path_kinds import run_path
    from planning.paths.scene import Scene

    built = []
    create = Scene.create.__func__

    def counting(cls, *args, **kwargs):
        built.append(1)
        return create(cls, *args, **kwargs)

    monkeypatch.setattr(Scene, "create", classmethod(counting))
    params = KINDS["path"].load_params({"scene": SCENE, "start": [1, 1, 1],
                                        "goal": [99, 99, 99]})
    assert len(built) == 1  # start and goal were checked against one scene
    scene = params.scene.to_scene()
    result = run_path(params, lambda f, m: None)
    assert len(built) == 1 and params.scene.to_scene() is scene
    assert result.success and scene.path_is_clear(result.path)


def test_multiarm_checks_and_plans_one_allocation_with_the_requested_balance(monkeypatch):
    """A face whose work balance differs from the count balance: the check allocates as the
    run plans, and the run plans the allocation the check made."""
    import planning.drilling.multiarm as multiarm
    from app.jobs.drilling_kinds import run_multiarm
    from kinematics.rigs import builtin_rig
    from planning.drilling.allocation import allocate_holes
    from planning.drilling.patterns import face_pattern

    face = {"spacing": 1000.0}
    holes = face_pattern(**face).holes
    rig = builtin_rig("tunnel_jumbo")
    by_work = allocate_holes(rig, holes, balance="work").counts()
    assert by_work != allocate_holes(rig, holes, balance="count").counts()
    params = KINDS["multiarm"].load_params({"face": face, "balance": "work"})
    assert params.allocation().counts() == by_work

    planned = []

    def plan_face(rig, holes, **kwargs):
        planned.append(kwargs["allocation"])
        raise RuntimeError("planned")

    monkeypatch.setattr(multiarm, "plan_face", plan_face)
    with pytest.raises(RuntimeError, match="planned"):
        run_multiarm(params, lambda f, m: None)
    assert planned == [params.allocation()]


def test_counts_that_do_not_add_up_name_the_counts():
    from pydantic import ValidationError

    with pytest.raises(ValidationError) as info:
        KINDS["multiarm"].load_params({"face": {"spacing": 1000.0},
                                       "counts": {"left": 1, "middle": 1, "right": 1}})
    err = info.value.errors()[0]
    assert err["loc"] == ("counts",) and "add up" in err["msg"]


@pytest.mark.parametrize("controller, kp, ki", [
    ({"kind": "pi", "kp": 3.0}, (3.0, 3.0), None),
    ({"kind": "pi", "kp": [2.0]}, (2.0, 2.0), None),
    ({"kind": "pi", "kp": [2.0, 5.0], "ki": 7.0}, (2.0, 5.0), 7.0),
    ({"kind": "default", "ki": 1.5}, None, 1.5),
])
def test_controller_gains_come_from_the_typed_params(controller, kp, ki):
    from planning.tracking import DEFAULT_GAINS, UNTUNED_PI_GAINS

    params = KINDS["tracking"].load_params({"task": {"kind": "line"}, "controller": controller})
    default = DEFAULT_GAINS if controller["kind"] == "default" else UNTUNED_PI_GAINS
    gains = params.controller.gains()
    assert tuple(gains.kp) == (kp or tuple(default.kp))
    assert gains.ki == (default.ki if ki is None else ki)
    assert KINDS["tracking"].load_params({"task": {"kind": "line"}}).controller.gains() \
        is DEFAULT_GAINS
