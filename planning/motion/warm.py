"""Loading the planner's compiled kernels before the first timed plan.

The kernels are compiled once per machine (``cache=True``: tens of seconds the first time,
then loaded from ``__pycache__`` in about a second per process). ``warm_up`` runs every one
of them once on a small problem (a built-in robot's capsule model among a few primitives, and
a search and a shortcut; the exact stage's mesh test on one triangle), so that a plan's
time limit never pays for it; ``start_warm_up`` does that in a background thread. Safe to
call again: the second call returns at once.
"""

from __future__ import annotations

import threading
import time

import numpy as np

__all__ = ["warm_up", "start_warm_up"]

_lock = threading.Lock()
_done = False


def warm_up() -> float:
    """Load (or compile) every kernel of ``planning.motion`` and answer the seconds it
    took (0 when already done or without compiled kernels)."""
    global _done
    with _lock:
        if _done:
            return 0.0
        t0 = time.perf_counter()
        from kinematics.library import builtin_model
        from planning.collision import CollisionScene, RobotCollisionModel

        from .checker import MotionChecker
        from .search import rrt_connect_compiled, shortcut_compiled

        model = builtin_model("glt_palletizer")
        cm = RobotCollisionModel.from_model(model)
        scene = CollisionScene.from_dicts([
            {"type": "box", "id": "b", "size": [100, 100, 100],
             "pose": [[1, 0, 0, 5000], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}])
        checker = MotionChecker(cm, scene)
        if checker._k is None:
            _done = True
            return 0.0
        a = model.mid_configuration().copy()
        b = a.copy()
        b[0] += 0.3
        checker.free(np.stack([a, b]))
        checker.segment_free(a, b, 0.01)
        checker._exact_free(a)
        checker.clearance(np.stack([a, b]), 0.01)
        rng = np.random.default_rng(0)
        path, _ = rrt_connect_compiled(checker, a, b[None], rng, lambda: False, 0.01)
        if path is not None:
            shortcut_compiled(checker, np.stack([a, 0.5 * (a + b), b]), rng, 0.01)
        # The compiled searches' calls back into Python (the deadline's clock, the exact
        # stage) are readied on their first run, tens of milliseconds: run them now, not
        # in the first plan that looks at its clock or meets a flagged state.
        from ._rrt import _exact_state, _late, _local

        _local.checker, _local.deadline = checker, None
        _late(np.zeros(1, np.int64), np.array([0, 0, 1, 0], np.int64))
        _exact_state(a, np.array([1, 0, 0, 0], np.int64))
        # The exact stage's compiled test of a mesh link against a box or a cylinder.
        from planning.geometry.registry import KERNEL_CODES
        from planning.geometry.triangles import MeshTriangles, triangles_meet_object

        tri = MeshTriangles([np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])])
        eye = np.ascontiguousarray(np.eye(4)[:3])
        for kind in (KERNEL_CODES["box"], KERNEL_CODES["cylinder"]):
            triangles_meet_object(tri.tri, tri.lo, tri.hi, tri.cbox, tri.cstart,
                                  tri.cfirst[0], tri.cfirst[1], eye, eye, np.int64(kind),
                                  np.ones(4))
        _done = True
        return time.perf_counter() - t0


def start_warm_up() -> threading.Thread:
    """``warm_up`` in a background daemon thread."""
    thread = threading.Thread(target=warm_up, name="kinoplan-motion-kernels", daemon=True)
    thread.start()
    return thread
