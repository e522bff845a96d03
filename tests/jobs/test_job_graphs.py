"""Jobs whose work divides (``JobKind.graph``): their steps run in any valid order, each as a
separate worker would run it (the params rebuilt from the job's payload, every argument and
value through a pickle round trip), give the result ``run`` gives in one process; and the
workspace's parts (``kinematics.workspace``) give the figures of sampling every point at
once, within memory bounded by the part size.

Fields that measure time (``runtime_s``, ``planning_time_s`` ...) differ between any two
runs and are left out of the comparisons."""

from __future__ import annotations

import json
import math
import pickle
import random
import tracemalloc

import numpy as np
import pytest

import kinematics.workspace as W
from app.jobs import drilling_kinds, motion_kinds
from app.jobs.catalog import KINDS
from app.jobs.graph import refs_of, resolve
from app.jobs.kinds import JobPayload, load_job
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.model import RobotModel

#: Result fields that measure time, left out of the comparisons.
TIMING = {"runtime_s", "mean_time_s", "planning_time_s", "simplify_time_s",
          "median_planning_time_s"}


def _timeless(value):
    if isinstance(value, dict):
        return {k: _timeless(v) for k, v in value.items() if k not in TIMING}
    if isinstance(value, list):
        return [_timeless(v) for v in value]
    return value


def _payload(name: str, params: dict, model: RobotModel | None = None) -> dict:
    kind = KINDS[name]
    checked = kind.load_params(params)
    if model is None and kind.needs_robot:
        model = builtin_model(checked.robot)
    return JobPayload(params=checked.model_dump(mode="json"),
                      robot_model=None if model is None else model.to_dict()
                      ).model_dump(mode="json")


def _round_trip(value):
    return pickle.loads(pickle.dumps(value))


def spread(name: str, params: dict, seed: int = 0, model: RobotModel | None = None) -> dict:
    """The job's result with its steps run one by one in a random valid order, each as a
    separate worker runs it."""
    payload = _payload(name, params, model)
    kind, first = load_job(name, payload)
    steps = _round_trip(kind.steps(first))  # functions travel by reference
    deps = [refs_of(s) for s in steps]
    rng, values, done = random.Random(seed), {}, set()
    while len(done) < len(steps):
        ready = [i for i in range(len(steps)) if i not in done and deps[i] <= done]
        i = rng.choice(ready)
        _, params_i = load_job(name, _round_trip(payload))
        args = resolve(steps[i].args, lambda j: _round_trip(values[j]))
        values[i] = _round_trip(steps[i].fn(params_i, *args, lambda f, m: None))
        done.add(i)
    return json.loads(kind.result_json(values[len(steps) - 1]))


def inline(name: str, params: dict, model: RobotModel | None = None) -> dict:
    """The job's result as ``run`` gives it in one process (a worker's ``execute``)."""
    kind, p = load_job(name, _payload(name, params, model))
    seen: list[float] = []
    out = json.loads(kind.result_json(kind.run(p, lambda f, m: seen.append(f))))
    assert seen and all(0.0 <= f <= 1.0 + 1e-12 for f in seen)
    assert seen == sorted(seen)
    return out


def step_count(name: str, params: dict) -> int:
    kind = KINDS[name]
    return len(kind.steps(kind.load_params(params)))


# ---- workspace ---------------------------------------------------------------------------
@pytest.fixture
def small_parts(monkeypatch):
    """Parts of 1,500 samples in FK batches of 500."""
    monkeypatch.setattr(W, "CHUNK", 500)
    monkeypatch.setattr(W, "PART", 1500)


