"""Path planners on paper 000's toy setup: a 100 mm cube, start [1, 1, 1], goal [100, 100, 100],
five spheres (the paper does not print where; ours sit across the diagonal, seeded)."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest

from kinematics.errors import FieldError
from planning.optimisers.ga import GeneticAlgorithm
from planning.optimisers.wolfpack import WolfPack
from planning.optimisers.wolfpack_improved import ImprovedWolfPack, levy_steps
from planning.paths import ALGORITHMS, PathEncoding, path_length, plan_path, shortcut
from planning.paths.auto import certified_shortest_path, plan_auto
from planning.paths.compare import toy_scene
from planning.paths.scene import Scene
from planning.status import PlanStatus

START, GOAL = [1.0, 1.0, 1.0], [100.0, 100.0, 100.0]

#: Light settings so every planner runs in a fraction of a second here (the paper's full
#: settings run in benchmarks/bench_path_planning.py).
LIGHT = {
    "wolfpack": {"n_wolves": 20, "iterations": 8},
    "wolfpack_improved": {"n_wolves": 20, "iterations": 8},
    "ga": {},
    "aca": {"n_ants": 40, "iterations": 15},
    "afsa": {"n_fish": 20, "try_number": 20, "iterations": 15},
    "rrt_star": {"samples": 400},
    "auto": {},
}



def assert_verified(scene: Scene, res) -> None:
    """A success is a clear path from start to goal; a failure returns no path."""
    assert res.success is (res.status is PlanStatus.OK)
    assert res.to_dict()["status"] == res.status.value
    if res.success:
        np.testing.assert_array_equal(res.path[0], START)
        np.testing.assert_array_equal(res.path[-1], GOAL)
        assert scene.path_is_clear(res.path)
        assert res.min_clearance >= scene.safety_margin
        assert res.length == pytest.approx(path_length(res.path))
        assert res.length <= res.raw_length + 1e-9  # shortcutting never lengthens
    else:
        assert res.path.shape == (0, 3) and res.message


def test_toy_scene_blocks_the_straight_line():
    for layout in range(3):
        assert not toy_scene(layout).path_is_clear([START, GOAL])


#: Each planner's outcome on layouts 0 and 1 (margin 0.5 mm, seed = layout, LIGHT settings):
#: every one of them finds a clear path there.
EXPECTED_STATUS = {(algorithm, layout): PlanStatus.OK
                   for algorithm in ALGORITHMS for layout in (0, 1)}
#: The straight line from START to GOAL, 99·sqrt(3) mm: no path is shorter.
STRAIGHT = 99.0 * 3**0.5


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("layout", [0, 1])
def test_every_planner_returns_a_verified_path(algorithm, layout):
    scene = toy_scene(layout, margin=0.5)
    res = plan_path(scene, START, GOAL, algorithm, seed=layout, params=LIGHT[algorithm])
    assert res.algorithm == algorithm
    assert res.status is EXPECTED_STATUS[algorithm, layout], res.message
    assert res.success
    assert_verified(scene, res)
    # The straight line is blocked, so every clear path is longer than it.
    assert STRAIGHT < res.length < 1.2 * STRAIGHT


#: How each planner fails against a wall: the optimisers' best path hits it, the graph and
#: the ants find no way through, RRT* runs out of samples.
WALL_STATUS = {"wolfpack": PlanStatus.COLLISION, "wolfpack_improved": PlanStatus.COLLISION,
               "ga": PlanStatus.COLLISION, "afsa": PlanStatus.COLLISION,
               "aca": PlanStatus.NO_PATH, "auto": PlanStatus.NO_PATH,
               "rrt_star": PlanStatus.BUDGET_SPENT}


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_wall_gives_an_honest_failure(algorithm):
    wall = Scene.create([[0, 0, 0], [100, 100, 100]],
                        [{"type": "box", "lower": [45, -1, -1], "upper": [55, 101, 101]}])
    res = plan_path(wall, START, GOAL, algorithm, seed=0, params=LIGHT[algorithm])
    assert not res.success and res.path.shape == (0, 3)
    assert res.status is WALL_STATUS[algorithm] and res.message
    out = res.to_dict()
    assert out["status"] == WALL_STATUS[algorithm].value and out["success"] is False
    if res.status is PlanStatus.COLLISION:
        assert "obstacles[0]" in res.message  # the obstacle hit is named


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_seeded_runs_are_reproducible(algorithm):
    scene = toy_scene(2)
    a = plan_path(scene, START, GOAL, algorithm, seed=7, params=LIGHT[algorithm])
    b = plan_path(scene, START, GOAL, algorithm, seed=7, params=LIGHT[algorithm])
    np.testing.assert_array_equal(a.path, b.path)
    np.testing.assert_array_equal(a.convergence, b.convergence)
    assert a.evaluations == b.evaluations


@pytest.mark.slow
def test_improved_wolf_pack_beats_the_basic_one():
    """Mean final fitness (penalised length of the best path, what paper 000 plots) over 3
    seeds and 2 layouts, light settings; the 30-seed comparison with Table 2's settings is
    the benchmark's."""
    fitness = {"wolfpack": [], "wolfpack_improved": []}
    for layout in (0, 1):
        scene = toy_scene(layout)
        for algorithm in fitness:
            for seed in range(3):
                res = plan_path(scene, START, GOAL, algorithm, seed, LIGHT[algorithm])
                assert_verified(scene, res)
                fitness[algorithm].append(res.convergence[-1])
    assert np.mean(fitness["wolfpack_improved"]) < np.mean(fitness["wolfpack"])


