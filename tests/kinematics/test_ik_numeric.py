"""Numeric IK: weighted damped least squares (paper 003 eqs. 6-13), batched, multi-start."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.errors import MethodUnavailableError
from kinematics.fk import fk
from kinematics.ik import NumericOptions, analytic_solver, solve_ik
from kinematics.ik.numeric import limit_gradient
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.transforms import pose_errors


def reachable_poses(model, n, seed):
    rng = np.random.default_rng(seed)
    q = rng.uniform(model.lower, model.upper, (n, model.dof))
    return q, fk(model, q)


@pytest.mark.parametrize("robot_id", BUILTIN_IDS)
def test_fk_ik_identity_numeric(robot_id):
    model = builtin_model(robot_id)
    _, T = reachable_poses(model, 60, seed=11)
    results = solve_ik(model, T, method="numeric")
    assert all(r.success for r in results), [r.message for r in results if not r.success]
    Q = np.array([r.q for r in results])
    dp, dr = pose_errors(fk(model, Q), T)
    assert dp.max() < 1e-4 and dr.max() < 1e-7
    assert all(model.within_limits(Q))
    assert all(r.within_limits and r.method == "numeric" for r in results)


def test_auto_uses_numeric_without_closed_form():
    model = builtin_model("hyper_redundant_9dof")
    assert analytic_solver(model) is None
    _, T = reachable_poses(model, 3, seed=2)
    assert {r.method for r in solve_ik(model, T)} == {"numeric"}
    with pytest.raises(MethodUnavailableError):
        solve_ik(model, T, method="analytic")
    with pytest.raises(MethodUnavailableError):
        solve_ik(model, T, method="learned")


def test_out_of_reach_gives_a_reason_not_an_exception():
    model = builtin_model("hyper_redundant_9dof")
    T = np.eye(4)
    T[:3, 3] = [3000.0, 0, 0]
    (res,) = solve_ik(model, T, method="numeric", options=NumericOptions(restarts=4))
    assert not res.success and res.status == "not_converged"
    assert "out of reach" in res.message and res.q is None
    assert res.position_error > 1000


def test_q0_picks_the_nearest_redundant_solution():
    model = builtin_model("hyper_redundant_9dof")
    q_true, T = reachable_poses(model, 1, seed=5)
    (res,) = solve_ik(model, T[0], method="numeric", q0=q_true[0] + 0.01)
    assert res.success
    # From a start this close, DLS walks straight to the nearby solution.
    assert np.abs(res.q - q_true[0]).max() < 0.05


def test_all_solutions_returns_distinct_branches():
    model = builtin_model("glt_palletizer")
    _, T = reachable_poses(model, 1, seed=8)
    (res,) = solve_ik(model, T, method="numeric", all_solutions=True,
                      options=NumericOptions(restarts=16))
    assert res.success and len(res.solutions) >= 2
    dp, dr = pose_errors(fk(model, res.solutions), T)
    assert dp.max() < 1e-4 and dr.max() < 1e-7
    assert len(np.unique(np.round(res.solutions, 4), axis=0)) == len(res.solutions)


def test_seeded_runs_are_reproducible():
    model = builtin_model("pile_driver")
    _, T = reachable_poses(model, 10, seed=9)
    a = solve_ik(model, T, method="numeric")
    b = solve_ik(model, T, method="numeric")
    for ra, rb in zip(a, b):
        np.testing.assert_array_equal(ra.q, rb.q)


def test_limit_gradient_is_derivative_of_objective():
    """Eq. 10 (per joint) is the derivative of eq. 9's H."""
    model = builtin_model("hyper_redundant_9dof")
    lo, hi = model.lower, model.upper
    n = model.dof

    def H(q):
        return np.sum((hi - lo) ** 2 / ((hi - q) * (q - lo))) / n

    q = np.random.default_rng(0).uniform(lo * 0.9, hi * 0.9)
    g = limit_gradient(q, lo, hi)
    for i in range(n):
        dq = np.zeros(n)
        dq[i] = 1e-6
        assert g[i] == pytest.approx((H(q + dq) - H(q - dq)) / 2e-6, rel=1e-5, abs=1e-8)
    # Zero at the middle of the range, growing without bound towards the limits.
    assert np.allclose(limit_gradient((lo + hi) / 2, lo, hi), 0)
    assert np.all(np.abs(limit_gradient(hi - 1e-6, lo, hi)) > 1e6)


def test_unweighted_option_also_converges():
    model = builtin_model("pile_driver")
    _, T = reachable_poses(model, 20, seed=12)
    res = solve_ik(model, T, method="numeric", options=NumericOptions(weighted=False))
    assert sum(r.success for r in res) >= 19


def test_rejects_non_rigid_and_nan_targets():
    model = builtin_model("glt_palletizer")
    T = fk(model, np.zeros(6))
    bad = T.copy()
    bad[:3, :3] *= 2
    with pytest.raises(ValueError, match="rigid"):
        solve_ik(model, bad)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        solve_ik(model, bad)
    with pytest.raises(ValueError, match="q0"):
        solve_ik(model, T, q0=np.zeros(5))
