"""Bounded work in motion planning: the finest ``resolution`` accepted, the deadline every
segment check looks at, and states sized before they are allocated.

Before these bounds a request with ``resolution`` 1e-12 ran for ten minutes past its 0.5 s
time limit, 1e-308 overflowed, and a job at 1e-12 tried to allocate 46.6 GiB."""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.library import builtin_model
from planning.collision import RobotCollisionModel
from planning.motion import MIN_RESOLUTION, MotionChecker, MotionStatus, plan_motion
from planning.motion.checker import segment_states
from planning.motion.planner import FINISH_S, SIMPLIFY_MIN_S, _trajectory_free

pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")

# The palletizer's swing of the attack that ran for ten minutes (at 1e-12).
START = np.array([-1.0, 0.3, -0.3, 0.0, 0.5, 0.0])
GOAL = np.array([1.0, 0.3, -0.3, 0.0, 0.5, 0.0])


@pytest.fixture(scope="module")
def glt():
    return RobotCollisionModel.from_model(builtin_model("glt_palletizer"))


@pytest.mark.parametrize("resolution", [MIN_RESOLUTION * 0.99, 1e-12, 1e-308, 5e-324])
def test_a_resolution_finer_than_the_floor_is_refused(glt, resolution):
    with pytest.raises(FieldError) as err:
        plan_motion(MotionChecker(glt), START, GOAL, resolution=resolution)
    assert tuple(err.value.loc) == ("resolution",)


def test_the_floor_itself_plans(glt):
    res = plan_motion(MotionChecker(glt), START, GOAL, resolution=MIN_RESOLUTION,
                      time_limit=5.0, seed=2)
    assert res.status is MotionStatus.OK and res.resolution == MIN_RESOLUTION


@pytest.mark.parametrize("jit", [True, False], ids=["compiled", "python"])
def test_a_plan_at_the_finest_resolution_keeps_its_time_limit(glt, jit):
    """At 1e-4 rad one segment of this swing is 20,000 states; the search used to check the
    whole path it found (0.15 s alone) before looking at its 0.02 s limit."""
    mc = MotionChecker(glt)
    if not jit:
        mc._k = None
    limit = 0.02
    # The time limit is the contract here (not a speed goal): a wall clock measures it.
    t0 = time.monotonic()
    res = plan_motion(mc, START, GOAL, resolution=MIN_RESOLUTION, time_limit=limit, seed=1)
    wall = time.monotonic() - t0
    # A check looks at the clock every few milliseconds of work (margins for a loaded
    # machine: the search alone took 0.15 s here before).
    assert res.planning_time_s <= limit + 0.1 or res.status is MotionStatus.OK and \
        res.planning_time_s - res.simplify_time_s <= limit + 0.1
    assert wall <= limit + SIMPLIFY_MIN_S + FINISH_S + 1.0
    assert mc.deadline is None   # cleared for the verification helpers
    if res.status is MotionStatus.OK:
        assert mc.path_free(res.path, MIN_RESOLUTION)


@pytest.mark.parametrize("jit", [True, False], ids=["compiled", "python"])
def test_a_segment_check_past_its_deadline_says_not_free(glt, jit):
    mc = MotionChecker(glt)
    if not jit:
        mc._k = None
    assert mc.segment_free(START, GOAL, MIN_RESOLUTION)
    mc.deadline = 0.0   # long past on the checker's clock
    checks = mc.checks
    assert not mc.segment_free(START, GOAL, MIN_RESOLUTION)
    # One chunk of states at most, not the segment's 20,000.
    assert mc.checks - checks <= 4096
    mc.deadline = None
    assert mc.segment_free(START, GOAL, MIN_RESOLUTION)


def test_the_compiled_shortcut_past_its_deadline_keeps_the_path(glt):
    from planning.motion.search import shortcut_compiled

    mc = MotionChecker(glt)
    if mc._k is None:
        pytest.skip("no compiled kernels")
    path = np.array([START, [0.0, 0.3, -0.3, 0.0, 0.9, 0.0], [0.5, 0.3, -0.3, 0.0, 0.5, 0.0],
                     GOAL])
    assert mc.path_free(path, MIN_RESOLUTION)
    mc.deadline = 0.0
    out = shortcut_compiled(mc, path, np.random.default_rng(0), MIN_RESOLUTION)
    mc.deadline = None
    assert np.array_equal(out, path)
    assert len(shortcut_compiled(mc, path, np.random.default_rng(0), MIN_RESOLUTION)) < 4


def test_segment_states_match_the_whole_list_without_building_it():
    rng = np.random.default_rng(11)
    for _ in range(100):
        k = int(rng.integers(2, 7))
        P = rng.normal(size=(k, 3))
        steps = rng.integers(1, 40, size=k - 1)
        most = int(rng.integers(1, 120))
        whole = [P[:1]] + [P[i] + (P[i + 1] - P[i]) * (np.arange(1, n + 1) / n)[:, None]
                           for i, n in enumerate(steps)]
        Q = np.concatenate(whole)
        if len(Q) > most:
            Q = Q[np.unique(np.linspace(0, len(Q) - 1, most).round().astype(int))]
        assert np.array_equal(segment_states(P, steps, most), Q)


