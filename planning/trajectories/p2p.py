"""Jerk-limited point-to-point motion: a seven-segment S-curve per joint, all joints
arriving together.

Each joint goes from rest at ``start`` to ``end`` (at rest, or at a given end velocity with
zero acceleration) within its velocity, acceleration and jerk limits V, A, J. Its
time-optimal profile changes velocity from 0 to a peak ``v_p``, cruises, and changes from
``v_p`` to the end velocity; each change is the fastest one from zero acceleration to zero
acceleration: jerk +J for ``A/J``, constant acceleration A, jerk -J for ``A/J`` when
``|dv| >= A^2/J`` (a trapezoid of acceleration), otherwise jerk +-J for ``sqrt(|dv|/J)``
each (a triangle). A symmetric acceleration pulse covers ``(v_from + v_to)/2`` times its
duration, so the distance is closed form; ``v_p = V`` when the joint has room to cruise,
otherwise the ``v_p`` whose two changes cover the distance exactly (bisection). At rest
at both ends that is the classic 7-segment S-curve.

The slowest joint sets the duration T. Rest to rest, every other joint's profile is
stretched to T (time x k: velocity / k, acceleration / k^2, jerk / k^3, so its limits
still hold). To an end velocity, stretching would change that velocity, so a faster
joint instead lowers its peak velocity until it takes T (and, if even its lowest peak is
too fast, waits at rest first).

Positions in rad (revolute) or mm (prismatic), time in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinematics.errors import FieldError

from .hydraulic import HydraulicLimits
from .limits_check import limit_ratios, piece_samples
from .trajectory import Limits, Trajectory

__all__ = ["PointToPoint", "jerk_limited", "velocity_change"]

#: Bisection steps for the peak velocity (relative precision 2^-60).
BISECTION_STEPS = 60


@dataclass(frozen=True)
class PointToPoint:
    """A synchronised jerk-limited move: ``trajectory`` (cubic pieces), each joint's own
    shortest duration ``joint_durations (dof,)`` s and the joint that sets the duration."""

    trajectory: Trajectory
    joint_durations: np.ndarray
    limiting_joint: int

    @property
    def duration(self) -> float:
        return self.trajectory.duration


def velocity_change(dv: float, A: float, J: float) -> list[tuple[float, float]]:
    """The fastest change of velocity by ``dv`` from zero to zero acceleration within
    ``A`` and ``J``: ``[(duration, jerk), ...]``.

    >>> velocity_change(2.0, 1.0, 1.0)  # trapezoid: 1 s ramps, 1 s at A
    [(1.0, 1.0), (1.0, 0.0), (1.0, -1.0)]
    """
    sign = 1.0 if dv >= 0 else -1.0
    m = abs(dv)
    if m == 0:
        return []
    if m >= A * A / J:
        return [(A / J, sign * J), (m / A - A / J, 0.0), (A / J, -sign * J)]
    tj = math.sqrt(m / J)
    return [(tj, sign * J), (tj, -sign * J)]


def _change_time(dv: np.ndarray, A: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Duration of ``velocity_change`` for arrays ``(dof,)``."""
    m = np.abs(dv)
    return np.where(m >= A * A / J, m / A + A / J, 2.0 * np.sqrt(m / J))


def _distance(vp, vf, A, J) -> np.ndarray:
    """Distance of the two changes 0 -> vp -> vf (no cruise)."""
    return 0.5 * vp * _change_time(vp, A, J) + 0.5 * (vp + vf) * _change_time(vf - vp, A, J)


def _segments(vp: float, vf: float, cruise: float, A: float, J: float, wait: float = 0.0
              ) -> list[tuple[float, float]]:
    segs = [(wait, 0.0)] if wait > 0 else []
    segs += velocity_change(vp, A, J)
    if cruise > 0:
        segs.append((cruise, 0.0))
    return segs + velocity_change(vf - vp, A, J)


def _peak_for_distance(d, vf, V, A, J) -> np.ndarray:
    """Per joint, the peak velocity ``vp`` in [vf, V] whose changes cover ``d`` (d > 0)."""
    lo, hi = np.array(vf, dtype=float), np.array(V, dtype=float)
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        over = _distance(mid, vf, A, J) > d
        hi = np.where(over, mid, hi)
        lo = np.where(over, lo, mid)
    return lo


def _profile_time(vp, vf, d, A, J) -> float:
    """Duration with peak ``vp`` (cruising for what the changes leave of ``d``)."""
    rest = d - _distance(vp, vf, A, J)
    cruise = rest / vp if vp > 0 else (0.0 if rest <= 0 else math.inf)
    return float(_change_time(vp, A, J) + _change_time(vf - vp, A, J) + max(cruise, 0.0))


