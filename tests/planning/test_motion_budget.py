"""The compiled simplification's budget: shortcuts too small to pay for their check are not
tried, a lazily checked segment that fails at the resolution is bent around what blocks it
(not shortened again from the start), and the planner answers the simplified path without
checking it a second time, every state of it free at the resolution.

Robots from ``tests/planning/test_motion.py``: the gantry (a 50 mm ball moved in the plane by
two prismatic joints, in mm) and the two-link revolute arm."""

from __future__ import annotations

import numpy as np
import pytest
from test_motion import BALL, box

from planning.collision import CollisionScene, collides
from planning.motion import MotionChecker, plan_motion

pytest.importorskip("fcl")
pytestmark = pytest.mark.usefixtures("motion_kernels")


def _compiled(checker: MotionChecker, exact: bool = True):
    """The compiled module and scratch of ``checker``, the exact stage on (or off)."""
    from planning.motion.search import _compiled as get

    got = get(checker)
    if got is None:
        pytest.skip("no compiled kernels")
    rr, work = got
    work[-1][0] = 1 if exact else 0
    rr._local.checker = checker
    return rr, work


def _grid_states(path: np.ndarray, ns: np.ndarray) -> np.ndarray:
    """Every state ``path[k] + (path[k+1] - path[k]) i / ns[k]``, ``i = 0 .. ns[k]``."""
    return np.concatenate([path[k] + (path[k + 1] - path[k])
                           * (np.arange(ns[k] + 1) / ns[k])[:, None]
                           for k in range(len(path) - 1)])


# ---- least gain -------------------------------------------------------------------------------
def _run_shortcuts(checker: MotionChecker, path: np.ndarray, least_gain: float, res: float):
    rr, work = _compiled(checker)
    n = len(path)
    buf = np.empty((n + 2 * 50 + 4, path.shape[1]))
    buf[:n] = path
    ns = np.zeros(len(buf), dtype=np.int64)
    rr.fill_steps(buf, n, res, work, ns)
    count = work[-2]
    c0 = int(count[0])
    state = np.array([99], dtype=np.uint64)
    n = rr.shortcut_run(checker._robot, checker._scene, buf, n,
                        np.ascontiguousarray(checker.weights), res, checker.margin, 50, 50,
                        state, work, ns, least_gain)
    return buf[:n].copy(), int(count[0]) - c0


def test_a_path_already_short_is_not_shortened_at_any_cost(gantry_cm):
    """A path bent by 10 mm over 900 mm could lose 0.22 mm (0.02 %): with a least gain of
    0.1 % no shortcut is checked (not one state) and the path stays; without one the
    shortcuts check states to win those slivers."""
    scene = CollisionScene.from_dicts([box("far", (50.0, 50.0, 50.0), (0.0, 900.0, 0.0))])
    checker = MotionChecker(gantry_cm, scene)
    path = np.array([[0.0, 0.0], [450.0, 10.0], [900.0, 0.0]])
    assert checker.path_free(path, 0.05)
    same, states = _run_shortcuts(checker, path, 1e-3, 0.05)
    assert states == 0 and np.array_equal(same, path)
    shorter, states = _run_shortcuts(checker, path, 0.0, 0.05)
    assert states > 0
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert np.linalg.norm(np.diff(shorter, axis=0), axis=1).sum() < length - 0.05


def test_a_large_gain_is_still_taken(gantry_cm):
    """A detour 300 mm off the straight line (20 % longer) is cut with the least gain on."""
    scene = CollisionScene.from_dicts([box("far", (50.0, 50.0, 50.0), (0.0, 900.0, 0.0))])
    checker = MotionChecker(gantry_cm, scene)
    path = np.array([[0.0, 0.0], [450.0, 300.0], [900.0, 0.0]])
    out, states = _run_shortcuts(checker, path, 1e-3, 0.05)
    assert states > 0
    before = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert np.linalg.norm(np.diff(out, axis=0), axis=1).sum() < before - 50.0


# ---- a lazily checked segment bent where it fails --------------------------------------------
def _refine(checker: MotionChecker, path: np.ndarray, coarse: float, fine: float,
            most: int = 8):
    """``refine_path`` on ``path`` whose segments were checked at ``coarse`` only."""
    rr, work = _compiled(checker)
    n = len(path)
    buf = np.empty((n + 3 * most + 4, path.shape[1]))
    buf[:n] = path
    ns = np.zeros(len(buf), dtype=np.int64)
    rr.fill_steps(buf, n, coarse, work, ns)
    state = np.array([7], dtype=np.uint64)
    m = rr.refine_path(checker._robot, checker._scene, buf, n,
                       np.ascontiguousarray(checker.weights), fine, checker.margin, work, ns,
                       np.ascontiguousarray(checker.lower, dtype=float),
                       np.ascontiguousarray(checker.upper, dtype=float), state, 20, most)
    return (buf[:m].copy(), ns[:m - 1].copy()) if m > 0 else (None, None)


