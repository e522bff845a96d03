"""The 3D viewer: a viser server in the service's process, showing its robots and jobs.

``Viewer.start(host, port, state)`` takes the application's ``state`` (its ``registry`` of
robots and rigs and its ``jobs`` manager), so the viewer sees exactly what the REST API sees.

What a browser gets (http://host:port):

* the robot picked in the dropdown (every built-in and custom robot, refreshed as robots are
  added, and the rigs: ``tunnel_jumbo`` draws its three arms), drawn by ``web.scene``;
* joint sliders (degrees, mm for prismatic joints) that move the arm live, and the cylinder
  lengths and strokes of hydraulic arms;
* a transform gizmo at the tool: dragging it solves IK from the current configuration and the
  arm follows; where IK fails the panel says why and the arm keeps its last good pose;
* a workspace button that runs a ``workspace`` job, shows its progress, then its point cloud
  coloured by height with the extents (one such job at a time, at most ``MAX_GUI_SAMPLES``,
  the API's synchronous cap; jobs are submitted to the same manager, with the same checks, as
  ``POST /jobs``);
* a **Run round**, **Run pallet** or **Run piles** button where the robot or rig shown has a
  stored plan (``web.cycles``: the product's example drill plan for ``tunnel_jumbo``, pallet
  for ``glt_palletizer``, pile plan for ``pile_driver``; ``Viewer.start(..., cycles=...)``
  hands others): it submits that whole-job work cycle the same way, shows its progress, then
  draws its answer (one such job at a time; a refusal says why);
* finished jobs shown by ``POST /viewer/show {"job": id}`` (``web.results``), with a time
  slider and play/pause when the plan moves arms (a batch of motion problems: one at a time,
  ``"problem": k``), and the answer of ``POST /robots/{id}/motion`` shown by
  ``POST /viewer/show {"motion": answer}``;
* robots imported from URDF drawn with their own meshes (``web.meshes``), and a "Collision
  model" checkbox showing the balls the collision checker uses, following the arm
  (``web.collision``);
* a stored scene shown by ``POST /viewer/show {"scene": id}`` (``web.site``: boxes, spheres,
  cylinders, capsules, meshes, point clouds under ``/scene/<id>``), until another scene
  replaces it or ``{"scene": null}`` clears it.

The camera frames everything shown (robot, plan, scene; ``web.camera``) whenever the robot,
the plan or the scene changes, keeping it clear of the control panel.

Access: ``Viewer.start`` runs viser on an internal loopback port and serves the public port
through ``web.gate``: with an API key the page and its websocket need ``/?key=<key>`` once (then
a cookie), and requests from other sites' pages (``Origin``) are refused (403).

Several tabs may watch at once: the scene and the panel are shared (all tabs see the same
robot and plan, and any tab may drive them); each tab's camera is its own. Every change of
state happens under one lock: viser runs GUI callbacks on a thread pool, the REST routes on
uvicorn's threads, and the viewer has its own threads for IK, playback and job polling.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from app.store import StoreError
from app.viewer import JobNotReady
from kinematics.ik import solve_ik
from kinematics.ik.result import IKResult
from kinematics.model import RobotModel

from .camera import RIG_VIEW_DIRECTION, VIEW_DIRECTION, View, frame_bounds, union_bounds
from .collision import CollisionSpheres
from .cycles import StoredPlan, check_plans, stored_plans
from .gate import Gate, lock_websockets_server, new_secret
from .gui import (
    MAX_GUI_SAMPLES,
    MIN_GUI_SAMPLES,
    NO_GOAL,
    NO_SCENE,
    ControlPanel,
    to_display,
)
from .meshes import ImportedRobotNodes, robot_nodes
from .results import DRAWERS, Plan, drawable, plan_from_motion, plan_from_result
from .scene import (
    MM_TO_M,
    RobotDrawing,
    RobotNodes,
    draw_plan,
    reach_m,
    wxyz_from_matrix,
)
from .site import SCENE_ROOT, SiteNodes, draw_site
from .tasks import LoadNodes, check_links, link_frame
from .text import code, plain
from .timed import TimedNodes

__all__ = ["Viewer", "JobNotReady", "MM_TO_M", "wxyz_from_matrix", "ROBOT_ROOT", "PLAN_ROOT",
           "SCENE_ROOT"]

log = logging.getLogger(__name__)

ROBOT_ROOT = "/robot"
PLAN_ROOT = "/plan"
IK_TARGET = "/ik/target"
#: The IK gizmo: its size as a share of the arm's reach, and its opacity.
GIZMO_SCALE, GIZMO_OPACITY = 0.12, 0.6
#: Period (s) of the viewer's own loop: playback frames and job polling.
TICK_S = 1.0 / 30.0
#: How often (s) the robot list is compared with the registry.
ROBOTS_REFRESH_S = 1.0
#: How often (s) a running workspace or motion job is polled.
POLL_S = 0.2
#: Planning time (s) of a motion planned from the viewer's Plan button.
PLAN_TIME_LIMIT_S = 5.0


class ServiceState(Protocol):
    """What the viewer needs of the application's state."""

    registry: Any  # app.registry.RobotRegistry: ids(), get(id), rigs, imported(id),
    #               collision_model(id)
    jobs: Any  # app.jobs.manager.JobManager: submit(kind, params), get(id), result(id)
    scenes: Any  # app.scenes.SceneRegistry: get(id) (the scene's validated objects)


@dataclass
class _Arm:
    """One drawn arm: its model, configuration and nodes."""

    key: str
    model: RobotModel
    q: np.ndarray
    nodes: RobotNodes | ImportedRobotNodes
    collision: CollisionSpheres | None = None


