"""Requests that try to exhaust the service: huge lists, extreme numbers, bodies over a
route's cap, cross-site content types, foreign Host names, slow clients, heavy calls.

Sizes are scaled down from the attacks they stand for (a 60 MB list of zeros becomes a few
hundred kB: the point is that the answer does not grow with the input); the full-size runs
against a live service are in ``tools/attack.py``.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import threading
import time
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import uvicorn
from fastapi.testclient import TestClient

from app.compute import ComputeBusy, ComputeFailed, ComputePool
from app.config import Settings
from app.limits import DEFAULT_BODY_CAP, ROUTE_BODY_CAPS, host_allow_list
from app.main import MAX_ERRORS, create_app
from app.server import guarded_protocol

GLT = "/robots/glt_palletizer"
PILE = "/robots/pile_driver"


def _app(tmp_path, **kw):
    return create_app(Settings(no_viewer=True, data_dir=tmp_path, **kw))


def _locs(r) -> list:
    return [e["loc"] for e in r.json()["detail"]]


# ---- sizes before contents ------------------------------------------------------------
@pytest.mark.parametrize("path, field", [(f"{GLT}/ik", "pose"), (f"{GLT}/fk", "q")])
def test_a_long_flat_list_costs_one_error(ro_client, path, field):
    # Scaled-down version of the 60 MB list of zeros that used to take the API down.
    r = ro_client.post(path, json={field: [0] * 200_000})
    assert r.status_code in (413, 422)
    assert _locs(r) == [["body", field]]
    assert len(r.content) < 1_000


def test_too_many_configurations_is_413_before_they_are_read(ro_client):
    # Each row is garbage: were rows validated first, this would be 100,001 errors.
    r = ro_client.post(f"{GLT}/fk", json={"q": [["x"]] * 100_001})
    assert r.status_code == 413
    assert r.json()["detail"] == [{"loc": ["body", "q"], "type": "too_large",
                                   "msg": "at most 100000 configurations per call, got 100001"}]


def test_a_bad_element_is_named_once(ro_client):
    q = [[0.0] * 6 for _ in range(1_000)]
    q[700][4] = "seven"
    r = ro_client.post(f"{GLT}/fk", json={"q": q})
    assert r.status_code == 422
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "q"] and err["msg"].startswith("[700][4]:")


def test_a_422_lists_at_most_a_few_dozen_errors(ro_client):
    holes = [["a", "b", "c"]] * 2_000  # 6,000 bad numbers
    r = ro_client.post("/robots/tunnel_drill_arm/drill-ik", json={"holes": holes})
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert len(detail) == MAX_ERRORS + 1
    assert detail[-1]["type"] == "too_many_errors"
    assert detail[-1]["msg"] == f"and {6_000 - MAX_ERRORS} more errors"
    assert len(r.content) < 10_000


def test_each_route_has_a_body_cap_below_the_global_one(ro_client):
    doc = ro_client.get("/openapi.json").json()
    caps = {(path, method): op["x-max-body-bytes"] for path, ops in doc["paths"].items()
            for method, op in ops.items() if method in ("post", "put", "patch")}
    assert caps[("/robots/{robot_id}/ik", "post")] == ROUTE_BODY_CAPS[
        "/robots/{robot_id}/ik"]
    assert caps[("/robots/{robot_id}/jacobian", "post")] == DEFAULT_BODY_CAP
    # Only batch routes and uploads take more than 8 MiB: each has its own cap.
    big = {"/robots/{robot_id}/fk", "/robots/import", "/scenes", "/meshes"}
    assert all(cap <= 8 * 1024 * 1024 or path in big for (path, _), cap in caps.items())
    assert all(caps[(path, "post")] == ROUTE_BODY_CAPS[path] for path in big)
    # A single-pose call refuses 300 kB at once, from Content-Length alone.
    r = ro_client.post(f"{GLT}/jacobian", content=b" " * 300_000,
                    headers={"content-type": "application/json"})
    assert r.status_code == 413 and r.json()["detail"][0]["type"] == "too_large"


def test_a_streamed_body_over_the_cap_is_413_not_400(ro_client):
    def chunks():
        for _ in range(40):
            yield b"0" * 10_000

    r = ro_client.post(f"{GLT}/jacobian", content=chunks(),
                    headers={"content-type": "application/json"})
    assert r.status_code == 413
    assert r.json()["detail"][0]["loc"] == ["body"]


# ---- every number finite and physical --------------------------------------------------
@pytest.mark.parametrize("body, loc", [
    ({"waypoints": [[0.0], [1.0]], "durations": [1e308]}, ["body", "durations", 0]),
    ({"waypoints": [[0.0], [1e308]], "durations": [1.0]}, ["body", "waypoints"]),
    ({"waypoints": [[0.0], [1.0]], "durations": [1.0], "dt": 1e300}, ["body", "dt"]),
    ({"waypoints": [[0.0], [1.0]], "durations": [1.0], "limits": {"velocity": 1e300}},
     ["body", "limits", "velocity"]),
    ({"waypoints": [[0.0]] * 1_001, "durations": [1.0] * 1_000}, ["body", "waypoints"]),
])
def test_trajectory_numbers_are_bounded(ro_client, body, loc):
    r = ro_client.post("/trajectories", json=body)
    assert r.status_code in (413, 422), r.text
    assert loc in _locs(r) or any(l[:len(loc)] == loc for l in _locs(r)), r.text


def test_cartesian_duration_is_bounded(ro_client):
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [500, 0, 500]},
        "duration": 1e308})
    assert r.status_code == 422 and ["body", "duration"] in _locs(r)


def _model(**joint):
    return {"id": "extreme", "joints": [{"lower": -1, "upper": 1, **joint}]}


@pytest.mark.parametrize("model, loc", [
    (_model(a=1e308), ["joints", 0, "a"]),
    (_model(d=-2e7), ["joints", 0, "d"]),
    (_model(alpha=1e9), ["joints", 0, "alpha"]),
    (_model(type="prismatic", lower=0, upper=1e308), ["joints", 0, "upper"]),
    (_model(velocity=1e300), ["joints", 0, "velocity"]),
    ({**_model(), "tool": [[1, 0, 0, 1e300], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ["tool"]),
    ({**_model(), "name": "arm\u0001"}, ["name"]),
    ({"id": "extreme", "joints": [{"name": "j\n1", "lower": -1, "upper": 1}]},
     ["joints", 0, "name"]),
    ({**_model(), "id": "rob\u00e9"}, ["id"]),
    ({**_model(), "id": "\u0661\u0662"}, ["id"]),  # Arabic-Indic digits pass isalnum()
])
def test_custom_robot_constants_are_physical(client, model, loc):
    r = client.post("/robots", json=model)
    assert r.status_code == 422, r.text
    assert _locs(r) == [["body", *loc]]
    assert client.get("/robots/extreme").status_code == 404


def test_a_printable_unicode_name_gives_well_formed_urdf(client):
    model = {**_model(a=100), "name": "Bohrarm Ü — 3"}
    assert client.post("/robots", json=model).status_code == 201
    urdf = client.get("/robots/extreme/urdf")
    assert urdf.status_code == 200
    assert ET.fromstring(urdf.content).get("name") is not None


def test_extreme_but_legal_robot_still_answers(client):
    # The largest accepted constants: FK and the Jacobian stay finite, no 500.
    model = {"id": "huge", "joints": [
        {"a": 1e7, "d": 1e7, "lower": -12, "upper": 12},
        {"type": "prismatic", "a": 1e7, "lower": -1e7, "upper": 1e7},
    ]}
    assert client.post("/robots", json=model).status_code == 201
    fk = client.post("/robots/huge/fk", json={"q": [12.0, 1e7]})
    assert fk.status_code == 200
    assert np.all(np.isfinite(fk.json()["poses"]))
    assert client.post("/robots/huge/jacobian", json={"q": [1.0, 1.0]}).status_code == 200
    ws = client.post("/robots/huge/workspace", json={"samples": 1000, "return_points": 10})
    assert ws.status_code == 200


# ---- browser-borne requests ------------------------------------------------------------
@pytest.mark.parametrize("ctype", ["text/plain", "application/x-www-form-urlencoded",
                                   "multipart/form-data; boundary=x", None])
def test_writes_need_a_json_body(client, ctype):
    headers = {} if ctype is None else {"content-type": ctype}
    r = client.post("/robots", content=json.dumps(_model()).encode(), headers=headers)
    assert r.status_code == 415
    assert r.json()["detail"][0]["loc"] == ["header", "content-type"]
    assert client.get("/robots/extreme").status_code == 404


@pytest.mark.parametrize("ctype", ["application/json; charset=utf-8",
                                   "application/problem+json"])
def test_json_content_types_pass(client, ctype):
    r = client.post("/robots", content=json.dumps(_model()).encode(),
                    headers={"content-type": ctype})
    assert r.status_code == 201


def test_host_allow_list_defaults():
    assert host_allow_list(None, "127.0.0.1") == ["localhost", "127.0.0.1", "::1"]
    assert host_allow_list(None, "::1") == ["localhost", "127.0.0.1", "::1"]
    assert host_allow_list(None, "0.0.0.0") is None
    assert host_allow_list("api.example, [::1]", "0.0.0.0") == ["api.example", "::1"]
    assert host_allow_list("*", "127.0.0.1") is None


@pytest.mark.parametrize("host, allowed", [
    ("127.0.0.1:8000", True), ("localhost", True), ("[::1]:8000", True),
    ("LOCALHOST:8000", True), ("evil.example", False), ("evil.example:8000", False),
    ("127.0.0.1.evil.example", False), ("", False),
])
def test_a_loopback_service_answers_loopback_names_only(tmp_path, host, allowed):
    client = TestClient(_app(tmp_path, host="127.0.0.1", allowed_hosts=None))
    r = client.get("/health", headers={"host": host})
    if allowed:
        assert r.status_code == 200
    else:
        assert r.status_code == 400
        assert r.json()["detail"][0]["loc"] == ["header", "host"]


def test_configured_hosts(tmp_path):
    client = TestClient(_app(tmp_path, host="0.0.0.0", allowed_hosts="kinoplan.site"))
    assert client.get("/health", headers={"host": "kinoplan.site:443"}).status_code == 200
    assert client.get("/health", headers={"host": "localhost"}).status_code == 400


# ---- slow clients ------------------------------------------------------------------------
@pytest.fixture
def live_server(tmp_path):
    """The app served by uvicorn with the service's protocol, short timeouts, on a free
    loopback port (in a thread of this process)."""
    config = uvicorn.Config(_app(tmp_path), host="127.0.0.1", port=0, log_level="warning",
                            http=guarded_protocol(1.0, 1.5), limit_concurrency=64)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.02)
    port = server.servers[0].sockets[0].getsockname()[1]
    # One whole request first: the first answer of a fresh app imports and builds what the
    # routes need, which on a loaded machine can hold the event loop for seconds and would
    # be timed as the timeout under test.
    import http.client
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    conn.request("POST", "/robots/pile_driver/fk", body=json.dumps({"q": [0.0] * 6}),
                 headers={"content-type": "application/json"})
    warm = conn.getresponse()
    assert warm.status == 200, warm.read()
    conn.close()
    yield port
    server.should_exit = True
    thread.join(10)


def _closed_after(sock: socket.socket) -> float:
    """Seconds until the server closes ``sock`` (reads until EOF); a connection the server
    never closes raises ``socket.timeout`` after 10 s."""
    start = time.monotonic()
    sock.settimeout(10)
    while sock.recv(4096):
        pass
    return time.monotonic() - start


def test_a_slow_request_head_is_cut_off(live_server):
    with socket.create_connection(("127.0.0.1", live_server)) as s:
        s.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # never finished
        assert 0.5 < _closed_after(s) < 3.0


def test_a_silent_connection_is_cut_off(live_server):
    with socket.create_connection(("127.0.0.1", live_server)) as s:
        assert _closed_after(s) < 3.0


@pytest.mark.slow
def test_a_body_that_stops_half_way_is_cut_off(live_server):
    with socket.create_connection(("127.0.0.1", live_server)) as s:
        s.sendall(b"POST /robots/pile_driver/fk HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                  b"Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"q\":")
        # The idle timer is 1.5 s; the upper bound leaves a loaded machine room (a connection
        # never cut raises after 10 s).
        assert 1.0 < _closed_after(s) < 8.0


@pytest.mark.slow
def test_a_steady_client_keeps_its_connection(live_server):
    import http.client

    # The client waits as long as the work takes (a loaded machine): the server must not cut.
    conn = http.client.HTTPConnection("127.0.0.1", live_server, timeout=60)
    for _ in range(3):  # keep-alive: the head timer must not fire between requests
        conn.request("GET", "/health")
        assert conn.getresponse().read()
        time.sleep(0.6)
    conn.request("POST", "/robots/pile_driver/workspace", body=json.dumps(
        {"samples": 200_000, "return_points": 10}), headers={"content-type": "application/json"})
    response = conn.getresponse()  # computing takes longer than both timeouts: not cut
    assert response.status == 200 and json.loads(response.read())["samples"] == 200_000
    conn.close()


# ---- heavy synchronous work ------------------------------------------------------------
def _sleep_then_pid(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def _die() -> None:
    os._exit(7)


@pytest.mark.slow
def test_heavy_work_runs_in_another_process():
    pool = ComputePool(workers=1, max_waiting=4)
    try:
        assert asyncio.run(pool.run(True, _sleep_then_pid, 0.0)) != os.getpid()
        assert asyncio.run(pool.run(False, _sleep_then_pid, 0.0)) == os.getpid()
    finally:
        pool.shutdown()


@pytest.mark.slow
def test_too_many_waiting_is_busy_and_a_dead_worker_fails_alone():
    pool = ComputePool(workers=1, max_waiting=2)

    async def burst() -> list:
        return await asyncio.gather(*(pool.run(True, _sleep_then_pid, 0.5) for _ in range(3)),
                                    return_exceptions=True)

    try:
        outcomes = asyncio.run(burst())
        assert sum(isinstance(o, ComputeBusy) for o in outcomes) == 1
        assert sum(isinstance(o, int) for o in outcomes) == 2
        with pytest.raises(ComputeFailed):
            asyncio.run(pool.run(True, _die))
        assert isinstance(asyncio.run(pool.run(True, _sleep_then_pid, 0.0)), int)
    finally:
        pool.shutdown()


@pytest.mark.slow
def test_large_requests_go_to_the_pool_and_answer_the_same(tmp_path):
    api = _app(tmp_path)
    client = TestClient(api)
    calls: list[bool] = []
    run = api.state.compute.run

    async def spy(heavy, fn, *args):
        calls.append(heavy)
        return await run(heavy, fn, *args)

    api.state.compute.run = spy
    try:
        body = {"samples": 60_000, "seed": 3, "return_points": 50, "projections": False}
        heavy = client.post(f"{PILE}/workspace", json=body).json()
        small = client.post(f"{PILE}/workspace", json={**body, "samples": 500}).json()
        assert calls == [True, False]
        inline = client.post(f"{GLT}/fk", json={"q": [[0.1] * 6] * 10}).json()
        pooled = client.post(f"{GLT}/fk", json={"q": [[0.1] * 6] * 20_001}).json()
        assert calls[2:] == [False, True]
        # (the kernels for long batches may round the last bit differently)
        np.testing.assert_allclose(pooled["poses"][0], inline["poses"][0], rtol=1e-12)
        assert heavy["samples"] == 60_000 and small["samples"] == 500
    finally:
        api.state.compute.shutdown()


def test_busy_compute_answers_503_with_retry_after(tmp_path):
    api = _app(tmp_path)
    api.state.compute.max_waiting = 1
    api.state.compute._waiting = 1  # one large request in flight already
    r = TestClient(api).post(f"{PILE}/workspace", json={"samples": 100_000})
    assert r.status_code == 503
    assert r.headers["retry-after"] == "2"
    assert r.json()["detail"][0]["loc"] == ["service", "compute"]


class _Unpicklable(Exception):
    def __init__(self, a, b):
        super().__init__(f"{a} and {b}")


def _raise_unpicklable() -> None:
    raise _Unpicklable(1, 2)


def _raise_method_unavailable() -> None:
    from kinematics.errors import MethodUnavailableError

    raise MethodUnavailableError("analytic", "no closed form for this robot")


@pytest.mark.slow
def test_errors_come_back_from_a_worker_without_breaking_it():
    from kinematics.errors import MethodUnavailableError

    pool = ComputePool(workers=1, max_waiting=4)
    try:
        with pytest.raises(MethodUnavailableError) as caught:
            asyncio.run(pool.run(True, _raise_method_unavailable))
        assert caught.value.method == "analytic"
        with pytest.raises(RuntimeError, match="_Unpicklable: 1 and 2"):
            asyncio.run(pool.run(True, _raise_unpicklable))
        assert isinstance(asyncio.run(pool.run(True, _sleep_then_pid, 0.0)), int)
    finally:
        pool.shutdown()


@pytest.mark.slow
def test_shutdown_stops_a_busy_worker_at_once():
    pool = ComputePool(workers=1, max_waiting=4)

    async def start_long() -> None:
        task = asyncio.ensure_future(pool.run(True, _sleep_then_pid, 60.0))
        await asyncio.sleep(1.0)
        task.cancel()

    asyncio.run(start_long())
    processes = list(pool._executor._processes.values())
    assert processes and all(p.is_alive() for p in processes)
    start = time.monotonic()
    pool.shutdown()
    assert not any(p.is_alive() for p in processes)
    assert time.monotonic() - start < 5.0


@pytest.mark.slow
def test_a_batch_ik_on_a_robot_without_a_closed_form_is_422(ro_client):
    T = [[1, 0, 0, 500], [0, 1, 0, 0], [0, 0, 1, 300], [0, 0, 0, 1]]
    r = ro_client.post("/robots/tunnel_drill_arm/ik", json={"pose": [T] * 12,
                                                        "method": "analytic"})
    assert r.status_code == 422 and _locs(r) == [["body", "method"]]
