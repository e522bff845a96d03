"""Bounded parameters of the planners a job may tune: the path optimisers (``path``,
``path_compare``), the hole sequencers (``sequence``, ``multiarm``) and the multi-arm move
planners (``multiarm``).

Each algorithm gets a pydantic model with a cap on every knob (``ge``/``le`` in its JSON
schema, so ``GET /jobs/kinds`` shows them) and the algorithm's own defaults, read from its
parameter dataclass. The caps keep one knob from running a job for days or filling the
memory (``iterations: 1e12`` is a 422 naming ``params.iterations``); the product of several
knobs is bounded by the job time limit, and, for the path planners, by ``check_batch_memory``
(the obstacle checks of one batch of candidate paths must fit in ``MAX_BATCH_BYTES``).

After the caps, the algorithm's dataclass is still built, so its own checks across knobs
(``elite < population``, an even population, ...) apply too.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import fields
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model
from pydantic_core import InitErrorDetails, PydanticCustomError

__all__ = [
    "Knobs",
    "PATH_KNOBS",
    "SEQUENCER_KNOBS",
    "MOVE_PLANNER_KNOBS",
    "MAX_BATCH_BYTES",
    "knobs_schema",
    "validate_knobs",
    "path_knobs",
    "sequencer_knobs",
    "move_planner_knobs",
    "check_batch_memory",
]


def Int(lo: int, hi: int, doc: str | None = None) -> Any:
    return Annotated[int, Field(ge=lo, le=hi, description=doc)]


def Real(lo: float, hi: float, doc: str | None = None, *, above: bool = False,
         below: bool = False) -> Any:
    """A float in [lo, hi]; ``above``/``below`` make that end open."""
    low = {"gt": lo} if above else {"ge": lo}
    high = {"lt": hi} if below else {"le": hi}
    return Annotated[float, Field(**low, **high, description=doc)]


Fraction = Real(0.0, 1.0)
Probability = Real(0.0, 1.0, "probability")


class Knobs(BaseModel):
    """Parameters of one algorithm: unknown names and NaN/inf are rejected."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


# ---- the caps ------------------------------------------------------------------------------
#: Knobs ``plan_path`` takes for every metaheuristic besides its optimiser's own.
_PATH_COMMON = {
    "waypoints": (Int(1, 50, "intermediate waypoints of the encoding"), None),
    "penalty": (Real(0.0, 1e9, "mm of length per mm of penetration", above=True), 1000.0),
    "max_evaluations": (Int(1, 100_000_000, "evaluation budget") | None, None),
    "shortcut": (bool, True),
    "random_shortcuts": (Int(0, 10_000), 100),
}
_SHORTCUTS = {k: _PATH_COMMON[k] for k in ("shortcut", "random_shortcuts")}

_WOLFPACK = {
    "n_wolves": Int(3, 1000),
    "scout_fraction": Real(0.0, 1.0, above=True, below=True),
    "step_factor": Real(1e-3, 1e6),
    "max_walks": Int(1, 100),
    "distance_factor": Real(1e-3, 1e6),
    "update_ratio": Real(1e-3, 1e3),
    "directions": Int(1, 100),
    "iterations": Int(1, 10_000),
    "max_summon_steps": Int(0, 1000),
}
_OPTIMISER_CAPS: dict[str, dict[str, Any]] = {
    "wolfpack": _WOLFPACK,
    "wolfpack_improved": _WOLFPACK | {"levy_lambda": Real(1.0, 3.0, above=True),
                                      "levy_weight": Real(0.0, 10.0)},
    "ga": {
        "population": Int(2, 2000),
        "crossover": Probability,
        "selection": Real(0.0, 1.0, "fraction of parents", above=True),
        "mutation": Probability,
        "iterations": Int(1, 20_000),
        "mutation_scale": Real(0.0, 10.0, "fraction of the range", above=True),
        "elite": Int(0, 1999),
    },
    "afsa": {
        "n_fish": Int(2, 300),
        "visual": Real(0.0, 10.0, "fraction of the mean range", above=True),
        "step": Real(0.0, 10.0, "fraction of the mean range", above=True),
        "crowding": Real(1e-3, 1e6),
        "try_number": Int(1, 300),
        "iterations": Int(1, 10_000),
    },
    "aca": {
        "n_ants": Int(1, 5000),
        "alpha": Real(0.0, 100.0),
        "beta": Real(0.0, 100.0),
        "evaporation": Real(0.0, 1.0, above=True),
        "q": Real(0.0, 1e9),
        "iterations": Int(1, 10_000),
        "n_slices": Int(1, 100),
        "grid": Int(2, 101),
        "window": Int(1, 20),
    },
}
#: Knobs of the two planners that are not metaheuristics (defaults: ``auto_planner``'s).
_OWN_PLANNERS = {
    "auto": {
        "samples": (Int(4, 2000, "surface samples per obstacle"), 150),
        "rel_offset": (Real(0.0, 1.0, "offset of the samples / obstacle size", above=True),
                       0.02),
        "rounds": (Int(0, 20, "tightening rounds"), 1),
    } | _SHORTCUTS,
    "rrt_star": {
        "samples": (Int(1, 20_000), 3000),
        "step": (Real(0.0, 1e8, "mm; default a tenth of the scene's diagonal", above=True)
                 | None, None),
        "goal_bias": (Probability, 0.05),
        "gamma": (Real(0.0, 1e9, "mm; default twice the scene's diagonal", above=True)
                  | None, None),
        "time_limit": (Real(0.0, 3600.0, "s", above=True) | None, None),
    } | _SHORTCUTS,
}

