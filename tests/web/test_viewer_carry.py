"""Task plans in the viewer: a carried load rides on its link between attach and detach, sits at
its pick pose before and where it was placed after; line and arc steps are drawn; the panel
says which step plays and what it holds.

The task is real (the ``motion`` job kind run in this process as a worker runs it, or by the
service's workers in the browser test): the GLT palletizer takes a 400 x 300 x 250 mm box off
a conveyor and puts it on a pallet. The references are the kinematics library's forward
kinematics at the result's own trajectory samples, interpolated here.
"""

from __future__ import annotations

import json
import shutil
import time
from types import SimpleNamespace

import numpy as np
import pytest
from chromium_setup import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS

from app.jobs.catalog import KINDS
from app.jobs.kinds import JobPayload, execute
from kinematics.fk import fk, fk_frames
from kinematics.library import builtin_model
from web.results import plan_from_result
from web.scene import MM_TO_M
from web.tasks import check_links, link_frame, state_times, task_track

pytestmark = pytest.mark.usefixtures("motion_kernels")

ROBOT = "glt_palletizer"
START = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]
#: The tool pointing straight down.
DOWN = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
PICK = np.array([1200.0, 600.0, 700.0])
PLACE = np.array([1200.0, -600.0, 700.0])
UP = np.array([0.0, 0.0, 200.0])
BOX = [400.0, 300.0, 250.0]
#: The box in the tool frame: its centre 195 mm along the tool's z (down), so its top is
#: 70 mm below the tool point, clear of the tool's collision capsule (radius 60 mm).
GRIP = np.eye(4)
GRIP[2, 3] = 195.0


def _pose(p: np.ndarray) -> list:
    T = np.eye(4)
    T[:3, :3] = DOWN
    T[:3, 3] = p
    return T.tolist()


def _at_xyz(x: float, y: float, z: float) -> list:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T.tolist()


def task_params() -> dict:
    """Above the conveyor, down 200 mm, take the box, up, over to the pallet, down, let go
    (placed), up."""
    steps = [
        {"type": "move", "goal": {"pose": _pose(PICK + UP)}},
        {"type": "line", "target": PICK.tolist(), "orientation": "hold"},
        {"type": "attach", "object": {"type": "box", "id": "carton", "size": BOX},
         "link": "tool", "pose": GRIP.tolist()},
        {"type": "line", "target": (PICK + UP).tolist(), "orientation": "hold"},
        {"type": "move", "goal": {"pose": _pose(PLACE + UP)}},
        {"type": "line", "target": PLACE.tolist(), "orientation": "hold"},
        {"type": "detach", "object": "carton"},
        {"type": "line", "target": (PLACE + UP).tolist(), "orientation": "hold"},
    ]
    # The box's bottom hangs 320 mm below the tool point: 10 mm above both tops at the pick.
    scene = {"objects": [
        {"type": "box", "id": "conveyor", "size": [600, 500, 370], "pose": _at_xyz(1200, 600, 185)},
        {"type": "box", "id": "pallet", "size": [1000, 800, 370], "pose": _at_xyz(1200, -600, 185)},
    ]}
    return {"robot": ROBOT, "start": START, "steps": steps, "scene": scene, "time_limit": 10.0}


@pytest.fixture(scope="module")
def job() -> tuple[dict, dict]:
    """The stored params and result JSON of the task run as a worker runs it."""
    spec = KINDS["motion"]
    checked = spec.load_params(task_params())
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(ROBOT).to_dict())
    text = execute("motion", payload.model_dump(mode="json"), lambda fraction, message: None)
    result = json.loads(text)
    assert result["status"] == "ok", result["message"]
    return checked.model_dump(mode="json"), result


@pytest.fixture
def shown(viewer, job):
    """The viewer showing the task."""
    params, result = job
    viewer.show_plan(plan_from_result("motion", params, result, job="t", models=builtin_model))
    return viewer


def _q_at(t: float, result: dict) -> np.ndarray:
    """The arm's configuration at ``t`` s: the result's trajectory samples, linear between."""
    tt = np.asarray(result["trajectory"]["t"], dtype=float)
    Q = np.asarray(result["trajectory"]["q"], dtype=float)
    return np.array([np.interp(t, tt, Q[:, j]) for j in range(Q.shape[1])])


