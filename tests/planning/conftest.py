"""Collision models of the small imported robots of ``test_motion`` (a gantry carrying a
ball, a two-link arm), built once per module that asks for them."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def gantry_cm():
    from test_motion import GANTRY

    from kinematics.urdf_import import import_robot
    from planning.collision import RobotCollisionModel

    return RobotCollisionModel.from_imported(import_robot(GANTRY.encode(), "gantry.urdf",
                                                          robot_id="gantry"))


@pytest.fixture(scope="module")
def arm_cm():
    from test_motion import ARM

    from kinematics.urdf_import import import_robot
    from planning.collision import RobotCollisionModel

    return RobotCollisionModel.from_imported(import_robot(ARM.encode(), "arm2.urdf",
                                                          robot_id="arm2"))
