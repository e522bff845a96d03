"""Quintic uniform B-spline through m path points (paper 002 section 3.4, eqs. 14-18).

The paper writes each of the m - 1 segments with the uniform quintic basis matrix (eq. 14)
over six control points N_{i-1}..N_{i+4}, interpolates the m path points (eq. 15) and adds
zero velocity and acceleration at both ends (eq. 17): m + 4 equations for m + 4 control
points (eq. 18). On the span of the path that is the unique quintic spline with simple knots
at the path points satisfying those m + 4 conditions, which is what scipy's
``make_interp_spline`` solves (in a clamped basis, better conditioned); ``paper_basis``
and ``paper_control_points`` build the paper's own system, and the tests check the two agree.

Position, velocity, acceleration and jerk are continuous (C4). With ``durations`` all equal
the knots are uniform as in the paper; unequal durations give the non-uniform spline.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_interp_spline

from .polynomials import check_waypoints, quintic_segments
from .trajectory import Trajectory

__all__ = ["quintic_bspline", "PAPER_BASIS", "paper_control_points", "paper_evaluate"]

#: Eq. 14: rows are the coefficients of u^5, u^4, ..., 1 (times 1/120) for the control points
#: N_{i-1} .. N_{i+4} of segment i, u in [0, 1].
PAPER_BASIS = np.array(
    [
        [-1, 5, -10, 10, -5, 1],
        [5, -20, 30, -20, 5, 0],
        [-10, 20, 0, -20, 10, 0],
        [10, 20, -60, 20, 10, 0],
        [-5, -50, 0, 50, 5, 0],
        [1, 26, 66, 26, 1, 0],
    ],
    dtype=float,
) / 120.0


def quintic_bspline(waypoints, durations) -> Trajectory:
    """Quintic B-spline through ``waypoints (m, dof)`` at times given by ``durations (m-1,)``,
    at rest at both ends. Two waypoints give the single rest-to-rest quintic."""
    q, h = check_waypoints(waypoints, durations)
    if len(q) == 2:
        traj = quintic_segments(q, h)
        return Trajectory(traj.breaks, traj.coeffs, "bspline5", traj.waypoint_index)
    t = np.concatenate([[0.0], np.cumsum(h)])
    zero = np.zeros(q.shape[1])
    spline = make_interp_spline(
        t, q, k=5, bc_type=([(1, zero), (2, zero)], [(1, zero), (2, zero)])
    )
    return Trajectory.from_bspline(spline, "bspline5", t)


def _basis_row(u: float, derivative: int) -> np.ndarray:
    """Weights of the six control points for the ``derivative`` of eq. 14 at u (per unit u)."""
    powers = np.array([5, 4, 3, 2, 1, 0], dtype=float)
    coeff = np.ones(6)
    p = powers.copy()
    for _ in range(derivative):
        coeff *= p
        p = p - 1
    monomials = np.where(p >= 0, u ** np.clip(p, 0, None), 0.0) * coeff
    return monomials @ PAPER_BASIS


def paper_control_points(waypoints) -> np.ndarray:
    """Control points ``(m+4, dof)`` of the paper's uniform quintic B-spline through
    ``waypoints (m, dof)`` with zero end velocity and acceleration (eqs. 15, 17, 18); one
    time unit per segment."""
    P = np.asarray(waypoints, dtype=float)
    m = len(P)
    A = np.zeros((m + 4, m + 4))
    rhs = np.zeros((m + 4, P.shape[1]))
    for i in range(m - 1):  # path point i is the start (u = 0) of segment i
        A[i, i : i + 6] = _basis_row(0.0, 0)
        rhs[i] = P[i]
    A[m - 1, m - 2 : m + 4] = _basis_row(1.0, 0)  # the last point ends the last segment
    rhs[m - 1] = P[-1]
    A[m, 0:6] = _basis_row(0.0, 1)  # start at rest
    A[m + 1, 0:6] = _basis_row(0.0, 2)
    A[m + 2, m - 2 : m + 4] = _basis_row(1.0, 1)  # end at rest
    A[m + 3, m - 2 : m + 4] = _basis_row(1.0, 2)
    return np.linalg.solve(A, rhs)


def paper_evaluate(control: np.ndarray, t: np.ndarray, derivative: int = 0) -> np.ndarray:
    """Evaluate eq. 14 (one time unit per segment) at times ``t (S,)`` in ``[0, m-1]``."""
    t = np.asarray(t, dtype=float)
    n_seg = control.shape[0] - 5
    i = np.clip(np.floor(t).astype(int), 0, n_seg - 1)
    u = t - i
    out = np.empty((len(t), control.shape[1]))
    for k in range(len(t)):
        out[k] = _basis_row(u[k], derivative) @ control[i[k] : i[k] + 6]
    return out
