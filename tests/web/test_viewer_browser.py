"""The viewer in a real browser: headless Chromium (Debian's, not Playwright's download)
driven by Playwright, against the API and the viser server in one process.

The browser's view of the scene is read from viser's test hooks: ``window.__viserSceneTree``
(node names and props) and ``window.__viserMutable.nodePoseData`` (node poses). The
environment map is off, so the canvas shows as soon as the scene arrives.
"""

from __future__ import annotations

import io
import math
import time

import numpy as np
import pytest
from chromium_setup import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS, served_viewer
from fastapi.testclient import TestClient

from app.jobs.catalog import KINDS
from kinematics.fk import fk
from web.gui import REVOLUTE_STEP_DEG
from web.scene import MM_TO_M
from web.viewer import Viewer

sync_api = pytest.importorskip("playwright.sync_api",
                               reason="Playwright is in the 'test' extra: pip install -e '.[test]'")

pytestmark = pytest.mark.browser

ROBOT = "/robot/pile_driver"
STEPS = 2  # arrow-key presses on the slider

NODE_NAMES = "() => Object.keys(window.__viserSceneTree.getState())"
NODE_POSITION = """(name) => {
    const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
    return p ? Array.from(p.position) : null; }"""
POINT_COUNT = """(name) => {
    const n = window.__viserSceneTree.getState()[name];
    return n ? n.message.props.points.length / 3 : -1; }"""


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """The API (job pool started) with the viewer on a free port."""
    with served_viewer(tmp_path_factory.mktemp("data")) as served:
        yield served


@pytest.fixture(scope="module")
def browser(service):
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def _open(browser, viewer: Viewer):
    page = browser.new_page(viewport={"width": 640, "height": 400})
    page.set_default_timeout(TIMEOUT_MS)
    page.goto(f"http://127.0.0.1:{viewer.port}")
    # viser's client retries a websocket connection only while its page has the focus.
    page.bring_to_front()
    page.get_by_text("Connected").wait_for()
    page.wait_for_function("() => window.__viserSceneTree !== undefined")
    return page


