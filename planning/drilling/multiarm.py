"""Whole-face planning for a multi-arm jumbo: allocation, sequencing, collision-free moves.

Paper 002, sections 3.3-3.4 and 4.2. For each arm: its holes (``allocation``), their
drilling order as an open path from the arm's parked position (``planning.sequencing``),
and a transfer between consecutive holes planned in joint space (``iapf.IAPF`` or the
``rrt.RRTConnect`` baseline) around the other arms' parked envelopes, smoothed with the
quintic B-spline of eqs. 14-18 (``planning.trajectories.bspline.quintic_bspline``) and
time-scaled to the rate limits (``planning.trajectories.time_scaling.fit_to_limits``).

A move between holes: the feed retracts the drill ``standoff`` mm from the face (rest to
rest quintic), the boom transfers with the feed keeping the tip that far in front of the
face (paper's joint 7 "compensating the distance to the face"), and the feed advances onto
the new hole. ``drill_time_s`` is spent on each hole.

Schedule (our reading of section 4.2): the middle arm, whose strip borders both others,
drills first while the side arms wait at their park poses (boom level, swung outboard); it
then stops and becomes a static obstacle, as in the paper, on its last hole, and the side
arms drill their holes at the same time. If the middle arm's last-hole pose blocks a side
arm's hole or transfer, the middle arm first returns to its home pose and parks there
(``FacePlan.middle_park`` says which). Side arms are planned against the parked middle arm;
if two side arms come too close when running at once, the later one waits for the earlier
(planned around its final pose).

Every plan is checked at the end: all arms sampled every ``check_dt`` (10 ms) on one time
axis, the signed distance between every pair of arm envelopes computed at every sample.
``FacePlan.success`` is False (``status`` says how and ``messages`` say why) if any pair's
envelopes overlap, any move failed, or a joint leaves its limits: a colliding plan is never
reported as a success.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.drilling import DRILL_D7, drill_ik
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.rigs import Rig

from ..registry import algorithm_classes, make
from ..sequencing import SequenceResult
from ..status import PlanStatus
from ..trajectories.bspline import quintic_bspline
from ..trajectories.time_scaling import fit_to_limits
from ..trajectories.trajectory import Limits, Trajectory
from .allocation import Allocation, allocate_holes, home_configuration
from .boom_time import COSTS, BoomTime, sequence_arm
from .envelopes import (
    ArmEnvelope,
    capsule_distances,
    capsules,
    drill_arm_envelope,
    min_distance,
)
from .iapf import MovePath
from .space import ArmSpace, Obstacles

__all__ = [
    "PLANNERS",
    "MotionLimits",
    "Move",
    "ArmTimeline",
    "ArmPlan",
    "FacePlan",
    "FaceOptions",
    "make_planner",
    "park_configuration",
    "plan_move",
    "smooth_path",
    "plan_face",
    "pair_distances",
]

#: Move planner name -> parameter dataclass: the ``move_planner`` family of
#: ``planning.registry`` (``iapf.IAPF``, ``rrt.RRTConnect``).
PLANNERS: dict[str, type] = algorithm_classes("move_planner")
#: Step of the final collision check, s (the brief's 10 ms).
CHECK_DT = 0.01
#: Joints whose accelerations the paper bounds (swing, pitch and the two compensation
#: joints, section 5): indices into q.
ROTATIONAL_JOINTS = (0, 1, 4, 5)
#: The paper's bound on those accelerations, rad/s^2 (abstract and section 5).
PAPER_ACCELERATION_BOUND = 0.25
ProgressFn = Callable[[float, str], None]


@dataclass(frozen=True)
class MotionLimits:
    """Rate limits of a transfer: per planned joint (swing rad/s, pitch rad/s, telescope
    mm/s and the same per s^2) and for the feed. The accelerations default to just under
    the paper's 0.25 rad/s^2; the rest are ours (no rates are printed)."""

    velocity: tuple[float, float, float] = (0.2, 0.2, 400.0)
    acceleration: tuple[float, float, float] = (0.24, 0.24, 300.0)
    feed_velocity: float = 500.0
    feed_acceleration: float = 500.0

    def limits(self) -> Limits:
        return Limits(velocity=np.array(self.velocity, dtype=float),
                      acceleration=np.array(self.acceleration, dtype=float))

    def feed_duration(self, distance: float) -> float:
        """Time of a rest-to-rest quintic over ``distance`` mm within the feed limits."""
        d = abs(distance)
        if d == 0:
            return 0.0
        # quintic blend: peak speed 15/8 d/T, peak acceleration 10/sqrt(3) d/T^2
        return max(15 / 8 * d / self.feed_velocity,
                   math.sqrt(10 / math.sqrt(3) * d / self.feed_acceleration))


