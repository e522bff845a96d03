"""Metaheuristic optimisers behind one interface (``base.Optimiser``); one module each."""

from .base import OptimResult, Problem, ProgressFn, run_with_budget

__all__ = ["OptimResult", "Problem", "ProgressFn", "run_with_budget"]
