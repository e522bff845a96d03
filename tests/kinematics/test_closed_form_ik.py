"""FK then closed-form IK is the identity, for every 6R arm with a closed form: the pile
driver (paper 001) and the GLT palletizer (paper 004), on random configurations inside the
joint limits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.fk import fk
from kinematics.ik import solve_ik
from kinematics.library import builtin_model
from kinematics.transforms import pose_errors


@pytest.mark.parametrize("robot", ["pile_driver", "glt_palletizer"])
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(u=st.lists(st.floats(0.02, 0.98), min_size=6, max_size=6))
def test_fk_ik_identity_closed_form(robot, u):
    model = builtin_model(robot)
    q = model.lower + np.array(u) * (model.upper - model.lower)
    T = fk(model, q)
    (res,) = solve_ik(model, T, method="analytic", all_solutions=True)
    assert res.success
    dp, dr = pose_errors(fk(model, res.solutions), T[None])
    assert dp.max() < 1e-6 and dr.max() < 1e-9
    if not res.singular:  # at a singular wrist only the sum of the outer angles is fixed
        assert np.abs(res.solutions - q).max(axis=1).min() < 1e-6
