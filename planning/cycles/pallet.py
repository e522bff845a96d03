"""The palletizing work cycle: boxes taken at a pick station and stacked on a pallet, layer by
layer, each carried level around the boxes already placed.

Two parts:

* **Patterns** (``pallet_pattern``, pure and fast): where each box goes. A ``Pallet`` (its
  frame: the centre of its bottom face, x along its length; size e.g. EUR 1200 x 800 x
  144 mm), a ``Box`` (length, width, height, optional mass) and a pattern: ``column`` (every
  layer the same grid), ``interlocked`` (every other layer the grid of the box turned 90°,
  so the joints of one layer are covered by the boxes of the next) or an explicit list of
  place poses. A grid is the most boxes of one orientation that fit on the pallet with
  ``gap`` mm between them and at most ``overhang`` mm past each edge, centred; within a
  layer the boxes farthest from the robot's base axis come first, so the arm never reaches
  over a box it has placed at the height of that box. A box that does not fit (past the
  pallet's edge, over the stack height limit, overlapping another box, not level, or beyond
  the pallet's capacity) is reported with why (``Rejected``), never placed. Every place pose
  is the box centre's, mm, in the robot's world frame, with its yaw about the vertical.
* **Planning** (``plan_pallet``): for every box two tasks of ``planning.motion.task``,
  each timed time-optimally within the robot's limits as one trajectory at rest at both
  ends: the *carry* (``attach`` the box at the pick, a straight ``line`` up by
  ``approach_mm``, a ``move`` with the box held level: an ``axis`` path constraint keeps its
  vertical within ``tilt_tolerance`` rad, around the pallet, the obstacles and every box
  placed so far, a ``line`` down to the place from ``approach_mm`` above the boxes resting
  beside it, ``detach``: the box stays there), then the
  *return* (a ``line`` up by ``retreat_mm``, a free ``move`` above the next pick, a
  ``line`` down to it). The collision model is the exact one of the motion planner (sphere
  stage confirmed by FCL), the carried box included as a body of the robot
  (``planning.collision.Attachment``). A placed box is an obstacle of every later task.

The gripper holds the box ``grip_offset_mm`` below the tool point (the box's top face
centred on the tool axis, its x along the tool's x): a built-in robot's collision model
wraps its last link in a capsule reaching 60 mm past the tool point, which a box let go in
the scene must clear. The box is taken and let go ``clearance_mm`` above where it rests
(a box resting on the conveyor, or on the layer below, touches it, and touching is a
collision): the last few mm of the drop are not modelled. Later tasks see a placed box where
it rests.

Cycle time per box: the carry's and the return's durations plus ``dwell_s`` at the pick and
at the place (gripping, letting go); per layer and per pallet their sums; boxes per hour
over the pallet. Lengths mm, angles rad, times s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk

__all__ = ["Pallet", "Box", "Place", "Rejected", "PalletPattern", "BoxPlan", "PalletResult",
           "PATTERNS", "EUR_PALLET", "MAX_BOXES", "MAX_LAYERS", "pallet_pattern", "plan_pallet",
           "grasp_transform", "box_tilt", "tool_pose_of_box"]

#: The patterns by name (an explicit list of place poses is the third way).
PATTERNS = ("column", "interlocked")
#: A EUR pallet (EPAL 1): 1200 x 800 mm, 144 mm high.
EUR_PALLET = (1200.0, 800.0, 144.0)
#: Most boxes of one pallet (a pattern or a list asking for more is refused naming it).
MAX_BOXES = 2000
#: Most layers of one pallet.
MAX_LAYERS = 100
#: A box is level when its vertical is within this angle of the world's (rad).
LEVEL_TOLERANCE = 1e-6
#: Slack of the fit checks (mm).
_FIT_EPS = 1e-6


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pose(position: Sequence[float], yaw: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = _rot_z(yaw)
    T[:3, 3] = position
    return T


def _positive3(value: Any, loc: tuple, what: str) -> tuple[float, float, float]:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise FieldError(loc, f"{what} must be three positive numbers (mm)")
    return float(v[0]), float(v[1]), float(v[2])


def _rigid(value: Any, loc: tuple) -> np.ndarray:
    T = np.asarray(value, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise FieldError(loc, "must be a 4x4 pose (mm)")
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0 \
            or np.abs(T[3] - [0, 0, 0, 1]).max() > 1e-9:
        raise FieldError(loc, "must be a rigid 4x4 pose (a rotation and a translation, mm)")
    return T.copy()


@dataclass(frozen=True, eq=False)
class Pallet:
    """A pallet: ``size`` (length along its x, width along its y, height; mm), ``pose``
    (T_world_pallet: the centre of its bottom face; its z must be vertical), ``overhang``
    (mm a box may stand out past each edge) and ``max_height`` (mm of boxes above its top,
    None: no limit)."""

    size: tuple[float, float, float] = EUR_PALLET
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    overhang: float = 0.0
    max_height: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _positive3(self.size, ("pallet", "size"), "size"))
        T = _rigid(self.pose, ("pallet", "pose"))
        if abs(T[2, 2] - 1.0) > LEVEL_TOLERANCE:
            raise FieldError(("pallet", "pose"), "the pallet must lie flat: its z axis "
                             "vertical")
        object.__setattr__(self, "pose", T)
        if not (math.isfinite(self.overhang) and self.overhang >= 0):
            raise FieldError(("pallet", "overhang"), "overhang must be a number >= 0 (mm)")
        if self.max_height is not None and not (math.isfinite(self.max_height)
                                                and self.max_height > 0):
            raise FieldError(("pallet", "max_height"), "max_height must be > 0 (mm) or null")

    @property
    def yaw(self) -> float:
        """The pallet's turn about the vertical (rad)."""
        return math.atan2(self.pose[1, 0], self.pose[0, 0])

    @property
    def top(self) -> float:
        """The height of its top face in the world (mm)."""
        return float(self.pose[2, 3] + self.size[2])

    def object(self) -> dict[str, Any]:
        """The pallet as a scene object (a box, id ``pallet``)."""
        T = self.pose.copy()
        T[:3, 3] += T[:3, 2] * self.size[2] / 2
        return {"type": "box", "id": "pallet", "size": list(self.size), "pose": T.tolist()}