def planar_arm(a1: float = 1000.0, a2: float = 600.0) -> RobotModel:
    """Two revolute joints about z (links a1, a2 mm, ±180 deg), base at (100, 200, 300)."""
    base = np.eye(4)
    base[:3, 3] = (100.0, 200.0, 300.0)
    home = np.eye(4)
    home[0, 3] = a1 + a2
    return RobotModel.from_dict({
        "id": "planar", "name": "planar", "convention": "poe", "base": base.tolist(),
        "home": home.tolist(),
        "joints": [{"name": "j1", "type": "revolute", "axis": [0, 0, 1], "point": [0, 0, 0],
                    "lower": -math.pi, "upper": math.pi},
                   {"name": "j2", "type": "revolute", "axis": [0, 0, 1], "point": [a1, 0, 0],
                    "lower": -math.pi, "upper": math.pi}]})


def reference_workspace(model: RobotModel, n: int, seed: int, k: int) -> dict:
    """The figures of every point held at once: one generator, FK in batches of CHUNK,
    voxels as unique rows, numpy's histograms."""
    rng = np.random.default_rng(seed)
    P = np.concatenate([
        fk(model, rng.uniform(model.lower, model.upper, (min(W.CHUNK, n - s), model.dof)))
        [:, :3, 3] for s in range(0, n, W.CHUNK)])
    lo, hi = P.min(axis=0), P.max(axis=0)
    T = np.linalg.inv(model.base)
    local = P @ T[:3, :3].T + T[:3, 3]
    r = np.hypot(local[:, 0], local[:, 1])
    voxel = max(float(np.max(hi - lo)) / 30, 1e-6)
    cells = np.floor((P - lo) / voxel).astype(np.int64)
    idx = np.sort(np.random.default_rng(seed).choice(n, size=k, replace=False))
    out = {"min": lo.tolist(), "max": hi.tolist(), "radial": [r.min(), r.max()],
           "vertical": [local[:, 2].min(), local[:, 2].max()], "voxel": voxel,
           "volume": len(np.unique(cells, axis=0)) * voxel**3, "points": P[idx].tolist(),
           "projections": {}}
    for name, (i, j) in {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}.items():
        H, ei, ej = np.histogram2d(P[:, i], P[:, j], bins=64, range=[
            [lo[i], max(hi[i], lo[i] + 1e-9)], [lo[j], max(hi[j], lo[j] + 1e-9)]])
        out["projections"][name] = {"counts": H.astype(np.int64).tolist(),
                                    "first_edges": ei.tolist(), "second_edges": ej.tolist()}
    return out


WS = {"robot": "pile_driver", "samples": 4321, "seed": 5, "return_points": 700}


@pytest.mark.slow
@pytest.mark.parametrize("change", [{}, {"projections": False, "return_points": 0},
                                    {"samples": 4500, "voxel": 250.0, "return_points": 4500},
                                    {"robot": "hyper_redundant_9dof", "seed": 11}])
def test_workspace_parts_spread_give_the_library_answer(small_parts, change):
    params = {**WS, **change}
    assert step_count("workspace", params) == 2 * math.ceil(params["samples"] / 1500) + 2
    got = spread("workspace", params, seed=len(change))
    assert got == inline("workspace", params)
    model = builtin_model(params["robot"])
    ws = W.sample_workspace(model, params["samples"], seed=params["seed"],
                            voxel=params.get("voxel"), return_points=params["return_points"],
                            projections=params.get("projections", True))
    report = W.workspace_report(ws, params["return_points"], params.get("projections", True))
    assert got == {"robot": params["robot"], **report}


def test_workspace_figures_do_not_depend_on_the_part_size(small_parts, monkeypatch):
    three = inline("workspace", WS)
    monkeypatch.setattr(W, "PART", 500)
    assert step_count("workspace", WS) == 2 * 9 + 2
    assert spread("workspace", WS, seed=3) == three
    monkeypatch.setattr(W, "PART", 5000)
    assert step_count("workspace", WS) == 1
    assert inline("workspace", WS) == three