_SEQUENCER_CAPS: dict[str, dict[str, Any]] = {
    "iga": {
        "population": Int(2, 500, "even"),
        "crossover": Probability,
        "mutation": Probability,
        "iterations": Int(1, 5000),
        "p_swap": Probability,
        "p_reverse": Probability,
        "p_insert": Probability,
        "cooling": Real(0.0, 1.0, above=True),
        "tournament": Int(1, 500),
        "destroy_fraction": Fraction,
        "removal": Literal["random", "related", "mixed"],
        "initial_temperature": Real(0.0, 1e7, "mm", above=True) | None,
    },
    "aco": {
        "ants": Int(1, 500),
        "alpha": Real(0.0, 20.0),
        "beta": Real(0.0, 20.0),
        "rho": Real(0.0, 1.0, above=True),
        "q": Real(0.0, 1e9, above=True),
        "iterations": Int(1, 5000),
    },
    "aga": {
        "population": Int(2, 1000, "even"),
        "crossover": Probability,
        "mutation": Probability,
        "iterations": Int(1, 20_000),
        "crossover_min": Probability,
        "mutation_min": Probability,
    },
    "auto": {
        "exact_max": Int(0, 16, "most holes solved exactly"),
        "kicks": Int(0, 100_000),
        "stall": Int(0, 100_000),
        "kick_segment": Int(0, 1000),
        "threshold": Real(0.0, 1.0, "fraction longer than the best accepted"),
        "restarts": Int(1, 200),
    },
}

_MOVE_PLANNER_CAPS: dict[str, dict[str, Any]] = {
    "iapf": {
        "attraction_gain": Real(0.0, 1e3, above=True),
        "goal_threshold": Real(0.0, 2.0, "normalised joint distance", above=True),
        "repulsion_gain": Real(0.0, 1e3),
        "influence": Real(0.0, 1e5, "mm", above=True),
        "step": Real(1e-5, 1.0, "normalised"),
        "far_step": Real(1e-5, 1.0, "normalised"),
        "safety": Real(0.0, 2000.0, "mm"),
        "max_steps": Int(1, 100_000),
        "stall_window": Int(1, 10_000),
        "escape_steps": Int(0, 10_000),
        "max_escapes": Int(0, 1000),
        "gradient_step": Real(1e-9, 0.1, "normalised"),
    },
    "rrt": {
        "step": Real(1e-4, 1.0, "normalised"),
        "edge_resolution": Real(1e-4, 1.0, "normalised"),
        "max_iterations": Int(1, 100_000),
        "safety": Real(0.0, 2000.0, "mm"),
        "shortcut": Int(0, 10_000),
    },
}


# ---- models --------------------------------------------------------------------------------
def _model(title: str, spec: dict[str, tuple[Any, Any]]) -> type[Knobs]:
    base = type("Knobs", (Knobs,), {"model_config": ConfigDict(title=title)})
    return create_model(title.replace(" ", "_"), __base__=base, **spec)  # type: ignore


