"""``kinoplan.client`` against a live service: ``python -m app`` in a subprocess on a free
port, with an API key, its own data dir.

The client imports robots from a URDF written here (the GLT palletizer by ``to_urdf``, box and
cylinder collision shapes on two links), stores scenes, runs FK and IK with numpy arrays over
the ``.npy`` transport (checked against ``kinematics.fk`` run here, not by the service), plans
a move and checks its path with the service's collision route, plans a quintic trajectory
(checked against the closed form), submits, follows and cancels jobs, and reads errors with
their status and field. The tour in docs/client.md is run block by block too.

The client's own pieces that need no service (error parsing, the progress bar, what importing
it loads) are tested first, in the fast tier.
"""

from __future__ import annotations

import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest

from kinoplan.client import (
    ApiError,
    Client,
    ConflictError,
    ForbiddenError,
    InvalidError,
    Job,
    NotFoundError,
    QueueFullError,
    UnauthorizedError,
)
from kinoplan.client.errors import error_from_answer
from kinoplan.client.jobs import ProgressBar

REPO = Path(__file__).resolve().parents[2]
API_KEY = "client-test-key"
ROBOT = "glt_palletizer"
START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
SRDF = """<?xml version="1.0"?>
<robot name="glt_palletizer">
  <group name="arm"><chain base_link="base_link" tip_link="tool"/></group>
</robot>
"""
#: Where the tool is half-way between START and GOAL (waist at 0): the ball's centre.
MIDDLE = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]


# ---- without a service -------------------------------------------------------------------
def test_importing_the_client_loads_none_of_the_service():
    """The client is a program of its own: importing it loads httpx and numpy, not the
    service, the libraries, the viewer, FastAPI or pydantic (``app`` itself is the
    ``kinoplan`` package's version string, ``app/__init__``, nothing more)."""
    code = ("import sys, kinoplan.client\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('planning', 'kinematics', 'web', 'fastapi', 'pydantic', 'scipy', 'uvicorn') "
            "or m.startswith('app.')))")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=60, check=True)
    assert done.stdout.strip() == "[]"


def test_an_error_answer_carries_status_detail_and_field():
    body = json.dumps({"detail": [{"loc": ["body", "q", 0], "msg": "bad", "type": "x"},
                                  {"loc": ["body", "q", 3], "msg": "worse", "type": "y"}]})
    e = error_from_answer(422, body.encode(), {}, method="POST", url="/robots/r/fk")
    assert isinstance(e, InvalidError) and isinstance(e, ApiError)
    assert e.status == 422 and e.field == ["body", "q", 0] and e.message == "bad"
    assert e.kind == "x" and len(e.detail) == 2
    assert str(e) == "422 at ['body', 'q', 0]: bad (POST /robots/r/fk)"
    full = error_from_answer(429, b'{"detail": [{"loc": ["body", "kind"], "msg": "full", '
                             b'"type": "queue_full"}]}', {"retry-after": "5"})
    assert isinstance(full, QueueFullError) and full.retry_after == 5.0
    plain = error_from_answer(502, b"Bad Gateway", {})
    assert type(plain) is ApiError and plain.field is None and plain.message == "Bad Gateway"
    other = error_from_answer(500, b'{"detail": "Internal Server Error"}', {})
    assert other.detail == "Internal Server Error" and other.field is None


def test_the_progress_bar_redraws_one_line_and_ends_it():
    out = io.StringIO()
    bar = ProgressBar(out, "sleep j1", width=10)
    bar({"status": "running", "progress": 0.3, "message": "step 3 of 10"})
    bar({"status": "running", "progress": 0.3, "message": "step 3 of 10"})  # unchanged: no-op
    bar({"status": "succeeded", "progress": 0.9, "message": "done"})
    bar.close()
    text = out.getvalue()
    first = "sleep j1 [###-------]  30%  running  step 3 of 10"
    last = "sleep j1 [##########] 100%  succeeded  done"
    assert text == "\r" + first + "\r" + last + " " * (len(first) - len(last)) + "\n"
    assert "\n" not in text[:-1]