def test_workspace_parts_give_the_figures_of_all_points_at_once(small_parts):
    model = builtin_model("glt_palletizer")
    params = {**WS, "robot": "glt_palletizer"}
    got = spread("workspace", params)
    ref = reference_workspace(model, WS["samples"], WS["seed"], WS["return_points"])
    for key in ("min", "max", "voxel", "volume", "points", "projections"):
        assert got[key] == ref[key], key
    for key in ("radial", "vertical"):
        assert got[key] == pytest.approx(ref[key], rel=1e-12, abs=1e-9)
    assert got["samples"] == WS["samples"] and got["seed"] == WS["seed"]
    for image in got["projections"].values():
        assert sum(map(sum, image["counts"])) == WS["samples"]


def test_workspace_of_a_planar_arm_is_its_annulus(monkeypatch):
    """Two links of 1000 and 600 mm, full turns: the tool sweeps the annulus between 400
    and 1600 mm around the base, at the base's height."""
    monkeypatch.setattr(W, "CHUNK", 5000)
    monkeypatch.setattr(W, "PART", 15000)
    model = planar_arm()
    n = 64_001
    params = {"robot": "planar", "samples": n, "seed": 2, "return_points": 50}
    assert step_count("workspace", params) == 2 * 5 + 2
    got = spread("workspace", params, model=model)
    assert got == inline("workspace", params, model=model)
    assert 1599.0 < got["radial"][1] <= 1600.0 + 1e-9
    assert 400.0 - 1e-9 <= got["radial"][0] < 401.0
    assert got["vertical"] == pytest.approx([0.0, 0.0], abs=1e-9)
    np.testing.assert_allclose(got["min"], [100 - 1600, 200 - 1600, 300], atol=1.0)
    np.testing.assert_allclose(got["max"], [100 + 1600, 200 + 1600, 300], atol=1.0)
    assert got["voxel"] == max(hi - lo for lo, hi in zip(got["min"], got["max"])) / 30
    area = math.pi * (1600.0**2 - 400.0**2)
    assert 0.9 * area * got["voxel"] < got["volume"] < 1.4 * area * got["voxel"]
    assert sum(map(sum, got["projections"]["xy"]["counts"])) == n
    P = np.asarray(got["points"])
    r = np.hypot(P[:, 0] - 100, P[:, 1] - 200)
    assert len(P) == 50 and np.all((r > 400 - 1e-6) & (r < 1600 + 1e-6))


@pytest.mark.slow
def test_workspace_memory_is_bounded_by_the_part(monkeypatch):
    """600,000 samples in parts of 50,000: the job never holds its samples' points (14.4 MB;
    a part's take some 2 MB to compute, and each part's voxels and images some 0.15 MB to
    keep); keeping every point (return_points=None) does."""
    monkeypatch.setattr(W, "CHUNK", 5000)
    monkeypatch.setattr(W, "PART", 50_000)
    n = 600_000
    model = builtin_model("pile_driver")
    kind = KINDS["workspace"]
    params = kind.load_params({"robot": "pile_driver", "samples": n, "return_points": 100})
    W.sample_workspace(model, 3000)  # imports and caches outside the measurement

    def peak(fn) -> int:
        tracemalloc.start()
        try:
            fn()
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    job = peak(lambda: kind.run(params, lambda f, m: None))
    everything = peak(lambda: W.sample_workspace(model, n, return_points=None))
    assert job < n * 24 / 3
    assert everything > n * 24


# ---- tracking ----------------------------------------------------------------------------
TRACKING = {"task": {"kind": "line", "length": 100.0, "duration": 2.0}, "tune": "pso",
            "iterations": 2, "runs": 3, "seed": 9, "dt": 0.1}


def test_tracking_runs_spread_give_the_inline_answer():
    assert step_count("tracking", TRACKING) == 4
    assert step_count("tracking", {**TRACKING, "runs": 1}) == 1
    got = spread("tracking", TRACKING, seed=1)
    assert got == inline("tracking", TRACKING)
    # each run is the tuner's own answer for its seed
    from planning.tracking import TrackingConfig, tune_gains

    model = builtin_model(got["robot"])
    kind = KINDS["tracking"]
    p = kind.load_params(TRACKING)
    for r, run in enumerate(got["runs"]):
        tuned = tune_gains(model, p.task.to_task(), "pso", TRACKING["seed"] + r,
                           controller="default", config=TrackingConfig(dt=0.1),
                           bounds=p.bounds.to_bounds(), iterations=2)
        assert run["seed"] == TRACKING["seed"] + r
        assert run["kp"] == list(tuned.gains.kp) and run["ki"] == tuned.gains.ki
    assert min(r["mean_error"] for r in got["runs"]) == got["mean_error"]


