"""A whole drilling round of a multi-boom jumbo: every boom drilling at once, none touching
another, and the round's cycle time.

``plan_round(rig, collars, toes, ids, options)`` takes a drill plan's holes (collar and toe
points, mm, rig frame) and:

1. **Reach of the whole hole.** A boom can take a hole only if it puts the drill tip on the
   collar with the tool axis (tool z) along the hole axis (``toe - collar``) within its
   joint limits, *and* the feed (the prismatic joint ``feed``, the arm's last joint, which
   moves the tip along tool z) then reaches the toe within its travel, with ``standoff`` mm
   of travel behind the collar for the approach. The boom holds its pose over the hole;
   the feed alone drills. The pose: ``kinematics.drilling.drill_ik`` perpendicular to the
   face (roll 0), then a Gauss-Newton continuation of swing, pitch, telescope and both
   compensation joints that turns the axis onto the hole's. The feed at the collar is
   ``DRILL_D7`` or less when the hole is deep (the toe then needs ``d7 + depth`` within
   the feed's limit). The approach, collar and toe poses and the feed line must be free of
   the scene, of the boom itself and of the other booms at their park poses. Holes no boom
   can take are reported with their ids and a reason: ``out_of_reach`` (the collar, or the
   toe, beyond the boom), ``axis_not_alignable`` (the collar is reached but not along the
   hole's axis within the joint limits), ``blocked`` (reached, but in collision, or no
   collision-free transfer to it).
2. **Allocation by time.** Each hole starts with the reachable boom mounted nearest it
   across the face; then holes move from the boom with the most work to one with less that
   reaches them, nearest the boundary first, while the largest work drops. Work = drilling
   time (collaring + depth / penetration rate + retraction) plus an estimate of the moves.
3. **Order** of each boom's holes: ``planning.drilling.boom_time.sequence_by_boom_time``
   from its park pose (the boom time of its joint speeds and accelerations).
4. **Moves.** Each transfer (from the approach pose of one hole, the tip ``standoff`` mm
   before its collar, to that of the next) is planned in the boom's full joint space by the
   joint-space motion planner (``planning.motion.plan_motion``) with the boom's exact
   collision model (capsules per link) against the static scene and the other booms parked,
   and timed time-optimally to the joint speed and acceleration limits (the planner's
   ``planning.trajectories`` timing). The feed onto the collar and off the hole are
   rest-to-rest quintics within the feed's limits; the drilling itself is the Cartesian line
   from collar to toe, every joint but the feed held (the feed, along the tool axis set on
   the hole's axis, moves the tip along that line; checked free at reach), run at the
   penetration rate. After its last hole a boom returns to its park
   pose.
5. **Prioritised timing.** Booms are timed one after another in priority order (most work
   first). A boom's next task (transfer, collar, drill, retract) starts as soon as its last
   one ends unless, checked at instants at most 10 ms and 5 mm apart against the booms
   already timed, it would come within ``clearance`` mm of one of them: then it **waits**
   (a delay inserted before the transfer, searched forward in steps of ``wait_step_s``
   growing with the delay) until clear. Paths are never replanned: a boom that waits sits
   still on its last hole, retracted, and if even that comes too close the task before is
   delayed instead (backtracking). A wait always ends: the booms timed before end at their
   park poses, which every move of the boom was planned around.
6. **Check.** The whole round is then sampled once more on one clock (every boom, the same
   10 ms / 5 mm rule over the union of their motion) and the least boom-boom clearance is
   computed exactly: per block of instants the boxes round each capsule's end points bound
   the distance of each pair of capsules from below, and the exact distance is computed
   for the pairs and blocks whose bound is under the least found so far (an upper bound,
   exact at every 64th instant, to begin with), which gives the same least; the least
   clearance from the scene is the motion checker's exact one
   over the booms' states at the checked instants (at most ``scene_check_states`` of them).

Units: mm, rad, s. Randomness: ``seed`` alone (the motion planner's).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.drilling import DRILL_D7, drill_ik
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.jacobian import jacobian_and_pose
from kinematics.rigs import Rig

from ..collision import CollisionScene, RobotCollisionModel
from ..drilling.allocation import home_configuration
from ..drilling.boom_time import BoomTime, sequence_by_boom_time
from ..drilling.envelopes import DRILL_ARM_RADII
from ..drilling.multiarm import park_configuration
from ..motion import MotionChecker, plan_motion
from ..sequencing import sequence_holes
from ..trajectories.trajectory import Limits
from .round_timeline import (
    CHECK_DT,
    BoomGeometry,
    BoomTimeline,
    Phase,
    pair_clearance,
    refine,
    sample_ends,
    still,
)

__all__ = [
    "REASONS",
    "ORDERS",
    "SCHEDULES",
    "FEED_JOINT",
    "DEFAULT_LINK_RADII",
    "DEFAULT_ACCELERATION",
    "RoundOptions",
    "HolePlan",
    "BoomPlan",
    "RoundResult",
    "hole_poses",
    "plan_round",
    "round_clearance",
]

#: How each boom's holes are ordered: by boom time (``sequence_by_boom_time``) or by the
#: shortest tool path (``planning.sequencing.sequence_holes``, the paper's criterion).
ORDERS = ("boom_time", "distance")
#: How the booms are timed: all at once with waits (``prioritised``), or one after another
#: in priority order (``sequential``: a boom starts when the one before is back at park).
SCHEDULES = ("prioritised", "sequential")
#: Why a hole is not drilled.
REASONS = ("out_of_reach", "axis_not_alignable", "blocked")
#: Index of the feed joint (the last, prismatic: moves the drill tip along tool z).
FEED_JOINT = 6
#: Capsule radius of each link of the drilling arm (mm), from the multi-arm planner's
#: envelope: mount, swing head, boom, (roll: zero length), cradle, wrist, feed beam.
DEFAULT_LINK_RADII = (DRILL_ARM_RADII["mount"], DRILL_ARM_RADII["swing"],
                      DRILL_ARM_RADII["boom"], DRILL_ARM_RADII["cradle"],
                      DRILL_ARM_RADII["cradle"], DRILL_ARM_RADII["wrist"],
                      DRILL_ARM_RADII["feed"])
#: Joint accelerations of the booms by joint name (rad/s^2, mm/s^2): the multi-arm
#: planner's transfer limits (just under paper 002's 0.25 rad/s^2) on every revolute joint.
DEFAULT_ACCELERATION: Mapping[str, float] = {
    "swing": 0.24, "pitch": 0.24, "telescope": 300.0, "roll": 0.24,
    "pitch_compensation": 0.24, "swing_compensation": 0.24, "feed": 500.0,
}
#: Gauss-Newton of the axis alignment: axis turn per continuation stage (rad), iterations
#: per stage and in the last, and the tolerances that accept a pose (mm, rad).
ALIGN_STAGE = 0.1
ALIGN_ITERATIONS = 6
ALIGN_FINAL = 40
ALIGN_TOL_MM = 1e-3
ALIGN_TOL_RAD = 1e-7
#: Free joints of the alignment (swing, pitch, telescope, pitch and swing compensation).
ALIGN_JOINTS = (0, 1, 2, 4, 5)
#: Most checks of one boom's delay search before it falls back to starting after the booms
#: timed before it have finished.
MAX_DELAY_CHECKS = 4000
#: Instants per cached block of a timed boom's end points, and most blocks kept (288 kB each
#: for a six-capsule boom).
GRID_CHUNK = 1000
GRID_CACHE = 128
#: Half the stretch (s) round the last touch checked first when a delayed start is tried.
HIT_WINDOW_S = 1.0
ProgressFn = Callable[[float, str], None]


@dataclass(frozen=True)
class RoundOptions:
    """How a round is planned (module docstring). Rates: ``penetration_rate_m_min`` (m/min)
    unless ``rates_by_type`` has the hole's type; ``collaring_s`` per hole; ``retract_s``
    the least time of the feed's return off a hole (longer if the feed's limits need it).
    ``standoff`` mm: the tip's distance before the collar during transfers. ``booms``: the
    booms used (default all), ``priority``: their timing order (default most work first).
    ``velocity`` / ``acceleration``: joint limits by name (defaults: the drilling arm's
    speeds of ``boom_time`` and ``DEFAULT_ACCELERATION``). ``clearance`` mm: the least
    boom-boom distance a plan keeps (and the margin of every move against the scene).
    ``transfer_time_limit`` s of search per transfer. ``scene``: a ``CollisionScene`` in
    the rig frame, or None. ``park``: a pose per boom (default: the multi-arm planner's
    park pose ``park_back`` mm before the face, at the median collar). For comparisons:
    ``assignment`` (hole id -> boom) fixes the allocation, ``order`` (``ORDERS``) picks how
    each boom's holes are ordered, ``schedule`` (``SCHEDULES``) how the booms are timed."""

    penetration_rate_m_min: float = 2.0
    rates_by_type: Mapping[str, float] | None = None
    collaring_s: float = 10.0
    retract_s: float = 8.0
    standoff: float = 300.0
    booms: tuple[str, ...] | None = None
    priority: tuple[str, ...] | None = None
    velocity: Mapping[str, float] | None = None
    acceleration: Mapping[str, float] | None = None
    link_radii: tuple[float, ...] = DEFAULT_LINK_RADII
    clearance: float = 50.0
    transfer_time_limit: float = 1.0
    wait_step_s: float = 0.5
    scene: CollisionScene | None = None
    park: Mapping[str, Any] | None = None
    park_back: float = 1500.0
    feed_max_step: float = 10.0
    scene_check_states: int = 2000
    seed: int = 0
    assignment: Mapping[str, str] | None = None
    order: str = "boom_time"
    schedule: str = "prioritised"

    def __post_init__(self) -> None:
        def positive(name: str, v: float, lo: float = 0.0, hi: float = math.inf) -> None:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < v <= hi:
                raise FieldError(name, f"{name}: must be a number in ({lo:g}, {hi:g}]")

        positive("penetration_rate_m_min", self.penetration_rate_m_min, 0.0, 100.0)
        for k, v in (self.rates_by_type or {}).items():
            positive(f"penetration_rate_by_type.{k}", v, 0.0, 100.0)
        for name in ("collaring_s", "retract_s", "clearance"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 3600:
                raise FieldError(name, f"{name}: must be a number in [0, 3600]")
        positive("standoff", self.standoff, 0.0, 2000.0)
        positive("transfer_time_limit", self.transfer_time_limit, 0.0, 60.0)
        positive("wait_step_s", self.wait_step_s, 0.0, 60.0)
        if self.order not in ORDERS:
            raise FieldError("order", f"order: must be one of {', '.join(ORDERS)}")
        if self.schedule not in SCHEDULES:
            raise FieldError("schedule", f"schedule: must be one of {', '.join(SCHEDULES)}")

    def rate_mm_s(self, hole_type: str | None) -> float:
        """Penetration rate of a hole of ``hole_type``, mm/s."""
        r = (self.rates_by_type or {}).get(hole_type or "", self.penetration_rate_m_min)
        return float(r) * 1000.0 / 60.0


@dataclass(frozen=True)
class HolePlan:
    """A drilled hole: ``id``, its ``boom``, when its collar phase starts (``start_s``,
    after the transfer) and its retraction ends (``end_s``), its depth (mm) and the boom's
    configuration on the collar ``q_collar (dof,)``."""

    id: str
    boom: str
    start_s: float
    end_s: float
    depth_mm: float
    drill_s: float
    q_collar: np.ndarray


@dataclass(eq=False)
class BoomPlan:
    """One boom: its holes in drilling order (``holes``: ids), its timeline (phases on the
    round's clock), its ``priority`` (0 first), time spent waiting for other booms
    (``wait_s``) and the time it ends (back at park)."""

    name: str
    holes: list[str]
    timeline: BoomTimeline
    priority: int
    wait_s: float
    park: np.ndarray

    @property
    def end_s(self) -> float:
        return self.timeline.end

    def samples(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The timed joint trajectory: ``t (S,)`` every ``dt`` s and at every phase
        boundary, and ``q (S, dof)``."""
        tl = self.timeline
        end = tl.end
        t = np.arange(0.0, end + 1e-12, dt) if end > 0 else np.zeros(1)
        t = np.unique(np.concatenate([t, [p.t0 for p in tl.phases], [end]]))
        return t, tl.evaluate(t)

    def phase_table(self) -> list[dict[str, Any]]:
        """The phases as ``{"kind", "start_s", "end_s", "hole"}``."""
        return [{"kind": p.kind, "start_s": p.t0, "end_s": p.t1, "hole": p.hole}
                for p in self.timeline.phases]


@dataclass(eq=False)
class RoundResult:
    """A planned round (module docstring): per boom its plan (``booms``), per drilled hole
    its plan (``holes``, in the plan's order), holes not drilled (``unreachable``: ``{"id",
    "reason", "detail"}``), ``cycle_time_s`` (the last boom back at park),
    ``lower_bound_s`` (the drilling time of the drilled holes, summed, over the number of
    booms) and ``ratio`` = cycle / bound, the least boom-boom clearance over the whole
    round (mm, ``min_boom_clearance_mm``; ``clearance_pair`` and ``clearance_t_s`` where)
    checked at ``checked_instants`` instants (``max_step_mm`` the largest motion of any
    point between two), the least scene clearance (None without a scene), the planning
    time, and notes."""

    booms: dict[str, BoomPlan]
    holes: list[HolePlan]
    unreachable: list[dict[str, str]]
    cycle_time_s: float
    lower_bound_s: float
    min_boom_clearance_mm: float | None
    clearance_pair: str | None
    clearance_t_s: float | None
    checked_instants: int
    max_step_mm: float
    min_scene_clearance_mm: float | None
    planning_time_s: float
    notes: list[str] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def ratio(self) -> float:
        return self.cycle_time_s / self.lower_bound_s if self.lower_bound_s > 0 else math.nan

    @property
    def collision_free(self) -> bool:
        return self.min_boom_clearance_mm is None or self.min_boom_clearance_mm > 0


# ---- input ---------------------------------------------------------------------------------
def _holes(collars, toes, ids) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Collars and toes ``(N, 3)`` checked (finite, toe distinct from collar), ids as
    strings, unique; ``FieldError`` naming the hole."""
    C = np.asarray(collars, dtype=float).reshape(-1, 3)
    T = np.asarray(toes, dtype=float).reshape(-1, 3)
    if C.shape != T.shape:
        raise FieldError("holes", "holes: as many toes as collars are needed")
    ids = [str(i) for i in (ids if ids is not None else range(len(C)))]
    if len(ids) != len(C):
        raise FieldError("holes", "holes: one id per hole is needed")
    seen: dict[str, int] = {}
    for k, i in enumerate(ids):
        if i in seen:
            raise FieldError(("holes", k, "id"), f"holes[{k}].id: {i!r} is used twice")
        seen[i] = k
    for k in range(len(C)):
        if not (np.all(np.isfinite(C[k])) and np.all(np.isfinite(T[k]))):
            raise FieldError(("holes", k), f"holes[{k}]: collar and toe must be finite")
        if np.linalg.norm(T[k] - C[k]) < 1.0:
            raise FieldError(("holes", k, "toe"), f"holes[{k}].toe: must lie at least 1 mm "
                             "from the collar")
    return C, T, ids


# ---- reach of the whole hole ---------------------------------------------------------------
def _align(model, q: np.ndarray, collar: np.ndarray, axis: np.ndarray,
           start_axis: np.ndarray) -> np.ndarray:
    """Turn the drill axis of ``q (N, dof)`` (tip on ``collar (N, 3)``, axis
    ``start_axis (3,)``) onto ``axis (N, 3)`` keeping the tip on the collar: Gauss-Newton
    on ``ALIGN_JOINTS`` in stages of ``ALIGN_STAGE`` rad of turn. Returns the new ``q``."""
    q = q.copy()
    free = list(ALIGN_JOINTS)
    ang = np.arccos(np.clip(axis @ start_axis, -1.0, 1.0))
    stages = max(1, int(math.ceil(float(ang.max(initial=0.0)) / ALIGN_STAGE)))
    for s in range(1, stages + 1):
        w = s / stages
        target = (1 - w) * start_axis[None] + w * axis
        target /= np.linalg.norm(target, axis=1, keepdims=True)
        for _ in range(ALIGN_FINAL if s == stages else ALIGN_ITERATIONS):
            J, T = jacobian_and_pose(model, q)
            z = T[:, :3, 2]
            e = np.concatenate([T[:, :3, 3] - collar, z - target], axis=1)
            if s == stages and np.all(np.abs(e[:, :3]) < 1e-6) and \
                    np.all(np.abs(e[:, 3:]) < 1e-12):
                break
            Jf = J[:, :, free]
            Jz = np.cross(np.swapaxes(Jf[:, 3:], 1, 2), z[:, None, :])
            G = np.concatenate([Jf[:, :3], np.swapaxes(Jz, 1, 2)], axis=1)
            dq = -np.einsum("nij,nj->ni", np.linalg.pinv(G), e)
            q[:, free] += dq
    return q


@dataclass(frozen=True)
class _Reach:
    """Per hole and boom: whether the boom takes the hole, its collar pose (``q (N, B,
    dof)``), the feed at the collar (``d7 (N, B)``) and per hole the reasons of the booms
    that cannot."""

    ok: np.ndarray
    q: np.ndarray
    d7: np.ndarray
    why: list[list[tuple[str, str]]]


def hole_poses(model, collars: np.ndarray, toes: np.ndarray, standoff: float,
               ) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str] | None]]:
    """The boom's pose on each hole's collar with the tool axis along the hole: ``(N, dof)``
    (NaN rows: none), the feed value at the collar ``(N,)`` and per hole ``None`` or
    ``(reason, detail)`` (``REASONS``). Kinematics only (no collision)."""
    N = len(collars)
    dof = model.dof
    axis = toes - collars
    depth = np.linalg.norm(axis, axis=1)
    axis = axis / depth[:, None]
    feed = model.joints[FEED_JOINT]
    d7 = np.minimum(DRILL_D7, feed.upper - depth)
    q = np.full((N, dof), np.nan)
    why: list[tuple[str, str] | None] = [None] * N
    normal = model.base[:3, 0]
    base_x = (collars - model.base[:3, 3]) @ normal
    for k in range(N):
        if depth[k] + standoff > feed.upper - feed.lower:
            why[k] = ("out_of_reach", f"the hole is {depth[k]:.0f} mm deep; the feed travels "
                      f"{feed.upper - feed.lower:.0f} mm ({standoff:.0f} mm of it behind the "
                      "collar)")
        elif d7[k] - standoff < feed.lower:
            why[k] = ("out_of_reach", "the toe is beyond the feed's travel")
        elif base_x[k] <= 0:
            why[k] = ("out_of_reach", f"the collar is {-base_x[k]:.0f} mm behind the boom's "
                      "mount")
        elif axis[k] @ normal <= 0.05:
            why[k] = ("axis_not_alignable", "the hole does not point towards the face")
    todo = [k for k in range(N) if why[k] is None]
    for v in np.unique(d7[todo]) if todo else []:
        ks = [k for k in todo if d7[k] == v]
        for k, r in zip(ks, drill_ik(model, collars[ks], d7=float(v))):
            if r.success:
                q[k] = r.q
            else:
                why[k] = ("out_of_reach", r.message.split(": ", 1)[-1])
    ok = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    if len(ok):
        qa = _align(model, q[ok], collars[ok], axis[ok], normal)
        T = fk(model, qa)
        dp = np.linalg.norm(T[:, :3, 3] - collars[ok], axis=1)
        dz = np.arccos(np.clip(np.einsum("ni,ni->n", T[:, :3, 2], axis[ok]), -1.0, 1.0))
        within = model.within_limits(qa, tol=1e-9)
        for j, k in enumerate(ok):
            if dp[j] > ALIGN_TOL_MM or dz[j] > ALIGN_TOL_RAD:
                why[k] = ("axis_not_alignable", f"no pose on the collar along the hole axis "
                          f"(left {dp[j]:.2g} mm, {math.degrees(dz[j]):.2g} deg off)")
                q[k] = np.nan
            elif not within[j]:
                names = model.limit_violations(qa[j], tol=1e-9)
                why[k] = ("axis_not_alignable", "along the hole axis the boom needs "
                          f"{', '.join(names)} beyond the limits")
                q[k] = np.nan
            else:
                q[k] = qa[j]
    return q, d7, why


