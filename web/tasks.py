"""What a task plan does, for playback: when each step runs, what it holds, and the loads the
robot carries (``planning.motion.task``: steps ``move``, ``line``, ``arc``, ``attach``,
``detach``).

A motion job's result gives each step's states in the task's joint path (``states: [first,
last]``); the arm plays the trajectory sampled from that path (corners blended), or the path
itself at a constant joint speed. ``state_times`` finds when the played motion passes each
state of the path, so each step gets a time span and each ``attach``/``detach`` a moment.

A carried load (``Load``) is drawn under ``<plan root>/loads/<id>``: a frame at the world pose
of the link that holds it, and the object's shape in that frame at ``T_link_object`` (the
attach step's ``pose`` composed with the object's own ``pose``, as
``planning.collision.Attachment`` composes them). So the load's world pose is always
``T_world_link @ T_link_object``, with the link frame taken

* before the attach: at the configuration where the attach step takes it (its pick pose: the
  attach step gives the load's pose relative to the link, so where it is picked is where the
  link is at that step);
* between attach and detach: at the arm's configuration at that moment (it rides on the link);
* after a detach with ``place``: at the configuration where the detach step lets go (it stays
  there, a scene object from then on); a detach with ``place: false`` hides it.

An attach step that did not end ``ok`` took nothing: the load stays at its pick pose. When the
same id is taken again later, each attach starts a ``Load`` of its own; the earlier one's
placed copy is shown until the later attach takes it.

Pure data and geometry here; ``LoadNodes`` makes and moves the viser nodes (the viewer calls it
under its lock). Lengths mm, times s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.model import RobotModel

from .meshes import node_safe
from .scene import MM_TO_M, wxyz_from_matrix
from .site import draw_site, object_bounds_mm
from .text import code, plain

__all__ = ["LOAD_COLOR", "SEGMENT_COLOR", "TOOL", "Load", "StepSpan", "TaskTrack",
           "LoadNodes", "state_times", "link_frame", "task_track", "step_tool_paths",
           "check_links"]

#: Colour of carried loads (cardboard).
LOAD_COLOR = (196, 150, 90)
#: Colour of the tool path of line and arc steps.
SEGMENT_COLOR = (200, 40, 200)
#: The link name that means the robot's last link (``planning.collision.attached.TOOL``).
TOOL = "tool"
#: Two positions along the played motion closer (weighted joint metric: rad, and mm /
#: ``PRISMATIC_SCALE``) than this to a state count as equally near: the earlier is taken, so a
#: state the arm passes twice (down a line and back up it) is matched in order.
TIE = 1e-3
#: How far along the played motion the next state is looked for: this many times the path's
#: step to it, plus ``AHEAD_MARGIN`` (same metric) and two samples. Blended corners make the
#: motion shorter than the path, never longer; a longer look could reach the same state met
#: again later (a line down and back up to where the move before it ended).
AHEAD = 1.1
AHEAD_MARGIN = 0.05


# ---- timing --------------------------------------------------------------------------------
def state_times(path: np.ndarray, t: np.ndarray, q: np.ndarray, weights: np.ndarray
                ) -> np.ndarray:
    """When the motion sampled at ``t (n,)``, ``q (n, dof)`` (linear between samples) passes
    each state of ``path (K, dof)``, in order: ``(K,)`` non-decreasing times.

    The states are matched one after the other, each to the nearest point of the sampled
    motion (in the weighted joint metric ``weights (dof,)``) at or after the previous state's
    point, looking ahead about as far along the motion as the path goes to the state
    (``AHEAD``, ``AHEAD_MARGIN`` and two samples); of points within ``TIE`` of the nearest,
    the earliest wins. A
    motion sampled at the path's own states (no trajectory) gives their times exactly."""
    P = np.asarray(path, dtype=float) * weights
    K = len(P)
    t = np.asarray(t, dtype=float)
    Q = np.asarray(q, dtype=float) * weights
    n = len(t)
    if K == 0:
        return np.zeros(0)
    if n < 2:
        return np.full(K, float(t[0]) if n else 0.0)
    D = np.diff(Q, axis=0)                                      # (n-1, dof)
    dd = np.einsum("ij,ij->i", D, D)
    seg = np.sqrt(dd)
    L = np.concatenate([[0.0], np.cumsum(seg)])                 # motion length at samples
    steps = np.linalg.norm(np.diff(P, axis=0), axis=1)          # (K-1,) path steps
    out = np.empty(K)
    j, u = 0, 0.0
    for k in range(K):
        here = L[j] + u * seg[j]
        ahead = AHEAD * (steps[k - 1] if k else 0.0) + AHEAD_MARGIN
        hi = int(np.searchsorted(L, here + ahead, side="right")) + 2
        J = np.arange(j, min(max(hi, j + 1), n - 1))
        A, d, dj = Q[J], D[J], dd[J]
        moving = dj > 0
        uu = np.where(moving, np.einsum("ij,ij->i", P[k] - A, d) / np.where(moving, dj, 1.0),
                      0.0)
        uu = np.clip(uu, 0.0, 1.0)
        uu[0] = max(uu[0], u)                                  # never behind the last match
        dist = np.linalg.norm(A + uu[:, None] * d - P[k], axis=1)
        best = int(np.flatnonzero(dist <= dist.min() + TIE)[0])
        j, u = int(J[best]), float(uu[best])
        out[k] = t[j] + u * (t[j + 1] - t[j])
    return out