def test_the_client_sends_the_api_key_from_its_argument_or_the_environment(monkeypatch):
    seen: list[str | None] = []

    def answer(request: httpx.Request) -> httpx.Response:
        seen.append(request.headers.get("authorization"))
        return httpx.Response(200, json={"status": "ok"})

    monkeypatch.setenv("KINOPLAN_API_KEY", "from-env")
    with Client("http://service:1/", transport=httpx.MockTransport(answer)) as c:
        c.health()
    with Client("http://service:1", api_key="given", transport=httpx.MockTransport(answer)) as c:
        c.health()
    monkeypatch.delenv("KINOPLAN_API_KEY")
    with Client("http://service:1", transport=httpx.MockTransport(answer)) as c:
        c.health()
    assert seen == ["Bearer from-env", "Bearer given", None]


def test_an_upload_given_as_bytes_is_named_by_its_format(monkeypatch):
    """The service tells a URDF from an archive by the upload's file name: bytes without a
    name are named by their first bytes (zip, gzip), else as URDF; the options go as form
    fields, ``fixed_joints`` as JSON."""
    sent: list[bytes] = []

    def answer(request: httpx.Request) -> httpx.Response:
        sent.append(request.read())
        return httpx.Response(201, json={"id": "r"})

    monkeypatch.delenv("KINOPLAN_API_KEY", raising=False)
    with Client("http://service:1", transport=httpx.MockTransport(answer)) as c:
        c.import_robot(b"PK\x03\x04rest", "a")
        c.import_robot(b"\x1f\x8bgzip", "b", srdf=b"<robot/>", group="arm")
        c.import_robot(b"<robot/>", "c", fixed_joints={"gripper": np.float64(0.5)})
        c.import_robot(b"<robot/>", "d", filename="arm.urdf.xml")
    names = [re.findall(rb'name="([a-z_]+)"(?:; filename="([^"]+)")?', body) for body in sent]
    assert sorted(names[0]) == [(b"file", b"robot.zip"), (b"id", b"")]
    assert (b"file", b"robot.tar.gz") in names[1] and (b"srdf", b"robot.srdf") in names[1]
    assert (b"group", b"") in names[1]
    assert (b"file", b"robot.urdf") in names[2] and b'{"gripper": 0.5}' in sent[2]
    assert (b"file", b"arm.urdf.xml") in names[3]


# ---- the live service --------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """``python -m app`` on a free port with an API key; its URL."""
    data = tmp_path_factory.mktemp("client-service")
    port = _free_port()
    log = (data / "service.log").open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "app", "--port", str(port), "--data-dir", str(data / "store"),
         "--workers", "2"],
        cwd=REPO, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
        env={**os.environ, "KINOPLAN_API_KEY": API_KEY}, start_new_session=True)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90  # a loaded CI machine
        while True:
            try:
                httpx.get(url + "/health", timeout=1)
                break
            except httpx.TransportError:
                assert proc.poll() is None, (data / "service.log").read_text()
                assert time.monotonic() < deadline, "service did not start"
                time.sleep(0.1)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        log.close()


@pytest.fixture
def client(service):
    with Client(service, api_key=API_KEY, timeout=60) as c:
        yield c


def _urdf() -> str:
    """The GLT palletizer as URDF, with box and cylinder collision shapes on two links."""
    from kinematics.library import builtin_model
    from kinematics.urdf import to_urdf

    text = to_urdf(builtin_model(ROBOT))
    shapes = {"link_2": '<box size="0.6 0.12 0.12"/>',
              "link_3": '<cylinder radius="0.05" length="0.5"/>'}
    for link, shape in shapes.items():
        text = text.replace(f'<link name="{link}" />',
                            f'<link name="{link}"><collision><geometry>{shape}</geometry>'
                            '</collision></link>')
    return text


