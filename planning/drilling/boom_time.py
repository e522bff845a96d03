"""What a drilling boom spends between holes: travel time in joint space, and the drilling
order (with each hole's IK branch) that minimises it.

Time model (``BoomTime``): all joints move at once and the slowest decides, so a move from
``q_a`` to ``q_b`` takes ``max_j g_j(|q_b,j - q_a,j|)`` with ``g_j(x) = x / v_j`` at joint
speed ``v_j`` (rad/s or mm/s), or, with an acceleration ``a_j`` too, the rest-to-rest
trapezoid ``x / v_j + v_j / a_j`` (``2 sqrt(x / a_j)`` when the speed is not reached). A
joint driven by hydraulic cylinders (``kinematics.cylinders``, declared in the model) whose
cylinder speeds are given is timed by its cylinders instead: ``|L_b - L_a| / v_cyl`` for
each cylinder (its length is monotonic in the joint over the joint's range, so that is the
stroke it travels), at the cylinder's extension or retraction speed as it lengthens or
shortens (the ``max_extension_speed`` / ``max_retraction_speed`` of the model's cylinder
data, or given); without cylinder speeds the joint speed is used. A move and its reverse
can then differ in time: the order search works on the mean of the two (and the least over
branches, ``planning.sequencing.branches``), every time reported is the directed one. The
feed's retraction and advance at each hole are the same for every order and are left out.

Branches: ``drill_ik`` holds the roll joint at a given value; at each roll value the arm
reaches a hole in a different configuration (the feed turned to another side of the boom,
swing, pitch, telescope and compensation joints changed to keep the drill perpendicular).
``drill_branches`` solves every hole at the rolls ``DEFAULT_ROLLS`` (0, +-90 deg, +-180
deg); the order and the branch of every hole are chosen together
(``planning.sequencing.branches``: order on the least time between any branches of two
holes, then the best branches for that order by dynamic programming, alternated).

Speeds: the tunnel drilling arm's data (paper 002) prints none. ``DRILL_ARM_SPEEDS`` takes
swing, pitch and telescope from ``multiarm.MotionLimits`` (0.2 rad/s, 0.2 rad/s, 400 mm/s)
and assumes roll 0.5 rad/s, compensation joints 0.3 rad/s (not limiting while they follow
the swing and pitch) and feed 500 mm/s. A model's own joint ``velocity`` limits take
precedence over these defaults; a joint with neither is not timed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from kinematics.cylinders import cylinder_set
from kinematics.drilling import DRILL_D7, ROLL_JOINT, drill_ik
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.model import RobotModel

from ..registry import make
from ..sequencing import SequenceResult, sequence_holes
from ..sequencing.base import check_holes
from ..sequencing.branches import best_alternatives, sequence_with_alternatives

__all__ = [
    "COSTS",
    "DEFAULT_ROLLS",
    "DRILL_ARM_SPEEDS",
    "BoomTime",
    "BoomSequence",
    "drill_branches",
    "order_time",
    "sequence_by_boom_time",
    "sequence_arm",
]

#: What a sequence minimises: tool path length (mm) or boom travel time (s).
COSTS = ("distance", "time")
#: Roll joint values (rad) at which ``drill_branches`` solves each hole.
DEFAULT_ROLLS = (0.0, math.pi / 2, -math.pi / 2, math.pi, -math.pi)
#: Assumed joint speeds of the tunnel drilling arm, by joint name (rad/s, mm/s).
DRILL_ARM_SPEEDS: Mapping[str, float] = {
    "swing": 0.2, "pitch": 0.2, "telescope": 400.0, "roll": 0.5,
    "pitch_compensation": 0.3, "swing_compensation": 0.3, "feed": 500.0,
}
#: Largest speed or acceleration taken (rad/s, mm/s and per s).
MAX_RATE = 1e6


def _rates(model: RobotModel, given: Mapping[str, float] | None, defaults: Mapping[str, float],
           field_name: str, own: np.ndarray | None) -> np.ndarray:
    """Per joint: the given rate, else the model's own, else the default, else inf."""
    names = [j.name for j in model.joints]
    for name, v in (given or {}).items():
        if name not in names:
            raise FieldError((field_name, name), f"{field_name}.{name}: {model.id} has no joint "
                             f"{name!r} (joints: {', '.join(names)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= MAX_RATE:
            raise FieldError((field_name, name), f"{field_name}.{name}: must be a number in "
                             f"(0, {MAX_RATE:g}]")
    out = np.full(model.dof, math.inf)
    for j, name in enumerate(names):
        if given and name in given:
            out[j] = float(given[name])
        elif own is not None and math.isfinite(own[j]):
            out[j] = float(own[j])
        elif name in defaults:
            out[j] = float(defaults[name])
    return out


def _ramp(x: np.ndarray, v: float, a: float) -> np.ndarray:
    """Rest-to-rest time over distances ``x >= 0`` at speed ``v`` and acceleration ``a``."""
    if math.isinf(a):
        return x / v if math.isfinite(v) else np.zeros_like(x)
    if math.isinf(v):
        return 2.0 * np.sqrt(x / a)
    return np.where(x >= v * v / a, x / v + v / a, 2.0 * np.sqrt(x / a))


@dataclass(frozen=True, eq=False)
class BoomTime:
    """Travel time of ``model`` between configurations (module docstring).

    ``velocity (dof,)`` and ``acceleration (dof,)`` per joint (inf: not limiting);
    ``cylinder_speeds``: ``(extending, retracting)`` mm/s by cylinder name, for the model's
    declared cylinders (a cylinder's time depends on the direction it moves, so a move and
    its reverse may differ). Build it with ``for_model``."""

    model: RobotModel
    velocity: np.ndarray
    acceleration: np.ndarray
    cylinder_speeds: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @classmethod
    def for_model(cls, model: RobotModel, velocity: Mapping[str, float] | None = None,
                  acceleration: Mapping[str, float] | None = None,
                  cylinder_speeds: Mapping[str, Any] | None = None,
                  defaults: Mapping[str, float] = DRILL_ARM_SPEEDS,
                  hydraulics: bool = True) -> BoomTime:
        """Joint speeds: ``velocity`` (by joint name), else the model's own limits, else
        ``defaults``; accelerations only where given. Cylinder speeds (mm/s, by name; a
        number, or ``(extending, retracting)``): ``cylinder_speeds``, else, with
        ``hydraulics``, the ``max_extension_speed`` / ``max_retraction_speed`` the model's
        cylinder data declares (one of the two serves both ways). ``FieldError`` naming
        the entry at fault (``velocity.swing``, ``cylinder_speeds.boom``)."""
        v = _rates(model, velocity, defaults, "velocity", model.velocity_limits)
        a = _rates(model, acceleration, {}, "acceleration", None)
        declared = "cylinders" in model.extras
        if cylinder_speeds and not declared:
            raise FieldError("cylinder_speeds", f"cylinder_speeds: {model.id} declares no "
                             "cylinders")
        cyl: dict[str, tuple[float, float]] = {}
        if declared:
            cs = cylinder_set(model)
            if cylinder_speeds:
                for name, sp in cylinder_speeds.items():
                    if name not in cs.names:
                        raise FieldError(("cylinder_speeds", name), f"cylinder_speeds.{name}: "
                                         f"{model.id} has no cylinder {name!r} (cylinders: "
                                         f"{', '.join(cs.names)})")
                    pair = (sp, sp) if isinstance(sp, (int, float)) else tuple(sp)
                    if len(pair) != 2 or any(
                            isinstance(x, bool) or not isinstance(x, (int, float))
                            or not 0 < x <= MAX_RATE for x in pair):
                        raise FieldError(("cylinder_speeds", name), f"cylinder_speeds.{name}: "
                                         f"must be a number in (0, {MAX_RATE:g}] mm/s or two")
                    cyl[name] = (float(pair[0]), float(pair[1]))
            elif hydraulics:
                for name, h in getattr(cs, "hydraulics", {}).items():
                    up = getattr(h, "max_extension_speed", None)
                    down = getattr(h, "max_retraction_speed", None)
                    if up is not None or down is not None:
                        cyl[name] = (float(up if up is not None else down),
                                     float(down if down is not None else up))
        return cls(model, v, a, cyl)

    @classmethod
    def planned_joints(cls, model: RobotModel, velocity, acceleration,
                       joints=(0, 1, 2)) -> BoomTime:
        """Only ``joints`` timed, at ``velocity``/``acceleration (len(joints),)``: the
        multi-arm planner's transfer, which moves swing, pitch and telescope at its limits
        with the compensation joints following the rule."""
        v = np.full(model.dof, math.inf)
        a = np.full(model.dof, math.inf)
        v[list(joints)] = velocity
        a[list(joints)] = acceleration
        return cls(model, v, a, {})

    @property
    def _cylinder_joints(self) -> dict[int, list[str]]:
        """Joint index -> its cylinders that have a speed."""
        if not self.cylinder_speeds:
            return {}
        cs = cylinder_set(self.model)
        out: dict[int, list[str]] = {}
        for name in self.cylinder_speeds:
            out.setdefault(cs.joint_of(name), []).append(name)
        return out

    def features(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the time is read from: ``q (*, dof)`` -> ``(*, K)`` (the timed joints not
        driven by cylinders with speeds, then those cylinders' lengths; NaN rows stay NaN),
        the speeds ``(2, K)`` while a feature grows (row 0) and shrinks (row 1), and the
        accelerations ``(K,)``."""
        q = np.asarray(q, dtype=float)
        cj = self._cylinder_joints
        joints = [j for j in range(self.model.dof) if j not in cj
                  and (math.isfinite(self.velocity[j]) or math.isfinite(self.acceleration[j]))]
        cols = [q[..., j] for j in joints]
        up = [self.velocity[j] for j in joints]
        down = list(up)
        a = [self.acceleration[j] for j in joints]
        if cj:
            flat = q.reshape(-1, self.model.dof)
            ok = np.all(np.isfinite(flat), axis=1)
            lengths = cylinder_set(self.model).lengths(flat[ok]) if ok.any() else {}
            for names in cj.values():
                for name in names:
                    L = np.full(len(flat), np.nan)
                    if ok.any():
                        L[ok] = lengths[name]
                    cols.append(L.reshape(q.shape[:-1]))
                    up.append(self.cylinder_speeds[name][0])
                    down.append(self.cylinder_speeds[name][1])
                    a.append(math.inf)
        F = np.stack(cols, axis=-1) if cols else np.zeros((*q.shape[:-1], 0))
        return F, np.array([up, down], dtype=float).reshape(2, -1), np.array(a)

    def cost_fn(self):
        """``cost(Fa (P, K), Fb (Q, K)) -> (P, Q)``: seconds from each row of ``Fa`` to each
        of ``Fb`` (feature rows as ``features`` makes them)."""
        _, v, a = self.features(np.zeros(self.model.dof))

        def cost(Fa: np.ndarray, Fb: np.ndarray) -> np.ndarray:
            T = np.zeros((len(Fa), len(Fb)))
            for k in range(Fa.shape[1]):
                x = Fb[None, :, k] - Fa[:, k, None]
                if v[0, k] == v[1, k]:
                    t = _ramp(np.abs(x), v[0, k], a[k])
                else:
                    t = np.maximum(_ramp(np.maximum(x, 0.0), v[0, k], a[k]),
                                   _ramp(np.maximum(-x, 0.0), v[1, k], a[k]))
                np.maximum(T, t, out=T)
            return T

        return cost

    def move_times(self, qa, qb) -> np.ndarray:
        """Seconds of every move from ``qa (P, dof)`` to ``qb (Q, dof)``: ``(P, Q)``."""
        Fa, _, _ = self.features(np.atleast_2d(qa))
        Fb, _, _ = self.features(np.atleast_2d(qb))
        return self.cost_fn()(Fa, Fb)

    def path_time(self, q, q_start=None) -> float:
        """Seconds to visit the configurations ``q (N, dof)`` in turn (from ``q_start``)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q_start is not None:
            q = np.vstack([np.asarray(q_start, dtype=float)[None], q])
        if len(q) < 2:
            return 0.0
        F, _, _ = self.features(q)
        cost = self.cost_fn()
        return float(sum(cost(F[k - 1 : k], F[k : k + 1])[0, 0] for k in range(1, len(F))))


def drill_branches(model: RobotModel, holes, rolls=DEFAULT_ROLLS, d7: float = DRILL_D7,
                   name: str = "holes") -> np.ndarray:
    """Drilling configurations of every hole at every roll: ``holes (N, 3)`` mm ->
    ``(N, R, dof)`` with NaN where ``drill_ik`` finds none within the joint limits.
    ``FieldError`` at ``(name, k)`` naming the first hole no roll reaches, with the reason
    at roll 0."""
    P = np.asarray(holes, dtype=float).reshape(-1, 3)
    rolls = tuple(float(r) for r in rolls)
    if not rolls:
        raise FieldError("rolls", "rolls: need at least one roll value")
    Q = np.full((len(P), len(rolls), model.dof), np.nan)
    why: list[str] = [""] * len(P)
    for b, r in enumerate(rolls):
        for k, res in enumerate(drill_ik(model, P, d7=d7, roll=r)):
            if res.success:
                Q[k, b] = res.q
            elif b == 0 or not why[k]:
                why[k] = res.message.split(": ", 1)[-1]
    lost = ~np.all(np.isfinite(Q), axis=2).any(axis=1)
    if lost.any():
        k = int(np.argmax(lost))
        raise FieldError((name, k), f"{name}[{k}]: out of reach of {model.id} drilling "
                         f"perpendicular to the face at any roll ({why[k]})")
    return Q


@dataclass(frozen=True)
class BoomSequence:
    """A drilling order chosen for boom time. ``order (N,)`` hole indices; ``q (N, dof)``
    the configuration at each hole in drilling order (its IK branch: ``roll (N,)`` rad);
    ``time_s`` the boom travel time from the start; ``length`` the tool path (mm, from the
    start point). ``distance_order``, its ``distance_time_s`` (best branches for that order)
    and ``distance_length``: the shortest-path order, for comparison; ``saved_s`` =
    ``distance_time_s - time_s``."""

    order: np.ndarray
    q: np.ndarray
    roll: np.ndarray
    time_s: float
    length: float
    distance_order: np.ndarray
    distance_time_s: float
    distance_length: float
    lower_bound_s: float
    rounds: int
    runtime_s: float

    @property
    def saved_s(self) -> float:
        return self.distance_time_s - self.time_s


def _tool_length(holes: np.ndarray, order: np.ndarray, start: np.ndarray | None) -> float:
    P = holes[order]
    if start is not None:
        P = np.vstack([start[None], P])
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def order_time(order, Q, q_start, timing: BoomTime) -> tuple[np.ndarray, float]:
    """The best branch of each hole for a drilling ``order (N,)`` of holes with branches
    ``Q (N, B, dof)`` from ``q_start (dof,)`` (None: the first hole drilled first): the
    branch index per hole in drilling order ``(N,)`` and the boom time, s."""
    F, _, _ = timing.features(Q)
    f0 = None if q_start is None else timing.features(np.asarray(q_start, dtype=float))[0]
    return best_alternatives(order, F, f0, timing.cost_fn())


def sequence_by_boom_time(
    model: RobotModel,
    holes,
    *,
    start=None,
    q_start=None,
    rolls=DEFAULT_ROLLS,
    branches: np.ndarray | None = None,
    timing: BoomTime | None = None,
    algorithm: str = "auto",
    params: Mapping[str, Any] | None = None,
    seed: int = 0,
    rounds: int = 6,
    distance_order=None,
) -> BoomSequence:
    """The drilling order of ``holes (N, 3)`` (mm, ``model``'s world frame) and each hole's
    IK branch that minimise the boom's travel time (``timing``, default
    ``BoomTime.for_model(model)``).

    The arm starts at ``q_start (dof,)`` or, given only ``start (3,)`` (mm), at its roll-0
    drilling configuration there; with neither, the first hole is drilled first. Branches:
    ``branches (N, B, dof)`` (NaN rows: none) or ``drill_branches(model, holes, rolls)``.
    ``algorithm``/``params`` pick the sequencer of the first order (``auto`` by default; the
    alternation of order and branches uses ``auto``'s local search). ``distance_order`` (hole
    indices) is the shortest-path order to compare with (default: ``auto`` on the hole
    positions from the start). Seeded and reproducible. ``FieldError`` naming the field at
    fault."""
    P = check_holes(holes)
    timing = timing or BoomTime.for_model(model)
    Q = drill_branches(model, P, rolls) if branches is None else \
        np.asarray(branches, dtype=float)
    if Q.shape[:1] != (len(P),) or Q.ndim != 3 or Q.shape[2] != model.dof:
        raise FieldError("branches", f"branches: must have shape ({len(P)}, B, {model.dof})")
    if q_start is not None:
        q0 = np.asarray(q_start, dtype=float).reshape(-1)
        if q0.shape != (model.dof,) or not np.all(np.isfinite(q0)):
            raise FieldError("q_start", f"q_start: must be {model.dof} finite joint values")
        start_pt = fk(model, q0)[:3, 3] if start is None else np.asarray(start, dtype=float)
    elif start is not None:
        start_pt = np.asarray(start, dtype=float).reshape(-1)
        res = drill_ik(model, start_pt)[0]
        if not res.success:
            raise FieldError("start", f"start: the arm cannot be there drilling (roll 0): "
                             f"{res.message.split(': ', 1)[-1]}")
        q0 = res.q
    else:
        q0, start_pt = None, None
    F, _, _ = timing.features(Q)
    f0 = None if q0 is None else timing.features(q0)[0]
    cost = timing.cost_fn()
    if distance_order is None:
        distance_order = sequence_holes(P, start_pt, "auto", seed).order
    distance_order = np.asarray(distance_order, dtype=int)
    _, dist_time = best_alternatives(distance_order, F, f0, cost)
    auto = make("sequencer", "auto", params if algorithm == "auto" else None)
    seq = sequence_with_alternatives(F, f0, cost, seed=seed, params=auto,
                                     sequencer=make("sequencer", algorithm, params),
                                     rounds=rounds, candidates=[distance_order])
    Qo = Q[seq.order, seq.branch]
    roll = Qo[:, ROLL_JOINT] if model.dof > ROLL_JOINT else np.zeros(len(P))
    return BoomSequence(
        order=seq.order, q=Qo, roll=roll, time_s=seq.cost,
        length=_tool_length(P, seq.order, start_pt),
        distance_order=distance_order, distance_time_s=dist_time,
        distance_length=_tool_length(P, distance_order, start_pt),
        lower_bound_s=seq.lower_bound_cost, rounds=seq.rounds, runtime_s=seq.runtime_s)


def sequence_arm(holes, q_holes, q_park, start, timing: BoomTime, *, cost: str = "distance",
                 algorithm: str = "auto", params: Mapping[str, Any] | None = None,
                 seed: int = 0) -> SequenceResult:
    """One arm's drilling order for ``plan_face``: ``holes (n, 3)`` mm with their drilling
    configurations ``q_holes (n, dof)`` (one branch each), the arm parked at ``q_park`` with
    its tool at ``start (3,)`` mm. ``cost="distance"``: ``sequence_holes`` as ever;
    ``"time"``: the order of least boom time (``timing``). Either way ``extra`` carries
    ``cost``, ``boom_time_s`` (the order's) and ``boom_time_distance_order_s`` (the
    shortest-path order's)."""
    if cost not in COSTS:
        raise FieldError("cost", f"cost: must be one of {', '.join(COSTS)}, got {cost!r}")
    P = np.asarray(holes, dtype=float)
    Q = np.asarray(q_holes, dtype=float)[:, None, :]
    dist = sequence_holes(P, start, algorithm, seed, params)
    _, dist_time = order_time(dist.order, Q, q_park, timing)
    if cost == "distance":
        extra = {**dist.extra, "cost": cost, "boom_time_s": dist_time,
                 "boom_time_distance_order_s": dist_time}
        return replace(dist, extra=extra)
    seq = sequence_by_boom_time(timing.model, P, start=start, q_start=q_park, branches=Q,
                                timing=timing, algorithm=algorithm, params=params, seed=seed,
                                distance_order=dist.order)
    return SequenceResult(
        order=seq.order, length=seq.length, history=np.array([seq.length]),
        runtime_s=dist.runtime_s + seq.runtime_s, evaluations=dist.evaluations,
        iterations=1, algorithm=dist.algorithm,
        message=f"least boom time: {seq.time_s:.1f} s, {seq.saved_s:.1f} s less than the "
                f"shortest path's order ({seq.distance_time_s:.1f} s)",
        extra={"cost": cost, "boom_time_s": seq.time_s,
               "boom_time_distance_order_s": seq.distance_time_s})