def _reach(rig: Rig, booms: Sequence[str], collars, toes, checkers, options: RoundOptions,
           report: ProgressFn) -> _Reach:
    """Reach of the whole hole by every boom, with collisions (module docstring, step 1)."""
    N, B = len(collars), len(booms)
    dof = rig.arms[booms[0]].dof
    ok = np.zeros((N, B), dtype=bool)
    Q = np.full((N, B, dof), np.nan)
    D7 = np.full((N, B), np.nan)
    why: list[list[tuple[str, str]]] = [[] for _ in range(N)]
    depth = np.linalg.norm(toes - collars, axis=1)
    for b, name in enumerate(booms):
        model = rig.arms[name]
        ch = checkers[name]
        q, d7, reasons = hole_poses(model, collars, toes, options.standoff)
        for k in range(N):
            if reasons[k] is not None:
                why[k].append((reasons[k][0], f"{name}: {reasons[k][1]}"))
                continue
            qc = q[k]
            qa, qt = qc.copy(), qc.copy()
            qa[FEED_JOINT] -= options.standoff
            qt[FEED_JOINT] += depth[k]
            free = ch.free(np.stack([qa, qc, qt]))
            if not np.all(free):
                what = ("approach", "collar", "toe")[int(np.argmin(free))]
                why[k].append(("blocked", f"{name}: its {what} pose collides"))
                continue
            # Over the feed only the feed joint moves: the tool's line to the toe is the
            # straight joint-space segment, checked here (the drilling path of _feed_line).
            if not ch.segment_free(qc, qt):
                why[k].append(("blocked", f"{name}: the feed's line to the toe collides"))
                continue
            ok[k, b] = True
            Q[k, b] = qc
            D7[k, b] = d7[k]
        report(0.05 + 0.15 * (b + 1) / B, f"reach of {name}")
    return _Reach(ok, Q, D7, why)


