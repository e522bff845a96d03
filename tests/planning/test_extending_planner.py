"""The recipe "Adding a planner" followed with a toy planner: RRT-Connect from the sampling core
(``planning.search``) as a ``SamplingPlanner``, tried on a 2-D box, registered in the
``path`` family and run end to end by ``plan_path``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from kinematics.errors import FieldError
from planning.paths import plan_path
from planning.paths.scene import Scene
from planning.registry import FAMILIES, ShortcutParams, knobs, make, register
from planning.search import (
    BoxSpace,
    SamplingPlanner,
    SearchResult,
    iteration_budget,
    rrt_connect,
)
from planning.status import PlanStatus

NAME = "toy_rrt_connect"


@dataclass(frozen=True)
class ToyRRT(SamplingPlanner):
    """RRT-Connect with an iteration budget (the toy of the recipe)."""

    iterations: int = field(default=2000, metadata={"ge": 1, "le": 100_000,
                                                   "description": "iterations"})

    def __post_init__(self) -> None:
        if self.iterations < 1:
            raise FieldError(("params", "iterations"), "params.iterations must be >= 1")

    def search(self, space, start, goal, rng, progress=None) -> SearchResult:
        return rrt_connect(space, start, goal, rng, iteration_budget(self.iterations))


# ---- the space: a 2-D box with a disc in the middle, checked by hand ---------------------
CENTRE, RADIUS = np.array([50.0, 50.0]), 20.0


def segments_miss_disc(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``(k,)`` whether each segment A[i]B[i] stays outside the disc (closest point)."""
    d = B - A
    t = np.clip(np.einsum("ij,ij->i", CENTRE - A, d) / np.maximum(
        np.einsum("ij,ij->i", d, d), 1e-300), 0.0, 1.0)
    closest = A + t[:, None] * d
    return np.linalg.norm(closest - CENTRE, axis=1) > RADIUS


def dense_clear(path: np.ndarray) -> bool:
    """Every point 0.01 apart along ``path`` outside the disc (an independent check)."""
    for a, b in zip(path[:-1], path[1:]):
        s = np.linspace(0.0, 1.0, int(np.ceil(np.linalg.norm(b - a) / 0.01)) + 2)
        if (np.linalg.norm(a + s[:, None] * (b - a) - CENTRE, axis=1) <= RADIUS).any():
            return False
    return True


def test_the_toy_searches_a_2d_box_through_the_core():
    space = BoxSpace([0.0, 0.0], [100.0, 100.0], step=5.0, segments_free=segments_miss_disc)
    start, goal = np.array([5.0, 50.0]), np.array([95.0, 50.0])
    assert not segments_miss_disc(start[None], goal[None])[0]  # the straight line is blocked
    runs = [ToyRRT().search(space, start, goal, np.random.default_rng(s)) for s in (3, 3, 4)]
    res = runs[0]
    assert res.status is PlanStatus.OK and res.success
    np.testing.assert_array_equal(res.path[0], start)
    np.testing.assert_array_equal(res.path[-1], goal)
    assert dense_clear(res.path)
    steps = np.linalg.norm(np.diff(res.path, axis=0), axis=1)
    assert steps.max() <= 5.0 + 1e-9  # no edge longer than the space's step
    np.testing.assert_array_equal(runs[1].path, res.path)  # seeded: the same draws
    assert not np.array_equal(runs[2].path, res.path)
    # Out of iterations before the trees meet: a failed status, no path.
    short = ToyRRT(iterations=1).search(space, start, goal, np.random.default_rng(3))
    assert short.path is None and short.status is PlanStatus.BUDGET_SPENT
    assert short.stats["iterations"] == 1


@pytest.fixture
def registered():
    entry = register("path", NAME, ToyRRT, shared=ShortcutParams,
                     summary="RRT-Connect from the sampling core (a toy)")
    yield entry
    del FAMILIES["path"].algorithms[NAME]


def test_a_registered_planner_is_a_plan_path_algorithm(registered):
    assert [k.name for k in knobs("path", NAME)] == ["iterations", "shortcut",
                                                      "random_shortcuts"]
    with pytest.raises(FieldError) as err:
        make("path", NAME, {"iterations": 0})
    assert err.value.loc == ("params", "iterations")
    scene = Scene.from_dict({"bounds": [[0, 0, 0], [100, 100, 100]], "safety_margin": 1.0,
                             "obstacles": [{"type": "sphere", "center": [50, 50, 50],
                                            "radius": 30}]})
    start, goal = [5.0, 5.0, 5.0], [95.0, 95.0, 95.0]
    res = plan_path(scene, start, goal, NAME, seed=2, params={"iterations": 3000})
    assert res.status is PlanStatus.OK, res.message
    assert res.algorithm == NAME and res.evaluations > 2
    np.testing.assert_allclose(res.path[[0, -1]], [start, goal])
    # Clear of the sphere by its margin, checked here on dense samples.
    pts = np.concatenate([a + np.linspace(0, 1, 200)[:, None] * (b - a)
                          for a, b in zip(res.path[:-1], res.path[1:])])
    assert np.linalg.norm(pts - 50.0, axis=1).min() >= 31.0 - 1e-6
    assert res.length < res.raw_length + 1e-9  # shortened after the search, never longer
    again = plan_path(scene, start, goal, NAME, seed=2, params={"iterations": 3000})
    np.testing.assert_array_equal(again.path, res.path)
    failed = plan_path(scene, start, goal, NAME, seed=2, params={"iterations": 1})
    assert failed.status is PlanStatus.BUDGET_SPENT and not failed.success
    assert failed.path.shape == (0, 3)
    with pytest.raises(FieldError) as err:
        plan_path(scene, start, goal, NAME, params={"steps": 3})
    assert err.value.loc == ("params", "steps")


def test_an_unregistered_planner_is_refused():
    with pytest.raises(FieldError) as err:
        plan_path(Scene.from_dict({"bounds": [[0, 0, 0], [1, 1, 1]]}), [0.1] * 3, [0.9] * 3,
                  NAME)
    assert err.value.loc == ("algorithm",)
