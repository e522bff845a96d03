"""The viewer without a browser: scene geometry, nodes, GUI state, jobs and the route.

A real viser server (port 0) takes the nodes; nothing renders. Poses are checked against the
kinematics library (fk, CylinderSet), plans against results of real library calls where the
job kind exists or the library can produce the documented shape.
"""

from __future__ import annotations

import json
import math
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from fastapi.testclient import TestClient

from kinematics.cylinders import FourBarCylinder, cylinder_set
from kinematics.fk import fk, fk_frames
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import RobotModel
from web.gui import from_display, to_display
from web.results import (
    DEFAULT_SECONDS,
    DRAWERS,
    Plan,
    Spheres,
    drawable,
    drawer,
    plan_from_result,
)
from web.scene import (
    MM_TO_M,
    RobotNodes,
    cylinder_drawings,
    height_colors,
    segment_pose,
)
from web.text import plain
from web.viewer import JobNotReady

RNG_SEED = 20240611


# ---- fixtures -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def server():
    import viser

    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()



def _wait(predicate, timeout: float = 30.0, step: float = 0.05):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(step)
    raise AssertionError("condition not met in time")


def _quat_to_matrix(wxyz) -> np.ndarray:
    import viser.transforms as vtf

    return vtf.SO3(wxyz=np.asarray(wxyz, dtype=float)).as_matrix()


