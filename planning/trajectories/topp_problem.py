"""The discretised time-optimal parameterisation problem that ``topp`` solves and
``smoothing`` lowers where a smoothed profile oversteps a limit.

It lives apart from both so that ``smoothing`` need not import ``topp`` (which imports
``smoothing``): the data flows one way, ``topp`` -> ``smoothing``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ToppProblem"]


@dataclass(frozen=True)
class ToppProblem:
    """The discretised problem: grid ``s (N+1,)``, first-order bounds ``x_max (N+1,)`` and
    second-order rows per stage ``A, B, lo, hi (N, R)``."""

    s: np.ndarray
    x_max: np.ndarray
    A: np.ndarray
    B: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