@dataclass(frozen=True)
class Box:
    """A box: ``size`` (length, width, height, mm) and ``mass`` (kg, optional: reported)."""

    size: tuple[float, float, float]
    mass: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _positive3(self.size, ("box", "size"), "size"))
        if self.mass is not None and not (math.isfinite(self.mass) and self.mass >= 0):
            raise FieldError(("box", "mass"), "mass must be a number >= 0 (kg) or null")


@dataclass(frozen=True)
class Place:
    """Where box ``index`` goes: ``layer`` (0: on the pallet), ``position`` (its centre,
    world, mm) and ``yaw`` (its x axis's turn about the vertical, rad)."""

    index: int
    layer: int
    position: tuple[float, float, float]
    yaw: float

    def pose(self) -> np.ndarray:
        """T_world_box (4x4): the box centre's pose where it rests."""
        return _pose(self.position, self.yaw)


@dataclass(frozen=True)
class Rejected:
    """A box that is not placed: its ``index``, its ``layer`` (None when it has none) and
    ``reason``; ``position``/``yaw`` where it was asked to go (None for a pattern's box
    beyond the pallet's capacity)."""

    index: int
    layer: int | None
    reason: str
    position: tuple[float, float, float] | None = None
    yaw: float | None = None


@dataclass
class PalletPattern:
    """The place poses of a pallet (module docstring): ``places`` in placing order,
    ``rejected`` the boxes that do not fit, ``per_layer`` the boxes of each layer."""

    places: list[Place]
    rejected: list[Rejected]
    per_layer: list[int]
    pattern: str


# ---- patterns ----------------------------------------------------------------------------
def _grid(length: float, width: float, a: float, b: float, gap: float,
          overhang: float) -> list[tuple[float, float]]:
    """Centres (pallet frame, x, y) of the largest grid of ``a x b`` footprints on a
    ``length x width`` pallet, ``gap`` between them, at most ``overhang`` past each edge."""
    nx = int(math.floor((length + 2 * overhang + gap + _FIT_EPS) / (a + gap)))
    ny = int(math.floor((width + 2 * overhang + gap + _FIT_EPS) / (b + gap)))
    xs = (np.arange(nx) - (nx - 1) / 2) * (a + gap)
    ys = (np.arange(ny) - (ny - 1) / 2) * (b + gap)
    return [(float(x), float(y)) for x in xs for y in ys]


def _footprint(x: float, y: float, a: float, b: float, yaw: float) -> np.ndarray:
    """The 4 corners ``(4, 2)`` of an ``a x b`` rectangle centred at (x, y) turned by yaw."""
    c, s = math.cos(yaw), math.sin(yaw)
    half = np.array([[a, b], [-a, b], [-a, -b], [a, -b]]) / 2
    return np.array([x, y]) + half @ np.array([[c, s], [-s, c]])


