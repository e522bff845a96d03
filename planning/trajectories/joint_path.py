"""Geometric joint paths q(s): where the joints go, without saying when.

Time-optimal parameterisation (``topp``) needs the path and its first three derivatives
with respect to the path parameter s. A ``JointPath`` is a piecewise polynomial in s
(ascending powers of the local parameter, like ``Trajectory``) made from

* a trajectory through waypoints (``from_trajectory``): its time becomes the path
  parameter, so any planner of ``plan_trajectory`` (or a Cartesian line or ellipse mapped
  through IK) gives the shape and ``topp`` re-times it;
* a waypoint polyline such as a motion planner returns (``smooth_polyline``): straight
  joint-space segments whose corners are replaced by degree-7 blends tangent to both
  segments with zero second and third derivatives where they join, so the path is C3 and
  stays within a given distance of each corner.

Where the tangent jumps (a corner left sharp), the path must be traversed at rest: those
parameters are the path's ``stops``. Joint values in rad (revolute) or mm (prismatic); s has
the unit of its source (s of the trajectory, or rad/mm of joint-space length).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline

from kinematics.errors import FieldError

from .hermite import hermite7
from .trajectory import Trajectory, _poly_at

__all__ = ["JointPath", "smooth_polyline", "CORNER_FACTOR"]

#: A corner blend of half-length l between unit directions d0, d1 passes
#: ``CORNER_FACTOR * l * |d1 - d0|`` from the corner (at its middle, the farthest point).
CORNER_FACTOR = 5.0 / 32.0
#: Relative tangent jump across a break above which the path must stop there.
TANGENT_JUMP_TOL = 1e-6


@dataclass(frozen=True)
class JointPath:
    """A piecewise-polynomial joint path.

    ``breaks (K+1,)`` path parameters of the piece boundaries (increasing); ``coeffs (K,
    deg+1, dof)`` each piece's coefficients in ascending powers of ``s - breaks[k]``;
    ``stops (M,)`` parameters where the tangent jumps (the path is traversed at rest there);
    ``waypoint_s (W,)`` the parameters of the waypoints the path was made from.
    """

    breaks: np.ndarray
    coeffs: np.ndarray
    stops: np.ndarray
    waypoint_s: np.ndarray

    @property
    def dof(self) -> int:
        return self.coeffs.shape[2]

    @property
    def length(self) -> float:
        """Parameter span ``s_end - s_start``."""
        return float(self.breaks[-1] - self.breaks[0])

    def piece(self, s: np.ndarray, side: str = "right") -> np.ndarray:
        """Index of the piece each parameter ``s (S,)`` lies in; at a break, the piece on
        ``side`` ('right': the one starting there, 'left': the one ending there)."""
        s = np.asarray(s, dtype=float)
        k = np.searchsorted(self.breaks, s, side="right" if side == "right" else "left") - 1
        return np.clip(k, 0, len(self.breaks) - 2)

    def evaluate(self, s, derivative: int = 0, side: str = "right") -> np.ndarray:
        """``d^m q / ds^m`` at ``s (S,)`` -> ``(S, dof)``; one-sided at breaks (``side``)."""
        s = np.clip(np.asarray(s, dtype=float), self.breaks[0], self.breaks[-1])
        k = self.piece(s, side)
        return _poly_at(self.coeffs[k], s - self.breaks[k], derivative)

    def derivatives(self, s, side: str = "right", order: int = 3) -> np.ndarray:
        """``q, q', q'', ...`` up to ``order`` at ``s (S,)``: ``(order+1, S, dof)``."""
        return np.stack([self.evaluate(s, m, side) for m in range(order + 1)])

    # ---- construction -------------------------------------------------------------------
    @classmethod
    def through(cls, waypoints) -> JointPath:
        """The C4 quintic spline through ``waypoints (n, dof)`` with the joint-space chord
        length as parameter and zero second and third derivatives at both ends (the path
        leaves and arrives straight). Unlike a spline at rest, whose ends have unbounded
        curvature as a curve, its tangent never vanishes for distinct waypoints, which is
        what time-optimal parameterisation wants. Repeated waypoints are dropped;
        ``FieldError`` naming ``waypoints`` when fewer than two distinct remain."""
        P = np.asarray(waypoints, dtype=float)
        if P.ndim != 2 or len(P) < 2 or not np.all(np.isfinite(P)):
            raise FieldError("waypoints", "waypoints: need at least 2 finite joint vectors")
        step = np.linalg.norm(np.diff(P, axis=0), axis=1)
        scale = max(float(step.max(initial=0.0)), 1e-300)
        keep = np.concatenate([[True], step > 1e-12 * scale])
        P = P[keep]
        if len(P) < 2 or step.max(initial=0.0) == 0:
            raise FieldError("waypoints", "waypoints: the path does not move")
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        zero = np.zeros(P.shape[1])
        spline = make_interp_spline(s, P, k=5, bc_type=([(2, zero), (3, zero)],
                                                         [(2, zero), (3, zero)]))
        piecewise = Trajectory.from_bspline(spline, "path", s)
        return cls(piecewise.breaks, piecewise.coeffs, np.zeros(0), s)

    @classmethod
    def from_trajectory(cls, traj: Trajectory, samples: int = 0) -> JointPath:
        """The shape of ``traj`` re-parameterised by joint-space arc length.

        A trajectory at rest somewhere (its ends, a waypoint where a quintic stops) has a
        vanishing tangent there, which makes its own time a poor path parameter (the path
        speed grows without bound near such points). Each stretch between interior rest
        points is resampled at equal arc lengths (``samples`` points, default 16 per
        trajectory piece and at least 64) and interpolated by a quintic spline (C4, error
        far below the sampling step); where two stretches meet at an angle the path stops.
        ``FieldError`` naming ``waypoints`` when the trajectory does not move.
        """
        t_way = np.asarray(traj.breaks[traj.waypoint_index], dtype=float)
        speed_at = np.linalg.norm(traj.evaluate(t_way, 1), axis=1)
        peak = float(np.max(traj.peaks(1)[0], initial=0.0))
        rest = t_way[1:-1][speed_at[1:-1] <= 1e-9 * max(peak, 1e-300)]
        cuts = np.concatenate([[traj.breaks[0]], rest, [traj.breaks[-1]]])
        breaks, coeffs, stops = [], [], []
        offset = 0.0
        way_s = np.zeros(len(t_way))
        for a, b in zip(cuts[:-1], cuts[1:]):
            n_piece = int(np.count_nonzero((traj.breaks > a) & (traj.breaks <= b)))
            section = _arc_length_section(traj, a, b, samples or max(64, 16 * n_piece))
            if section is None:
                continue
            sec_breaks, sec_coeffs, sigma_of = section
            inside = (t_way >= a) & (t_way <= b)
            way_s[inside] = offset + sigma_of(t_way[inside])
            if breaks:
                stops.append(offset)
            breaks.append(offset + sec_breaks[:-1])
            coeffs.append(sec_coeffs)
            offset += float(sec_breaks[-1])
        if not breaks:
            raise FieldError("waypoints", "waypoints: the path does not move")
        all_breaks = np.concatenate(breaks + [[offset]])
        all_coeffs = np.concatenate(coeffs)
        jumps = _tangent_jumps(all_breaks, all_coeffs)
        return cls(all_breaks, all_coeffs, np.intersect1d(np.array(stops), jumps), way_s)