# ---- path_compare ------------------------------------------------------------------------
def _compare_params(runs: int) -> dict:
    from planning.paths.compare import TOY_GOAL, TOY_START

    return {"scene": {"bounds": [[0, 0, 0], [100, 100, 100]],
                      "obstacles": [{"center": [50, 50, 50], "radius": 15.0},
                                    {"center": [30, 25, 30], "radius": 10.0}]},
            "start": list(TOY_START), "goal": list(TOY_GOAL), "seed": 4, "runs": runs,
            "algorithms": ["ga", "aca"],
            "params": {"ga": {"iterations": 5}, "aca": {"iterations": 3}}}


@pytest.mark.slow
def test_path_compare_parts_spread_give_the_rows_of_compare_planners():
    from app.jobs.path_kinds import compare_part_runs
    from planning.paths.compare import compare_planners

    params = _compare_params(runs=13)
    per = [compare_part_runs(a) for a in params["algorithms"]]
    assert step_count("path_compare", params) == sum(math.ceil(13 / k) for k in per) + 1
    got = spread("path_compare", params, seed=2)
    assert _timeless(got) == _timeless(inline("path_compare", params))
    p = KINDS["path_compare"].load_params(params)
    rows = compare_planners(p.scene.to_scene(), p.start, p.goal, p.algorithms, p.runs, p.seed,
                            p.params)
    assert _timeless(got["rows"]) == _timeless([r.to_dict() for r in rows])
    assert [r["runs"] for r in got["rows"]] == [13, 13]
    assert step_count("path_compare", {**params, "runs": 2, "algorithms": ["ga"],
                                       "params": None}) == 1


# ---- motion ------------------------------------------------------------------------------
def _motion_params(n: int) -> dict:
    robot = "glt_palletizer"
    model = builtin_model(robot)
    middle = np.array([0.0, 0.3, -0.3, 0.0, 0.5, 0.0])
    pose = np.eye(4)
    pose[:3, 3] = fk(model, middle)[:3, 3]
    ball = {"type": "sphere", "id": "ball", "radius": 150.0, "pose": pose.tolist()}
    rng = np.random.default_rng(3)
    problems = []
    for i in range(n):
        a, b = rng.uniform(0.6, 1.4, 2)
        q0 = [-a, 0.3, -0.3, 0.0, 0.5, 0.0]
        q1 = [b, 0.3, -0.3, 0.0, 0.5, 0.0]
        problems.append({"start": q0, "goal": {"q": q1}, "seed": 100 + i})
    return {"robot": robot, "scene": {"objects": [ball]}, "time_limit": 5.0,
            "problems": problems}


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_motion_batch_parts_spread_give_the_one_checker_answer():
    """Problems planned in parts, a checker each, answer as one checker planning them all
    in turn (``motion_whole``, the whole batch in one step): a plan depends on its seed."""
    n = motion_kinds.MOTION_PART_PROBLEMS + 3
    params = _motion_params(n)
    assert step_count("motion", params) == 3
    assert step_count("motion", _motion_params(motion_kinds.MOTION_PART_PROBLEMS)) == 1
    got = spread("motion", params, seed=5)
    assert _timeless(got) == _timeless(inline("motion", params))
    kind, p = load_job("motion", _payload("motion", params))
    whole = json.loads(kind.result_json(motion_kinds.motion_whole(p, lambda f, m: None)))
    assert _timeless(got) == _timeless(whole)
    assert got["summary"]["total"] == n and got["summary"]["solved"] == n