class Viewer:
    """A running viser server and what it shows. Thread-safe."""

    def __init__(self, server: Any, state: ServiceState, *, environment_map: bool = True,
                 cycles: Mapping[str, StoredPlan] | None = None) -> None:
        self.server = server
        self.registry = state.registry
        self.jobs = state.jobs
        self.scenes = getattr(state, "scenes", None)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._key: str = ""
        self._arms: dict[str, _Arm] = {}
        self._active: str = ""
        self._generation = 0  # bumped whenever the robot changes (stale IK answers drop)
        self._plan: Plan | None = None
        self._plan_handles: dict[str, Any] = {}
        self._loads: LoadNodes | None = None  # a task's carried loads (``web.tasks``)
        self._timed: TimedNodes | None = None  # segments recoloured in time (``web.timed``)
        self._time = 0.0
        self._playing = False
        self._ik_pending: tuple[np.ndarray, bool] | None = None
        self._ik_wake = threading.Event()
        self._ik_last: IKResult | None = None
        self._workspace_job: str | None = None
        self._goal: tuple[str, str, np.ndarray] | None = None  # (robot or rig, arm, q)
        self._motion_job: str | None = None
        # The stored plans of the work-cycle buttons (``web.cycles``) and the viewer's job.
        self._cycles = check_plans(stored_plans() if cycles is None else cycles)
        self._cycle_job: str | None = None
        self.gate: Gate | None = None
        self._options: tuple[str, ...] = ()
        self.current: dict | None = None
        self._site: SiteNodes | None = None
        self._collision_on = False
        self._unframed: set[int] = set()  # clients whose canvas size is not known yet

        scene = server.scene
        scene.set_up_direction("+z")
        if not environment_map:
            # Without the image-based light, a sky light and a key light from the camera's
            # side keep the faces that look at the default view lit.
            scene.configure_environment_map(None)
            scene.add_light_hemisphere("/lights/sky", sky_color=(255, 255, 255),
                                       ground_color=(90, 90, 100), intensity=1.2)
            scene.add_light_directional("/lights/key", intensity=1.6,
                                        position=(2.0, -4.0, 5.0))
        self._grid = scene.add_grid("/ground", width=4.0, height=4.0, cell_size=0.25,
                                    section_size=1.0)
        self._options = self._robot_options()
        first = self._options[0]
        self.gui = ControlPanel(server.gui, self._options, first)
        # Translucent and about a tenth of the arm's reach: the tool stays visible under it.
        self.gizmo = scene.add_transform_controls(IK_TARGET, scale=0.3, depth_test=False,
                                                  opacity=GIZMO_OPACITY)
        self._wire()
        self.select(first)
        server.on_client_connect(self._on_connect)
        server.on_client_disconnect(lambda client: self._unframed.discard(client.client_id))
        self._threads = [
            threading.Thread(target=self._tick_loop, name="viewer-tick", daemon=True),
            threading.Thread(target=self._ik_loop, name="viewer-ik", daemon=True),
        ]
        for t in self._threads:
            t.start()

    @classmethod
    def start(cls, host: str, port: int, state: ServiceState, *, environment_map: bool = True,
              api_key: str | None = None, allowed_origins: str | Sequence[str] | None = None,
              cycles: Mapping[str, StoredPlan] | None = None) -> Viewer:
        """Serve the viewer on ``host:port`` (0: any free port, see ``port``).

        viser listens on an internal loopback port that answers only the front
        (``web.gate.Gate``) on ``host:port``. With ``api_key`` the front asks for it
        (``/?key=<key>`` once, then a cookie). ``allowed_origins`` (a list or a
        comma-separated string; default: the viewer's own addresses) are the pages that may
        open it. Without a key the viewer is open to any client that reaches the port, but
        still not to other sites' pages. ``cycles``: the stored plans of the work-cycle
        buttons by robot or rig id (default ``web.cycles.stored_plans()``)."""
        import viser

        # No label: the panel title then shows the connection state ("Connected"). viser
        # prints its own (internal) address; the service logs the public one instead.
        with contextlib.redirect_stdout(io.StringIO()):
            server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        secret = new_secret()
        try:
            if not lock_websockets_server(server.get_port(), secret):
                log.warning("viser's internal port %d could not be locked to the viewer's "
                            "front: local clients may open it directly", server.get_port())
            gate = Gate(host, port, server.get_port(), api_key=api_key,
                        allowed_origins=allowed_origins, upstream_secret=secret).start()
        except BaseException:
            server.stop()
            raise
        try:
            viewer = cls(server, state, environment_map=environment_map, cycles=cycles)
        except BaseException:
            gate.stop()
            server.stop()
            raise
        viewer.gate = gate
        return viewer

    @property
    def port(self) -> int:
        """The public port (the front's; viser's own when started without one)."""
        return self.gate.port if self.gate is not None else self.server.get_port()

    def stop(self) -> None:
        """Stop the threads, the front and the server."""
        self._stop.set()
        self._ik_wake.set()
        for t in self._threads:
            t.join(timeout=2.0)
        if self.gate is not None:
            self.gate.stop()
        self.server.stop()

    # ---- robots -----------------------------------------------------------------------
    def _robot_options(self) -> tuple[str, ...]:
        return (*self.registry.ids(), *self.registry.rigs)

    def _arm_models(self, key: str) -> dict[str, RobotModel]:
        """Arms to draw for a robot or rig id; KeyError if it is neither."""
        rigs = self.registry.rigs
        if key in rigs:
            return dict(rigs[key].arms)
        return {"": self.registry.get(key)}

    def select(self, key: str, q=None, *, keep_plan: bool = False) -> dict:
        """Show robot or rig ``key`` at ``q`` (``(dof,)`` for a robot, ``{arm: (dof,)}`` for a
        rig; default mid-limits). KeyError if unknown, ValueError for a wrong ``q``."""
        models = self._arm_models(key)
        qs: dict[str, np.ndarray] = {}
        for arm, model in models.items():
            given = q.get(arm) if isinstance(q, dict) else (q if arm == "" else None)
            qa = model.mid_configuration() if given is None else np.asarray(given, float)
            if qa.shape != (model.dof,) or not np.all(np.isfinite(qa)):
                raise ValueError(f"expected {model.dof} finite joint values for robot "
                                 f"'{model.id}', got {list(np.shape(given))}")
            qs[arm] = qa
        if self._collision_on:
            self._build_collision_models(models.values())
        with self._lock, self.server.atomic():
            if not keep_plan:
                self._clear_plan()
            for arm in self._arms.values():
                arm.nodes.remove()
            self._generation += 1
            if key != self._key:
                self._goal = None
                self.gui.run_plan.disabled = True
                self.gui.motion.content = NO_GOAL
            self._key = key
            self.gui.show_cycle_plan(key, self._cycles.get(key), self._cycles)
            self._arms = {}
            for arm, model in models.items():
                root = f"{ROBOT_ROOT}/{key}" + (f"/{arm}" if arm else "")
                nodes = robot_nodes(self.server.scene, root, model, qs[arm],
                                    self._imported(model))
                self._arms[arm] = _Arm(arm, model, qs[arm], nodes)
            self._active = next(iter(self._arms))
            self._draw_collision()
            self.gui.robot.value = key
            self.gui.arm.options = tuple(self._arms) if len(self._arms) > 1 else ("-",)
            self.gui.arm.visible = len(self._arms) > 1
            if len(self._arms) > 1:
                self.gui.arm.value = self._active
            self._show_active()
            self._frame_cameras()
            self._remember()
            return self.current

    def _imported(self, model: RobotModel) -> Any:
        """The ``ImportedRobot`` behind ``model`` (None: not imported from URDF)."""
        lookup = getattr(self.registry, "imported", None)
        if lookup is None:
            return None
        try:
            robot = lookup(model.id)
        except KeyError:
            return None
        # Rebuilt from its stored description, its model is an equal copy of ``model``.
        return robot if robot is not None and robot.model.dof == model.dof else None

    def _show_active(self) -> None:
        """Sliders, cylinder table and gizmo for the active arm (under the lock)."""
        arm = self._arms[self._active]
        self.gui.set_joints(arm.model, arm.q, self._on_slider)
        self.gui.show_cylinders(arm.nodes.drawing.cylinders)
        self._place_gizmo(arm.nodes.drawing)
        self.gui.ik.content = "The arm follows the gizmo where IK reaches it."

    def _place_gizmo(self, drawing: RobotDrawing) -> None:
        T = drawing.T_base_tool
        self.gizmo.position = T[:3, 3] * MM_TO_M
        self.gizmo.wxyz = wxyz_from_matrix(T[:3, :3])
        self.gizmo.scale = max(0.1, GIZMO_SCALE * reach_m(self._arms[self._active].model))

    def _remember(self) -> None:
        if len(self._arms) == 1 and "" in self._arms:
            self.current = {"robot": self._key, "q": self._arms[""].q.tolist()}
        else:
            self.current = {"robot": self._key,
                            "q": {k: a.q.tolist() for k, a in self._arms.items()}}
        if self._plan is not None:
            self.current["job"] = self._plan.job
            self.current["kind"] = self._plan.kind
        if self._site is not None:
            self.current["scene"] = self._site.scene_id

    def set_q(self, q, arm: str | None = None, *, source: str = "api") -> RobotDrawing:
        """Move an arm (default: the active one) to ``q (dof,)``. ``source`` says who asked:
        the sliders are not written back to themselves, the gizmo not while it is dragged."""
        with self._lock, self.server.atomic():
            key = self._active if arm is None else arm
            a = self._arms[key]
            a.q = np.asarray(q, dtype=float).copy()
            drawing = a.nodes.update(a.q)
            if a.collision is not None:
                a.collision.update(a.q)
            if key == self._active:
                if source != "slider":
                    self.gui.show_q(a.model, a.q)
                self.gui.show_cylinders(drawing.cylinders)
                if source != "ik":
                    self._place_gizmo(drawing)
            self._remember()
            return drawing

    def q(self, arm: str | None = None) -> np.ndarray:
        """Current configuration of an arm (default: the active one)."""
        with self._lock:
            return self._arms[self._active if arm is None else arm].q.copy()

    def tool_position(self, arm: str | None = None) -> np.ndarray:
        """Tool position ``(3,)`` mm of an arm as drawn."""
        with self._lock:
            a = self._arms[self._active if arm is None else arm]
            return a.nodes.drawing.T_base_tool[:3, 3].copy()

    @property
    def arm_roots(self) -> dict[str, str]:
        """Scene root of each drawn arm."""
        with self._lock:
            return {k: a.nodes.root for k, a in self._arms.items()}

    # ---- IK -----------------------------------------------------------------------------
    def drag_tool_to(self, T_base_tool, arm: str | None = None) -> IKResult:
        """Solve IK for the tool pose ``(4, 4)`` mm from the current configuration and move
        the arm there if it succeeds; otherwise keep it and report why in the panel."""
        with self._lock:
            key = self._active if arm is None else arm
            a = self._arms[key]
            model, q0, generation = a.model, a.q.copy(), self._generation
        (result,) = solve_ik(model, np.asarray(T_base_tool, dtype=float), q0=q0)
        with self._lock:
            if generation != self._generation:
                return result  # the robot changed meanwhile: the answer is stale
            self._ik_last = result
            if result.success:
                self.set_q(result.q, key, source="ik")
                self.gui.ik.content = (f"Reached: position error {result.position_error:.2g} "
                                       f"mm ({plain(result.method)}).")
            else:
                self.gui.ik.content = (f"**Cannot reach the gizmo** ({plain(result.status)}): "
                                       f"{plain(result.message)}\n\nThe arm stays at its last "
                                       "good pose.")
        return result

    def _on_gizmo(self, event: Any) -> None:
        target = event.target
        T = np.eye(4)
        T[:3, :3] = _matrix_from_wxyz(np.asarray(target.wxyz, dtype=float))
        T[:3, 3] = np.asarray(target.position, dtype=float) / MM_TO_M
        with self._lock:
            if event.phase == "start":
                self._playing = False
            # Only the newest pose matters: drags arrive faster than IK may answer.
            self._ik_pending = (T, event.phase == "end")
        self._ik_wake.set()

    def _ik_loop(self) -> None:
        while not self._stop.is_set():
            self._ik_wake.wait()
            self._ik_wake.clear()
            with self._lock:
                pending, self._ik_pending = self._ik_pending, None
            if pending is None or self._stop.is_set():
                continue
            T, ended = pending
            try:
                self.drag_tool_to(T)
            except Exception as exc:  # a bad pose must not kill the IK thread
                log.warning("IK for the gizmo failed: %s", exc)
                with self._lock:
                    self.gui.ik.content = f"**IK error**: {plain(exc)}"
            if ended:
                with self._lock:
                    if self._ik_pending is None:  # back to the tool at the end of a drag
                        self._place_gizmo(self._arms[self._active].nodes.drawing)

    # ---- GUI callbacks ------------------------------------------------------------------
    def _wire(self) -> None:
        g = self.gui

        @g.robot.on_update
        def _(event: Any) -> None:
            if event.client is None:  # set by the viewer itself
                return
            try:
                self.select(g.robot.value)
            except KeyError:
                self.refresh_robots()

        @g.arm.on_update
        def _(event: Any) -> None:
            if event.client is None:
                return
            with self._lock:
                if g.arm.value in self._arms:
                    self._active = g.arm.value
                    self._show_active()

        @g.run_workspace.on_click
        def _(event: Any) -> None:
            self.run_workspace(g.samples.value)

        for kind, button in g.run_cycle.items():
            button.on_click(lambda event, kind=kind: self.run_cycle(kind))

        @g.set_goal.on_click
        def _(event: Any) -> None:
            self.set_goal()

        @g.run_plan.on_click
        def _(event: Any) -> None:
            self.plan_to_goal()

        @g.time.on_update
        def _(event: Any) -> None:
            if event.client is None:
                return
            with self._lock:
                self._playing = False
                g.play.label = "Play"
                self._apply_time(float(g.time.value))

        @g.play.on_click
        def _(event: Any) -> None:
            self.toggle_play()

        @g.collision.on_update
        def _(event: Any) -> None:
            if event.client is None:
                return
            self.set_collision(bool(g.collision.value))

        self.gizmo.on_update(self._on_gizmo)

    def _on_slider(self, i: int, event: Any) -> None:
        if event.client is None:
            return
        with self._lock:
            a = self._arms[self._active]
            q = a.q.copy()
            q[i] = self.gui.slider_q(a.model)[i]
            self._playing = False
            self.set_q(q, source="slider")

    def _on_connect(self, client: Any) -> None:
        with self._lock:
            position, look_at = self._camera_pose()
            # Framed again at its first camera report, which tells the canvas size.
            self._unframed.add(client.client_id)
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.position = position
        client.camera.look_at = look_at

        @client.camera.on_update
        def _(camera: Any) -> None:
            if client.client_id not in self._unframed:  # every later move: no lock taken
                return
            with self._lock:
                if client.client_id not in self._unframed:
                    return
                view = _client_view(client)
                if view is None:
                    return
                self._unframed.discard(client.client_id)
                position, look_at = self._camera_pose(view)
            camera.position = position
            camera.look_at = look_at

    # ---- camera -------------------------------------------------------------------------
    def content_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World bounds ``(lower (3,), upper (3,))`` mm of everything drawn: the arms (their
        meshes for imported robots), their collision balls, the plan and the scene."""
        with self._lock:
            boxes = [a.nodes.bounds_mm() for a in self._arms.values()]
            boxes += [a.collision.bounds_mm() for a in self._arms.values()
                      if a.collision is not None]
            if self._plan is not None:
                boxes.append(self._plan.bounds())
            if self._loads is not None:
                boxes.append(self._loads.bounds)
            if self._site is not None:
                boxes.append(self._site.bounds)
            found = union_bounds(boxes)
            return found if found is not None else (np.zeros(3), np.zeros(3))

    def _camera_pose(self, view: View | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Camera ``(position, look_at)`` (m) framing everything drawn (``web.camera``) on a
        canvas ``view`` (default: an assumed one)."""
        lo, hi = self.content_bounds()
        rig = self._key in self.registry.rigs
        return frame_bounds(lo * MM_TO_M, hi * MM_TO_M, view,
                            direction=RIG_VIEW_DIRECTION if rig else VIEW_DIRECTION)

    def _frame_cameras(self) -> None:
        """Point every browser's camera (and "reset view") at everything drawn, and size the
        ground grid to it (under the lock)."""
        position, look_at = self._camera_pose()
        self.server.initial_camera.position = position
        self.server.initial_camera.look_at = look_at
        lo, hi = self.content_bounds()
        reach = float(np.abs(np.concatenate([lo[:2], hi[:2]])).max()) * MM_TO_M
        self._grid.width = self._grid.height = float(max(4.0, 2.0 * math.ceil(reach) + 2.0))
        # The ground under everything drawn (a face's holes reach below a rig's frame).
        self._grid.position = (0.0, 0.0, min(0.0, float(lo[2]) * MM_TO_M))
        for client in self.server.get_clients().values():
            view = _client_view(client)
            if view is not None:
                position, look_at = self._camera_pose(view)
            client.camera.position = position
            client.camera.look_at = look_at

    # ---- collision model ----------------------------------------------------------------
    def set_collision(self, on: bool) -> int:
        """Show (or hide) the collision model's balls on every drawn arm; returns how many
        balls are shown. An arm whose collision model cannot be built shows none, and the
        panel says why."""
        with self._lock:
            self._collision_on = bool(on)
            if self.gui.collision.value != self._collision_on:
                self.gui.collision.value = self._collision_on
            models = [a.model for a in self._arms.values()]
            if on:
                self.gui.show_collision("Building the collision model…")
        if on:
            self._build_collision_models(models)
        with self._lock, self.server.atomic():
            return self._draw_collision()

    def _build_collision_models(self, models) -> None:
        """Have the registry build (and keep) the collision models of ``models``, outside the
        lock: an imported robot's sphere trees take seconds. Failures show when drawn."""
        for model in models:
            try:
                self.registry.collision_model(model.id)
            except Exception:  # noqa: BLE001 - reported by _draw_collision
                pass

    @property
    def collision_nodes(self) -> list[str]:
        """Node names of the collision balls shown (one node per arm)."""
        with self._lock:
            return [a.collision.name for a in self._arms.values() if a.collision is not None]

    def _draw_collision(self) -> int:
        """Add or remove the arms' collision balls as the checkbox says (under the lock)."""
        notes, count = [], 0
        for a in self._arms.values():
            if a.collision is not None and not self._collision_on:
                a.collision.remove()
                a.collision = None
            if self._collision_on and a.collision is None:
                try:
                    cm = self.registry.collision_model(a.model.id)
                    a.collision = CollisionSpheres(self.server.scene,
                                                   f"{a.nodes.root}/collision", cm, a.q)
                except Exception as exc:  # e.g. a URDF without collision geometry
                    log.info("no collision model for '%s': %s", a.model.id, exc)
                    notes.append(f"{code(a.model.id)}: {plain(exc)}")
                    continue
            if a.collision is not None:
                count += a.collision.count
        if self._collision_on:
            text = f"{count} balls on {len(self._arms)} arm(s)" if len(self._arms) > 1 \
                else f"{count} balls"
            if notes:
                text += "\n\n**No collision model** for " + "; ".join(notes)
            self.gui.show_collision(text)
        else:
            self.gui.show_collision("")
        return count

    # ---- scenes -------------------------------------------------------------------------
    def show_scene(self, scene_id: str | None) -> dict:
        """Draw the stored scene ``scene_id`` under ``/scene/<id>``, replacing the scene
        shown; None clears it. KeyError if the scene is unknown (nothing changes then)."""
        objects = None
        if scene_id is not None:
            if self.scenes is None:
                raise KeyError(scene_id)
            objects = self.scenes.get(scene_id).objects
        with self._lock, self.server.atomic():
            if self._site is not None:
                self._site.remove()
                self._site = None
            if objects is not None:
                self._site = draw_site(self.server.scene, scene_id, objects)
                n = len(self._site.objects)
                self.gui.scene.content = f"**Scene** {code(scene_id)}: {n} object(s)"
            else:
                self.gui.scene.content = NO_SCENE
            self._frame_cameras()
            self._remember()
            return {**self.current, "scene_nodes": self.scene_nodes}

    @property
    def scene_nodes(self) -> list[str]:
        """Node names of the scene's objects shown (in the scene's order)."""
        with self._lock:
            return self._site.names if self._site is not None else []

    def refresh_robots(self) -> None:
        """Compare the robot list with the registry; update the dropdown when it changed
        (and show the first robot if the one shown has been deleted)."""
        options = self._robot_options()
        with self._lock:
            if options == self._options:
                return
            self._options = options
            self.gui.robot.options = options
            if self._key in options:
                self.gui.robot.value = self._key
                return
        self.select(options[0])

    # ---- jobs ---------------------------------------------------------------------------
    def run_workspace(self, samples: Any) -> str | None:
        """Submit a ``workspace`` job for the active arm; the tick loop follows it. Returns
        the job id, or None when it is not started (the panel says why): a workspace job the
        viewer started is still queued or running (one at a time, whichever tab asked), the
        sample count is not a whole number within ``MIN_GUI_SAMPLES..MAX_GUI_SAMPLES`` (the API's
        synchronous cap), or the job manager refused it (full queue, bad parameters)."""
        with self._lock:
            busy = self._workspace_in_flight()
            if busy is not None:
                self.gui.workspace.content = (
                    f"**Not started**: workspace job {code(busy)} is still running; wait for "
                    "it (one workspace job at a time from the viewer).")
                return None
            count = _sample_count(samples)
            if count is None:
                self.gui.workspace.content = (
                    f"**Not started**: samples must be a whole number from "
                    f"{MIN_GUI_SAMPLES:,} to {MAX_GUI_SAMPLES:,}.")
                return None
            model = self._arms[self._active].model
            # Submitted under the lock: two clicks cannot both pass the check above.
            try:
                job = self.jobs.submit("workspace", {"robot": model.id, "samples": count})
            except Exception as exc:  # JobParamsError, QueueFullError: say why in the panel
                self.gui.workspace.content = f"**Not started**: {plain(exc)}"
                return None
            self._workspace_job = job.id
            self.gui.progress.value = 0.0
            self.gui.progress.visible = True
            self.gui.workspace.content = f"Job {code(job.id)}: queued ({count:,} samples)"
            return job.id

    def _workspace_in_flight(self) -> str | None:
        """The viewer's workspace job if it is still queued or running (under the lock)."""
        return self._in_flight(self._workspace_job)

    def _look_up(self, job_id: str, panel: Any) -> tuple[bool, Any]:
        """Whether the viewer's job ``job_id`` could be read, and its record (None once it
        vanished); with the data store down, ``panel`` says so and the next poll tries
        again."""
        try:
            return True, self.jobs.get(job_id)
        except KeyError:
            return True, None
        except StoreError as exc:
            with self._lock:
                panel.content = (f"Job {code(job_id)}: the data store is unavailable "
                                 f"({plain(exc.reason)}); still waiting")
            return False, None

    def _follow(self, attr: str, panel: Any, bar: Any, failed: str,
                kind: bool = False) -> str | None:
        """Poll the viewer's job held in ``self.<attr>``: its progress on ``bar`` and its
        status in ``panel`` (with the job's kind when ``kind``). Answers the job's id once
        it has succeeded (``attr`` cleared), else None: still running, or ended otherwise
        (``failed``, formatted with ``job`` and ``why``, says so in the panel)."""
        with self._lock:
            job_id = getattr(self, attr)
        if job_id is None:
            return None
        read, job = self._look_up(job_id, panel)
        if not read:
            return None
        with self._lock:
            if job is None or job.status in ("failed", "cancelled"):
                why = "vanished" if job is None else f"{job.status}: {job.error or ''}"
                panel.content = failed.format(job=code(job_id), why=plain(why))
                bar.visible = False
                setattr(self, attr, None)
                return None
            bar.value = float(np.clip(100.0 * job.progress, 0.0, 100.0))
            if job.status != "succeeded":
                msg = f" ({plain(job.message)})" if job.message else ""
                what = f" ({plain(job.kind)})" if kind else ""
                panel.content = (f"Job {code(job_id)}{what}: {plain(job.status)}, "
                                 f"{100 * job.progress:.0f} %{msg}")
                return None
            setattr(self, attr, None)
            bar.visible = False
        return job_id

    def _show_followed(self, job_id: str, panel: Any) -> bool:
        """Draw the viewer's finished job; False (and why in ``panel``) if it cannot be."""
        try:
            self.show_job(job_id)
        except (KeyError, ValueError, JobNotReady) as exc:
            with self._lock:
                panel.content = f"Job {code(job_id)} cannot be shown: {plain(exc)}"
            return False
        return True

    def _poll_workspace(self) -> None:
        job_id = self._follow("_workspace_job", self.gui.workspace, self.gui.progress,
                              "Job {job} {why}")
        if job_id is None or not self._show_followed(job_id, self.gui.workspace):
            return
        with self._lock:
            if self._plan is not None:
                self.gui.workspace.content = self._plan.summary

    # ---- work cycles ----------------------------------------------------------------------
    @property
    def cycles(self) -> dict[str, StoredPlan]:
        """The stored plans of the work-cycle buttons, by robot or rig id."""
        return dict(self._cycles)

    def run_cycle(self, kind: str | None = None) -> str | None:
        """Submit the work-cycle job of the stored plan of the robot or rig shown (``kind``:
        the button pressed, which must be that plan's); the tick loop follows it and draws its
        answer. Returns the job id, or None when it is not started (the panel says why): the
        robot shown has no stored plan (of that kind), a work-cycle job the viewer started is
        still queued or running (one at a time, whichever tab asked), the plan cannot be
        built, or the job manager refused it (the field at fault, a full queue)."""
        with self._lock:
            plan = self._cycles.get(self._key)
            if plan is None or (kind is not None and plan.kind != kind):
                what = "stored plan" if kind is None else f"stored {plain(kind)} plan"
                self.gui.cycle.content = (f"**Not started**: {code(self._key)} has no "
                                          f"{what}.")
                return None
            busy = self._in_flight(self._cycle_job)
            if busy is not None:
                self.gui.cycle.content = (
                    f"**Not started**: work-cycle job {code(busy)} is still running; wait "
                    "for it (one work cycle at a time from the viewer).")
                return None
            try:
                params = plan.params()
            except Exception as exc:  # noqa: BLE001 - a builder's failure, said in the panel
                self.gui.cycle.content = (f"**Not started**: the stored plan cannot be "
                                          f"built: {plain(exc)}")
                return None
            # Submitted under the lock: two clicks cannot both pass the check above.
            try:
                job = self.jobs.submit(plan.kind, params)
            except Exception as exc:  # JobParamsError (naming the field), QueueFullError
                loc = getattr(exc, "loc", None)
                where = f"{code('.'.join(str(p) for p in loc))}: " if loc else ""
                self.gui.cycle.content = f"**Not started**: {where}{plain(exc)}"
                return None
            self._cycle_job = job.id
            self.gui.cycle_progress.value = 0.0
            self.gui.cycle_progress.visible = True
            self.gui.cycle.content = f"Job {code(job.id)} ({plain(plan.kind)}): queued"
            return job.id

    def _poll_cycle(self) -> None:
        """Follow the viewer's work-cycle job: its status and progress in the panel, its
        answer drawn once it succeeds, or why it did not."""
        job_id = self._follow("_cycle_job", self.gui.cycle, self.gui.cycle_progress,
                              "**Not planned**: job {job} {why}", kind=True)
        if job_id is None or not self._show_followed(job_id, self.gui.cycle):
            return
        with self._lock:
            kind = self._plan.kind if self._plan is not None else ""
            play = " Play runs it." if self._plan is not None and self._plan.motions else ""
            self.gui.cycle.content = (f"Planned: job {code(job_id)} ({plain(kind)}), "
                                      f"shown under **Plan**.{play}")

    # ---- planning from the viewer ---------------------------------------------------------
    def set_goal(self) -> np.ndarray:
        """Keep the active arm's configuration as the goal of the next ``plan_to_goal``."""
        with self._lock:
            arm = self._arms[self._active]
            self._goal = (self._key, self._active, arm.q.copy())
            self.gui.run_plan.disabled = False
            shown = ", ".join(f"{v:.1f}" for v in to_display(arm.model, arm.q))
            self.gui.motion.content = (f"Goal kept: ({plain(shown)}). Move the arm to the "
                                       "start, then press **Plan**.")
            return arm.q.copy()

    def plan_to_goal(self, time_limit: float = PLAN_TIME_LIMIT_S) -> str | None:
        """Submit a ``motion`` job of the active arm from its configuration to the kept goal,
        in the scene shown (if any); the tick loop follows it and plays the answer. Returns
        the job id, or None when it is not started (the panel says why): no goal kept for
        this robot and arm, a plan from the viewer still running, a robot the motion planner
        does not know by id (a rig's arm), or the job manager refused it."""
        with self._lock:
            arm = self._arms[self._active]
            if self._goal is None or self._goal[:2] != (self._key, self._active):
                self.gui.motion.content = f"**Not planned**: {NO_GOAL}"
                return None
            busy = self._in_flight(self._motion_job)
            if busy is not None:
                self.gui.motion.content = (f"**Not planned**: motion job {code(busy)} is "
                                           "still running; wait for it.")
                return None
            try:
                self.registry.get(arm.model.id)
            except KeyError:
                self.gui.motion.content = (
                    f"**Not planned**: arm {code(self._active)} of {code(self._key)} is not a "
                    "robot of its own; plan a rig's arms with a multiarm job.")
                return None
            params: dict[str, Any] = {"robot": arm.model.id, "start": arm.q.tolist(),
                                      "goal": {"q": self._goal[2].tolist()},
                                      "time_limit": time_limit}
            if self._site is not None:
                params["scene"] = self._site.scene_id
            try:
                job = self.jobs.submit("motion", params)
            except Exception as exc:  # JobParamsError, QueueFullError: say why in the panel
                self.gui.motion.content = f"**Not planned**: {plain(exc)}"
                return None
            self._motion_job = job.id
            self.gui.motion.content = f"Planning: job {code(job.id)} queued"
            return job.id

    def _in_flight(self, job_id: str | None) -> str | None:
        """``job_id`` if that job is still queued or running (under the lock)."""
        if job_id is None:
            return None
        try:
            status = self.jobs.get(job_id).status
        except KeyError:
            status = "vanished"
        return job_id if status in ("queued", "running") else None

    def _poll_motion(self) -> None:
        """Follow the viewer's motion job: its status in the panel, its answer shown (and
        played) once it succeeds, or why it did not."""
        with self._lock:
            job_id = self._motion_job
        if job_id is None:
            return
        read, job = self._look_up(job_id, self.gui.motion)
        if not read or (job is not None and job.status in ("queued", "running")):
            return
        with self._lock:
            self._motion_job = None
            if job is None or job.status != "succeeded":
                why = "vanished" if job is None else f"{job.status}: {job.error or ''}"
                self.gui.motion.content = f"**Not planned**: job {code(job_id)} {plain(why)}"
                return
        try:
            self.show_job(job_id)
        except (KeyError, ValueError, JobNotReady) as exc:
            with self._lock:
                self.gui.motion.content = f"Job {code(job_id)} cannot be shown: {plain(exc)}"
            return
        with self._lock:
            result = json.loads(self.jobs.result(job_id))
            status = result.get("status", "?")
            if status == "ok":
                self.gui.motion.content = f"Planned: job {code(job_id)}, playing."
                self._time = 0.0
                self._playing = True
                self.gui.play.label = "Pause"
            else:
                message = result.get("message") or ""
                self.gui.motion.content = (f"**No plan** ({plain(status)}): "
                                           f"{plain(message)}")

    def show_job(self, job_id: str, problem: int | None = None) -> dict:
        """Draw a finished job's result (``problem``: which of a batch's problems). KeyError
        if the job is unknown, ``JobNotReady`` if it has not succeeded, ValueError if its kind
        cannot be drawn or its result is not of the documented shape (``FieldError`` at
        ``("problem",)`` for a problem it does not have)."""
        job = self.jobs.get(job_id)
        if not drawable(job.kind):
            raise ValueError(f"the viewer cannot show jobs of kind '{job.kind}'; it shows "
                             f"{', '.join(DRAWERS)}")
        if job.status != "succeeded":
            raise JobNotReady(job_id, job.status, job.error)
        result = json.loads(self.jobs.result(job_id))
        plan = plan_from_result(job.kind, job.params, result, job=job_id,
                                models=self.registry.get, rigs=self.registry.rigs,
                                problem=problem)
        return self.show_plan(plan)

    def show_motion(self, answer: Any) -> dict:
        """Draw an answer of ``POST /robots/{id}/motion`` (its JSON object): its robot moves
        along it. ValueError naming the key for an answer of another shape or robot."""
        return self.show_plan(plan_from_motion(answer, models=self.registry.get))

    def show_plan(self, plan: Plan) -> dict:
        """Draw ``plan`` (replacing any plan shown), switching to its robot if it names one."""
        with self._lock:
            if plan.robot is not None and plan.robot != self._key:
                self.select(plan.robot)
            for arm in plan.motions:
                if arm not in self._arms:
                    raise ValueError(f"the plan moves arm '{arm}', which '{self._key}' "
                                     "does not have")
            if plan.task is not None and plan.task.loads and plan.motions:
                check_links(plan.task.loads, self._link_frames(next(iter(plan.motions))))
            with self.server.atomic():
                self._clear_plan()
                self._plan = plan
                size = max(reach_m(a.model) for a in self._arms.values())
                root = f"{PLAN_ROOT}/{plan.kind}"
                self._plan_handles = draw_plan(self.server.scene, root, plan, size)
                for site in plan.sites:  # after the root: removed with it
                    self._plan_handles.update(draw_site(
                        self.server.scene, site.name, site.objects,
                        root=f"{root}/{site.name}").handles)
                if plan.task is not None and plan.task.loads and plan.motions:
                    self._loads = LoadNodes(self.server.scene, root, plan.task.loads,
                                            self._link_frames(next(iter(plan.motions))))
                    self._plan_handles.update(self._loads.handles)
                if plan.timed:
                    self._timed = TimedNodes(self.server.scene, root, plan.timed,
                                             max(0.004, 0.004 * size))
                    self._plan_handles.update(self._timed.handles)
                self.gui.plan.content = plan.summary
                self.gui.set_playback(plan.duration)
                self._time = 0.0
                self._playing = False
                if plan.motions:
                    self._apply_time(0.0)
                self._frame_cameras()
            self._remember()
            return {**self.current, "nodes": sorted(self._plan_handles)}

    def _link_frames(self, arm: str):
        """``frame(link, q)``: the world pose (mm) of a link of ``arm`` at ``q``, where the
        collision checker puts what the link carries (``web.tasks.link_frame``)."""
        model = self._arms[arm].model
        imported = self._imported(model)
        return lambda link, q: link_frame(model, imported, link, q)

    @property
    def loads(self) -> dict[str, np.ndarray | None]:
        """The world pose ``T_world_object (4, 4)`` mm of each load of the task shown, by its
        node name under ``<plan>/loads`` (None while hidden)."""
        with self._lock:
            if self._loads is None:
                return {}
            return {k: (None if v is None else v.copy()) for k, v in self._loads.poses.items()}

    @property
    def plan_nodes(self) -> list[str]:
        """Node names of the plan shown."""
        with self._lock:
            return sorted(self._plan_handles)

    def _clear_plan(self) -> None:
        root = next(iter(self._plan_handles.values()), None)
        if root is not None:
            root.remove()
        self._plan_handles = {}
        self._plan = None
        self._loads = None
        self._timed = None
        self._playing = False
        self.gui.plan.content = "No plan shown: `POST /viewer/show {\"job\": id}`."
        self.gui.set_playback(0.0)

    # ---- playback -----------------------------------------------------------------------
    def toggle_play(self) -> bool:
        """Start or pause the plan's motion; returns whether it now plays."""
        with self._lock:
            if self._plan is None or not self._plan.motions:
                return False
            self._playing = not self._playing
            if self._playing and self._time >= self._plan.duration:
                self._time = 0.0
            self.gui.play.label = "Pause" if self._playing else "Play"
            return self._playing

    def set_time(self, t: float) -> None:
        """Put the plan's arms at time ``t`` s (paused)."""
        with self._lock:
            self._playing = False
            self._apply_time(t)

    def _apply_time(self, t: float) -> None:
        if self._plan is None:
            return
        self._time = float(np.clip(t, 0.0, self._plan.duration))
        with self.server.atomic():
            for arm, motion in self._plan.motions.items():
                self.set_q(motion.at(self._time), arm, source="playback")
            if self._loads is not None:
                self._loads.update(self._time, self._arms[next(iter(self._plan.motions))].q)
            if self._timed is not None:
                self._timed.update(self._time)
            task = self._plan.task
            if task is not None:
                live = task.text_at(self._time)
                text = self._plan.summary + (f"\n\n{live}" if live else "")
                if self.gui.plan.content != text:
                    self.gui.plan.content = text
            if abs(self.gui.time.value - self._time) > 1e-9:
                self.gui.time.value = self._time

    def _tick_loop(self) -> None:
        last_refresh = last_poll = 0.0
        previous = time.monotonic()
        last_error = ""
        while not self._stop.wait(TICK_S):
            now = time.monotonic()
            dt, previous = now - previous, now
            try:
                with self._lock:
                    if self._playing and self._plan is not None:
                        t = self._time + dt * float(self.gui.speed.value)
                        if t >= self._plan.duration:
                            self._playing = False
                            self.gui.play.label = "Play"
                        self._apply_time(t)
                if now - last_poll >= POLL_S:
                    last_poll = now
                    self._poll_workspace()
                    self._poll_motion()
                    self._poll_cycle()
                if now - last_refresh >= ROBOTS_REFRESH_S:
                    last_refresh = now
                    self.refresh_robots()
                last_error = ""
            except Exception as exc:  # keep the loop alive; the panel shows job errors itself
                if str(exc) != last_error:  # once per distinct failure, not 30 times a second
                    log.exception("viewer tick failed")
                last_error = str(exc)


def _sample_count(value: Any) -> int | None:
    """``value`` as a whole number of workspace samples the viewer may ask for, else None."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    if not (np.isfinite(number) and number == int(number)
            and MIN_GUI_SAMPLES <= number <= MAX_GUI_SAMPLES):
        return None
    return int(number)


def _client_view(client: Any) -> View | None:
    """A browser's camera as ``(vertical fov rad, canvas width px, height px)``, None until
    it has reported it."""
    try:
        camera = client.camera
        view = (float(camera.fov), int(camera.image_width), int(camera.image_height))
    except (AssertionError, AttributeError, ValueError):  # viser: nothing reported yet
        return None
    return view if view[0] > 0 and view[1] > 0 and view[2] > 0 else None


def _matrix_from_wxyz(wxyz: np.ndarray) -> np.ndarray:
    import viser.transforms as vtf

    return vtf.SO3(wxyz=wxyz / np.linalg.norm(wxyz)).as_matrix()