# ---- allocation ----------------------------------------------------------------------------
def _allocate(rig: Rig, booms: Sequence[str], collars: np.ndarray, reach: _Reach,
              drill_s: np.ndarray, move_s: float) -> np.ndarray:
    """Boom index per hole (-1: none), balancing drilling time plus ``move_s`` per hole
    (module docstring, step 2)."""
    N, B = reach.ok.shape
    lateral = np.array([rig.arms[a].base[1, 3] for a in booms])
    cost = np.abs(collars[:, 1][:, None] - lateral[None, :])
    cost = np.where(reach.ok, cost, np.inf)
    owner = np.where(reach.ok.any(axis=1), np.argmin(cost, axis=1), -1)
    work = np.array([(drill_s[owner == b] + move_s).sum() for b in range(B)])
    for _ in range(N):
        hi = int(np.argmax(work))
        best = None
        for k in np.flatnonzero(owner == hi):
            for b in np.flatnonzero(reach.ok[k]):
                if b == hi:
                    continue
                t = drill_s[k] + move_s
                new_max = max(work[hi] - t, work[b] + t)
                if new_max >= work[hi] - 1e-9:
                    continue
                extra = cost[k, b] - cost[k, hi]
                if best is None or extra < best[0]:
                    best = (extra, k, b, t)
        if best is None:
            break
        _, k, b, t = best
        owner[k] = b
        work[hi] -= t
        work[b] += t
    return owner


