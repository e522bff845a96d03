"""``PositionJacobian``: the prefix-product fast path for all-revolute product-of-exponentials
arms agrees with the general Jacobian, and every other model goes through the general one."""

from __future__ import annotations

import numpy as np
import pytest

import kinematics
from kinematics.jacobian import PositionJacobian, jacobian_and_pose
from kinematics.library import builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import rot_x, rot_z, trans

ARM = builtin_model("hyper_redundant_9dof")


def _unit(v) -> list[float]:
    return (np.asarray(v, dtype=float) / np.linalg.norm(v)).tolist()


#: All revolute, product of exponentials, with what the 9-DOF arm lacks: skew axes, joint
#: offsets, a turned home frame and a tool with an offset.
SKEW_POE = RobotModel.from_dict({
    "id": "skew_poe",
    "convention": "poe",
    "joints": [
        {"type": "revolute", "axis": [0, 0, 1], "point": [10, 0, 0], "offset": 0.3,
         "lower": -3, "upper": 3},
        {"type": "revolute", "axis": _unit([0, 1, 1]), "point": [0, 50, 300], "lower": -2,
         "upper": 2},
        {"type": "revolute", "axis": _unit([1, -2, 0.5]), "point": [200, 0, 400], "offset": -0.7,
         "lower": -2, "upper": 2},
        {"type": "revolute", "axis": [1, 0, 0], "point": [450, 20, 380], "lower": -3,
         "upper": 3},
        {"type": "revolute", "axis": [0, 0, 1], "point": [500, 0, 350], "lower": -3,
         "upper": 3},
    ],
    "home": (trans(520, 15, 360) @ rot_x(0.4) @ rot_z(-0.9)).tolist(),
    "tool": trans(5, -10, 80).tolist(),
})


def _moved(model: RobotModel) -> RobotModel:
    data = model.to_dict()
    c, s = np.cos(0.7), np.sin(0.7)
    data["base"] = [[c, -s, 0, 100.0], [s, c, 0, -50.0], [0, 0, 1, 30.0], [0, 0, 0, 1]]
    return RobotModel.from_dict(data)


@pytest.mark.parametrize("model", [ARM, _moved(ARM), SKEW_POE, _moved(SKEW_POE)],
                         ids=["9dof", "9dof-moved-base", "skew", "skew-moved-base"])
def test_fast_path_matches_the_general_jacobian(model):
    jac = PositionJacobian(model)
    assert jac.fast
    q = np.random.default_rng(0).uniform(model.lower, model.upper, size=(64, model.dof))
    p, J = jac(q)
    J_ref, T_ref = jacobian_and_pose(model, q)
    assert p.shape == (64, 3) and J.shape == (64, 3, model.dof)
    np.testing.assert_allclose(p, T_ref[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(J, J_ref[:, :3], atol=1e-9)


@pytest.mark.parametrize("robot", ["glt_palletizer", "pile_driver", "tunnel_drill_arm"])
def test_other_models_use_the_general_jacobian(robot):
    model = builtin_model(robot)
    jac = PositionJacobian(model)
    assert not jac.fast
    q = np.random.default_rng(1).uniform(model.lower, model.upper, size=(8, model.dof))
    p, J = jac(q)
    J_ref, T_ref = jacobian_and_pose(model, q)
    np.testing.assert_array_equal(p, T_ref[:, :3, 3])
    np.testing.assert_array_equal(J, J_ref[:, :3])


def test_a_prismatic_joint_takes_the_general_path():
    data = SKEW_POE.to_dict()
    data["joints"][2] = {"type": "prismatic", "axis": [1, 0, 0], "lower": 0, "upper": 300}
    model = RobotModel.from_dict(data)
    assert not PositionJacobian(model).fast
    q = np.random.default_rng(2).uniform(model.lower, model.upper, size=(8, model.dof))
    p, J = PositionJacobian(model)(q)
    J_ref, T_ref = jacobian_and_pose(model, q)
    np.testing.assert_allclose(p, T_ref[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(J, J_ref[:, :3], atol=1e-9)


def test_position_jacobian_is_public():
    assert kinematics.PositionJacobian is PositionJacobian
