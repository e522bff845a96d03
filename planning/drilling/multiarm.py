"""Whole-face planning for a multi-arm jumbo: allocation, sequencing, collision-free moves.

Paper 002, sections 3.3-3.4 and 4.2. For each arm: its holes (``allocation``), their
drilling order as an open path from the arm's parked position (``planning.sequencing``),
and a transfer between consecutive holes planned in joint space (``iapf.IAPF`` or the
``rrt.RRTConnect`` baseline) around the other arms' parked envelopes, smoothed with the
quintic B-spline of eqs. 14-18 (``planning.bspline.quintic_bspline``) and time-scaled to
the rate limits (``planning.time_scaling.fit_to_limits``).

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
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.drilling import DRILL_D7, drill_ik
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.rigs import Rig

from ..bspline import quintic_bspline
from ..sequencing import SequenceResult, sequence_holes
from ..status import PlanStatus
from ..time_scaling import fit_to_limits
from ..trajectory import Limits, Trajectory
from .allocation import Allocation, allocate_holes, home_configuration
from .envelopes import (
    ArmEnvelope,
    capsule_distances,
    capsules,
    drill_arm_envelope,
    min_distance,
)
from .iapf import IAPF, PathResult
from .rrt import RRTConnect
from .space import ArmSpace, Obstacles

__all__ = [
    "PLANNERS",
    "MotionLimits",
    "Move",
    "ArmTimeline",
    "ArmPlan",
    "FacePlan",
    "make_planner",
    "park_configuration",
    "plan_move",
    "smooth_path",
    "plan_face",
    "pair_distances",
]

PLANNERS: dict[str, type] = {"iapf": IAPF, "rrt": RRTConnect}
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
    path: PathResult
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
def pair_distances(rig: Rig, envelope: ArmEnvelope, q: Mapping[str, np.ndarray],
                   moving: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Signed distance (mm) between the envelopes of every pair of arms at every sample:
    ``q[arm] (S, 7)`` -> ``{"a-b": (S,)}``. With ``moving[arm] (S,) bool``, samples at which
    neither arm of a pair moves (and did not at the sample before) repeat the last value
    instead of being recomputed."""
    names = list(q)
    S = len(next(iter(q.values())))
    caps = {a: None for a in names}
    out: dict[str, np.ndarray] = {}
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
        out[f"{a}-{b}"] = full[pos]
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
    defaults; ``FieldError`` naming ``planner`` or ``planner_params.<name>``."""
    if name not in PLANNERS:
        raise FieldError("planner", f"planner: must be one of {', '.join(PLANNERS)}, "
                         f"got {name!r}")
    cls = PLANNERS[name]
    known = set(cls.__dataclass_fields__)
    for key in params or {}:
        if key not in known:
            raise FieldError(("planner_params", key), f"planner_params.{key}: not a parameter "
                             f"of {name} (known: {', '.join(sorted(known))})")
    return cls(**dict(params or {}))


def _arm_moves(space, obstacles, configs, planner, fallback, rng, limits, standoff,
               t0, drill_time_s, on_move=None
               ) -> tuple[ArmTimeline, list[tuple[PlanStatus, str]]]:
    """Moves through ``configs (K, 7)`` (first = where the arm is), starting at ``t0``; with
    the status and message of each failed move."""
    moves, starts, msgs = [], [], []
    t = t0
    for k in range(1, len(configs)):
        mv = plan_move(space, obstacles, configs[k - 1], configs[k], planner, rng,
                       limits=limits, standoff=standoff, fallback=fallback)
        if not mv.success:
            msgs.append((mv.status, f"move {k}: {mv.message}"))
        moves.append(mv)
        starts.append(t)
        t += mv.duration + drill_time_s
        if on_move is not None:
            on_move()
    return ArmTimeline(configs[0], tuple(moves), np.array(starts)), msgs


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
) -> FacePlan:
    """Plan a whole face for ``rig`` (e.g. ``builtin_rig("tunnel_jumbo")``).

    ``holes (N, 3)`` mm on the face (rig frame; the face plane is their mean x), or give a
    ready ``allocation``. ``planner``: ``"iapf"`` or ``"rrt"`` with ``planner_params``;
    ``sequencer`` and ``sequencer_params`` as ``planning.sequencing.sequence_holes``;
    ``balance`` / ``counts`` as ``allocation.allocate_holes``; ``radii`` as
    ``envelopes.drill_arm_envelope``; ``standoff`` (mm) the feed retraction between holes;
    ``drill_time_s`` the dwell on each hole; ``middle_park``: ``"last_hole"`` (the paper) or
    ``"home"``; ``fallback``: try the other planner on a move the first cannot plan
    (reported per arm in ``planner_counts``). Seeded and reproducible.
    """
    t_start = time.perf_counter()
    report = progress or (lambda f, m: None)
    if middle_park not in ("last_hole", "home"):
        raise FieldError("middle_park", "middle_park: must be 'last_hole' or 'home', got "
                         f"{middle_park!r}")
    if not 0 <= standoff <= 2000:
        raise FieldError("standoff", "standoff: must be in [0, 2000] mm")
    if not drill_time_s >= 0:
        raise FieldError("drill_time_s", "drill_time_s: must be >= 0")
    if not 1e-4 <= check_dt <= 0.1:
        raise FieldError("check_dt", "check_dt: must be in [0.0001, 0.1] s")
    limits = limits or MotionLimits()
    main = make_planner(planner, planner_params)
    other_name = "rrt" if planner == "iapf" else "iapf"
    backup = PLANNERS[other_name](safety=main.safety) if fallback else None
    envelope = drill_arm_envelope(radii)
    if allocation is None:
        allocation = allocate_holes(rig, holes, balance=balance, counts=counts)
    P = allocation.holes
    face_x = float(P[:, 0].mean())
    if np.ptp(P[:, 0]) > 1.0:
        raise FieldError("holes", "holes: all holes must lie on one face plane (same x within "
                         "1 mm)")
    arms = tuple(rig.arms)  # every arm is there, with holes or parked
    working = [a for a in arms if a in allocation.arms and len(allocation.indices[a])]
    rng = np.random.default_rng(seed)
    spaces = {a: ArmSpace(rig.arms[a], envelope, face_x) for a in arms}
    park = {a: park_configuration(rig, a, face_x) for a in arms}
    mounts = np.array([rig.arms[a].base[1, 3] for a in arms])
    middle = arms[int(np.argmin(np.abs(mounts - mounts.mean())))] if len(arms) > 2 else None
    n_moves = sum(len(allocation.indices[a]) for a in working) + 1
    done = [0]

    def tick() -> None:
        done[0] += 1
        report(0.05 + 0.85 * min(1.0, done[0] / n_moves), "planning moves")

    # sequencing, each arm from where it waits
    plans: dict[str, dict[str, Any]] = {}
    for k, a in enumerate(arms):
        idx = allocation.indices[a] if a in working else np.zeros(0, dtype=int)
        start = fk(rig.arms[a], park[a])[:3, 3]
        res = None
        order = idx
        if len(idx) >= 2:
            res = sequence_holes(P[idx], start, sequencer, seed + k, sequencer_params)
            order = idx[res.order]
        q_holes = allocation.q[a][np.searchsorted(idx, order)] if len(idx) else \
            np.zeros((0, 7))
        plans[a] = {"order": order, "sequence": res,
                    "configs": np.vstack([park[a][None], q_holes])}
    report(0.05, "sequenced")

    # failures, by the arm (or pair of arms) at fault: any makes the plan unsuccessful
    failures: list[tuple[str, PlanStatus, str]] = []
    notes: list[str] = []
    timelines = {a: ArmTimeline(park[a], (), np.zeros(0)) for a in arms}
    park_used = "none"
    # phase 1: the middle arm, the others parked
    t_phase2 = 0.0
    if middle in working:
        obs = Obstacles.of_arms({a: (rig.arms[a], park[a]) for a in arms if a != middle},
                                envelope)
        configs = plans[middle]["configs"]
        park_used = middle_park
        if middle_park == "last_hole" and not _park_ok(rig, envelope, middle, configs[-1],
                                                       plans, working, main.safety):
            park_used = "home"
            notes.append(f"{middle} returns home: parked on its last hole it would block "
                         "a side arm's hole")
        if park_used != "last_hole":
            configs = np.vstack([configs, park[middle][None]])
        tl, msgs = _arm_moves(spaces[middle], obs, configs, main, backup, rng, limits,
                              standoff, 0.0, drill_time_s, tick)
        failures += [(middle, st, f"{middle} {m}") for st, m in msgs]
        timelines[middle] = tl
        t_phase2 = tl.end
    # phase 2: the other arms at once, the middle arm (and idle arms) parked
    side = [a for a in working if a != middle]
    for a in side:
        parked = {x: (rig.arms[x], timelines[x].q_final) for x in arms
                  if x not in side}
        obs = Obstacles.of_arms(parked, envelope)
        tl, msgs = _arm_moves(spaces[a], obs, plans[a]["configs"], main, backup, rng, limits,
                              standoff, t_phase2, drill_time_s, tick)
        failures += [(a, st, f"{a} {m}") for st, m in msgs]
        timelines[a] = tl
    report(0.9, "checking")
    t, q, dist = _check(rig, envelope, timelines, check_dt)
    # side arms that meet: the later one waits for the earlier, planned around it
    for pair in list(dist):
        a, b = pair.split("-")
        if (dist[pair] < 0).any() and a in side and b in side:
            parked = {x: (rig.arms[x], timelines[x].q_final) for x in arms if x != b}
            obs = Obstacles.of_arms(parked, envelope)
            tl, msgs = _arm_moves(spaces[b], obs, plans[b]["configs"], main, backup, rng,
                                  limits, standoff, timelines[a].end, drill_time_s)
            failures = [f for f in failures if f[0] != b]
            failures += [(b, st, f"{b} {m}") for st, m in msgs]
            notes.append(f"{b} waits for {a}: running at once they would meet")
            timelines[b] = tl
            t, q, dist = _check(rig, envelope, timelines, check_dt)
    collisions = {p: int((d < 0).sum()) for p, d in dist.items()}
    for p, n in collisions.items():
        if n:
            failures.append((p, PlanStatus.COLLISION, f"{p}: envelopes overlap at {n} samples "
                             f"(closest {dist[p].min():.0f} mm)"))
    for a in arms:
        bad = ~rig.arms[a].within_limits(q[a], tol=1e-6)
        if bad.any():
            k = int(np.argmax(bad))
            names = rig.arms[a].limit_violations(q[a][k], tol=1e-6)
            failures.append((a, PlanStatus.OUT_OF_LIMITS,
                             f"{a}: {', '.join(names)} outside limits at t = {t[k]:.2f} s"))
    acc = _accelerations(q, t)
    arm_plans = {}
    for a in arms:
        tl = timelines[a]
        counts_used: dict[str, int] = {}
        for mv in tl.moves:
            counts_used[mv.path.planner] = counts_used.get(mv.path.planner, 0) + 1
        res = plans[a]["sequence"]
        straight = res.length if res is not None else (
            float(np.linalg.norm(P[plans[a]["order"][0]] - fk(rig.arms[a], park[a])[:3, 3]))
            if len(plans[a]["order"]) else 0.0)
        arm_plans[a] = ArmPlan(a, plans[a]["order"], res, tl, straight / 1000.0,
                               float(sum(mv.tool_path_m for mv in tl.moves)), counts_used)
    report(1.0, "done")
    status = failures[0][1] if failures else PlanStatus.OK
    return FacePlan(allocation, arm_plans, t, q, dist, collisions, status,
                    [m for _, _, m in failures],
                    planner, park_used, time.perf_counter() - t_start, acc,
                    {"face_x": face_x, "middle": middle, "phase2_start_s": t_phase2,
                     "notes": notes})


def _park_ok(rig, envelope, middle, q_last, plans, working, safety) -> bool:
    """Whether the middle arm parked at ``q_last`` leaves every side arm's holes clear."""
    obs = Obstacles.of_arms({middle: (rig.arms[middle], q_last)}, envelope)
    for a in working:
        if a == middle:
            continue
        C = capsules(rig.arms[a], plans[a]["configs"], envelope)
        d = capsule_distances(C, envelope.radii, obs.segments, obs.radii)
        if d.min() < safety:
            return False
    return True


def _check(rig, envelope, timelines, check_dt):
    end = max(tl.end for tl in timelines.values())
    n = int(math.floor(end / check_dt + 1e-9)) + 1
    t = np.arange(n) * check_dt
    if t[-1] < end - 1e-9:
        t = np.append(t, end)
    q, moving = {}, {}
    for a, tl in timelines.items():
        q[a], moving[a] = tl.evaluate(t)
    return t, q, pair_distances(rig, envelope, q, moving)


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