@pytest.mark.paper
def test_improved_wolf_pack_with_paper_parameters():
    """Table 2's settings (its time goal is benchmarks/bench_speed_goals.py's)."""
    scene = toy_scene(0)
    res = plan_path(scene, START, GOAL, "wolfpack_improved", seed=0)
    assert res.success
    assert len(res.convergence) == ImprovedWolfPack().iterations
    assert np.all(np.diff(res.convergence) <= 0)  # best-so-far never rises


@pytest.mark.slow
@pytest.mark.parametrize("layout", [0, 1])
def test_auto_is_within_one_percent_of_the_certified_shortest_path(layout):
    """Its time goal (under 1 s) is benchmarks/bench_speed_goals.py's."""
    scene = toy_scene(layout, margin=0.5)
    res = plan_path(scene, START, GOAL, "auto", seed=0)
    certified = certified_shortest_path(scene, START, GOAL, samples=400)
    assert certified is not None and scene.path_is_clear(certified)
    assert res.success
    assert res.length <= 1.01 * path_length(certified)


def test_straight_line_when_nothing_is_in_the_way():
    scene = Scene.create([[0, 0, 0], [100, 100, 100]], [{"center": [90, 10, 10], "radius": 5}])
    res = plan_path(scene, START, GOAL, "auto")
    assert res.success and len(res.path) == 2
    assert res.length == pytest.approx(np.sqrt(3) * 99)


def test_penalised_cost_counts_penetration():
    scene = toy_scene(0)
    enc = PathEncoding(scene, np.array(START), np.array(GOAL), 1)
    mid = (np.array(START) + np.array(GOAL)) / 2
    free = plan_path(scene, START, GOAL, "auto").path
    through, around = enc.cost(mid[None])[0], enc.paths_cost(free[None])[0]
    assert through > path_length([START, mid, GOAL]) + 100  # penalised
    assert around == pytest.approx(path_length(free), abs=1e-3)  # clear paths ~pay nothing


def test_shortcut_keeps_the_path_clear_and_never_longer():
    scene = toy_scene(1, margin=0.5)
    res = plan_path(scene, START, GOAL, "rrt_star", seed=3, params={"samples": 600})
    assert res.success
    rng = np.random.default_rng(0)
    again = shortcut(scene, res.path, rng, random_tries=50)
    assert scene.path_is_clear(again) and path_length(again) <= res.length + 1e-9