# ---- link frames ---------------------------------------------------------------------------
def link_frame(model: RobotModel, imported: Any, link: str, q: np.ndarray) -> np.ndarray:
    """World pose ``(4, 4)`` mm of the link ``link`` of ``model`` at ``q (dof,)``, as the
    collision checker places an attachment: an imported robot's URDF link (``imported``: its
    ``ImportedRobot``; ``tool`` is its tip link), a D-H / PoE robot's ``link<k>`` (the frame
    after joint ``k``; ``tool`` is the last). KeyError for a link the robot does not have."""
    q = np.asarray(q, dtype=float)
    if imported is not None:
        name = imported.tip_link if link == TOOL else link
        if name not in imported.link_names:
            raise KeyError(link)
        return imported.link_pose(name, q)
    k = model.dof - 1 if link == TOOL else _link_index(link, model.dof)
    return fk_frames(model, q)[k + 1]


def _link_index(link: str, dof: int) -> int:
    if link.startswith("link") and link[4:].isdigit() and int(link[4:]) < dof:
        return int(link[4:])
    raise KeyError(link)


# ---- what a task holds ---------------------------------------------------------------------
@dataclass(frozen=True)
class Load:
    """One carried load: ``object`` (a ``SceneObject``) whose ``pose`` is ``T_link_object``,
    riding on ``link`` from ``attach_time`` (None: the attach step failed; it is never
    carried) to ``detach_time`` (None: to the end). ``attach_q`` / ``detach_q``: the
    configurations of those steps (the pick and the place poses of the link). Shown from
    ``shown_from`` to ``shown_until`` (None: to the end)."""

    id: str
    name: str
    object: Any
    link: str
    attach_time: float | None
    attach_q: np.ndarray
    detach_time: float | None = None
    detach_q: np.ndarray | None = None
    placed: bool = True
    shown_from: float = 0.0
    shown_until: float | None = None
    #: The attach step's index in the task.
    step: int = 0

    @property
    def T_link_object(self) -> np.ndarray:
        return np.asarray(self.object.pose, dtype=float)

    def configuration(self, t: float, q: np.ndarray) -> np.ndarray | None:
        """The configuration whose link frame holds the load at time ``t`` (``q``: the arm's
        then), None when it is not shown."""
        if t < self.shown_from or (self.shown_until is not None and t > self.shown_until):
            return None
        if self.attach_time is None or t < self.attach_time:
            return self.attach_q
        if self.detach_time is not None and t >= self.detach_time:
            return self.detach_q if self.placed else None
        return np.asarray(q, dtype=float)


