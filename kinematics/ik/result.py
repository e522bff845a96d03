"""What every IK solver returns, and the branch bookkeeping the closed forms share."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..fast import c_array, chain_of
from ..fk import fk
from ..model import RobotModel
from ..status import Status
from ..transforms import pose_errors

__all__ = ["IKStatus", "IKResult", "finish_analytic", "finish_one", "expand_turns",
           "order_by_distance"]

#: Residuals below which a closed-form branch counts as a true solution of the target pose.
BRANCH_POSITION_TOL = 1e-4  # mm
BRANCH_ROTATION_TOL = 1e-7  # rad


class IKStatus(Status):
    """Outcome of an IK request (a member of the status family, ``kinematics.status``)."""

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


def expand_turns(model: RobotModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every copy of the solutions ``q (K, dof)`` shifted by whole turns on revolute joints
    that lands inside the limits (joints with ranges past 360° have several).

    A solution with a joint that no turn brings inside its limits is kept once, as it is, so
    the caller can report it as out of limits. Returns the copies ``(M, dof)`` and, for each,
    the index of the solution it came from ``(M,)``.
    """
    rows = np.atleast_2d(np.asarray(q, dtype=float)).copy()
    src = np.arange(len(rows))
    two_pi = 2 * math.pi
    kept_rows, kept_src = [], []
    for i, j in enumerate(model.joints):
        if not j.revolute or len(rows) == 0:
            continue
        v = rows[:, i]
        k_lo = np.ceil((j.lower - v) / two_pi - 1e-12)
        k_hi = np.floor((j.upper - v) / two_pi + 1e-12)
        none = k_hi < k_lo
        if none.any():
            kept_rows.append(rows[none])
            kept_src.append(src[none])
            keep = ~none
            rows, src, v, k_lo, k_hi = rows[keep], src[keep], v[keep], k_lo[keep], k_hi[keep]
        n_copies = (k_hi - k_lo + 1).astype(int)
        starts = np.cumsum(n_copies) - n_copies
        k = np.repeat(k_lo, n_copies) + np.arange(n_copies.sum()) - np.repeat(starts, n_copies)
        rows = np.repeat(rows, n_copies, axis=0)
        src = np.repeat(src, n_copies)
        rows[:, i] = np.repeat(v, n_copies) + two_pi * k
    return np.concatenate([rows, *kept_rows]), np.concatenate([src, *kept_src])


def order_by_distance(q: np.ndarray, q0: np.ndarray | None) -> np.ndarray:
    """Indices ordering solutions ``(K, dof)`` by distance to ``q0`` (stable if None)."""
    if q0 is None or len(q) == 0:
        return np.arange(len(q))
    return np.argsort(np.linalg.norm(q - q0, axis=1), kind="stable")


def finish_analytic(
    model: RobotModel,
    T_target: np.ndarray,
    branches: np.ndarray,
    owner: np.ndarray,
    method: str,
    q0: np.ndarray | None,
    *,
    reasons: list[str | None],
    singular: np.ndarray,
) -> list[IKResult]:
    """Turn the raw branches of a closed form into one ``IKResult`` per target.

    ``branches (R, dof)`` are candidate solutions (NaN rows where a branch does not exist),
    ``owner (R,)`` the target index of each; ``T_target (B, 4, 4)``; ``reasons[b]`` says why
    target b is unreachable if no branch reaches it; ``singular (B,)``. Each branch is checked
    by FK against its target (so an algebra slip can never return a wrong answer), expanded
    into the extra turns the limits allow, and ordered: within limits first, nearest ``q0``
    (without it: nearest the middle of the joint ranges, ``model.mid_configuration()``) first.
    """
    B = T_target.shape[0]
    valid = np.all(np.isfinite(branches), axis=1)
    rows, own = branches[valid], owner[valid]
    dp, dr = pose_errors(fk(model, rows), T_target[own]) if len(rows) else (rows[:, 0],) * 2
    ok = (dp < BRANCH_POSITION_TOL) & (dr < BRANCH_ROTATION_TOL)
    rows, own, err = rows[ok], own[ok], np.stack([dp[ok], dr[ok]], axis=1)

    # Whole turns leave the pose unchanged: each copy keeps its branch's residuals.
    expanded, src = expand_turns(model, rows) if len(rows) else (rows, own)
    own, err = own[src], err[src]
    # Drop repeats (the same to 1e-9) per target.
    keys = np.column_stack([own, np.round(expanded, 9)])
    _, first = np.unique(keys, axis=0, return_index=True)
    expanded, own, err = expanded[first], own[first], err[first]
    inside = model.within_limits(expanded)
    # Without q0, the branch nearest the middle of the joint ranges comes first: one answer
    # for one pose, whatever order the closed form produced its branches in.
    ref = model.mid_configuration() if q0 is None else q0
    # To 1e-9: branches as near as each other (+pi and -pi from 0) keep np.unique's order.
    dist = np.floor(np.linalg.norm(expanded - ref, axis=1) * 1e9 + 0.5) / 1e9
    order = np.lexsort((dist, ~inside, own))
    expanded, own, err, inside = expanded[order], own[order], err[order], inside[order]
    bounds = np.searchsorted(own, np.arange(B + 1))

    results = []
    for b in range(B):
        sl = slice(bounds[b], bounds[b + 1])
        results.append(_one_result(model, method, expanded[sl], err[sl], inside[sl],
                                   reasons[b], bool(singular[b])))
    return results


def finish_one(
    K, model: RobotModel, T_target: np.ndarray, branches: np.ndarray, method: str,
    q0: np.ndarray | None, *, reason: str | None, singular: bool,
) -> IKResult:
    """``finish_analytic`` for one target ``(4, 4)`` on the compiled kernels ``K``
    (``_kernels.finish_branches``): the same checks, turns, order and messages."""
    ch = chain_of(model)
    ref = c_array(model.mid_configuration() if q0 is None else q0)
    sols, errs, inside = K.finish_branches(ch.C, ch.prismatic, ch.offset, ch.lower, ch.upper,
                                           T_target, branches, ref, True)
    return _one_result(model, method, sols, errs, inside, reason, singular)


def _one_result(model: RobotModel, method: str, sols: np.ndarray, errs: np.ndarray,
                ins: np.ndarray, reason: str | None, sing: bool) -> IKResult:
    """The result for one target from its ordered solutions ``(K, dof)`` (within limits
    first), their residuals ``(K, 2)`` and limit flags ``(K,)``."""
    if len(sols) == 0:
        reason = reason or "no closed-form branch reaches the target pose"
        return IKResult(
            IKStatus.UNREACHABLE, None, np.empty((0, model.dof)), math.nan, math.nan,
            False, method, f"unreachable: {reason}",
        )
    if not ins[0]:
        worst = model.limit_violations(sols[0])
        return IKResult(
            IKStatus.OUT_OF_LIMITS, None, sols, float(errs[0, 0]), float(errs[0, 1]),
            False, method,
            f"reachable only outside the joint limits: {len(sols)} branch(es), the "
            f"nearest violates {', '.join(worst)}",
            singular=sing,
        )
    good = sols[ins]
    msg = f"{len(good)} solution(s) within limits"
    if sing:
        msg += "; singular configuration: the solutions form a continuous family, " \
            "samples returned"
    return IKResult(
        IKStatus.OK, good[0], good, float(errs[0, 0]), float(errs[0, 1]), True,
        method, msg, singular=sing,
    )
