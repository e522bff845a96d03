"""Every algorithm a caller picks by name, in one place: per family, name -> parameter dataclass.

* ``path``: ``plan_path``'s ``algorithm`` (parameters ``params``): the metaheuristics of
  ``planning.optimisers`` ``wolfpack_improved``, ``wolfpack``, ``ga``, ``aca``, ``afsa``, and
  ``rrt_star`` and ``auto`` (``planning.paths.auto``);
* ``sequencer``: ``sequence_holes``' ``algorithm`` (``params``) and ``plan_face``'s
  ``sequencer`` (``sequencer_params``): ``iga``, ``aco``, ``aga``, ``auto``;
* ``move_planner``: ``plan_face``'s ``planner`` (``planner_params``): ``iapf``, ``rrt``;
* ``tuner``: ``tune_gains``' ``tuner`` (``tuner_params``): ``hgso``, ``pso``, ``ga``,
  ``aco``, ``gwo``.

A name is unique within its family and means one algorithm there; the same name in two
families is read in its own family only. ``aco`` is the ant colony hole sequencer (Ant
System, paper 002) among sequencers and ACO_R, the ant colony for continuous variables
(paper 003), among tuners; the path planners' ant colony is ``aca`` (paper 000). ``auto`` is
each family's own near-optimal method (visibility graph for paths, dynamic programming and
local search for hole orders). ``ga`` is the same genetic algorithm in ``path`` (paper 000's
settings) and ``tuner`` (paper 003's). Each ``Algorithm`` has a one-line ``summary`` saying
which it is.

Each tunable field of a parameter dataclass declares its caps as field metadata::

    iterations: int = field(default=50, metadata={"ge": 1, "le": 10_000,
                                                  "description": "..."})

``ge``/``gt`` a lower and ``le``/``lt`` an upper bound (every number has both), ``choices``
the values of a string field, ``description`` a few words. The caps are what a service may
accept (the REST API builds its request models and their published schemas from them, so
adding an algorithm here is all it takes for the API to accept it); the library itself
takes any value the dataclass's own checks accept.

``make(family, name, params)`` builds an algorithm's dataclass with ``params`` overriding
its defaults; an unknown name or parameter, or values that do not go together, raise
``FieldError`` at the family's fields (``algorithm``, ``params.<name>``, ``planner``, ...).
Classes load on first use: importing this module costs nothing. The built-in algorithms are
registered by ``planning.catalog`` (the package imports it first), which sits above every
module it names; this module imports none of them.
"""

from __future__ import annotations

import dataclasses
import importlib
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from kinematics.errors import FieldError

__all__ = [
    "FAMILIES",
    "Algorithm",
    "Family",
    "Knob",
    "MetaheuristicParams",
    "ShortcutParams",
    "AutoPlannerParams",
    "RRTStarParams",
    "algorithm_classes",
    "algorithm_names",
    "dataclass_knobs",
    "knobs",
    "lookup",
    "make",
    "register",
]


# ---- knobs plan_path takes besides the algorithm's own -------------------------------------
@dataclass(frozen=True)
class ShortcutParams:
    """What ``plan_path`` does with every planner's path (``planning.paths.encoding.shortcut``)."""

    shortcut: bool = field(default=True, metadata={"description": "shorten the found path"})
    random_shortcuts: int = field(default=100, metadata={
        "ge": 0, "le": 10_000, "description": "random shortcuts tried after the greedy pass"})


@dataclass(frozen=True)
class MetaheuristicParams(ShortcutParams):
    """What ``plan_path`` takes for every metaheuristic besides its optimiser's own: the
    encoding (``planning.paths.encoding.PathEncoding``), the penalised cost and the
    evaluation budget."""

    waypoints: int = field(default=5, metadata={
        "ge": 1, "le": 50, "description": "intermediate waypoints of the encoding"})
    penalty: float = field(default=1000.0, metadata={
        "gt": 0.0, "le": 1e9, "description": "mm of length per mm of penetration"})
    max_evaluations: int | None = field(default=None, metadata={
        "ge": 1, "le": 100_000_000, "description": "evaluation budget"})