# ---- the booms' tasks ------------------------------------------------------------------------
def _quintic(q0: np.ndarray, q1: np.ndarray, T: float) -> Callable[[np.ndarray], np.ndarray]:
    """Rest-to-rest quintic from ``q0`` to ``q1`` over ``T`` s."""
    def f(tau):
        s = np.clip(np.asarray(tau, dtype=float) / T, 0.0, 1.0) if T > 0 else \
            np.ones(len(np.atleast_1d(tau)))
        b = s**3 * (10 - 15 * s + 6 * s**2)
        return q0[None] + b[:, None] * (q1 - q0)[None]
    return f


def _feed_time(distance: float, v: float, a: float) -> float:
    """Least duration of a rest-to-rest quintic over ``distance`` mm within feed speed ``v``
    and acceleration ``a`` (peak speed 15/8 d/T, peak acceleration 10/sqrt(3) d/T^2)."""
    d = abs(distance)
    return max(15 / 8 * d / v, math.sqrt(10 / math.sqrt(3) * d / a)) if d > 0 else 0.0


def _polyline(path: np.ndarray, T: float) -> Callable[[np.ndarray], np.ndarray]:
    """The joint path ``path (K, dof)`` at a constant rate along its length over ``T`` s."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(path))

    def f(tau):
        u = np.clip(np.asarray(tau, dtype=float) / T, 0.0, 1.0) if T > 0 else \
            np.ones(len(np.atleast_1d(tau)))
        return np.stack([np.interp(u, s, path[:, j]) for j in range(path.shape[1])], axis=1)
    return f


def _trajectory_fn(traj) -> Callable[[np.ndarray], np.ndarray]:
    return lambda tau: traj.evaluate(np.clip(np.asarray(tau, dtype=float), 0.0,
                                             traj.duration))


@dataclass(eq=False)
class _Task:
    """One task of a boom, local time from 0: phases ``(kind, duration, evaluate, hole,
    q_end)``; the hole it drills (None: the return to park)."""

    hole: int | None
    phases: list[tuple[str, float, Callable, str | None, np.ndarray]]

    @property
    def duration(self) -> float:
        return float(sum(p[1] for p in self.phases))

    def at(self, t0: float) -> list[Phase]:
        out, t = [], t0
        for kind, d, f, hole, q_end in self.phases:
            out.append(Phase(kind, t, d, f, hole, q_end))
            t += d
        return out


def _transfer(checker: MotionChecker, qa: np.ndarray, qb: np.ndarray, limits: Limits,
              options: RoundOptions, seed: int):
    """The timed joint-space transfer ``qa`` -> ``qb`` (None if the planner finds none
    within its time, tried twice: the limit, then four times it)."""
    if np.allclose(qa, qb, atol=1e-9):
        return None, "no motion"
    for tl in (options.transfer_time_limit, 4 * options.transfer_time_limit):
        res = plan_motion(checker, qa, qb, time_limit=tl, seed=seed, limits=limits)
        if res.success and res.trajectory is not None:
            return res.trajectory, "ok"
    return False, f"{res.status.value}: {res.message}"


def _feed_line(model, qc: np.ndarray, toe: np.ndarray, options: RoundOptions) -> np.ndarray:
    """The drilling path: the tool along the hole axis from the collar pose ``qc`` to the
    toe, every joint but the feed held at ``qc``, ``(K, dof)`` at feed steps of at most
    ``feed_max_step`` mm. With the other joints held the feed (prismatic along tool z) moves
    the tip on a straight line along the tool axis, which the collar pose put on the hole's
    axis (within ``ALIGN_TOL_RAD``): the Cartesian line from collar to toe, orientation
    held. Its states were checked free (1 mm steps, ``clearance`` margin) when the hole was
    found reachable, so they are not checked again here."""
    qt = qc.copy()
    qt[FEED_JOINT] += float(np.linalg.norm(toe - fk(model, qc)[:3, 3]))
    n = max(1, int(math.ceil((qt[FEED_JOINT] - qc[FEED_JOINT]) / options.feed_max_step)))
    return qc[None] + np.linspace(0.0, 1.0, n + 1)[:, None] * (qt - qc)[None]


def _boom_tasks(name: str, model, checker: MotionChecker, park: np.ndarray,
                order: Sequence[int], reach: _Reach, b: int, collars, toes, ids, depth,
                rates, options: RoundOptions, limits: Limits, feed_v: float, feed_a: float,
                blocked: dict[int, str]) -> list[_Task]:
    """The tasks of one boom over its holes in ``order`` and back to park; holes whose
    transfer cannot be planned go to ``blocked`` (hole -> detail) and are skipped."""
    tasks: list[_Task] = []
    q_here = park
    seed = options.seed
    for k in order:
        qc = reach.q[k, b]
        qa = qc.copy()
        qa[FEED_JOINT] -= options.standoff
        seed += 1
        traj, msg = _transfer(checker, q_here, qa, limits, options, seed)
        if traj is False:
            blocked[k] = f"{name}: no collision-free transfer to it ({msg})"
            continue
        hid = ids[k]
        path = _feed_line(model, qc, toes[k], options)
        qt = path[-1]
        t_adv = _feed_time(options.standoff, feed_v, feed_a)
        t_drill = depth[k] / rates[k]
        t_ret = max(options.retract_s, _feed_time(depth[k] + options.standoff, feed_v, feed_a))
        ph = []
        if traj is not None:
            ph.append(("transfer", float(traj.duration), _trajectory_fn(traj), hid, qa))
        ph += [("collar", t_adv, _quintic(qa, qc, t_adv), hid, qc),
               ("collar", float(options.collaring_s), still(qc), hid, qc),
               ("drill", t_drill, _polyline(path, t_drill), hid, qt),
               ("retract", t_ret, _quintic(qt, qa, t_ret), hid, qa)]
        tasks.append(_Task(k, ph))
        q_here = qa
    seed += 1
    traj, msg = _transfer(checker, q_here, park, limits, options, seed)
    if traj is not None and traj is not False:
        tasks.append(_Task(None, [("transfer", float(traj.duration), _trajectory_fn(traj),
                                   None, park)]))
    elif traj is False:
        raise RuntimeError(f"{name}: no way back to its park pose ({msg})")
    return tasks


# ---- prioritised timing ----------------------------------------------------------------------
class _Clock:
    """The booms already timed: their timelines and geometry, and the check of a new boom's
    motion against them over an interval.

    The instants checked over ``[t0, t1]`` are the multiples of ``CHECK_DT`` from the last
    at or before ``t0`` to the first at or after ``t1`` (no two more than 10 ms apart),
    refined where some capsule end point of either boom moves more than ``REFINE_MM``. A
    boom resting is evaluated once. The timed booms' end points at
    the multiples of ``CHECK_DT`` are computed once, in blocks of ``GRID_CHUNK`` instants,
    and kept (at most ``GRID_CACHE`` blocks): the delay search checks one boom's task at
    start after start against the same timed booms."""

    def __init__(self, geometry: dict[str, BoomGeometry], clearance: float) -> None:
        self.geometry = geometry
        self.clearance = clearance
        self.timed: dict[str, BoomTimeline] = {}
        self.checks = 0
        self._grid: dict[tuple[str, int], np.ndarray] = {}

    def _grid_ends(self, name: str, k0: int, k1: int) -> np.ndarray:
        """End points of timed boom ``name`` at ``k * CHECK_DT`` for ``k0 <= k <= k1``."""
        parts = []
        for c in range(k0 // GRID_CHUNK, k1 // GRID_CHUNK + 1):
            E = self._grid.get((name, c))
            if E is None:
                if len(self._grid) >= GRID_CACHE:
                    self._grid.clear()
                t = np.arange(c * GRID_CHUNK, (c + 1) * GRID_CHUNK) * CHECK_DT
                E = self.geometry[name].ends(self.timed[name].evaluate(t))
                self._grid[(name, c)] = E
            lo = max(k0 - c * GRID_CHUNK, 0)
            hi = min(k1 - c * GRID_CHUNK, GRID_CHUNK - 1)
            parts.append(E[lo:hi + 1])
        return np.concatenate(parts)

    def first_touch(self, name: str, evaluate: Callable[[np.ndarray], np.ndarray],
                    t0: float, t1: float, still_at: np.ndarray | None = None
                    ) -> float | None:
        """The first checked instant in ``[t0, t1]`` at which boom ``name`` moving as
        ``evaluate(t)`` (or resting at ``still_at``) comes within ``clearance`` of a timed
        boom (None: never). The instants: the multiples of ``CHECK_DT`` from the last at or
        before ``t0`` to the first at or after ``t1`` (the boom's own positions just outside
        the interval are real ones too), refined as ``refine`` does. The exact distance is
        computed wherever the bound of ``pair_clearance`` does not already keep the two
        beyond the clearance."""
        others = list(self.timed)
        if not others or t1 < t0:
            return None
        self.checks += 1
        g = self.geometry
        fixed = None if still_at is None else g[name].ends(np.asarray(still_at)[None])
        span = 10.0
        a = t0
        while a <= t1:
            b = min(t1, a + span)
            k0 = int(math.floor(a / CHECK_DT + 1e-9))
            k1 = max(k0, int(math.ceil(b / CHECK_DT - 1e-9)))
            t = np.arange(k0, k1 + 1) * CHECK_DT

            def own(tt):
                return (np.repeat(fixed, len(tt), axis=0) if fixed is not None
                        else g[name].ends(evaluate(tt)))

            def ends(tt):
                return [own(tt)] + [g[o].ends(self.timed[o].evaluate(tt)) for o in others]
            E = [own(t)] + [self._grid_ends(o, k0, k1) for o in others]
            t, E = refine(t, E, ends)
            first = None
            for j, o in enumerate(others):
                d = pair_clearance(E[0], g[name].radius, E[j + 1], g[o].radius,
                                   below=self.clearance + 1.0)
                bad = np.flatnonzero(d <= self.clearance)
                if len(bad) and (first is None or t[bad[0]] < first):
                    first = float(t[bad[0]])
            if first is not None:
                return first
            if b >= t1:
                break
            a = b
        return None


def _after(q0: np.ndarray, tasks: list[_Task], t0: float
           ) -> tuple[BoomTimeline, float, str | None]:
    """A boom's tasks back to back from ``t0`` s, waiting at ``q0`` until then."""
    phases: list[Phase] = []
    if t0 > 0 and tasks:
        phases.append(Phase("wait", 0.0, t0, still(q0), None, q0))
    t = t0
    for task in tasks:
        phases += task.at(t)
        t += task.duration
    return BoomTimeline(q0, phases), (t0 if tasks else 0.0), None