def _blend(tau: np.ndarray) -> np.ndarray:
    """Rest-to-rest quintic 0 -> 1 on tau in [0, 1]."""
    tau = np.clip(tau, 0.0, 1.0)
    return tau**3 * (10 - 15 * tau + 6 * tau**2)


@dataclass(frozen=True, eq=False)
class Move:
    """One move of an arm: retract the feed by ``standoff`` mm, transfer (``traj`` over the
    planned joints, local time), advance onto the goal. Local time 0 .. ``duration``.

    ``q_start``, ``q_goal (7,)`` are the drilling (or park) configurations it joins;
    ``path`` is the planner's raw joint-space path; ``tool_path_m`` the drill tip's path on
    the face plane (m). ``status``: ``ok``, the planner's failure, or ``collision`` /
    ``out_of_limits`` when no smoothing of its path stays clear and within the limits."""

    space: ArmSpace
    q_start: np.ndarray
    q_goal: np.ndarray
    traj: Trajectory | None
    standoff: float
    t_retract: float
    t_advance: float
    path: MovePath
    status: PlanStatus
    message: str
    tool_path_m: float = 0.0
    waypoints: int = 0

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK

    @property
    def t_transfer(self) -> float:
        return 0.0 if self.traj is None else self.traj.duration

    @property
    def duration(self) -> float:
        return self.t_retract + self.t_transfer + self.t_advance

    def evaluate(self, t) -> np.ndarray:
        """Configurations at local times ``t (S,)`` s -> ``(S, 7)``."""
        t = np.asarray(t, dtype=float)
        q = np.empty((len(t), 7))
        t1 = self.t_retract
        t2 = t1 + self.t_transfer
        a = t < t1
        c = t >= t2
        b = ~a & ~c
        if a.any():
            q[a] = self.q_start
            s = _blend(t[a] / t1) if t1 > 0 else np.ones(a.sum())
            q[a, 6] = self.q_start[6] - self.standoff * s
        if b.any():
            qp = self.traj.evaluate(t[b] - t1)
            q[b] = self.space.full_q(qp, self.space.d7_face(qp, self.standoff))
        if c.any():
            q[c] = self.q_goal
            s = _blend((t[c] - t2) / self.t_advance) if self.t_advance > 0 else \
                np.ones(c.sum())
            q[c, 6] = self.q_goal[6] - self.standoff * (1 - s)
        return q


@dataclass(frozen=True, eq=False)
class ArmTimeline:
    """An arm over time: at ``q0 (7,)`` until its first move, then ``moves`` starting at
    ``starts (M,)`` s, each followed by a dwell; after the last, still."""

    q0: np.ndarray
    moves: tuple[Move, ...]
    starts: np.ndarray

    @property
    def end(self) -> float:
        if not self.moves:
            return 0.0
        return float(self.starts[-1] + self.moves[-1].duration)

    @property
    def q_final(self) -> np.ndarray:
        return self.moves[-1].q_goal if self.moves else self.q0

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray]:
        """``t (S,)`` s -> configurations ``(S, 7)`` and whether the arm moves ``(S,)``."""
        t = np.asarray(t, dtype=float)
        q = np.repeat(self.q0[None], len(t), axis=0)
        moving = np.zeros(len(t), dtype=bool)
        if not self.moves:
            return q, moving
        k = np.searchsorted(self.starts, t, side="right") - 1  # last move started
        before = k < 0
        kk = np.maximum(k, 0)
        for m in np.unique(kk[~before]):
            sel = np.flatnonzero((kk == m) & ~before)
            mv = self.moves[m]
            local = t[sel] - self.starts[m]
            inside = local <= mv.duration
            q[sel[inside]] = mv.evaluate(local[inside])
            moving[sel[inside]] = True
            q[sel[~inside]] = mv.q_goal
        return q, moving


@dataclass(frozen=True, eq=False)
class ArmPlan:
    """One arm's plan: hole indices (into the face) in drilling order, the sequencing
    result, its timeline and summary numbers."""

    name: str
    order: np.ndarray
    sequence: SequenceResult | None
    timeline: ArmTimeline
    sequence_length_m: float
    tool_path_m: float
    planner_counts: dict[str, int]