@dataclass(frozen=True)
class StepSpan:
    """One step as played: from ``start`` to ``end`` s; ``text`` what it does (``line, 200
    mm``), ``held`` what it keeps (``orientation ±0.1 rad``; empty: nothing)."""

    index: int
    type: str
    start: float
    end: float
    text: str
    held: str = ""


@dataclass(frozen=True)
class TaskTrack:
    """The steps of a task as played (``total``: how many the task asked for; ``spans``: the
    ones planned) and the loads it carries."""

    total: int
    spans: tuple[StepSpan, ...]
    loads: tuple[Load, ...] = field(default_factory=tuple)

    def step_at(self, t: float) -> StepSpan | None:
        """The step being played at ``t``: the last one started by then."""
        found = None
        for s in self.spans:
            if s.start <= t + 1e-9:
                found = s
        return found

    def text_at(self, t: float) -> str:
        """Markdown for the panel at time ``t``: the step played, what it holds, and the
        loads carried."""
        lines = []
        s = self.step_at(t)
        if s is not None:
            lines.append(f"**step {s.index + 1} of {self.total}**: {s.text}")
            if s.held:
                lines.append(f"held: {s.held}")
        carried = [ld for ld in self.loads if ld.attach_time is not None
                   and ld.attach_time <= t + 1e-9
                   and (ld.detach_time is None or t < ld.detach_time)]
        if carried:
            lines.append("carrying: " + ", ".join(
                f"{_shape_text(ld.object)} {code(ld.id)} on {code(ld.link)}" for ld in carried))
        return "\n\n".join(lines)


def _shape_text(o: Any) -> str:
    if o.type == "box":
        return "box " + " × ".join(f"{v:g}" for v in o.size) + " mm"
    if o.type == "sphere":
        return f"sphere r {o.radius:g} mm"
    if o.type == "cylinder":
        return f"cylinder r {o.radius:g} × {o.height:g} mm"
    if o.type == "capsule":
        return f"capsule r {o.radius:g} mm"
    if o.type == "mesh":
        return f"mesh of {len(o.faces):,} triangles"
    return plain(o.type)


def _tolerance_text(tol: Any, unit: str) -> str:
    values = [float(v) for v in (tol if isinstance(tol, list | tuple) else [tol])]
    if len(set(values)) == 1:
        return f"±{values[0]:g} {unit}"
    shown = ["free" if v >= math.pi else f"{v:g}" for v in values]
    return f"±({', '.join(shown)}) {unit}"


def _constraint_text(c: Mapping[str, Any]) -> str:
    kind = c.get("type")
    tol = c.get("tolerance")
    if kind == "axis":
        axis = c.get("axis", [0, 0, 1])
        name = {(1, 0, 0): "x", (0, 1, 0): "y", (0, 0, 1): "z"}.get(
            tuple(float(v) for v in axis), plain(str(list(axis))))
        direction = ", ".join(f"{float(v):g}" for v in c.get("direction", []))
        return f"tool {name} axis {_tolerance_text(tol, 'rad')} of [{direction}]"
    if kind == "orientation":
        return f"orientation {_tolerance_text(tol, 'rad')}"
    if kind == "position_line":
        return f"position {_tolerance_text(tol, 'mm')} of a line"
    if kind == "position_plane":
        return f"position {_tolerance_text(tol, 'mm')} of a plane"
    if kind == "joint_range":
        return "joint ranges"
    return plain(str(kind))


def _orientation_text(asked: Mapping[str, Any], tolerance: float) -> tuple[str, str]:
    """A segment's orientation: (note for the step's text, what it holds)."""
    how = asked.get("orientation", "slerp")
    target = asked.get("target")
    is_pose = isinstance(target, list) and len(target) == 4
    if how == "hold" or (how == "slerp" and asked.get("type") == "line" and not is_pose):
        return "", f"orientation (the step's start's, ±{tolerance:g} rad)"
    if how == "rotate":
        return "orientation turning with the arc", ""
    return "orientation slerped to the target's", ""