def test_a_post_missed_between_coarse_states_is_bent_around(gantry_cm):
    """A 20 mm post on the line from x = 0 to 900 mm: the coarse states (180 mm apart)
    clear it by 30 mm, the fine ones (50 mm apart) do not. The segment is bent around the
    post between the two coarse states about it: the ends stay, every state of the grid
    the answer was checked at is free by the collision package, no two of them farther
    apart than the resolution, and the path is longer by a bump, not a new route."""
    scene = CollisionScene.from_dicts([box("post", (20.0, 20.0, 400.0), (450.0, 0.0, 0.0))])
    checker = MotionChecker(gantry_cm, scene)
    a, b = np.array([0.0, 0.0]), np.array([900.0, 0.0])
    assert checker.segment_free(a, b, 2.0) and not checker.segment_free(a, b, 0.5)
    out, ns = _refine(checker, np.stack([a, b]), 2.0, 0.5)
    assert out is not None
    assert np.array_equal(out[0], a) and np.array_equal(out[-1], b) and len(out) > 2
    for k in range(len(out) - 1):
        assert ns[k] >= checker.steps(out[k], out[k + 1], 0.5)
    Q = _grid_states(out, ns)
    assert not collides(gantry_cm, Q, scene, exact=True).any()
    # The post's 20 mm and the ball's radius each side: the bump leaves y = 0 by at least
    # 60 mm near x = 450, within the two coarse states (x = 360 and 540).
    assert np.abs(out[:, 1]).max() >= BALL + 10.0
    assert np.all((np.abs(out[:, 1]) < 1e-9) | ((out[:, 0] > 360.0 - 1e-6)
                                                 & (out[:, 0] < 540.0 + 1e-6)))
    assert np.linalg.norm(np.diff(out, axis=0), axis=1).sum() < 900.0 + 2 * 360.0


def test_a_wall_too_long_to_bend_around_is_refused(gantry_cm):
    """A 2 m wall across the line: no bump about the coarse states clears it, and the
    refinement says so (the shortcuts then start again at the resolution)."""
    scene = CollisionScene.from_dicts([box("wall", (20.0, 2000.0, 400.0), (450.0, 0.0, 0.0))])
    checker = MotionChecker(gantry_cm, scene)
    a, b = np.array([0.0, 0.0]), np.array([900.0, 0.0])
    assert checker.segment_free(a, b, 2.0) and not checker.segment_free(a, b, 0.5)
    out, _ = _refine(checker, np.stack([a, b]), 2.0, 0.5)
    assert out is None


# ---- the planner's answer -------------------------------------------------------------------
def test_the_compiled_answer_is_free_at_the_resolution_without_a_second_check(arm_cm,
                                                                              monkeypatch):
    """Round a post with the arm: the planner answers the compiled simplification's path
    without checking it again (``path_free`` is never called), and every state of it at
    the resolution is free by the collision package."""
    scene = CollisionScene.from_dicts([box("post", (80.0, 80.0, 600.0), (450.0, 250.0, 0.0))])
    checker = MotionChecker(arm_cm, scene)
    if checker._k is None:
        pytest.skip("no compiled kernels")

    def no_second_check(*_a, **_k):
        raise AssertionError("the simplified path was checked again")

    monkeypatch.setattr(MotionChecker, "path_free", no_second_check)
    res = plan_motion(checker, [-1.2, 0.3], [1.5, -0.4], time_limit=2.0, seed=5,
                      trajectory=False)
    assert res.status == "ok", res.message
    assert res.stats["raw_waypoints"] > 2          # simplified (and not checked again)
    assert "simplified_path_rejected" not in res.stats
    P = res.path
    assert np.array_equal(P[0], [-1.2, 0.3]) and np.array_equal(P[-1], [1.5, -0.4])
    ns = [checker.steps(P[k], P[k + 1], res.resolution) for k in range(len(P) - 1)]
    assert not collides(arm_cm, _grid_states(P, np.array(ns)), scene, exact=True).any()
    assert res.length < res.stats["raw_length"] + 1e-9
