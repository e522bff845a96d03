"""Hermite pieces: polynomials matching given derivatives at both ends of an interval.

``hermite5`` matches position, velocity and acceleration (quintic); ``hermite7`` also the
jerk (degree 7). Both are vectorised over pieces and joints and return coefficients in
ascending powers of local time, as ``Trajectory`` stores them.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["hermite5", "hermite7"]


def hermite5(q0, q1, v0, v1, a0, a1, T) -> np.ndarray:
    """Quintic pieces ``(K, 6, dof)`` (ascending powers of local time) matching position,
    velocity and acceleration at both ends of durations ``T (K,)``; inputs ``(K, dof)``."""
    T = np.asarray(T, dtype=float)[:, None]
    c = np.zeros((len(T), 6, np.shape(q0)[1]))
    c[:, 0], c[:, 1], c[:, 2] = q0, v0, a0 / 2
    dq = q1 - q0
    c[:, 3] = (20 * dq - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T**2) / (2 * T**3)
    c[:, 4] = (-30 * dq + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T**2) / (2 * T**4)
    c[:, 5] = (12 * dq - 6 * (v1 + v0) * T - (a0 - a1) * T**2) / (2 * T**5)
    return c


def _septic_matrix() -> np.ndarray:
    """Rows m = 0..3: the m-th derivative at u = 1 of u^k, k = 4..7."""
    k = np.arange(4, 8)
    return np.array([[math.perm(int(kk), m) for kk in k] for m in range(4)], dtype=float)


_SEPTIC_INV = np.linalg.inv(_septic_matrix())


def hermite7(start: np.ndarray, end: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Degree-7 pieces ``(K, 8, dof)`` (ascending powers of local time) with derivatives
    0..3 ``start``/``end`` ``(4, K, dof)`` at both ends of durations ``T (K,)``."""
    T = np.asarray(T, dtype=float)[:, None]
    fact = np.array([1.0, 1.0, 2.0, 6.0])
    b = np.zeros((len(T), 8, start.shape[2]))  # coefficients in u = tau / T
    for m in range(4):
        b[:, m] = start[m] * T**m / fact[m]
    rhs = np.stack([end[m] * T**m - sum(math.perm(k, m) * b[:, k] for k in range(m, 4))
                    for m in range(4)], axis=1)  # (K, 4, dof)
    b[:, 4:] = np.einsum("km,nmd->nkd", _SEPTIC_INV, rhs)
    return b / T[:, :, None] ** np.arange(8)[None, :, None]