def _path_length(points: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()) if len(points) > 1 \
        else 0.0


def step_tool_paths(model: RobotModel, path: np.ndarray, steps: Sequence[Any]
                    ) -> dict[int, np.ndarray]:
    """The tool's points ``(m, 3)`` mm of every line and arc step (FK of its states), by step
    index."""
    out = {}
    for s in steps:
        if s.type in ("line", "arc"):
            first, last = s.states
            if last > first:
                out[s.index] = fk(model, path[first:last + 1])[:, :3, 3]
    return out


def task_track(model: RobotModel, asked: Sequence[Any], steps: Sequence[Any],
               path: np.ndarray, times: np.ndarray, key: str = "params.steps") -> TaskTrack:
    """The ``TaskTrack`` of a task: ``asked`` the steps of the request (dicts, as the job's
    params hold them), ``steps`` the result's (``StepOut``: ``index``, ``type``,
    ``status``, ``states``, ``planner``), ``path (K, dof)`` its joint path and ``times (K,)``
    when the played motion passes each state (``state_times``). ValueError naming the key
    for a step that is not the one asked for or states outside the path."""
    from planning.collision import Attachment
    from planning.motion.cartesian import DEFAULT_ORIENTATION_TOLERANCE

    K = len(path)
    tools = step_tool_paths(model, path, [s for s in steps if _states_ok(s, K)])
    spans, loads = [], []
    open_loads: dict[str, int] = {}
    for s in steps:
        i = s.index
        if not 0 <= i < len(asked) or not isinstance(asked[i], Mapping) \
                or asked[i].get("type") != s.type:
            raise ValueError(f"result.steps.{i}: a {s.type} step, which is not "
                             f"{key}.{i}")
        if not _states_ok(s, K):
            raise ValueError(f"result.steps.{i}.states: {list(s.states)} is not within the "
                             f"path's {K} states")
        a = asked[i]
        first, last = s.states
        start, end = float(times[first]), float(times[last])
        held = ""
        if s.type == "move":
            text = f"move ({plain(s.planner)})"
            if a.get("constraints"):
                held = "; ".join(_constraint_text(c) for c in a["constraints"]
                                 if isinstance(c, Mapping))
        elif s.type in ("line", "arc"):
            note, held = _orientation_text(a, DEFAULT_ORIENTATION_TOLERANCE)
            length = _path_length(tools.get(i, np.zeros((0, 3))))
            text = f"{s.type}, {length:,.0f} mm" + (f", {note}" if note else "")
        elif s.type == "attach":
            data = {k: a[k] for k in ("object", "link", "pose", "touch_links") if k in a}
            try:
                att = Attachment.from_dict(data, i)
            except FieldError as exc:
                where = ".".join(str(k) for k in exc.loc[2:])
                raise ValueError(f"{key}.{i}.{where}: {exc.message}") from None
            shape = replace(att.object, pose=att.T_link_object)
            text = f"attach {_shape_text(shape)} {code(att.id)} on {code(att.link)}"
            again = open_loads.get(att.id)
            shown_from = 0.0
            if again is not None:   # taken again: the earlier copy stays until now
                loads[again] = _until(loads[again], start)
                shown_from = start
            taken = s.status == "ok"
            loads.append(Load(att.id, att.id, shape, att.link, start if taken else None,
                              np.array(path[first], dtype=float), shown_from=shown_from,
                              step=i))
            open_loads[att.id] = len(loads) - 1
        else:   # detach
            oid = a.get("object")
            place = a.get("place", True) is not False
            text = f"detach {code(str(oid))} (" + ("placed where it is" if place
                                                   else "dropped from the task") + ")"
            k = open_loads.get(oid)
            if k is not None and loads[k].attach_time is not None \
                    and loads[k].detach_time is None:
                loads[k] = _detached(loads[k], start, np.array(path[first], dtype=float),
                                     place)
        if s.status != "ok":
            text += f": **{plain(s.status.replace('_', ' '))}**"
        spans.append(StepSpan(i, s.type, start, end, text, held))
    taken: set[str] = set()
    named = tuple(_named(ld, node_safe(ld.id, taken)) for ld in loads)
    return TaskTrack(len(asked), tuple(spans), named)


