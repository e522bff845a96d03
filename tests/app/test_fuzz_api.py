"""Property-based fuzz of the whole API from its own OpenAPI document (schemathesis 4).

Every operation the app publishes at /openapi.json (new ones are picked up automatically) is
one test: schemathesis's coverage cases (boundaries, missing and wrong-typed fields, unexpected
methods) and up to ``MAX_EXAMPLES`` generated requests, valid and invalid, sent in-process to
a fresh ASGI app. Every answer must
- not be a 5xx (``not_a_server_error``: "never 500 for anything a client sends"), and
- conform to the response schema the document declares for its status code
  (``response_schema_conformance``).
Status codes are not checked against the document: it does not declare most 404s.

Bounded and deterministic: fixed seed, derandomised, no shrinking, no example database.
Random robot ids and joint vectors almost never name a robot or have its dof, so a case hook
rewrites most cases to a built-in robot, joint vectors to its dof, poses to rigid ones and job
kinds to real ones: the generated values then reach the kinematics and the job checks instead
of stopping at 404/422. /viewer operations run against the real viewer (on a free loopback
port). A job that POST /jobs accepts is cancelled at once, so fuzzing cannot leave long work
running.
"""

from __future__ import annotations

import os
import tempfile
import zlib
from typing import Any

import pytest
import schemathesis
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, Phase, settings

from app.config import Settings
from app.main import create_app

MAX_EXAMPLES = int(os.environ.get("KINOPLAN_FUZZ_EXAMPLES", "12"))  # tools/fuzz.py: more
#: ``k/n``: fuzz only the operations whose place in the document's order is k modulo n, so
#: that n pytest processes share the operations out (``make test`` runs two, one a core).
SHARD = os.environ.get("KINOPLAN_FUZZ_SHARD", "0/1")
SEED = 20240611

CONFIG = schemathesis.Config.from_dict({
    "seed": SEED,
    "generation": {
        "max-examples": MAX_EXAMPLES,
        "deterministic": True,
        "no-shrink": True,
        "database": "none",
    },
    "phases": {"stateful": {"enabled": False}},
    "checks": {
        "enabled": False,
        "not_a_server_error": {"enabled": True},
        "response_schema_conformance": {"enabled": True},
    },
})


def _new_app(data_dir):
    # Explicit backend and key: KINOPLAN_* variables of the shell must not leak in.
    return create_app(Settings(no_viewer=True, workers=1, jobs_backend="local", api_key=None,
                               data_dir=data_dir))


def _read_app() -> tuple[dict, dict[str, int], list[str]]:
    """OpenAPI document, built-in robots' dof and job kinds, from a throwaway app (no lifespan).

    (``schemathesis.pytest.from_fixture`` would build the schema per test instead, but 4.x
    reads ``Node._nodeid``, which pytest 9.2 no longer has.)"""
    with tempfile.TemporaryDirectory() as tmp:
        client = TestClient(_new_app(tmp))
        document = client.get("/openapi.json").json()
        dof = {r["id"]: r["dof"] for r in client.get("/robots").json() if r["builtin"]}
        kinds = client.get("/jobs/kinds")
        listed = kinds.json() if kinds.status_code == 200 else []
        names = [k.get("kind") or k.get("name") for k in listed]
    return document, dof, names


def _cylinder_strokes() -> dict[str, dict[str, tuple[float, float]]]:
    """Each built-in robot's cylinders: name -> (min_length, max_length), mm."""
    from kinematics.cylinders import cylinder_set
    from kinematics.library import builtin_model

    out = {}
    for robot_id in BUILTIN_DOF:
        try:
            cyl = cylinder_set(builtin_model(robot_id))
        except Exception:  # no cylinder data (or a rig's arm): nothing to aim at
            continue
        out[robot_id] = {name: cyl.limits(name) for name in cyl.names}
    return out


DOCUMENT, BUILTIN_DOF, JOB_KINDS = _read_app()
CYLINDERS = _cylinder_strokes()
BUILTINS = sorted(BUILTIN_DOF)
schema = schemathesis.openapi.from_dict(DOCUMENT, config=CONFIG)


def _shard(spec: str) -> set[str]:
    """The labels (``POST /robots/{robot_id}/fk``) of the operations of shard ``k/n``."""
    k, n = (int(v) for v in spec.split("/"))
    if not 0 <= k < n:
        raise ValueError(f"KINOPLAN_FUZZ_SHARD: {spec!r} is not k/n with 0 <= k < n")
    labels = [result.ok().label for result in schema.get_all_operations()]
    return set(labels[k::n])


SHARD_LABELS = _shard(SHARD)


def _pick(options: list, *key: Any):
    """A deterministic choice among ``options`` keyed by the generated data."""
    return options[zlib.crc32(repr(key).encode()) % len(options)]


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _vector(x: Any) -> bool:
    return isinstance(x, list) and len(x) > 0 and all(_number(v) for v in x)


def _fit_joints(value: Any, dof: int) -> Any:
    """A joint vector, or a list of them, cut or zero-padded to ``dof`` values each."""
    if _vector(value):
        return [*value[:dof], *[0.0] * (dof - len(value))]
    if isinstance(value, list) and value and all(_vector(row) for row in value):
        return [_fit_joints(row, dof) for row in value]
    return value


def _numbers(value: Any) -> list:
    if _number(value):
        return [value]
    return [x for v in value for x in _numbers(v)] if isinstance(value, list) else []


