"""Polynomial joint trajectories of paper 004 section 6: quintic segments and the sextic.

* ``quintic_segments``: one quintic per segment between consecutive waypoints, with given
  (default zero: the paper's "stay" case, eqs. 18-21) velocities and accelerations at every
  waypoint.
* ``sextic_via``: one degree-6 polynomial from A through B to C that does not stop at B
  (eqs. 22-26). Eq. 24 as printed has two slips in its last row (the ``a_C`` row reads
  ``0 1 2 6t_C ...``; the derivative of ``a_1 t`` vanishes, so it is ``0 0 2 6t_C ...``),
  and its ``v_C`` row writes ``2`` for ``2 t_C``; we build the system from the constraints.
* ``smooth_spline``: where one sextic no longer fits (more than one via point), a quintic
  spline through every waypoint with zero velocity and acceleration at both ends: position,
  velocity, acceleration and jerk continuous (C4).
"""

from __future__ import annotations

from math import comb

import numpy as np
from scipy.interpolate import make_interp_spline

from kinematics.errors import FieldError

from .trajectory import Trajectory

__all__ = ["quintic_segments", "sextic_via", "smooth_spline", "check_waypoints"]


def check_waypoints(waypoints, durations) -> tuple[np.ndarray, np.ndarray]:
    """Validate waypoints ``(n, dof)`` and segment durations ``(n-1,)``; ``FieldError`` naming
    the field at fault (``waypoints`` or ``durations``)."""
    q = np.asarray(waypoints, dtype=float)
    if q.ndim != 2 or q.shape[0] < 2:
        raise FieldError("waypoints",
                         "waypoints: need at least 2 waypoints, each a list of joint values")
    if not np.all(np.isfinite(q)):
        raise FieldError("waypoints", "waypoints: values must be finite")
    h = np.asarray(durations, dtype=float).reshape(-1)
    if h.shape[0] != q.shape[0] - 1:
        raise FieldError(
            "durations", f"durations: need one per segment ({q.shape[0] - 1} for "
            f"{q.shape[0]} waypoints), got {h.shape[0]}"
        )
    if not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise FieldError("durations", "durations: every duration must be positive and finite")
    return q, h


def quintic_segments(
    waypoints,
    durations,
    velocities=None,
    accelerations=None,
) -> Trajectory:
    """Quintic per segment. ``waypoints (n, dof)``, ``durations (n-1,)`` s; optional
    ``velocities``/``accelerations (n, dof)`` at the waypoints (default zero: stop at each).

    With zero boundary rates and duration T the segment is the paper's eq. 21:
    ``q(t) = q_A + d (10 s^3 - 15 s^4 + 6 s^5)``, ``s = t / T``, ``d = q_B - q_A``.
    """
    q, h = check_waypoints(waypoints, durations)
    n, dof = q.shape
    v = np.zeros_like(q) if velocities is None else np.asarray(velocities, dtype=float)
    a = np.zeros_like(q) if accelerations is None else np.asarray(accelerations, dtype=float)
    for name, arr in (("velocities", v), ("accelerations", a)):
        if arr.shape != q.shape:
            raise FieldError(name, f"{name}: expected shape {list(q.shape)}, got "
                             f"{list(arr.shape)}")
        if not np.all(np.isfinite(arr)):
            raise FieldError(name, f"{name}: values must be finite")
    T = h[:, None]
    q0, q1, v0, v1, a0, a1 = q[:-1], q[1:], v[:-1], v[1:], a[:-1], a[1:]
    c = np.zeros((n - 1, 6, dof))
    c[:, 0], c[:, 1], c[:, 2] = q0, v0, a0 / 2
    # The remaining three coefficients from position, velocity, acceleration at tau = T.
    c[:, 3] = (20 * (q1 - q0) - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T**2) / (2 * T**3)
    c[:, 4] = (-30 * (q1 - q0) + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T**2) / (
        2 * T**4
    )
    c[:, 5] = (12 * (q1 - q0) - 6 * (v1 + v0) * T - (a0 - a1) * T**2) / (2 * T**5)
    breaks = np.concatenate([[0.0], np.cumsum(h)])
    return Trajectory(breaks, c, "quintic", np.arange(n))


def sextic_via(waypoints, durations) -> Trajectory:
    """One sextic through A, B, C (``waypoints (3, dof)``, ``durations (2,)``), at rest at A
    and C, passing B without stopping (eqs. 22-24). Returned as two pieces split at B so the
    continuity report can show the join."""
    q, h = check_waypoints(waypoints, durations)
    if q.shape[0] != 3:
        raise FieldError("waypoints",
                         "waypoints: a sextic goes through exactly 3 waypoints (A, B, C)")
    tB, tC = h[0], h[0] + h[1]
    powers = np.arange(7)
    A = np.zeros((7, 7))
    A[0, 0] = 1.0  # q(0) = q_A
    A[1, 1] = 1.0  # q'(0) = 0
    A[2, 2] = 2.0  # q''(0) = 0
    A[3] = tB**powers  # q(tB) = q_B
    A[4] = tC**powers  # q(tC) = q_C
    A[5, 1:] = powers[1:] * tC ** (powers[1:] - 1)  # q'(tC) = 0
    A[6, 2:] = powers[2:] * (powers[2:] - 1) * tC ** (powers[2:] - 2)  # q''(tC) = 0
    rhs = np.zeros((7, q.shape[1]))
    rhs[0], rhs[3], rhs[4] = q[0], q[1], q[2]
    coef = np.linalg.solve(A, rhs)  # (7, dof), ascending powers from t = 0
    second = _shift(coef, tB)
    return Trajectory(np.array([0.0, tB, tC]), np.stack([coef, second]), "sextic",
                      np.arange(3))


def _shift(coef: np.ndarray, t0: float) -> np.ndarray:
    """Coefficients of ``p(t0 + tau)`` in powers of tau, for ascending ``coef (deg+1, dof)``."""
    deg = coef.shape[0] - 1
    out = np.zeros_like(coef)
    for p in range(deg + 1):
        for k in range(p + 1):
            out[k] += comb(p, k) * t0 ** (p - k) * coef[p]
    return out


def smooth_spline(waypoints, durations) -> Trajectory:
    """C4 quintic spline through all waypoints at their times, at rest (zero velocity and
    acceleration) at both ends. Knots at the waypoints."""
    q, h = check_waypoints(waypoints, durations)
    t = np.concatenate([[0.0], np.cumsum(h)])
    zero = np.zeros(q.shape[1])
    if len(q) == 2:
        return quintic_segments(q, h)
    spline = make_interp_spline(
        t, q, k=5, bc_type=([(1, zero), (2, zero)], [(1, zero), (2, zero)])
    )
    return Trajectory.from_bspline(spline, "smooth", t)
