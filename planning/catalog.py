"""The built-in algorithms, registered by name in ``planning.registry``'s families.

This table sits at the top of ``planning``: it names modules of every floor (the
optimisers, the sequencers, the drilling planners), while the registry below them knows only
how to load a ``(module, class)`` pair on first use. ``planning/__init__.py`` imports it, so
the names are registered before any ``planning`` module runs; nothing is loaded until a
name is used.
"""

from __future__ import annotations

from .registry import AutoPlannerParams, RRTStarParams, ShortcutParams, register

__all__: list[str] = []

for _name, _module, _cls, _preset, _summary in (
    ("wolfpack_improved", "planning.optimisers.wolfpack_improved", "ImprovedWolfPack", None,
     "improved wolf pack: adaptive steps, Levy-flight wandering (paper 000)"),
    ("wolfpack", "planning.optimisers.wolfpack", "WolfPack", None,
     "wolf pack algorithm (paper 000's baseline)"),
    ("ga", "planning.optimisers.ga", "GeneticAlgorithm", "paper_000",
     "real-coded genetic algorithm with paper 000's settings"),
    ("aca", "planning.optimisers.aca", "AntColony", None,
     "ant colony algorithm on a layered grid (paper 000's baseline)"),
    ("afsa", "planning.optimisers.afsa", "FishSwarm", None,
     "artificial fish swarm algorithm (paper 000's baseline)"),
):
    register("path", _name, (_module, _cls), preset=_preset, summary=_summary)
register("path", "rrt_star", RRTStarParams, shared=ShortcutParams,
         summary="RRT* with exact edge checks")
register("path", "auto", AutoPlannerParams, shared=ShortcutParams,
         summary="near-shortest path: visibility graph, shortcutting and tightening (ours)")

for _kind, _name, _module, _cls, _summary in (
    ("sequencer", "iga", "planning.sequencing.iga", "IGA",
     "improved genetic algorithm (paper 002)"),
    ("sequencer", "aco", "planning.sequencing.aco", "ACO",
     "ant colony hole sequencer, Ant System (paper 002's baseline)"),
    ("sequencer", "aga", "planning.sequencing.aga", "AGA",
     "adaptive genetic algorithm (paper 002's baseline)"),
    ("sequencer", "auto", "planning.sequencing.auto", "Auto",
     "near-optimal order: exact on small faces, iterated 2-opt/Or-opt above (ours)"),
    ("move_planner", "iapf", "planning.drilling.iapf", "IAPF",
     "improved artificial potential field in joint space (paper 002)"),
    ("move_planner", "rrt", "planning.drilling.rrt", "RRTConnect",
     "joint-space RRT-Connect (paper 002's baseline)"),
    ("tuner", "hgso", "planning.optimisers.hgso", "HGSO",
     "Henry gas solubility optimisation (paper 003)"),
    ("tuner", "pso", "planning.optimisers.pso", "PSO", "particle swarm optimisation (paper 003)"),
    ("tuner", "ga", "planning.optimisers.ga", "GeneticAlgorithm",
     "real-coded genetic algorithm with paper 003's settings"),
    ("tuner", "aco", "planning.optimisers.acor", "ACOR",
     "ACO_R, ant colony for continuous variables (paper 003)"),
    ("tuner", "gwo", "planning.optimisers.gwo", "GWO", "grey wolf optimiser (paper 003)"),
):
    register(_kind, _name, (_module, _cls), summary=_summary)
del _kind, _name, _module, _cls, _preset, _summary
