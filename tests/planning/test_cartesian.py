"""Cartesian lines and ellipses mapped through IK into joint trajectories."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.trajectories.cartesian import ellipse_points, follow_path, line_points


def test_ellipse_points_lie_on_the_ellipse_evenly_spaced():
    pts = ellipse_points([100, 0, 50], (300, 100), 41, normal=[0, 0, 1], major=[1, 0, 0])
    x, y = (pts[:, 0] - 100) / 300, pts[:, 1] / 100
    np.testing.assert_allclose(x**2 + y**2, 1.0, atol=1e-9)
    np.testing.assert_allclose(pts[:, 2], 50.0)
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    # Even by arc length: the chords differ only where the curvature is high (the ellipse's
    # tips, radius of curvature b^2/a = 33 mm, about one step).
    assert steps.max() / steps.min() < 1.03
    np.testing.assert_allclose(pts[0], pts[-1], atol=1e-9)  # closed


@pytest.mark.parametrize("bad", [dict(radii=(0, 1)), dict(normal=(0, 0, 0))])
def test_ellipse_rejects_bad_input(bad):
    kwargs = dict(center=[0, 0, 0], radii=(1, 1), n=10) | bad
    with pytest.raises(ValueError):
        ellipse_points(kwargs.pop("center"), kwargs.pop("radii"), kwargs.pop("n"), **kwargs)


def test_glt_follows_a_line_closely():
    glt = builtin_model("glt_palletizer")
    q0 = np.radians([10, 40, 10, 0, 40, 0])
    T0 = fk(glt, q0)
    pts = line_points(T0[:3, 3], T0[:3, 3] + [100, 300, -200], 40)
    plan = follow_path(glt, pts, T0[:3, :3], 6.0, q0)
    assert plan.waypoint_error.max() < 1e-6
    T = fk(glt, plan.q_waypoints)
    np.testing.assert_allclose(T[:, :3, 3], pts, atol=1e-6)
    np.testing.assert_allclose(T[:, :3, :3], np.broadcast_to(T0[:3, :3], T[:, :3, :3].shape),
                               atol=1e-9)
    # Between waypoints the joint spline strays a little from the straight line.
    assert plan.max_deviation < 2.0 and plan.mean_deviation < plan.max_deviation
    assert max(plan.trajectory.continuity().values()) < 1e-6


def test_unreachable_path_names_the_point():
    glt = builtin_model("glt_palletizer")
    q0 = np.radians([10, 40, 10, 0, 40, 0])
    T0 = fk(glt, q0)
    pts = line_points(T0[:3, 3], [6000.0, 0.0, 0.0], 10)
    with pytest.raises(ValueError, match=r"points\[\d+\]"):
        follow_path(glt, pts, T0[:3, :3], 5.0, q0)
