"""Obstacle-avoiding paths for a tool and for a whole arm (paper 000 and ours).

* ``scene``: the obstacles (spheres, boxes, capsules), the bounds and the exact
  segment-obstacle clearances every planner is checked with;
* ``encoding``: a path as a flat vector for the metaheuristics, its penalised cost, the
  planning slack and shortcutting (shared with ``planning.optimisers.aca``; it imports no
  planner);
* ``auto``: the visibility-graph planner (``auto``), RRT* and the certifier the tests hold
  planners to;
* ``planners``: ``plan_path``, any planner by name, verified and shortened;
* ``arm``: ``plan_arm_path``, a tool path the whole arm follows clear of the obstacles
  (``planning.motion.arm_motion.plan_arm_motion``, one floor up, falls back on a joint-space
  motion when the arm cannot follow it);
* ``compare``: repeated runs of several planners side by side.

The names below load their module on first use, so importing ``planning.paths.encoding``
(as the ant colony does) loads no planner.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from .arm import ArmPathResult as ArmPathResult
    from .arm import arm_clearance as arm_clearance
    from .arm import plan_arm_path as plan_arm_path
    from .auto import certified_shortest_path as certified_shortest_path
    from .auto import plan_auto as plan_auto
    from .auto import plan_rrt_star as plan_rrt_star
    from .compare import CompareRow as CompareRow
    from .compare import compare_planners as compare_planners
    from .encoding import PathEncoding as PathEncoding
    from .encoding import path_length as path_length
    from .encoding import shortcut as shortcut
    from .planners import ALGORITHMS as ALGORITHMS
    from .planners import PathResult as PathResult
    from .planners import make_optimiser as make_optimiser
    from .planners import plan_path as plan_path
    from .scene import Box as Box
    from .scene import Capsule as Capsule
    from .scene import Scene as Scene
    from .scene import Sphere as Sphere

#: Public name -> the module it loads from on first use.
_LAZY = {
    "ArmPathResult": "arm",
    "arm_clearance": "arm",
    "plan_arm_path": "arm",
    "certified_shortest_path": "auto",
    "plan_auto": "auto",
    "plan_rrt_star": "auto",
    "CompareRow": "compare",
    "compare_planners": "compare",
    "PathEncoding": "encoding",
    "path_length": "encoding",
    "shortcut": "encoding",
    "ALGORITHMS": "planners",
    "PathResult": "planners",
    "make_optimiser": "planners",
    "plan_path": "planners",
    "Box": "scene",
    "Capsule": "scene",
    "Scene": "scene",
    "Sphere": "scene",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