def _from_dataclass(title: str, cls: type, defaults: object, caps: dict[str, Any],
                    extra: dict[str, tuple[Any, Any]] | None = None) -> type[Knobs]:
    """The model of dataclass ``cls``: every field capped by ``caps`` (a field without a cap
    is an error here, so a new knob cannot slip through uncapped), defaults from
    ``defaults`` (an instance: a preset may differ from the class defaults)."""
    names = [f.name for f in fields(cls)]
    missing = set(names) - set(caps)
    if missing:
        raise TypeError(f"{cls.__name__}: no cap for {', '.join(sorted(missing))}")
    spec = {n: (caps[n], getattr(defaults, n)) for n in names}
    return _model(title, spec | (extra or {}))


def _path_models() -> dict[str, type[Knobs]]:
    from planning.paths import _OPTIMISERS, DEFAULT_WAYPOINTS

    out: dict[str, type[Knobs]] = {}
    for name, (module, cls_name, preset) in _OPTIMISERS.items():
        cls = getattr(importlib.import_module(module), cls_name)
        base = getattr(cls, preset)() if preset else cls()
        common = dict(_PATH_COMMON)
        common["waypoints"] = (common["waypoints"][0], DEFAULT_WAYPOINTS.get(name, 5))
        out[name] = _from_dataclass(f"{name} params", cls, base, _OPTIMISER_CAPS[name],
                                    common)
    for name, spec in _OWN_PLANNERS.items():
        out[name] = _model(f"{name} params", spec)
    return out


def _dataclass_models(registry: dict[str, type], caps: dict[str, dict[str, Any]],
                      what: str) -> dict[str, type[Knobs]]:
    return {name: _from_dataclass(f"{name} {what}", cls, cls(), caps[name])
            for name, cls in registry.items()}


def _sequencer_models() -> dict[str, type[Knobs]]:
    from planning.sequencing import SEQUENCERS

    return _dataclass_models(SEQUENCERS, _SEQUENCER_CAPS, "params")


def _move_planner_models() -> dict[str, type[Knobs]]:
    from planning.drilling.multiarm import PLANNERS

    return _dataclass_models(PLANNERS, _MOVE_PLANNER_CAPS, "planner_params")


PATH_KNOBS = _path_models()
SEQUENCER_KNOBS = _sequencer_models()
MOVE_PLANNER_KNOBS = _move_planner_models()


def knobs_schema(models: dict[str, type[Knobs]], description: str) -> dict[str, Any]:
    """JSON schema of a free-form parameter object: one of the algorithms' schemas (each
    titled with the algorithm), or null."""
    return {"anyOf": [*(m.model_json_schema() for m in models.values()), {"type": "null"}],
            "description": description}


# ---- validation ----------------------------------------------------------------------------
def _renamed(exc: ValidationError, prefix: str, algorithm: str, model: type[Knobs],
             loc: tuple) -> ValidationError:
    """``exc`` with each message naming the knob (``params.iterations: ...``) and each
    ``loc`` under ``loc``, so the API names the knob in both."""
    known = ", ".join(model.model_fields)
    details: list[InitErrorDetails] = []
    for err in exc.errors():
        name = ".".join(str(p) for p in (prefix, *err["loc"]))
        if err["type"] == "extra_forbidden":
            msg = f"{name} is not a parameter of {algorithm}; known: {known}"
        else:
            msg = f"{name}: {err['msg']}"
        # Braces would be read as placeholders of the message template.
        msg = msg.replace("{", "(").replace("}", ")")
        details.append({"type": PydanticCustomError(err["type"], msg),
                        "loc": (*loc, *err["loc"]), "input": err.get("input")})
    return ValidationError.from_exception_data(model.__name__, details)


def validate_knobs(models: dict[str, type[Knobs]], algorithm: str, value: dict | None,
                   prefix: str, loc: tuple = ()) -> dict[str, Any] | None:
    """``value`` checked against the model of ``algorithm``: the knobs given (types coerced,
    nothing added), or a ``ValidationError`` whose messages start with ``prefix`` and whose
    locations start with ``loc``."""
    if value is None or algorithm not in models:
        return value
    model = models[algorithm]
    try:
        checked = model.model_validate(value)
    except ValidationError as exc:
        raise _renamed(exc, prefix, algorithm, model, loc) from None
    return checked.model_dump(exclude_unset=True, exclude_none=True)