def _states_ok(s: Any, K: int) -> bool:
    first, last = s.states
    return 0 <= first <= last < K


def _until(load: Load, t: float) -> Load:
    return replace(load, shown_until=t)


def _detached(load: Load, t: float, q: np.ndarray, place: bool) -> Load:
    return replace(load, detach_time=t, detach_q=q, placed=place)


def _named(load: Load, name: str) -> Load:
    return replace(load, name=name)


# ---- nodes ---------------------------------------------------------------------------------
def check_links(loads: Sequence[Load], frame: Callable[[str, np.ndarray], np.ndarray],
                key: str = "params.steps") -> None:
    """ValueError naming the attach step's ``link`` when ``frame`` (``link_frame`` of the
    robot shown) does not know it (e.g. the robot was replaced since the job ran)."""
    for ld in loads:
        try:
            frame(ld.link, ld.attach_q)
        except KeyError:
            raise ValueError(f"{key}.{ld.step}.link: the robot shown has no link "
                             f"{ld.link!r}") from None


class LoadNodes:
    """The nodes of a task's loads under ``<root>/loads``: per load a frame
    (``<root>/loads/<name>``) at its link's world pose and its shape in that frame
    (``<root>/loads/<name>/<name>``). ``frame(link, q)`` gives a link's world pose (mm).
    ``update(t, q)`` moves them. Not thread-safe by itself."""

    def __init__(self, scene: Any, root: str, loads: Sequence[Load],
                 frame: Callable[[str, np.ndarray], np.ndarray]) -> None:
        self.root = f"{root}/loads"
        self.loads = tuple(loads)
        self.frame = frame
        self.handles: dict[str, Any] = {self.root: scene.add_frame(self.root,
                                                                   show_axes=False)}
        self.frames: dict[str, Any] = {}
        #: World pose ``T_world_object`` (mm) of each load as drawn now (None: hidden).
        self.poses: dict[str, np.ndarray | None] = {}
        lows, highs = [], []
        for ld in self.loads:
            node = f"{self.root}/{ld.name}"
            site = draw_site(scene, ld.name, [_renamed(ld.object, ld.name)], LOAD_COLOR,
                             root=node)
            self.handles.update(site.handles)
            self.frames[ld.name] = site.handles[node]
            for q in (ld.attach_q, ld.detach_q):
                if q is not None:
                    found = object_bounds_mm(_posed(ld.object, frame(ld.link, q)))
                    if found is not None:
                        lows.append(found[0])
                        highs.append(found[1])
        self.bounds = (np.min(lows, axis=0), np.max(highs, axis=0)) if lows else None

    def update(self, t: float, q: np.ndarray) -> None:
        """Put every load where it is at time ``t`` (``q``: the arm's configuration then)."""
        for ld in self.loads:
            at = ld.configuration(t, q)
            h = self.frames[ld.name]
            if at is None:
                self.poses[ld.name] = None
                if h.visible:
                    h.visible = False
                continue
            T = self.frame(ld.link, at)
            self.poses[ld.name] = T @ ld.T_link_object
            h.position = T[:3, 3] * MM_TO_M
            h.wxyz = wxyz_from_matrix(T[:3, :3])
            if not h.visible:
                h.visible = True


def _renamed(o: Any, name: str) -> Any:
    """``o`` under another id (its node's name)."""
    return replace(o, id=name)


def _posed(o: Any, T_world_link: np.ndarray) -> Any:
    """``o`` (posed in its link's frame) in the world."""
    return replace(o, pose=T_world_link @ np.asarray(o.pose, dtype=float))