def _time_boom(clock: _Clock, name: str, q0: np.ndarray, tasks: list[_Task],
               wait_step: float) -> tuple[BoomTimeline, float, str | None]:
    """Start times of a boom's tasks against the booms already timed (module docstring,
    step 5). Returns the timeline, the time spent waiting, and a note if the search fell
    back to starting after the others."""
    K = len(tasks)
    starts = [0.0] * K
    min_start = [0.0] * K
    ends_at = [0.0] * K
    rests = [q0] + [t.phases[-1][4] for t in tasks]
    others_end = max((tl.end for tl in clock.timed.values()), default=0.0)
    note = None
    k = 0
    budget = MAX_DELAY_CHECKS
    while k < K:
        rest_from = ends_at[k - 1] if k else 0.0
        s = max(rest_from, min_start[k])
        q_rest = rests[k]
        rest_fn = still(q_rest)
        touch = (clock.first_touch(name, rest_fn, rest_from, s, still_at=q_rest)
                 if s > rest_from else None)
        back = touch is not None
        hit = None
        last = None   # where in the task (local s) the last start tried touched
        while not back:
            task_fn = BoomTimeline(q_rest, tasks[k].at(s)).evaluate
            budget -= 1
            dur = tasks[k].duration
            hit = None
            if last is not None:
                # Where the last start touched is where a start a little later most likely
                # touches too: a touch there rejects this start without the whole scan (a
                # start is accepted only after the whole task is checked clear).
                hit = clock.first_touch(name, task_fn, s + max(0.0, last - HIT_WINDOW_S),
                                        s + min(dur, last + HIT_WINDOW_S))
            if hit is None:
                hit = clock.first_touch(name, task_fn, s, s + dur)
            if hit is None:
                break
            last = hit - s
            if (s >= others_end and s > rest_from) or budget <= 0:
                break
            step = max(wait_step, 0.1 * (s - rest_from))
            s_next = min(s + step, others_end) if s < others_end else s + step
            if clock.first_touch(name, rest_fn, s, s_next, still_at=q_rest) is not None:
                back = True
                break
            s = s_next
        if not back and hit is not None:
            note = f"{name}: delay search ended; the boom starts after the others finish"
            break
        if back:
            if k == 0:
                note = f"{name}: its park pose is not clear; it starts after the others"
                break
            k -= 1
            min_start[k] = starts[k] + max(wait_step, 0.1 * (starts[k] - (ends_at[k - 1]
                                                                          if k else 0.0)))
            continue
        starts[k] = s
        ends_at[k] = s + tasks[k].duration
        k += 1
    if note is not None:
        t = others_end
        for j in range(K):
            starts[j] = t
            t += tasks[j].duration
    phases: list[Phase] = []
    t_prev = 0.0
    q_prev = q0
    waited = 0.0
    for j, task in enumerate(tasks):
        if starts[j] > t_prev + 1e-12:
            phases.append(Phase("wait", t_prev, starts[j] - t_prev, still(q_prev),
                                None, q_prev))
            waited += starts[j] - t_prev
        phases += task.at(starts[j])
        t_prev = starts[j] + task.duration
        q_prev = task.phases[-1][4]
    return BoomTimeline(q0, phases), waited, note