def _overlap_2d(P: np.ndarray, Q: np.ndarray) -> bool:
    """Whether two convex polygons ``(4, 2)`` overlap with positive area (separating axes)."""
    for poly in (P, Q):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([-edges[:, 1], edges[:, 0]], axis=1)
        for n in normals:
            p, q = P @ n, Q @ n
            if p.max() <= q.min() + _FIT_EPS * np.linalg.norm(n) \
                    or q.max() <= p.min() + _FIT_EPS * np.linalg.norm(n):
                return False
    return True


def _fit_reason(pallet: Pallet, box: Box, T: np.ndarray, placed: list[tuple[np.ndarray,
                float, float, int]]) -> str | None:
    """Why a box with centre pose ``T`` (world) does not fit, None when it does. ``placed``:
    ``(footprint, z_low, z_high, index)`` of the boxes that fit before it."""
    a, b, h = box.size
    L, W, _ = pallet.size
    if abs(T[2, 2] - 1.0) > LEVEL_TOLERANCE:
        return "not level: a box is placed with its z axis vertical"
    P = np.linalg.inv(pallet.pose) @ T
    yaw = math.atan2(P[1, 0], P[0, 0])
    corners = _footprint(P[0, 3], P[1, 3], a, b, yaw)
    past = max(float(np.abs(corners[:, 0]).max() - L / 2),
               float(np.abs(corners[:, 1]).max() - W / 2))
    if past > pallet.overhang + _FIT_EPS:
        return (f"off the pallet: it reaches {past:.1f} mm past the pallet's edge "
                f"(overhang allowed: {pallet.overhang:g} mm)")
    bottom = P[2, 3] - h / 2 - pallet.size[2]
    if bottom < -_FIT_EPS:
        return f"below the pallet's top by {-bottom:.1f} mm"
    top = bottom + h
    if pallet.max_height is not None and top > pallet.max_height + _FIT_EPS:
        return (f"over the stack height limit: its top would be {top:.1f} mm above the "
                f"pallet (limit {pallet.max_height:g} mm)")
    for other, lo, hi, j in placed:
        if bottom < hi - _FIT_EPS and top > lo + _FIT_EPS and _overlap_2d(corners, other):
            return f"overlaps box {j}"
    return None


def _layer_order(places: list[tuple[float, float, float, float]], base: np.ndarray
                 ) -> list[tuple[float, float, float, float]]:
    """A layer's boxes (world x, y, z, yaw), the farthest from the robot's base axis first
    (then by angle about it, so the arm sweeps across the row)."""
    key = [(-round(math.hypot(x - base[0], y - base[1]), 3),
            math.atan2(y - base[1], x - base[0])) for x, y, _, _ in places]
    return [p for _, p in sorted(zip(key, places), key=lambda kv: kv[0])]


