"""Position-only IK: the tool point on a given point within the limits less an inset, from
a seeded table of starts; the closest solution to a given guess; reach; unreachable points."""

from __future__ import annotations

import numpy as np
import pytest

import kinematics
from kinematics.fk import fk
from kinematics.ik.position import (
    LIMIT_INSET,
    REACH_TOL,
    SEED_TABLE,
    position_dls,
    position_ik,
    reach,
)
from kinematics.library import builtin_model

PILE = builtin_model("pile_driver")
ARM9 = builtin_model("hyper_redundant_9dof")


def _inset_limits(model, inset=LIMIT_INSET):
    span = model.upper - model.lower
    return model.lower + inset * span, model.upper - inset * span


@pytest.mark.parametrize("model", [PILE, ARM9, builtin_model("glt_palletizer")],
                         ids=lambda m: m.id)
def test_position_ik_puts_the_tool_point_on_reachable_points(model):
    lo, hi = _inset_limits(model, 0.05)
    q_true = np.random.default_rng(3).uniform(lo, hi, size=(5, model.dof))
    for point in fk(model, q_true)[:, :3, 3]:
        q, err = position_ik(model, point)
        assert q is not None, point
        assert err < REACH_TOL
        assert np.linalg.norm(fk(model, q)[:3, 3] - point) < REACH_TOL
        lower, upper = _inset_limits(model)
        assert np.all(q >= lower - 1e-12) and np.all(q <= upper + 1e-12)


def test_position_ik_returns_the_solution_nearest_the_guess():
    """The redundant arm has a family of solutions for a point: the one returned is the one
    nearest ``q0``, which is ``q0`` itself when it already reaches the point."""
    q0 = ARM9.mid_configuration() + 0.2
    point = fk(ARM9, q0)[:3, 3]
    q, err = position_ik(ARM9, point, q0=q0)
    assert err < REACH_TOL
    np.testing.assert_allclose(q, q0, atol=1e-6)
    q_free, _ = position_ik(ARM9, point)
    assert np.linalg.norm(q_free - q0) > 1e-3  # without the guess: another member


def test_position_ik_says_how_close_it_came_to_an_unreachable_point():
    far = np.array([3000.0, 0.0, 0.0])
    q, err = position_ik(PILE, far)
    assert q is None
    d = np.linalg.norm(far - PILE.base[:3, 3])
    assert d - reach(PILE) - 1.0 < err < d  # about the distance beyond the reach


def test_reach_bounds_every_sampled_tool_point():
    R = reach(PILE)
    q = np.random.default_rng(7).uniform(PILE.lower, PILE.upper, size=(SEED_TABLE, PILE.dof))
    d = np.linalg.norm(fk(PILE, q)[:, :3, 3] - PILE.base[:3, 3], axis=1)
    assert d.max() <= R * 1.01 and R <= PILE.length_scale
    assert 1900 < R < 1920


def test_position_dls_is_batched_and_stays_inside_the_inset_limits():
    rng = np.random.default_rng(5)
    targets = fk(PILE, rng.uniform(*_inset_limits(PILE, 0.1), size=(6, PILE.dof)))[:, :3, 3]
    starts = np.tile(PILE.mid_configuration(), (6, 1))
    for inset in (LIMIT_INSET, 0.05):
        Q, err = position_dls(PILE, starts, targets, 200, REACH_TOL / 10, inset=inset)
        assert Q.shape == (6, PILE.dof) and err.shape == (6,)
        np.testing.assert_allclose(err, np.linalg.norm(fk(PILE, Q)[:, :3, 3] - targets,
                                                       axis=1), atol=1e-9)
        lower, upper = _inset_limits(PILE, inset)
        assert np.all(Q >= lower - 1e-12) and np.all(Q <= upper + 1e-12)
    assert np.all(err < REACH_TOL)


def test_centring_moves_free_joints_towards_mid_range():
    """The 9-DOF arm keeps six free joints for a point; a centring step spends them on
    getting closer to mid-range, and the point is still reached."""
    q_start = ARM9.mid_configuration() + 0.6 * (ARM9.upper - ARM9.mid_configuration())
    point = fk(ARM9, q_start)[:3, 3]
    plain, e_plain = position_dls(ARM9, q_start[None], point, 50, REACH_TOL / 10)
    centred, e_centred = position_dls(ARM9, q_start[None], point, 50, REACH_TOL / 10,
                                      centring=0.2)
    assert e_plain[0] < REACH_TOL and e_centred[0] < REACH_TOL
    mid = ARM9.mid_configuration()
    assert np.linalg.norm(centred[0] - mid) < np.linalg.norm(plain[0] - mid) - 1e-3


def test_position_ik_is_public():
    assert kinematics.position_ik is position_ik and kinematics.reach is reach