# ---- the whole-round check -------------------------------------------------------------------
def round_clearance(timelines: Mapping[str, BoomTimeline],
                    geometry: Mapping[str, BoomGeometry], end: float | None = None
                    ) -> tuple[float | None, str | None, float | None, int, float]:
    """The least boom-boom clearance over the whole round, exactly at instants at most 10 ms
    apart with no point of any boom moving more than 5 mm between two: ``(least mm, pair
    "a-b", time s, instants, largest end point motion between two instants mm)``."""
    names = list(timelines)
    if len(names) < 2:
        return None, None, None, 0, 0.0
    end = max(tl.end for tl in timelines.values()) if end is None else end
    best, pair, when, count, step = math.inf, None, None, 0, 0.0
    span = 60.0
    a = 0.0
    while True:
        b = min(end, a + span)

        def ends(t):
            return [geometry[n].ends(timelines[n].evaluate(t)) for n in names]
        t, E = sample_ends(a, b, ends)
        count += len(t) - (1 if a > 0 else 0)
        for e in E:
            if len(t) > 1:
                step = max(step, float(np.linalg.norm(np.diff(e, axis=0), axis=-1).max()))
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                ri, rj = geometry[names[i]].radius, geometry[names[j]].radius
                # An upper bound of this stretch's least distance (exact at every 64th
                # instant): below it the distance is computed exactly, so the least is.
                cap = min(best, float(pair_clearance(E[i][::64], ri, E[j][::64], rj).min()))
                d = pair_clearance(E[i], ri, E[j], rj, below=cap + 1e-6)
                m = int(np.argmin(d))
                if d[m] < best:
                    best, pair, when = float(d[m]), f"{names[i]}-{names[j]}", float(t[m])
        if b >= end:
            break
        a = b
    return best, pair, when, count, step


