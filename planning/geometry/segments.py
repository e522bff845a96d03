"""Exact distances from segments (and points, as segments of zero length) to spheres,
capsules, axis-aligned boxes and other segments: what point paths and drilling envelopes
measure. Closed forms, no sampling:

* segment–point (a sphere is a point plus its radius): the distance from the point to the
  segment's closest point;
* segment–segment (a capsule is a segment plus its radius; two capsule envelopes are two
  segments): Ericson, *Real-Time Collision Detection* 5.1.9, clamped;
* segment–box: outside the box, the squared distance along the segment is piecewise
  quadratic in the segment parameter with at most six breakpoints (where a coordinate
  crosses a face plane), minimised in closed form on each piece; inside, the box's signed
  distance is the maximum of six linear functions of the parameter, whose minimum lies at an
  end or where two of them cross (15 candidates).

Every function broadcasts its arguments (last axis xyz). Lengths in mm. They are the
``("segment", shape)`` rows of the pair table (``planning.geometry.table``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "segment_point_distance",
    "segment_segment_distance",
    "segment_box_distance",
    "box_point_sdf",
    "unit",
    "fibonacci_sphere",
]


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", u, v)


def segment_point_distance(P0, P1, C) -> tuple[np.ndarray, np.ndarray]:
    """Distance from segments ``P0–P1`` to points ``C`` (all broadcast, ``(..., 3)``).

    Returns ``(distance (...), t (...))`` with ``P0 + t (P1 - P0)`` the closest point.
    Zero-length segments are points (t = 0).
    """
    d = P1 - P0
    dd = _dot(d, d)
    t = np.where(dd > 0, _dot(C - P0, d) / np.where(dd > 0, dd, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    closest = P0 + t[..., None] * d
    return np.linalg.norm(C - closest, axis=-1), t


def segment_segment_distance(P0, P1, Q0, Q1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance between segments ``P0–P1`` and ``Q0–Q1`` (broadcast, ``(..., 3)``).

    Returns ``(distance, s, t)``: closest points ``P0 + s (P1-P0)`` and ``Q0 + t (Q1-Q0)``.
    Ericson's clamped solution; handles zero-length and parallel segments.
    """
    d1, d2, r = P1 - P0, Q1 - Q0, P0 - Q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    a_ok, e_ok = a > 0, e > 0
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    general = denom > 1e-12 * a * e
    s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0, np.clip(-c / a_s, 0, 1), np.where(t > 1, np.clip((b - c) / a_s, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # Degenerate cases: one or both segments are points.
    only_q = ~a_ok & e_ok
    only_p = a_ok & ~e_ok
    both = ~a_ok & ~e_ok
    s = np.where(only_q | both, 0.0, np.where(only_p, np.clip(-c / a_s, 0, 1), s))
    t = np.where(both | only_p, 0.0, np.where(only_q, np.clip(f / e_s, 0, 1), t))
    p = P0 + s[..., None] * d1
    q = Q0 + t[..., None] * d2
    return np.linalg.norm(p - q, axis=-1), s, t


def segment_box_distance(P0, P1, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance between segments ``P0–P1`` and boxes ``[lower, upper]`` (broadcast).

    Returns ``(clearance, t)``: the least signed distance from a point of the segment to
    the box (negative = deepest penetration) and the segment parameter where it occurs.
    """
    P0, P1, lower, upper = np.broadcast_arrays(P0, P1, lower, upper)
    d = P1 - P0
    # Outside part: breakpoints where a coordinate meets a face plane.
    with np.errstate(divide="ignore", invalid="ignore"):
        tb = np.concatenate([(lower - P0) / d, (upper - P0) / d], axis=-1)
    tb = np.where(np.isfinite(tb), np.clip(tb, 0.0, 1.0), 0.0)
    knots = np.sort(np.concatenate([np.zeros(tb.shape[:-1] + (1,)), tb,
                                    np.ones(tb.shape[:-1] + (1,))], axis=-1), axis=-1)
    t_lo, t_hi = knots[..., :-1], knots[..., 1:]  # (..., 7) pieces
    tm = 0.5 * (t_lo + t_hi)
    pm = P0[..., None, :] + tm[..., None] * d[..., None, :]  # (..., 7, 3)
    below = pm < lower[..., None, :]
    above = pm > upper[..., None, :]
    bound = np.where(below, lower[..., None, :], upper[..., None, :])
    active = below | above
    alpha = np.where(active, P0[..., None, :] - bound, 0.0)
    beta = np.where(active, d[..., None, :], 0.0)
    A = np.sum(beta * beta, axis=-1)
    B = np.sum(alpha * beta, axis=-1)
    tq = np.where(A > 0, -B / np.where(A > 0, A, 1.0), t_lo)
    tq = np.clip(tq, t_lo, t_hi)
    res = alpha + beta * tq[..., None]
    f2 = np.sum(res * res, axis=-1)
    k = np.argmin(f2, axis=-1)
    out_d = np.sqrt(np.take_along_axis(f2, k[..., None], -1)[..., 0])
    out_t = np.take_along_axis(tq, k[..., None], -1)[..., 0]
    # Inside part: sdf(t) = max of 6 linear functions g_j(t) = c_j + m_j t.
    cst = np.concatenate([lower - P0, P0 - upper], axis=-1)  # (..., 6)
    slope = np.concatenate([-d, d], axis=-1)
    i, j = np.triu_indices(6, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = (cst[..., j] - cst[..., i]) / (slope[..., i] - slope[..., j])
    tx = np.where(np.isfinite(tx), np.clip(tx, 0.0, 1.0), 0.0)
    cand = np.concatenate([tx, np.zeros(tx.shape[:-1] + (1,)), np.ones(tx.shape[:-1] + (1,))],
                          axis=-1)  # (..., 17)
    g = np.max(cst[..., None, :] + slope[..., None, :] * cand[..., None], axis=-1)
    kin = np.argmin(g, axis=-1)
    in_d = np.take_along_axis(g, kin[..., None], -1)[..., 0]
    in_t = np.take_along_axis(cand, kin[..., None], -1)[..., 0]
    inside = in_d < 0
    return np.where(inside, in_d, out_d), np.where(inside, in_t, out_t)


def box_point_sdf(X, lower, upper) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance of points to boxes and its gradient (unit, ``(..., 3)``)."""
    q = np.maximum(lower - X, X - upper)  # per-axis outside distance (negative inside)
    outside = np.maximum(q, 0.0)
    n_out = np.linalg.norm(outside, axis=-1)
    m = np.max(q, axis=-1)
    sdf = np.where(n_out > 0, n_out, m)
    sign = np.where(lower - X > X - upper, -1.0, 1.0)
    g_out = sign * outside / np.where(n_out > 0, n_out, 1.0)[..., None]
    face = np.argmax(q, axis=-1)
    g_in = np.take_along_axis(sign, face[..., None], -1) * (
        np.arange(3) == face[..., None])
    return sdf, np.where((n_out > 0)[..., None], g_out, g_in)


def unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1.0), 0.0)


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly evenly spread unit vectors ``(n, 3)``."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = k * math.pi * (3 - math.sqrt(5))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
