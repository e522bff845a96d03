"""The joint-space planner's simplification and clearance: shortcuts keep only checked
states, and the clearance found through growing bound caps is the exact one.

Robots from ``tests/planning/test_motion.py``: the gantry (a 50 mm ball moved in the plane by
two prismatic joints, so its clearance from a box is known in closed form) and the two-link
revolute arm."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_motion import BALL, box

from planning.collision import CollisionScene, collides
from planning.motion import MotionChecker, plan_motion
from planning.motion.checker import CLEARANCE_CAPS

pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")


# ---- clearance ------------------------------------------------------------------------------
@pytest.mark.parametrize("gap", [3.0, 20.0, 90.0, 300.0, 800.0, 1500.0])
def test_clearance_is_the_exact_distance_below_every_cap_and_beyond(gantry_cm, gap):
    """A box whose near face is ``BALL + gap`` mm from the ball's centre: the clearance is
    ``gap`` (capped at ``reach``, 1000 mm), whichever of the caps it falls under."""
    face = 500.0
    scene = CollisionScene.from_dicts([box("wall", (200.0, 4000.0, 400.0),
                                           (face + 100.0, 0.0, 0.0))])
    checker = MotionChecker(gantry_cm, scene)
    q = np.array([face - BALL - gap, 0.0])     # the ball's centre, mm along x
    got = checker.clearance(q[None])
    assert got == pytest.approx(min(gap, 1000.0), abs=1e-6)
    # Along a path the least one is taken: moving away only adds larger ones.
    away = np.array([q, q - [200.0, 0.0]])
    assert checker.clearance(away) == pytest.approx(min(gap, 1000.0), abs=1e-6)


def test_the_caps_grow_below_the_default_reach():
    assert list(CLEARANCE_CAPS) == sorted(CLEARANCE_CAPS) and CLEARANCE_CAPS[-1] < 1000.0


# ---- shortcuts keep only checked states --------------------------------------------------------
def _grid_states(path: np.ndarray, ns: np.ndarray) -> np.ndarray:
    """Every state ``path[k] + (path[k+1] - path[k]) i / ns[k]``, ``i = 0 .. ns[k]``."""
    out = [path[k] + (path[k + 1] - path[k]) * (np.arange(ns[k] + 1) / ns[k])[:, None]
           for k in range(len(path) - 1)]
    return np.concatenate(out)


def test_shortcuts_keep_pieces_made_of_checked_states(arm_cm):
    """The compiled reduction and shortcuts of a long zig-zag path round a post: every
    segment left has a step count at least its own (no two checked states farther apart than
    the resolution), and every state of that grid is free by the collision package."""
    from planning.motion import _rrt as rr

    scene = CollisionScene.from_dicts([box("post", (80.0, 80.0, 600.0), (450.0, 250.0, 0.0))])
    checker = MotionChecker(arm_cm, scene)
    res = plan_motion(checker, [-1.2, 0.3], [1.5, -0.4], time_limit=2.0, seed=5,
                      simplify=False, trajectory=False)
    raw = res.path
    # A detour through checked, free waypoints: many segments to shorten.
    zig = [raw[0]]
    for a, b in zip(raw[:-1], raw[1:]):
        for t in (0.25, 0.5, 0.75):
            p = a + (b - a) * t + np.array([0.0, 0.15 * math.sin(9 * t)])
            if checker.free(p) and checker.segment_free(zig[-1], p, 0.01):
                zig.append(p)
        if checker.segment_free(zig[-1], b, 0.01):
            zig.append(b)
        else:
            pytest.skip("detour not free")   # never expected with this post
    path = np.array(zig)
    assert checker.path_free(path, 0.01)
    res_ = 0.01
    from planning.motion.search import _compiled

    got = _compiled(checker)
    assert got is not None
    rr_, work = got
    assert rr_ is rr
    buf = np.empty((len(path) + 2 * 200 + 4, 2))
    buf[:len(path)] = path
    n = len(path)
    ns = np.zeros(len(buf), dtype=np.int64)
    w = np.ascontiguousarray(checker.weights)
    work[-1][0] = 0
    rr._local.checker = checker
    rr.fill_steps(buf, n, res_, work, ns)
    n = rr.reduce_path(checker._robot, checker._scene, buf, n, w, res_, checker.margin,
                       work, ns)
    state = np.array([12345], dtype=np.uint64)
    n = rr.shortcut_run(checker._robot, checker._scene, buf, n, w, res_, checker.margin,
                        200, 60, state, work, ns)
    out, steps = buf[:n], ns[:n - 1]
    assert np.allclose(out[0], path[0]) and np.allclose(out[-1], path[-1])
    for k in range(n - 1):
        assert steps[k] >= checker.steps(out[k], out[k + 1], res_)
    Q = _grid_states(out, steps)
    assert not collides(arm_cm, Q, scene, exact=True).any()
    before = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    after = np.linalg.norm(np.diff(out, axis=0), axis=1).sum()
    assert after < before - 0.05                 # the shortcuts did shorten it


# ---- one search, spheres then exact ----------------------------------------------------------
def _lid_scene(gap: float) -> CollisionScene:
    """A box over the arm's upper link (a 30 mm cylinder along x at z = 200 mm when the
    shoulder is at 0), ``gap`` mm above its surface."""
    bottom = 200.0 + 30.0 + gap
    return CollisionScene.from_dicts([box("lid", (120.0, 120.0, 100.0),
                                          (200.0, 0.0, bottom + 50.0))])


def test_a_start_the_spheres_flag_is_left_exactly_and_the_search_goes_on(arm_cm):
    """2 mm under a lid: free, but within the spheres' slack. The plan leaves the start by
    an exactly checked path the search grows on from, and every state of the answer is
    free by the collision package."""
    from planning.motion.search import sphere_free

    scene = _lid_scene(2.0)
    checker = MotionChecker(arm_cm, scene)
    start, goal = np.array([0.0, 0.0]), np.array([2.0, -1.0])
    assert checker.free(start) and not sphere_free(checker, start[None])[0]
    res = plan_motion(checker, start, goal, time_limit=2.0, seed=2, trajectory=False)
    assert res.status == "ok", res.message
    assert res.stats["escaped"] is True
    P = res.path
    assert np.array_equal(P[0], start) and np.array_equal(P[-1], goal)
    Q = np.concatenate([a + (b - a) * np.linspace(0, 1, 200)[:, None]
                        for a, b in zip(P[:-1], P[1:])])
    assert not collides(arm_cm, Q, scene, exact=True).any()


@pytest.mark.parametrize("schedule, exact_chunks", [(False, 0), (True, 1)])
def test_the_search_asks_its_schedule_before_each_chunk(arm_cm, schedule, exact_chunks):
    """``exact`` as a callable: asked before every chunk of iterations, and the chunks it
    answers True for are counted."""
    from planning.motion.search import rrt_connect_compiled

    checker = MotionChecker(arm_cm, _lid_scene(40.0))
    asked = []

    def exact() -> bool:
        asked.append(1)
        return schedule

    path, st = rrt_connect_compiled(checker, np.array([-2.0, 0.5]), np.array([[2.0, -0.5]]),
                                    np.random.default_rng(0), lambda: False, 0.01,
                                    exact=exact)
    assert path is not None and len(asked) == st["iterations"] // 256
    assert (st["exact_chunks"] >= 1) == bool(exact_chunks) and st["exact_chunks"] <= len(asked)


def test_a_head_lets_a_sphere_search_leave_a_flagged_start(arm_cm):
    """On the spheres alone a search cannot leave a start they flag; given an exactly
    checked way out (``head``) it starts there, and the answer begins with that way."""
    from planning.motion.search import escape, rrt_connect_compiled, sphere_free

    checker = MotionChecker(arm_cm, _lid_scene(2.0))
    start = np.array([0.0, 0.0])
    rng = np.random.default_rng(4)
    head = escape(checker, start, rng, lambda: False, 0.01)
    assert head is not None and sphere_free(checker, head[-1:])[0]
    # The spheres flag every shoulder angle that keeps the upper link under the lid: the
    # goal lies on the side the way out leads to.
    goal = np.array([2.0, -1.0]) if head[-1, 0] > 0 else np.array([-2.0, 1.0])
    calls = []

    def stop() -> bool:
        calls.append(1)
        return len(calls) > 40

    alone, _ = rrt_connect_compiled(checker, start, goal[None], rng, stop, 0.01)
    assert alone is None
    calls.clear()
    path, _ = rrt_connect_compiled(checker, start, goal[None], rng, stop, 0.01, head=head)
    assert path is not None
    assert np.array_equal(path[:len(head)], head) and np.array_equal(path[-1], goal)
    assert checker.path_free(path, 0.01)


def test_a_lazy_shortcut_through_a_thin_wall_is_refused(gantry_cm):
    """The shortcuts first check new segments at ``SHORTCUT_LAZY`` times the resolution: a
    20 mm wall that the 50 mm ball passes between two coarse states (200 mm apart) lets the
    straight line through, the check at the resolution (50 mm) finds the wall, and the
    shortcuts run again at the resolution: the answer goes through the gap, every state of
    it 50 mm apart free by the collision package."""
    from planning.motion.search import SHORTCUT_LAZY, shortcut_compiled

    assert SHORTCUT_LAZY * 0.5 * 100.0 >= 200.0       # coarse prismatic steps of 200 mm
    h = 2000.0
    scene = CollisionScene.from_dicts([
        box("upper", (20.0, h, 400), (450.0, 150.0 + h / 2, 0)),
        box("lower", (20.0, h, 400), (450.0, -150.0 - h / 2, 0))])
    checker = MotionChecker(gantry_cm, scene)
    path = np.array([[0.0, 600.0], [450.0, 0.0], [900.0, 600.0]])
    assert checker.path_free(path, 0.5)
    assert checker.segment_free(path[0], path[-1], SHORTCUT_LAZY * 0.5)   # missed coarsely
    assert not checker.segment_free(path[0], path[-1], 0.5)
    out = shortcut_compiled(checker, path, np.random.default_rng(0), 0.5)
    assert np.array_equal(out[0], path[0]) and np.array_equal(out[-1], path[-1])
    assert len(out) >= 3                                  # not the straight line
    Q = np.concatenate([a + (b - a) * (np.arange(n + 1) / n)[:, None]
                        for a, b in zip(out[:-1], out[1:])
                        for n in [max(1, int(np.ceil(np.abs(b - a).max() / 50.0)))]])
    assert not collides(gantry_cm, Q, scene, exact=True).any()


# ---- a search's path checked at its lazy step only ------------------------------------------
def _dense_free(cm, path: np.ndarray, scene: CollisionScene, step_mm: float) -> bool:
    """Every state of ``path`` at most ``step_mm`` apart free by the collision package."""
    Q = np.concatenate([a + (b - a) * (np.arange(n + 1) / n)[:, None]
                        for a, b in zip(path[:-1], path[1:])
                        for n in [max(1, int(np.ceil(np.abs(b - a).max() / step_mm)))]])
    return not collides(cm, Q, scene, exact=True).any()


def _slit_scene() -> CollisionScene:
    h = 2000.0
    return CollisionScene.from_dicts([
        box("upper", (20.0, h, 400), (450.0, 150.0 + h / 2, 0)),
        box("lower", (20.0, h, 400), (450.0, -150.0 - h / 2, 0))])


@pytest.mark.parametrize("lazy", [4, 1])
@pytest.mark.parametrize("seed", range(4))
def test_a_coarsely_checked_path_is_certified_or_refused(gantry_cm, seed, lazy, monkeypatch):
    """A segment checked at 300 mm steps only (``checked``), its coarse states clear of a
    20 mm wall they straddle: the simplification never answers it as it is, whether its
    shortcuts start at a coarser step (``SHORTCUT_LAZY`` 4) or at the resolution (1). It
    answers a path whose every state 50 mm apart is free by the collision package (bent
    through the slit), or None (the caller searches again)."""
    import planning.motion.search as search
    from planning.motion.search import shortcut_compiled

    monkeypatch.setattr(search, "SHORTCUT_LAZY", lazy)

    scene = _slit_scene()
    checker = MotionChecker(gantry_cm, scene)
    path = np.array([[0.0, 600.0], [880.0, 600.0]])
    coarse = 3.0                                          # weighted: 300 mm
    assert checker.segment_free(path[0], path[1], coarse)
    assert not checker.segment_free(path[0], path[1], 0.5)
    out = shortcut_compiled(checker, path, np.random.default_rng(seed), 0.5,
                            checked=np.array([coarse]))
    if out is not None:
        assert np.array_equal(out[0], path[0]) and np.array_equal(out[-1], path[-1])
        assert len(out) > 2
        assert _dense_free(gantry_cm, out, scene, 50.0)


def test_coarse_segments_of_a_path_are_checked_where_the_answer_keeps_them(gantry_cm):
    """A path around the wall's end whose middle segment was checked coarsely and runs
    through the wall: the answer does not keep that segment unchecked (its states 50 mm
    apart are free), while segments checked at the resolution are trusted as they are."""
    from planning.motion.search import shortcut_compiled

    scene = _slit_scene()
    checker = MotionChecker(gantry_cm, scene)
    path = np.array([[0.0, 600.0], [300.0, 600.0], [700.0, 600.0], [880.0, 600.0]])
    checked = np.array([0.5, 4.0, 0.5])                  # the middle one at 400 mm steps
    assert checker.segment_free(path[1], path[2], 4.0)
    out = shortcut_compiled(checker, path, np.random.default_rng(1), 0.5, checked=checked)
    assert out is None or _dense_free(gantry_cm, out, scene, 50.0)


def test_a_refused_lazy_path_is_searched_again_at_the_resolution(gantry_cm, monkeypatch):
    """When the simplification cannot certify the search's lazily checked path, the
    planner searches again, checking each path found at the resolution, and answers a path
    free on dense states (and says so in its statistics)."""
    import planning.motion.planner as planner

    scene = _slit_scene()
    checker = MotionChecker(gantry_cm, scene)
    real = planner.shortcut_compiled
    calls = []

    def refuse_lazy(*args, checked=None, **kw):
        calls.append(checked is not None)
        if checked is not None:
            return None
        return real(*args, checked=checked, **kw)

    monkeypatch.setattr(planner, "shortcut_compiled", refuse_lazy)
    res = plan_motion(checker, [0.0, 600.0], [880.0, 600.0], time_limit=5.0, seed=3,
                      trajectory=False, resolution=0.5)
    assert res.success, res.message
    # Lazily found, refused on the spheres and exactly; then found again, validated.
    assert calls == [True, True, False]
    assert res.stats["lazy_path_rejected"] is True
    assert _dense_free(gantry_cm, np.asarray(res.path), scene, 50.0)


def test_a_lazy_path_the_spheres_refuse_is_certified_exactly_before_a_new_search(
        gantry_cm, monkeypatch):
    """A path found on the spheres alone whose certification on the spheres fails is
    certified again with the exact stage settling what the spheres flag, before any new
    search: one search, the second certification exact."""
    import planning.motion.planner as planner

    scene = _slit_scene()
    checker = MotionChecker(gantry_cm, scene)
    real = planner.shortcut_compiled
    calls = []

    def refuse_on_spheres(*args, exact=False, checked=None, **kw):
        calls.append((exact, checked is not None))
        if checked is not None and not exact:
            return None
        return real(*args, exact=exact, checked=checked, **kw)

    monkeypatch.setattr(planner, "shortcut_compiled", refuse_on_spheres)
    res = plan_motion(checker, [0.0, 600.0], [880.0, 600.0], time_limit=5.0, seed=4,
                      trajectory=False, resolution=0.5)
    assert res.success, res.message
    assert calls == [(False, True), (True, True)]
    assert "lazy_path_rejected" not in res.stats
    assert _dense_free(gantry_cm, np.asarray(res.path), scene, 50.0)


@pytest.mark.parametrize("simplify", [True, False])
def test_only_a_path_to_be_simplified_is_left_unchecked_at_the_resolution(
        gantry_cm, monkeypatch, simplify):
    """``simplify: false`` answers the search's path itself, so the search checks it at the
    resolution when the trees meet; with simplification it does not (the simplification
    certifies what it keeps). Either answer is free on dense states."""
    import planning.motion.planner as planner

    scene = _slit_scene()
    checker = MotionChecker(gantry_cm, scene)
    real = planner.rrt_connect_compiled
    asked = []

    def spy(*args, validate=True, **kw):
        asked.append(validate)
        return real(*args, validate=validate, **kw)

    monkeypatch.setattr(planner, "rrt_connect_compiled", spy)
    res = plan_motion(checker, [0.0, 600.0], [880.0, 600.0], time_limit=5.0, seed=2,
                      trajectory=False, resolution=0.05, simplify=simplify)
    assert res.success, res.message
    assert asked == [not simplify]
    assert _dense_free(gantry_cm, np.asarray(res.path), scene, 5.0)