def _scene_clearance(checkers: Mapping[str, MotionChecker],
                     timelines: Mapping[str, BoomTimeline], scene: CollisionScene | None,
                     most: int) -> float | None:
    """Least exact clearance of the booms from the scene over their moving states (at most
    ``most`` per boom, evenly spread over the 10 ms instants) and every hole pose."""
    if scene is None or not len(scene):
        return None
    best = math.inf
    for name, tl in timelines.items():
        ch = checkers[name]
        solo = MotionChecker(ch.cm, scene, self_collision=False)
        t = np.arange(0.0, tl.end + 1e-12, CHECK_DT)
        keep = np.zeros(len(t), dtype=bool)
        for p in tl.phases:
            if p.kind != "wait":
                keep |= (t >= p.t0) & (t <= p.t1)
        Q = tl.evaluate(t[keep]) if keep.any() else tl.q0[None]
        if len(Q) > most:
            Q = Q[np.unique(np.linspace(0, len(Q) - 1, most).round().astype(int))]
        for q in Q:
            c = solo.clearance(q[None], most=1)
            if c is not None:
                best = min(best, c)
    return best if math.isfinite(best) else None


# ---- the planner -----------------------------------------------------------------------------
def _parks(rig: Rig, booms: Sequence[str], collars: np.ndarray, options: RoundOptions
           ) -> dict[str, np.ndarray]:
    """Each boom's park pose: given, else the multi-arm planner's ``park_back`` mm before
    the nearest collar (the face plane itself if that is out of the boom's reach)."""
    out = {}
    face_x = float(np.median(collars[:, 0])) if len(collars) else 9000.0
    for a in booms:
        if options.park and a in options.park:
            q = np.asarray(options.park[a], dtype=float).reshape(-1)
            model = rig.arms[a]
            if q.shape != (model.dof,) or not model.within_limits(q):
                raise FieldError(("park", a), f"park.{a}: must be {model.dof} joint values "
                                 "within the limits")
            out[a] = q
            continue
        for x in (face_x - options.park_back, face_x):
            try:
                out[a] = park_configuration(rig, a, x)
                break
            except (ValueError, FieldError):
                continue
        else:
            out[a] = home_configuration(rig.arms[a], face_x)
    return out


def _park_objects(rig: Rig, name: str, q: np.ndarray, radii: np.ndarray) -> list[dict]:
    """Boom ``name`` at ``q`` as capsule scene objects (its links of non-zero length)."""
    from kinematics.fk import fk_frames

    F = fk_frames(rig.arms[name], q[None])[0, :, :3, 3]
    out = []
    for k in range(len(F) - 1):
        if np.linalg.norm(F[k + 1] - F[k]) > 1e-6:
            out.append({"type": "capsule", "id": f"{name}-park-link{k}", "a": F[k].tolist(),
                        "b": F[k + 1].tolist(), "radius": float(radii[k])})
    return out


