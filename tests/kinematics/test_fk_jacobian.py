"""FK and Jacobian: batching, independent re-derivations, finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from kinematics.fk import fk, fk_frames
from kinematics.jacobian import dexterity, jacobian
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import rot_x, rot_z, rotation_log, trans

SDH_ARM = RobotModel.from_dict(
    {
        "id": "sdh_arm",
        "convention": "sdh",
        "joints": [
            {"type": "revolute", "a": 50, "alpha": -np.pi / 2, "d": 300,
             "lower": -3, "upper": 3},
            {"type": "prismatic", "a": 0, "alpha": np.pi / 2, "theta": 0.3,
             "lower": 0, "upper": 500},
            {"type": "revolute", "a": 120, "alpha": 0.4, "d": 10, "offset": 0.2,
             "lower": -2, "upper": 2},
            {"type": "revolute", "a": 0, "alpha": np.pi / 2, "d": 80, "lower": -2, "upper": 2},
        ],
        "tool": [[1, 0, 0, 10], [0, 1, 0, 0], [0, 0, 1, 60], [0, 0, 0, 1]],
        "base": [[0, -1, 0, 100], [1, 0, 0, 0], [0, 0, 1, 20], [0, 0, 0, 1]],
    }
)

POE_ARM = RobotModel.from_dict(
    {
        "id": "poe_arm",
        "convention": "poe",
        "joints": [
            {"type": "revolute", "axis": [0, 0, 1], "point": [0, 0, 0], "lower": -3,
             "upper": 3},
            {"type": "revolute", "axis": [0, 1, 0], "point": [0, 0, 400], "lower": -2,
             "upper": 2},
            {"type": "prismatic", "axis": [1, 0, 0], "lower": 0, "upper": 300},
            {"type": "revolute", "axis": [1, 0, 0], "point": [500, 0, 400], "lower": -3,
             "upper": 3},
        ],
        "home": [[1, 0, 0, 600], [0, 1, 0, 0], [0, 0, 1, 400], [0, 0, 0, 1]],
        "tool": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]],
    }
)

MODELS = [builtin_model(rid) for rid in BUILTIN_IDS] + [SDH_ARM, POE_ARM]
IDS = [m.id for m in MODELS]


def random_q(model: RobotModel, n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.lower, model.upper, (n, model.dof))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_batched_fk_equals_single_pose_path(model):
    Q = random_q(model, 20)
    batch = fk(model, Q)
    assert batch.shape == (20, 4, 4)
    for k in range(20):
        np.testing.assert_allclose(batch[k], fk(model, Q[k]), atol=1e-12)
    frames = fk_frames(model, Q)
    assert frames.shape == (20, model.dof + 1, 4, 4)
    np.testing.assert_allclose(frames[:, -1], batch, atol=1e-9)
    np.testing.assert_allclose(frames[:, 0], np.broadcast_to(model.base, (20, 4, 4)))


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_fk_rejects_wrong_shape(model):
    with pytest.raises(ValueError, match=str(model.dof)):
        fk(model, np.zeros(model.dof + 1))
    with pytest.raises(ValueError, match=str(model.dof)):
        fk(model, np.zeros((2, 3, model.dof + 1)))
    with pytest.raises(ValueError):
        fk(model, 0.0)


def _hand_chain(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """The chain multiplied out from elementary transforms (independent of fk.py)."""
    T = model.base.copy()
    for j, v in zip(model.joints, q):
        theta = v + j.offset if j.revolute else j.theta
        d = j.d if j.revolute else v + j.offset
        if model.convention == "mdh":
            T = T @ rot_x(j.alpha) @ trans(j.a) @ rot_z(theta) @ trans(0, 0, d)
        else:
            T = T @ rot_z(theta) @ trans(0, 0, d) @ trans(j.a) @ rot_x(j.alpha)
    return T @ model.tool


@pytest.mark.parametrize("model", [builtin_model("glt_palletizer"), SDH_ARM], ids=["mdh", "sdh"])
def test_dh_fk_matches_elementary_product(model):
    for q in random_q(model, 10, seed=3):
        np.testing.assert_allclose(fk(model, q), _hand_chain(model, q), atol=1e-9)


def _twist_matrix(axis, point, revolute):
    w = np.array(axis, dtype=float)
    S = np.zeros((4, 4))
    if revolute:
        S[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
        S[:3, 3] = -np.cross(w, point)
    else:
        S[:3, 3] = w
    return S


@pytest.mark.parametrize(
    "model", [builtin_model("hyper_redundant_9dof"), POE_ARM], ids=["9dof", "poe_arm"]
)
def test_poe_fk_matches_matrix_exponential(model):
    for q in random_q(model, 10, seed=4):
        T = model.base.copy()
        for j, v in zip(model.joints, q):
            T = T @ expm(_twist_matrix(j.axis, j.point or (0, 0, 0), j.revolute) * v)
        np.testing.assert_allclose(fk(model, q), T @ model.home @ model.tool, atol=1e-9)


def _numeric_jacobian(model: RobotModel, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    J = np.zeros((6, model.dof))
    T0 = fk(model, q)
    for i in range(model.dof):
        dq = np.zeros(model.dof)
        dq[i] = h
        Tp, Tm = fk(model, q + dq), fk(model, q - dq)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        # World-frame angular velocity: log(R(q+h) R(q)^T) / h, central difference.
        wp = rotation_log(Tp[:3, :3] @ T0[:3, :3].T)
        wm = rotation_log(Tm[:3, :3] @ T0[:3, :3].T)
        J[3:, i] = (wp - wm) / (2 * h)
    return J


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_jacobian_equals_finite_differences(model):
    for q in random_q(model, 5, seed=5):
        J = jacobian(model, q)
        assert J.shape == (6, model.dof)
        Jn = _numeric_jacobian(model, q)
        scale = np.abs(J).max()
        np.testing.assert_allclose(J[:3], Jn[:3], atol=1e-6 * scale)
        np.testing.assert_allclose(J[3:], Jn[3:], atol=1e-7)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_batched_jacobian_equals_single(model):
    Q = random_q(model, 7, seed=6)
    JB = jacobian(model, Q)
    for k in range(7):
        np.testing.assert_allclose(JB[k], jacobian(model, Q[k]), atol=1e-12)


def _reference_pose(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """One tool pose from elementary transforms or matrix exponentials (not fk.py)."""
    if model.convention != "poe":
        return _hand_chain(model, q)
    T = model.base.copy()
    for j, v in zip(model.joints, q):
        T = T @ expm(_twist_matrix(j.axis, j.point or (0, 0, 0), j.revolute) * (v + j.offset))
    return T @ model.home @ model.tool


#: Leading batch shape of the property test: two groups of three configurations.
BATCH = (2, 3)


@pytest.mark.slow
@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(
    st.sampled_from(MODELS),
    st.lists(st.floats(0.0, 1.0), min_size=6 * 9, max_size=6 * 9),
)
def test_fk_leading_batch_dims_property(model, u):
    """``(2, 3, dof) -> (2, 3, 4, 4)`` (frames ``(2, 3, dof + 1, 4, 4)``, Jacobians
    ``(2, 3, 6, dof)``), entry by entry equal to one call per configuration and to the chain
    multiplied out by hand. Row k draws every joint from its own sixth of the joint range,
    so no two of the six configurations are alike."""
    n = BATCH[0] * BATCH[1]
    frac = (np.arange(n)[:, None] + np.array(u).reshape(n, 9)[:, : model.dof]) / n
    Q = (model.lower + frac * (model.upper - model.lower)).reshape(BATCH + (model.dof,))
    assert len({tuple(row) for row in Q.reshape(n, model.dof)}) == n
    T = fk(model, Q)
    F = fk_frames(model, Q)
    J = jacobian(model, Q)
    assert T.shape == BATCH + (4, 4)
    assert F.shape == BATCH + (model.dof + 1, 4, 4)
    assert J.shape == BATCH + (6, model.dof)
    for i in range(BATCH[0]):
        for k in range(BATCH[1]):
            np.testing.assert_allclose(T[i, k], fk(model, Q[i, k]), atol=1e-9)
            np.testing.assert_allclose(T[i, k], _reference_pose(model, Q[i, k]), atol=1e-8)
            np.testing.assert_allclose(F[i, k], fk_frames(model, Q[i, k]), atol=1e-9)
            np.testing.assert_allclose(J[i, k], jacobian(model, Q[i, k]), atol=1e-9)
    # The poses differ from row to row, so a mix-up of rows would show.
    flat = T.reshape(n, 4, 4)
    assert min(np.abs(flat[a] - flat[b]).max() for a in range(n) for b in range(a)) > 1e-6
    # Every pose is rigid.
    R = T[..., :3, :3]
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_fk_accepts_any_leading_shape(model):
    q = random_q(model, 1, seed=9)[0]
    assert fk(model, q).shape == (4, 4)
    assert fk(model, q[None, None, None]).shape == (1, 1, 1, 4, 4)
    assert fk(model, np.zeros((0, model.dof))).shape == (0, 4, 4)
    assert fk(model, np.zeros((2, 0, model.dof))).shape == (2, 0, 4, 4)
    np.testing.assert_allclose(fk(model, q[None, None])[0, 0], fk(model, q), atol=1e-12)


def test_dexterity_at_singularity():
    glt = builtin_model("glt_palletizer")
    q = np.radians([10, 30, 20, 40, 0, 50])  # theta5 = 0: wrist axes 4 and 6 align
    dx = dexterity(glt, jacobian(glt, q))
    assert dx.condition == np.inf or dx.condition > 1e10
    assert dx.manipulability < 1e-3
    dx_ok = dexterity(glt, jacobian(glt, np.radians([10, 30, 20, 40, 45, 50])))
    assert np.isfinite(dx_ok.condition) and dx_ok.manipulability > 1.0