def _media_types(client: Client) -> list[str]:
    """The content types of every answer ``client`` receives from now on."""
    seen: list[str] = []
    client._http.event_hooks["response"].append(
        lambda response: seen.append(response.headers.get("content-type", "")))
    return seen


@pytest.mark.slow
def test_a_robot_imported_from_urdf_answers_fk_and_ik_as_arrays(client, tmp_path):
    from kinematics import builtin_model, fk

    path = tmp_path / "glt.urdf"
    path.write_text(_urdf())
    # The chain's tip from the SRDF's group (else it would end at the flange, not the tool).
    model = client.import_robot(path, "glt_client", srdf=SRDF.encode(), group="arm",
                                name="GLT from URDF")
    assert model["id"] == "glt_client" and model["name"] == "GLT from URDF"
    assert [j["name"] for j in model["joints"]] == [j.name for j in builtin_model(ROBOT).joints]
    listed = {r["id"]: r for r in client.robots()}
    assert listed["glt_client"]["dof"] == 6 and listed["glt_client"]["builtin"] is False
    assert client.robot("glt_client")["joints"] == model["joints"]
    with pytest.raises(ConflictError) as taken:
        client.import_robot(_urdf().encode(), "glt_client")
    assert taken.value.status == 409 and taken.value.field == ["body", "id"]

    media = _media_types(client)
    rng = np.random.default_rng(7)
    robot = builtin_model(ROBOT)
    lo, hi = (np.array([getattr(j, k) for j in robot.joints]) for k in ("lower", "upper"))
    q = rng.uniform(lo * 0.8, hi * 0.8, size=(16, 6))
    T = client.fk("glt_client", q)
    assert T.shape == (16, 4, 4) and T.dtype == np.float64
    np.testing.assert_allclose(T, fk(robot, q), atol=1e-6)       # the library, here
    one = client.fk("glt_client", q[0])
    assert one.shape == (4, 4)
    np.testing.assert_allclose(one, T[0])
    frames = client.fk("glt_client", q[:3], frames="all")
    assert frames.shape == (3, 7, 4, 4)
    np.testing.assert_allclose(frames[:, -1], T[:3], atol=1e-9)

    solved = client.ik(ROBOT, T, q0=q[0])
    assert solved.shape == (16, 6)
    np.testing.assert_allclose(fk(robot, solved), T, atol=1e-6)    # round trip: same poses
    assert client.ik(ROBOT, T[0], q0=q[0]).shape == (6,)
    J = client.jacobian(ROBOT, q[0])
    assert J.shape == (6, 6)
    step = 1e-6 * np.eye(6)[2]                                      # the elbow's column
    np.testing.assert_allclose(J[:3, 2], (fk(robot, q[0] + step)[:3, 3]
                                          - fk(robot, q[0] - step)[:3, 3]) / 2e-6, atol=1e-3)
    assert media and all(m == "application/x-npy" for m in media)   # every answer as .npy

    far = T[0].copy()
    far[:3, 3] = [9000.0, 0.0, 0.0]
    both = client.ik(ROBOT, np.stack([T[1], far]), q0=q[1])
    assert np.isfinite(both[0]).all() and np.isnan(both[1]).all()
    results = client.ik_results(ROBOT, np.stack([T[1], far]), all_solutions=True)
    assert [r["status"] for r in results] == ["ok", "unreachable"]
    assert results[0]["solutions"].ndim == 2 and results[0]["solutions"].shape[1] == 6
    assert results[1]["q"] is None

    points = client.workspace(ROBOT, 2_000, seed=3, return_points=50)
    assert points.shape == (50, 3) and np.isfinite(points).all()
    np.testing.assert_array_equal(client.workspace(ROBOT, 2_000, seed=3, return_points=50),
                                  points)                           # seeded: the same points
    assert not np.array_equal(client.workspace(ROBOT, 2_000, seed=4, return_points=50), points)

    client.delete_robot("glt_client")
    with pytest.raises(NotFoundError) as gone:
        client.robot("glt_client")
    assert gone.value.status == 404 and gone.value.field == ["path", "robot_id"]