def path_knobs(algorithm: str, value: dict | None, prefix: str = "params", loc: tuple = ()
               ) -> dict[str, Any] | None:
    """A path planner's params, capped, then built (the optimiser's own cross checks)."""
    value = validate_knobs(PATH_KNOBS, algorithm, value, prefix, loc)
    if value is not None and algorithm not in _OWN_PLANNERS:
        from planning.paths import make_optimiser

        make_optimiser(algorithm, {k: v for k, v in value.items() if k not in _PATH_COMMON})
    return value


def sequencer_knobs(algorithm: str, value: dict | None, prefix: str = "params"
                    ) -> dict[str, Any] | None:
    """A hole sequencer's params, capped, then built."""
    value = validate_knobs(SEQUENCER_KNOBS, algorithm, value, prefix)
    if value is not None:
        from planning.sequencing import make_sequencer

        make_sequencer(algorithm, value)
    return value


def move_planner_knobs(planner: str, value: dict | None, prefix: str = "planner_params"
                       ) -> dict[str, Any] | None:
    """A multi-arm move planner's params, capped, then built."""
    value = validate_knobs(MOVE_PLANNER_KNOBS, planner, value, prefix)
    if value is not None:
        from planning.drilling.multiarm import make_planner

        make_planner(planner, value)
    return value


# ---- memory of one batch of obstacle checks ----------------------------------------------
#: Most bytes the obstacle checks of one batch of candidate paths may take (4 GiB).
MAX_BATCH_BYTES = 4 << 30
#: Peak bytes per (segment, obstacle) pair of ``Scene.segment_clearance``, by obstacle type
#: (measured, with some room).
PAIR_BYTES = {"sphere": 120, "capsule": 220, "box": 3600}


def _batch_segments(algorithm: str, knobs: dict[str, Any]) -> int:
    """Segments in the largest single obstacle check of ``algorithm``."""
    model = PATH_KNOBS[algorithm]
    p = {name: f.default for name, f in model.model_fields.items()} | knobs
    if algorithm in ("wolfpack", "wolfpack_improved"):
        n = p["n_wolves"]
        scouts = min(n - 2, max(1, round(p["scout_fraction"] * n)))
        return max(n, scouts * p["directions"]) * (p["waypoints"] + 1)
    if algorithm == "ga":
        return p["population"] * (p["waypoints"] + 1)
    if algorithm == "afsa":
        return p["n_fish"] * p["try_number"] * (p["waypoints"] + 1)
    if algorithm == "aca":
        lattice = p["grid"] ** 2 * min(2 * p["window"] + 1, p["grid"]) ** 2
        return max(p["n_ants"] * (p["n_slices"] + 1), lattice)
    return 0


def check_batch_memory(algorithm: str, knobs: dict[str, Any] | None,
                       obstacle_types: list[str]) -> None:
    """ValueError when one batch of obstacle checks of ``algorithm`` with ``knobs`` among
    obstacles of ``obstacle_types`` would take more than ``MAX_BATCH_BYTES``."""
    if not obstacle_types or algorithm not in PATH_KNOBS:
        return
    per_segment = sum(PAIR_BYTES[t] for t in obstacle_types)
    knobs = knobs or {}
    if algorithm == "auto":  # every surface sample is checked against every obstacle
        samples = knobs.get("samples", PATH_KNOBS["auto"].model_fields["samples"].default)
        segments = samples * len(obstacle_types)
        what = f"{samples} surface samples per obstacle"
    else:
        segments = _batch_segments(algorithm, knobs)
        what = "one batch of candidate paths"
    need = segments * per_segment
    if need > MAX_BATCH_BYTES:
        raise ValueError(
            f"{algorithm}: {what} against {len(obstacle_types)} obstacles would take about "
            f"{need / 2**30:.1f} GiB of memory; at most {MAX_BATCH_BYTES / 2**30:g} GiB: "
            "use a smaller population or fewer waypoints, samples or obstacles "
            f"(boxes cost {math.ceil(PAIR_BYTES['box'] / PAIR_BYTES['sphere'])} times "
            "a sphere)")
