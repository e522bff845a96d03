"""Time scaling: the shortest durations that keep a trajectory within its rate limits.

Two ways, named by ``TIME_SCALINGS``:

* ``uniform`` (``fit_to_limits``, ``fit_uniform``): stretching a segment's time by a factor
  f divides its velocity by f, acceleration by f^2 and jerk by f^3 while leaving the path
  unchanged, so the factor that brings a segment exactly to its limits is ``max over
  joints and quantities of (peak / limit) ** (1 / m)``; cylinder speeds and pump flow
  scale like velocities. With it the binding quantity's peak equals its limit (to the
  accuracy of the peak search, well under 1 %) -- at one instant only.
* ``optimal`` (``fit_optimal``): the path through the waypoints (``path_for``) re-timed by
  time-optimal path parameterisation (``topp``): some limit binds at every instant. With a
  jerk limit, the smoothing pass of ``smoothing`` keeps it too.

``none`` leaves the trajectory as planned.
"""

from __future__ import annotations

import numpy as np

from kinematics.errors import FieldError

from .hydraulic import HydraulicLimits
from .joint_path import JointPath, smooth_polyline
from .limits_check import limit_ratios, piece_samples
from .topp import DEFAULT_GRID, ToppResult, time_optimal
from .trajectory import Limits, Trajectory

__all__ = ["TIME_SCALINGS", "fit_to_limits", "fit_uniform", "fit_optimal", "path_for"]

TIME_SCALINGS = ("none", "uniform", "optimal")


def _has_rate_limit(limits: Limits) -> bool:
    return any(lim is not None and np.any(np.isfinite(np.asarray(lim, dtype=float)))
               for lim in (limits.velocity, limits.acceleration, limits.jerk))


def fit_to_limits(traj: Trajectory, limits: Limits, *, per_segment: bool) -> Trajectory:
    """Rescale ``traj`` in time so its peak velocity, acceleration and jerk meet ``limits``.

    ``per_segment=True`` scales each segment on its own (right for trajectories that stop at
    every waypoint: the joins stay at rest); otherwise one factor stretches the whole
    trajectory, which keeps smooth trajectories smooth. Factors below 1 shorten a trajectory
    that was slower than it needed to be. Raises ``FieldError`` naming ``limits`` when no
    rate limit is finite.
    """
    if not _has_rate_limit(limits):
        raise FieldError("limits", "limits: time scaling needs a finite velocity, acceleration "
                         "or jerk limit")
    if per_segment:
        segments = [np.array([k]) for k in range(len(traj.breaks) - 1)]
        factors = traj.stretch_factor(limits, segments)
    else:
        factors = traj.stretch_factor(limits)
    # A segment that does not move at all keeps its duration.
    factors = np.where(factors > 0, factors, 1.0)
    return traj.scaled(factors if per_segment else float(factors[0]))


def _hydraulic_ratios(traj: Trajectory, hydraulics: HydraulicLimits) -> np.ndarray:
    """Largest cylinder-speed or pump-flow ratio of each segment ``(K,)``."""
    _, q, qd = piece_samples(traj)
    r = limit_ratios(q, qd, qd, None, None, None, None, hydraulics).first_order()
    return r.reshape(len(traj.breaks) - 1, -1).max(axis=1)


def fit_uniform(traj: Trajectory, limits: Limits, hydraulics: HydraulicLimits | None = None,
                *, per_segment: bool) -> Trajectory:
    """``fit_to_limits`` that also keeps the cylinder speeds and the pump flow within the
    ``hydraulics``: the factor is the largest of the joints' and the hydraulics' own.
    ``FieldError`` naming ``limits`` when there is no rate limit at all."""
    if hydraulics is None:
        return fit_to_limits(traj, limits, per_segment=per_segment)
    if _has_rate_limit(limits):
        traj = fit_to_limits(traj, limits, per_segment=per_segment)
        floor = 1.0  # the joints' factor is already applied: only stretch further
    else:
        floor = 0.0
    r = _hydraulic_ratios(traj, hydraulics)
    if per_segment:
        f = np.where(r > 0, np.maximum(r, floor), 1.0)
        return traj.scaled(f)
    f = float(r.max(initial=0.0))
    return traj.scaled(max(f, floor) if f > 0 else 1.0)


def fit_optimal(path: JointPath | Trajectory, limits: Limits,
                hydraulics: HydraulicLimits | None = None, *, grid: int = DEFAULT_GRID
                ) -> ToppResult:
    """``path`` timed by ``topp.time_optimal`` within ``limits`` and the ``hydraulics``, at
    rest at both ends. A ``Trajectory`` is taken for its shape (``JointPath.from_trajectory``);
    ``path_for`` gives the path a planning method stands for. ``FieldError`` naming
    ``limits.acceleration`` when a joint that moves has no acceleration limit (without one
    the fastest motion would jump in speed)."""
    if isinstance(path, Trajectory):
        path = JointPath.from_trajectory(path)
    acc = limits.acceleration
    acc = np.full(path.dof, np.inf) if acc is None else \
        np.broadcast_to(np.asarray(acc, dtype=float), (path.dof,))
    q = path.evaluate(np.linspace(path.breaks[0], path.breaks[-1], 257))
    moves = np.ptp(q, axis=0) > 0
    if np.any(moves & ~np.isfinite(acc)):
        j = int(np.argmax(moves & ~np.isfinite(acc)))
        raise FieldError(("limits", "acceleration"), "limits.acceleration: optimal time "
                         f"scaling needs an acceleration limit for every joint that moves "
                         f"(joint {j} has none)")
    return time_optimal(path, limits, hydraulics, grid=grid)


def path_for(method: str, waypoints, traj: Trajectory | None = None, *,
             rests: bool = True) -> JointPath:
    """The geometric path a planning ``method`` stands for when it is re-timed: ``quintic``
    at rest at every waypoint, straight joint-space segments stopping at every corner;
    quintic with given waypoint rates, the shape of ``traj``; the smooth methods
    (``sextic``, ``bspline5``, ``smooth``), the C4 spline through the waypoints leaving and
    arriving straight (``JointPath.through``)."""
    if method == "quintic":
        if rests:
            return smooth_polyline(waypoints, 0.0)
        if traj is None:
            raise ValueError("a quintic with waypoint rates needs its trajectory")
        return JointPath.from_trajectory(traj)
    return JointPath.through(waypoints)