@pytest.mark.slow
def test_a_robot_model_is_added_and_only_custom_ones_are_deleted(client):
    from kinematics import RobotModel, fk

    data = {"id": "client_arm", "name": "Two joints", "convention": "mdh", "joints": [
        {"name": "j1", "type": "revolute", "a": 0, "alpha": 0, "d": 0, "offset": 0,
         "lower": -3.1, "upper": 3.1, "velocity": 1.0},
        {"name": "j2", "type": "prismatic", "a": 150, "alpha": -1.5708, "theta": 0,
         "offset": 0, "lower": 0, "upper": 800}]}
    stored = client.add_robot(data)
    assert stored["id"] == "client_arm" and [j["name"] for j in stored["joints"]] == ["j1", "j2"]
    q = np.array([[0.3, 100.0], [-1.0, 650.0]])
    np.testing.assert_allclose(client.fk("client_arm", q), fk(RobotModel.from_dict(data), q),
                               atol=1e-9)
    with pytest.raises(InvalidError) as bad:
        client.add_robot({**data, "id": "client_bad",
                          "joints": [{**data["joints"][0], "lower": float("nan")}]})
    assert bad.value.field == ["body", "joints", 0, "lower"]
    client.delete_robot("client_arm")
    with pytest.raises(ForbiddenError) as builtin:
        client.delete_robot(ROBOT)
    assert builtin.value.status == 403 and builtin.value.field == ["path", "robot_id"]


@pytest.mark.slow
def test_scenes_are_stored_listed_read_and_deleted(client):
    pose = np.eye(4)
    pose[:3, 3] = [1000.0, 200.0, 300.0]
    stored = client.store_scene("client_box", [{"type": "box", "id": "crate",
                                                "size": np.array([400.0, 300.0, 200.0]),
                                                "pose": pose}], name="a crate")
    assert stored["id"] == "client_box" and stored["name"] == "a crate"
    assert stored["objects"][0]["pose"] == pose.tolist()
    assert {"id": "client_box", "name": "a crate", "objects": 1} in [
        {k: s[k] for k in ("id", "name", "objects")} for s in client.scenes()]
    assert client.scene("client_box")["objects"] == stored["objects"]
    moveit = client.scene("client_box", format="moveit")
    box = moveit["world"]["collision_objects"][0]
    assert box["primitives"][0]["dimensions"] == pytest.approx([0.4, 0.3, 0.2])   # metres
    with pytest.raises(ConflictError) as taken:
        client.store_scene("client_box", [])
    assert taken.value.field == ["body", "id"]
    with pytest.raises(InvalidError) as bad:
        client.store_scene("client_bad", [{"type": "sphere", "id": "s", "radius": -1.0,
                                           "pose": np.eye(4)}])
    assert bad.value.field[:3] == ["body", "objects", 0]
    client.delete_scene("client_box")
    with pytest.raises(NotFoundError) as gone:
        client.scene("client_box")
    assert gone.value.field == ["path", "scene_id"]


