"""Motion plans in the viewer: results of ``motion`` jobs (one problem, a batch) and answers of
``POST /robots/{id}/motion`` drawn and played back, without a browser and in one.

Every result is real: the ``motion`` job kind run in this process as a worker runs it (it
calls ``planning.motion.plan_motion``), ``plan_motion`` itself, or the service with its
workers for the browser. The references are the kinematics library's forward kinematics, the
imported robot's own link poses and the numbers the scene was given with.
"""

from __future__ import annotations

import io
import json
import math
import time

import numpy as np
import pytest
from chromium_setup import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS, served_viewer
from fastapi.testclient import TestClient

from app.jobs.catalog import KINDS
from app.jobs.kinds import JobPayload, execute
from app.jobs.motion_kinds import motion_answer
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.library import builtin_model
from web.results import (
    DEFAULT_SECONDS,
    DRAWERS,
    TOOL_PATH_STEP,
    Plan,
    picks_problems,
    plan_from_motion,
    plan_from_result,
)
from web.scene import MM_TO_M
from web.viewer import Viewer

pytestmark = pytest.mark.usefixtures("motion_kernels")

ROBOT = "glt_palletizer"
IMPORTED = "glt_meshed"
START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
MIDDLE = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]  # its tool point is the ball's centre
RADIUS = 150.0


def _ball_center() -> np.ndarray:
    return fk(builtin_model(ROBOT), np.array(MIDDLE))[:3, 3]


def _ball() -> dict:
    pose = np.eye(4)
    pose[:3, 3] = _ball_center()
    return {"type": "sphere", "id": "ball", "radius": RADIUS, "pose": pose.tolist()}


def _run(params: dict) -> tuple[dict, dict]:
    """The stored params and result JSON of a motion job run as a worker runs it."""
    spec = KINDS["motion"]
    checked = spec.load_params(params)
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(params["robot"]).to_dict())
    text = execute("motion", payload.model_dump(mode="json"), lambda fraction, message: None)
    return checked.model_dump(mode="json"), json.loads(text)


@pytest.fixture(scope="module")
def one() -> tuple[dict, dict]:
    """One problem around the ball, timed."""
    return _run({"robot": ROBOT, "scene": {"objects": [_ball()]}, "start": START,
                 "goal": {"q": GOAL}, "time_limit": 2.0})


@pytest.fixture(scope="module")
def untimed() -> tuple[dict, dict]:
    """The same problem without a trajectory."""
    return _run({"robot": ROBOT, "scene": {"objects": [_ball()]}, "start": START,
                 "goal": {"q": GOAL}, "time_limit": 2.0, "trajectory": False})


#: A tool pose 20 m away: no arm here reaches it.
FAR = [[1.0, 0.0, 0.0, 20_000.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 1000.0],
       [0.0, 0.0, 0.0, 1.0]]


@pytest.fixture(scope="module")
def batch() -> tuple[dict, dict]:
    """Four problems: one whose start collides with the ball, there and back, and a goal
    pose out of reach."""
    return _run({"robot": ROBOT, "scene": {"objects": [_ball()]}, "time_limit": 2.0,
                 "problems": [{"start": MIDDLE, "goal": {"q": GOAL}},
                              {"start": START, "goal": {"q": GOAL}},
                              {"start": GOAL, "goal": {"q": START}, "seed": 7},
                              {"start": START, "goal": {"pose": FAR}}]})



def _draw(params: dict, result: dict, **kw) -> Plan:
    return plan_from_result("motion", params, result, job="m", models=builtin_model, **kw)


def _polyline(plan: Plan, name: str) -> np.ndarray:
    return next(p.points for p in plan.polylines if p.name == name)


def _balls(plan: Plan, name: str) -> np.ndarray:
    return next(s.centers for s in plan.spheres if s.name == name)


def _at(t: float, times, rows) -> np.ndarray:
    """Joint values at ``t`` between the samples ``rows`` taken at ``times``."""
    rows = np.asarray(rows, dtype=float)
    return np.array([np.interp(t, times, rows[:, j]) for j in range(rows.shape[1])])