def _pose_in(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Point ``p (3,)`` expressed in the frame ``T (4, 4)``."""
    return T[:3, :3].T @ (p - T[:3, 3])


# ---- geometry -----------------------------------------------------------------------------
@pytest.mark.parametrize("direction", [
    (0, 0, 1), (0, 0, -1), (1, 0, 0), (0, -1, 0), (1, 2, 3), (-0.3, 0.2, -5.0), (1e-9, 0, -1),
])
def test_segment_pose_puts_the_cylinder_axis_on_the_segment(direction):
    p0 = np.array([0.1, -0.2, 0.3])
    p1 = p0 + np.asarray(direction, dtype=float)
    position, wxyz, length = segment_pose(p0, p1)
    R = _quat_to_matrix(wxyz)
    np.testing.assert_allclose(R @ [0, 0, 1], (p1 - p0) / np.linalg.norm(p1 - p0), atol=1e-12)
    np.testing.assert_allclose(position, 0.5 * (p0 + p1))
    assert length == pytest.approx(np.linalg.norm(p1 - p0))
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_drawn_cylinders_are_exactly_as_long_as_the_library_says():
    model = builtin_model("pile_driver")
    cs = cylinder_set(model)
    rng = np.random.default_rng(RNG_SEED)
    for q in rng.uniform(model.lower, model.upper, size=(25, model.dof)):
        lengths = cs.lengths(q)
        drawn = {c.name: c for c in cylinder_drawings(model, q)}
        assert set(drawn) == set(cs.names)
        for name, c in drawn.items():
            assert np.linalg.norm(c.rod_pin - c.barrel_pin) == pytest.approx(lengths[name],
                                                                             abs=1e-9)
            assert c.stroke == pytest.approx(lengths[name] - c.min_length)
            assert c.within_stroke
        four_bar = next(m for m in cs.mechanisms if isinstance(m, FourBarCylinder))
        bars = drawn[four_bar.name].bars
        for bar, want in (("rocker", four_bar.l_mn), ("coupler", four_bar.l_km),
                          ("crank", four_bar.l_kh)):
            assert np.linalg.norm(bars[bar][1] - bars[bar][0]) == pytest.approx(want, abs=1e-9)


def test_cylinder_pins_ride_on_their_links():
    """Moving any joint leaves the barrel pin fixed in the carrying link (frame before the
    driven joint) and the rod pin fixed in the driven link (frame after it); for the four-bar,
    the rocker pivot N rides on the stick and the link pin K on the driven link."""
    model = builtin_model("pile_driver")
    cs = cylinder_set(model)
    rng = np.random.default_rng(RNG_SEED + 1)
    q0 = model.mid_configuration()
    base = {c.name: c for c in cylinder_drawings(model, q0)}
    F0 = fk_frames(model, q0)
    for q in rng.uniform(model.lower, model.upper, size=(10, model.dof)):
        F = fk_frames(model, q)
        for c in cylinder_drawings(model, q):
            j = cs.joint_of(c.name)
            b0 = base[c.name]
            np.testing.assert_allclose(_pose_in(F[j], c.barrel_pin),
                                       _pose_in(F0[j], b0.barrel_pin), atol=1e-9)
            if c.bars:  # four-bar: the rod pin M rides on the rocker; K on the driven link
                np.testing.assert_allclose(_pose_in(F[j + 1], c.bars["crank"][1]),
                                           _pose_in(F0[j + 1], b0.bars["crank"][1]), atol=1e-9)
                np.testing.assert_allclose(_pose_in(F[j], c.bars["rocker"][0]),
                                           _pose_in(F0[j], b0.bars["rocker"][0]), atol=1e-9)
            else:
                np.testing.assert_allclose(_pose_in(F[j + 1], c.rod_pin),
                                           _pose_in(F0[j + 1], b0.rod_pin), atol=1e-9)


def test_robots_without_cylinder_data_draw_none():
    for robot in ("glt_palletizer", "hyper_redundant_9dof", "tunnel_drill_arm"):
        model = builtin_model(robot)
        assert cylinder_drawings(model, model.mid_configuration()) == ()


def test_height_colours_rise_with_height():
    z = np.linspace(-1.0, 2.0, 50)
    rgb = height_colors(z).astype(int)
    assert rgb.shape == (50, 3) and rgb.dtype == int
    brightness = rgb.sum(axis=1)
    assert brightness[-1] > brightness[0]  # viridis: dark purple (low) to yellow (high)
    assert height_colors(np.zeros(3)).shape == (3, 3)


def test_display_units_round_trip():
    model = builtin_model("tunnel_drill_arm")  # revolute and prismatic joints
    q = model.mid_configuration()
    shown = to_display(model, q)
    assert shown[0] == pytest.approx(math.degrees(q[0]))
    assert shown[2] == pytest.approx(q[2])  # telescope, mm
    np.testing.assert_allclose(from_display(model, shown), q)


# ---- nodes --------------------------------------------------------------------------------
@pytest.mark.parametrize("robot", BUILTIN_IDS)
def test_robot_nodes_follow_the_chain_and_move_with_q(server, robot):
    model = builtin_model(robot)
    root = f"/robot/{robot}"
    q0 = model.mid_configuration()
    nodes = RobotNodes(server.scene, root, model, q0)
    try:
        names = set(nodes.names)
        for i in range(model.dof):
            assert {f"{root}/link_{i}", f"{root}/joint_{i}"} <= names
        assert {f"{root}/base", f"{root}/tool"} <= names
        frames = fk_frames(model, q0)
        tool = nodes.handles[nodes.tool]
        np.testing.assert_allclose(tool.position, frames[-1][:3, 3] * MM_TO_M, atol=1e-9)
        np.testing.assert_allclose(_quat_to_matrix(tool.wxyz), frames[-1][:3, :3], atol=1e-9)
        for i in range(model.dof):
            link = nodes.handles[nodes.link(i)]
            mid = 0.5 * (frames[i][:3, 3] + frames[i + 1][:3, 3]) * MM_TO_M
            np.testing.assert_allclose(link.position, mid, atol=1e-9)
        rng = np.random.default_rng(RNG_SEED)
        q1 = rng.uniform(model.lower, model.upper)
        nodes.update(q1)
        np.testing.assert_allclose(tool.position, fk(model, q1)[:3, 3] * MM_TO_M, atol=1e-9)
        frames1 = fk_frames(model, q1)
        for i in range(model.dof):
            link = nodes.handles[nodes.link(i)]
            length = np.linalg.norm(frames1[i + 1][:3, 3] - frames1[i][:3, 3]) * MM_TO_M
            if link.visible:
                assert link.height == pytest.approx(length, abs=1e-9)
            else:
                assert length < 1e-6
        has_cylinders = "cylinders" in model.extras
        assert any("/cylinders/" in n for n in names) == has_cylinders
    finally:
        nodes.remove()
    assert nodes.handles == {}


def test_pile_driver_cylinders_are_barrel_and_rod_pairs(server):
    model = builtin_model("pile_driver")
    nodes = RobotNodes(server.scene, "/robot/pile_driver", model, model.mid_configuration())
    try:
        for name in cylinder_set(model).names:
            base = f"/robot/pile_driver/cylinders/{name}"
            barrel, rod = nodes.handles[f"{base}/barrel"], nodes.handles[f"{base}/rod"]
            assert barrel.radius > rod.radius
            c = next(c for c in nodes.drawing.cylinders if c.name == name)
            # The barrel starts at its pin, the rod ends at its pin.
            R = _quat_to_matrix(barrel.wxyz)
            start = np.asarray(barrel.position) - 0.5 * barrel.height * (R @ [0, 0, 1])
            np.testing.assert_allclose(start, c.barrel_pin * MM_TO_M, atol=1e-9)
            R = _quat_to_matrix(rod.wxyz)
            end = np.asarray(rod.position) + 0.5 * rod.height * (R @ [0, 0, 1])
            np.testing.assert_allclose(end, c.rod_pin * MM_TO_M, atol=1e-9)
    finally:
        nodes.remove()


# ---- the viewer ---------------------------------------------------------------------------
def test_viewer_offers_every_robot_and_rig_and_refreshes(api):
    v = api.state.viewer
    options = set(v.gui.robot.options)
    assert set(BUILTIN_IDS) <= options and "tunnel_jumbo" in options
    assert v.current["robot"] == "pile_driver"
    custom = builtin_model("glt_palletizer").to_dict() | {"id": "my_glt", "name": "mine"}
    api.state.registry.add(RobotModel.from_dict(custom))
    v.refresh_robots()
    assert "my_glt" in v.gui.robot.options
    shown = v.select("my_glt")
    assert shown["robot"] == "my_glt" and len(shown["q"]) == 6
    api.state.registry.remove("my_glt")
    v.refresh_robots()  # the robot shown is gone: back to the first
    assert "my_glt" not in v.gui.robot.options and v.current["robot"] == "pile_driver"


def test_the_rig_is_drawn_as_three_arms(api):
    v = api.state.viewer
    v.select("tunnel_jumbo")
    roots = v.arm_roots
    assert roots == {arm: f"/robot/tunnel_jumbo/{arm}" for arm in ("left", "middle", "right")}
    assert v.gui.arm.visible and set(v.gui.arm.options) == set(roots)
    rig = api.state.registry.rigs["tunnel_jumbo"]
    for arm, model in rig.arms.items():
        np.testing.assert_allclose(v.tool_position(arm), fk(model, model.mid_configuration())
                                   [:3, 3])
    # The arms are 2 m apart along y: their base discs are too.
    ys = sorted(v.tool_position(a)[1] for a in roots)
    np.testing.assert_allclose(np.diff(ys), [2000.0, 2000.0], atol=1e-6)
    # Framed face-on: the camera looks along the tunnel (+x, towards the face the booms
    # drill), not across it as it does at a single arm.
    look = np.asarray(v.server.initial_camera.look_at) - v.server.initial_camera.position
    look /= np.linalg.norm(look)
    assert look[0] > 0.8 and abs(look[1]) < 0.4
    v.select("glt_palletizer")
    look = np.asarray(v.server.initial_camera.look_at) - v.server.initial_camera.position
    assert abs(look[1]) / np.linalg.norm(look) > 0.7
    # The ground lies under everything drawn, at z = 0 or lower.
    assert v._grid.position[2] == 0.0
    v.show_plan(Plan("low", "sequence", spheres=(Spheres("holes", np.array([[9000.0, 0, -1300]]),
                                                         np.full(1, 50.0), (250, 200, 30)),)))
    assert v._grid.position[2] == pytest.approx(-1.35)
    # The IK gizmo is a tenth of the arm's reach, translucent: the tool shows under it.
    # (The palletizer reaches 1.9 m: README's workspace.)
    assert 0.1 <= v.gizmo.scale <= 0.3 and v.gizmo.opacity < 1.0


def test_a_browser_slider_moves_the_arm_and_shows_cylinders(api):
    v = api.state.viewer
    model = builtin_model("pile_driver")
    before = v.tool_position().copy()
    slider = v.gui.sliders[0]
    assert slider.label.startswith("1 swing")
    slider.value = slider.value + 10.0  # as the browser would set it ...
    v._on_slider(0, SimpleNamespace(client=object()))  # ... and then call back
    q = model.mid_configuration().copy()
    q[0] += math.radians(10.0)
    np.testing.assert_allclose(v.q(), q, atol=1e-12)
    np.testing.assert_allclose(v.tool_position(), fk(model, q)[:3, 3], atol=1e-9)
    assert not np.allclose(v.tool_position(), before)
    table = v.gui.cylinders.content
    lengths = cylinder_set(model).lengths(q)
    assert f"| boom | boom | {lengths['boom']:.1f} |" in table
    assert v.gui.cylinders_folder.visible
    v.select("glt_palletizer")
    assert not v.gui.cylinders_folder.visible


def test_ik_drag_follows_reachable_targets_and_keeps_the_last_good_pose(api):
    v = api.state.viewer
    model = builtin_model("pile_driver")
    q_target = model.mid_configuration() + 0.05
    result = v.drag_tool_to(fk(model, q_target))
    assert result.success
    np.testing.assert_allclose(v.tool_position(), fk(model, q_target)[:3, 3], atol=1e-6)
    good = v.q()
    far = fk(model, q_target)
    far[:3, 3] *= 10.0
    result = v.drag_tool_to(far)
    assert not result.success
    np.testing.assert_array_equal(v.q(), good)
    # The message as the panel's Markdown shows text (web.text).
    assert "Cannot reach" in v.gui.ik.content and plain(result.message) in v.gui.ik.content
    # The gizmo's own path: a drag event is solved on the IK thread.
    T = fk(model, model.mid_configuration() - 0.05)
    import viser.transforms as vtf

    target = SimpleNamespace(position=T[:3, 3] * MM_TO_M,
                             wxyz=vtf.SO3.from_matrix(T[:3, :3]).wxyz)
    v._on_gizmo(SimpleNamespace(target=target, phase="end", client=None))
    _wait(lambda: np.allclose(v.tool_position(), T[:3, 3], atol=1e-6))
    _wait(lambda: np.allclose(v.gizmo.position, T[:3, 3] * MM_TO_M, atol=1e-9))


@pytest.mark.slow
def test_concurrent_updates_from_many_threads_leave_a_consistent_scene(api):
    v = api.state.viewer
    model = builtin_model("pile_driver")
    rng = np.random.default_rng(RNG_SEED)
    qs = rng.uniform(model.lower, model.upper, size=(4, 40, model.dof))
    errors: list[BaseException] = []

    def drive(rows):
        try:
            for q in rows:
                v.set_q(q)
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=drive, args=(rows,)) for rows in qs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    q = v.q()
    assert any(np.array_equal(q, rows[-1]) for rows in qs)
    np.testing.assert_allclose(v.tool_position(), fk(model, q)[:3, 3], atol=1e-9)
    np.testing.assert_allclose(v.gui.slider_q(model), q, atol=1e-9)


@pytest.mark.slow
def test_workspace_button_runs_a_job_and_shows_the_cloud(api):
    v = api.state.viewer
    with TestClient(api):  # the lifespan starts the job pool
        job_id = v.run_workspace(1500)
        assert job_id is not None
        _wait(lambda: "/plan/workspace/points" in v.plan_nodes, timeout=60)
        result = json.loads(api.state.jobs.result(job_id))
    cloud = v._plan_handles["/plan/workspace/points"]
    points = np.asarray(result["points"])
    assert cloud.points.shape == (1500, 3)
    np.testing.assert_allclose(cloud.points, points * MM_TO_M, rtol=1e-6)
    top = int(np.argmax(points[:, 2]))
    bottom = int(np.argmin(points[:, 2]))
    assert int(cloud.colors[top].sum()) > int(cloud.colors[bottom].sum())
    text = v.gui.workspace.content
    assert job_id in text and f"{result['max'][2]:,.0f} mm" in text
    assert not v.gui.progress.visible


# ---- plans of other kinds -----------------------------------------------------------------
def _line_path_result(model: RobotModel):
    """A ``path`` result in the documented shape, from real library calls: a straight tool line
    mapped through IK (planning.trajectories.cartesian) past a sphere, clearance by
    planning.paths.scene. Not the output of a path planner (none is registered here)."""
    from planning.paths.scene import Scene
    from planning.trajectories.cartesian import follow_path, line_points

    q0 = model.mid_configuration()
    T0 = fk(model, q0)
    start = T0[:3, 3]
    goal = start + np.array([0.0, 300.0, -150.0])
    points = line_points(start, goal, 12)
    plan = follow_path(model, points, T0[:3, :3], duration=4.0, q0=q0)
    scene = {"bounds": [(start - 1000).tolist(), (start + 1000).tolist()],
             "obstacles": [{"center": (start + [300.0, 150.0, 0.0]).tolist(), "radius": 100.0}]}
    clearance = Scene.from_dict(scene).path_clearance(points)
    length = float(np.linalg.norm(goal - start))
    result = {"path": points.tolist(), "joint_path": plan.q_waypoints.tolist(),
              "length": length, "min_clearance": clearance, "runtime_s": 0.0,
              "convergence": [], "algorithm": "auto", "evaluations": 0, "success": True,
              "status": "ok", "message": "a straight line", "raw_length": length,
              "trajectory": None, "cylinders": None, "robot": model.id}
    params = {"scene": scene, "start": start.tolist(), "goal": goal.tolist(),
              "algorithm": "auto", "seed": 0, "robot": model.id}
    return params, result


def test_a_path_plan_draws_obstacles_the_line_and_moves_the_arm(api):
    v = api.state.viewer
    model = builtin_model("glt_palletizer")
    params, result = _line_path_result(model)
    plan = plan_from_result("path", params, result, job="line", models=api.state.registry.get)
    shown = v.show_plan(plan)
    assert shown["robot"] == "glt_palletizer" and shown["kind"] == "path"
    nodes = set(v.plan_nodes)
    assert {"/plan/path/path", "/plan/path/obstacles/0", "/plan/path/bounds",
            "/plan/path/start/0", "/plan/path/goal/0"} <= nodes
    assert plan.duration == DEFAULT_SECONDS
    assert not v.gui.time.disabled
    assert v.gui.time.max == pytest.approx(DEFAULT_SECONDS, abs=v.gui.time.step)
    v.set_time(DEFAULT_SECONDS)
    np.testing.assert_allclose(v.tool_position(), result["path"][-1], atol=1e-4)
    v.set_time(0.0)
    np.testing.assert_allclose(v.tool_position(), result["path"][0], atol=1e-4)
    v.gui.speed.value = 10.0
    assert v.toggle_play()
    _wait(lambda: not v._playing, timeout=DEFAULT_SECONDS / 10.0 + 5)
    np.testing.assert_allclose(v.tool_position(), result["path"][-1], atol=1e-4)


# ---- the route ------------------------------------------------------------------------------
def test_viewer_show_route_maps_errors(api):
    with TestClient(api) as client:
        r = client.post("/viewer/show", json={"robot": "glt_palletizer", "q": [0.1] * 6})
        assert r.status_code == 200 and r.json()["shown"]["robot"] == "glt_palletizer"
        assert r.json()["shown"]["q"] == [0.1] * 6
        r = client.post("/viewer/show", json={"robot": "tunnel_jumbo"})
        assert r.status_code == 200 and set(r.json()["shown"]["q"]) == {"left", "middle",
                                                                          "right"}
        assert client.post("/viewer/show", json={"robot": "nope"}).status_code == 404
        r = client.post("/viewer/show", json={"robot": "pile_driver", "q": [0.0]})
        assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "q"]
        r = client.post("/viewer/show", json={"job": "0123456789abcdef"})
        assert r.status_code == 404 and r.json()["detail"][0]["loc"] == ["body", "job"]
        echo = client.post("/jobs", json={"kind": "echo", "params": {"value": 1}}).json()
        assert client.post("/viewer/show", json={"job": echo["id"]}).status_code == 422
        assert client.post("/viewer/show", json={"robot": "pile_driver",
                                                 "job": echo["id"]}).status_code == 422
        # A tracking result stored before the desired path was kept: 422 naming the key.
        store = api.state.store
        store.add_job("oldtracking", "tracking", {"task": {"kind": "line"}}, {})
        store.finish_job("oldtracking", "succeeded", result_json=json.dumps({
            "robot": "hyper_redundant_9dof", "t": [0.0, 0.1], "q": [[0.0] * 9] * 2}))
        r = client.post("/viewer/show", json={"job": "oldtracking"})
        assert r.status_code == 422, r.text
        assert "result.task: Field required" in r.json()["detail"][0]["msg"]


def test_viewer_show_route_is_409_until_the_job_succeeds(api):
    client = TestClient(api)  # no lifespan: the job pool is not started, jobs stay queued
    job = client.post("/jobs", json={"kind": "workspace",
                                     "params": {"robot": "pile_driver", "samples": 100}}).json()
    r = client.post("/viewer/show", json={"job": job["id"]})
    assert r.status_code == 409 and "queued" in r.json()["detail"][0]["msg"]
    with pytest.raises(JobNotReady):
        api.state.viewer.show_job(job["id"])


# ---- results of real jobs of every drawable kind -----------------------------------------
SIDES = {"left": [[9000, 2600, 300], [9000, 3400, 1500]],
         "middle": [[9000, 0, 2400], [9000, 1000, 4300]],
         "right": [[9000, -2600, 500], [9000, -3500, 2000]]}
HOLES = [[9000, 0, 0], [9000, 1200, 300], [9000, -800, 900], [9000, 400, 2000]]


def _drawable_params(kind: str) -> dict:
    """Small params of a real job of each drawable kind."""
    if kind == "workspace":
        return {"robot": "pile_driver", "samples": 400, "return_points": 50}
    if kind == "path":
        model = builtin_model("pile_driver")
        start = fk(model, np.radians([10, 30, -30, -30, 0, 0]))[:3, 3]
        goal = fk(model, np.radians([60, 35, -25, -30, 0, 0]))[:3, 3]
        return {"scene": {"bounds": [[-2500, -2500, -1000], [2500, 2500, 2000]],
                          "obstacles": [{"center": ((start + goal) / 2).tolist(),
                                         "radius": 100},
                                        {"type": "box", "lower": [-2000, -2000, -900],
                                         "upper": [-1800, -1800, -700]}]},
                "start": start.tolist(), "goal": goal.tolist(), "algorithm": "auto",
                "seed": 0, "robot": "pile_driver"}
    if kind == "sequence":
        return {"holes": HOLES, "start": [9000, 0, -1000]}
    if kind == "multiarm":
        return {"holes": SIDES, "output_dt": 1.0}
    if kind == "motion":  # drawn in detail by test_viewer_motion
        return {"robot": "glt_palletizer", "start": [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0],
                "goal": {"q": [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]}, "time_limit": 2.0}
    return {"robot": "hyper_redundant_9dof",
            "task": {"kind": "line", "length": 100.0, "duration": 5.0}}


def _run_kind(kind: str, params: dict) -> tuple[dict, dict]:
    """The stored params and result JSON of a job run in this process as a worker runs it."""
    from app.jobs.catalog import KINDS
    from app.jobs.kinds import JobPayload, execute

    spec = KINDS[kind]
    checked = spec.load_params(params)
    robot = spec.robot_id(checked)
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(robot).to_dict() if robot else None)
    text = execute(kind, payload.model_dump(mode="json"), lambda fraction, message: None)
    return checked.model_dump(mode="json"), json.loads(text)


@pytest.fixture(scope="module")
def real_jobs() -> dict[str, tuple[dict, dict]]:
    # The work cycles (round, pallet, piles) are drawn by test_viewer_cycles.
    return {kind: _run_kind(kind, _drawable_params(kind)) for kind in DRAWERS
            if kind not in ("round", "pallet", "piles")}


def test_the_drawable_kinds_are_the_kinds_with_a_drawer():
    from app.jobs.catalog import KINDS

    assert set(DRAWERS) == {"workspace", "path", "sequence", "multiarm", "tracking",
                            "motion", "round", "pallet", "piles"}
    assert set(DRAWERS) <= set(KINDS)
    assert drawable("path") and not drawable("echo")
    with pytest.raises(ValueError, match="'nope' is not a job kind"):
        drawer("nope")(lambda params, result, ctx: None)
    with pytest.raises(ValueError, match="'path' has a drawer already"):
        drawer("path")(lambda params, result, ctx: None)
    assert DRAWERS["path"].__name__ == "_path"
    with pytest.raises(ValueError, match="kind 'echo'"):
        plan_from_result("echo", {}, {"value": 1}, models=builtin_model)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["workspace", "path", "sequence", "multiarm", "tracking"])
def test_every_drawable_kind_is_drawn_from_its_typed_result(api, real_jobs, kind):
    from app.jobs.catalog import KINDS

    v = api.state.viewer
    registry = api.state.registry
    params, result = real_jobs[kind]
    plan = plan_from_result(kind, params, result, job="j", models=registry.get,
                            rigs=registry.rigs)
    spec = KINDS[kind]  # the models themselves draw the same
    typed = plan_from_result(kind, spec.load_params(params), spec.load_result(result),
                             job="j", models=registry.get, rigs=registry.rigs)
    assert typed.names == plan.names and typed.summary == plan.summary
    v.select("glt_palletizer")
    shown = v.show_plan(plan)
    nodes = set(v.plan_nodes)
    root = f"/plan/{kind}"
    if kind == "workspace":
        assert shown["robot"] == "pile_driver" and f"{root}/points" in nodes
        np.testing.assert_allclose(plan.clouds[0].points, result["points"])
    elif kind == "path":
        assert {f"{root}/path", f"{root}/obstacles/0", f"{root}/bounds", f"{root}/start/0",
                f"{root}/goal/0", f"{root}/obstacle_box_1"} <= nodes
        assert result["trajectory"] is not None
        assert plan.duration == pytest.approx(result["trajectory"]["t"][-1])
        v.set_time(plan.duration)  # the arm moves along the trajectory, to the goal
        np.testing.assert_allclose(v.tool_position(), params["goal"], atol=1.0)
    elif kind == "sequence":
        (line,) = plan.polylines
        expected = np.vstack([params["start"], np.array(HOLES)[result["order"]]])
        np.testing.assert_allclose(line.points, expected)
        assert {f"{root}/holes/3", f"{root}/order"} <= nodes and not plan.motions
        assert shown["robot"] == "glt_palletizer"  # a sequence names no robot: kept
    elif kind == "multiarm":
        assert shown["robot"] == "tunnel_jumbo" and set(plan.motions) == set(SIDES)
        for arm, data in result["arms"].items():
            assert {f"{root}/{arm}/holes/0", f"{root}/{arm}/order",
                    f"{root}/{arm}/tool_path"} <= nodes
            order = next(p for p in plan.polylines if p.name == f"{arm}/order")
            np.testing.assert_allclose(order.points, data["holes"])  # in drilling order
            motion = plan.motions[arm]
            np.testing.assert_allclose(motion.t, result["t"])
            np.testing.assert_allclose(motion.q, data["q"])
        v.set_time(result["t"][1])
        model = registry.rigs["tunnel_jumbo"].arms["left"]
        np.testing.assert_allclose(v.tool_position("left"),
                                   fk(model, np.array(result["arms"]["left"]["q"][1]))[:3, 3],
                                   atol=1e-6)
    else:
        desired, actual = plan.polylines
        assert (desired.name, actual.name) == ("desired", "actual")
        np.testing.assert_allclose(desired.points, result["x_desired"])
        model = builtin_model("hyper_redundant_9dof")
        np.testing.assert_allclose(actual.points, fk(model, np.asarray(result["q"]))[:, :3, 3])
        np.testing.assert_allclose(actual.points, result["x_actual"], atol=1e-9)
        assert plan.motions[""].duration == pytest.approx(result["t"][-1] - result["t"][0])
        assert {f"{root}/actual", f"{root}/desired"} <= nodes


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


@pytest.mark.slow
@pytest.mark.parametrize("kind, where, path, value, words", [
    ("workspace", "result", "points.0", [1, 2], "result.points.0: List should have at least 3"),
    ("workspace", "result", "volume", "big", "result.volume:"),
    ("path", "result", "trajectory", ..., "result.trajectory: Field required"),
    ("path", "result", "orders", [0], "result.orders: Extra inputs are not permitted"),
    ("path", "params", "start", [1e9, 0, 0], "params.start"),
    ("sequence", "result", "order", [7, 0, 1, 2], "result.order: hole indices must lie in 0..3"),
    ("sequence", "params", "robot", "pile_driver", "params.robot: Extra inputs"),
    ("multiarm", "result", "arms.left.order", [0, 1], "result.arms.left.order: Extra inputs"),
    ("multiarm", "result", "arms.left.q.0", [0.0] * 5, "result.arms.left.q: expected 7"),
    ("multiarm", "result", "t.0", 5.0, "result.t: expected"),
    ("tracking", "result", "x_desired", ..., "result.x_desired: Field required"),
    ("tracking", "result", "dt", 0.1, "result.dt: Extra inputs"),
    ("tracking", "result", "q.0", [0.0] * 6, "result.q: expected 9 joint values"),
    ("tracking", "params", "robot", "nope", "params.robot: unknown robot 'nope'"),
])
def test_a_result_of_the_wrong_shape_is_rejected_naming_the_key(api, real_jobs, kind, where,
                                                                path, value, words):
    params, result = real_jobs[kind]
    if where == "result":
        result = _changed(result, path, value)
    else:
        params = _changed(params, path, value)
    with pytest.raises(ValueError) as info:
        plan_from_result(kind, params, result, models=api.state.registry.get,
                         rigs=api.state.registry.rigs)
    assert words in str(info.value)


def test_a_result_that_is_not_an_object_is_rejected():
    with pytest.raises(ValueError, match="^result: expected a JSON object"):
        plan_from_result("sequence", {"holes": HOLES}, [0, 1, 2, 3], models=builtin_model)


def test_a_stored_job_is_shown_by_its_id(api, real_jobs):
    params, result = real_jobs["sequence"]
    store = api.state.store
    store.add_job("seq", "sequence", params, {})
    store.finish_job("seq", "succeeded", result_json=json.dumps(result))
    shown = api.state.viewer.show_job("seq")
    assert "/plan/sequence/order" in shown["nodes"]


def test_a_workspace_job_survives_a_store_outage(api, monkeypatch):
    from app.store import StoreError

    v = api.state.viewer
    job_id = v.run_workspace(1500)  # queued: no lifespan, no pool
    assert job_id is not None

    def down(_job_id):
        raise StoreError(api.state.store.path, "database disk image is malformed")

    with monkeypatch.context() as m:
        m.setattr(api.state.jobs, "get", down)
        for _ in range(5):
            v._poll_workspace()
        assert "unavailable" in v.gui.workspace.content
        assert "malformed" in v.gui.workspace.content
    assert v._workspace_job == job_id  # still followed once the store is back
    v._poll_workspace()
    assert "queued" in v.gui.workspace.content