@dataclass(frozen=True, eq=False)
class FacePlan:
    """A whole face: allocation, per-arm plans, the 10 ms check (``t (S,)``, ``q[arm]
    (S, 7)``, signed envelope distance per arm pair ``min_distance["left-middle"] (S,)`` mm,
    samples with overlapping envelopes per pair ``collisions``), ``status`` and messages.
    ``status`` is that of the first failure ``messages`` lists: a move's own, ``collision``
    for overlapping envelopes, ``out_of_limits`` for a joint beyond its limits."""

    allocation: Allocation
    arms: dict[str, ArmPlan]
    t: np.ndarray
    q: dict[str, np.ndarray]
    min_distance: dict[str, np.ndarray]
    collisions: dict[str, int]
    status: PlanStatus
    messages: list[str]
    planner: str
    middle_park: str
    runtime_s: float
    accelerations: dict[str, np.ndarray]
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK

    @property
    def total_collisions(self) -> int:
        return int(sum(self.collisions.values()))

    def tool_path_m(self) -> float:
        return float(sum(a.tool_path_m for a in self.arms.values()))


# ---- one move ------------------------------------------------------------------------------
def _rdp(u: np.ndarray, tol: float) -> np.ndarray:
    """Indices of the Ramer-Douglas-Peucker simplification of the polyline ``u (K, d)``."""
    if len(u) <= 2 or tol <= 0:
        return np.arange(len(u))
    keep = np.zeros(len(u), dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, len(u) - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        a, b = u[i], u[j]
        ab = b - a
        L2 = float(ab @ ab)
        pts = u[i + 1 : j]
        if L2 == 0:
            d = np.linalg.norm(pts - a, axis=1)
        else:
            s = np.clip((pts - a) @ ab / L2, 0, 1)
            d = np.linalg.norm(pts - (a + s[:, None] * ab), axis=1)
        k = int(np.argmax(d))
        if d[k] > tol:
            keep[i + 1 + k] = True
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return np.flatnonzero(keep)


def smooth_path(space: ArmSpace, path_q: np.ndarray, obstacles: Obstacles,
                limits: MotionLimits, *, tolerance: float = 0.004,
                check_dt: float = CHECK_DT
                ) -> tuple[Trajectory | None, int, PlanStatus, str]:
    """Quintic B-spline through a simplified ``path_q (K, 3)`` at rest at both ends,
    time-scaled to ``limits``; checked every ``check_dt`` s for overlap with the obstacles
    and for joint limits. The simplification (Ramer-Douglas-Peucker in normalised units)
    is tightened (``tolerance``, /4, /16, every point, every point with midpoints) until
    the check passes. Returns ``(trajectory or None, waypoints used, status, message)``: no
    trajectory with status ``ok`` when the path does not move."""
    u = space.to_u(path_q)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(u, axis=0), axis=1) > 1e-9])
    u, path_q = u[keep], path_q[keep]
    if len(u) < 2:
        return None, len(u), PlanStatus.OK, "no motion"
    attempts: list[np.ndarray] = [
        path_q[_rdp(u, tol)] for tol in (tolerance, tolerance / 4, tolerance / 16, 0.0)
    ]
    mid = np.empty((2 * len(path_q) - 1, 3))
    mid[0::2] = path_q
    mid[1::2] = 0.5 * (path_q[:-1] + path_q[1:])
    attempts.append(mid)
    lim = limits.limits()
    status, why = PlanStatus.OK, ""
    for W in attempts:
        h = np.linalg.norm(np.diff(space.to_u(W), axis=0), axis=1)
        traj = quintic_bspline(W, np.maximum(h, 1e-6) * 10.0)  # ~0.1 unit/s, then scaled
        traj = fit_to_limits(traj, lim, per_segment=False)
        n = max(2, int(math.ceil(traj.duration / check_dt)) + 1)
        ts = np.linspace(0.0, traj.duration, n)
        qp = traj.evaluate(ts)
        c = space.clearance(qp, obstacles)
        if np.all(c > 0):
            return traj, len(W), PlanStatus.OK, "ok"
        bad = int(np.argmin(c))
        if np.isfinite(c[bad]):
            status = PlanStatus.COLLISION
            why = f"smoothed transfer comes within {c[bad]:.0f} mm of an obstacle"
        else:
            status = PlanStatus.OUT_OF_LIMITS
            why = f"smoothed transfer leaves the joint limits at t = {ts[bad]:.2f} s"
    return None, len(attempts[-1]), status, why


