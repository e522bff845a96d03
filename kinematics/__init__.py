"""Kinematics of serial arms and hydraulic cylinders: robot models, forward kinematics,
Jacobians, inverse kinematics, workspaces, rigs, calibration and learned IK.

Frames, units and array layouts: docs/conventions.md. Pure numpy/scipy code: it never
imports ``app`` or ``web``. The names below are the public surface; the modules that need
scipy (``calibration``, ``learned_ik``) load on first use of their names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

from .cylinders import CylinderError as CylinderError
from .cylinders import CylinderPins as CylinderPins
from .cylinders import CylinderSet as CylinderSet
from .cylinders import FourBarCylinder as FourBarCylinder
from .cylinders import SwingCylinderPair as SwingCylinderPair
from .cylinders import TriangleCylinder as TriangleCylinder
from .cylinders import cylinder_set as cylinder_set
from .cylinders import diagnose_limits as diagnose_limits
from .drilling import DRILL_D7 as DRILL_D7
from .drilling import compensation_angles as compensation_angles
from .drilling import drill_axis as drill_axis
from .drilling import drill_ik as drill_ik
from .drilling import roll_joint as roll_joint
from .errors import FieldError as FieldError
from .errors import KinematicsError as KinematicsError
from .errors import MethodUnavailableError as MethodUnavailableError
from .fk import fk as fk
from .fk import fk_frames as fk_frames
from .ik import IKResult as IKResult
from .ik import IKStatus as IKStatus
from .ik import NumericOptions as NumericOptions
from .ik import available_methods as available_methods
from .ik import position_ik as position_ik
from .ik import reach as reach
from .ik import solve_ik as solve_ik
from .jacobian import Dexterity as Dexterity
from .jacobian import PositionJacobian as PositionJacobian
from .jacobian import dexterity as dexterity
from .jacobian import jacobian as jacobian
from .jacobian import jacobian_and_pose as jacobian_and_pose
from .library import BUILTIN_IDS as BUILTIN_IDS
from .library import builtin_model as builtin_model
from .library import builtin_models as builtin_models
from .model import Joint as Joint
from .model import ModelError as ModelError
from .model import RobotModel as RobotModel
from .numbers import finite_or_none as finite_or_none
from .rigs import BUILTIN_RIG_IDS as BUILTIN_RIG_IDS
from .rigs import Rig as Rig
from .rigs import builtin_rig as builtin_rig
from .transforms import invert_pose as invert_pose
from .transforms import make_pose as make_pose
from .transforms import matrix_to_rpy as matrix_to_rpy
from .transforms import pose_errors as pose_errors
from .transforms import rot_x as rot_x
from .transforms import rot_y as rot_y
from .transforms import rot_z as rot_z
from .transforms import rpy_to_matrix as rpy_to_matrix
from .transforms import trans as trans
from .urdf import to_urdf as to_urdf
from .workspace import Workspace as Workspace
from .workspace import sample_workspace as sample_workspace
from .workspace import workspace_report as workspace_report

if TYPE_CHECKING:
    from .calibration import CalibrationResult as CalibrationResult
    from .calibration import calibrate as calibrate
    from .learned_ik import LearnedIK as LearnedIK
    from .learned_ik import TrainingReport as TrainingReport
    from .learned_ik import train_learned_ik as train_learned_ik

#: Names whose modules import scipy, loaded on first use: name -> module.
_LAZY = {
    "CalibrationResult": "calibration",
    "calibrate": "calibration",
    "LearnedIK": "learned_ik",
    "TrainingReport": "learned_ik",
    "train_learned_ik": "learned_ik",
}

__all__ = [
    "BUILTIN_IDS",
    "BUILTIN_RIG_IDS",
    "CalibrationResult",
    "CylinderError",
    "CylinderPins",
    "CylinderSet",
    "DRILL_D7",
    "Dexterity",
    "FieldError",
    "FourBarCylinder",
    "IKResult",
    "IKStatus",
    "Joint",
    "KinematicsError",
    "LearnedIK",
    "MethodUnavailableError",
    "ModelError",
    "NumericOptions",
    "PositionJacobian",
    "Rig",
    "RobotModel",
    "SwingCylinderPair",
    "TrainingReport",
    "TriangleCylinder",
    "Workspace",
    "available_methods",
    "builtin_model",
    "builtin_models",
    "builtin_rig",
    "calibrate",
    "compensation_angles",
    "cylinder_set",
    "dexterity",
    "diagnose_limits",
    "drill_axis",
    "drill_ik",
    "finite_or_none",
    "fk",
    "fk_frames",
    "invert_pose",
    "jacobian",
    "jacobian_and_pose",
    "make_pose",
    "matrix_to_rpy",
    "pose_errors",
    "position_ik",
    "reach",
    "roll_joint",
    "rot_x",
    "rot_y",
    "rot_z",
    "rpy_to_matrix",
    "sample_workspace",
    "solve_ik",
    "to_urdf",
    "train_learned_ik",
    "trans",
    "workspace_report",
]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
