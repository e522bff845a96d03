"""Bounded parameters of the planners a job may tune: the path planners (``path``,
``path_compare``), the hole sequencers (``sequence``, ``multiarm``) and the multi-arm move
planners (``multiarm``).

Each algorithm of ``planning.registry`` gets a pydantic model generated from its parameter
dataclass: every knob typed as its field, capped by the bounds of its field metadata
(``ge``/``gt``/``le``/``lt`` in its JSON schema, so ``GET /jobs/kinds`` shows them), with
the algorithm's own defaults and the description of its field; the model is described by the
algorithm's summary. Registering an algorithm is all it takes for the API to accept it. The
caps keep one knob from running a job for days or filling the memory (``iterations: 1e12``
is a 422 naming ``params.iterations``); the product of several knobs is bounded by the job
time limit, and, for the path planners, by ``check_batch_memory`` (the obstacle checks of
one batch of candidate paths must fit in ``MAX_BATCH_BYTES``).

After the caps, the algorithm's dataclass is still built (``planning.registry.make``), so
its own checks across knobs (``elite < population``, an even population, ...) apply too.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, ValidationError, create_model
from pydantic_core import InitErrorDetails, PydanticCustomError

from planning.registry import FAMILIES, Knob, algorithm_names, knobs, lookup, make

from ..fields import StrictModel

__all__ = [
    "Knobs",
    "PATH_KNOBS",
    "SEQUENCER_KNOBS",
    "MOVE_PLANNER_KNOBS",
    "MAX_BATCH_BYTES",
    "knobs_model",
    "knobs_models",
    "knobs_schema",
    "validate_knobs",
    "path_knobs",
    "sequencer_knobs",
    "move_planner_knobs",
    "check_batch_memory",
]


class Knobs(StrictModel):
    """Parameters of one algorithm: unknown names and NaN/inf are rejected."""


# ---- models, from the registry ------------------------------------------------------------
def _annotation(knob: Knob) -> Any:
    """The pydantic type of ``knob``: one of its choices, or its type within its caps; or
    None too when it is optional."""
    if knob.choices is not None:
        tp: Any = Literal[knob.choices]
    elif knob.bounds:
        tp = Annotated[knob.type, Field(**knob.bounds)]
    else:
        tp = knob.type
    return tp | None if knob.optional else tp


def knobs_model(family: str, name: str) -> type[Knobs]:
    """The model of algorithm ``name`` of ``family`` (``planning.registry.knobs``), titled
    ``"<name> <params field>"`` (``"ga params"``, ``"rrt planner_params"``). TypeError naming
    the field when a number of its dataclass has no caps."""
    entry = lookup(family, name)
    title = f"{name} {FAMILIES[family].params_field}"
    spec: dict[str, Any] = {
        k.name: (_annotation(k), Field(k.default, description=k.description))
        for k in knobs(family, name)}
    base = type("Knobs", (Knobs,), {"model_config": ConfigDict(title=title)})
    return create_model(title.replace(" ", "_"), __base__=base,  # type: ignore
                        __doc__=entry.summary or None, **spec)


def knobs_models(family: str) -> dict[str, type[Knobs]]:
    """Name -> model of every algorithm of ``family``."""
    return {name: knobs_model(family, name) for name in algorithm_names(family)}


PATH_KNOBS = knobs_models("path")
SEQUENCER_KNOBS = knobs_models("sequencer")
MOVE_PLANNER_KNOBS = knobs_models("move_planner")
_KNOBS = {"path": PATH_KNOBS, "sequencer": SEQUENCER_KNOBS,
          "move_planner": MOVE_PLANNER_KNOBS}


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


def family_knobs(family: str, name: str, value: dict | None, prefix: str, loc: tuple = ()
                 ) -> dict[str, Any] | None:
    """Params of algorithm ``name`` of a registry family, capped, then built (so the
    algorithm's own cross checks run as well)."""
    value = validate_knobs(_KNOBS[family], name, value, prefix, loc)
    if value is not None:
        make(family, name, value)
    return value


def path_knobs(algorithm: str, value: dict | None, prefix: str = "params", loc: tuple = ()
               ) -> dict[str, Any] | None:
    """A path planner's params, capped, then built."""
    return family_knobs("path", algorithm, value, prefix, loc)


def sequencer_knobs(algorithm: str, value: dict | None, prefix: str = "params"
                    ) -> dict[str, Any] | None:
    """A hole sequencer's params, capped, then built."""
    return family_knobs("sequencer", algorithm, value, prefix)


def move_planner_knobs(planner: str, value: dict | None, prefix: str = "planner_params"
                       ) -> dict[str, Any] | None:
    """A multi-arm move planner's params, capped, then built."""
    return family_knobs("move_planner", planner, value, prefix)


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
    # ``auto`` sizes its own arrays (broad phase, chunked checks): nothing to refuse.
    if not obstacle_types or algorithm not in PATH_KNOBS or algorithm == "auto":
        return
    per_segment = sum(PAIR_BYTES[t] for t in obstacle_types)
    segments = _batch_segments(algorithm, (knobs or {}))
    what = "one batch of candidate paths"
    need = segments * per_segment
    if need > MAX_BATCH_BYTES:
        raise ValueError(
            f"{algorithm}: {what} against {len(obstacle_types)} obstacles would take about "
            f"{need / 2**30:.1f} GiB of memory; at most {MAX_BATCH_BYTES / 2**30:g} GiB: "
            "use a smaller population or fewer waypoints, samples or obstacles "
            f"(boxes cost {math.ceil(PAIR_BYTES['box'] / PAIR_BYTES['sphere'])} times "
            "a sphere)")
