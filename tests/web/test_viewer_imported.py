"""The viewer's imported robots, collision balls, stored scenes and camera, without a browser.

A real viser server takes the nodes (nothing renders). The imported robot is the GLT
palletizer written as URDF with meshes (``conftest.glt_archive``); where its link frames are
checked, the reference is the built-in GLT model's own D-H forward kinematics, which the URDF
was written from. Scene objects are checked against the numbers they were stored with.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from kinematics.fk import fk, fk_frames
from kinematics.library import builtin_model
from kinematics.urdf import to_urdf
from kinematics.urdf_import import import_robot, mesh_to_bytes
from web.camera import DEFAULT_CANVAS_PX, DEFAULT_FOV_RAD, PANEL_PX, frame_bounds
from web.meshes import ImportedRobotNodes, robot_nodes
from web.results import Plan, Spheres
from web.scene import MM_TO_M, RobotNodes
from web.viewer import Viewer

trimesh = pytest.importorskip("trimesh")

RNG_SEED = 20260412
ROBOT = "glt_meshed"


@pytest.fixture(scope="module")
def server():
    import viser

    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


@pytest.fixture(scope="module")
def meshed(glt_meshed_zip):
    return import_robot(glt_meshed_zip, "glt.zip", robot_id=ROBOT)


@pytest.fixture
def api(tmp_path, meshed):
    """An application (no processes started) with the meshed robot imported and a viewer."""
    app = create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))
    app.state.registry.add_imported(meshed, {k: mesh_to_bytes(m)
                                             for k, m in meshed.meshes.items()})
    app.state.viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
    yield app
    app.state.viewer.stop()


def _matrix(wxyz) -> np.ndarray:
    import viser.transforms as vtf

    return vtf.SO3(wxyz=np.asarray(wxyz, dtype=float)).as_matrix()


def _node_names(server) -> set[str]:
    return set(server.scene._handle_from_node_name)


# ---- imported robots ------------------------------------------------------------------------
def test_imported_robot_link_frames_carry_its_meshes_and_follow_q(server, meshed):
    reference = builtin_model("glt_palletizer")  # the D-H model the URDF was written from
    root = f"/robot/{ROBOT}"
    q0 = reference.mid_configuration()
    nodes = robot_nodes(server.scene, root, meshed.model, q0, meshed)
    assert isinstance(nodes, ImportedRobotNodes) and nodes.source == "visual"
    try:
        meshed_links = [link.name for link in meshed.links if link.visual]
        assert meshed_links == ["base_link", "link_1", "link_2", "link_3", "link_4", "link_6"]
        for name in meshed_links:
            link = next(x for x in meshed.links if x.name == name)
            mesh = nodes.handles[f"{root}/links/{name}/visual_0"]
            # Uploaded once, in metres, coloured by the URDF material.
            np.testing.assert_allclose(
                mesh.vertices, meshed.meshes[link.visual[0].mesh].vertices * MM_TO_M,
                atol=1e-6)
            rgba = (0.3, 0.32, 0.36) if name in ("base_link", "link_1", "link_6") \
                else (0.93, 0.5, 0.12)
            want = tuple(int(round(255 * c)) for c in rgba)
            assert tuple(mesh.color) == want
        assert f"{root}/links/link_0" not in nodes.handles  # no geometry, no node

        uploads = []
        original = server.scene.add_mesh_simple
        server.scene.add_mesh_simple = lambda *a, **k: uploads.append(a) or original(*a, **k)
        try:
            rng = np.random.default_rng(RNG_SEED)
            for q in rng.uniform(reference.lower, reference.upper, size=(5, reference.dof)):
                nodes.update(q)
                frames = fk_frames(reference, q)
                for i in range(1, 6):
                    h = nodes.handles[f"{root}/links/link_{i}"] if i != 5 else None
                    if h is not None:
                        np.testing.assert_allclose(h.position, frames[i][:3, 3] * MM_TO_M,
                                                   atol=1e-9)
                # The flange link (the imported chain's tip) carries the built-in tool.
                h = nodes.handles[f"{root}/links/link_6"]
                T6 = np.eye(4)
                T6[:3, :3], T6[:3, 3] = _matrix(h.wxyz), np.asarray(h.position) / MM_TO_M
                np.testing.assert_allclose(T6 @ reference.tool, fk(reference, q), atol=1e-6)
                # The tool axes (and the IK gizmo) sit at the imported model's tip.
                tool = nodes.handles[f"{root}/tool"]
                np.testing.assert_allclose(tool.position, T6[:3, 3] * MM_TO_M, atol=1e-9)
                np.testing.assert_allclose(_matrix(tool.wxyz), T6[:3, :3], atol=1e-9)
        finally:
            server.scene.add_mesh_simple = original
        assert uploads == []  # moving never sends a mesh again
        # Bounds hold every mesh vertex where it is drawn.
        lo, hi = nodes.bounds_mm()
        for name in meshed_links:
            link = next(x for x in meshed.links if x.name == name)
            h = nodes.handles[f"{root}/links/{name}"]
            V = meshed.meshes[link.visual[0].mesh].vertices @ _matrix(h.wxyz).T \
                + np.asarray(h.position) / MM_TO_M
            assert np.all(V >= lo - 1e-6) and np.all(V <= hi + 1e-6)
    finally:
        nodes.remove()
    assert not any(n.startswith(root) for n in _node_names(server))


def test_a_robot_without_visuals_draws_its_collision_geometry(server, glt_collision_only_zip):
    robot = import_robot(glt_collision_only_zip, "glt.zip", robot_id="glt_collision")
    nodes = robot_nodes(server.scene, "/robot/glt_collision", robot.model,
                        robot.model.mid_configuration(), robot)
    try:
        assert isinstance(nodes, ImportedRobotNodes) and nodes.source == "collision"
        assert "/robot/glt_collision/links/link_2/collision_0" in nodes.handles
        mesh = nodes.handles["/robot/glt_collision/links/link_2/collision_0"]
        assert tuple(mesh.color) == (175, 178, 185)  # no material: neutral grey
    finally:
        nodes.remove()


def test_a_urdf_without_geometry_is_drawn_as_a_chain(server):
    model = builtin_model("glt_palletizer")
    robot = import_robot(to_urdf(model).encode(), "glt.urdf", robot_id="glt_bare")
    nodes = robot_nodes(server.scene, "/robot/glt_bare", robot.model,
                        robot.model.mid_configuration(), robot)
    try:
        assert isinstance(nodes, RobotNodes)
        assert "/robot/glt_bare/link_1" in nodes.handles
    finally:
        nodes.remove()


def test_the_viewer_shows_an_imported_robot_with_sliders_and_ik(api, meshed):
    v: Viewer = api.state.viewer
    shown = v.select(ROBOT)
    assert shown["robot"] == ROBOT
    model = api.state.registry.get(ROBOT)
    labels = [s.label for s in v.gui.sliders]
    assert [label.split(" ")[1] for label in labels] == [j.name for j in model.joints]
    root = v.arm_roots[""]
    handle = api.state.viewer.server.scene._handle_from_node_name[f"{root}/links/link_3"]
    q1 = model.mid_configuration() + 0.2
    v.set_q(q1)
    np.testing.assert_allclose(handle.position,
                               meshed.link_pose("link_3", q1)[:3, 3] * MM_TO_M, atol=1e-9)
    # IK drag: a reachable tool pose moves the arm there, and the meshes with it.
    q2 = model.mid_configuration() - 0.15
    result = v.drag_tool_to(fk(model, q2))
    assert result.success, result.message
    np.testing.assert_allclose(fk(model, v.q()), fk(model, q2), atol=1e-6)
    np.testing.assert_allclose(handle.position,
                               meshed.link_pose("link_3", v.q())[:3, 3] * MM_TO_M, atol=1e-9)


# ---- the collision model ---------------------------------------------------------------------
def _segment_distance(p, a, b) -> float:
    d = b - a
    t = 0.0 if not d.any() else float(np.clip((p - a) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * d)))


def test_collision_balls_toggle_and_follow_a_dh_robot(api):
    v: Viewer = api.state.viewer
    model = builtin_model("pile_driver")
    v.select("pile_driver")
    names = _node_names(v.server)
    assert "/robot/pile_driver/collision" not in names
    count = v.set_collision(True)
    assert v.gui.collision.value is True
    assert v.collision_nodes == ["/robot/pile_driver/collision"]
    handle = v.server.scene._handle_from_node_name["/robot/pile_driver/collision"]
    assert count == len(handle.batched_positions) > model.dof
    assert f"{count} balls" in v.gui.collision_info.content
    rng = np.random.default_rng(RNG_SEED)
    for q in rng.uniform(model.lower, model.upper, size=(4, model.dof)):
        v.set_q(q)
        # Every ball sits on a link: on the segment between two consecutive frame origins.
        origins = fk_frames(model, q)[:, :3, 3]
        for c in np.asarray(handle.batched_positions, dtype=float) / MM_TO_M:
            gap = min(_segment_distance(c, origins[k], origins[k + 1])
                      for k in range(model.dof))
            assert gap < 1e-3
    # A rig: one node per arm; switching robots keeps the toggle.
    v.select("tunnel_jumbo")
    assert sorted(v.collision_nodes) == [f"/robot/tunnel_jumbo/{arm}/collision"
                                         for arm in ("left", "middle", "right")]
    v.set_collision(False)
    assert v.collision_nodes == []
    assert not any(n.endswith("/collision") for n in _node_names(v.server))
    assert not v.gui.collision_info.visible


@pytest.mark.slow
def test_collision_balls_of_an_imported_robot_follow_its_links(api, meshed):
    v: Viewer = api.state.viewer
    v.select(ROBOT)
    v.set_collision(True)
    cm = api.state.registry.collision_model(ROBOT)
    handle = v.server.scene._handle_from_node_name[f"/robot/{ROBOT}/collision"]
    q = meshed.model.mid_configuration() + 0.3
    v.set_q(q)
    # Each ball centre, taken back into its link's frame, is where the model's tree has it.
    poses = meshed.link_poses(q)
    centres = np.asarray(handle.batched_positions, dtype=float) / MM_TO_M
    radii = np.asarray(handle.batched_scales, dtype=float) / MM_TO_M
    assert len(centres) == len(cm.sphere_links)
    for link_name in set(cm.sphere_links):
        T = poses[meshed.link_names.index(link_name)]
        sel = np.array([n == link_name for n in cm.sphere_links])
        local = (centres[sel] - T[:3, 3]) @ T[:3, :3]
        link = meshed.links[meshed.link_names.index(link_name)]
        V = meshed.meshes[link.collision[0].mesh].vertices
        # The balls cover the link's mesh: every vertex is inside some ball (to the
        # float32 the scene keeps).
        d = np.linalg.norm(V[:, None, :] - local[None], axis=-1) - radii[sel][None]
        assert d.min(axis=1).max() <= 1e-3
    v.set_collision(False)


def test_a_robot_without_collision_geometry_says_so(api):
    v: Viewer = api.state.viewer
    model = builtin_model("glt_palletizer")
    bare = import_robot(to_urdf(model).encode(), "glt.urdf", robot_id="glt_bare")
    api.state.registry.add_imported(bare, {})
    v.select("glt_bare")
    assert v.set_collision(True) == 0
    assert "No collision model" in v.gui.collision_info.content
    v.set_collision(False)


# ---- scenes --------------------------------------------------------------------------------
def _pose(x, y, z, yaw=0.0) -> list:
    c, s = math.cos(yaw), math.sin(yaw)
    return [[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def _store_scene(scenes, scene_id: str = "cell") -> dict:
    if "crate" not in scenes.mesh_ids():
        box = trimesh.creation.box(extents=(300.0, 200.0, 100.0))
        scenes.add_mesh("crate", np.asarray(box.vertices), np.asarray(box.faces), "crate.stl")
    rng = np.random.default_rng(RNG_SEED)
    wall = np.column_stack([np.full(400, 1800.0), rng.uniform(-500, 500, 400),
                            rng.uniform(0, 1200, 400)])
    objects = [
        {"type": "box", "id": "table", "size": [1200, 800, 40], "pose": _pose(900, 0, 380)},
        {"type": "sphere", "id": "ball", "radius": 90, "pose": _pose(600, 500, 500)},
        {"type": "cylinder", "id": "post", "radius": 60, "height": 1500,
         "pose": _pose(-400, 500, 750)},
        {"type": "capsule", "id": "pipe", "a": [0, 0, 0], "b": [0, 600, 0], "radius": 40,
         "pose": _pose(300, -700, 900)},
        {"type": "mesh", "id": "crate", "mesh": "crate", "scale": 2.0,
         "pose": _pose(900, 0, 450, yaw=0.5)},
        {"type": "points", "id": "scan/wall", "points": wall.tolist(), "radius": 8},
    ]
    return scenes.add(scene_id, {"objects": objects})


def test_a_stored_scene_draws_every_object_type(api):
    v: Viewer = api.state.viewer
    stored = _store_scene(api.state.scenes)
    shown = v.show_scene("cell")
    assert shown["scene"] == "cell"
    root = "/scene/cell"
    want = [f"{root}/{o['id'].replace('/', '_')}" for o in stored["objects"]]
    assert shown["scene_nodes"] == want == v.scene_nodes
    h = v.server.scene._handle_from_node_name
    import viser

    kinds = [viser.BoxHandle, viser.IcosphereHandle, viser.CylinderHandle, viser.MeshHandle,
             viser.MeshHandle, viser.PointCloudHandle]
    for name, kind in zip(want, kinds):
        assert isinstance(h[name], kind), (name, type(h[name]))
    np.testing.assert_allclose(h[f"{root}/table"].dimensions, [1.2, 0.8, 0.04])
    np.testing.assert_allclose(h[f"{root}/table"].position, [0.9, 0.0, 0.38])
    assert h[f"{root}/ball"].radius == pytest.approx(0.09)
    assert (h[f"{root}/post"].radius, h[f"{root}/post"].height) == pytest.approx((0.06, 1.5))
    # The capsule: its mesh spans the segment plus the radius at both ends.
    pipe = h[f"{root}/pipe"]
    V = np.asarray(pipe.vertices) @ _matrix(pipe.wxyz).T + pipe.position
    np.testing.assert_allclose(V.min(axis=0), [0.26, -0.74, 0.86], atol=2e-3)
    np.testing.assert_allclose(V.max(axis=0), [0.34, -0.06, 0.94], atol=2e-3)
    # The mesh: scaled twice, turned by its pose.
    crate = h[f"{root}/crate"]
    assert np.ptp(np.asarray(crate.vertices), axis=0) == pytest.approx([0.6, 0.4, 0.2])
    np.testing.assert_allclose(_matrix(crate.wxyz), np.asarray(_pose(0, 0, 0, 0.5))[:3, :3],
                               atol=1e-9)
    assert len(h[f"{root}/scan_wall"].points) == 400
    # Another scene replaces it; None clears it.
    api.state.scenes.add("small", {"objects": [{"type": "sphere", "radius": 50}]})
    shown = v.show_scene("small")
    assert shown["scene_nodes"] == ["/scene/small/sphere0"]
    assert not any(n.startswith("/scene/cell") for n in _node_names(v.server))
    shown = v.show_scene(None)
    assert shown["scene_nodes"] == [] and "scene" not in shown
    assert not any(n.startswith("/scene/") for n in _node_names(v.server))
    with pytest.raises(KeyError):
        v.show_scene("nope")


@pytest.mark.slow
def test_viewer_show_route_shows_and_clears_scenes(api):
    _store_scene(api.state.scenes)
    with TestClient(api) as client:
        r = client.post("/viewer/show", json={"scene": "nope"})
        assert r.status_code == 404 and r.json()["detail"][0]["loc"] == ["body", "scene"]
        r = client.post("/viewer/show", json={"scene": "not an id"})
        assert r.status_code == 422
        r = client.post("/viewer/show", json={"robot": ROBOT, "q": [0.1] * 6, "scene": "cell"})
        assert r.status_code == 200, r.text
        shown = r.json()["shown"]
        assert shown["robot"] == ROBOT and shown["q"] == [0.1] * 6 and shown["scene"] == "cell"
        assert "/scene/cell/table" in shown["scene_nodes"] and len(shown["scene_nodes"]) == 6
        # An unknown scene changes nothing, not even the robot.
        r = client.post("/viewer/show", json={"robot": "pile_driver", "scene": "nope"})
        assert r.status_code == 404
        assert api.state.viewer.current["robot"] == ROBOT
        r = client.post("/viewer/show", json={"scene": None})
        assert r.status_code == 200 and r.json()["shown"]["scene_nodes"] == []
        assert r.json()["shown"]["robot"] == ROBOT
        for body in ({}, {"q": [0.0] * 6}, {"scene": "cell", "q": [0.0] * 6}):
            r = client.post("/viewer/show", json=body)
            assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "robot"]


# ---- the camera ----------------------------------------------------------------------------
def _ndc(points, position, look_at, view) -> np.ndarray:
    """Pinhole projection of world points ``(N, 3)`` to normalised device coordinates
    ``(N, 2)`` (x right, y up, -1..1 on the canvas) for a camera with z up."""
    fov, width, height = view
    f = (look_at - position) / np.linalg.norm(look_at - position)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    rel = np.asarray(points) - position
    depth = rel @ f
    assert np.all(depth > 0)
    t = math.tan(fov / 2)
    return np.column_stack([rel @ right / (depth * t * width / height), rel @ up / (depth * t)])


def _corners(lo, hi) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])


@pytest.mark.parametrize("view", [(DEFAULT_FOV_RAD, *DEFAULT_CANVAS_PX),
                                  (math.radians(50), 900, 600),
                                  (math.radians(75), 1920, 1080),
                                  (math.radians(75), 600, 900)])
def test_framed_bounds_fit_the_canvas_left_of_the_panel(view):
    rng = np.random.default_rng(RNG_SEED)
    width = view[1]
    free_right = 1.0 - 2.0 * PANEL_PX / width if width - PANEL_PX >= 0.5 * width else 1.0
    for _ in range(50):
        lo = rng.uniform(-10, 10, 3)
        hi = lo + rng.uniform(0.01, 12, 3) * rng.uniform(0, 1, 3) ** 2
        position, look_at = frame_bounds(lo, hi, view)
        p = _ndc(_corners(lo, hi), position, look_at, view)
        assert np.all(p[:, 0] >= -1) and np.all(p[:, 0] <= free_right)
        assert np.all(np.abs(p[:, 1]) <= 1)
        # Not needlessly far: the box's ball would not fit at two thirds of the distance.
        radius = max(0.5 * np.linalg.norm(hi - lo), 0.25)
        assert np.linalg.norm(position - look_at) < 3.0 * radius / math.sin(view[0] / 2)


def test_the_camera_frames_the_robot_the_plan_and_the_scene(api):
    v: Viewer = api.state.viewer
    v.select("glt_palletizer")
    far = np.array([[9000.0, 4000.0, 1500.0], [9500.0, 4500.0, 2500.0]])  # holes 9 m away
    v.show_plan(Plan("far", "sequence", spheres=(Spheres("holes", far, np.full(2, 50.0),
                                                        (250, 200, 30)),)))
    view = (DEFAULT_FOV_RAD, *DEFAULT_CANVAS_PX)
    position = np.asarray(v.server.initial_camera.position)
    look_at = np.asarray(v.server.initial_camera.look_at)
    tool = v.tool_position() * MM_TO_M
    p = _ndc(np.vstack([far * MM_TO_M, tool, [0.0, 0.0, 0.0]]), position, look_at, view)
    assert np.all(np.abs(p) <= 1) and np.all(p[:, 0] <= 1 - 2 * PANEL_PX / view[1])
    # The imported robot's meshes and a scene are framed too.
    _store_scene(api.state.scenes)
    v.select(ROBOT)
    v.show_scene("cell")
    lo, hi = v.content_bounds()
    assert np.all(lo <= [-460.0, -740.0, 0.0]) and np.all(hi >= [1808.0, 500.0, 1500.0])
    position = np.asarray(v.server.initial_camera.position)
    look_at = np.asarray(v.server.initial_camera.look_at)
    p = _ndc(_corners(lo * MM_TO_M, hi * MM_TO_M), position, look_at, view)
    assert np.all(np.abs(p) <= 1) and np.all(p[:, 0] <= 1 - 2 * PANEL_PX / view[1])