def _step(result: dict, kind: str) -> dict:
    return next(s for s in result["steps"] if s["type"] == kind)


def _drawn(viewer, name: str) -> np.ndarray:
    """The world pose (mm) of load ``name`` as its nodes place it: the frame, then the shape
    in it."""
    import viser.transforms as vtf

    def pose(h) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = vtf.SO3(wxyz=np.asarray(h.wxyz, dtype=float)).as_matrix()
        T[:3, 3] = np.asarray(h.position, dtype=float) / MM_TO_M
        return T

    root = f"/plan/motion/loads/{name}"
    return pose(viewer._plan_handles[root]) @ pose(viewer._plan_handles[f"{root}/{name}"])


# ---- timing ----------------------------------------------------------------------------------
def test_state_times_follow_the_states_in_order_even_where_the_arm_comes_back():
    """Down a line and back up it: the states met again on the way up get the later times
    (a nearest-point match alone would give them the way down's)."""
    there = np.array([0.0, 0.1, 0.2, 0.3, 0.2, 0.1, 0.0])
    path = np.column_stack([there, 0.5 * there])
    times = np.arange(len(path), dtype=float)
    np.testing.assert_allclose(state_times(path, times, path, np.ones(2)), times, atol=1e-12)
    fine_t = np.linspace(0.0, 6.0, 25)      # the same motion sampled four times finer
    fine_q = np.column_stack([np.interp(fine_t, times, path[:, j]) for j in range(2)])
    np.testing.assert_allclose(state_times(path, fine_t, fine_q, np.ones(2)), times,
                               atol=1e-9)
    # A motion that pauses at the turn: the turn's state is met when the pause starts.
    paused_t = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 6.0, 7.0, 8.0])
    paused_q = np.vstack([path[:4], path[3:]])
    got = state_times(path, paused_t, paused_q, np.ones(2))
    np.testing.assert_allclose(got, [0.0, 1.0, 2.0, 3.0, 6.0, 7.0, 8.0], atol=1e-9)


# ---- the carried load ----------------------------------------------------------------------
def test_the_carried_box_rides_on_the_tool_between_attach_and_detach(shown, job):
    params, result = job
    viewer = shown
    model = builtin_model(ROBOT)
    (load,) = viewer._plan.task.loads
    assert load.id == "carton" and load.attach_time < load.detach_time
    assert load.detach_time < viewer._plan.duration
    for share in (0.05, 0.5, 0.95):
        t = load.attach_time + share * (load.detach_time - load.attach_time)
        viewer.set_time(t)
        q = _q_at(t, result)
        np.testing.assert_allclose(viewer.q(), q, atol=1e-12)
        want = fk(model, q) @ GRIP                  # the tool's pose times the offset
        np.testing.assert_allclose(fk_frames(model, q)[-1], fk(model, q), atol=1e-9)
        np.testing.assert_allclose(viewer.loads["carton"], want, atol=1e-6)
        np.testing.assert_allclose(_drawn(viewer, "carton"), want, atol=1e-6)
    # The box is as big as asked.
    shape = viewer._plan_handles["/plan/motion/loads/carton/carton"]
    np.testing.assert_allclose(np.asarray(shape.dimensions) / MM_TO_M, BOX, atol=1e-6)


def test_before_the_attach_it_waits_at_its_pick_pose_and_after_the_detach_where_placed(
        shown, job):
    params, result = job
    viewer = shown
    model = builtin_model(ROBOT)
    path = np.asarray(result["path"], dtype=float)
    picked = fk(model, path[_step(result, "attach")["states"][0]]) @ GRIP
    placed = fk(model, path[_step(result, "detach")["states"][0]]) @ GRIP
    # The pick pose: the box hangs below the tool at the conveyor, 10 mm above it.
    np.testing.assert_allclose(picked[:3, 3], PICK + [0.0, 0.0, -195.0], atol=0.5)
    (load,) = viewer._plan.task.loads
    for t in (0.0, 0.5 * load.attach_time, 0.99 * load.attach_time):
        viewer.set_time(t)
        np.testing.assert_allclose(viewer.loads["carton"], picked, atol=1e-6)
        np.testing.assert_allclose(_drawn(viewer, "carton"), picked, atol=1e-6)
    end = viewer._plan.duration
    for t in (load.detach_time + 0.01, 0.5 * (load.detach_time + end), end):
        viewer.set_time(t)
        np.testing.assert_allclose(viewer.loads["carton"], placed, atol=1e-6)
        np.testing.assert_allclose(_drawn(viewer, "carton"), placed, atol=1e-6)
        # The arm has gone up: the tool is no longer at the box.
    assert np.linalg.norm(fk(model, _q_at(end, result))[:3, 3] - placed[:3, 3]) > 300.0
    # Taken and let go where the arm is: no jump at either moment (the trajectory passes
    # within a few mm of the states where its corners are blended).
    for moment, at in ((load.attach_time, picked), (load.detach_time, placed)):
        ridden = fk(model, _q_at(moment + 1e-6, result)) @ GRIP
        assert np.linalg.norm(ridden[:3, 3] - at[:3, 3]) < 3.0