def plan_move(space: ArmSpace, obstacles: Obstacles, q_start: np.ndarray,
              q_goal: np.ndarray, planner, rng: np.random.Generator, *,
              limits: MotionLimits, standoff: float,
              fallback=None) -> Move:
    """Plan one move between drilling (or park) configurations ``q_start``, ``q_goal (7,)``.
    ``fallback``: a second planner tried if the first fails (its name goes in the path)."""
    path = planner.plan(space, obstacles, q_start[:3], q_goal[:3], rng)
    if not path.success and fallback is not None:
        path = fallback.plan(space, obstacles, q_start[:3], q_goal[:3], rng)
    t_r = limits.feed_duration(standoff)
    if not path.success:
        return Move(space, q_start, q_goal, None, standoff, t_r, t_r, path, path.status,
                    f"{path.planner}: {path.message}")
    traj, n_way, status, msg = smooth_path(space, path.q, obstacles, limits)
    if status is not PlanStatus.OK:
        return Move(space, q_start, q_goal, None, standoff, t_r, t_r, path, status, msg)
    tool = 0.0
    if traj is not None:
        n = max(2, int(math.ceil(traj.duration / CHECK_DT)) + 1)
        yz = space.tip_yz(traj.evaluate(np.linspace(0, traj.duration, n)))
        tool = float(np.linalg.norm(np.diff(yz, axis=0), axis=1).sum()) / 1000.0
    return Move(space, q_start, q_goal, traj, standoff, t_r, t_r, path, PlanStatus.OK, "ok",
                tool, n_way)


# ---- parking ---------------------------------------------------------------------------------
def park_configuration(rig: Rig, arm: str, face_x: float, d7: float = DRILL_D7) -> np.ndarray:
    """Where an arm waits: the paper's initial pose (boom level, straight ahead, tip on the
    face plane) for the middle arm; for a side arm the same height with the tip swung as far
    outboard of its mount as the initial pose's tip is to the left of it, so its feed stays
    out of the middle arm's strip. ``(7,)``."""
    model = rig.arms[arm]
    q = home_configuration(model, face_x, d7)
    tip = fk(model, q)[:3, 3]
    mounts = np.array([rig.arms[a].base[1, 3] for a in rig.arms])
    side = np.sign(model.base[1, 3] - mounts.mean())
    if side == 0:
        return q
    offset = abs(tip[1] - model.base[1, 3])
    target = np.array([face_x, model.base[1, 3] + side * offset, tip[2]])
    r = drill_ik(model, target, d7=d7)[0]
    if not r.success:
        raise ValueError(f"face_x: no park pose for arm {arm!r}: {r.message}")
    return r.q


# ---- the final check -------------------------------------------------------------------------
#: Two arms, in the rig's order.
Pair = tuple[str, str]


def _pair_key(pair: Pair) -> str:
    """How results name an arm pair: ``("left", "middle")`` -> ``"left-middle"``."""
    return f"{pair[0]}-{pair[1]}"