def pallet_pattern(pallet: Pallet, box: Box, pattern: str | Sequence[Any] = "column", *,
                   layers: int = 1, count: int | None = None, gap: float = 5.0,
                   robot_base: Sequence[float] = (0.0, 0.0)) -> PalletPattern:
    """Where each box goes (module docstring). ``pattern``: ``column``, ``interlocked``, or
    a list of place poses (each T_world_box 4x4 of the box centre, or ``[x, y, z, yaw]``,
    world, mm and rad; ``layers`` is then ignored and the layer is the box's height rank).
    ``count``: how many boxes (default: every place of ``layers`` layers; more than fit are
    rejected, "the pallet is full"); ``gap`` (mm) between the boxes of a grid;
    ``robot_base`` (world x, y): the axis the order of a layer is measured from.
    ``FieldError`` naming the argument for bad input."""
    if isinstance(layers, bool) or not isinstance(layers, int) or not 1 <= layers <= MAX_LAYERS:
        raise FieldError(("layers",), f"layers must be an integer in [1, {MAX_LAYERS}]")
    if count is not None and (isinstance(count, bool) or not isinstance(count, int)
                              or not 1 <= count <= MAX_BOXES):
        raise FieldError(("count",), f"count must be an integer in [1, {MAX_BOXES}] or null")
    if not (math.isfinite(gap) and 0 <= gap <= 1000):
        raise FieldError(("gap",), "gap must be a number in [0, 1000] (mm)")
    base = np.asarray(robot_base, dtype=float)
    a, b, h = box.size
    L, W, H = pallet.size
    yaw0 = pallet.yaw
    if not isinstance(pattern, str):
        return _explicit(pallet, box, pattern)
    if pattern not in PATTERNS:
        raise FieldError(("pattern",), f"pattern must be one of {', '.join(PATTERNS)} or a "
                         "list of place poses")
    along = _grid(L, W, a, b, gap, pallet.overhang)        # box x along the pallet's x
    across = _grid(L, W, b, a, gap, pallet.overhang)       # turned 90°
    first, second = (along, 0.0), (across, math.pi / 2)
    if len(across) > len(along):
        first, second = second, first
    if not first[0]:
        reason = (f"the box ({a:g} x {b:g} mm) does not fit on the pallet ({L:g} x {W:g} mm, "
                  f"overhang {pallet.overhang:g} mm) in either orientation")
        n = count if count is not None else 1
        return PalletPattern([], [Rejected(i, None, reason) for i in range(n)], [], pattern)
    places: list[Place] = []
    rejected: list[Rejected] = []
    per_layer: list[int] = []
    want = count if count is not None else math.inf
    index = 0
    for k in range(layers):
        grid, turn = first if (pattern == "column" or k % 2 == 0 or not second[0]) else second
        z = H + k * h + h / 2
        world = []
        for x, y in grid:
            p = pallet.pose @ np.array([x, y, z, 1.0])
            world.append((float(p[0]), float(p[1]), float(p[2]),
                          math.remainder(yaw0 + turn, 2 * math.pi)))
        top = (k + 1) * h
        over = pallet.max_height is not None and top > pallet.max_height + _FIT_EPS
        n_layer = 0
        for x, y, zz, yaw in _layer_order(world, base):
            if index >= want:
                break
            if index >= MAX_BOXES:
                raise FieldError(("count",), f"the pattern places more than {MAX_BOXES} "
                                 "boxes: give count or fewer layers")
            if over:
                rejected.append(Rejected(index, k, f"over the stack height limit: layer {k} "
                                         f"reaches {top:g} mm above the pallet (limit "
                                         f"{pallet.max_height:g} mm)", (x, y, zz), yaw))
            else:
                places.append(Place(index, k, (x, y, zz), yaw))
                n_layer += 1
            index += 1
        per_layer.append(n_layer)
        if index >= want:
            break
    if count is not None and index < count:
        capacity = len(places) + len(rejected)
        for i in range(index, count):
            rejected.append(Rejected(i, None, f"the pallet is full: {capacity} places in "
                                     f"{layers} layer(s) of this pattern"))
    return PalletPattern(places, rejected, per_layer, pattern)


def _explicit(pallet: Pallet, box: Box, poses: Sequence[Any]) -> PalletPattern:
    """An explicit list of place poses checked one by one, in order."""
    if isinstance(poses, str | bytes) or not isinstance(poses, Sequence) or not poses:
        raise FieldError(("pattern",), "must be a non-empty list of place poses")
    if len(poses) > MAX_BOXES:
        raise FieldError(("pattern",), f"at most {MAX_BOXES} place poses")
    Ts = []
    for i, p in enumerate(poses):
        arr = np.asarray(p, dtype=float) if not isinstance(p, np.ndarray) else p
        if arr.shape == (4,):
            if not np.all(np.isfinite(arr)):
                raise FieldError(("pattern", i), "must be finite")
            Ts.append(_pose(arr[:3], float(arr[3])))
        else:
            Ts.append(_rigid(arr, ("pattern", i)))
    h = box.size[2]
    places: list[Place] = []
    rejected: list[Rejected] = []
    kept: list[tuple[np.ndarray, float, float, int]] = []
    inv = np.linalg.inv(pallet.pose)
    for i, T in enumerate(Ts):
        P = inv @ T
        layer = int(round((P[2, 3] - h / 2 - pallet.size[2]) / h))
        yaw = math.atan2(T[1, 0], T[0, 0])
        pos = (float(T[0, 3]), float(T[1, 3]), float(T[2, 3]))
        why = _fit_reason(pallet, box, T, kept)
        if why is not None:
            rejected.append(Rejected(i, max(layer, 0), why, pos, yaw))
            continue
        py = math.atan2(P[1, 0], P[0, 0])
        bottom = P[2, 3] - h / 2 - pallet.size[2]
        kept.append((_footprint(P[0, 3], P[1, 3], box.size[0], box.size[1], py),
                     bottom, bottom + h, i))
        places.append(Place(i, max(layer, 0), pos, yaw))
    n_layers = max((p.layer for p in places), default=-1) + 1
    per_layer = [sum(1 for p in places if p.layer == k) for k in range(n_layers)]
    return PalletPattern(places, rejected, per_layer, "explicit")


