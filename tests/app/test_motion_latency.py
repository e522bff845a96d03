"""What is kept between synchronous motion requests (``app.collision_models``): in a compute
worker, collision models and scenes by token (a stored scene's version, an inline scene's
content), sent only until the worker keeps them (``run_kept``), and the planner's prepared
checker per model, scene and settings (``worker_prepared``), lent to one request at a time,
bounded, and never reused across a change of the scene or the model; in the API process,
the collision model found for a robot and the inline scenes built lately. Speed is the
benchmark's business (``benchmarks/bench_motion_http.py``); these tests hold the behaviour.

The worker's caches are module globals; each test gets empty ones (``fresh_caches``).
"""

from __future__ import annotations

import asyncio
import json
import pickle
from collections import OrderedDict
from dataclasses import replace

import numpy as np
import pytest
from fastapi.testclient import TestClient

import app.collision_models as cmod
from app.api.routes import motion as motion_route
from app.collision_models import Kept, Lacking, run_kept, worker_cached, worker_prepared
from app.config import Settings
from app.main import create_app
from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel
from planning.motion.request import robot_problem

ROBOT = "glt_palletizer"
START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
MIDDLE = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]


@pytest.fixture(autouse=True)
def fresh_caches(monkeypatch):
    """Empty worker caches for this test (the test process plays the worker)."""
    monkeypatch.setattr(cmod, "_WORKER_CACHE", OrderedDict())
    monkeypatch.setattr(cmod, "_WORKER_PREPARED", OrderedDict())
    monkeypatch.setattr(cmod, "_INLINE_SCENES", OrderedDict())


def _ball_at(q: list[float], name: str, radius: float = 150.0) -> dict:
    pose = np.eye(4)
    pose[:3, 3] = fk(builtin_model(ROBOT), np.array(q))[:3, 3]
    return {"type": "sphere", "id": name, "radius": radius, "pose": pose.tolist()}


# ---- worker_prepared ---------------------------------------------------------------------
class _Built:
    """A stand-in for a checker: counts its builds, records resets."""

    made = 0

    def __init__(self) -> None:
        _Built.made += 1
        self.serial = _Built.made
        self.dirty = False
        self.resets = 0


def _reset(obj: _Built) -> None:
    obj.dirty = False
    obj.resets += 1


def _use(key, build=_Built) -> _Built:
    with worker_prepared(key, build, _reset) as obj:
        obj.dirty = True
        return obj


def test_a_prepared_object_is_built_once_per_key_and_reset_before_reuse():
    first = _use(("m", "s1"))
    again = _use(("m", "s1"))
    assert again is first
    assert first.resets == 2 and not first.dirty
    other = _use(("m", "s2"))
    assert other is not first


def test_without_a_key_every_request_builds_its_own_and_nothing_is_kept():
    a, b = _use(None), _use(None)
    assert a is not b
    assert a.resets == 0 and b.resets == 0
    assert len(cmod._WORKER_PREPARED) == 0


def test_a_lent_object_is_not_lent_again_until_it_is_returned():
    with worker_prepared("k", _Built, _reset) as outer:
        with worker_prepared("k", _Built, _reset) as inner:
            assert inner is not outer
    # Both went back; the one returned last is kept (one entry per key).
    assert len(cmod._WORKER_PREPARED) == 1
    assert _use("k") is outer


def test_an_object_whose_request_failed_is_dropped():
    with pytest.raises(RuntimeError):
        with worker_prepared("k", _Built, _reset) as broken:
            raise RuntimeError("the plan failed")
    assert _use("k") is not broken


def test_the_prepared_cache_is_bounded_least_recently_used_first():
    size = cmod.WORKER_PREPARED_SIZE
    objs = {k: _use(k) for k in range(size)}
    assert _use(0) is objs[0]                 # 0 is now the most recently used
    _use("new")                               # one over: the least recently used (1) leaves
    assert len(cmod._WORKER_PREPARED) == size
    assert _use(0) is objs[0]
    assert _use(1) is not objs[1]


# ---- worker_cached -----------------------------------------------------------------------
def test_a_kept_value_in_use_stays_while_others_come_and_go():
    model = object()
    assert worker_cached("model", model) is model
    for k in range(3 * cmod.WORKER_CACHE_SIZE):
        worker_cached(f"scene:{k}", object())
        assert worker_cached("model", object()) is model   # used by every request
    assert len(cmod._WORKER_CACHE) == cmod.WORKER_CACHE_SIZE
    assert cmod.worker_kept("scene:0") is None


