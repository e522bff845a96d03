"""Robot model descriptions: validation names the field at fault; JSON round trips."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import MAX_DOF, ModelError, RobotModel

BASE = {
    "id": "arm",
    "convention": "mdh",
    "joints": [
        {"name": "j1", "type": "revolute", "a": 0, "alpha": 0, "d": 100, "lower": -3, "upper": 3},
        {"name": "j2", "type": "prismatic", "a": 150, "alpha": -1.5708, "theta": 0,
         "lower": 0, "upper": 800},
    ],
}


def mutated(path, value):
    data = copy.deepcopy(BASE)
    target = data
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return data


@pytest.mark.parametrize(
    "path, value, field",
    [
        (["joints", 0, "lower"], 5.0, "joints[0].lower"),
        (["joints", 1, "upper"], math.nan, "joints[1].upper"),
        (["joints", 0, "a"], math.inf, "joints[0].a"),
        (["joints", 0, "type"], "helical", "joints[0].type"),
        (["joints", 0, "velocity"], -1.0, "joints[0].velocity"),
        (["joints", 0, "lower"], "low", "joints[0].lower"),
        (["convention"], "dh", "convention"),
        (["id"], "", "id"),
        (["id"], "has space", "id"),
        (["joints"], [], "joints"),
        (["base"], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "base"),
        (["tool"], [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "tool"),
        (["joints", 0, "colour"], "red", "joints[0].colour"),
    ],
)
def test_invalid_models_name_the_field(path, value, field):
    with pytest.raises(ModelError) as err:
        RobotModel.from_dict(mutated(path, value))
    assert err.value.field == field
    assert field in str(err.value)


def test_too_many_joints():
    data = copy.deepcopy(BASE)
    data["joints"] = [dict(BASE["joints"][0], name=f"j{i}") for i in range(MAX_DOF + 1)]
    with pytest.raises(ModelError, match="at most"):
        RobotModel.from_dict(data)


def test_poe_needs_home_and_unit_axes():
    data = {
        "id": "p", "convention": "poe",
        "joints": [{"type": "revolute", "axis": [0, 0, 1], "point": [0, 0, 0],
                    "lower": -1, "upper": 1}],
    }
    with pytest.raises(ModelError, match="home"):
        RobotModel.from_dict(data)
    data["home"] = np.eye(4).tolist()
    data["joints"][0]["axis"] = [0, 0, 2]
    with pytest.raises(ModelError, match="unit"):
        RobotModel.from_dict(data)


@pytest.mark.parametrize("robot_id", BUILTIN_IDS)
def test_json_round_trip_keeps_kinematics(robot_id):
    model = builtin_model(robot_id)
    again = RobotModel.from_dict(model.to_dict())
    q = np.random.default_rng(0).uniform(model.lower, model.upper, (5, model.dof))
    np.testing.assert_allclose(fk(again, q), fk(model, q), atol=1e-12)
    assert again.to_dict() == model.to_dict()


def test_builtins_document_their_source():
    for robot_id in BUILTIN_IDS:
        data = builtin_model(robot_id).to_dict()
        assert data["source"] and data["notes"]


def test_nine_dof_reading_and_limits():
    model = builtin_model("hyper_redundant_9dof")
    assert model.dof == 9 and model.convention == "poe"
    np.testing.assert_allclose(model.velocity_limits, 0.1)
    np.testing.assert_allclose(model.upper, np.radians(120))
    axes = [j.axis for j in model.joints]
    assert axes[0::2] == [(0.0, 0.0, 1.0)] * 5 and axes[1::2] == [(1.0, 0.0, 0.0)] * 4
    centres = [j.point[2] for j in model.joints]
    np.testing.assert_allclose(centres, [0, 136.80, 286.11, 483.75, 621.91, 815.07, 940.63,
                                         1114.45, 1241.08])


def test_limit_helpers():
    model = builtin_model("pile_driver")
    q = model.mid_configuration()
    assert model.within_limits(q)
    q[4] = 1.0
    assert not model.within_limits(q)
    assert model.limit_violations(q) == ["tilt"]
    with pytest.raises(ValueError):
        model.lower[0] = 0.0  # derived arrays are read-only


def test_editing_a_models_dict_leaves_the_model_alone():
    """to_dict's answer is the caller's: renaming a cylinder's joint in it once corrupted
    the cached built-in pile driver for every later user in the process."""
    from kinematics.library import builtin_model

    data = builtin_model("pile_driver").to_dict()
    data["cylinders"][0]["joint"] = "renamed"
    data["joints"][1]["name"] = "renamed"
    again = builtin_model("pile_driver").to_dict()
    assert again["cylinders"][0]["joint"] != "renamed"
    assert again["joints"][1]["name"] != "renamed"