def pair_distances(rig: Rig, envelope: ArmEnvelope, q: Mapping[str, np.ndarray],
                   moving: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Signed distance (mm) between the envelopes of every pair of arms at every sample:
    ``q[arm] (S, 7)`` -> ``{"a-b": (S,)}``. With ``moving[arm] (S,) bool``, samples at which
    neither arm of a pair moves (and did not at the sample before) repeat the last value
    instead of being recomputed."""
    return {_pair_key(p): d for p, d in _pair_distances(rig, envelope, q, moving).items()}


def _pair_distances(rig: Rig, envelope: ArmEnvelope, q: Mapping[str, np.ndarray],
                    moving: Mapping[str, np.ndarray] | None = None
                    ) -> dict[Pair, np.ndarray]:
    """``pair_distances`` keyed by the pairs themselves: ``{(a, b): (S,)}``."""
    names = list(q)
    S = len(next(iter(q.values())))
    caps = {a: None for a in names}
    out: dict[Pair, np.ndarray] = {}
    for a, b in itertools.combinations(names, 2):
        if moving is None:
            need = np.ones(S, dtype=bool)
        else:
            m = moving[a] | moving[b]
            need = m.copy()
            need[1:] |= m[:-1]
            need[0] = True
        idx = np.flatnonzero(need)
        for x in (a, b):
            if caps[x] is None:
                caps[x] = _capsules_dedup(rig.arms[x], q[x], envelope,
                                          None if moving is None else moving[x])
        d = min_distance(caps[a][idx], envelope.radii, caps[b][idx], envelope.radii)
        full = np.empty(S)
        full[idx] = d
        # forward-fill the skipped samples
        pos = np.where(need, np.arange(S), 0)
        np.maximum.accumulate(pos, out=pos)
        out[(a, b)] = full[pos]
    return out


def _capsules_dedup(model, q, envelope, moving) -> np.ndarray:
    """``capsules`` of ``q (S, 7)``, computed once per run of samples where the arm is still
    (``moving (S,)`` False there)."""
    if moving is None:
        return capsules(model, q, envelope)
    need = moving.copy()
    need[1:] |= moving[:-1]
    need[0] = True
    idx = np.flatnonzero(need)
    C = capsules(model, q[idx], envelope)
    pos = np.where(need, np.arange(len(q)), 0)
    np.maximum.accumulate(pos, out=pos)
    return C[np.searchsorted(idx, pos)]


# ---- the face planner ------------------------------------------------------------------------
def make_planner(name: str, params: Mapping[str, Any] | None = None):
    """The move planner ``name`` (``"iapf"`` or ``"rrt"``) with ``params`` overriding its
    defaults: ``registry.make("move_planner", name, params)``; ``FieldError`` naming
    ``planner`` or ``planner_params.<name>``."""
    return make("move_planner", name, params)


@dataclass(frozen=True)
class FaceOptions:
    """How ``plan_face`` plans a face once its holes are allocated (its keyword arguments
    of the same names), checked when made: ``FieldError`` naming the field at fault."""

    planner: str = "iapf"
    planner_params: Mapping[str, Any] | None = None
    sequencer: str = "auto"
    sequencer_params: Mapping[str, Any] | None = None
    seed: int = 0
    radii: Mapping[str, float] | None = None
    standoff: float = 300.0
    drill_time_s: float = 0.0
    limits: MotionLimits = field(default_factory=MotionLimits)
    middle_park: str = "last_hole"
    fallback: bool = True
    check_dt: float = CHECK_DT
    cost: str = "distance"

    def __post_init__(self) -> None:
        if self.middle_park not in ("last_hole", "home"):
            raise FieldError("middle_park", "middle_park: must be 'last_hole' or 'home', got "
                             f"{self.middle_park!r}")
        if not 0 <= self.standoff <= 2000:
            raise FieldError("standoff", "standoff: must be in [0, 2000] mm")
        if not self.drill_time_s >= 0:
            raise FieldError("drill_time_s", "drill_time_s: must be >= 0")
        if self.cost not in COSTS:
            raise FieldError("cost", f"cost: must be one of {', '.join(COSTS)}, got "
                             f"{self.cost!r}")
        if not 1e-4 <= self.check_dt <= 0.1:
            raise FieldError("check_dt", "check_dt: must be in [0.0001, 0.1] s")

    def move_planners(self) -> tuple[Any, Any | None]:
        """The move planner and, with ``fallback``, the other one with the same safety
        margin, tried on a move the first cannot plan."""
        main = make_planner(self.planner, self.planner_params)
        other = "rrt" if self.planner == "iapf" else "iapf"
        return main, PLANNERS[other](safety=main.safety) if self.fallback else None


@dataclass(eq=False)
class _ArmState:
    """One arm while its face is planned: where it waits (``park (7,)``, its tool then at
    ``start (3,)`` mm), its holes in drilling order (``order``, from ``sequence``), the
    configurations it visits (``configs (K, 7)``: the park pose, then one per hole) and its
    timeline so far."""

    name: str
    space: ArmSpace
    park: np.ndarray
    start: np.ndarray
    order: np.ndarray
    sequence: SequenceResult | None
    configs: np.ndarray
    timeline: ArmTimeline


@dataclass(frozen=True)
class _Failure:
    """Why the plan fails, and who is at fault: an arm, or a pair of arms."""

    who: str | Pair
    status: PlanStatus
    message: str


@dataclass(frozen=True)
class _Check:
    """The final check: samples ``t (S,)`` s, configurations ``q[arm] (S, 7)`` and the signed
    envelope distance per arm pair ``distance[(a, b)] (S,)`` mm."""

    t: np.ndarray
    q: dict[str, np.ndarray]
    distance: dict[Pair, np.ndarray]


@dataclass(eq=False)
class _MoveProgress:
    """Progress over the moves to plan: 0.05 when sequenced, 0.9 when all are planned."""

    report: Callable[[float, str], None]
    total: int
    done: int = 0

    def tick(self) -> None:
        self.done += 1
        self.report(0.05 + 0.85 * min(1.0, self.done / self.total), "planning moves")


@dataclass(eq=False)
class _FaceRun:
    """What the steps of ``plan_face`` share: the rig, the options and the move planners,
    every arm's state (``arms``, in the rig's order), the arms with holes (``working``), the
    middle arm (None for fewer than three arms), and the failures and notes so far."""

    rig: Rig
    options: FaceOptions
    allocation: Allocation
    envelope: ArmEnvelope
    face_x: float
    main: Any
    backup: Any | None
    rng: np.random.Generator
    arms: dict[str, _ArmState]
    working: list[str]
    middle: str | None
    failures: list[_Failure] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def sides(self) -> list[str]:
        """The arms with holes other than the middle arm."""
        return [a for a in self.working if a != self.middle]

    def at_rest(self, arms: Iterable[str]) -> Obstacles:
        """``arms`` as obstacles, each where its timeline (so far) leaves it."""
        return Obstacles.of_arms({a: (self.rig.arms[a], self.arms[a].timeline.q_final)
                                  for a in arms}, self.envelope)

    def plan_arm(self, arm: str, obstacles: Obstacles, configs: np.ndarray, t0: float,
                 on_move: Callable[[], None] | None = None) -> None:
        """Plan ``arm``'s moves through ``configs (K, 7)`` (the first where it is) among
        ``obstacles``, starting at ``t0`` s: its new timeline, and its failed moves in place
        of any earlier ones."""
        o = self.options
        state = self.arms[arm]
        moves, starts, failed = [], [], []
        t = t0
        for k in range(1, len(configs)):
            mv = plan_move(state.space, obstacles, configs[k - 1], configs[k], self.main,
                           self.rng, limits=o.limits, standoff=o.standoff, fallback=self.backup)
            if not mv.success:
                failed.append(_Failure(arm, mv.status, f"{arm} move {k}: {mv.message}"))
            moves.append(mv)
            starts.append(t)
            t += mv.duration + o.drill_time_s
            if on_move is not None:
                on_move()
        state.timeline = ArmTimeline(configs[0], tuple(moves), np.array(starts))
        self.failures = [f for f in self.failures if f.who != arm] + failed


def plan_face(
    rig: Rig,
    holes,
    *,
    planner: str = "iapf",
    planner_params: Mapping[str, Any] | None = None,
    sequencer: str = "auto",
    sequencer_params: Mapping[str, Any] | None = None,
    seed: int = 0,
    balance: str = "count",
    counts: Mapping[str, int] | None = None,
    allocation: Allocation | None = None,
    radii: Mapping[str, float] | None = None,
    standoff: float = 300.0,
    drill_time_s: float = 0.0,
    limits: MotionLimits | None = None,
    middle_park: str = "last_hole",
    fallback: bool = True,
    check_dt: float = CHECK_DT,
    progress: ProgressFn | None = None,
    cost: str = "distance",
) -> FacePlan:
    """Plan a whole face for ``rig`` (e.g. ``builtin_rig("tunnel_jumbo")``).

    ``holes (N, 3)`` mm on the face (rig frame; the face plane is their mean x), or give a
    ready ``allocation``. ``planner``: ``"iapf"`` or ``"rrt"`` with ``planner_params``;
    ``sequencer`` and ``sequencer_params`` as ``planning.sequencing.sequence_holes``;
    ``balance`` / ``counts`` as ``allocation.allocate_holes``; ``radii`` as
    ``envelopes.drill_arm_envelope``; ``standoff`` (mm) the feed retraction between holes;
    ``drill_time_s`` the dwell on each hole; ``middle_park``: ``"last_hole"`` (the paper) or
    ``"home"``; ``fallback``: try the other planner on a move the first cannot plan
    (reported per arm in ``planner_counts``); ``cost``: each arm's drilling order minimises
    its tool path (``"distance"``) or the boom's travel time between holes (``"time"``,
    ``boom_time.sequence_arm``; every arm plan's ``sequence.extra`` gives both orders'
    boom times). Seeded and reproducible.

    The steps: allocate and sequence each arm's holes (``_start_face``), plan the middle
    arm's moves (``_plan_middle_arm``) and then the side arms' (``_plan_side_arms``), check
    every pair of arms every ``check_dt`` s (``_check``), make side arms that meet wait for
    one another (``_separate_side_arms``), and report (``_face_plan``).
    """
    t_start = time.perf_counter()
    report = progress or (lambda f, m: None)
    options = FaceOptions(
        planner=planner, planner_params=planner_params, sequencer=sequencer,
        sequencer_params=sequencer_params, seed=seed, radii=radii, standoff=standoff,
        drill_time_s=drill_time_s, limits=limits or MotionLimits(), middle_park=middle_park,
        fallback=fallback, check_dt=check_dt, cost=cost)
    run = _start_face(rig, holes, options, allocation, balance, counts)
    report(0.05, "sequenced")
    moves = _MoveProgress(report, sum(len(run.allocation.indices[a]) for a in run.working) + 1)
    park_used, t_phase2 = _plan_middle_arm(run, moves.tick)
    _plan_side_arms(run, t_phase2, moves.tick)
    report(0.9, "checking")
    check = _separate_side_arms(run, _check(run))
    _record_check_failures(run, check)
    plan = _face_plan(run, check, park_used, t_phase2, t_start)
    report(1.0, "done")
    return plan


def _start_face(rig: Rig, holes, options: FaceOptions, allocation: Allocation | None,
                balance: str, counts: Mapping[str, int] | None) -> _FaceRun:
    """The move planners and envelopes, the allocation (``allocate_holes`` unless given, on
    one face plane), where each arm waits, and each arm's holes in drilling order from
    there (sequencer seeded with ``seed`` plus the arm's index in the rig)."""
    main, backup = options.move_planners()
    envelope = drill_arm_envelope(options.radii)
    if allocation is None:
        allocation = allocate_holes(rig, holes, balance=balance, counts=counts)
    P = allocation.holes
    face_x = float(P[:, 0].mean())
    if np.ptp(P[:, 0]) > 1.0:
        raise FieldError("holes", "holes: all holes must lie on one face plane (same x within "
                         "1 mm)")
    names = tuple(rig.arms)  # every arm is there, with holes or parked
    working = [a for a in names if a in allocation.arms and len(allocation.indices[a])]
    spaces = {a: ArmSpace(rig.arms[a], envelope, face_x) for a in names}
    parks = {a: park_configuration(rig, a, face_x) for a in names}
    arms = {}
    for k, a in enumerate(names):
        idx = allocation.indices[a] if a in working else np.zeros(0, dtype=int)
        arms[a] = _sequenced_arm(a, spaces[a], parks[a], fk(rig.arms[a], parks[a])[:3, 3],
                                 idx, allocation, options, options.seed + k)
    return _FaceRun(rig, options, allocation, envelope, face_x, main, backup,
                    np.random.default_rng(options.seed), arms, working, _middle_arm(rig))


def _middle_arm(rig: Rig) -> str | None:
    """The arm mounted nearest the middle of the rig (None for fewer than three arms)."""
    names = tuple(rig.arms)
    if len(names) <= 2:
        return None
    mounts = np.array([rig.arms[a].base[1, 3] for a in names])
    return names[int(np.argmin(np.abs(mounts - mounts.mean())))]


def _sequenced_arm(name: str, space: ArmSpace, park: np.ndarray, start: np.ndarray,
                   idx: np.ndarray, allocation: Allocation, options: FaceOptions,
                   seed: int) -> _ArmState:
    """An arm parked at ``park``, its tool at ``start``, with the holes ``idx`` (indices into
    the face) put in drilling order from there."""
    sequence = None
    order = idx
    if len(idx) >= 2:
        timing = BoomTime.planned_joints(space.model, options.limits.velocity,
                                         options.limits.acceleration)
        sequence = sequence_arm(allocation.holes[idx], allocation.q[name], park, start,
                                timing, cost=options.cost, algorithm=options.sequencer,
                                params=options.sequencer_params, seed=seed)
        order = idx[sequence.order]
    q_holes = allocation.q[name][np.searchsorted(idx, order)] if len(idx) else \
        np.zeros((0, 7))
    return _ArmState(name, space, park, start, order, sequence,
                     np.vstack([park[None], q_holes]), ArmTimeline(park, (), np.zeros(0)))


def _plan_middle_arm(run: _FaceRun, tick: Callable[[], None]) -> tuple[str, float]:
    """Phase 1: the middle arm drills its holes while the others wait parked, then stays on
    its last hole (the paper) or returns home (``middle_park="home"``, or when on its last
    hole it would block a side arm's hole). Returns where it stays (``"none"`` if it has no
    holes) and when phase 2 starts (s)."""
    middle = run.middle
    if middle not in run.working:
        return "none", 0.0
    obstacles = run.at_rest(a for a in run.arms if a != middle)
    configs = run.arms[middle].configs
    park_used = run.options.middle_park
    if park_used == "last_hole" and not _park_ok(run, configs[-1]):
        park_used = "home"
        run.notes.append(f"{middle} returns home: parked on its last hole it would block "
                         "a side arm's hole")
    if park_used != "last_hole":
        configs = np.vstack([configs, run.arms[middle].park[None]])
    run.plan_arm(middle, obstacles, configs, 0.0, tick)
    return park_used, run.arms[middle].timeline.end


def _park_ok(run: _FaceRun, q_last: np.ndarray) -> bool:
    """Whether the middle arm parked at ``q_last`` leaves every side arm's holes clear."""
    middle, env = run.middle, run.envelope
    obs = Obstacles.of_arms({middle: (run.rig.arms[middle], q_last)}, env)
    for a in run.sides:
        C = capsules(run.rig.arms[a], run.arms[a].configs, env)
        d = capsule_distances(C, env.radii, obs.segments, obs.radii)
        if d.min() < run.main.safety:
            return False
    return True


def _plan_side_arms(run: _FaceRun, t0: float, tick: Callable[[], None]) -> None:
    """Phase 2, from ``t0`` s: the other arms with holes all at once, each planned around
    the arms without holes and the middle arm, parked."""
    sides = run.sides
    for a in sides:
        obstacles = run.at_rest(x for x in run.arms if x not in sides)
        run.plan_arm(a, obstacles, run.arms[a].configs, t0, tick)


def _check(run: _FaceRun) -> _Check:
    """Every arm sampled every ``check_dt`` s over the whole plan (and at its end), and the
    envelope distance of every pair of arms at every sample."""
    end = max(st.timeline.end for st in run.arms.values())
    n = int(math.floor(end / run.options.check_dt + 1e-9)) + 1
    t = np.arange(n) * run.options.check_dt
    if t[-1] < end - 1e-9:
        t = np.append(t, end)
    q, moving = {}, {}
    for a, st in run.arms.items():
        q[a], moving[a] = st.timeline.evaluate(t)
    return _Check(t, q, _pair_distances(run.rig, run.envelope, q, moving))


def _separate_side_arms(run: _FaceRun, check: _Check) -> _Check:
    """Side arms that meet when running at once: the later of the pair waits until the
    earlier is done, planned around where it stops. Returns the check of the final plan."""
    sides = run.sides
    for a, b in list(check.distance):
        if (check.distance[(a, b)] < 0).any() and a in sides and b in sides:
            obstacles = run.at_rest(x for x in run.arms if x != b)
            run.plan_arm(b, obstacles, run.arms[b].configs, run.arms[a].timeline.end)
            run.notes.append(f"{b} waits for {a}: running at once they would meet")
            check = _check(run)
    return check


def _record_check_failures(run: _FaceRun, check: _Check) -> None:
    """Failures the final check finds: overlapping envelopes, joints beyond their limits."""
    for p, d in check.distance.items():
        n = int((d < 0).sum())
        if n:
            run.failures.append(_Failure(p, PlanStatus.COLLISION,
                                         f"{_pair_key(p)}: envelopes overlap at {n} samples "
                                         f"(closest {d.min():.0f} mm)"))
    for a in run.arms:
        model = run.rig.arms[a]
        bad = ~model.within_limits(check.q[a], tol=1e-6)
        if bad.any():
            k = int(np.argmax(bad))
            names = model.limit_violations(check.q[a][k], tol=1e-6)
            run.failures.append(_Failure(a, PlanStatus.OUT_OF_LIMITS,
                                         f"{a}: {', '.join(names)} outside limits at "
                                         f"t = {check.t[k]:.2f} s"))


def _arm_plan(state: _ArmState, holes: np.ndarray) -> ArmPlan:
    """An arm's summary: moves per planner, the sequenced path length (the straight line to
    a single hole) and the drill tip's path, m."""
    tl = state.timeline
    planner_counts: dict[str, int] = {}
    for mv in tl.moves:
        planner_counts[mv.path.planner] = planner_counts.get(mv.path.planner, 0) + 1
    if state.sequence is not None:
        length = state.sequence.length
    elif len(state.order):
        length = float(np.linalg.norm(holes[state.order[0]] - state.start))
    else:
        length = 0.0
    return ArmPlan(state.name, state.order, state.sequence, tl, length / 1000.0,
                   float(sum(mv.tool_path_m for mv in tl.moves)), planner_counts)


def _face_plan(run: _FaceRun, check: _Check, park_used: str, t_phase2: float,
               t_start: float) -> FacePlan:
    """The plan as reported: arm pairs named ``"a-b"``, the status that of the first
    failure, the run time since ``t_start`` (``time.perf_counter``)."""
    distance = {_pair_key(p): d for p, d in check.distance.items()}
    acc = _accelerations(check.q, check.t)
    arm_plans = {a: _arm_plan(st, run.allocation.holes) for a, st in run.arms.items()}
    return FacePlan(
        run.allocation, arm_plans, check.t, check.q, distance,
        {p: int((d < 0).sum()) for p, d in distance.items()},
        run.failures[0].status if run.failures else PlanStatus.OK,
        [f.message for f in run.failures], run.options.planner, park_used,
        time.perf_counter() - t_start, acc,
        {"face_x": run.face_x, "middle": run.middle, "phase2_start_s": t_phase2,
         "notes": run.notes})


def _accelerations(q: Mapping[str, np.ndarray], t: np.ndarray) -> dict[str, np.ndarray]:
    """Peak |acceleration| per joint over the sampled timeline (central differences of the
    10 ms samples; rad/s^2 and mm/s^2). ``{arm: (7,)}``."""
    out = {}
    for a, qa in q.items():
        if len(t) < 3:
            out[a] = np.zeros(qa.shape[1])
            continue
        h = np.diff(t)
        v = np.diff(qa, axis=0) / h[:, None]
        acc = np.diff(v, axis=0) / (0.5 * (h[1:] + h[:-1]))[:, None]
        out[a] = np.abs(acc).max(axis=0)
    return out