# ---- the grasp -----------------------------------------------------------------------------
def grasp_transform(box: Box, grip_offset: float) -> np.ndarray:
    """T_tool_box of a box held from above: its top face ``grip_offset`` mm along the tool's
    z axis (pointing down into the box), its x along the tool's x, its z against the
    tool's (a half turn about x)."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[2, 3] = grip_offset + box.size[2] / 2
    return T


def tool_pose_of_box(T_world_box: np.ndarray, T_tool_box: np.ndarray) -> np.ndarray:
    """T_world_tool that holds a box at ``T_world_box``."""
    return T_world_box @ np.linalg.inv(T_tool_box)


def box_tilt(model: Any, Q: np.ndarray) -> np.ndarray:
    """``(N,)`` the tilt (rad) of a box held as ``grasp_transform`` holds it, at the
    configurations ``Q (N, dof)``: the angle of the tool's z axis from the world's -z."""
    T = fk(model, np.atleast_2d(Q))
    return np.arccos(np.clip(-T[:, 2, 2], -1.0, 1.0))


# ---- planning ------------------------------------------------------------------------------
@dataclass
class BoxPlan:
    """One box's outcome: ``status`` ``placed``, ``not_fitting`` (the pattern rejected it),
    ``not_planned`` (the robot could not get back to the pick before it) or the status of
    the task step that failed (``collision``, ``timeout``, ``unreachable``, ...) with
    ``reason``. ``place``: where it was to go; ``placed_pose``: T_world_box where it rests
    (FK of ``q_place``); ``carry``/``back``: the two ``TaskResult``s (the carry's last
    attempt: ``attempts``, 1 or 2); durations (s) of their trajectories; ``tilt``: the
    largest tilt of the box along the carry's states (rad)."""

    index: int
    layer: int | None
    status: str
    reason: str = ""
    place: Place | None = None
    position: tuple[float, float, float] | None = None
    yaw: float | None = None
    q_pick: np.ndarray | None = None
    q_place: np.ndarray | None = None
    placed_pose: np.ndarray | None = None
    carry: Any = None
    back: Any = None
    carry_s: float = 0.0
    return_s: float = 0.0
    cycle_s: float = 0.0
    tilt: float | None = None
    planning_time_s: float = 0.0
    attempts: int = 0

    @property
    def placed(self) -> bool:
        return self.status == "placed"

    def summary(self) -> dict[str, Any]:
        """JSON-ready, without the paths."""
        pose = None if self.placed_pose is None else np.round(self.placed_pose, 9).tolist()
        return {"index": self.index, "layer": self.layer, "status": self.status,
                "reason": self.reason,
                "position": None if self.position is None else list(self.position),
                "yaw": self.yaw, "placed_pose": pose,
                "q_pick": None if self.q_pick is None else self.q_pick.tolist(),
                "q_place": None if self.q_place is None else self.q_place.tolist(),
                "carry_s": self.carry_s, "return_s": self.return_s, "cycle_s": self.cycle_s,
                "tilt": self.tilt, "planning_time_s": self.planning_time_s,
                "attempts": self.attempts,
                "carry_states": 0 if self.carry is None else len(self.carry.path),
                "return_states": 0 if self.back is None else len(self.back.path)}


@dataclass
class PalletResult:
    """A planned pallet: ``boxes`` (one ``BoxPlan`` per box, by index), the ``pattern``,
    ``layer_s`` (the cycle time of each layer's placed boxes), ``pallet_s`` (all of them),
    ``boxes_per_hour`` (placed boxes per hour of ``pallet_s``), ``start`` (the first pick's
    configuration) and the planning time."""

    boxes: list[BoxPlan]
    pattern: PalletPattern
    layer_s: list[float]
    pallet_s: float
    boxes_per_hour: float
    start: np.ndarray | None
    planning_time_s: float
    T_tool_box: np.ndarray
    tilt_tolerance: float
    mass: float | None = None

    @property
    def placed(self) -> int:
        return sum(b.placed for b in self.boxes)

    @property
    def success(self) -> bool:
        return bool(self.boxes) and all(b.placed for b in self.boxes)


