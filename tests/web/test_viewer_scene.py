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

from app.config import Settings
from app.main import create_app
from kinematics.cylinders import FourBarCylinder, cylinder_set
from kinematics.fk import fk, fk_frames
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import RobotModel
from web.gui import from_display, to_display
from web.results import DEFAULT_SECONDS, plan_from_result
from web.scene import (
    MM_TO_M,
    RobotNodes,
    cylinder_drawings,
    height_colors,
    segment_pose,
)
from web.viewer import JobNotReady, Viewer

RNG_SEED = 20240611


# ---- fixtures -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def server():
    import viser

    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


@pytest.fixture
def api(tmp_path):
    """An application without processes started (jobs stay queued) and a viewer on port 0."""
    app = create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))
    app.state.viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
    yield app
    app.state.viewer.stop()


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
    assert "Cannot reach" in v.gui.ik.content and result.message in v.gui.ik.content
    # The gizmo's own path: a drag event is solved on the IK thread.
    T = fk(model, model.mid_configuration() - 0.05)
    import viser.transforms as vtf

    target = SimpleNamespace(position=T[:3, 3] * MM_TO_M,
                             wxyz=vtf.SO3.from_matrix(T[:3, :3]).wxyz)
    v._on_gizmo(SimpleNamespace(target=target, phase="end", client=None))
    _wait(lambda: np.allclose(v.tool_position(), T[:3, 3], atol=1e-6))
    _wait(lambda: np.allclose(v.gizmo.position, T[:3, 3] * MM_TO_M, atol=1e-9))


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
    mapped through IK (planning.cartesian) past a sphere, clearance by planning.scene. Not
    the output of a path planner (none is registered here)."""
    from planning.cartesian import follow_path, line_points
    from planning.scene import Scene

    q0 = model.mid_configuration()
    T0 = fk(model, q0)
    start = T0[:3, 3]
    goal = start + np.array([0.0, 300.0, -150.0])
    points = line_points(start, goal, 12)
    plan = follow_path(model, points, T0[:3, :3], duration=4.0, q0=q0)
    scene = {"bounds": [(start - 1000).tolist(), (start + 1000).tolist()],
             "obstacles": [{"center": (start + [300.0, 150.0, 0.0]).tolist(), "radius": 100.0}]}
    clearance = Scene.from_dict(scene).path_clearance(points)
    result = {"path": points.tolist(), "joint_path": plan.q_waypoints.tolist(),
              "length": float(np.linalg.norm(goal - start)), "min_clearance": clearance,
              "runtime_s": 0.0, "convergence": []}
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
    assert not v.gui.time.disabled and v.gui.time.max == pytest.approx(DEFAULT_SECONDS)
    v.set_time(DEFAULT_SECONDS)
    np.testing.assert_allclose(v.tool_position(), result["path"][-1], atol=1e-4)
    v.set_time(0.0)
    np.testing.assert_allclose(v.tool_position(), result["path"][0], atol=1e-4)
    v.gui.speed.value = 10.0
    assert v.toggle_play()
    _wait(lambda: not v._playing, timeout=DEFAULT_SECONDS / 10.0 + 5)
    np.testing.assert_allclose(v.tool_position(), result["path"][-1], atol=1e-4)


def test_a_tracking_plan_draws_desired_and_actual_paths():
    tracking = pytest.importorskip("planning.tracking")
    model = builtin_model("hyper_redundant_9dof")
    task = tracking.LineTask(length=100.0, duration=4.0)
    run = tracking.simulate(model, task, tracking.PIGains((2.0, 2.0), 0.5),
                            controller="default")
    result = {"q": run.q[0].tolist(), "errors": run.error[0].tolist(),
              "x_desired": run.x_desired.tolist(), "mean_error": float(run.mean_error[0]),
              "max_error": float(run.max_error[0])}
    plan = plan_from_result("tracking", {"robot": model.id}, result, job="t",
                            models=builtin_model)
    desired, actual = plan.polylines
    np.testing.assert_allclose(desired.points, run.x_desired)
    np.testing.assert_allclose(np.linalg.norm(actual.points - desired.points, axis=1),
                               run.error[0], atol=1e-6)
    assert plan.motions[""].duration == pytest.approx(run.t[-1])


def test_sequence_and_multiarm_plans_read_the_documented_shapes(api):
    """Rendering only: the holes are tool positions of real FK, but the orders and joint
    paths below are made up for the test (no sequencing or multi-arm planner exists yet)."""
    v = api.state.viewer
    rig = api.state.registry.rigs["tunnel_jumbo"]
    rng = np.random.default_rng(RNG_SEED)
    holes, trajectories = {}, {}
    for arm, model in rig.arms.items():
        qs = rng.uniform(model.lower, model.upper, size=(4, model.dof))
        holes[arm] = fk(model, qs)[:, :3, 3].tolist()
        trajectories[arm] = {"q": qs.tolist(), "t": [0.0, 1.0, 2.0, 3.0], "order": [0, 1, 2, 3]}
    plan = plan_from_result("multiarm", {"rig": "tunnel_jumbo", "holes": holes,
                                         "planner": "iapf"},
                            {"trajectories": trajectories, "min_distance": {"left-middle": [
                                900.0, 850.0]}, "collisions": []},
                            job="m", models=api.state.registry.get, rigs=api.state.registry.rigs)
    v.show_plan(plan)
    assert v.current["robot"] == "tunnel_jumbo"
    assert {"/plan/multiarm/left/holes/0", "/plan/multiarm/right/order",
            "/plan/multiarm/middle/tool_path"} <= set(v.plan_nodes)
    v.set_time(3.0)  # every arm ends at its last configuration: on its last hole
    for arm in rig.arms:
        np.testing.assert_allclose(v.tool_position(arm), holes[arm][3], atol=1e-6)

    drill = builtin_model("tunnel_drill_arm")
    pts = fk(drill, rng.uniform(drill.lower, drill.upper, size=(6, drill.dof)))[:, :3, 3]
    plan = plan_from_result("sequence", {"holes": pts.tolist(), "start": [0.0, 0.0, 0.0]},
                            {"order": [5, 4, 3, 2, 1, 0], "length": 1.0}, job="s",
                            models=builtin_model)
    (line,) = plan.polylines
    np.testing.assert_allclose(line.points, np.vstack([[0, 0, 0], pts[::-1]]))
    v.show_plan(plan)
    assert {"/plan/sequence/holes/5", "/plan/sequence/order"} <= set(v.plan_nodes)
    assert v.current["robot"] == "tunnel_jumbo"  # a sequence without robot keeps the scene
    with pytest.raises(ValueError, match="order"):
        plan_from_result("sequence", {"holes": pts.tolist()}, {"order": [7]},
                         models=builtin_model)


def test_results_without_the_documented_shape_are_rejected_by_key():
    with pytest.raises(ValueError, match="kind 'echo'"):
        plan_from_result("echo", {}, {"value": 1}, models=builtin_model)
    with pytest.raises(ValueError, match="^points"):
        plan_from_result("workspace", {"robot": "pile_driver"}, {"points": [[1, 2]]},
                         models=builtin_model)
    with pytest.raises(ValueError, match="joint_path"):
        plan_from_result("path", {"robot": "pile_driver"},
                         {"path": [[0, 0, 0], [1, 1, 1]], "joint_path": [[0.0] * 5]},
                         models=builtin_model)
    with pytest.raises(ValueError, match="params.robot"):
        plan_from_result("tracking", {"robot": "nope"}, {"q": [[0.0]]}, models=builtin_model)


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


def test_viewer_show_route_is_409_until_the_job_succeeds(api):
    client = TestClient(api)  # no lifespan: the job pool is not started, jobs stay queued
    job = client.post("/jobs", json={"kind": "workspace",
                                     "params": {"robot": "pile_driver", "samples": 100}}).json()
    r = client.post("/viewer/show", json={"job": job["id"]})
    assert r.status_code == 409 and "queued" in r.json()["detail"][0]["msg"]
    with pytest.raises(JobNotReady):
        api.state.viewer.show_job(job["id"])


# ---- results of the real job kinds, where this tree registers them -------------------------
def _run_kind(kind: str, params: dict) -> tuple[dict, dict]:
    from app.jobs.kinds import KINDS, load_kind_modules

    load_kind_modules()
    if kind not in KINDS:
        pytest.skip(f"the '{kind}' job kind is not registered in this tree yet")
    spec = KINDS[kind]
    clean = spec.params.model_validate(params).model_dump(mode="json")
    payload = dict(clean)
    if clean.get("robot"):
        payload["_model"] = builtin_model(clean["robot"]).to_dict()
    result = json.loads(json.dumps(spec.run(payload, lambda fraction, message: None)))
    return clean, result


def test_a_real_path_job_result_is_drawn_and_moves_the_arm(api):
    model = builtin_model("pile_driver")
    start = fk(model, np.radians([10, 30, -30, -30, 0, 0]))[:3, 3]
    goal = fk(model, np.radians([60, 35, -25, -30, 0, 0]))[:3, 3]
    params, result = _run_kind("path", {
        "scene": {"bounds": [[-2500, -2500, -1000], [2500, 2500, 2000]],
                  "obstacles": [{"center": ((start + goal) / 2).tolist(), "radius": 100}]},
        "start": start.tolist(), "goal": goal.tolist(), "algorithm": "auto", "seed": 0,
        "robot": "pile_driver"})
    plan = plan_from_result("path", params, result, job="p", models=builtin_model)
    v = api.state.viewer
    v.show_plan(plan)
    assert {"/plan/path/path", "/plan/path/obstacles/0"} <= set(v.plan_nodes)
    if result.get("trajectory"):
        v.set_time(plan.duration)
        np.testing.assert_allclose(v.tool_position(), goal, atol=1.0)


def test_a_real_tracking_job_result_is_drawn(api):
    params, result = _run_kind("tracking", {
        "robot": "hyper_redundant_9dof", "task": {"kind": "line", "length": 100.0,
                                                  "duration": 5.0}})
    plan = plan_from_result("tracking", params, result, job="t", models=builtin_model)
    names = [p.name for p in plan.polylines]
    assert names == ["desired", "actual"]  # the job's result carries the desired path
    actual = plan.polylines[names.index("actual")].points
    model = builtin_model("hyper_redundant_9dof")
    np.testing.assert_allclose(actual, fk(model, np.asarray(result["q"]))[:, :3, 3])
    np.testing.assert_allclose(plan.polylines[0].points, result["x_desired"])
    assert "desired" in plan.summary
    assert plan.motions[""].duration == pytest.approx(result["t"][-1] - result["t"][0])
    api.state.viewer.show_plan(plan)
    assert {"/plan/tracking/actual", "/plan/tracking/desired"} <= set(api.state.viewer.plan_nodes)


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
