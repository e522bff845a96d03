"""Tool paths in Cartesian space (straight lines, ellipses) mapped through IK into joints.

The tool keeps a constant orientation along the path. Points are spaced evenly by arc
length; the joint waypoints from IK (each solved near the previous one, so the arm stays on
one branch) are joined by a C4 quintic spline timed by arc length, and the report says how
far the tool strays from the ideal path between the waypoints as well as at them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.ik import solve_ik
from kinematics.model import RobotModel

from .polynomials import smooth_spline
from .trajectory import Trajectory

__all__ = ["line_points", "ellipse_points", "CartesianPlan", "follow_path", "path_deviation"]

#: Samples per waypoint interval used to measure the deviation between waypoints.
DEVIATION_OVERSAMPLING = 20


def line_points(start, end, n: int) -> np.ndarray:
    """``n`` points evenly spaced from ``start`` to ``end`` (mm) -> ``(n, 3)``; ``FieldError``
    naming ``points`` (``n``) or ``end``."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    if n < 2:
        raise FieldError("points", "points: a path needs at least 2 points")
    if np.linalg.norm(end - start) < 1e-9:
        raise FieldError("end", "end: a line needs distinct start and end points")
    return start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)


def ellipse_points(center, radii, n: int, *, normal=(0.0, 0.0, 1.0), major=None,
                   closed: bool = True) -> np.ndarray:
    """``n`` points on an ellipse (mm) evenly spaced by arc length -> ``(n, 3)``.

    ``radii = (a, b)`` along the major direction ``major`` (default: any direction normal to
    ``normal``) and ``normal x major``; the first point is at ``center + a * major``.
    ``closed`` repeats the first point at the end. ``FieldError`` naming the argument at
    fault (``points`` for ``n``).
    """
    c = np.asarray(center, dtype=float)
    a, b = (float(r) for r in radii)
    if a <= 0 or b <= 0:
        raise FieldError("radii", "radii: both radii must be positive")
    if n < 3:
        raise FieldError("points", "points: an ellipse needs at least 3 points")
    nz = np.asarray(normal, dtype=float)
    if np.linalg.norm(nz) < 1e-12:
        raise FieldError("normal", "normal: must be a non-zero vector")
    nz = nz / np.linalg.norm(nz)
    if major is None:
        helper = np.array([1.0, 0.0, 0.0]) if abs(nz[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        major = helper - nz * (helper @ nz)
    ex = np.asarray(major, dtype=float) - nz * (np.asarray(major, dtype=float) @ nz)
    if np.linalg.norm(ex) < 1e-12:
        raise FieldError("major", "major: must not be parallel to the normal")
    ex /= np.linalg.norm(ex)
    ey = np.cross(nz, ex)
    # Even spacing by arc length: invert the cumulative length on a fine grid.
    phi = np.linspace(0.0, 2 * np.pi, 4097)
    pts = a * np.cos(phi)[:, None] * ex + b * np.sin(phi)[:, None] * ey
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    targets = np.linspace(0.0, s[-1], n) if closed else np.linspace(0.0, s[-1], n + 1)[:n]
    phis = np.interp(targets, s, phi)
    return c + a * np.cos(phis)[:, None] * ex + b * np.sin(phis)[:, None] * ey


@dataclass(frozen=True)
class CartesianPlan:
    """A tool path mapped into joints. ``q_waypoints (n, dof)``; ``trajectory`` through them;
    ``waypoint_error`` (mm) the IK residual at each point; ``max_deviation`` and
    ``mean_deviation`` (mm) the tool's distance from the ideal polyline path over the whole
    sampled trajectory; ``failed`` the indices of points IK could not reach, with reasons."""

    points: np.ndarray
    q_waypoints: np.ndarray
    trajectory: Trajectory
    waypoint_error: np.ndarray
    max_deviation: float
    mean_deviation: float
    failed: list[tuple[int, str]]


def _distance_to_polyline(p: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of points ``p (S, 3)`` to the polyline through ``line (n, 3)``."""
    a, b = line[:-1], line[1:]
    ab = b - a
    L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    t = np.clip(np.einsum("sij,ij->si", p[:, None, :] - a[None], ab) / L2, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None, :] - closest, axis=-1).min(axis=1)


def follow_path(
    model: RobotModel,
    points: np.ndarray,
    rotation: np.ndarray,
    duration: float,
    q0: np.ndarray | None = None,
) -> CartesianPlan:
    """Map tool positions ``points (n, 3)`` (mm, world frame) with constant tool ``rotation
    (3, 3)`` into a joint trajectory lasting ``duration`` s.

    Each point is solved near the previous solution (the first near ``q0``). Raises
    ValueError if some point cannot be reached, naming the first one and why (``FieldError``
    naming ``duration`` for a duration <= 0).
    """
    points = np.asarray(points, dtype=float)
    if not duration > 0:
        raise FieldError("duration", "duration: must be positive")
    n = len(points)
    T = np.repeat(np.eye(4)[None], n, axis=0)
    T[:, :3, :3] = rotation
    T[:, :3, 3] = points
    q_prev = q0
    qs, errs, failed = [], [], []
    for k in range(n):
        (res,) = solve_ik(model, T[k], q0=q_prev)
        if not res.success:
            failed.append((k, res.message))
            break
        qs.append(res.q)
        errs.append(res.position_error)
        q_prev = res.q
    if failed:
        k, why = failed[0]
        raise ValueError(f"points[{k}] at {np.round(points[k], 3).tolist()} mm: {why}")
    q = np.array(qs)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    durations = duration * seg / seg.sum()
    traj = smooth_spline(q, durations)
    dev_max, dev_mean = path_deviation(model, traj, points)
    return CartesianPlan(points, q, traj, np.array(errs), dev_max, dev_mean, failed)


def path_deviation(model: RobotModel, traj: Trajectory, points: np.ndarray
                   ) -> tuple[float, float]:
    """Largest and mean distance (mm) of the tool along ``traj`` from the polyline through
    ``points (n, 3)``, sampled ``DEVIATION_OVERSAMPLING`` times per point interval (e.g.
    after the joint path was re-timed)."""
    t = np.linspace(traj.breaks[0], traj.breaks[-1],
                    (len(points) - 1) * DEVIATION_OVERSAMPLING + 1)
    dev = _distance_to_polyline(fk(model, traj.evaluate(t))[:, :3, 3], points)
    return float(dev.max()), float(dev.mean())