def plan_round(rig: Rig, collars, toes, ids=None, options: RoundOptions | None = None, *,
               types: Sequence[str | None] | None = None,
               progress: ProgressFn | None = None) -> RoundResult:
    """Plan a whole round (module docstring): ``collars``, ``toes (N, 3)`` mm in the rig
    frame, ``ids`` (default ``"0"``, ``"1"``, ...), ``types`` per hole (for
    ``rates_by_type``). ``progress(fraction, message)``. ``FieldError`` naming the field at
    fault for bad input."""
    t_start = time.perf_counter()
    options = options or RoundOptions()
    report = progress or (lambda f, m: None)
    C, T, ids = _holes(collars, toes, ids)
    N = len(C)
    types = list(types) if types is not None else [None] * N
    booms = tuple(options.booms) if options.booms else tuple(rig.arms)
    for a in booms:
        if a not in rig.arms:
            raise FieldError("booms", f"booms: rig {rig.id!r} has no boom {a!r} "
                             f"(booms: {', '.join(rig.arms)})")
    model0 = rig.arms[booms[0]]
    radii = np.asarray(options.link_radii, dtype=float)
    if radii.shape != (model0.dof,) or np.any(radii <= 0):
        raise FieldError("link_radii", f"link_radii: must be {model0.dof} positive numbers")
    timing = {a: BoomTime.for_model(rig.arms[a], velocity=options.velocity,
                                    acceleration={**DEFAULT_ACCELERATION,
                                                  **(options.acceleration or {})})
              for a in booms}
    limits = {a: Limits(velocity=timing[a].velocity, acceleration=timing[a].acceleration)
              for a in booms}
    parks = _parks(rig, booms, C, options)
    cms = {a: RobotCollisionModel.from_model(rig.arms[a], link_radius=radii) for a in booms}
    geometry = {a: BoomGeometry.of(cms[a]) for a in booms}
    user = list(options.scene.objects) if options.scene is not None else []
    checkers = {}
    for a in booms:
        objs = [o for x in booms if x != a for o in _park_objects(rig, x, parks[x], radii)]
        scene = CollisionScene(user + list(CollisionScene.from_dicts(objs).objects))
        checkers[a] = MotionChecker(cms[a], scene, margin=options.clearance)
    notes: list[str] = []
    for a in booms:
        if not checkers[a].free(parks[a][None])[0]:
            notes.append(f"{a}: its park pose is within {options.clearance:g} mm of the scene "
                         "or another boom's park pose")
    report(0.05, "reach")
    reach = _reach(rig, booms, C, T, checkers, options, report)
    depth = np.linalg.norm(T - C, axis=1)
    rates = np.array([options.rate_mm_s(t) for t in types])
    feed_v = float(timing[booms[0]].velocity[FEED_JOINT])
    feed_a = float(timing[booms[0]].acceleration[FEED_JOINT])
    feed_v = feed_v if math.isfinite(feed_v) else 500.0
    feed_a = feed_a if math.isfinite(feed_a) else 500.0
    retract = np.array([max(options.retract_s, _feed_time(d + options.standoff, feed_v,
                                                          feed_a)) for d in depth])
    drill_s = options.collaring_s + depth / rates + retract
    if options.assignment is not None:
        owner = np.full(N, -1)
        for k, hid in enumerate(ids):
            a = options.assignment.get(hid)
            if a in booms and reach.ok[k, booms.index(a)]:
                owner[k] = booms.index(a)
    else:
        owner = _allocate(rig, booms, C, reach, drill_s, move_s=5.0)
    report(0.25, "allocated")
    # order
    orders: dict[str, list[int]] = {}
    for b, a in enumerate(booms):
        idx = np.flatnonzero(owner == b)
        if len(idx) >= 2 and options.order == "distance":
            start = fk(rig.arms[a], parks[a])[:3, 3]
            seq = sequence_holes(C[idx], start, "auto", options.seed + b)
            orders[a] = [int(i) for i in idx[seq.order]]
        elif len(idx) >= 2:
            qa = reach.q[idx, b].copy()
            qa[:, FEED_JOINT] -= options.standoff
            seq = sequence_by_boom_time(rig.arms[a], C[idx], q_start=parks[a],
                                        branches=qa[:, None, :], timing=timing[a],
                                        seed=options.seed + b)
            orders[a] = [int(i) for i in idx[seq.order]]
        else:
            orders[a] = [int(i) for i in idx]
    report(0.3, "ordered")
    # moves
    blocked: dict[int, str] = {}
    tasks: dict[str, list[_Task]] = {}
    for b, a in enumerate(booms):
        tasks[a] = _boom_tasks(a, rig.arms[a], checkers[a], parks[a], orders[a], reach, b,
                               C, T, ids, depth, rates, options, limits[a], feed_v, feed_a,
                               blocked)
        report(0.3 + 0.4 * (b + 1) / len(booms), f"moves of {a}")
    # priority
    work = {a: sum(t.duration for t in tasks[a]) for a in booms}
    if options.priority:
        pr = [a for a in options.priority if a in booms]
        priority = pr + [a for a in booms if a not in pr]
    else:
        priority = sorted(booms, key=lambda a: -work[a])
    clock = _Clock(geometry, options.clearance)
    plans: dict[str, BoomPlan] = {}
    t_free = 0.0
    for i, a in enumerate(priority):
        if options.schedule == "sequential":
            tl, waited, note = _after(parks[a], tasks[a], t_free)
            t_free = max(t_free, tl.end)
        else:
            tl, waited, note = _time_boom(clock, a, parks[a], tasks[a], options.wait_step_s)
        if note:
            notes.append(note)
        clock.timed[a] = tl
        plans[a] = BoomPlan(a, [ids[t.hole] for t in tasks[a] if t.hole is not None], tl, i,
                            waited, parks[a])
        report(0.7 + 0.2 * (i + 1) / len(booms), f"timed {a}")
    plans = {a: plans[a] for a in booms}
    # results
    holes: list[HolePlan] = []
    for b, a in enumerate(booms):
        tl = plans[a].timeline
        for hid in plans[a].holes:
            ph = [p for p in tl.phases if p.hole == hid and p.kind != "transfer"]
            k = ids.index(hid)
            holes.append(HolePlan(hid, a, ph[0].t0, ph[-1].t1, float(depth[k]),
                                  float(drill_s[k]), reach.q[k, b].copy()))
    holes.sort(key=lambda h: ids.index(h.id))
    unreachable = []
    for k in range(N):
        if owner[k] < 0:
            reason, detail = _reason(reach.why[k])
            unreachable.append({"id": ids[k], "reason": reason, "detail": detail})
        elif k in blocked:
            unreachable.append({"id": ids[k], "reason": "blocked", "detail": blocked[k]})
    drilled = np.array([ids.index(h.id) for h in holes], dtype=int)
    cycle = max((p.end_s for p in plans.values()), default=0.0)
    bound = float(drill_s[drilled].sum()) / len(booms) if len(drilled) else 0.0
    report(0.9, "checking")
    least, pair, when, count, step = round_clearance(
        {a: p.timeline for a, p in plans.items()}, geometry)
    scene_c = _scene_clearance(checkers, {a: p.timeline for a, p in plans.items()},
                               options.scene, options.scene_check_states)
    report(1.0, "done")
    return RoundResult(
        booms=plans, holes=holes, unreachable=unreachable, cycle_time_s=float(cycle),
        lower_bound_s=bound, min_boom_clearance_mm=least, clearance_pair=pair,
        clearance_t_s=when, checked_instants=count, max_step_mm=step,
        min_scene_clearance_mm=scene_c, planning_time_s=time.perf_counter() - t_start,
        notes=notes,
        stats={"priority": priority, "delay_checks": clock.checks,
               "work_s": {a: round(w, 3) for a, w in work.items()},
               "parks": {a: parks[a].tolist() for a in booms}})


def _reason(why: list[tuple[str, str]]) -> tuple[str, str]:
    """The reason reported for a hole no boom takes: the furthest along of the booms'
    (``blocked`` over ``axis_not_alignable`` over ``out_of_reach``), with every boom's
    detail."""
    rank = {r: i for i, r in enumerate(REASONS)}
    if not why:
        return "out_of_reach", "no boom"
    best = max(why, key=lambda w: rank[w[0]])[0]
    return best, "; ".join(d for _, d in why)