def _rigid(value: Any, n: int) -> Any:
    """An ``n x n`` rigid transform (identity rotation) whose translation is the first
    generated numbers; a list of them for a list of matrices (three levels of lists)."""
    if not isinstance(value, list):
        return value
    if value and isinstance(value[0], list) and value[0] and isinstance(value[0][0], list):
        return [_rigid(m, n) for m in value]
    rows = [[float(i == j) for j in range(n)] for i in range(n)]
    if n == 4:
        for i, t in enumerate([*_numbers(value), 0.0, 0.0, 0.0][:3]):
            rows[i][3] = t
    return rows


def _fit_body(body: dict, dof: int | None) -> dict:
    body = dict(body)
    if isinstance(body.get("robot"), str) and body["robot"] not in BUILTIN_DOF:
        body["robot"] = _pick(BUILTINS, body["robot"])
    if dof is None and isinstance(body.get("robot"), str):
        dof = BUILTIN_DOF.get(body["robot"])
    if dof is not None:
        for key in ("q", "q0", "waypoints", "velocities", "accelerations"):
            if key in body:
                body[key] = _fit_joints(body[key], dof)
    for key, n in (("pose", 4), ("rotation", 3)):
        if key in body:
            body[key] = _rigid(body[key], n)
    waypoints, durations = body.get("waypoints"), body.get("durations")
    if isinstance(waypoints, list) and len(waypoints) >= 2 and isinstance(durations, list):
        # One duration per segment, positive: the planner itself runs instead of a 422.
        body["durations"] = [abs(d) % 10 + 0.5 if _number(d) else 1.0
                             for d in [*durations, 1.0] * len(waypoints)][:len(waypoints) - 1]
    if JOB_KINDS and isinstance(body.get("kind"), str) and body["kind"] not in JOB_KINDS:
        body["kind"] = _pick(JOB_KINDS, body["kind"])
    if isinstance(body.get("params"), dict):
        body["params"] = _fit_body(body["params"], None)
    return body


def _fit_cylinder_lengths(body: dict, robot_id: str) -> dict:
    """Give ``lengths`` the robot's cylinder names and lengths inside their strokes."""
    strokes = CYLINDERS.get(robot_id)
    lengths = body.get("lengths")
    if not strokes or not isinstance(lengths, dict) or not lengths:
        return body
    names = sorted(strokes)
    fitted = {}
    for k, value in enumerate(lengths.values()):
        lo, hi = strokes[names[k % len(names)]]
        t = abs(value) % 1.0 if _number(value) else 0.5
        fitted[names[k % len(names)]] = lo + t * (hi - lo)
    return {**body, "lengths": fitted}


@schema.hook
def map_case(context, case):
    """Keep one case in four as generated; aim the others at built-in robots and real kinds."""
    key = (case.method, case.path_parameters, case.query, case.body)
    if _pick([False, True, True, True], key):
        params = case.path_parameters or {}
        dof = None
        if "robot_id" in params:
            if not isinstance(params["robot_id"], str) or params["robot_id"] not in BUILTIN_DOF:
                case.path_parameters = {**params, "robot_id": _pick(BUILTINS, key)}
            dof = BUILTIN_DOF[case.path_parameters["robot_id"]]
        if isinstance(case.body, dict):
            case.body = _fit_body(case.body, dof)
            if "robot_id" in params:
                case.body = _fit_cylinder_lengths(case.body, case.path_parameters["robot_id"])
    return case


@pytest.fixture
def api(tmp_path):
    """A fresh app (one job worker, data under tmp_path); its viewer, if a test started one,
    and its compute workers are stopped afterwards."""
    fresh = _new_app(tmp_path / "data")
    yield fresh
    if fresh.state.viewer is not None:
        fresh.state.viewer.stop()
    fresh.state.compute.shutdown()


def _ensure_viewer(case, api) -> None:
    """/viewer operations get the real viewer (as ``python -m kinoplan`` starts it, on a free
    loopback port) instead of the 503 of ``--no-viewer``."""
    if case.path.startswith("/viewer") and api.state.viewer is None:
        from web.viewer import Viewer

        api.state.viewer = Viewer.start("127.0.0.1", 0, api.state)


def _cancel_accepted_job(case, response, api) -> None:
    """DELETE a job that POST /jobs accepted, through the same in-process transport."""
    if case.method.upper() != "POST" or case.path != "/jobs" or response.status_code != 202:
        return
    job_id = response.json().get("id")
    if job_id is not None:
        cancel = schema["/jobs/{job_id}"]["DELETE"]
        cancel.Case(path_parameters={"job_id": job_id}).call(app=api)


# After the hook: the clone keeps it. ``schema`` itself keeps every operation (the cancel).
fuzzed = schema.include(lambda ctx: ctx.operation.label in SHARD_LABELS)


@pytest.mark.slow
@fuzzed.parametrize()
# Every number a request carries is bounded, so no computation may overflow: a numeric
# warning in any handler fails the case.
@pytest.mark.filterwarnings("error::RuntimeWarning")
@settings(
    max_examples=MAX_EXAMPLES,
    derandomize=True,
    database=None,
    deadline=None,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=list(HealthCheck),
)
def test_api_fuzz(case, api):
    _ensure_viewer(case, api)
    response = case.call(app=api)
    try:
        case.validate_response(response)
    finally:
        _cancel_accepted_job(case, response, api)
