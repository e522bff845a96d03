"""Who may open the 3D viewer: the API key, allowed origins, the internal port, and the
limits on the workspace jobs a viewer may start.

Real viewers on free loopback ports are driven over raw HTTP (``http.client``, sockets) and
real websockets (the ``websockets`` client, with viser's subprotocol). The job pool is not
started, so jobs submitted from the viewer stay queued.
"""

from __future__ import annotations

import http.client
import socket
import threading
import time
from pathlib import Path

import msgspec
import pytest
import viser
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from app.__main__ import parse_args
from app.config import Settings
from app.main import create_app
from kinematics.workspace import MAX_SAMPLES
from kinoplan.__main__ import main
from web import gate as gate_module
from web.gate import (
    GATE_HEADER,
    GatePolicy,
    HeadError,
    default_origins,
    normalize_origin,
    parse_head,
    parse_origins,
    session_token,
)
from web.gui import MAX_GUI_SAMPLES, MIN_GUI_SAMPLES
from web.viewer import Viewer

KEY = "viewer-test-key-0123456789"
EVIL = "http://evil.example"
SUBPROTOCOL = f"viser-v{viser.__version__}"
INDEX_HTML = (Path(viser.__file__).parent / "client" / "build" / "index.html").read_bytes()


# ---- fixtures and helpers ----------------------------------------------------------------
def _viewer_on(tmp_path_factory, port: int, **kwargs):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("data"),
                              workers=1))
    viewer = Viewer.start("127.0.0.1", port, api.state, environment_map=False, **kwargs)
    return api, viewer


def _viewer(tmp_path_factory, **kwargs):
    return _viewer_on(tmp_path_factory, 0, **kwargs)


@pytest.fixture(scope="module")
def keyed(tmp_path_factory):
    """A viewer started with an API key."""
    api, viewer = _viewer(tmp_path_factory, api_key=KEY)
    yield viewer
    viewer.stop()


@pytest.fixture(scope="module")
def keyless(tmp_path_factory):
    """A viewer started without a key, as before keys existed."""
    api, viewer = _viewer(tmp_path_factory)
    yield viewer
    viewer.stop()


@pytest.fixture
def service(tmp_path_factory):
    """An application (job pool not started: jobs stay queued) with a keyless viewer."""
    api, viewer = _viewer(tmp_path_factory)
    yield api, viewer
    viewer.stop()


def _get(port: int, target: str = "/", headers: dict | None = None):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        conn.request("GET", target, headers=headers or {})
        response = conn.getresponse()
        return response.status, response.headers, response.read()
    finally:
        conn.close()


def _login(viewer: Viewer) -> str:
    """The cookie the key earns, as a ``Cookie`` header value."""
    status, headers, _ = _get(viewer.port, f"/?key={KEY}")
    assert status == 303
    return headers["Set-Cookie"].split(";", 1)[0]


def _own_origin(viewer: Viewer) -> str:
    return f"http://127.0.0.1:{viewer.port}"


def _open_ws(port: int, *, cookie: str | None = None, origin: str | None = None):
    headers = {"Cookie": cookie} if cookie else None
    return connect(f"ws://127.0.0.1:{port}/", subprotocols=[SUBPROTOCOL],
                   additional_headers=headers, origin=origin, open_timeout=10,
                   max_size=None)


def _refused_ws(port: int, **kwargs) -> int:
    with pytest.raises(InvalidStatus) as info:
        with _open_ws(port, **kwargs):
            pass
    return info.value.response.status_code


def _raw(port: int, data: bytes, *, wait_s: float = 10.0) -> bytes:
    """Send ``data`` on a new connection and read until the server closes it."""
    with socket.create_connection(("127.0.0.1", port), timeout=wait_s) as s:
        s.sendall(data)
        chunks = []
        try:
            while chunk := s.recv(65536):
                chunks.append(chunk)
        except ConnectionResetError:
            pass
        return b"".join(chunks)