def _arc_length_section(traj: Trajectory, a: float, b: float, n: int):
    """Trajectory times ``[a, b]`` as a quintic spline in arc length sigma from 0:
    ``(breaks, coeffs, sigma_of_t)``, or None when the joints do not move there."""
    fine = np.linspace(a, b, 64 * n + 1)
    speed = np.linalg.norm(traj.evaluate(fine, 1), axis=1)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(fine))])
    total = float(sigma[-1])
    q_span = np.ptp(traj.evaluate(fine), axis=0).max()
    if total <= 1e-12 * max(1.0, float(q_span)) or total == 0.0:
        return None
    targets = np.linspace(0.0, total, n + 1)
    t_at = np.interp(targets, sigma, fine)
    spline = make_interp_spline(targets, traj.evaluate(t_at), k=5)
    piecewise = Trajectory.from_bspline(spline, "path", targets)

    def sigma_of(t: np.ndarray) -> np.ndarray:
        return np.interp(t, fine, sigma)

    return piecewise.breaks - piecewise.breaks[0], piecewise.coeffs, sigma_of


def _tangent_jumps(breaks: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Interior breaks where the first derivative jumps by more than ``TANGENT_JUMP_TOL``
    relative to the larger side."""
    if len(breaks) < 3:
        return np.zeros(0)
    h = np.diff(breaks)
    left = _poly_at(coeffs[:-1], h[:-1], 1)
    right = _poly_at(coeffs[1:], np.zeros(len(h) - 1), 1)
    scale = np.maximum(np.linalg.norm(left, axis=1), np.linalg.norm(right, axis=1))
    jump = np.linalg.norm(left - right, axis=1)
    return breaks[1:-1][jump > TANGENT_JUMP_TOL * np.maximum(scale, 1e-300)]


def _blend(p: np.ndarray, d0: np.ndarray, d1: np.ndarray, half: float) -> np.ndarray:
    """Degree-7 piece ``(8, dof)`` (ascending powers of sigma in [0, 2 half]) from
    ``p - half d0`` to ``p + half d1`` with unit-speed tangents d0, d1 and zero second and
    third derivatives at both ends: a C3 join with the straight segments either side (a
    jerk-limited motion sees no jump of the third derivative there)."""
    zero = np.zeros_like(p)
    start = np.stack([p - half * d0, d0, zero, zero])[:, None, :]
    end = np.stack([p + half * d1, d1, zero, zero])[:, None, :]
    return hermite7(start, end, np.array([2.0 * half]))[0]


def smooth_polyline(points, deviation: float) -> JointPath:
    """The polyline through ``points (n, dof)`` with every interior corner blended.

    Straight pieces are parameterised by joint-space length; a corner between unit
    directions d0, d1 becomes a degree-7 blend over ``2 l`` of parameter that leaves the first
    segment ``l`` before the corner and joins the next ``l`` after it, with
    ``l = min(deviation / (CORNER_FACTOR |d1 - d0|), half of either segment)``: it passes
    within ``deviation`` of the corner (rad/mm, joint-space distance). ``deviation = 0``
    keeps every corner sharp: the path stops there. Repeated points are dropped.
    ``FieldError`` naming ``waypoints`` (fewer than two distinct points, non-finite) or
    ``deviation`` (negative).
    """
    P = np.asarray(points, dtype=float)
    if P.ndim != 2 or len(P) < 2 or not np.all(np.isfinite(P)):
        raise FieldError("waypoints", "waypoints: need at least 2 finite joint vectors")
    if not (math.isfinite(deviation) and deviation >= 0):
        raise FieldError("deviation", "deviation: must be a finite number >= 0")
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    keep = np.concatenate([[True], step > 1e-12])
    P = P[keep]
    if len(P) < 2:
        raise FieldError("waypoints", "waypoints: the points do not move")
    seg = np.diff(P, axis=0)
    L = np.linalg.norm(seg, axis=1)
    d = seg / L[:, None]
    n_corner = len(P) - 2
    half = np.zeros(len(P))  # blend half-length at each vertex (0 at the ends)
    if n_corner and deviation > 0:
        turn = np.linalg.norm(d[1:] - d[:-1], axis=1)
        room = 0.5 * np.minimum(L[:-1], L[1:])
        with np.errstate(divide="ignore"):
            want = np.where(turn > 1e-12, deviation / (CORNER_FACTOR * turn), np.inf)
        half[1:-1] = np.minimum(want, room)
    pieces, stops, waypoint_s = [], [], [0.0]
    s = 0.0
    dof = P.shape[1]
    for k in range(len(seg)):
        start = P[k] + half[k] * d[k]
        run = L[k] - half[k] - half[k + 1]
        if run > 1e-12 * L[k]:
            c = np.zeros((8, dof))
            c[0], c[1] = start, d[k]
            pieces.append((s, run, c))
            s += run
        if k + 1 < len(seg):
            if half[k + 1] > 0:
                pieces.append((s, 2 * half[k + 1], _blend(P[k + 1], d[k], d[k + 1],
                                                          half[k + 1])))
                waypoint_s.append(s + half[k + 1])
                s += 2 * half[k + 1]
            else:
                stops.append(s)
                waypoint_s.append(s)
    waypoint_s.append(s)
    breaks = np.array([p[0] for p in pieces] + [s])
    coeffs = np.stack([p[2] for p in pieces])
    stops_arr = np.array([x for x in stops if 0 < x < s])
    # A corner left sharp where its directions agree (collinear points) is no stop.
    if len(stops_arr):
        stops_arr = np.intersect1d(stops_arr, _tangent_jumps(breaks, coeffs))
    return JointPath(breaks, coeffs, stops_arr, np.array(waypoint_s))
