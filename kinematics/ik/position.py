"""Position-only IK: joints that put the tool point at a given point, however the tool is
turned (a tool path fixes where the tool goes, not how it is turned).

Damped least squares on the three position rows of the Jacobian::

    dq = Jp^T (Jp Jp^T + lambda^2 I)^-1 e,     lambda = 1e-3 * length_scale

batched over starts and projected after every step onto the joint limits less an inset of
``LIMIT_INSET`` of each range, so that a curve through the solutions (a spline that
overshoots a waypoint slightly where a joint rides its stop) stays within the limits. Starts
come from a seeded table of in-limit configurations, nearest tool point first.

It is not ``numeric.solve_batch``: that solver fits the whole pose (six rows, rotation
included), weighs joints by paper 003's limit objective and adapts its damping per target;
here the task has three rows, the damping is fixed, and an optional null-space step moves
the joints the point leaves free towards mid-range.

Units: mm, rad (mm for prismatic joints); points in the world frame of ``fk``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..fk import fk
from ..jacobian import jacobian_and_pose
from ..model import RobotModel

__all__ = ["LIMIT_INSET", "REACH_TOL", "SEED_TABLE", "position_dls", "position_ik", "reach"]

#: Largest tool position error (mm) accepted as reaching a point.
REACH_TOL = 1e-2
#: Fraction of each joint range kept clear of the limits by the iteration.
LIMIT_INSET = 0.005
#: Configurations in the seeded table the starts are taken from.
SEED_TABLE = 4096


def position_dls(model: RobotModel, Q: np.ndarray, target: np.ndarray, iterations: int,
                 tol: float, centring: float = 0.0, inset: float = LIMIT_INSET
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares on the tool position for a batch ``Q (B, dof)`` towards
    ``target (3,)`` or ``(B, 3)`` mm, projected onto the joint limits less ``inset`` of each
    range; rows stop together once every error is below ``tol`` mm.

    ``centring`` > 0 adds a null-space step (on the first iteration) of that gain towards
    mid-range (arms with more than 3 joints have freedom left over; using it keeps joints
    off their stops). Returns ``(Q (B, dof), error (B,) mm)``."""
    lam2 = (1e-3 * model.length_scale) ** 2
    mid, span = model.mid_configuration(), model.upper - model.lower
    span = np.where(np.isfinite(span) & (span > 0), span, 1.0)
    lower, upper = model.lower + inset * span, model.upper - inset * span
    Q = np.array(Q, dtype=float)
    err = np.full(len(Q), np.inf)
    for it in range(iterations):
        J, T = jacobian_and_pose(model, Q)
        e = target - T[:, :3, 3]
        err = np.linalg.norm(e, axis=1)
        if np.all(err < tol) and (centring == 0 or it > 0):
            break
        Jp = J[:, :3, :]
        A = Jp @ np.swapaxes(Jp, 1, 2) + lam2 * np.eye(3)
        Jpinv = np.swapaxes(Jp, 1, 2) @ np.linalg.inv(A)  # (B, dof, 3)
        dq = np.einsum("bij,bj->bi", Jpinv, e)
        if centring and it == 0:  # one centring step, then converge on the position
            g = centring * (mid - Q) / span * span.min()
            dq += g - np.einsum("bij,bjk,bk->bi", Jpinv, Jp, g)
        Q = np.clip(Q + dq, lower, upper)
    else:
        err = np.linalg.norm(target - fk(model, Q)[:, :3, 3], axis=1)
    return Q, err


@lru_cache(maxsize=16)
def _table(model: RobotModel, size: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded in-limit configurations ``(size, dof)`` and their tool points ``(size, 3)``."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(model.lower, model.upper, size=(size, model.dof))
    # Joints that do not move the tool point start mid-range rather than anywhere.
    q0 = np.tile(model.mid_configuration(), (1, 1))
    J = jacobian_and_pose(model, q0)[0][0, :3]
    idle = np.all(np.abs(J) < 1e-9, axis=0)
    q[:, idle] = model.mid_configuration()[idle]
    return q, fk(model, q)[:, :3, 3]


def reach(model: RobotModel) -> float:
    """Largest distance (mm) of the tool point from the base origin over a seeded sample of
    in-limit configurations: the arm's reach, to within the sampling."""
    return float(np.max(np.linalg.norm(_table(model, SEED_TABLE, 0)[1] - model.base[:3, 3],
                                       axis=1)))


def position_ik(model: RobotModel, point, q0=None, starts: int = 16,
                iterations: int = 100) -> tuple[np.ndarray | None, float]:
    """Joints ``(dof,)`` within limits that put the tool point at ``point (3,)`` mm, or None;
    also the least position error (mm) found. Starts from ``q0`` (if given) and the
    ``starts`` table configurations nearest the point; returns the solution closest to
    ``q0`` (or to mid-range). A point counts as reached within ``REACH_TOL`` mm."""
    point = np.asarray(point, dtype=float)
    Qt, Pt = _table(model, SEED_TABLE, 0)
    near = np.argsort(np.linalg.norm(Pt - point, axis=1))[:starts]
    Q = Qt[near]
    if q0 is not None:
        Q = np.vstack([np.clip(q0, model.lower, model.upper), Q])
    Q, err = position_dls(model, Q, point, iterations, REACH_TOL / 10)
    ok = err < REACH_TOL
    if not ok.any():
        return None, float(err.min())
    ref = model.mid_configuration() if q0 is None else np.asarray(q0, float)
    cand = Q[ok]
    return cand[np.argmin(np.linalg.norm(cand - ref, axis=1))], float(err[ok].min())