@pytest.mark.parametrize("change, loc, words", [
    ({"algorithm": "dijkstra"}, ("algorithm",), "algorithm must be one of"),
    ({"start": "inside"}, ("start",), "start is inside obstacles["),
    ({"goal": [0, 0, 101]}, ("goal",), "goal is outside bounds"),
    ({"algorithm": "ga", "params": {"foo": 1}}, ("params", "foo"),
     "params.foo is not a parameter of ga"),
    ({"algorithm": "afsa", "params": {"waypoints": 0}}, ("params", "waypoints"),
     "params.waypoints must be at least 1"),
    ({"algorithm": "ga", "params": {"population": 4, "elite": 4}}, ("params",), "elite"),
    ({"algorithm": "auto", "params": {"samples": 2}}, ("params", "samples"), "samples"),
    ({"algorithm": "rrt_star", "params": {"goal_bias": 2}}, ("params", "goal_bias"),
     "goal_bias"),
])
def test_invalid_requests_name_the_field(change, loc, words):
    scene = toy_scene(0)
    args = {"start": START, "goal": GOAL, "algorithm": "auto"} | change
    if args["start"] == "inside":
        args["start"] = scene.obstacles[2].center
    with pytest.raises(FieldError) as err:
        plan_path(scene, args["start"], args["goal"], args["algorithm"],
                  params=args.get("params"))
    assert err.value.loc == loc and words in err.value.message


def test_parameters_default_to_the_papers():
    assert WolfPack() == WolfPack(n_wolves=100, scout_fraction=0.5, step_factor=100,
                                  max_walks=10, distance_factor=3, update_ratio=3,
                                  directions=20, iterations=50)
    paper = GeneticAlgorithm.paper_000()
    assert (paper.population, paper.crossover, paper.selection, paper.mutation) == \
        (5, 0.8, 0.5, 0.2)
    tuning = GeneticAlgorithm()
    assert (tuning.population, tuning.crossover, tuning.mutation, tuning.iterations) == \
        (50, 0.8, 0.5, 50)


def test_levy_steps_are_heavy_tailed_and_seeded():
    a = levy_steps(np.random.default_rng(1), 100_000)
    b = levy_steps(np.random.default_rng(1), 100_000)
    np.testing.assert_array_equal(a, b)
    gauss = np.random.default_rng(1).normal(size=100_000) * np.std(a[np.abs(a) < 3])
    assert np.mean(np.abs(a) > 10) > 20 * np.mean(np.abs(gauss) > 10)


def test_optimisers_minimise_a_plain_box_problem():
    """The optimisers are generic: on a sphere function each gets close to the minimum."""
    from planning.optimisers.aca import AntColony
    from planning.optimisers.afsa import FishSwarm
    from planning.optimisers.base import Problem

    problem = Problem(lambda X: np.sum((X - 0.3) ** 2, axis=1), np.full(4, -1.0),
                      np.full(4, 1.0))
    for opt in (WolfPack(n_wolves=30, iterations=20), ImprovedWolfPack(n_wolves=30,
                                                                       iterations=20),
                GeneticAlgorithm(), FishSwarm(iterations=30),
                # the paths' alpha = 10 settles too early on a plain grid
                AntColony(iterations=30, alpha=1.0)):
        res = opt.minimize(problem, np.random.default_rng(0))
        assert res.fun < 0.05, type(opt).__name__
        budget = opt.minimize(problem, np.random.default_rng(0), max_evaluations=500)
        assert budget.evaluations == 500


# ---- many obstacles: bounded memory, the fallback ------------------------------------------

TUBE_START, TUBE_GOAL = np.array([40.0, 40.0, 40.0]), np.array([960.0, 960.0, 960.0])