def _wait(predicate, timeout: float = 30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError("condition not met in time")


# ---- plans ----------------------------------------------------------------------------------
def test_motion_jobs_are_drawable_one_problem_at_a_time():
    assert "motion" in DRAWERS and picks_problems("motion")
    assert not picks_problems("path")
    with pytest.raises(FieldError) as info:  # before anything is parsed
        plan_from_result("path", {}, {}, models=builtin_model, problem=0)
    assert info.value.loc == ("problem",)


def test_one_problem_plays_its_trajectory_through_its_scene(one):
    params, result = one
    assert result["status"] == "ok" and result["trajectory"] is not None
    model = builtin_model(ROBOT)
    plan = _draw(params, result)
    assert (plan.kind, plan.robot, plan.job) == ("motion", ROBOT, "m")
    motion = plan.motions[""]
    trajectory = result["trajectory"]
    np.testing.assert_allclose(motion.t, trajectory["t"])
    np.testing.assert_allclose(motion.q, trajectory["q"])
    assert plan.duration == pytest.approx(trajectory["duration"])
    np.testing.assert_allclose(motion.at(0.0), START, atol=1e-9)
    np.testing.assert_allclose(motion.at(plan.duration), result["goal"], atol=1e-9)
    np.testing.assert_allclose(result["goal"], GOAL, atol=1e-9)
    # The tool's route: from the start's tool point to the goal's, around the ball.
    route = _polyline(plan, "tool_path")
    assert len(route) == len(trajectory["q"])
    np.testing.assert_allclose(route[0], fk(model, np.array(START))[:3, 3], atol=1e-6)
    np.testing.assert_allclose(route[-1], fk(model, np.array(GOAL))[:3, 3], atol=1e-6)
    assert np.linalg.norm(route - _ball_center(), axis=1).min() > RADIUS
    np.testing.assert_allclose(_balls(plan, "start"), [fk(model, np.array(START))[:3, 3]])
    np.testing.assert_allclose(_balls(plan, "goal"), [fk(model, np.array(GOAL))[:3, 3]])
    waypoints = _balls(plan, "waypoints")
    assert len(waypoints) == len(result["path"])
    for point, q in zip(waypoints, result["path"]):
        np.testing.assert_allclose(point, fk(model, np.array(q))[:3, 3], atol=1e-9)
    # The scene it planned in, as given.
    (site,) = plan.sites
    assert site.name == "scene" and [o.id for o in site.objects] == ["ball"]
    np.testing.assert_allclose(site.objects[0].pose[:3, 3], _ball_center())
    assert site.objects[0].radius == RADIUS
    lower, upper = plan.bounds()
    assert np.all(lower <= _ball_center() - RADIUS) and np.all(upper >= _ball_center() + RADIUS)
    assert "**ok**" in plan.summary and "time-optimal" in plan.summary


def test_without_a_trajectory_the_arm_moves_along_the_path_at_constant_speed(untimed):
    params, result = untimed
    assert result["status"] == "ok" and result["trajectory"] is None
    model = builtin_model(ROBOT)
    path = np.array(result["path"])
    plan = _draw(params, result)
    motion = plan.motions[""]
    np.testing.assert_allclose(motion.q, path)
    assert motion.t[0] == 0.0 and plan.duration == pytest.approx(DEFAULT_SECONDS)
    speeds = np.linalg.norm(np.diff(path, axis=0), axis=1) / np.diff(motion.t)  # revolute
    np.testing.assert_allclose(speeds, result["length"] / DEFAULT_SECONDS, rtol=1e-9)
    # The route follows the straight joint segments, refined: it passes every waypoint's
    # tool point and has at least a point per TOOL_PATH_STEP of the largest joint step.
    route = _polyline(plan, "tool_path")
    steps = np.ceil(np.abs(np.diff(path, axis=0)).max(axis=1) / TOOL_PATH_STEP)
    assert len(route) >= steps.sum() + 1
    for q in path:
        tool = fk(model, q)[:3, 3]
        assert np.linalg.norm(route - tool, axis=1).min() < 1e-6
    assert np.linalg.norm(route - _ball_center(), axis=1).min() > RADIUS
    assert "constant joint speed" in plan.summary


def test_a_batch_shows_its_first_solved_problem_or_the_one_named(batch):
    params, result = batch
    statuses = [p["status"] for p in result["problems"]]
    assert statuses == ["start_in_collision", "ok", "ok", "goal_unreachable"]
    model = builtin_model(ROBOT)
    first = _draw(params, result)
    np.testing.assert_allclose(first.motions[""].q[0], START, atol=1e-9)
    np.testing.assert_allclose(first.motions[""].q[-1], GOAL, atol=1e-9)
    assert "problem 1 of 0..3" in first.summary and "2 of 4 solved" in first.summary
    back = _draw(params, result, problem=2)
    np.testing.assert_allclose(back.motions[""].q[0], GOAL, atol=1e-9)
    np.testing.assert_allclose(back.motions[""].q[-1], START, atol=1e-9)
    np.testing.assert_allclose(back.motions[""].t, result["problems"][2]["trajectory"]["t"])
    # An unsolved problem: the arm waits at its start, the goal asked for is marked.
    stuck = _draw(params, result, problem=0)
    assert stuck.duration == 0.0 and not stuck.polylines
    np.testing.assert_allclose(stuck.motions[""].q, [MIDDLE])
    np.testing.assert_allclose(_balls(stuck, "goal"), [fk(model, np.array(GOAL))[:3, 3]])
    assert "start in collision" in stuck.summary and "`ball`" in stuck.summary
    # A goal pose out of reach: the ball marks the pose asked for.
    far = _draw(params, result, problem=3)
    np.testing.assert_allclose(far.motions[""].q, [START])
    np.testing.assert_allclose(_balls(far, "goal"), [np.array(FAR)[:3, 3]])
    assert "goal unreachable" in far.summary
    with pytest.raises(FieldError) as info:
        _draw(params, result, problem=4)
    assert info.value.loc == ("problem",) and "0 to 3" in info.value.message


def test_a_single_problem_is_problem_zero(one):
    params, result = one
    assert _draw(params, result, problem=0).motions[""].duration > 0
    with pytest.raises(FieldError, match="planned one problem"):
        _draw(params, result, problem=1)


def _changed(data: dict, path: str, value) -> dict:
    """A deep copy of ``data`` with the item at dotted ``path`` set (``...`` deletes it)."""
    out = json.loads(json.dumps(data))
    *keys, last = [int(k) if k.isdigit() else k for k in path.split(".")]
    node = out
    for k in keys:
        node = node[k]
    if value is ...:
        del node[last]
    else:
        node[last] = value
    return out


@pytest.mark.parametrize("where, path, value, words", [
    ("result", "joints.0", "swing", "result.joints: the result's joints"),
    ("result", "path.1", [0.0] * 5, "result.path: expected 6 joint values"),
    ("result", "trajectory.t.1", -1.0, "result.trajectory.t: expected"),
    ("result", "trajectory.q.3", [0.0] * 7, "result.trajectory.q: expected 6"),
    ("result", "status", "fine", "result.status:"),
    ("result", "goal", [0.0, 1.0], "result.goal: expected 6"),
    ("params", "robot", "nope", "params.robot: unknown robot 'nope'"),
    ("params", "scene.objects.0.radius", -5.0, "params.scene"),
])
def test_a_motion_result_that_does_not_fit_is_rejected_naming_the_key(one, where, path,
                                                                     value, words):
    params, result = one
    if where == "result":
        result = _changed(result, path, value)
    else:
        params = _changed(params, path, value)
    with pytest.raises(ValueError) as info:
        _draw(params, result)
    assert words in str(info.value)


def test_a_batch_result_of_another_length_is_rejected(batch):
    params, result = batch
    result = _changed(result, "problems.2", ...)
    with pytest.raises(ValueError, match="result.problems: expected 4 results"):
        _draw(params, result)


# ---- the viewer -----------------------------------------------------------------------------
def test_the_viewer_shows_a_motion_job_and_plays_it(api, one):
    params, result = one
    api.state.store.add_job("mj", "motion", params, {})
    api.state.store.finish_job("mj", "succeeded", result_json=json.dumps(result))
    v: Viewer = api.state.viewer
    v.select("pile_driver")
    shown = v.show_job("mj")
    assert (shown["robot"], shown["job"], shown["kind"]) == (ROBOT, "mj", "motion")
    root = "/plan/motion"
    assert {f"{root}/tool_path", f"{root}/waypoints/0", f"{root}/start/0", f"{root}/goal/0",
            f"{root}/scene/ball"} <= set(shown["nodes"])
    ball = v._plan_handles[f"{root}/scene/ball"]
    np.testing.assert_allclose(ball.position, _ball_center() * MM_TO_M, atol=1e-9)
    model = builtin_model(ROBOT)
    trajectory = result["trajectory"]
    step = v.gui.time.step                                       # a power of ten, and the
    assert not v.gui.time.disabled and math.log10(step) == round(math.log10(step))
    assert trajectory["duration"] <= v.gui.time.max < trajectory["duration"] + step  # end
    np.testing.assert_allclose(v.q(), START, atol=1e-9)
    for t in (0.37 * trajectory["duration"], trajectory["duration"]):
        v.set_time(t)
        q = _at(t, trajectory["t"], trajectory["q"])
        np.testing.assert_allclose(v.q(), q, atol=1e-9)
        np.testing.assert_allclose(v.tool_position(), fk(model, q)[:3, 3], atol=1e-6)
    np.testing.assert_allclose(v.tool_position(), fk(model, np.array(GOAL))[:3, 3], atol=1e-6)
    # Play runs from the start again (it was at the end), moving the arm.
    v.set_time(0.0)
    assert v.toggle_play()
    _wait(lambda: v.gui.time.value > 0.0 and not np.allclose(v.q(), START))
    assert not v.toggle_play()
    # The scene goes with the plan.
    v.select("pile_driver")
    assert not v.plan_nodes


def test_the_route_shows_one_problem_of_a_batch(api, batch):
    params, result = batch
    api.state.store.add_job("mb", "motion", params, {})
    api.state.store.finish_job("mb", "succeeded", result_json=json.dumps(result))
    client = TestClient(api)
    r = client.post("/viewer/show", json={"job": "mb", "problem": 2})
    assert r.status_code == 200, r.text
    np.testing.assert_allclose(api.state.viewer.q(), GOAL, atol=1e-9)  # problem 2's start
    r = client.post("/viewer/show", json={"job": "mb", "problem": 4})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "problem"]
    r = client.post("/viewer/show", json={"problem": 0})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "problem"]
    r = client.post("/viewer/show", json={"job": "mb", "problem": -1})
    assert r.status_code == 422