# ---- the path planners that are not metaheuristics (``planning.paths.auto``) --------------
@dataclass(frozen=True)
class AutoPlannerParams:
    """Options of ``planning.paths.auto.plan_auto`` (its defaults)."""

    samples: int = field(default=150, metadata={
        "ge": 4, "le": 2000, "description": "surface samples per obstacle"})
    rel_offset: float = field(default=0.02, metadata={
        "gt": 0.0, "le": 1.0, "description": "offset of the samples / obstacle size"})
    rounds: int = field(default=1, metadata={
        "ge": 0, "le": 20, "description": "tightening rounds"})


@dataclass(frozen=True)
class RRTStarParams:
    """Options of ``planning.paths.auto.plan_rrt_star`` (its defaults)."""

    samples: int = field(default=3000, metadata={"ge": 1, "le": 20_000})
    step: float | None = field(default=None, metadata={
        "gt": 0.0, "le": 1e8, "description": "mm; default a tenth of the scene's diagonal"})
    goal_bias: float = field(default=0.05, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    gamma: float | None = field(default=None, metadata={
        "gt": 0.0, "le": 1e9, "description": "mm; default twice the scene's diagonal"})
    time_limit: float | None = field(default=None, metadata={
        "gt": 0.0, "le": 3600.0, "description": "s"})


# ---- the registry ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Algorithm:
    """One algorithm: its parameter dataclass (``source``: the class, or ``(module, class
    name)`` loaded on first use), the classmethod giving its defaults (``preset``; None: the
    class defaults), the dataclass of the knobs its family's entry point takes besides its
    own (``shared``), and a one-line ``summary``."""

    family: str
    name: str
    source: type | tuple[str, str]
    preset: str | None = None
    shared: type | None = None
    summary: str = ""

    @property
    def params(self) -> type:
        """The parameter dataclass."""
        if isinstance(self.source, type):
            return self.source
        module, name = self.source
        return getattr(importlib.import_module(module), name)

    def defaults(self) -> Any:
        """The dataclass with the algorithm's defaults (its preset's, if any)."""
        cls = self.params
        return getattr(cls, self.preset)() if self.preset else cls()


@dataclass(frozen=True)
class Family:
    """Algorithms picked by the same argument: ``name_field`` names the choice and
    ``params_field`` the parameters (the fields an error names); ``shared``: the knobs its
    entry point takes for every algorithm that does not say otherwise."""

    name: str
    summary: str
    name_field: str
    params_field: str
    shared: type | None = None
    algorithms: dict[str, Algorithm] = field(default_factory=dict)


#: Family name -> family; each family's ``algorithms`` maps name -> ``Algorithm``.
FAMILIES: dict[str, Family] = {f.name: f for f in (
    Family("path", "obstacle-avoiding tool paths (planning.paths.plan_path)", "algorithm",
           "params", MetaheuristicParams),
    Family("sequencer", "drilling order of a face's holes (planning.sequencing)", "algorithm",
           "params"),
    Family("move_planner", "joint-space moves between holes of a multi-arm jumbo "
           "(planning.drilling.multiarm)", "planner", "planner_params"),
    Family("tuner", "PI gain tuners of the tracking controller (planning.tracking)", "tune",
           "tuner_params"),
)}


def _family(family: str) -> Family:
    try:
        return FAMILIES[family]
    except KeyError:
        raise ValueError(f"no algorithm family {family!r}; families: "
                         f"{', '.join(FAMILIES)}") from None


def register(family: str, name: str, params: type | tuple[str, str], *,
             preset: str | None = None, shared: type | None = None,
             summary: str = "") -> Algorithm:
    """Add algorithm ``name`` to ``family`` with parameter dataclass ``params`` (or its
    ``(module, class name)``); ``shared`` defaults to the family's. ValueError if the family
    already has that name."""
    fam = _family(family)
    if not isinstance(name, str) or not name:
        raise ValueError(f"{family}: an algorithm name must be a non-empty string")
    if name in fam.algorithms:
        raise ValueError(f"{family} already has an algorithm {name!r}")
    entry = Algorithm(family, name, params, preset, shared or fam.shared, summary)
    fam.algorithms[name] = entry
    return entry


def algorithm_names(family: str) -> tuple[str, ...]:
    """The names of ``family``'s algorithms, in registration order."""
    return tuple(_family(family).algorithms)


def algorithm_classes(family: str) -> dict[str, type]:
    """``family``'s algorithms: name -> parameter dataclass (loads them)."""
    return {name: a.params for name, a in _family(family).algorithms.items()}


def lookup(family: str, name: str) -> Algorithm:
    """Algorithm ``name`` of ``family``; ``FieldError`` at the family's name field (e.g.
    ``algorithm``, ``planner``) if it has none of that name."""
    fam = _family(family)
    entry = fam.algorithms.get(name) if isinstance(name, str) else None
    if entry is None:
        raise FieldError(fam.name_field, f"{fam.name_field}: must be one of "
                         f"{', '.join(fam.algorithms)}, got {name!r}")
    return entry


@dataclass(frozen=True)
class Knob:
    """One tunable field: ``type`` bool, int, float or str (``optional``: None allowed too,
    the algorithm then picks), its ``default``, its caps (``bounds``: ``ge``/``gt`` and
    ``le``/``lt``), the ``choices`` of a string and a ``description``."""

    name: str
    type: type
    default: Any
    optional: bool = False
    bounds: Mapping[str, float] = field(default_factory=dict)
    choices: tuple[str, ...] | None = None
    description: str | None = None


_KNOB_TYPES = (bool, int, float, str)
_LOWER, _UPPER = ("ge", "gt"), ("le", "lt")


def _knob(cls: type, f: dataclasses.Field, hint: Any, default: Any) -> Knob:
    where = f"{cls.__name__}.{f.name}"
    args = typing.get_args(hint) if typing.get_origin(hint) in (
        typing.Union, types.UnionType) else (hint,)
    kinds = [a for a in args if a is not type(None)]
    if len(kinds) != 1 or kinds[0] not in _KNOB_TYPES:
        raise TypeError(f"{where}: a knob is bool, int, float or str (or one of them | None), "
                        f"not {hint}")
    kind = kinds[0]
    meta = f.metadata
    bounds = {k: meta[k] for k in (*_LOWER, *_UPPER) if k in meta}
    choices = tuple(meta["choices"]) if "choices" in meta else None
    if kind in (int, float) and not (set(_LOWER) & set(bounds) and set(_UPPER) & set(bounds)):
        raise TypeError(f"{where}: no cap; its field metadata needs a lower (ge or gt) and an "
                        "upper (le or lt) bound")
    if kind is str and not choices:
        raise TypeError(f"{where}: a string knob lists its choices in its field metadata")
    return Knob(f.name, kind, default, len(kinds) < len(args), bounds, choices,
                meta.get("description"))


def dataclass_knobs(cls: type, defaults: Any = None) -> tuple[Knob, ...]:
    """The knobs of parameter dataclass ``cls`` (its init fields), with the defaults of
    instance ``defaults`` (None: the class's). TypeError naming the field when a number has
    no caps, a string no choices, or a field another type."""
    defaults = cls() if defaults is None else defaults
    hints = typing.get_type_hints(cls)
    return tuple(_knob(cls, f, hints[f.name], getattr(defaults, f.name))
                 for f in dataclasses.fields(cls) if f.init)


def knobs(family: str, name: str) -> tuple[Knob, ...]:
    """Every knob algorithm ``name`` of ``family`` takes: its dataclass's, then its family's
    shared ones."""
    entry = lookup(family, name)
    out = dataclass_knobs(entry.params, entry.defaults())
    if entry.shared is not None:
        out += dataclass_knobs(entry.shared)
    return out


def make(family: str, name: str, params: Mapping[str, Any] | None = None) -> Any:
    """Algorithm ``name`` of ``family``: its parameter dataclass with ``params`` overriding
    its defaults (the shared knobs of its family are accepted and left out).

    ``FieldError`` at the family's name field for an unknown name, at ``<params
    field>.<key>`` for an unknown parameter, and at the params field when the values do not
    go together (the dataclass's own checks may name the parameter themselves)."""
    entry = lookup(family, name)
    field_name = FAMILIES[family].params_field
    cls = entry.params
    own = {f.name for f in dataclasses.fields(cls) if f.init}
    shared = {f.name for f in dataclasses.fields(entry.shared) if f.init} \
        if entry.shared is not None else set()
    params = dict(params or {})
    for key in params:
        if key not in own and key not in shared:
            raise FieldError((field_name, key), f"{field_name}.{key} is not a parameter of "
                             f"{name}; known: {', '.join(sorted(own | shared))}")
    try:
        return dataclasses.replace(entry.defaults(),
                                   **{k: v for k, v in params.items() if k in own})
    except FieldError:
        raise
    except (TypeError, ValueError) as exc:
        raise FieldError(field_name, f"{field_name}: {exc}") from None
