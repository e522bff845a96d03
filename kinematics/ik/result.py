"""What every IK solver returns, and the branch bookkeeping the closed forms share."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from ..fk import fk
from ..model import RobotModel
from ..transforms import pose_errors

__all__ = ["IKStatus", "IKResult", "finish_analytic", "expand_turns", "order_by_distance"]

#: Residuals below which a closed-form branch counts as a true solution of the target pose.
BRANCH_POSITION_TOL = 1e-4  # mm
BRANCH_ROTATION_TOL = 1e-7  # rad


class IKStatus(StrEnum):
    """Outcome of an IK request."""

    OK = "ok"
    UNREACHABLE = "unreachable"  # no configuration reaches the pose, limits aside
    OUT_OF_LIMITS = "out_of_limits"  # reachable, but only outside the joint limits
    NOT_CONVERGED = "not_converged"  # numeric search found nothing within tolerance


@dataclass(frozen=True)
class IKResult:
    """One IK answer. ``q`` is the chosen solution ``(dof,)`` or None; ``solutions`` holds every
    solution found ``(K, dof)`` (within limits first). Errors are those of ``q``, or of the
    best attempt when there is no ``q``: position in mm, rotation in rad."""

    status: IKStatus
    q: np.ndarray | None
    solutions: np.ndarray
    position_error: float
    rotation_error: float
    within_limits: bool
    method: str
    message: str
    singular: bool = False
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is IKStatus.OK


def expand_turns(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Every copy of ``q (dof,)`` shifted by whole turns on revolute joints that lands inside the
    limits (joints with ranges over 360° have several). Returns ``(K, dof)``; if some joint
    has no copy inside its limits, the single wrapped ``q`` is returned unchanged."""
    options = []
    for i, j in enumerate(model.joints):
        v = q[i]
        if not j.revolute:
            options.append([v])
            continue
        k_lo = math.ceil((j.lower - v) / (2 * math.pi) - 1e-12)
        k_hi = math.floor((j.upper - v) / (2 * math.pi) + 1e-12)
        vals = [v + 2 * math.pi * k for k in range(k_lo, k_hi + 1)]
        if not vals:
            return q[None, :].copy()
        options.append(vals)
    return np.array(list(itertools.product(*options)))


def order_by_distance(q: np.ndarray, q0: np.ndarray | None) -> np.ndarray:
    """Indices ordering solutions ``(K, dof)`` by distance to ``q0`` (stable if None)."""
    if q0 is None or len(q) == 0:
        return np.arange(len(q))
    return np.argsort(np.linalg.norm(q - q0, axis=1), kind="stable")


def _dedupe(q: np.ndarray) -> np.ndarray:
    if len(q) == 0:
        return q
    keys = np.round(q, 9)
    _, idx = np.unique(keys, axis=0, return_index=True)
    return q[np.sort(idx)]


def finish_analytic(
    model: RobotModel,
    T_target: np.ndarray,
    branches: np.ndarray,
    method: str,
    q0: np.ndarray | None,
    *,
    unreachable_reason: str | None = None,
    singular: bool = False,
) -> IKResult:
    """Turn the raw branches ``(K, dof)`` of a closed form into an ``IKResult``.

    Each branch is checked by FK against the target (so an algebra slip can never return a
    wrong answer), expanded into the extra turns the limits allow, and ordered: solutions
    within limits first, nearest ``q0`` first.
    """
    branches = np.asarray(branches, dtype=float).reshape(-1, model.dof)
    if len(branches):
        dp, dr = pose_errors(fk(model, branches), T_target[None])
        branches = branches[(dp < BRANCH_POSITION_TOL) & (dr < BRANCH_ROTATION_TOL)]
    if len(branches) == 0:
        reason = unreachable_reason or "no closed-form branch reaches the target pose"
        return IKResult(
            IKStatus.UNREACHABLE, None, np.empty((0, model.dof)), math.nan, math.nan,
            False, method, f"unreachable: {reason}",
        )
    expanded = _dedupe(np.concatenate([expand_turns(model, b) for b in branches]))
    inside = model.within_limits(expanded)
    good = expanded[inside]
    if len(good) == 0:
        outside = expanded[order_by_distance(expanded, q0)]
        worst = model.limit_violations(outside[0])
        dp, dr = pose_errors(fk(model, outside[0]), T_target)
        return IKResult(
            IKStatus.OUT_OF_LIMITS, None, outside, float(dp), float(dr), False, method,
            f"reachable only outside the joint limits: {len(outside)} branch(es), the nearest "
            f"violates {', '.join(worst)}",
            singular=singular,
        )
    good = good[order_by_distance(good, q0)]
    dp, dr = pose_errors(fk(model, good[0]), T_target)
    msg = f"{len(good)} solution(s) within limits"
    if singular:
        msg += "; singular configuration: the solutions form a continuous family, samples returned"
    return IKResult(
        IKStatus.OK, good[0], good, float(dp), float(dr), True, method, msg, singular=singular
    )