def _nearest_free_ik(model: Any, T: np.ndarray, q_near: np.ndarray, checker: Any
                     ) -> tuple[np.ndarray | None, str]:
    """The IK solution of ``T`` within the limits nearest ``q_near`` whose state is free in
    ``checker`` (None and why when there is none)."""
    from kinematics.ik import solve_ik

    r = solve_ik(model, T, q0=q_near, all_solutions=True)[0]
    if r.q is None or not len(r.solutions):
        return None, f"unreachable: {r.message}"
    S = np.asarray(r.solutions, dtype=float)
    ok = checker.within_limits(S)
    S = S[ok]
    if not len(S):
        return None, "out_of_limits: no IK solution within the joint limits"
    S = S[np.argsort(np.abs((S - q_near) * checker.weights).max(axis=1)
                     + 0.1 * np.linalg.norm(S - q_near, axis=1))]
    free = checker.free(S)
    if not np.any(free):
        pairs = ", ".join(f"{a}-{b}" for a, b in checker.pairs(S[0]))
        return None, f"collision: every IK solution collides ({pairs})"
    return S[int(np.argmax(free))].copy(), ""


def _over_neighbours(resting: list[dict], release: np.ndarray, size: tuple) -> float:
    """How far (mm) a box let go at ``release`` (T_world_box) must come down from above the
    boxes resting beside it: the top of the highest one whose footprint may touch its own
    (bounding circles within 50 mm), less the bottom of the box there (0 when none)."""
    reach = 0.5 * math.hypot(size[0], size[1])
    bottom = release[2, 3] - size[2] / 2
    need = 0.0
    for o in resting:
        T = np.asarray(o["pose"])
        s = o["size"]
        if np.linalg.norm(T[:2, 3] - release[:2, 3]) <= reach + 0.5 * math.hypot(s[0], s[1]) \
                + 50.0:
            need = max(need, T[2, 3] + s[2] / 2 - bottom)
    return need


