"""Time scaling: the shortest durations that keep a trajectory within its rate limits.

Stretching a segment's time by a factor s divides its velocity by s, acceleration by s^2 and
jerk by s^3 while leaving the path unchanged. So the factor that brings a segment exactly to
its limits is ``max over joints and quantities of (peak / limit) ** (1 / m)``; with it the
binding quantity's peak equals its limit (to the accuracy of the peak search, well under 1 %).
"""

from __future__ import annotations

import numpy as np

from kinematics.errors import FieldError

from .trajectory import Limits, Trajectory

__all__ = ["fit_to_limits"]


def fit_to_limits(traj: Trajectory, limits: Limits, *, per_segment: bool) -> Trajectory:
    """Rescale ``traj`` in time so its peak velocity, acceleration and jerk meet ``limits``.

    ``per_segment=True`` scales each segment on its own (right for trajectories that stop at
    every waypoint: the joins stay at rest); otherwise one factor stretches the whole
    trajectory, which keeps smooth trajectories smooth. Factors below 1 shorten a trajectory
    that was slower than it needed to be. Raises ``FieldError`` naming ``limits`` when no
    rate limit is finite.
    """
    if not any(
        lim is not None and np.any(np.isfinite(np.asarray(lim, dtype=float)))
        for lim in (limits.velocity, limits.acceleration, limits.jerk)
    ):
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
