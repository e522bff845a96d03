"""Tunnel-face drilling with a multi-arm jumbo (paper 002, sections 3.2-3.4, 4 and 5).

* ``patterns``: face drilling patterns (horseshoe, circular) and hole import (CSV, JSON);
* ``allocation``: holes to arms by reach and balance (the paper's 40 / 52 / 40);
* ``envelopes``: capsule envelopes of the arms' links and distances between arms;
* ``space``: the joint space of a transfer between holes (drill kept perpendicular);
* ``iapf``: the paper's improved artificial potential field (eqs. 8-13);
* ``rrt``: the RRT-Connect baseline;
* ``multiarm``: the whole-face planner and its 10 ms collision check;
* ``plans``: drill plans in and out (IREDES ``DRPPlan``, CSV, JSON): ``DrillPlan``, ``Hole``.

Sequencing (the drilling order of one arm's holes) lives in ``planning.sequencing``.
"""

from __future__ import annotations

from .allocation import Allocation as Allocation
from .allocation import allocate_holes as allocate_holes
from .allocation import assign_holes as assign_holes
from .allocation import home_configuration as home_configuration
from .envelopes import ArmEnvelope as ArmEnvelope
from .envelopes import drill_arm_envelope as drill_arm_envelope
from .iapf import IAPF as IAPF
from .iapf import MovePath as MovePath
from .multiarm import FacePlan as FacePlan
from .multiarm import MotionLimits as MotionLimits
from .multiarm import park_configuration as park_configuration
from .multiarm import plan_face as plan_face
from .multiarm import plan_move as plan_move
from .patterns import FacePattern as FacePattern
from .patterns import HolePattern as HolePattern
from .patterns import face_pattern as face_pattern
from .patterns import load_holes as load_holes
from .patterns import parse_holes as parse_holes
from .plans import DrillPlan as DrillPlan
from .plans import Hole as Hole
from .plans import PlanFormatError as PlanFormatError
from .plans import read_csv as read_csv
from .plans import read_iredes as read_iredes
from .plans import read_json as read_json
from .plans import to_csv as to_csv
from .plans import write_iredes as write_iredes
from .rrt import RRTConnect as RRTConnect
from .space import ArmSpace as ArmSpace
from .space import Obstacles as Obstacles

__all__ = [
    "Allocation",
    "ArmEnvelope",
    "ArmSpace",
    "DrillPlan",
    "FacePattern",
    "FacePlan",
    "Hole",
    "HolePattern",
    "IAPF",
    "MotionLimits",
    "MovePath",
    "Obstacles",
    "PlanFormatError",
    "RRTConnect",
    "allocate_holes",
    "assign_holes",
    "drill_arm_envelope",
    "face_pattern",
    "home_configuration",
    "load_holes",
    "parse_holes",
    "park_configuration",
    "plan_face",
    "plan_move",
    "read_csv",
    "read_iredes",
    "read_json",
    "to_csv",
    "write_iredes",
]