def _check(limits: Limits, moving: np.ndarray, dof: int, allow_unlimited_velocity: bool
           ) -> tuple[np.ndarray, ...]:
    out = []
    for name in ("velocity", "acceleration", "jerk"):
        value = limits.of(name)
        arr = np.full(dof, np.inf) if value is None else np.asarray(value, dtype=float)
        arr = np.broadcast_to(arr, (dof,)).astype(float) if arr.ndim == 0 else arr
        if arr.shape != (dof,):
            raise FieldError(("limits", name), f"limits.{name}: expected one value or {dof} "
                             f"values, got {arr.size}")
        if np.any(np.isnan(arr)) or np.any(arr <= 0):
            raise FieldError(("limits", name), f"limits.{name}: every limit must be positive")
        if np.any(~np.isfinite(arr) & moving) and not (
                name == "velocity" and allow_unlimited_velocity):
            j = int(np.argmax(~np.isfinite(arr) & moving))
            raise FieldError(("limits", name), f"limits.{name}: joint {j} moves and needs a "
                             f"finite {name} limit for a jerk-limited profile")
        out.append(arr if name == "velocity" else np.where(np.isfinite(arr), arr, 1.0))
    return tuple(out)


def _cylinder_speed_limits(p0, p1, hydraulics: HydraulicLimits, V: np.ndarray,
                           samples: int = 257) -> np.ndarray:
    """Joint velocity limits ``(dof,)`` that keep every cylinder within its speed limit
    between ``p0`` and ``p1``: a joint's velocity keeps one sign over these profiles, so each
    of its cylinders moves one way; the limit is the least ``v_cyl / |dL/dq|`` over the
    joint's range of motion."""
    V = V.copy()
    f = np.linspace(0.0, 1.0, samples)[:, None]
    q = p0[None, :] + f * (p1 - p0)[None, :]
    dL = hydraulics.dlength_dq(q)  # (samples, C)
    for c, j in enumerate(hydraulics.joint):
        direction = np.sign(p1[j] - p0[j])
        if direction == 0:
            continue
        extends = dL[:, c] * direction > 0
        lim = np.where(extends, hydraulics.max_extension[c], hydraulics.max_retraction[c])
        with np.errstate(divide="ignore"):
            joint_lim = np.where(np.abs(dL[:, c]) > 0, lim / np.abs(dL[:, c]), np.inf)
        V[j] = min(V[j], float(joint_lim.min()))
    return V


def jerk_limited(start, end, limits: Limits, end_velocity=None,
                 hydraulics: HydraulicLimits | None = None) -> PointToPoint:
    """Synchronised jerk-limited move from rest at ``start (dof,)`` to ``end (dof,)``, at
    rest or at ``end_velocity (dof,)`` (zero acceleration), within ``limits`` (velocity,
    acceleration and jerk per joint, finite for every joint that moves).

    ``hydraulics``: each cylinder's speed limit becomes a velocity limit of its joint over
    the joint's range of motion (exact: a joint never reverses in these profiles); the pump
    flow, which depends on how the joints' speeds overlap, is met by stretching a
    rest-to-rest move uniformly; to an end velocity (which a stretch would change) it is
    only reported by the caller.

    ``FieldError`` naming ``limits.<name>`` (missing or not positive), ``waypoints`` (bad
    shapes) or ``end_velocity`` (above the velocity limit, or pointing away from the end,
    or too fast to reach from rest within the distance: this profile does not overshoot
    and come back)."""
    p0, p1 = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    if p0.ndim != 1 or p0.shape != p1.shape or not np.all(np.isfinite(p0 + p1)):
        raise FieldError("waypoints", "waypoints: start and end need the same number of "
                         "finite joint values")
    dof = len(p0)
    vf = np.zeros(dof) if end_velocity is None else np.asarray(end_velocity, dtype=float)
    if vf.shape != (dof,) or not np.all(np.isfinite(vf)):
        raise FieldError("end_velocity", f"end_velocity: expected {dof} finite values")
    d_signed = p1 - p0
    moving = (np.abs(d_signed) > 0) | (vf != 0)
    V, A, J = _check(limits, moving, dof, allow_unlimited_velocity=hydraulics is not None)
    if hydraulics is not None:
        V = _cylinder_speed_limits(p0, p1, hydraulics, V)
        if np.any(~np.isfinite(V) & moving):
            j = int(np.argmax(~np.isfinite(V) & moving))
            raise FieldError(("limits", "velocity"), f"limits.velocity: joint {j} moves and "
                             "needs a finite velocity limit for a jerk-limited profile")
    sign = np.where(d_signed < 0, -1.0, 1.0)
    sign = np.where(d_signed == 0, np.where(vf < 0, -1.0, 1.0), sign)
    d, w = np.abs(d_signed), vf * sign  # each joint moving forwards
    for j in np.flatnonzero(moving):
        if w[j] > V[j] * (1 + 1e-12):
            raise FieldError(("end_velocity", int(j)), f"end_velocity[{j}]: {vf[j]:g} exceeds "
                             f"the velocity limit {V[j]:g}")
        if w[j] < 0 or (w[j] > 0 and 0.5 * w[j] * _change_time(w[j], A[j], J[j]) > d[j]):
            raise FieldError(("end_velocity", int(j)), f"end_velocity[{j}]: {vf[j]:g} cannot "
                             "be reached from rest within the joint's distance without "
                             "overshooting")
    # Each joint's fastest profile.
    cruise_ok = _distance(V, w, A, J) <= d
    vp = np.where(cruise_ok, V, _peak_for_distance(d, w, np.where(moving, V, 1.0), A, J))
    T_own = np.array([_profile_time(vp[j], w[j], d[j], A[j], J[j]) if moving[j] else 0.0
                      for j in range(dof)])
    T = float(T_own.max(initial=0.0))
    if T <= 0:
        raise FieldError("waypoints", "waypoints: start and end are the same at rest")
    limiting = int(np.argmax(T_own))
    profiles: list[list[tuple[float, float]]] = []
    rest_to_rest = not np.any(w != 0)
    for j in range(dof):
        if not moving[j]:
            profiles.append([(T, 0.0)])
            continue
        segs = _segments(vp[j], w[j], max((d[j] - _distance(vp[j], w[j], A[j], J[j]))
                                          / vp[j], 0.0), A[j], J[j])
        if rest_to_rest or T_own[j] >= T * (1 - 1e-12):
            k = T / T_own[j]
            segs = [(dt * k, jerk / k**3) for dt, jerk in segs]
        else:
            segs = _slower(d[j], w[j], vp[j], A[j], J[j], T)
        profiles.append([(dt, jerk * sign[j]) for dt, jerk in segs])
    traj = _piecewise(p0, profiles, T)
    if hydraulics is not None and hydraulics.has_pump and rest_to_rest:
        _, q, qd = piece_samples(traj)
        k = float(limit_ratios(q, qd, qd, None, None, None, None, hydraulics).pump.max())
        if k > 1:
            traj = traj.scaled(k)
    return PointToPoint(traj, T_own, limiting)