@pytest.mark.slow
def test_a_planned_move_goes_around_the_ball_of_a_stored_scene(client):
    from kinematics import builtin_model, fk

    robot = builtin_model(ROBOT)
    ball = np.eye(4)
    ball[:3, 3] = fk(robot, np.array(MIDDLE))[:3, 3]
    client.store_scene("client_ball", [{"type": "sphere", "id": "ball", "radius": 150.0,
                                        "pose": ball}])
    direct = client.request("POST", f"/robots/{ROBOT}/collision",
                            {"q": np.array(MIDDLE), "scene": "client_ball"})
    assert direct["results"][0]["collides"] is True                 # the straight way is shut

    plan = client.motion(ROBOT, START, GOAL, scene="client_ball", planner="rrt_connect",
                         seed=1, time_limit=1.5)
    assert plan["status"] == "ok", plan["message"]
    path = plan["path"]
    assert path.ndim == 2 and path.shape[1] == 6 and len(path) >= 3
    np.testing.assert_allclose(path[0], START)
    np.testing.assert_allclose(path[-1], GOAL)
    # Every waypoint and the midpoints of every segment are clear, by the service's own check.
    probes = np.concatenate([path, (path[1:] + path[:-1]) / 2])
    checked = client.request("POST", f"/robots/{ROBOT}/collision",
                             {"q": probes, "scene": "client_ball"})["results"]
    assert not any(r["collides"] for r in checked)
    traj = plan["trajectory"]
    assert traj["q"].shape == (len(traj["t"]), 6) and np.all(np.diff(traj["t"]) > 0)
    np.testing.assert_allclose(traj["q"][[0, -1]], [START, GOAL], atol=1e-9)
    page = client.motion_replay(ROBOT, plan, scene="client_ball")
    assert page.startswith("<!DOCTYPE html>") and '"scene/ball"' in page

    to_pose = client.motion(ROBOT, START, fk(robot, np.array(GOAL)), scene="client_ball",
                            planner="rrt_connect", trajectory=False, time_limit=1.5)
    assert to_pose["status"] == "ok", to_pose["message"]
    np.testing.assert_allclose(fk(robot, to_pose["path"][-1]), fk(robot, np.array(GOAL)),
                               atol=1e-3)
    far = np.eye(4)
    far[:3, 3] = [9000.0, 0.0, 0.0]
    out_of_reach = client.motion(ROBOT, START, {"pose": far}, scene="client_ball")
    assert out_of_reach["status"] == "goal_unreachable"          # an answer, not an error
    assert out_of_reach["path"].shape == (0, 6)


