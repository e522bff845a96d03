"""The algorithm registry: one name -> parameter dataclass mapping per family, the caps on
every knob declared on the dataclasses, one ``make`` for every family, and the API built
from it (names accepted, knobs capped, caps published)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import textwrap
import typing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from kinematics.errors import FieldError
from planning.drilling.iapf import IAPF
from planning.drilling.multiarm import PLANNERS, make_planner
from planning.drilling.rrt import RRTConnect
from planning.optimisers.acor import ACOR
from planning.optimisers.ga import GeneticAlgorithm
from planning.optimisers.wolfpack import WolfPack
from planning.paths.encoding import DEFAULT_PENALTY, DEFAULT_RANDOM_SHORTCUTS
from planning.paths.planners import ALGORITHMS, DEFAULT_WAYPOINTS, make_optimiser, plan_path
from planning.paths.scene import Scene
from planning.registry import (
    FAMILIES,
    AutoPlannerParams,
    MetaheuristicParams,
    algorithm_classes,
    algorithm_names,
    dataclass_knobs,
    knobs,
    lookup,
    make,
    register,
)
from planning.sequencing import ACO, SEQUENCERS, make_sequencer
from planning.tracking import TUNERS, make_tuner

ROOT = Path(__file__).resolve().parents[2]
LOWER, UPPER = {"ge", "gt"}, {"le", "lt"}


def every_algorithm():
    return [(f, n) for f, fam in FAMILIES.items() for n in fam.algorithms]


# ---- caps on the dataclasses -----------------------------------------------------------------
@pytest.mark.parametrize("family, name", every_algorithm())
def test_every_numeric_field_of_every_algorithm_has_caps(family, name):
    entry = FAMILIES[family].algorithms[name]
    defaults = entry.defaults()
    for cls, instance in ((entry.params, defaults), (entry.shared, None)):
        if cls is None:
            continue
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            kinds = set(typing.get_args(hints[f.name]) or (hints[f.name],)) - {type(None)}
            value = getattr(instance if instance is not None else cls(), f.name)
            where = f"{family} {name}: {cls.__name__}.{f.name}"
            if kinds <= {bool}:
                continue
            if kinds <= {int, float}:
                assert LOWER & set(f.metadata) and UPPER & set(f.metadata), where
                if value is not None:  # the default lies within the caps
                    m = f.metadata
                    assert m.get("ge", -float("inf")) <= value <= m.get("le", float("inf")), where
                    assert m.get("gt", -float("inf")) < value < m.get("lt", float("inf")), where
            elif kinds == {str}:
                assert value in f.metadata["choices"], where
            else:
                pytest.fail(f"{where}: not a knob type")


def test_a_field_without_caps_is_refused():
    @dataclass(frozen=True)
    class Loose:
        rate: float = field(default=0.5, metadata={"ge": 0.0})
        mode: str = "fast"

    with pytest.raises(TypeError, match="Loose.rate: no cap"):
        dataclass_knobs(Loose)

    @dataclass(frozen=True)
    class Unlisted:
        mode: str = "fast"

    with pytest.raises(TypeError, match="Unlisted.mode"):
        dataclass_knobs(Unlisted)

    @dataclass(frozen=True)
    class Listy:
        weights: list = field(default_factory=list)

    with pytest.raises(TypeError, match="Listy.weights"):
        dataclass_knobs(Listy)


def test_knobs_carry_type_caps_defaults_and_choices():
    by_name = {k.name: k for k in knobs("path", "ga")}
    assert by_name["population"].default == 5  # paper 000's preset
    assert by_name["iterations"].bounds == {"ge": 1, "le": 20_000}
    assert by_name["iterations"].type is int
    assert by_name["max_evaluations"].optional  # a knob plan_path shares with every optimiser
    assert by_name["shortcut"].type is bool and not by_name["shortcut"].bounds
    removal = {k.name: k for k in knobs("sequencer", "iga")}["removal"]
    assert removal.choices == ("random", "related", "mixed") and removal.default == "mixed"
    assert [k.name for k in knobs("path", "auto")] == [
        "samples", "rel_offset", "rounds", "shortcut", "random_shortcuts"]


def test_the_shared_path_knobs_default_as_plan_path_does():
    shared = MetaheuristicParams()
    assert shared.penalty == DEFAULT_PENALTY
    assert shared.random_shortcuts == DEFAULT_RANDOM_SHORTCUTS
    for name in ALGORITHMS:
        if lookup("path", name).shared is MetaheuristicParams:
            assert shared.waypoints == DEFAULT_WAYPOINTS.get(name, 5), name


@pytest.mark.parametrize("name", ["auto", pytest.param("rrt_star", marks=pytest.mark.slow)])
def test_the_planner_defaults_are_the_planners_own(name):
    """Giving the registry's defaults explicitly plans the very path the planner's own
    defaults plan (None: the planner derives it from the scene)."""
    scene = Scene.create([[0, 0, 0], [100, 100, 100]],
                         [{"center": [50, 50, 50], "radius": 20}], 1.0)
    given = {k.name: k.default for k in knobs("path", name) if k.default is not None}
    a = plan_path(scene, [5, 5, 5], [95, 95, 95], name, seed=0)
    b = plan_path(scene, [5, 5, 5], [95, 95, 95], name, seed=0, params=given)
    assert a.success and np.array_equal(a.path, b.path)


# ---- names -----------------------------------------------------------------------------------
def test_each_family_is_the_one_list_of_its_names():
    assert ALGORITHMS == algorithm_names("path")
    assert SEQUENCERS == algorithm_classes("sequencer")
    assert PLANNERS == algorithm_classes("move_planner") == {"iapf": IAPF, "rrt": RRTConnect}
    assert TUNERS == algorithm_classes("tuner")
    for family, fam in FAMILIES.items():
        assert all(entry.name == name and entry.family == family and entry.summary
                   for name, entry in fam.algorithms.items())


def test_a_name_means_one_algorithm_within_its_family():
    assert lookup("sequencer", "aco").params is ACO  # the hole sequencer (Ant System)
    assert lookup("tuner", "aco").params is ACOR  # the continuous ant colony
    assert "hole" in lookup("sequencer", "aco").summary
    assert "continuous" in lookup("tuner", "aco").summary
    # the same GA with each paper's settings
    assert make("path", "ga") == GeneticAlgorithm.paper_000()
    assert make("tuner", "ga") == GeneticAlgorithm()
    with pytest.raises(ValueError, match="already has"):
        register("sequencer", "aco", ACO)
    with pytest.raises(ValueError, match="no algorithm family"):
        algorithm_names("solvers")


# ---- make ------------------------------------------------------------------------------------
def test_make_overrides_defaults_and_takes_the_shared_knobs():
    opt = make("path", "wolfpack", {"iterations": 3, "waypoints": 7, "shortcut": False})
    assert opt == WolfPack(iterations=3)
    assert make("path", "auto", {"samples": 40, "random_shortcuts": 0}) == \
        AutoPlannerParams(samples=40)
    assert make("sequencer", "aco", {"ants": 3}) == ACO(ants=3)
    assert make("move_planner", "rrt", {"shortcut": 5}) == RRTConnect(shortcut=5)
    assert make("tuner", "aco", {"iterations": 4}) == ACOR(iterations=4)
    # the caps are the service's: the library takes what the dataclass accepts
    assert make("path", "ga", {"iterations": 50_000}).iterations == 50_000


@pytest.mark.parametrize("family, name, params, loc, words", [
    ("path", "dijkstra", None, ("algorithm",), "algorithm: must be one of wolfpack_improved"),
    ("path", "ga", {"foo": 1}, ("params", "foo"), "params.foo is not a parameter of ga"),
    ("path", "ga", {"population": 4, "elite": 4}, ("params",), "elite"),
    ("path", "auto", {"iterations": 3}, ("params", "iterations"), "known: random_shortcuts"),
    ("sequencer", "lkh", None, ("algorithm",), "algorithm: must be one of iga"),
    ("sequencer", "iga", {"wolves": 3}, ("params", "wolves"), "params.wolves"),
    ("sequencer", "aco", {"rho": 0.0}, ("params", "rho"), "params.rho"),
    ("sequencer", "iga", {"population": "x"}, ("params",), "params:"),
    ("move_planner", "prm", None, ("planner",), "planner: must be one of iapf, rrt"),
    ("move_planner", "iapf", {"lam": 1}, ("planner_params", "lam"), "planner_params.lam"),
    ("move_planner", "rrt", {"max_iterations": 0}, ("planner_params", "max_iterations"),
     "max_iterations"),
    ("tuner", "cmaes", None, ("tune",), "tune: must be one of hgso"),
    ("tuner", "pso", {"n_particles": 1}, ("tuner_params",), "n_particles"),
])
def test_make_names_the_field_at_fault(family, name, params, loc, words):
    with pytest.raises(FieldError) as err:
        make(family, name, params)
    assert err.value.loc == loc
    assert words in str(err.value)


def test_the_family_factories_are_make():
    assert make_optimiser("afsa", {"n_fish": 4}) == make("path", "afsa", {"n_fish": 4})
    assert make_sequencer("aga", {"iterations": 9}) == make("sequencer", "aga", {"iterations": 9})
    assert make_planner("iapf", {"step": 0.01}) == IAPF(step=0.01)
    assert make_tuner("gwo", 5) == make("tuner", "gwo", {"iterations": 5})
    with pytest.raises(FieldError) as err:
        make_tuner("nope")
    assert err.value.loc == ("tune",)


# ---- the API, built from the registry --------------------------------------------------------
def test_the_api_algorithm_names_are_the_registry_names():
    from app.jobs import drilling_kinds, path_kinds, tracking_kinds

    assert typing.get_args(path_kinds.Algorithm) == algorithm_names("path")
    assert typing.get_args(drilling_kinds.Algorithm) == algorithm_names("sequencer")
    assert typing.get_args(drilling_kinds.Planner) == algorithm_names("move_planner")
    assert typing.get_args(tracking_kinds.Tuner) == algorithm_names("tuner")


def _number(prop: dict) -> dict:
    """The number schema of a property (inside its ``anyOf`` when it may be null)."""
    for node in prop.get("anyOf", [prop]):
        if node.get("type") in ("integer", "number", "string", "boolean"):
            return node
    raise AssertionError(prop)


def test_every_knob_shows_its_caps_in_the_published_schemas(tmp_path):
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    client = TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path)))
    kinds = {k["kind"]: k["params"] for k in client.get("/jobs/kinds").json()}
    published = {"path": kinds["path"]["properties"]["params"],
                 "sequencer": kinds["sequence"]["properties"]["params"],
                 "move_planner": kinds["multiarm"]["properties"]["planner_params"]}
    schema_key = {"ge": "minimum", "gt": "exclusiveMinimum", "le": "maximum",
                  "lt": "exclusiveMaximum"}
    for family, schema in published.items():
        models = {s["title"]: s for s in schema["anyOf"] if s.get("type") == "object"}
        field_name = FAMILIES[family].params_field
        assert set(models) == {f"{n} {field_name}" for n in algorithm_names(family)}
        for name in algorithm_names(family):
            model = models[f"{name} {field_name}"]
            assert model["description"] == lookup(family, name).summary
            assert model["additionalProperties"] is False
            assert list(model["properties"]) == [k.name for k in knobs(family, name)]
            for k in knobs(family, name):
                prop = model["properties"][k.name]
                node = _number(prop)
                where = f"{family} {name}.{k.name}"
                assert {schema_key[b]: v for b, v in k.bounds.items()} == {
                    key: node[key] for key in schema_key.values() if key in node}, where
                assert prop.get("default") == k.default, where
                if k.choices:
                    assert node["enum"] == list(k.choices), where


@dataclass(frozen=True)
class Tiny:
    rounds: int = field(default=7, metadata={"ge": 1, "le": 40, "description": "rounds"})


@pytest.fixture
def tiny():
    entry = register("path", "tiny", Tiny, summary="a tiny optimiser")
    yield entry
    del FAMILIES["path"].algorithms["tiny"]


def test_a_registered_algorithm_gets_a_capped_model(tiny):
    from pydantic import ValidationError

    from app.jobs.planner_params import knobs_models

    model = knobs_models("path")["tiny"]
    assert model.model_validate({"rounds": 40, "waypoints": 3}).rounds == 40
    with pytest.raises(ValidationError, match="less than or equal to 40"):
        model.model_validate({"rounds": 41})
    assert make("path", "tiny", {"rounds": 2, "penalty": 5.0}) == Tiny(rounds=2)


@pytest.mark.slow
def test_registering_an_algorithm_is_all_the_api_needs(tmp_path):
    """A fresh service process with one more optimiser registered: jobs name it, its knob is
    capped (422 naming it above the cap) and its caps are published."""
    code = textwrap.dedent("""
        import json, sys
        from dataclasses import dataclass, field

        from planning.registry import register

        @dataclass(frozen=True)
        class Tiny:
            rounds: int = field(default=7, metadata={"ge": 1, "le": 40})

        register("path", "tiny", Tiny, summary="a tiny optimiser")

        from fastapi.testclient import TestClient

        from app.config import Settings
        from app.main import create_app

        client = TestClient(create_app(Settings(no_viewer=True, data_dir=sys.argv[1])))
        task = {"scene": {"bounds": [[0, 0, 0], [100, 100, 100]]}, "start": [1, 1, 1],
                "goal": [99, 99, 99]}

        def post(kind, params):
            r = client.post("/jobs", json={"kind": kind, "params": {**task, **params}})
            return {"status": r.status_code, "detail": r.json().get("detail")}

        kinds = {k["kind"]: k["params"] for k in client.get("/jobs/kinds").json()}
        print(json.dumps({
            "ok": post("path", {"algorithm": "tiny", "params": {"rounds": 40}}),
            "over": post("path", {"algorithm": "tiny", "params": {"rounds": 41}}),
            "compare": post("path_compare", {"algorithms": ["tiny", "ga"],
                                             "params": {"tiny": {"rounds": 0}}}),
            "schema": kinds["path"],
        }))
    """)
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["ok"]["status"] == 202, out["ok"]
    (over,) = out["over"]["detail"]
    assert out["over"]["status"] == 422
    assert over["loc"] == ["body", "params", "params", "rounds"]
    assert "params.rounds" in over["msg"] and "40" in over["msg"]
    (low,) = out["compare"]["detail"]
    assert low["loc"] == ["body", "params", "params", "tiny", "rounds"]
    schema = out["schema"]
    assert "tiny" in json.dumps(schema["properties"]["algorithm"])
    models = {s["title"]: s for s in schema["properties"]["params"]["anyOf"]
              if s.get("type") == "object"}
    assert models["tiny params"]["properties"]["rounds"]["maximum"] == 40
    assert models["tiny params"]["description"] == "a tiny optimiser"
