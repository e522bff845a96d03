"""The built-in algorithms, registered by name in ``planning.registry``'s families.

This table sits at the top of ``planning``: it names modules of every floor (the
optimisers, the sequencers, the drilling planners), while the registry below them knows only
how to load a ``(module, class)`` pair on first use. ``planning/__init__.py`` imports it, so
the names are registered before any ``planning`` module runs; nothing is loaded until a
name is used.
"""

from __future__ import annotations

from typing import Any

from .registry import AutoPlannerParams, RRTStarParams, ShortcutParams, register

__all__: list[str] = []

#: Every built-in algorithm, in the order each family lists it: (family, name, its parameter
#: dataclass or ``(module, class name)`` loaded on first use, preset, shared knobs, summary).
BUILTIN: tuple[tuple[str, str, Any, str | None, type | None, str], ...] = (
    ("path", "wolfpack_improved",
     ("planning.optimisers.wolfpack_improved", "ImprovedWolfPack"), None, None,
     "improved wolf pack: adaptive steps, Levy-flight wandering (paper 000)"),
    ("path", "wolfpack", ("planning.optimisers.wolfpack", "WolfPack"), None, None,
     "wolf pack algorithm (paper 000's baseline)"),
    ("path", "ga", ("planning.optimisers.ga", "GeneticAlgorithm"), "paper_000", None,
     "real-coded genetic algorithm with paper 000's settings"),
    ("path", "aca", ("planning.optimisers.aca", "AntColony"), None, None,
     "ant colony algorithm on a layered grid (paper 000's baseline)"),
    ("path", "afsa", ("planning.optimisers.afsa", "FishSwarm"), None, None,
     "artificial fish swarm algorithm (paper 000's baseline)"),
    ("path", "rrt_star", RRTStarParams, None, ShortcutParams, "RRT* with exact edge checks"),
    ("path", "auto", AutoPlannerParams, None, ShortcutParams,
     "near-shortest path: visibility graph, shortcutting and tightening (ours)"),
    ("sequencer", "iga", ("planning.sequencing.iga", "IGA"), None, None,
     "improved genetic algorithm (paper 002)"),
    ("sequencer", "aco", ("planning.sequencing.aco", "ACO"), None, None,
     "ant colony hole sequencer, Ant System (paper 002's baseline)"),
    ("sequencer", "aga", ("planning.sequencing.aga", "AGA"), None, None,
     "adaptive genetic algorithm (paper 002's baseline)"),
    ("sequencer", "auto", ("planning.sequencing.auto", "Auto"), None, None,
     "near-optimal order: exact on small faces, iterated 2-opt/Or-opt above (ours)"),
    ("move_planner", "iapf", ("planning.drilling.iapf", "IAPF"), None, None,
     "improved artificial potential field in joint space (paper 002)"),
    ("move_planner", "rrt", ("planning.drilling.rrt", "RRTConnect"), None, None,
     "joint-space RRT-Connect (paper 002's baseline)"),
    ("tuner", "hgso", ("planning.optimisers.hgso", "HGSO"), None, None,
     "Henry gas solubility optimisation (paper 003)"),
    ("tuner", "pso", ("planning.optimisers.pso", "PSO"), None, None,
     "particle swarm optimisation (paper 003)"),
    ("tuner", "ga", ("planning.optimisers.ga", "GeneticAlgorithm"), None, None,
     "real-coded genetic algorithm with paper 003's settings"),
    ("tuner", "aco", ("planning.optimisers.acor", "ACOR"), None, None,
     "ACO_R, ant colony for continuous variables (paper 003)"),
    ("tuner", "gwo", ("planning.optimisers.gwo", "GWO"), None, None,
     "grey wolf optimiser (paper 003)"),
)

for _family, _name, _params, _preset, _shared, _summary in BUILTIN:
    register(_family, _name, _params, preset=_preset, shared=_shared, summary=_summary)
del _family, _name, _params, _preset, _shared, _summary