# ---- run_kept ----------------------------------------------------------------------------
class _Heavy:
    """A value whose pickling is counted (a collision model of megabytes)."""

    pickled = 0

    def __init__(self, name: str) -> None:
        self.name = name

    def __reduce__(self):
        _Heavy.pickled += 1
        return (_Heavy, (self.name,))


class _Workers:
    """A ``ComputePool`` of ``n`` simulated workers (process ids 1000, 1001, ...) taking
    calls in turn, as a real pool's workers do under one client's requests: arguments and
    answers travel pickled, and each worker has its own kept values."""

    def __init__(self, n: int) -> None:
        self.workers = n
        self.holders = OrderedDict()
        self.caches = [OrderedDict() for _ in range(n)]
        self.turn = 0
        self.calls = 0

    async def run(self, heavy: bool, fn, *args):
        assert heavy
        k = self.turn % self.workers
        self.turn += 1
        self.calls += 1
        saved = cmod._WORKER_CACHE, cmod._worker_id
        cmod._WORKER_CACHE, cmod._worker_id = self.caches[k], lambda: 1000 + k
        try:
            fn, args = pickle.loads(pickle.dumps((fn, args)))
            return pickle.loads(pickle.dumps(fn(*args)))
        finally:
            cmod._WORKER_CACHE, cmod._worker_id = saved


def _names(a, b, extra):
    return (a.name, None if b is None else b.name, extra)


def _run(pool, values, extra=0):
    return asyncio.run(run_kept(pool, _names, values, extra))


def test_a_value_is_sent_until_the_worker_keeps_it_then_its_token_alone():
    _Heavy.pickled = 0
    pool = _Workers(1)
    values = [("m1", _Heavy("model")), ("s1", _Heavy("scene"))]
    assert _run(pool, values, 7) == ("model", "scene", 7)
    assert pool.calls == 1 and _Heavy.pickled == 2
    for _ in range(3):
        assert _run(pool, values, 7) == ("model", "scene", 7)
    assert pool.calls == 4 and _Heavy.pickled == 2     # tokens alone from then on


def test_every_worker_of_the_pool_gets_the_values_once():
    _Heavy.pickled = 0
    pool = _Workers(2)
    values = [("m1", _Heavy("model")), ("s1", _Heavy("scene"))]
    answers = [_run(pool, values, 1) for _ in range(6)]
    assert answers == [("model", "scene", 1)] * 6
    assert all(set(c) == {"m1", "s1"} for c in pool.caches)
    assert pool.calls == 6 and _Heavy.pickled == 4


def test_only_new_values_are_sent_and_untokened_ones_always_are():
    pool = _Workers(1)
    _run(pool, [("m1", _Heavy("model")), ("s1", _Heavy("a"))])
    _Heavy.pickled = 0
    assert _run(pool, [("m1", _Heavy("model")), ("s2", _Heavy("b"))]) == ("model", "b", 0)
    assert _Heavy.pickled == 1                                    # the new scene alone
    _Heavy.pickled = 0
    assert _run(pool, [("m1", _Heavy("model")), (None, _Heavy("c"))]) == ("model", "c", 0)
    assert _run(pool, [("m1", _Heavy("model")), (None, _Heavy("c"))]) == ("model", "c", 0)
    assert _Heavy.pickled == 2                                    # inline: every time
    assert _run(pool, [("m1", _Heavy("model")), (None, None)]) == ("model", None, 0)


def test_a_worker_that_let_a_value_go_gets_it_again():
    pool = _Workers(1)
    values = [("m1", _Heavy("model")), ("s1", _Heavy("scene"))]
    _run(pool, values)
    pool.caches[0].pop("s1")                   # left the worker's cache
    _Heavy.pickled, calls = 0, pool.calls
    assert _run(pool, values) == ("model", "scene", 0)
    assert pool.calls == calls + 2 and _Heavy.pickled == 1     # lacking, then the scene
    assert set(pool.caches[0]) == {"m1", "s1"}


def test_a_replaced_worker_gets_the_values_again():
    pool = _Workers(2)
    values = [("m1", _Heavy("model")), ("s1", _Heavy("scene"))]
    for _ in range(2):
        _run(pool, values)
    pool.caches = [OrderedDict(), OrderedDict()]   # a new pool: new processes, empty caches
    for _ in range(6):
        assert _run(pool, values) == ("model", "scene", 0)
    assert all(set(c) == {"m1", "s1"} for c in pool.caches)


def test_a_worker_answers_lacking_instead_of_running_without_the_value():
    ran = []
    pid, kept, out = cmod._with_kept(lambda *a: ran.append(a), [("m9", Kept("m9"))], ())
    assert out == Lacking(("m9",)) and kept == () and ran == []