def tube_scene(n: int, seed: int = 11) -> Scene:
    """``n`` spheres (radius 10-30 mm) jittered about a 1 m cube's diagonal: from a few
    hundred on they merge into a tube the path has to go round."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.15, 0.85, n)
    centres = TUBE_START + t[:, None] * (TUBE_GOAL - TUBE_START) + rng.uniform(-30, 30, (n, 3))
    radii = rng.uniform(10, 30, n)
    return Scene.create([[0, 0, 0], [1000, 1000, 1000]],
                        [{"center": c.tolist(), "radius": float(r)}
                         for c, r in zip(centres, radii)], 1.0)


@pytest.mark.slow
def test_many_spheres_plan_in_bounded_memory():
    """300 spheres with a small node budget (the 1,000-sphere case, sized down): the old
    visibility graph over every sample needed memory quadratic in the samples; now every
    array is sized by the caps."""
    scene = tube_scene(300)
    tracemalloc.start()
    try:
        res = plan_path(scene, TUBE_START, TUBE_GOAL, "auto", seed=0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.success, res.message
    assert scene.path_is_clear(res.path) and res.min_clearance >= scene.safety_margin
    np.testing.assert_array_equal(res.path[[0, -1]], [TUBE_START, TUBE_GOAL])
    assert res.extra["method"] == "visibility graph + tightening"
    assert all(r["nodes"] <= 1200 for r in res.extra["rounds"])
    assert peak < 400 * 2**20, f"peak {peak / 2**20:.0f} MiB"
    # Going round the tube costs a little: more than the straight line, well under 1 % more.
    straight = float(np.linalg.norm(TUBE_GOAL - TUBE_START))
    assert straight < res.length < 1.01 * straight


@pytest.mark.slow
def test_many_spheres_are_reproducible():
    scene = tube_scene(120, seed=12)
    a = plan_path(scene, TUBE_START, TUBE_GOAL, "auto", seed=3)
    b = plan_path(scene, TUBE_START, TUBE_GOAL, "auto", seed=3)
    np.testing.assert_array_equal(a.path, b.path)


@pytest.mark.slow
def test_sampling_fallback_when_the_node_budget_is_too_small():
    """16 graph nodes cannot get round the tube: the thinned rounds find nothing, and the
    RRT* fallback gives a verified path."""
    scene = tube_scene(150, seed=13)
    raw = plan_auto(scene, TUBE_START, TUBE_GOAL, np.random.default_rng(0), max_nodes=16,
                    time_limit=None, fallback_samples=1500)
    assert raw.status is PlanStatus.OK
    assert raw.extra["method"] == "rrt_star fallback + tightening"
    assert raw.extra["fallback_reason"] == "thinned graphs found no path"
    assert all(r["length"] is None and r["nodes"] <= 16 for r in raw.extra["rounds"])
    assert math.isinf(raw.extra["rounds"][-1]["bound"])  # every bound was tried
    assert scene.path_is_clear(raw.path)


def test_time_limit_ends_the_graph_and_the_fallback_honestly():
    scene = tube_scene(150, seed=13)
    raw = plan_auto(scene, TUBE_START, TUBE_GOAL, np.random.default_rng(0), time_limit=1e-6)
    assert raw.status is PlanStatus.BUDGET_SPENT and raw.path is None
    assert raw.extra["method"] == "rrt_star fallback"
    assert "the time limit" in raw.extra["message"]


def test_a_complete_graph_without_a_path_is_no_path_without_fallback():
    wall = Scene.create([[0, 0, 0], [100, 100, 100]],
                        [{"type": "box", "lower": [45, -1, -1], "upper": [55, 101, 101]}])
    raw = plan_auto(wall, START, GOAL, np.random.default_rng(0))
    assert raw.status is PlanStatus.NO_PATH and "fallback_nodes" not in raw.extra


@pytest.mark.parametrize("kwargs", [{"max_nodes": 8}, {"time_limit": 0.0}])
def test_bad_budgets_are_refused(kwargs):
    with pytest.raises(ValueError):
        plan_auto(toy_scene(0), START, GOAL, np.random.default_rng(0), **kwargs)
