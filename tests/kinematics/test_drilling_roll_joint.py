"""The drilling arm's roll joint, named by its structure: the joint ``drill_ik``'s ``roll``
sets, with its limits; arms without the drilling structure have none."""

from __future__ import annotations

import numpy as np
import pytest

import kinematics
from kinematics.drilling import (
    ROLL_JOINT,
    DrillingJoint,
    check_drilling_structure,
    drill_ik,
    roll_joint,
)
from kinematics.library import builtin_model
from kinematics.model import RobotModel

ARM = builtin_model("tunnel_drill_arm")


def test_the_roll_joint_is_the_one_drill_ik_turns():
    roll = roll_joint(ARM)
    assert roll == DrillingJoint(ROLL_JOINT, "roll", -np.pi, np.pi)
    hole = [9500.0, 1500.0, 3000.0]
    base = drill_ik(ARM, hole)[0].q
    (res,) = drill_ik(ARM, hole, roll=0.4)
    assert res.success, res.message
    assert res.q[roll.index] == pytest.approx(0.4)
    assert base[roll.index] == 0.0


def test_the_roll_joint_follows_the_model_limits_and_names():
    data = ARM.to_dict()
    data["joints"][ROLL_JOINT].update(name="drill_roll", lower=-0.5, upper=0.25)
    roll = roll_joint(RobotModel.from_dict(data))
    assert (roll.name, roll.lower, roll.upper) == ("drill_roll", -0.5, 0.25)
    assert roll.within(0.25) and roll.within(-0.5) and roll.within(0.0)
    assert not roll.within(0.2500001) and not roll.within(-0.6)


@pytest.mark.parametrize("robot", ["glt_palletizer", "pile_driver", "hyper_redundant_9dof"])
def test_other_arms_have_no_roll_joint_and_say_why(robot):
    model = builtin_model(robot)
    with pytest.raises(ValueError) as structure:
        check_drilling_structure(model)
    with pytest.raises(ValueError) as err:
        roll_joint(model)
    assert str(err.value) == str(structure.value)


def test_roll_joint_is_public():
    assert kinematics.roll_joint is roll_joint
