"""Allocation of a face's holes to the arms of a rig (paper 002, section 5: 40 / 52 / 40).

A hole can go to an arm only if the arm reaches it drilling perpendicular to the face within
its joint limits (``kinematics.drilling.drill_ik`` succeeds). Among those, holes go to arms
in vertical strips across the face, each arm taking the holes nearest its own side (the cost
of giving hole h to arm a is ``((y_h - y_a) / 1 m)^2``, ``y_a`` = the arm's mount across the
face), subject to a target number of holes per arm. The targets are

* ``balance="count"`` (default): equal shares, the remainder to the arms nearest the middle;
* ``balance="work"``: start from equal shares and move one hole at a time from the arm with
  the most work to the one with the least, work = ``drill_time_s`` per hole plus the travel
  of its drilling order (``planning.sequencing``, ``auto``) at ``travel_speed`` mm/s, while
  that lowers the largest work;
* ``counts={"left": 40, "middle": 52, "right": 40}``: given (the paper's split).

The assignment with targets is a transportation problem, solved exactly as an assignment of
holes to arm "slots" (``scipy.optimize.linear_sum_assignment``): each arm has its target
number of ordinary slots and, for holes that only it can reach, overflow slots whose
penalty dwarfs any lateral cost. So reach always wins over balance, and balance over
geometry. Holes no arm reaches raise ``FieldError`` naming them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from kinematics.drilling import DRILL_D7, drill_ik
from kinematics.errors import FieldError, loc_from_path
from kinematics.fk import fk
from kinematics.model import RobotModel
from kinematics.rigs import Rig

from ..sequencing import sequence_holes
from ..sequencing.base import check_holes

__all__ = [
    "Allocation",
    "allocate_holes",
    "assign_holes",
    "home_configuration",
    "home_tip",
    "reach_table",
]

#: Cost of an overflow slot (above an arm's target), in units of (1 m)^2 lateral cost.
OVERFLOW_COST = 1e6
#: Cost standing for "cannot reach" (never chosen while any other assignment exists).
UNREACHABLE_COST = 1e12
#: Sequencer settings of the travel estimate in ``balance="work"`` (a short local search).
QUICK_SEQUENCING = {"kicks": 50, "restarts": 1, "stall": 25}
#: Holes listed by name in an out-of-reach error before "and N more".
LIST_MAX = 8


@dataclass(frozen=True)
class Allocation:
    """Which arm drills which hole. ``arm_of (N,)`` arm index per hole (into ``arms``);
    ``indices[name] (n_a,)`` the hole indices of each arm (ascending); ``q[name] (n_a, 7)``
    the drilling configurations of those holes (rad / mm); ``reach (N, A)`` whether each arm
    reaches each hole; ``targets`` the per-arm hole counts aimed for."""

    arms: tuple[str, ...]
    holes: np.ndarray
    arm_of: np.ndarray
    indices: dict[str, np.ndarray]
    q: dict[str, np.ndarray]
    reach: np.ndarray
    targets: dict[str, int]
    extras: dict = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        return {a: int(len(self.indices[a])) for a in self.arms}


def reach_table(rig: Rig, holes: np.ndarray, arms: tuple[str, ...], d7: float = DRILL_D7
                ) -> tuple[np.ndarray, np.ndarray, list[list[str]]]:
    """Per arm and hole: reachable within limits drilling perpendicular to the face.
    Returns ``reach (N, A)``, ``q (N, A, 7)`` (NaN where unreachable) and per hole the
    messages of the arms that fail (for error reports)."""
    N, A = len(holes), len(arms)
    reach = np.zeros((N, A), dtype=bool)
    q = np.full((N, A, 7), np.nan)
    why: list[list[str]] = [[] for _ in range(N)]
    for a, name in enumerate(arms):
        for k, r in enumerate(drill_ik(rig.arms[name], holes, d7=d7)):
            if r.success:
                reach[k, a] = True
                q[k, a] = r.q
            else:
                why[k].append(f"{name}: {r.message.split(': ', 1)[-1]}")
    return reach, q, why


def _equal_targets(n: int, arms: tuple[str, ...], lateral: np.ndarray) -> dict[str, int]:
    base, extra = divmod(n, len(arms))
    centre = np.mean(lateral)
    priority = np.argsort(np.abs(lateral - centre), kind="stable")  # middle arms first
    targets = {a: base for a in arms}
    for k in priority[:extra]:
        targets[arms[k]] += 1
    return targets


def _assign(holes: np.ndarray, reach: np.ndarray, lateral: np.ndarray,
            targets: Mapping[str, int], arms: tuple[str, ...]) -> np.ndarray:
    """Arm index per hole minimising the lateral cost with the targets as soft capacities."""
    N, A = reach.shape
    lat = ((holes[:, 1][:, None] - lateral[None, :]) / 1000.0) ** 2  # (N, A)
    # Ties (holes in one vertical column) are broken by height, so strips stay clean.
    lat = lat + 1e-9 * holes[:, 2][:, None] * np.arange(A)[None, :]
    cols, owner = [], []
    for a, name in enumerate(arms):
        t = int(targets[name])
        slot_cost = np.where(reach[:, a], lat[:, a], UNREACHABLE_COST)
        cols.append(np.repeat(slot_cost[:, None], t, axis=1))
        over = np.where(reach[:, a], lat[:, a] + OVERFLOW_COST, UNREACHABLE_COST)
        cols.append(np.repeat(over[:, None], N, axis=1))
        owner.extend([a] * (t + N))
    cost = np.concatenate(cols, axis=1)
    rows, c = linear_sum_assignment(cost)
    arm_of = np.empty(N, dtype=int)
    arm_of[rows] = np.asarray(owner)[c]
    return arm_of


def allocate_holes(
    rig: Rig,
    holes,
    *,
    arms: tuple[str, ...] | None = None,
    balance: str = "count",
    counts: Mapping[str, int] | None = None,
    d7: float = DRILL_D7,
    drill_time_s: float = 60.0,
    travel_speed: float = 250.0,
    max_rounds: int = 40,
) -> Allocation:
    """Allocate ``holes (N, 3)`` (mm, rig frame) to the rig's ``arms`` (default: all).

    ``balance``: ``"count"`` or ``"work"`` (see the module docstring); ``counts`` fixes the
    number of holes per arm instead (must add up to N). ``d7``: feed joint value at the holes
    (mm). ``FieldError`` naming the field at fault; holes no arm reaches are named with
    each arm's reason.
    """
    P = check_holes(holes, "holes")
    arms = tuple(rig.arms) if arms is None else tuple(arms)
    for name in arms:
        if name not in rig.arms:
            raise FieldError("arms", f"arms: rig {rig.id!r} has no arm {name!r} "
                             f"(arms: {', '.join(rig.arms)})")
    if not arms:
        raise FieldError("arms", "arms: need at least one arm")
    if balance not in ("count", "work"):
        raise FieldError("balance", f"balance: must be 'count' or 'work', got {balance!r}")
    reach, q_all, why = reach_table(rig, P, arms, d7)
    lost = np.flatnonzero(~reach.any(axis=1))
    if len(lost):
        listed = "; ".join(
            f"holes[{k}] {P[k].round(1).tolist()} ({' | '.join(why[k])})" for k in lost[:LIST_MAX]
        )
        more = f"; and {len(lost) - LIST_MAX} more" if len(lost) > LIST_MAX else ""
        raise FieldError("holes", f"holes: {len(lost)} out of reach of every arm: "
                         f"{listed}{more}")
    lateral = np.array([rig.arms[a].base[1, 3] for a in arms])
    N = len(P)
    if counts is not None:
        unknown = [a for a in counts if a not in arms]
        if unknown:
            raise FieldError(("counts", unknown[0]), f"counts.{unknown[0]}: not one of the "
                             f"arms ({', '.join(arms)})")
        missing = [a for a in arms if a not in counts]
        if missing:
            raise FieldError(("counts", missing[0]), f"counts.{missing[0]}: missing")
        for a in arms:
            c = counts[a]
            if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or c < 0:
                raise FieldError(("counts", a), f"counts.{a}: must be a non-negative whole "
                                 "number")
        if sum(int(counts[a]) for a in arms) != N:
            raise FieldError("counts", f"counts: must add up to the {N} holes, got "
                             f"{sum(int(counts[a]) for a in arms)}")
        targets = {a: int(counts[a]) for a in arms}
    else:
        targets = _equal_targets(N, arms, lateral)
    arm_of = _assign(P, reach, lateral, targets, arms)
    extras: dict = {}
    if balance == "work" and counts is None:
        arm_of, targets, extras = _balance_work(rig, P, reach, lateral, targets, arms, arm_of,
                                                drill_time_s, travel_speed, max_rounds)
    indices = {a: np.flatnonzero(arm_of == k) for k, a in enumerate(arms)}
    q = {a: q_all[indices[a], k] for k, a in enumerate(arms)}
    return Allocation(arms, P, arm_of, indices, q, reach, targets, extras)


def assign_holes(rig: Rig, holes: Mapping[str, Any], d7: float = DRILL_D7,
                 name: str = "holes") -> Allocation:
    """An allocation given per arm: ``{"left": (n_l, 3), "middle": ..., ...}`` mm (rig
    frame). Checks the arm names, every list (``check_holes``), duplicates across arms, at
    least 2 holes in all, and that each arm reaches its own holes; ``FieldError`` naming
    the field, e.g. ``holes.left[3]`` (``name`` is a field path). Holes are numbered arm by
    arm, in the order given."""
    loc = loc_from_path(name)
    if not isinstance(holes, Mapping) or not holes:
        raise FieldError(loc, f"{name}: must map arm names to hole lists")
    arms = tuple(a for a in rig.arms if a in holes)
    for a in holes:
        if a not in rig.arms:
            raise FieldError((*loc, a), f"{name}.{a}: rig {rig.id!r} has no arm {a!r} "
                             f"(arms: {', '.join(rig.arms)})")
    per_arm = {a: check_holes(holes[a], f"{name}.{a}", min_count=0) for a in arms}
    P = np.concatenate([per_arm[a] for a in arms])
    label = [f"{name}.{a}[{k}]" for a in arms for k in range(len(per_arm[a]))]
    hole_locs = [(*loc, a, k) for a in arms for k in range(len(per_arm[a]))]
    if len(P) < 2:
        raise FieldError(loc, f"{name}: need at least 2 holes in all, got {len(P)}")
    check_holes(P, name, labels=label)  # duplicates across arms
    arm_of = np.concatenate([np.full(len(per_arm[a]), k) for k, a in enumerate(arms)])
    reach, q_all, why = reach_table(rig, P, arms, d7)
    mine = reach[np.arange(len(P)), arm_of]
    if not mine.all():
        k = int(np.argmin(mine))
        own = [w for w in why[k] if w.startswith(f"{arms[arm_of[k]]}:")]
        raise FieldError(hole_locs[k], f"{label[k]}: {P[k].round(1).tolist()} is out of reach "
                         f"of the {arms[arm_of[k]]} arm ({own[0] if own else 'unreachable'})")
    indices = {a: np.flatnonzero(arm_of == k) for k, a in enumerate(arms)}
    q = {a: q_all[indices[a], k] for k, a in enumerate(arms)}
    targets = {a: int(len(indices[a])) for a in arms}
    return Allocation(arms, P, arm_of, indices, q, reach, targets, {"given": True})


def home_configuration(model: RobotModel, face_x: float, d7: float = DRILL_D7) -> np.ndarray:
    """The paper's initial pose (Table 3, row 1: swing 0, boom level, roll 0, compensation
    90 deg / 90 deg) with the telescope set so the drill tip touches the face plane
    ``x = face_x`` (rig frame, mm). ``(7,)``; ``FieldError`` naming ``face_x`` if the
    telescope cannot reach it within its limits."""
    q = np.array([0.0, -np.pi / 2, 0.0, 0.0, np.pi / 2, np.pi / 2, d7])
    q1 = q.copy()
    q1[2] = 1.0
    x0, x1 = fk(model, q)[0, 3], fk(model, q1)[0, 3]
    q[2] = (face_x - x0) / (x1 - x0)
    lo, hi = model.joints[2].lower, model.joints[2].upper
    if not lo <= q[2] <= hi:
        raise FieldError("face_x", f"face_x: {face_x:g} mm needs telescope {q[2]:.0f} mm for "
                         f"{model.id}'s home pose, outside {lo:g}..{hi:g} mm")
    return q


def home_tip(model: RobotModel, face_x: float, d7: float = DRILL_D7) -> np.ndarray:
    """Drill tip of ``home_configuration`` (mm, rig frame) ``(3,)``: the arm's start."""
    return fk(model, home_configuration(model, face_x, d7))[:3, 3]