def test_clearance_over_a_long_fine_path_stays_small_in_memory(glt):
    """120 swings at 1e-4 rad are 24 million states (1.2 GB as one array): only the 100
    the clearance looks at are built."""
    mc = MotionChecker(glt)
    path = np.array([START if i % 2 == 0 else GOAL for i in range(121)])
    tracemalloc.start()
    try:
        d = mc.clearance(path, MIN_RESOLUTION)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert d is not None and d > 0
    assert peak < 20e6


def test_the_trajectory_check_is_sized_before_it_is_allocated(glt):
    """At 1e-12 rad the blend check asked for 3.6e12 states (a MemoryError of tens of GB);
    it now stops at its cap whatever it is asked."""
    from planning.trajectories.joint_path import smooth_polyline
    from planning.trajectories.topp import time_optimal
    from planning.trajectories.trajectory import Limits

    model = builtin_model("glt_palletizer")
    path = np.array([START, [0.0, 0.3, -0.3, 0.0, 0.9, 0.0], GOAL])
    traj = time_optimal(smooth_polyline(path, 0.05),
                        Limits(velocity=np.asarray(model.velocity_limits),
                               acceleration=np.full(6, 2.0))).trajectory
    mc = MotionChecker(glt)
    tracemalloc.start()
    try:
        free = _trajectory_free(mc, traj, 1e-12)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert free
    assert peak < 200e6


_NO_COMPILE_AFTER_WARM_UP = """
from numba.core import event
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel
from planning.motion import MotionChecker, plan_motion, warm_up

warm_up()


class Count(event.Listener):
    def __init__(self):
        self.names = []

    def on_start(self, ev):
        self.names.append(str(ev.data.get("dispatcher", "")))

    def on_end(self, ev):
        pass


model = builtin_model("glt_palletizer")
cm = RobotCollisionModel.from_model(model)
wall = {"type": "box", "id": "w", "size": [200, 2000, 1500],
        "pose": [[1, 0, 0, 1500], [0, 1, 0, 0], [0, 0, 1, 750], [0, 0, 0, 1]]}
checker = MotionChecker(cm, CollisionScene.from_dicts([wall]))
seen = Count()
with event.install_listener("numba:compile", seen):
    for _ in range(2):   # the second's checks pass the clock's first look (every 1,024)
        plan_motion(checker, [-1, 0.3, -0.3, 0, 0.5, 0], [1, 0.3, -0.3, 0, 0.5, 0],
                    time_limit=5.0, trajectory=False)
    # The exact stage's mesh test, called as MotionChecker._exact_free calls it.
    import numpy as np
    from planning.geometry.triangles import MeshTriangles, triangles_meet_object
    tri = MeshTriangles([np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]), None])
    M = np.zeros((2, 3, 4))
    M[:, :, :3] = np.eye(3)
    T_inv, kind, par = M[:1].copy(), np.array([1], dtype=np.int64), np.ones((1, 4))
    a, c = 0, 0
    grown = par[c].copy()
    ready = len(triangles_meet_object.signatures)   # loaded from the cache or compiled
    triangles_meet_object(tri.tri, tri.lo, tri.hi, tri.cbox, tri.cstart, tri.cfirst[a],
                          tri.cfirst[a + 1], M[a], T_inv[c], kind[c], grown)
    if ready == 0 or len(triangles_meet_object.signatures) != ready:
        seen.names.append("triangles_meet_object not readied by the warm-up")
print("COMPILED", len(seen.names), seen.names)
"""


@pytest.mark.slow
def test_after_the_warm_up_a_plan_compiles_nothing():
    """In a fresh process, once ``warm_up`` has run, plans whose compiled checks look at the
    clock compile nothing more (numba's compile events): the searches' calls back into
    Python are readied by the warm-up, not by the first plan that reaches them; so is the
    exact stage's compiled mesh test, for the argument types the checker passes it."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, "-c", _NO_COMPILE_AFTER_WARM_UP], cwd=root,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    line = next(s for s in done.stdout.splitlines() if s.startswith("COMPILED"))
    assert line.startswith("COMPILED 0 "), line


def test_read_only_configurations_compile_nothing_new():
    """A read-only array (a planner's answered path, a model's frozen limits) is copied
    before the kernels see it: numba would compile every kernel anew for it (tens of
    seconds on a cold cache), so the dispatchers gain no signature."""
    import planning.motion._kernels as kernels
    import planning.motion._rrt as rr
    from kinematics.library import builtin_model
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion import MotionChecker, warm_up

    warm_up()
    model = builtin_model("glt_palletizer")
    checker = MotionChecker(RobotCollisionModel.from_model(model), CollisionScene.from_dicts(
        [{"type": "box", "id": "b", "size": [100, 100, 100],
          "pose": [[1, 0, 0, 5000], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]))
    a = model.mid_configuration().copy()
    b = a.copy()
    b[0] += 0.3
    Q = np.stack([a, b])
    Q.setflags(write=False)
    before = (len(kernels.check_states.signatures), len(rr._segment_free.signatures),
              len(kernels.state_hits.signatures))
    checker.free(Q)
    checker.segment_free(Q[0], Q[1], 0.01)
    checker._exact_free(Q[0])
    after = (len(kernels.check_states.signatures), len(rr._segment_free.signatures),
             len(kernels.state_hits.signatures))
    assert after == before
