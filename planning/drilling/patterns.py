"""Drilling patterns of a tunnel face, generated or imported: ``planning.sequencing.patterns``
under the name the drilling planners and the service use (the pattern itself sits with the
sequencers that order its holes, below everything that plans motions over the face)."""

from ..sequencing.patterns import FACE_X as FACE_X
from ..sequencing.patterns import HOLE_KINDS as HOLE_KINDS
from ..sequencing.patterns import FacePattern as FacePattern
from ..sequencing.patterns import HolePattern as HolePattern
from ..sequencing.patterns import face_pattern as face_pattern
from ..sequencing.patterns import load_holes as load_holes
from ..sequencing.patterns import parse_holes as parse_holes

__all__ = ["FACE_X", "HOLE_KINDS", "FacePattern", "HolePattern", "face_pattern", "load_holes",
           "parse_holes"]