# ---- the motion route's worker side --------------------------------------------------------
def _request():
    model = builtin_model(ROBOT)
    return robot_problem(model, START, {"q": GOAL}, planner="auto", seed=0,
                         resolution=0.02, simplify=True, self_collision=True, margin=0.0,
                         trajectory=False, time_limit=2.0)


@pytest.mark.usefixtures("motion_kernels")
def test_a_reused_checker_answers_as_a_new_one_would():
    model = builtin_model(ROBOT)
    cm = RobotCollisionModel.from_model(model)
    scene = CollisionScene.from_request({"objects": [_ball_at(MIDDLE, "ball")]})
    req = _request()
    fresh = req.plan(req.checker(cm, scene), model)
    assert fresh.status.value == "ok"
    answers = [pickle.loads(pickle.dumps(motion_route._plan(cm, scene, None, "m", "s", req)))
               for _ in range(3)]
    assert len(cmod._WORKER_PREPARED) == 1          # one checker, prepared once, reused
    for data in answers:
        out = json.loads(data)
        assert out["status"] == "ok"
        assert np.array_equal(np.array(out["path"]), fresh.path)
        assert out["stats"]["checks"] == fresh.stats["checks"]
    (checker,) = cmod._WORKER_PREPARED.values()
    assert checker.deadline is None and checker.exact and checker.exact_zone is None


@pytest.mark.usefixtures("motion_kernels")
def test_the_checker_is_kept_per_scene_version_and_settings():
    model = builtin_model(ROBOT)
    cm = RobotCollisionModel.from_model(model)
    scene = CollisionScene.from_request({"objects": [_ball_at(MIDDLE, "ball")]})
    motion_route._plan(cm, scene, None, "m", "scene:a:1", _request())
    motion_route._plan(cm, scene, None, "m", "scene:a:2", _request())
    motion_route._plan(cm, scene, None, "m", "scene:a:2", replace(_request(), margin=5.0))
    motion_route._plan(cm, scene, None, "m", None, _request())   # no token: not kept
    assert sorted(k[2:] for k in cmod._WORKER_PREPARED) == [
        ("scene:a:1", True, 0.0), ("scene:a:2", True, 0.0), ("scene:a:2", True, 5.0)]


# ---- through the endpoint ------------------------------------------------------------------
@pytest.fixture
def service(tmp_path):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, prebuild_collision=False,
                              compute_workers=1))
    with TestClient(api) as client:
        yield client
    api.state.compute.shutdown()


def _move(client: TestClient, scene, start=START):
    body = {"start": start, "goal": {"q": GOAL}, "scene": scene, "time_limit": 1.0,
            "trajectory": False}
    r = client.post(f"/robots/{ROBOT}/motion", json=body)
    assert r.status_code == 200, r.text
    return r.json()


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_a_stored_scene_stored_again_changes_the_answer(service):
    """The worker keeps the scene and its checker by the scene's token: the same id stored
    again with an obstacle at the start must be planned in the new scene."""
    far = {"id": "cell", "objects": [_ball_at(MIDDLE, "far", radius=10.0)]}
    far["objects"][0]["pose"][2][3] += 5000.0
    assert service.post("/scenes", json=far).status_code == 201
    for _ in range(2):  # the second answer comes from the kept scene and checker
        out = _move(service, "cell")
        assert out["status"] == "ok"
    assert service.delete("/scenes/cell").status_code == 204
    near = {"id": "cell", "objects": [_ball_at(START, "here")]}
    assert service.post("/scenes", json=near).status_code == 201
    out = _move(service, "cell")
    assert out["status"] == "start_in_collision"
    assert any("here" in p for p in out["pairs"])


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_equal_requests_get_equal_answers_stored_or_inline(service):
    objects = [_ball_at(MIDDLE, "ball")]
    assert service.post("/scenes", json={"id": "ball", "objects": objects}).status_code == 201
    answers = [_move(service, "ball") for _ in range(3)]
    answers.append(_move(service, {"objects": objects}))
    for out in answers:
        assert out["status"] == "ok"
        assert out["path"] == answers[0]["path"]
        assert out["min_clearance"] == answers[0]["min_clearance"]


def test_an_unknown_robot_is_404_before_the_body_is_read(service):
    r = service.post("/robots/no_such_robot/motion", json={"start": "x", "time_limit": -1})
    assert r.status_code == 404, r.text
    assert r.json()["detail"][0]["loc"] == ["path", "robot_id"]