@pytest.mark.slow
def test_an_imported_robot_moves_its_meshes_along_a_motion_answer(api, glt_meshed_zip):
    """The answer of a motion request (``plan_motion`` on the imported robot's model, capsule
    collision model, in the route's answer form) shown with ``{"motion": answer}``: the
    mesh-carrying link frames follow the imported robot's own link poses."""
    from kinematics.urdf_import import import_robot, mesh_to_bytes
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion import MotionChecker, plan_motion

    robot = import_robot(glt_meshed_zip, "glt.zip", robot_id=IMPORTED)
    api.state.registry.add_imported(robot, {k: mesh_to_bytes(m)
                                            for k, m in robot.meshes.items()})
    model = robot.model
    scene = CollisionScene.from_request({"objects": [_ball()]})
    checker = MotionChecker(RobotCollisionModel.from_model(model), scene)
    planned = plan_motion(checker, np.array(START), np.array(GOAL), model=model,
                          time_limit=2.0)
    assert planned.success, planned.message
    names = [j.name for j in model.joints]
    answer = {**motion_answer(planned, names), "robot": IMPORTED, "joints": names}
    client = TestClient(api)
    r = client.post("/viewer/show", json={"motion": answer})
    assert r.status_code == 200, r.text
    shown = r.json()["shown"]
    assert shown["robot"] == IMPORTED and "/plan/motion/tool_path" in shown["nodes"]
    v: Viewer = api.state.viewer
    nodes = v._arms[""].nodes
    assert set(nodes.link_nodes) == {"base_link", "link_1", "link_2", "link_3", "link_4",
                                     "link_6"}
    trajectory = answer["trajectory"]
    for t in (0.0, 0.5 * trajectory["duration"], trajectory["duration"]):
        v.set_time(t)
        q = _at(t, trajectory["t"], trajectory["q"])
        for link, node in nodes.link_nodes.items():
            T = robot.link_pose(link, q)
            np.testing.assert_allclose(nodes.handles[node].position, T[:3, 3] * MM_TO_M,
                                       atol=1e-9)
    # Answers the viewer cannot follow, named.
    r = client.post("/viewer/show", json={"motion": {**answer, "joints": names[::-1]}})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "motion"]
    r = client.post("/viewer/show", json={"motion": {**answer, "robot": "nope"}})
    assert r.status_code == 404
    assert r.json()["detail"][0]["loc"] == ["body", "motion", "robot"]
    r = client.post("/viewer/show", json={"motion": answer, "robot": ROBOT})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "motion"]
    with pytest.raises(ValueError, match="motion.path: expected 6"):
        plan_from_motion({**answer, "path": [[0.0] * 5]}, models=api.state.registry.get)