def _work(rig, P, arm_of, arms, drill_time_s, travel_speed) -> np.ndarray:
    out = np.zeros(len(arms))
    for k, a in enumerate(arms):
        idx = np.flatnonzero(arm_of == k)
        if len(idx) == 0:
            continue
        start = home_tip(rig.arms[a], float(P[idx, 0].mean()))
        # a quick estimate: one short run of the local search
        travel = sequence_holes(P[idx], start, "auto", seed=0, params=QUICK_SEQUENCING).length \
            if len(idx) >= 2 else float(np.linalg.norm(P[idx[0]] - start))
        out[k] = len(idx) * drill_time_s + travel / travel_speed
    return out


def _balance_work(rig, P, reach, lateral, targets, arms, arm_of, drill_time_s, travel_speed,
                  max_rounds):
    work = _work(rig, P, arm_of, arms, drill_time_s, travel_speed)
    history = [work.max()]
    for _ in range(max_rounds):
        hi, lo = int(np.argmax(work)), int(np.argmin(work))
        if hi == lo or targets[arms[hi]] == 0:
            break
        trial = dict(targets)
        trial[arms[hi]] -= 1
        trial[arms[lo]] += 1
        new_arm_of = _assign(P, reach, lateral, trial, arms)
        new_work = _work(rig, P, new_arm_of, arms, drill_time_s, travel_speed)
        if new_work.max() >= work.max() - 1e-9:
            break
        targets, arm_of, work = trial, new_arm_of, new_work
        history.append(work.max())
    return arm_of, targets, {"work_s": dict(zip(arms, work.round(3).tolist())),
                             "max_work_history_s": history}