# ---- the API process's side ----------------------------------------------------------------
class _Registry:
    """The part of ``RobotRegistry`` that ``collision_entry`` uses, counting lookups of the
    stored collision model."""

    def __init__(self) -> None:
        self.models = {"arm": object()}
        self.lookups = 0

    def get(self, robot_id: str):
        return self.models[robot_id]

    def stored_collision(self, robot_id: str):
        self.lookups += 1
        model = self.get(robot_id)
        return (f"cm of {id(model)}", f"{robot_id}:{self.lookups}")


def test_the_api_finds_a_kept_collision_model_again_until_the_robot_changes():
    from types import SimpleNamespace

    state, registry = SimpleNamespace(), _Registry()
    first = asyncio.run(cmod.collision_entry(state, registry, "arm"))
    assert asyncio.run(cmod.collision_entry(state, registry, "arm")) == first
    assert registry.lookups == 1
    registry.models["arm"] = object()               # stored again: another model
    changed = asyncio.run(cmod.collision_entry(state, registry, "arm"))
    assert changed != first and registry.lookups == 2
    del registry.models["arm"]                       # deleted
    with pytest.raises(KeyError):
        asyncio.run(cmod.collision_entry(state, registry, "arm"))


class _Scenes:
    """The part of ``SceneRegistry`` that ``resolve_scene`` uses for inline scenes, counting
    builds."""

    def __init__(self) -> None:
        self.builds = 0

    def build(self, data: dict):
        self.builds += 1
        return CollisionScene.from_request(data)


def test_an_inline_scene_is_named_by_its_content():
    ball = _ball_at(MIDDLE, "ball")
    token = cmod.inline_token({"objects": [ball]})
    assert token is not None and token.startswith("inline:")
    assert cmod.inline_token({"objects": [dict(reversed(list(ball.items())))]}) == token
    moved = {**ball, "radius": ball["radius"] + 1.0}
    assert cmod.inline_token({"objects": [moved]}) != token
    stored_mesh = {"type": "mesh", "id": "m", "mesh": "part", "pose": ball["pose"]}
    assert cmod.inline_token({"objects": [ball, stored_mesh]}) is None


def test_an_inline_scene_sent_again_is_not_built_again():
    scenes = _Scenes()
    data = {"objects": [_ball_at(MIDDLE, "ball")]}
    first, token = cmod.resolve_scene(scenes, data)
    again, token2 = cmod.resolve_scene(scenes, {"objects": [dict(data["objects"][0])]})
    assert again is first and token2 == token and scenes.builds == 1
    other, token3 = cmod.resolve_scene(scenes, {"objects": [_ball_at(START, "ball")]})
    assert other is not first and token3 != token and scenes.builds == 2
    for k in range(cmod.INLINE_SCENES_SIZE):      # the cache is bounded
        cmod.resolve_scene(scenes, {"objects": [_ball_at(START, f"b{k}")]})
    assert len(cmod._INLINE_SCENES) == cmod.INLINE_SCENES_SIZE
    builds = scenes.builds
    cmod.resolve_scene(scenes, data)
    assert scenes.builds == builds + 1


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_an_inline_scene_that_changes_changes_the_answer(service):
    far = _ball_at(MIDDLE, "far", radius=10.0)
    far["pose"][2][3] += 5000.0
    for _ in range(2):
        assert _move(service, {"objects": [far]})["status"] == "ok"
    out = _move(service, {"objects": [_ball_at(START, "here")]})
    assert out["status"] == "start_in_collision"


@pytest.mark.slow
def test_a_real_pool_runs_by_token_once_its_worker_keeps_the_value():
    import operator

    from app.compute import ComputePool

    pool = ComputePool(workers=1, max_waiting=4)
    try:
        values = [("t1", "kept "), (None, "sent ")]
        assert asyncio.run(run_kept(pool, operator.concat, values[:1], "x")) == "kept x"
        (pid,) = pool.holders["t1"]
        # By token alone now: a worker without the value would answer Lacking, not this.
        first = [("t1", Kept("t1"))]
        out = asyncio.run(pool.run(True, cmod._with_kept, operator.concat, first, ("y",)))
        assert out == (pid, ("t1",), "kept y")
        assert asyncio.run(run_kept(pool, operator.concat, values[1:], "z")) == "sent z"
    finally:
        pool.shutdown()
    assert not pool.holders                          # forgotten with the workers


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_the_robot_model_travels_inside_its_collision_model(service, monkeypatch):
    sent = []

    async def spy(pool, fn, values, *args):
        sent.append([value for _, value in values])
        return await run_kept(pool, fn, values, *args)

    monkeypatch.setattr(motion_route, "run_kept", spy)
    for _ in range(2):
        assert _move(service, None)["robot"] == ROBOT
    assert [v[2] for v in sent] == [None, None]        # no model of its own
    assert all(isinstance(v[0], RobotCollisionModel) for v in sent)