# ---- in a browser -------------------------------------------------------------------------
NODE_POSITION = """(name) => {
    const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
    return p ? Array.from(p.position) : null; }"""


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """The API with its job and compute workers, and the viewer on a free port."""
    with served_viewer(tmp_path_factory.mktemp("data")) as served:
        yield served


@pytest.fixture(scope="module")
def page(service):
    sync_api = pytest.importorskip(
        "playwright.sync_api", reason="Playwright is in the 'test' extra: pip install -e "
        "'.[test]'")
    api, _ = service
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 640, "height": 400})
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(f"http://127.0.0.1:{api.state.viewer.port}")
        page.bring_to_front()  # viser's client connects only while its page has the focus
        page.get_by_text("Connected").wait_for()
        page.wait_for_function("() => window.__viserSceneTree !== undefined")
        yield page
        browser.close()


def _wait_job(client: TestClient, job_id: str, timeout: float = 120.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in ("succeeded", "failed", "cancelled"):
            assert job["status"] == "succeeded", job
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not finish")


def _wait_nodes(page, names: list[str]) -> None:
    page.wait_for_function("(names) => names.every(n => n in window.__viserSceneTree"
                           ".getState())", arg=names)


def _wait_position(page, name: str, want_m: np.ndarray) -> None:
    page.wait_for_function(
        """([name, want]) => {
            const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
            return p && p.position.every((v, i) => Math.abs(v - want[i]) < 1e-6); }""",
        arg=[name, [float(v) for v in want_m]])


def _scene_pixels(page, path) -> np.ndarray:
    """A screenshot (saved at ``path``) as grey levels, the part left of the GUI panel."""
    from PIL import Image

    page.wait_for_function(
        "() => { const c = document.querySelector('canvas');"
        " return c && getComputedStyle(c).opacity === '1'; }")
    time.sleep(0.5)  # let the frame render
    png = page.screenshot(path=str(path))
    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    return pixels[:, : int(pixels.shape[1] * 0.6)]


@pytest.mark.browser
def test_a_motion_job_plays_in_the_browser(service, page, tmp_path):
    api, client = service
    viewer: Viewer = api.state.viewer
    model = builtin_model(ROBOT)
    r = client.post("/scenes", json={"id": "cell", "objects": [_ball()]})
    assert r.status_code == 201, r.text
    job = client.post("/jobs", json={"kind": "motion", "params": {
        "robot": ROBOT, "scene": "cell", "start": START, "goal": {"q": GOAL},
        "time_limit": 2.0}})
    assert job.status_code == 202, job.text
    job_id = job.json()["id"]
    _wait_job(client, job_id)
    result = client.get(f"/jobs/{job_id}/result").json()
    assert result["status"] == "ok"
    r = client.post("/viewer/show", json={"job": job_id})
    assert r.status_code == 200, r.text
    robot = f"/robot/{ROBOT}"
    wanted = ["/plan/motion/tool_path", "/plan/motion/scene/ball", "/plan/motion/start/0",
              "/plan/motion/goal/0", f"{robot}/tool",
              *[f"{robot}/link_{i}" for i in range(model.dof)]]
    assert set(wanted) - {f"{robot}/tool", *[f"{robot}/link_{i}" for i in range(model.dof)]} \
        <= set(r.json()["shown"]["nodes"])
    _wait_nodes(page, wanted)
    # Two times on the slider: the arm is where the trajectory says, and the picture changes.
    trajectory = result["trajectory"]
    shots = []
    for k, t in enumerate((0.0, trajectory["duration"])):
        viewer.set_time(t)
        q = _at(t, trajectory["t"], trajectory["q"])
        _wait_position(page, f"{robot}/tool", fk(model, q)[:3, 3] * MM_TO_M)
        shots.append(_scene_pixels(page, tmp_path / f"viewer_motion_{k}.png"))
    for shot in shots:  # not blank
        assert shot.std() > 8.0 and len(np.unique(shot)) > 50
    changed = np.abs(shots[0] - shots[1]) > 24
    assert changed.mean() > 0.005, changed.mean()
    # The Play button in the page runs the motion.
    page.get_by_role("button", name="Play").click()
    _wait(lambda: viewer.gui.time.value > 0.0)
    start_tool = fk(model, np.array(START))[:3, 3] * MM_TO_M
    page.wait_for_function(
        """([name, start]) => {
            const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
            return p && p.position.some((v, i) => Math.abs(v - start[i]) > 1e-3); }""",
        arg=[f"{robot}/tool", [float(v) for v in start_tool]])
    viewer.set_time(0.0)  # pauses


@pytest.mark.browser
def test_a_motion_answer_of_an_imported_robot_plays_in_the_browser(service, page, tmp_path,
                                                                  glt_meshed_zip):
    """``POST /robots/{id}/motion`` for a robot imported with meshes, shown with its stored
    scene: the meshes ride on link frames placed by the imported robot's link poses."""
    api, client = service
    viewer: Viewer = api.state.viewer
    r = client.post("/robots/import", files={"file": ("glt.zip", glt_meshed_zip,
                                                      "application/zip")},
                    data={"id": IMPORTED})
    assert r.status_code == 201, r.text
    if "cell" not in client.get("/scenes").text:
        assert client.post("/scenes", json={"id": "cell", "objects": [_ball()]}
                           ).status_code == 201
    # The bones overlap at the joints: the robot is checked against the scene only.
    r = client.post(f"/robots/{IMPORTED}/motion", json={
        "start": START, "goal": {"q": GOAL}, "scene": "cell", "self_collision": False})
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["status"] == "ok", answer["message"]
    r = client.post("/viewer/show", json={"motion": answer, "scene": "cell"})
    assert r.status_code == 200, r.text
    assert r.json()["shown"]["scene_nodes"] == ["/scene/cell/ball"]
    root = f"/robot/{IMPORTED}"
    meshes = [f"{root}/links/{link}/visual_0"
              for link in ("base_link", "link_1", "link_2", "link_3", "link_4", "link_6")]
    _wait_nodes(page, [*meshes, "/plan/motion/tool_path", "/scene/cell/ball"])
    imported = api.state.registry.imported(IMPORTED)
    trajectory = answer["trajectory"]
    t = 0.5 * trajectory["duration"]
    viewer.set_time(t)
    q = _at(t, trajectory["t"], trajectory["q"])
    for link in ("link_2", "link_4"):
        _wait_position(page, f"{root}/links/{link}", imported.link_pose(link, q)[:3, 3]
                       * MM_TO_M)
    shot = _scene_pixels(page, tmp_path / "viewer_motion_imported.png")
    assert shot.std() > 8.0 and len(np.unique(shot)) > 50


def test_set_goal_then_plan_submits_a_motion_job_and_plays_its_answer(api):
    """The Plan folder: the arm's configuration kept as the goal, then Plan from where the arm
    is now, in the scene shown: a motion job with those values; once it succeeds its answer
    is drawn and plays. Refusals say why in the panel."""
    v: Viewer = api.state.viewer
    api.state.scenes.add("cell", {"objects": [_ball()]})
    v.select(ROBOT)
    assert v.plan_to_goal() is None and "Set goal here" in v.gui.motion.content
    assert v.gui.run_plan.disabled
    v.set_q(np.array(GOAL))
    np.testing.assert_allclose(v.set_goal(), GOAL)
    assert not v.gui.run_plan.disabled
    v.set_q(np.array(START))
    v.show_scene("cell")
    job_id = v.plan_to_goal()
    assert job_id is not None
    job = api.state.jobs.get(job_id)
    assert job.kind == "motion"
    np.testing.assert_allclose(job.params["start"], START)
    np.testing.assert_allclose(job.params["goal"]["q"], GOAL)
    assert job.params["robot"] == ROBOT
    assert [o["id"] for o in job.params["scene"]["objects"]] == ["ball"]  # filled in
    # One plan from the viewer at a time.
    assert v.plan_to_goal() is None and job_id in v.gui.motion.content
    # Run it as a worker would, then let the viewer find it finished.
    params, result = _run({k: job.params[k] for k in ("robot", "scene", "start", "goal",
                                                       "time_limit")})
    assert result["status"] == "ok"
    api.state.store.finish_job(job_id, "succeeded", result_json=json.dumps(result))
    v._poll_motion()
    assert "playing" in v.gui.motion.content
    assert "/plan/motion/tool_path" in v.plan_nodes
    _wait(lambda: v.gui.time.value > 0.0)
    # Another robot: the goal is dropped.
    v.select("pile_driver")
    assert v.gui.run_plan.disabled and v.plan_to_goal() is None


def test_a_failed_plan_from_the_viewer_says_why(api):
    v: Viewer = api.state.viewer
    v.select(ROBOT)
    v.set_goal()
    job_id = v.plan_to_goal()
    api.state.store.finish_job(job_id, "failed", error="the planner stopped")
    v._poll_motion()
    assert "Not planned" in v.gui.motion.content and "the planner stopped" in v.gui.motion.content
    assert v.plan_nodes == []


def test_a_task_answer_plays_as_one_motion(api):
    """An answer of a task (``steps``), whose status may be a segment's (here ``collision``:
    the line down meets a tray), is shown as any motion answer: the arm moves along its path."""
    client = TestClient(api)
    tray = {"type": "box", "id": "tray", "size": [300, 300, 40],
            "pose": [[1, 0, 0, 1306], [0, 1, 0, -404], [0, 0, 1, 1100], [0, 0, 0, 1]]}
    start = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
    answer = client.post("/robots/glt_palletizer/motion", json={
        "start": start, "scene": {"objects": [tray]}, "steps": [
            {"type": "move", "goal": {"q": [0.3, 0.3, -0.3, 0.0, 0.5, 0.0]}},
            {"type": "line", "target": [1306.1, -404.0, 1087.6], "orientation": "hold"}]}).json()
    assert answer["status"] == "collision" and "steps" in answer, answer
    r = client.post("/viewer/show", json={"motion": answer})
    assert r.status_code == 200, r.text
    np.testing.assert_allclose(api.state.viewer.q(), start, atol=1e-9)