def _wait(predicate, timeout: float = 10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if value := predicate():
            return value
        time.sleep(0.02)
    raise AssertionError("condition not met in time")


# ---- the key -------------------------------------------------------------------------------
def test_without_the_key_the_page_is_401_and_says_how_to_open_it(keyed):
    status, headers, body = _get(keyed.port)
    assert status == 401
    assert headers["Content-Type"].startswith("text/plain")
    assert b"?key=" in body and b"<html" not in body
    assert "Set-Cookie" not in headers


def test_a_wrong_key_is_401_without_a_cookie(keyed):
    for target in ("/?key=wrong", f"/?key={KEY}x", f"/?key={KEY[:-1]}", "/?key=",
                   f"/?key={KEY}&key=wrong"):
        status, headers, _ = _get(keyed.port, target)
        assert status == 401, target
        assert "Set-Cookie" not in headers, target


def test_the_right_key_sets_a_cookie_and_redirects_without_it(keyed):
    status, headers, _ = _get(keyed.port, f"/?key={KEY}")
    assert status == 303
    assert headers["Location"] == "/"
    cookie = headers["Set-Cookie"]
    attributes = [a.strip() for a in cookie.split(";")]
    name, _, value = attributes[0].partition("=")
    assert name == f"kinoplan_viewer_{keyed.port}"
    assert value == session_token(KEY) and KEY not in cookie
    assert {"HttpOnly", "SameSite=Strict", "Path=/"} <= set(attributes[1:])
    assert headers["Cache-Control"] == "no-store"
    # Other parameters of the address are kept; an odd path cannot redirect elsewhere.
    assert _get(keyed.port, f"/?x=1&key={KEY}&y=2")[1]["Location"] == "/?x=1&y=2"
    assert _get(keyed.port, f"/\\evil.example/?key={KEY}")[1]["Location"] == "/evil.example/"


def test_the_cookie_opens_the_page(keyed):
    cookie = _login(keyed)
    status, _, body = _get(keyed.port, "/", {"Cookie": f"other=1; {cookie}"})
    assert status == 200
    assert body == INDEX_HTML  # viser's page, relayed byte for byte
    # A cookie of the wrong value, or one earned with another key, is not enough.
    name = cookie.split("=", 1)[0]
    for bad in (f"{name}=0123", f"{name}={session_token('other key')}", f"{name}={KEY}",
                f"kinoplan_viewer_1={session_token(KEY)}"):
        assert _get(keyed.port, "/", {"Cookie": bad})[0] == 401, bad


def test_the_websocket_needs_the_cookie(keyed):
    assert _refused_ws(keyed.port) == 401
    assert _refused_ws(keyed.port, origin=_own_origin(keyed)) == 401
    assert _refused_ws(keyed.port, cookie="kinoplan=x", origin=_own_origin(keyed)) == 401


def test_a_websocket_from_another_origin_is_403_even_with_the_cookie(keyed):
    cookie = _login(keyed)
    assert _refused_ws(keyed.port, cookie=cookie, origin=EVIL) == 403
    assert _refused_ws(keyed.port, origin=EVIL) == 403
    assert _refused_ws(keyed.port, cookie=cookie, origin="null") == 403
    # The same holds for the page and for the key itself.
    assert _get(keyed.port, "/", {"Cookie": cookie, "Origin": EVIL})[0] == 403
    status, headers, _ = _get(keyed.port, f"/?key={KEY}", {"Origin": EVIL})
    assert status == 403 and "Set-Cookie" not in headers


def test_the_websocket_with_the_cookie_and_an_allowed_origin_gets_the_scene(keyed):
    cookie = _login(keyed)
    for origin in (_own_origin(keyed), f"http://localhost:{keyed.port}"):
        with _open_ws(keyed.port, cookie=cookie, origin=origin) as ws:
            assert ws.subprotocol == SUBPROTOCOL
            first = ws.recv(timeout=10)  # the scene so far (viser's compressed batches)
            assert isinstance(first, bytes) and len(first) > 100


# ---- without a key -------------------------------------------------------------------------
def test_without_a_key_the_viewer_is_open(keyless):
    status, headers, body = _get(keyless.port)
    assert status == 200 and body == INDEX_HTML
    assert "Set-Cookie" not in headers
    assert _get(keyless.port, "/?key=anything")[0] == 200  # no key to check
    with _open_ws(keyless.port, origin=_own_origin(keyless)) as ws:
        assert ws.recv(timeout=10)
    with _open_ws(keyless.port) as ws:  # no Origin: not a page of another site
        assert ws.recv(timeout=10)


def test_without_a_key_other_origins_are_still_403(keyless):
    assert _refused_ws(keyless.port, origin=EVIL) == 403
    assert _refused_ws(keyless.port, origin=f"http://127.0.0.1:{keyless.port + 1}") == 403
    assert _get(keyless.port, "/", {"Origin": EVIL})[0] == 403


def test_configured_origins_replace_the_defaults(tmp_path_factory):
    api, viewer = _viewer(tmp_path_factory, api_key=KEY,
                          allowed_origins="https://viewer.example.com, http://10.0.0.5:9000")
    try:
        cookie = _login(viewer)
        with _open_ws(viewer.port, cookie=cookie, origin="https://viewer.example.com") as ws:
            assert ws.recv(timeout=10)
        with _open_ws(viewer.port, cookie=cookie, origin="http://10.0.0.5:9000") as ws:
            assert ws.recv(timeout=10)
        assert _refused_ws(viewer.port, cookie=cookie, origin=_own_origin(viewer)) == 403
        assert _refused_ws(viewer.port, cookie=cookie, origin=EVIL) == 403
    finally:
        viewer.stop()
    with pytest.raises(ValueError, match="origin"):
        _viewer(tmp_path_factory, allowed_origins="viewer.example.com")


# ---- the internal port and the request head ------------------------------------------------
def test_the_internal_viser_port_answers_only_the_front(keyed):
    internal = keyed.server.get_port()
    assert internal != keyed.port
    status, _, body = _get(internal)
    assert status == 403 and body != INDEX_HTML
    assert _get(internal, "/", {GATE_HEADER: "guess"})[0] == 403
    assert _refused_ws(internal, origin=f"http://127.0.0.1:{internal}") == 403
    # A client cannot smuggle its own gate header through the front either.
    cookie = _login(keyed)
    assert _get(keyed.port, "/", {"Cookie": cookie, GATE_HEADER: "guess"})[0] == 200


def test_one_request_per_connection(keyed):
    cookie = _login(keyed)
    first = f"GET / HTTP/1.1\r\nHost: x\r\nCookie: {cookie}\r\n\r\n".encode()
    second = b"GET / HTTP/1.1\r\nHost: x\r\nOrigin: http://evil.example\r\n\r\n"
    answer = _raw(keyed.port, first + second)
    assert answer.startswith(b"HTTP/1.1 200")
    assert answer.count(b"HTTP/1.1 ") == 1


def test_malformed_slow_and_large_heads(keyed, monkeypatch):
    cookie = _login(keyed)
    assert _raw(keyed.port, b"POST / HTTP/1.1\r\nHost: x\r\n\r\n").startswith(b"HTTP/1.1 405")
    with_body = f"GET / HTTP/1.1\r\nCookie: {cookie}\r\nContent-Length: 3\r\n\r\nabc".encode()
    assert _raw(keyed.port, with_body).startswith(b"HTTP/1.1 400")
    assert _raw(keyed.port, b"GET http://x/ HTTP/1.1\r\n\r\n").startswith(b"HTTP/1.1 400")
    assert _raw(keyed.port, b"GET / HTTP/1.1\nHost: x\n\n\r\n\r\n").startswith(b"HTTP/1.1 400")
    huge = b"GET / HTTP/1.1\r\nX-Pad: " + b"a" * (gate_module.HEAD_LIMIT + 10) + b"\r\n\r\n"
    assert _raw(keyed.port, huge).startswith(b"HTTP/1.1 431")
    monkeypatch.setattr(gate_module, "HEAD_TIMEOUT_S", 0.3)
    started = time.monotonic()
    assert _raw(keyed.port, b"GET / HTTP/1.1\r\n").startswith(b"HTTP/1.1 408")
    assert time.monotonic() - started < 5


def test_connections_beyond_the_cap_are_closed(keyed, monkeypatch):
    monkeypatch.setattr(gate_module, "MAX_CONNECTIONS", 2)
    idle = [socket.create_connection(("127.0.0.1", keyed.port), timeout=5) for _ in range(2)]
    try:
        time.sleep(0.3)  # both accepted and waiting for their heads
        assert _raw(keyed.port, b"GET / HTTP/1.1\r\n\r\n", wait_s=5) == b""
    finally:
        for s in idle:
            s.close()
    _wait(lambda: _get(keyed.port)[0] == 401)


# ---- the policy, without sockets -----------------------------------------------------------
def _head(*headers: str, target: str = "/") -> bytes:
    return (f"GET {target} HTTP/1.1\r\n" + "".join(f"{h}\r\n" for h in headers)
            + "\r\n").encode()


def test_default_origins():
    loopback, same_host = default_origins("127.0.0.1", 8080)
    assert loopback == {"http://127.0.0.1:8080", "http://localhost:8080", "http://[::1]:8080"}
    assert not same_host
    named, same_host = default_origins("viewer.lan", 8080)
    assert named == {"http://viewer.lan:8080"} and not same_host
    everywhere, same_host = default_origins("0.0.0.0", 8080)
    assert "http://localhost:8080" in everywhere and same_host
    assert default_origins("::1", 80)[0] >= {"http://[::1]", "http://localhost"}


def _status(policy: GatePolicy, *headers: str, target: str = "/") -> int:
    """403/401/... for an answer, 0 for a relay."""
    return getattr(policy.decide(parse_head(_head(*headers, target=target))), "status", 0)


def test_bound_everywhere_the_page_may_use_the_address_it_was_opened_with():
    cookie = f"Cookie: kinoplan_viewer_8080={session_token(KEY)}"
    keyed = GatePolicy(port=8080, host="0.0.0.0", api_key=KEY)
    relay = keyed.decide(parse_head(_head("Host: robots.lan:9090", cookie, "Upgrade: websocket",
                                          "Origin: http://robots.lan:9090")))
    assert getattr(relay, "both_ways", False)
    for host, origin in (("robots.lan:9090", EVIL), ("robots.lan:9090", "http://robots.lan"),
                         ("evil.example", "http://robots.lan:9090")):
        assert _status(keyed, f"Host: {host}", f"Origin: {origin}", cookie) == 403
    # Behind a TLS proxy that keeps the Host header.
    assert _status(keyed, "Host: robots.lan", "Origin: https://robots.lan", cookie) == 0
    # Without a key: addresses (a published container port), not names (DNS rebinding).
    open_ = GatePolicy(port=8080, host="0.0.0.0")
    assert _status(open_, "Host: 192.168.1.5:9090", "Origin: http://192.168.1.5:9090") == 0
    assert _status(open_, "Host: [fd00::5]:8080", "Origin: http://[fd00::5]:8080") == 0
    assert _status(open_, "Host: localhost:9090", "Origin: http://localhost:9090") == 0
    assert _status(open_, "Host: evil.example:8080", "Origin: http://evil.example:8080") == 403
    # Bound to one address, the Host header does not matter.
    one = GatePolicy(port=8080, host="127.0.0.1")
    assert _status(one, "Host: 127.0.0.1:9090", "Origin: http://127.0.0.1:9090") == 403


def test_origins_are_normalized_and_checked():
    assert normalize_origin("HTTP://Viewer.Example.com:80/") == "http://viewer.example.com"
    assert normalize_origin("https://x.example:443") == "https://x.example"
    assert normalize_origin("http://[::1]:8080") == "http://[::1]:8080"
    assert parse_origins(" http://a.example, ,https://b.example:8443 ") == (
        "http://a.example", "https://b.example:8443")
    assert parse_origins("") is None and parse_origins(None) is None
    for bad in ("a.example", "ftp://a.example", "http://a.example/path", "http://u@a.example",
                "http://a.example:99999", "http://"):
        with pytest.raises(ValueError):
            normalize_origin(bad)


def test_forwarded_heads_carry_the_secret_and_drop_the_clients():
    policy = GatePolicy(port=8080, host="127.0.0.1", upstream_secret="s3cret")
    relay = policy.decide(parse_head(_head("Host: x", f"{GATE_HEADER}: forged")))
    forwarded = relay.head.decode()
    assert f"{GATE_HEADER}: s3cret\r\n" in forwarded and "forged" not in forwarded
    assert forwarded.startswith("GET / HTTP/1.1\r\nHost: x\r\n")
    assert not relay.both_ways
    with pytest.raises(HeadError):
        policy.decide(parse_head(_head("Origin: http://a", "Origin: http://b")))


# ---- settings and the command line ---------------------------------------------------------
def test_settings_and_flag_reach_the_viewer(tmp_path, monkeypatch):
    import uvicorn

    monkeypatch.setenv("KINOPLAN_ALLOWED_ORIGINS", "https://env.example")
    assert Settings().allowed_origins == "https://env.example"
    assert parse_args([]).allowed_origins == "https://env.example"
    assert parse_args(["--allowed-origins", "https://a.example,https://b.example"]
                      ).allowed_origins == "https://a.example,https://b.example"

    calls = []

    class FakeViewer:
        port = 1

        def stop(self) -> None:
            calls.append("stopped")

    def fake_start(cls, host, port, state, **kwargs):
        calls.append((host, port, kwargs))
        return FakeViewer()

    monkeypatch.setattr(Viewer, "start", classmethod(fake_start))
    monkeypatch.setattr(uvicorn, "run", lambda *a, **k: None)
    monkeypatch.setenv("KINOPLAN_API_KEY", KEY)
    assert main(["--data-dir", str(tmp_path), "--viewer-port", "9123"]) == 0
    host, port, kwargs = calls[0]
    assert (host, port) == ("127.0.0.1", 9123)
    assert kwargs["api_key"] == KEY
    assert kwargs["allowed_origins"] == "https://env.example"
    assert calls[-1] == "stopped"


# ---- workspace jobs from the viewer --------------------------------------------------------
def _workspace_jobs(api) -> list:
    return [j for j in api.state.jobs.list() if j.kind == "workspace"]


def test_one_workspace_job_of_the_viewer_at_a_time(service):
    api, viewer = service
    first = viewer.run_workspace(2500)
    assert first is not None
    assert viewer.run_workspace(2500) is None
    assert "still running" in viewer.gui.workspace.content and first in viewer.gui.workspace.content
    # Many clicks at once from many tabs: still one job.
    threads = [threading.Thread(target=viewer.run_workspace, args=(1000,)) for _ in range(20)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert [j.id for j in _workspace_jobs(api)] == [first]
    # Once it has ended (here: cancelled through the API), the next one may start.
    api.state.jobs.cancel(first)
    second = viewer.run_workspace(2500)
    assert second not in (None, first)
    assert len(_workspace_jobs(api)) == 2


def test_workspace_samples_stay_within_the_api_caps(service):
    api, viewer = service
    assert MAX_GUI_SAMPLES == MAX_SAMPLES  # the synchronous cap, below the job cap
    assert viewer.gui.samples.max == MAX_GUI_SAMPLES
    assert viewer.gui.samples.min == MIN_GUI_SAMPLES
    for bad in (MAX_SAMPLES + 1, 20_000_000, MIN_GUI_SAMPLES - 1, 0, -5, 1500.5,
                float("nan"), float("inf"), "many", None):
        assert viewer.run_workspace(bad) is None, bad
        assert "samples must be a whole number" in viewer.gui.workspace.content
    assert _workspace_jobs(api) == []
    job_id = viewer.run_workspace(float(MAX_SAMPLES))
    assert api.state.jobs.get(job_id).params["samples"] == MAX_SAMPLES


def test_clicks_over_the_websocket_start_one_bounded_job(service):
    """What a browser (or any websocket client) sends: a huge sample count is refused, and a
    burst of clicks starts one job."""
    api, viewer = service
    samples = viewer.gui.samples._impl.uuid
    button = viewer.gui.run_workspace._impl.uuid

    def update(uuid: str, value) -> bytes:
        return msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": uuid,
                                       "updates": {"value": value}})

    with _open_ws(viewer.port, origin=_own_origin(viewer)) as ws:
        ws.recv(timeout=10)
        # viser counts a client as connected (and runs its callbacks) after its first camera.
        ws.send(msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0],
            "position": [3.0, 0.0, 1.0], "fov": 1.0, "near": 0.01, "far": 100.0,
            "image_height": 600, "image_width": 800, "look_at": [0.0, 0.0, 0.0],
            "up_direction": [0.0, 0.0, 1.0]}))
        _wait(lambda: len(viewer.server.get_clients()) == 1)
        ws.send(update(samples, 20_000_000))
        _wait(lambda: viewer.gui.samples.value == 20_000_000)
        ws.send(update(button, True))
        _wait(lambda: "samples must be a whole number" in viewer.gui.workspace.content)
        assert _workspace_jobs(api) == []
        ws.send(update(samples, 3000))
        _wait(lambda: viewer.gui.samples.value == 3000)
        for _ in range(30):
            ws.send(update(button, True))
        _wait(lambda: "still running" in viewer.gui.workspace.content)
    jobs = _workspace_jobs(api)
    assert len(jobs) == 1 and jobs[0].params["samples"] == 3000


def test_a_busy_port_moves_the_viewer_to_a_free_one(tmp_path_factory):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        busy = taken.getsockname()[1]
        api, viewer = _viewer_on(tmp_path_factory, busy)
        try:
            assert viewer.port > busy
            assert _get(viewer.port)[0] == 200
        finally:
            viewer.stop()
