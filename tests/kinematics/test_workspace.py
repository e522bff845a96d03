"""Monte Carlo workspace."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.workspace import MAX_SAMPLES, sample_workspace


def test_seeded_and_consistent():
    model = builtin_model("glt_palletizer")
    a = sample_workspace(model, 5000, seed=3)
    b = sample_workspace(model, 5000, seed=3)
    np.testing.assert_array_equal(a.points, b.points)
    c = sample_workspace(model, 5000, seed=4)
    assert not np.array_equal(a.points, c.points)
    assert a.points.shape == (5000, 3)
    np.testing.assert_allclose(a.min, a.points.min(axis=0))
    for name in ("xy", "xz", "yz"):
        assert a.projections[name].sum() == 5000
        assert a.projections[name].shape == (64, 64)
    assert a.volume > 0 and a.voxel > 0


def test_points_are_tool_positions_within_limits():
    model = builtin_model("pile_driver")
    ws = sample_workspace(model, 2000, seed=1)
    rng = np.random.default_rng(1)
    q = rng.uniform(model.lower, model.upper, (2000, model.dof))
    np.testing.assert_allclose(ws.points, fk(model, q)[:, :3, 3])


def test_radial_and_vertical_are_in_the_base_frame():
    model = builtin_model("glt_palletizer")  # base raised 449.822 mm
    ws = sample_workspace(model, 3000, seed=0)
    r = np.hypot(ws.points[:, 0], ws.points[:, 1])
    assert ws.radial == pytest.approx((r.min(), r.max()))
    assert ws.vertical[1] == pytest.approx(ws.max[2] - 449.822)


def test_volume_grows_towards_a_limit_with_samples():
    model = builtin_model("pile_driver")
    v_small = sample_workspace(model, 2000, voxel=100.0).volume
    v_large = sample_workspace(model, 40000, voxel=100.0).volume
    assert v_large > v_small


@pytest.mark.parametrize("samples", [0, -5, MAX_SAMPLES + 1])
def test_sample_count_checked(samples):
    with pytest.raises(ValueError, match="samples"):
        sample_workspace(builtin_model("pile_driver"), samples)


def test_progress_reported():
    seen = []
    sample_workspace(builtin_model("pile_driver"), 120_000, progress=seen.append)
    assert seen[-1] == 1.0 and seen == sorted(seen) and len(seen) >= 3