def _slower(d, w, vp_fast, A, J, T) -> list[tuple[float, float]]:
    """A profile of duration ``T`` to end velocity ``w > 0``: the peak velocity lowered in
    (0, vp_fast] until it takes T; waiting at rest first if even the lowest is faster."""
    lo, hi = 0.0, float(vp_fast)
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        if _profile_time(mid, w, d, A, J) > T:
            lo = mid
        else:
            hi = mid
    vp = hi
    took = _profile_time(vp, w, d, A, J)
    cruise = max((d - _distance(vp, w, A, J)) / vp, 0.0)
    return _segments(vp, w, cruise, A, J, wait=max(T - took, 0.0))


def _piecewise(p0: np.ndarray, profiles: list[list[tuple[float, float]]], T: float
               ) -> Trajectory:
    """Cubic pieces on the union of every joint's segment boundaries."""
    dof = len(p0)
    cuts = [np.concatenate([[0.0], np.cumsum([dt for dt, _ in segs])]) for segs in profiles]
    breaks = np.unique(np.concatenate(cuts))
    breaks = breaks[breaks < T * (1 - 1e-12)]
    breaks = np.append(breaks, T)
    coeffs = np.zeros((len(breaks) - 1, 4, dof))
    for j, segs in enumerate(profiles):
        # State (p, v, a) at each of the joint's own segment starts.
        state = [(float(p0[j]), 0.0, 0.0)]
        for dt, jerk in segs:
            p, v, a = state[-1]
            state.append((p + v * dt + a * dt**2 / 2 + jerk * dt**3 / 6,
                          v + a * dt + jerk * dt**2 / 2, a + jerk * dt))
        own = cuts[j]
        k = np.clip(np.searchsorted(own, breaks[:-1], side="right") - 1, 0, len(segs) - 1)
        tau = breaks[:-1] - own[k]
        st = np.array(state)[k]
        jerk = np.array([segs[i][1] for i in k])
        coeffs[:, 0, j] = st[:, 0] + st[:, 1] * tau + st[:, 2] * tau**2 / 2 + jerk * tau**3 / 6
        coeffs[:, 1, j] = st[:, 1] + st[:, 2] * tau + jerk * tau**2 / 2
        coeffs[:, 2, j] = (st[:, 2] + jerk * tau) / 2
        coeffs[:, 3, j] = jerk / 6
    return Trajectory(breaks, coeffs, "jerk_limited", np.array([0, len(breaks) - 1]))