def test_lines_are_drawn_and_the_panel_says_what_plays(shown, job):
    params, result = job
    viewer = shown
    model = builtin_model(ROBOT)
    path = np.asarray(result["path"], dtype=float)
    plan = viewer._plan
    lines = [s for s in result["steps"] if s["type"] == "line"]
    names = {p.name: p for p in plan.polylines}
    for s in lines:
        first, last = s["states"]
        drawn = names[f"segments/{s['index']}"].points
        np.testing.assert_allclose(drawn, fk(model, path[first:last + 1])[:, :3, 3],
                                   atol=1e-9)
        assert np.linalg.norm(drawn[-1] - drawn[0]) == pytest.approx(200.0, abs=0.5)
        assert f"/plan/motion/segments/{s['index']}" in viewer.plan_nodes
    spans = {s.index: s for s in plan.task.spans}
    down = spans[1]
    viewer.set_time(0.5 * (down.start + down.end))
    text = viewer.gui.plan.content
    assert "**step 2 of 8**: line, 200 mm" in text
    assert "held: orientation (the step's start's, ±0.001 rad)" in text
    assert "carrying" not in text
    up = spans[3]
    viewer.set_time(0.5 * (up.start + up.end))
    text = viewer.gui.plan.content
    assert "**step 4 of 8**: line, 200 mm" in text
    assert "carrying: box 400 × 300 × 250 mm `carton` on `tool`" in text
    viewer.set_time(plan.duration)
    assert "carrying" not in viewer.gui.plan.content
    assert "1 load(s)" in plan.summary


def test_held_constraints_are_named_and_a_dropped_load_disappears():
    """What the panel says of a constrained move, and a load let go without ``place``: the
    steps as a result gives them (states into a path of four states)."""
    model = builtin_model(ROBOT)
    path = np.array([START, START, START, START], dtype=float)
    path[1:, 0] += [0.1, 0.2, 0.3]
    asked = [
        {"type": "attach", "object": {"type": "sphere", "id": "ball", "radius": 50.0}},
        {"type": "move", "goal": {"q": path[2].tolist()},
         "constraints": [{"type": "orientation", "rotation": np.eye(3).tolist(),
                          "tolerance": 0.1},
                         {"type": "axis", "direction": [0, 0, -1], "tolerance": 0.05},
                         {"type": "position_plane", "point": [0, 0, 0],
                          "normal": [0, 0, 1], "tolerance": 2.0}]},
        {"type": "detach", "object": "ball", "place": False},
        {"type": "move", "goal": {"q": path[3].tolist()}},
    ]
    done = [SimpleNamespace(index=0, type="attach", status="ok", states=[0, 0], planner="attach"),
            SimpleNamespace(index=1, type="move", status="ok", states=[0, 2],
                            planner="constrained"),
            SimpleNamespace(index=2, type="detach", status="ok", states=[2, 2],
                            planner="detach"),
            SimpleNamespace(index=3, type="move", status="collision", states=[2, 3],
                            planner="rrt_connect")]
    track = task_track(model, asked, done, path, np.array([0.0, 1.0, 2.0, 3.0]))
    assert track.spans[1].held == ("orientation ±0.1 rad; tool z axis ±0.05 rad of "
                                   "[0, 0, -1]; position ±2 mm of a plane")
    assert "held: orientation ±0.1 rad" in track.text_at(1.5)
    assert "**step 4 of 4**: move (rrt\\_connect): **collision**" in track.text_at(2.5)
    (ball,) = track.loads
    assert ball.attach_time == 0.0 and ball.detach_time == 2.0 and not ball.placed
    np.testing.assert_allclose(ball.configuration(1.0, path[1]), path[1])
    assert ball.configuration(2.5, path[2]) is None   # dropped from the task: gone


