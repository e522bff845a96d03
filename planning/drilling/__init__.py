"""Tunnel-face drilling with a multi-arm jumbo (paper 002, sections 3.2-3.4, 4 and 5).

* ``patterns``: face drilling patterns (horseshoe, circular) and hole import (CSV, JSON);
* ``allocation``: holes to arms by reach and balance (the paper's 40 / 52 / 40);
* ``envelopes``: capsule envelopes of the arms' links and distances between arms;
* ``space``: the joint space of a transfer between holes (drill kept perpendicular);
* ``iapf``: the paper's improved artificial potential field (eqs. 8-13);
* ``rrt``: the RRT-Connect baseline;
* ``multiarm``: the whole-face planner and its 10 ms collision check.

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
from .rrt import RRTConnect as RRTConnect
from .space import ArmSpace as ArmSpace
from .space import Obstacles as Obstacles

__all__ = [
    "Allocation",
    "ArmEnvelope",
    "ArmSpace",
    "FacePattern",
    "FacePlan",
    "HolePattern",
    "IAPF",
    "MotionLimits",
    "MovePath",
    "Obstacles",
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
]