def _wait_job(client: TestClient, job_id: str, timeout: float = 60.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in ("succeeded", "failed", "cancelled"):
            assert job["status"] == "succeeded", job
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not finish")


def _wait_position(page, name: str, want_m: np.ndarray) -> None:
    page.wait_for_function(
        """([name, want]) => {
            const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
            return p && p.position.every((v, i) => Math.abs(v - want[i]) < 1e-6); }""",
        arg=[name, [float(v) for v in want_m]])


def test_viewer_in_a_browser(service, browser, tmp_path):
    api, client = service
    viewer: Viewer = api.state.viewer
    model = api.state.registry.get("pile_driver")
    page = _open(browser, viewer)

    # The robot's nodes, named along the chain, with its hydraulic cylinders.
    page.wait_for_function(f"() => '{ROBOT}/tool' in window.__viserSceneTree.getState()")
    names = set(page.evaluate(NODE_NAMES))
    for i in range(model.dof):
        assert {f"{ROBOT}/link_{i}", f"{ROBOT}/joint_{i}"} <= names
    assert {f"{ROBOT}/base", f"{ROBOT}/cylinders/boom/barrel",
            f"{ROBOT}/cylinders/boom/rod"} <= names
    tool_before = np.array(page.evaluate(NODE_POSITION, f"{ROBOT}/tool"))
    np.testing.assert_allclose(tool_before, viewer.tool_position() * MM_TO_M, atol=1e-6)

    # Arrow keys on the first joint slider (swing, 0.5 deg a step) turn the arm.
    slider = page.get_by_role("slider").first
    slider.focus()
    for _ in range(STEPS):
        slider.press("ArrowRight")
    q = model.mid_configuration().copy()
    q[0] += math.radians(STEPS * REVOLUTE_STEP_DEG)
    deadline = time.monotonic() + 10
    while not np.allclose(viewer.q(), q, atol=1e-9) and time.monotonic() < deadline:
        time.sleep(0.05)
    np.testing.assert_allclose(viewer.q(), q, atol=1e-9)
    tool_after = fk(model, q)[:3, 3] * MM_TO_M
    assert np.linalg.norm(tool_after - tool_before) > 0.02  # 1 deg at ~1.7 m reach
    _wait_position(page, f"{ROBOT}/tool", tool_after)

    # A second tab watches the same scene, as it is now.
    other = _open(browser, viewer)
    _wait_position(other, f"{ROBOT}/tool", tool_after)

    # The workspace button: a job, its progress, then the cloud.
    viewer.gui.samples.value = 2500
    page.get_by_role("button", name="Run workspace").click()
    page.wait_for_function(f"() => ({POINT_COUNT})('/plan/workspace/points') === 2500",
                           timeout=60_000)
    assert "Workspace" in viewer.gui.workspace.content

    # A finished job shown through the API replaces it.
    job = client.post("/jobs", json={"kind": "workspace",
                                     "params": {"robot": "pile_driver", "samples": 1200}})
    _wait_job(client, job.json()["id"])
    r = client.post("/viewer/show", json={"job": job.json()["id"]})
    assert r.status_code == 200, r.text
    assert "/plan/workspace/points" in r.json()["shown"]["nodes"]
    page.wait_for_function(f"() => ({POINT_COUNT})('/plan/workspace/points') === 1200")
    other.wait_for_function(f"() => ({POINT_COUNT})('/plan/workspace/points') === 1200")

    # The picture is not blank: the canvas is shown and the pixels vary.
    page.wait_for_function(
        "() => { const c = document.querySelector('canvas');"
        " return c && getComputedStyle(c).opacity === '1'; }")
    png = page.screenshot(path=str(tmp_path / "viewer.png"))
    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    scene_part = pixels[:, : pixels.shape[1] // 2]  # left of the GUI panel
    assert scene_part.std() > 8.0, scene_part.std()
    assert len(np.unique(scene_part)) > 50
    other.close()
    page.close()


def test_a_path_job_in_the_browser(service, browser):
    assert "path" in KINDS
    api, client = service
    viewer: Viewer = api.state.viewer
    model = api.state.registry.get("pile_driver")
    # Tool positions the arm reaches, with a ball between them.
    start = fk(model, np.radians([10, 30, -30, -30, 0, 0]))[:3, 3]
    goal = fk(model, np.radians([60, 35, -25, -30, 0, 0]))[:3, 3]
    params = {"scene": {"bounds": [[-2500, -2500, -1000], [2500, 2500, 2000]],
                        "obstacles": [{"center": ((start + goal) / 2).tolist(), "radius": 100}]},
              "start": start.tolist(), "goal": goal.tolist(), "algorithm": "auto", "seed": 0,
              "robot": "pile_driver"}
    job = client.post("/jobs", json={"kind": "path", "params": params})
    assert job.status_code == 202, job.text
    _wait_job(client, job.json()["id"], timeout=120)
    r = client.post("/viewer/show", json={"job": job.json()["id"]})
    assert r.status_code == 200, r.text
    page = _open(browser, viewer)
    page.wait_for_function(
        "() => '/plan/path/path' in window.__viserSceneTree.getState()"
        " && '/plan/path/obstacles/0' in window.__viserSceneTree.getState()")
    result = client.get(f"/jobs/{job.json()['id']}/result").json()
    if result.get("trajectory"):  # the arm moves along it: at the end, its tool is at the goal
        assert not viewer.gui.time.disabled
        viewer.set_time(viewer.gui.time.max)
        _wait_position(page, f"{ROBOT}/tool", viewer.tool_position() * MM_TO_M)
        np.testing.assert_allclose(viewer.tool_position(), goal, atol=1.0)
    page.close()


def test_plan_pressed_in_the_browser_plans_and_plays(service, browser):
    """Set goal here, move the arm back, Plan: a motion job runs in the pool and its plan's
    nodes appear in the browser, the arm moving along it."""
    api, client = service
    viewer: Viewer = api.state.viewer
    goal = np.array([1.0, 0.3, -0.3, 0.0, 0.5, 0.0])
    start = np.array([-1.0, 0.3, -0.3, 0.0, 0.5, 0.0])
    viewer.select("glt_palletizer", goal)
    page = _open(browser, viewer)
    page.get_by_role("button", name="Set goal here").click()
    page.wait_for_function("() => !document.evaluate(\"//button[normalize-space()='Plan']\","
                           " document, null, 9, null).singleNodeValue.disabled")
    viewer.set_q(start)
    page.get_by_role("button", name="Plan", exact=True).click()
    page.wait_for_function("() => '/plan/motion/tool_path' in window.__viserSceneTree"
                           ".getState()", timeout=60_000)
    assert "playing" in viewer.gui.motion.content
    # The arm plays along the plan: its tool leaves the start in the browser.
    at_start = fk(api.state.registry.get("glt_palletizer"), start)[:3, 3] * MM_TO_M
    page.wait_for_function(
        """([position, start]) => { const p = eval(position)('/robot/glt_palletizer/tool');
            return p !== null && Math.hypot(...p.map((v, i) => v - start[i])) > 0.01; }""",
        arg=[NODE_POSITION, [float(v) for v in at_start]])
    page.close()


def test_a_keyed_viewer_in_a_browser(service, browser, tmp_path_factory):
    """With an API key: a browser without it gets the 401 page; ``/?key=`` sets the cookie,
    drops the key from the address, and the page connects and draws the robot."""
    api, _ = service
    key = "browser-test-key"
    viewer = Viewer.start("127.0.0.1", 0, api.state, environment_map=False, api_key=key)
    context = browser.new_context(viewport={"width": 640, "height": 400})
    try:
        page = context.new_page()
        page.set_default_timeout(TIMEOUT_MS)
        answer = page.goto(f"http://127.0.0.1:{viewer.port}/")
        assert answer.status == 401
        assert "?key=" in page.content()
        answer = page.goto(f"http://127.0.0.1:{viewer.port}/?key={key}")
        assert answer.status == 200
        assert page.url == f"http://127.0.0.1:{viewer.port}/"
        cookies = context.cookies()
        assert len(cookies) == 1 and cookies[0]["httpOnly"] and key not in cookies[0]["value"]
        page.bring_to_front()
        page.get_by_text("Connected").wait_for()
        page.wait_for_function(f"() => '{ROBOT}/tool' in window.__viserSceneTree.getState()")
        tool = np.array(page.evaluate(NODE_POSITION, f"{ROBOT}/tool"))
        np.testing.assert_allclose(tool, viewer.tool_position() * MM_TO_M, atol=1e-6)
    finally:
        context.close()
        viewer.stop()


def test_an_imported_robot_and_a_scene_in_the_browser(service, browser, tmp_path,
                                                      glt_meshed_zip):
    """A URDF robot with meshes (POST /robots/import) and a stored scene with a box, an
    uploaded mesh and a point cloud, shown through the API; the collision checkbox adds the
    balls."""
    trimesh = pytest.importorskip("trimesh")
    api, client = service
    viewer: Viewer = api.state.viewer
    r = client.post("/robots/import", files={"file": ("glt.zip", glt_meshed_zip,
                                                      "application/zip")},
                    data={"id": "glt_meshed"})
    assert r.status_code == 201, r.text
    crate = trimesh.creation.box(extents=(500.0, 400.0, 300.0)).export(file_type="stl")
    r = client.post("/meshes", files={"file": ("crate.stl", crate, "model/stl")},
                    data={"id": "crate"})
    assert r.status_code == 201, r.text
    rng = np.random.default_rng(20260412)
    wall = np.column_stack([rng.uniform(-800, 800, 3000), np.full(3000, -1400.0),
                            rng.uniform(0, 1600, 3000)])
    eye = np.eye(4)

    def at(x, y, z):
        T = eye.copy()
        T[:3, 3] = (x, y, z)
        return T.tolist()

    r = client.post("/scenes", json={"id": "cell", "objects": [
        {"type": "box", "id": "pallet", "size": [1200, 800, 150], "pose": at(1300, 0, 75)},
        {"type": "mesh", "id": "crate", "mesh": "crate", "pose": at(1300, 0, 300)},
        {"type": "points", "id": "wall", "points": wall.tolist(), "radius": 10},
    ]})
    assert r.status_code == 201, r.text
    r = client.post("/viewer/show", json={"robot": "glt_meshed", "scene": "cell"})
    assert r.status_code == 200, r.text
    scene_nodes = r.json()["shown"]["scene_nodes"]
    assert scene_nodes == ["/scene/cell/pallet", "/scene/cell/crate", "/scene/cell/wall"]

    page = _open(browser, viewer)
    root = "/robot/glt_meshed"
    meshes = [f"{root}/links/{link}/visual_0"
              for link in ("base_link", "link_1", "link_2", "link_3", "link_4", "link_6")]
    wanted = [*meshes, *scene_nodes]
    page.wait_for_function("(names) => names.every(n => n in window.__viserSceneTree"
                           ".getState())", arg=wanted)
    assert page.evaluate(f"() => ({POINT_COUNT})('/scene/cell/wall')") == 3000
    # The meshes ride on their link frames, where the kinematics puts them.
    q = viewer.q()
    imported = api.state.registry.imported("glt_meshed")
    _wait_position(page, f"{root}/links/link_3",
                   imported.link_pose("link_3", q)[:3, 3] * MM_TO_M)
    # The collision checkbox (the collision model is built on first use: seconds).
    page.get_by_label("Collision model").check()
    page.wait_for_function(f"() => '{root}/collision' in window.__viserSceneTree.getState()",
                           timeout=120_000)
    assert viewer.collision_nodes == [f"{root}/collision"]
    page.wait_for_function(
        "() => { const c = document.querySelector('canvas');"
        " return c && getComputedStyle(c).opacity === '1'; }")
    time.sleep(1.0)  # let the meshes render
    png = page.screenshot(path=str(tmp_path / "viewer_import.png"))
    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("L"), dtype=float)
    scene_part = pixels[:, : pixels.shape[1] // 2]
    assert scene_part.std() > 8.0, scene_part.std()
    assert len(np.unique(scene_part)) > 50
    page.get_by_label("Collision model").uncheck()
    page.wait_for_function(
        f"() => !('{root}/collision' in window.__viserSceneTree.getState())")
    # Clearing the scene removes its nodes from the browser.
    assert client.post("/viewer/show", json={"scene": None}).status_code == 200
    page.wait_for_function("() => !('/scene/cell' in window.__viserSceneTree.getState())")
    page.close()
