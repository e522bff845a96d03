"""Hole sequencing: the drilling order of a face as an open path from the arm's position.

``sequence_holes(holes, start, algorithm, seed, params)`` is the entry point; the algorithms
are the paper's IGA (``iga``), its two baselines ACO (``aco``) and AGA (``aga``), and our
near-optimal ``auto`` (exact dynamic programming on small faces, a compiled iterated 2-opt /
Or-opt / Lin-Kernighan search over neighbour lists above: ``auto``, ``oropt``,
``candidates``). Paper 002, sections 3.2 and 4.1. Any symmetric cost table can be sequenced
too (``SequencingProblem.from_costs``), and nodes with several alternatives each (IK
branches of a hole) by ``branches``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..registry import algorithm_classes, make
from .aco import ACO as ACO
from .aga import AGA as AGA
from .auto import Auto as Auto
from .base import ProgressFn as ProgressFn
from .base import SequenceResult as SequenceResult
from .base import SequencingProblem as SequencingProblem
from .base import check_holes as check_holes
from .exact import held_karp as held_karp
from .iga import IGA as IGA

__all__ = [
    "ACO",
    "AGA",
    "Auto",
    "IGA",
    "SEQUENCERS",
    "ProgressFn",
    "SequenceResult",
    "SequencingProblem",
    "check_holes",
    "held_karp",
    "make_sequencer",
    "sequence_holes",
]

#: Algorithm name -> parameter dataclass (defaults = the paper's): the ``sequencer`` family
#: of ``planning.registry``.
SEQUENCERS: dict[str, type] = algorithm_classes("sequencer")


def make_sequencer(algorithm: str, params: dict[str, Any] | None = None):
    """The sequencer ``algorithm`` with ``params`` overriding its defaults:
    ``registry.make("sequencer", algorithm, params)``. ``FieldError`` naming ``algorithm``,
    or ``params.<name>`` for an unknown or out-of-range parameter."""
    return make("sequencer", algorithm, params)


def sequence_holes(
    holes,
    start=None,
    algorithm: str = "auto",
    seed: int | np.random.Generator = 0,
    params: dict[str, Any] | None = None,
    *,
    progress: ProgressFn | None = None,
    max_evaluations: int | None = None,
) -> SequenceResult:
    """Drilling order of ``holes (N, 3)`` (mm) as an open path from ``start (3,)`` (mm; None:
    from ``holes[0]``, drilled first), no return. Returns a ``SequenceResult`` whose ``order``
    lists hole indices and ``length`` is in mm. ``FieldError`` naming the field at fault."""
    seq = make_sequencer(algorithm, params)
    problem = SequencingProblem.from_holes(holes, start)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    return seq.solve(problem, rng, progress=progress, max_evaluations=max_evaluations)