@pytest.mark.slow
def test_a_quintic_trajectory_is_the_closed_form(client):
    out = client.trajectory([[0.0, 0.0], [1.0, 2.0]], [2.0], dt=0.25)
    t = out["t"]
    np.testing.assert_allclose(t, np.arange(9) * 0.25)
    s = t / 2.0
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5                        # rest to rest
    np.testing.assert_allclose(out["q"], blend[:, None] * [1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(out["qd"][:, 1], 2.0 * (30 * s**2 - 60 * s**3 + 30 * s**4)
                               / 2.0, atol=1e-12)
    assert out["qddd"].shape == (9, 2) and out["limits"]["ok"] is True
    with pytest.raises(InvalidError) as bad:
        client.trajectory([[0.0, 0.0], [1.0, 2.0]], [2.0, 1.0])
    assert bad.value.field == ["body", "durations"]


@pytest.mark.slow
def test_a_job_is_followed_to_its_typed_result(client, capsys):
    from app.jobs.kinds import SleepResult

    job = client.submit("sleep", {"seconds": 0.6, "steps": 6})
    assert isinstance(job, Job) and job.kind == "sleep" and job.id
    assert job.status() in ("queued", "running", "succeeded")
    seen: list[tuple[float, str]] = []
    record = job.wait(timeout=60, progress=lambda p, m: seen.append((p, m)), poll=0.05)
    assert record["status"] == "succeeded" and record["progress"] == 1.0
    fractions = [p for p, _ in seen]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(seen) >= 3
    assert any(m.startswith("step ") for _, m in seen)

    result = job.result()
    assert isinstance(result, SleepResult) and result.slept == 0.6 and result.pid > 0
    assert job.result(typed=False) == {"slept": 0.6, "pid": result.pid}
    again = client.job(job.id)
    assert again.kind == "sleep" and again.result().pid == result.pid
    assert job.id in [r["id"] for r in client.jobs(kind="sleep", status="succeeded")]
    assert "sleep" in [k["kind"] for k in client.job_kinds()]
    with pytest.raises(InvalidError) as no_motion:                  # a sleep has no motion
        job.replay_html()
    assert no_motion.value.status == 422 and no_motion.value.field == ["path", "job_id"]

    capsys.readouterr()
    client.submit("sleep", {"seconds": 0.2, "steps": 2}).wait(timeout=60)  # stderr: no tty
    assert capsys.readouterr().err == ""
    drawn = client.submit("sleep", {"seconds": 0.3, "steps": 3})
    drawn.wait(timeout=60, progress=True)
    err = capsys.readouterr().err
    assert err.startswith("\r") and err.endswith("\n") and err.count("\n") == 1
    assert f"sleep {drawn.id} [" in err and "100%  succeeded" in err


@pytest.mark.slow
def test_a_job_is_cancelled_and_then_deleted(client):
    job = client.submit("sleep", {"seconds": 60, "steps": 60})
    with pytest.raises(TimeoutError):
        job.wait(timeout=0.3, progress=False)
    record = job.cancel()
    assert record is not None and record["id"] == job.id
    assert job.wait(timeout=15, progress=False)["status"] == "cancelled"
    with pytest.raises(ConflictError) as early:
        job.result()
    assert early.value.status == 409 and early.value.field == ["path", "job_id"]
    assert job.cancel() is None                     # ended: deleted, with its record
    with pytest.raises(NotFoundError) as gone:
        job.status()
    assert gone.value.status == 404 and gone.value.field == ["path", "job_id"]


@pytest.mark.slow
def test_errors_carry_status_detail_and_field(client, service):
    with pytest.raises(InvalidError) as nan:
        client.fk(ROBOT, [0.0, np.nan, 0.0, 0.0, 0.0, 0.0])
    assert nan.value.status == 422 and nan.value.field == ["body", "q", 1]
    assert nan.value.detail[0]["type"] == "finite_number"
    with pytest.raises(InvalidError) as short:
        client.ik(ROBOT, np.eye(4), q0=[0.0, 0.0])
    assert short.value.field == ["body", "q0"]
    with pytest.raises(NotFoundError) as robot:
        client.fk("no_such_robot", np.zeros(6))
    assert robot.value.status == 404 and robot.value.field == ["path", "robot_id"]
    with pytest.raises(InvalidError) as params:
        client.submit("sleep", {"seconds": -1})
    assert params.value.field == ["body", "params", "seconds"]
    with pytest.raises(ApiError) as kind:
        client.submit("no_such_kind")
    assert kind.value.status == 422 and kind.value.field == ["body", "kind"]
    with Client(service, api_key="wrong") as stranger:
        assert stranger.robots()                    # reading needs no key
        with pytest.raises(UnauthorizedError) as denied:
            stranger.submit("sleep", {"seconds": 0})
    assert denied.value.status == 401 and denied.value.field == ["header", "authorization"]


@pytest.mark.slow
def test_the_tour_in_the_docs_runs(service, tmp_path, monkeypatch, capsys):
    """Every ```python block of docs/client.md, in order, in one namespace, against a fresh
    part of the service (its own robot and scene ids); what each ``print`` shows is the
    comment beside it (up to a colon), but for the lists of every robot and scene."""
    text = (REPO / "docs" / "client.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) >= 6
    code = "\n".join(blocks)
    assert "http://127.0.0.1:8000" in code
    renames = {"http://127.0.0.1:8000": service, '"my_glt': '"doc_glt', "'my_glt": "'doc_glt",
               '"cell"': '"doc_cell"'}
    for old, new in renames.items():
        code = code.replace(old, new)
    monkeypatch.setenv("KINOPLAN_API_KEY", API_KEY)
    monkeypatch.chdir(tmp_path)
    capsys.readouterr()
    exec(compile(code, str(REPO / "docs" / "client.md"), "exec"), {"__name__": "tour"})  # noqa: S102
    printed = capsys.readouterr().out.splitlines()
    prints = [line for line in code.splitlines() if line.lstrip().startswith("print(")]
    expected = [line.split("# ", 1)[1].split(":")[0].strip() for line in prints]
    assert len(printed) == len(expected)
    for line, got, want in zip(prints, printed, expected):
        if "c.robots()" in line or "c.scenes()" in line:
            continue                  # lists of ids: other tests' robots and scenes too
        assert got == want.replace("my_glt", "doc_glt"), line
