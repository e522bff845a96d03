"""The sampling-based search core: RRT-Connect, RRT* and path shortcutting over an abstract
space, shared by every planner that samples.

A planner supplies a space (``space.SearchSpace``: ``sample``, ``nearest``, ``steer``,
``segment_free``, and for RRT* the batch ``distances``/``segments_free``) and a stop rule;
the core grows the trees, draws the random numbers in a fixed order (the space's
``sample`` being the only draw of an RRT-Connect iteration) and returns a ``SearchResult``
(path, status, statistics). Users: the tool paths (``planning.paths.auto``: RRT* in the
scene's box), the drilling arms (``planning.drilling.rrt``: RRT-Connect in the normalised
transfer space), joint-space motion (``planning.motion.search``: lazy RRT-Connect and
shortcutting in weighted joint coordinates, with ``planning.motion._rrt`` its compiled
twin).

This package imports only ``planning.status``: it sits just above the floor of what every
planner shares, below geometry, collision and every planner.
"""

from .planner import STEP_FRACTION as STEP_FRACTION
from .planner import SamplingPlanner as SamplingPlanner
from .result import SearchResult as SearchResult
from .result import Stop as Stop
from .result import iteration_budget as iteration_budget
from .rrt_connect import rrt_connect as rrt_connect
from .rrt_star import rrt_star as rrt_star
from .rrt_star import rrt_star_informed as rrt_star_informed
from .shortcut import farthest_visible as farthest_visible
from .shortcut import path_length as path_length
from .shortcut import reduce_waypoints as reduce_waypoints
from .shortcut import shortcut as shortcut
from .shortcut import shortcut_chords as shortcut_chords
from .shortcut import shortcut_vertices as shortcut_vertices
from .space import BoxSpace as BoxSpace
from .space import SearchSpace as SearchSpace
from .tree import Tree as Tree

__all__ = ["SamplingPlanner", "STEP_FRACTION", "SearchResult", "Stop", "iteration_budget",
           "rrt_connect", "rrt_star", "rrt_star_informed", "farthest_visible", "path_length",
           "reduce_waypoints", "shortcut", "shortcut_chords", "shortcut_vertices", "BoxSpace",
           "SearchSpace", "Tree"]