# ---- sequence ----------------------------------------------------------------------------
def _holes(n: int, seed: int) -> list:
    H = np.random.default_rng(seed).uniform(0, 6000, (n, 3))
    H[:, 0] = 9000.0
    return H.tolist()


@pytest.mark.parametrize("n, knobs, stopped", [
    (150, {"kicks": 3000, "stall": 300}, "kicks"),
    (90, {"kicks": 1500, "stall": 100, "restarts": 4}, "runs")])
def test_sequence_runs_spread_give_the_answer_of_one_search(n, knobs, stopped):
    """Stopped by its kick budget or its runs (a time limit that does not bind), the runs
    computed apart make the order, length and history of the search run in one process."""
    from planning.sequencing import sequence_holes

    params = {"holes": _holes(n, n), "seed": 6,
              "params": {**knobs, "time_limit": 3600.0}}
    auto = drilling_kinds._auto_search(KINDS["sequence"].load_params(params))[0]
    assert step_count("sequence", params) == auto.max_runs(n) + 1 > 2
    got = spread("sequence", params, seed=n)
    assert _timeless(got) == _timeless(inline("sequence", params))
    one = sequence_holes(params["holes"], None, "auto", 6, params["params"])
    assert one.extra["stopped"] == stopped
    assert got["order"] == one.order.tolist() and got["length"] == one.length
    assert got["convergence"] == one.history.tolist()
    assert (got["evaluations"], got["iterations"], got["message"]) == (
        one.evaluations, one.iterations, one.message)


def test_sequence_jobs_that_do_not_divide_are_one_step():
    holes = _holes(40, 1)
    assert step_count("sequence", {"holes": holes[:10]}) == 1  # solved exactly
    assert step_count("sequence", {"holes": holes, "algorithm": "iga"}) == 1
    assert step_count("sequence", {"holes": holes, "params": {"restarts": 1}}) == 1


def test_auto_combine_runs_again_what_it_lacks_or_cannot_use(fake_clock):
    """``combine`` makes the one-process answer of any prefix of the runs (it runs the
    missing ones itself), re-running the run whose kicks the budget cuts short; a run
    stopped by its own time limit ends the search there."""
    from planning.sequencing import Auto, SequencingProblem

    p = SequencingProblem.from_holes(_holes(150, 150), None)
    auto = Auto(kicks=3000, stall=300, time_limit=3600.0)
    one = auto.solve(p, np.random.default_rng(6))
    runs = [auto.search_run(p, 6, r) for r in range(auto.max_runs(p.n))]
    used = one.extra["runs"]
    assert sum(r.kicks for r in runs[:used]) > 3000  # the last run used is cut short
    # later runs with the kicks the first four leave them (None: the search ends before)
    caps = [auto.run_cap(p.n, r, runs[:4]) for r in range(4, len(runs))]
    assert caps[: used - 4] and None not in caps[: used - 4] and caps[-1] is None
    assert caps == sorted(caps, key=lambda c: -1 if c is None else -c)
    waves = runs[:4] + [None if c is None else auto.search_run(p, 6, r, c)
                        for r, c in enumerate(caps, start=4)]
    for given in (runs, waves, runs[:2], []):
        got = auto.combine(p, given, 6)
        assert np.array_equal(got.order, one.order) and got.length == one.length
        assert np.array_equal(got.history, one.history)
        assert (got.evaluations, got.message) == (one.evaluations, one.message)
    slow = Auto(kicks=3000, stall=300, time_limit=3.0)
    timed = [slow.search_run(p, 6, 0, clock=fake_clock(1.0))] + runs[1:]
    assert timed[0].stop == "time limit" and timed[0].kicks < 3000
    got = slow.combine(p, timed, 6)
    assert got.extra["stopped"] == "time limit" and got.extra["runs"] == 1
    assert got.extra["kicks"] == timed[0].kicks
    assert sorted(got.order.tolist()) == list(range(150))