def plan_pallet(model: Any, pick: Any, box: Box, pallet: Pallet,
                pattern: str | Sequence[Any] = "column", *, layers: int = 1,
                count: int | None = None, gap: float = 5.0, approach_mm: float = 150.0,
                retreat_mm: float = 150.0, tilt_tolerance: float = 0.05,
                grip_offset_mm: float = 65.0, clearance_mm: float = 5.0,
                dwell_s: float = 0.0, margin_mm: float = 0.0,
                obstacles: Sequence[dict] = (),
                collision_model: Any = None, start: Any = None, time_limit: float = 10.0,
                resolution: float | None = None, seed: int = 0,
                progress: Callable[[float, str], Any] | None = None) -> PalletResult:
    """Plan the pallet (module docstring). ``model``: the robot's ``RobotModel``; ``pick``:
    T_world_box of the box at the pick station (4x4, its centre where it rests), or a list
    of them used in turn; ``box``, ``pallet``, ``pattern``, ``layers``, ``count``, ``gap``:
    as ``pallet_pattern``; ``approach_mm``: the straight lift at the pick and the straight
    descent to the place (carrying), the descent starting ``approach_mm`` above the boxes
    resting beside the place (so the box comes down into its slot on a line);
    ``retreat_mm``: the straight rise after letting go and the descent at the next pick
    (empty); ``tilt_tolerance`` (rad, > 0): the box's vertical within it along the
    carry; ``grip_offset_mm``, ``clearance_mm``, ``dwell_s``: module docstring;
    ``margin_mm``: closer than this to anything counts as a collision (below ``gap`` and
    ``clearance_mm``, which a box comes that close to as it is let go);
    ``obstacles``: scene objects (the ``POST /scenes`` format) besides the pallet;
    ``collision_model``: the robot's (default ``RobotCollisionModel.from_model``);
    ``start``: the robot's configuration before the first box (default: at the first pick;
    the move from ``start`` to it is planned, not counted in any box's cycle);
    ``time_limit``: s of planning per task (a carry or a return); ``progress(fraction,
    message)`` after each box (may raise to stop). ``FieldError`` naming the argument."""
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion.checker import DEFAULT_RESOLUTION, MotionChecker
    from planning.motion.task import plan_task

    t0 = time.perf_counter()
    for name, v, lo, hi in (("approach_mm", approach_mm, 0.0, 5000.0),
                            ("retreat_mm", retreat_mm, 0.0, 5000.0),
                            ("grip_offset_mm", grip_offset_mm, 0.0, 5000.0),
                            ("clearance_mm", clearance_mm, 0.0, 1000.0),
                            ("dwell_s", dwell_s, 0.0, 3600.0),
                            ("margin_mm", margin_mm, 0.0, 1000.0)):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or not lo <= v <= hi:
            raise FieldError((name,), f"{name} must be a number in [{lo:g}, {hi:g}]")
    if not (isinstance(tilt_tolerance, int | float) and math.isfinite(tilt_tolerance)
            and 0 < tilt_tolerance < math.pi):
        raise FieldError(("tilt_tolerance",), "tilt_tolerance must be in (0, pi) rad")
    resolution = DEFAULT_RESOLUTION if resolution is None else float(resolution)
    picks = [_rigid(pick, ("pick",))] if np.asarray(pick).shape == (4, 4) else \
        [_rigid(p, ("pick", i)) for i, p in enumerate(pick)]
    if not picks:
        raise FieldError(("pick",), "give at least one pick pose")
    for i, P in enumerate(picks):
        if abs(P[2, 2] - 1.0) > LEVEL_TOLERANCE:
            raise FieldError(("pick",) if len(picks) == 1 else ("pick", i),
                             "the box at the pick must be level (its z axis vertical)")
    plan = pallet_pattern(pallet, box, pattern, layers=layers, count=count, gap=gap,
                          robot_base=model.base[:2, 3] if hasattr(model, "base") else (0, 0))
    cm = collision_model if collision_model is not None else \
        RobotCollisionModel.from_model(model)
    G = grasp_transform(box, grip_offset_mm)
    up = np.array([0.0, 0.0, 1.0])

    def lifted(T: np.ndarray, mm: float) -> np.ndarray:
        out = T.copy()
        out[:3, 3] += up * mm
        return out

    fixed = [pallet.object(), *[dict(o) for o in obstacles]]
    resting: list[dict] = []           # the placed boxes, where they rest

    def scene() -> Any:
        return CollisionScene.from_request({"objects": [*fixed, *resting]})

    def checker_of(carrying: bool, sc: Any) -> MotionChecker:
        m = cm
        if carrying:
            from planning.collision import Attachment

            m = cm.with_attached([Attachment.make(
                {"type": "box", "id": "carried", "size": list(box.size)}, pose=G)])
        return MotionChecker(m, sc, margin=float(margin_mm))

    constraint = {"type": "axis", "axis": [0.0, 0.0, 1.0], "direction": [0.0, 0.0, -1.0],
                  "tolerance": float(tilt_tolerance)}
    line = {"type": "line", "orientation": "hold"}
    by_index: dict[int, BoxPlan] = {r.index: BoxPlan(r.index, r.layer, "not_fitting",
                                                     r.reason, None, r.position, r.yaw)
                                    for r in plan.rejected}
    places = plan.places
    n = len(places)
    empty_checker = checker_of(False, scene())
    first_pick_tool = tool_pose_of_box(lifted(picks[0], clearance_mm), G)
    q_ref = (np.asarray(start, dtype=float) if start is not None
             else 0.5 * (empty_checker.lower + empty_checker.upper))
    if start is not None and q_ref.shape != (model.dof,):
        raise FieldError(("start",), f"start must have {model.dof} joint values")
    q_first, why = _nearest_free_ik(model, first_pick_tool, q_ref, empty_checker)
    q = q_first
    stuck = None if q_first is not None else f"the first pick: {why}"
    start_q = q_first if start is None else q_ref
    if start is not None and q_first is not None:
        # From the given start to the first pick: a return-like task, not counted per box.
        pre = plan_task(empty_checker, q_ref, [
            {"type": "move", "goal": {"q": (q_first + 0).tolist()}}],
            model=model, time_limit=time_limit, resolution=resolution, seed=seed,
            trajectory=False)
        if not pre.success:
            stuck = f"from start to the first pick: {pre.message}"
    for k, place in enumerate(places):
        tb = time.perf_counter()
        pick_T = picks[place.index % len(picks)]
        bp = BoxPlan(place.index, place.layer, "not_planned", place=place,
                     position=place.position, yaw=place.yaw)
        by_index[place.index] = bp
        if stuck is not None:
            bp.reason = stuck
            continue
        sc = scene()
        carrying = checker_of(True, sc)
        bp.q_pick = q.copy()
        T_pick_tool = fk(model, q)
        release = lifted(place.pose(), clearance_mm)
        T_place_tool = tool_pose_of_box(release, G)
        T_above = lifted(T_place_tool, approach_mm + _over_neighbours(resting, release,
                                                                      box.size))
        q_above, why = _nearest_free_ik(model, T_above, q, carrying)
        if q_above is None:
            bp.status, bp.reason = why.split(":", 1)[0], f"above the place: {why}"
        else:
            # First the lift of approach_mm; should the carry fail, once more with the box
            # lifted clear of the stack as it stands (an open space to turn in above it).
            bottom = T_pick_tool[2, 3] - (G[2, 3] + box.size[2] / 2) * -T_pick_tool[2, 2]
            tops = [np.asarray(o["pose"])[2, 3] + o["size"][2] / 2 for o in resting]
            lifts = [approach_mm]
            if tops and max(tops) + approach_mm - bottom > approach_mm + 1.0:
                lifts.append(max(tops) + approach_mm - bottom)
            else:
                lifts.append(approach_mm)
            for attempt, lift in enumerate(lifts):
                steps = [{"type": "attach",
                          "object": {"type": "box", "id": f"box{place.index}",
                                     "size": list(box.size)}, "pose": G.tolist()},
                         {**line, "target": lifted(T_pick_tool, lift)[:3, 3].tolist()},
                         {"type": "move", "goal": {"q": q_above.tolist()},
                          "constraints": [constraint]},
                         {**line, "target": T_place_tool.tolist()},
                         {"type": "detach", "object": f"box{place.index}"}]
                carry = plan_task(checker_of(False, sc), q, steps, model=model,
                                  time_limit=time_limit, resolution=resolution,
                                  seed=seed + place.index + 104729 * attempt)
                if carry.success:
                    break
            bp.carry = carry
            bp.attempts = attempt + 1
            if not carry.success:
                bp.status, bp.reason = carry.status, f"carry: {carry.message}"
            else:
                bp.q_place = carry.path[-1].copy()
                bp.placed_pose = lifted(fk(model, bp.q_place) @ G, -clearance_mm)
                bp.carry_s = float(carry.trajectory.duration) if carry.trajectory else 0.0
                bp.tilt = float(box_tilt(model, carry.path).max())
                resting.append({"type": "box", "id": f"box{place.index}",
                                "size": list(box.size), "pose": bp.placed_pose.tolist()})
                q = bp.q_place
                bp.status, bp.reason = "placed", ""
        # Back to the next pick (the box's own, when it was not carried away).
        nxt = picks[places[k + 1].index % len(picks)] if k + 1 < n else pick_T
        T_next = tool_pose_of_box(lifted(nxt, clearance_mm), G)
        back_checker = checker_of(False, scene())
        q_next_above, why = _nearest_free_ik(model, lifted(T_next, retreat_mm), q,
                                             back_checker)
        if q_next_above is None:
            stuck = f"box {place.index}'s return to the pick: {why}"
        else:
            T_here = fk(model, q)
            back = plan_task(back_checker, q, [
                {**line, "target": lifted(T_here, retreat_mm)[:3, 3].tolist()},
                {"type": "move", "goal": {"q": q_next_above.tolist()}},
                {**line, "target": T_next.tolist()}],
                model=model, time_limit=time_limit, resolution=resolution,
                seed=seed + 7919 + place.index)
            bp.back = back
            if back.success:
                bp.return_s = float(back.trajectory.duration) if back.trajectory else 0.0
                q = back.path[-1].copy()
            else:
                stuck = f"box {place.index}'s return to the pick: {back.message}"
                if bp.placed:
                    bp.reason = f"placed, but the return failed: {back.message}"
        if bp.placed:
            bp.cycle_s = bp.carry_s + bp.return_s + 2 * dwell_s
        bp.planning_time_s = time.perf_counter() - tb
        if progress is not None:
            progress((k + 1) / n, f"box {k + 1} of {n}: {bp.status}")
    boxes = [by_index[i] for i in sorted(by_index)]
    n_layers = max([b.layer for b in boxes if b.layer is not None], default=-1) + 1
    layer_s = [sum(b.cycle_s for b in boxes if b.layer == j and b.placed)
               for j in range(n_layers)]
    total = float(sum(layer_s))
    placed = sum(b.placed for b in boxes)
    mass = None if box.mass is None else box.mass * placed
    return PalletResult(boxes, plan, layer_s, total,
                        3600.0 * placed / total if total > 0 else 0.0, start_q,
                        time.perf_counter() - t0, G, float(tilt_tolerance), mass)