def test_a_link_the_robot_does_not_have_is_named():
    """A D-H robot's links are ``link0`` .. ``link5`` (the frame after each joint) and
    ``tool``; a load on another link is refused naming its attach step's ``link``."""
    model = builtin_model(ROBOT)
    q = np.array(START)
    frames = fk_frames(model, q)
    np.testing.assert_allclose(link_frame(model, None, "link2", q), frames[3])
    np.testing.assert_allclose(link_frame(model, None, "tool", q), frames[-1])
    asked = [{"type": "move", "goal": {"q": START}},
             {"type": "attach", "object": {"type": "sphere", "id": "ball", "radius": 5.0},
              "link": "link6"}]
    done = [SimpleNamespace(index=0, type="move", status="ok", states=[0, 1],
                            planner="rrt_connect"),
            SimpleNamespace(index=1, type="attach", status="ok", states=[1, 1],
                            planner="attach")]
    track = task_track(model, asked, done, np.array([START, START]), np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match=r"params\.steps\.1\.link: .*'link6'"):
        check_links(track.loads, lambda link, q: link_frame(model, None, link, q))


# ---- in a browser ------------------------------------------------------------------------
NODE_POSITION = """(name) => {
    const p = window.__viserMutable && window.__viserMutable.nodePoseData[name];
    return p ? Array.from(p.position) : null; }"""


@pytest.mark.slow
@pytest.mark.browser
def test_a_pick_and_place_task_plays_in_the_browser(tmp_path):
    """A task job run by the service's workers, shown with ``POST /viewer/show``: the box's
    nodes and the lines' appear in the browser, and mid-move the box's frame is at the tool
    where the kinematics puts it."""
    sync_api = pytest.importorskip("playwright.sync_api")
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app
    from web.viewer import Viewer

    if not shutil.which(CHROMIUM):
        pytest.fail(f"Chromium not found at {CHROMIUM}: run `make chromium`")
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))
    api.state.viewer = viewer = Viewer.start("127.0.0.1", 0, api.state,
                                             environment_map=False)
    try:
        with TestClient(api) as client, sync_api.sync_playwright() as p:
            r = client.post("/jobs", json={"kind": "motion", "params": task_params()})
            assert r.status_code == 202, r.text
            job_id = r.json()["id"]
            end = time.monotonic() + 120
            while client.get(f"/jobs/{job_id}").json()["status"] in ("queued", "running"):
                assert time.monotonic() < end, "the task job did not finish"
                time.sleep(0.2)
            result = client.get(f"/jobs/{job_id}/result").json()
            assert result["status"] == "ok", result["message"]
            r = client.post("/viewer/show", json={"job": job_id})
            assert r.status_code == 200, r.text
            nodes = r.json()["shown"]["nodes"]
            box = "/plan/motion/loads/carton"
            assert {box, f"{box}/carton", "/plan/motion/segments/1"} <= set(nodes)

            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 640, "height": 400})
            page.set_default_timeout(TIMEOUT_MS)
            page.goto(f"http://127.0.0.1:{viewer.port}")
            page.bring_to_front()
            page.get_by_text("Connected").wait_for()
            page.wait_for_function("(names) => names.every(n => n in "
                                   "window.__viserSceneTree.getState())",
                                   arg=[box, f"{box}/carton", "/plan/motion/segments/1",
                                        "/plan/motion/segments/5"])
            (load,) = viewer._plan.task.loads
            t = 0.5 * (load.attach_time + load.detach_time)
            viewer.set_time(t)
            tool = fk(builtin_model(ROBOT), _q_at(t, result))
            assert viewer.loads["carton"] == pytest.approx(tool @ GRIP, abs=1e-6)
            want = [float(v) for v in tool[:3, 3] * MM_TO_M]   # the frame: the tool's
            page.wait_for_function(
                """([position, name, want]) => { const p = eval(position)(name);
                    return p !== null && p.every((v, i) => Math.abs(v - want[i]) < 1e-6); }""",
                arg=[NODE_POSITION, box, want])
            assert "carrying: box 400 × 300 × 250 mm" in viewer.gui.plan.content
            browser.close()
    finally:
        viewer.stop()
