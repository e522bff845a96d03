"""A planning result is described in the library (a dataclass, often with ``to_dict``) and
again at the API edge (the pydantic model a job kind or an endpoint publishes). This test
pins the two descriptions to each other, for every job kind and every synchronous planning
endpoint with a response model: each field is the library's under the same name, or listed
below as the service's own or as one the service does not publish, and the JSON types of
the shared fields agree (a status enum's values are the model's literals). A field added on
one side only fails here until the other side, or the lists, say what became of it."""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import numpy as np
import pytest
from pydantic import BaseModel

from app.api.routes.motion import MotionAnswer, MotionTaskAnswer
from app.jobs import (
    drilling_kinds,
    motion_kinds,
    pallet_kinds,
    path_kinds,
    pile_kinds,
    round_kinds,
    tracking_kinds,
)
from app.jobs.catalog import KINDS
from planning.cycles.pallet import BoxPlan, PalletResult
from planning.cycles.piles import CoverResult, PileOutcome, PilesPlan
from planning.cycles.round import BoomPlan, HolePlan
from planning.cycles.round import RoundResult as RoundPlan
from planning.drilling.multiarm import ArmPlan, FacePlan
from planning.motion import MotionResult, MotionStatus
from planning.motion.task import StepResult, TaskResult
from planning.paths.arm import ArmPathResult
from planning.paths.compare import CompareRow
from planning.paths.planners import PathResult
from planning.sequencing.base import SequenceResult
from planning.status import PlanStatus
from planning.tracking.simulator import TrackingResult
from planning.tracking.tuning import TuningResult


@dataclass(frozen=True)
class Pair:
    """An API model and the library results it is made of. ``service``: the model's fields
    the service adds (not the library's); ``unpublished``: the library's fields and
    ``to_dict`` keys the model leaves out; ``samples``: library results whose ``to_dict``
    the model is picked from (``app.jobs.kinds.pick``); ``reduced``: shared names whose
    published value sums the library's up (its best run's, or a total), of another type."""

    model: type[BaseModel]
    library: tuple[type, ...]
    service: frozenset[str] = frozenset()
    unpublished: frozenset[str] = frozenset()
    reduced: frozenset[str] = frozenset()
    samples: tuple[Any, ...] = field(default=(), compare=False)


def _motion_result() -> MotionResult:
    return MotionResult(MotionStatus.OK, "ok", np.zeros((2, 6)), length=1.0)


def _task_result() -> TaskResult:
    return TaskResult("ok", "ok", np.zeros((2, 6)), [StepResult(0, "move", "ok", "ok", 0, 1,
                                                                "rrt_connect")])


def _path_result() -> PathResult:
    return PathResult(np.zeros((2, 3)), 1.0, 1.0, 0.1, np.zeros(3), "a", 1, PlanStatus.OK,
                      "ok")


def _arm_path_result() -> ArmPathResult:
    return ArmPathResult(_path_result(), np.zeros((2, 3)), np.zeros(2), np.zeros((2, 6)),
                         None, None, None, 1.0, PlanStatus.OK, "ok")


MOTION = Pair(motion_kinds.MotionOut, (MotionResult,), samples=(_motion_result(),))
PAIRS: dict[str, list[Pair]] = {
    # ---- job kinds ----
    "motion": [
        MOTION,
        Pair(motion_kinds.MotionTaskOut, (TaskResult,), samples=(_task_result(),)),
        Pair(motion_kinds.MotionJobResult, (MotionResult, TaskResult),
             service=frozenset({"robot", "joints", "problems", "summary"}),
             samples=(_task_result(),)),
    ],
    "path": [Pair(path_kinds.PathResult, (PathResult, ArmPathResult),
                  service=frozenset({"robot"}),
                  # the arm's own: its tool path (flattened), dense samples and extras
                  unpublished=frozenset({"tool", "points", "s", "q", "extra",
                                         "cylinders_within_stroke"}),
                  samples=(_arm_path_result(),))],
    "path_compare": [Pair(path_kinds.CompareRow, (CompareRow,),
                          samples=(CompareRow("a", 2, 1, 1.0, 1.0, 1.0, 0.1, 10.0),))],
    "sequence": [Pair(drilling_kinds.SequenceResult, (SequenceResult,),
                      service=frozenset({"length_m", "convergence", "seed", "cost",
                                         "boom_time_s", "boom_time_distance_order_s",
                                         "boom_time_saved_s", "distance_order",
                                         "distance_order_length", "rolls", "q"}),
                      # history is published as convergence; budget_spent in message
                      unpublished=frozenset({"history", "budget_spent", "extra"}))],
    "multiarm": [
        Pair(drilling_kinds.MultiarmResult, (FacePlan,),
             service=frozenset({"rig", "success", "notes", "min_distance_overall",
                                "collisions_by_pair", "travel_m", "total_travel_m", "cost",
                                "boom_time_s", "boom_time_distance_order_s",
                                "boom_time_saved_s", "acceleration_bound", "check_dt",
                                "samples"}),
             unpublished=frozenset({"allocation", "q", "status", "accelerations", "extras"}),
             # the total over the pairs; per pair in collisions_by_pair
             reduced=frozenset({"collisions"})),
        Pair(drilling_kinds.MultiarmArm, (ArmPlan,),
             service=frozenset({"holes", "hole_ids", "q", "move_starts_s", "end_s",
                                "travel_m", "peak_acceleration",
                                "max_rotational_acceleration", "boom_time_s",
                                "boom_time_distance_order_s"}),
             unpublished=frozenset({"name", "order", "sequence", "timeline",
                                    "tool_path_m"})),
    ],
    "tracking": [Pair(tracking_kinds.TrackingResult, (TrackingResult, TuningResult),
                      service=frozenset({"robot", "task", "controller", "tune", "mean_error",
                                         "max_error", "std_error", "kp", "ki", "seed",
                                         "x_actual", "errors", "joint_speed_max",
                                         "fitness_history", "runs", "summary"}),
                      unpublished=frozenset({"error", "error_xyz", "qd", "fitness", "gains",
                                             "optim"}),
                      # the best run's, of the library's one per gain candidate
                      reduced=frozenset({"saturated_steps", "q"}))],
    "pallet": [
        Pair(pallet_kinds.PalletJobResult, (PalletResult,),
             service=frozenset({"robot", "joints", "per_layer", "placed", "total",
                                "pallet_size", "pallet_pose", "box_size"}),
             # the robot's first configuration and the grasp stay in the library
             unpublished=frozenset({"start", "T_tool_box"}),
             # the pattern by its name
             reduced=frozenset({"pattern"})),
        Pair(pallet_kinds.PalletBoxOut, (BoxPlan,),
             service=frozenset({"carry_states", "return_states"}),
             # the tasks themselves (their paths) and the place (as position and yaw)
             unpublished=frozenset({"carry", "back", "place"})),
    ],
    "round": [
        Pair(round_kinds.RoundResult, (RoundPlan,),
             service=frozenset({"rig", "ratio", "priority"}), unpublished=frozenset({"stats"})),
        Pair(round_kinds.RoundBoom, (BoomPlan,),
             service=frozenset({"t", "q", "phases", "end_s"}),
             unpublished=frozenset({"name", "timeline", "park"})),
        Pair(round_kinds.RoundHolePlan, (HolePlan,), unpublished=frozenset({"q_collar"})),
    ],
    "piles": [
        Pair(pile_kinds.PilesResult, (PilesPlan,),
             service=frozenset({"robot", "piles_total", "piles_reached", "unreached",
                                "cycle_time_s", "per_pile_s", "max_axis_error",
                                "max_position_error"}),
             # the plan itself, the candidates' table and the times per set-up (published
             # in setups); total_s is cycle_time_s
             unpublished=frozenset({"plan", "candidates", "table", "setup_times",
                                    "total_s"})),
        Pair(pile_kinds.PileOut, (PileOutcome,), service=frozenset({"id"}),
             # the plan's index (published as id), the lift (as long as lower_s), the
             # reason of an unreached pile (published in unreached)
             unpublished=frozenset({"index", "lift_s", "reason"})),
        Pair(pile_kinds.CoverOut, (CoverResult,), service=frozenset({"setups", "candidates"}),
             # the chosen candidates (published in setups)
             unpublished=frozenset({"chosen"})),
    ],
    # Kinds whose result is no planning result: diagnostics, and kinematics' own.
    "sleep": [], "echo": [], "workspace": [], "calibrate": [], "ik_train": [],
    # ---- synchronous planning endpoints with a response model ----
    "POST /robots/{robot_id}/motion": [
        MOTION,
        Pair(MotionAnswer, (MotionResult,), service=frozenset({"robot", "joints"}),
             samples=(_motion_result(),)),
        Pair(MotionTaskAnswer, (TaskResult,), service=frozenset({"robot", "joints"}),
             samples=(_task_result(),)),
    ],
}

ALL_PAIRS = [p for pairs in PAIRS.values() for p in pairs]
IDS = [f"{p.model.__name__}-{'+'.join(c.__name__ for c in p.library)}" for p in ALL_PAIRS]


def test_every_kind_is_paired_or_said_to_have_no_planning_result():
    assert set(KINDS) <= set(PAIRS), sorted(set(KINDS) - set(PAIRS))


#: Planning endpoints that publish no response model (their answers are built as dicts).
UNTYPED = {"GET /robots/{robot_id}/collision", "POST /robots/{robot_id}/collision",
           "POST /trajectories", "POST /trajectories/plot", "POST /trajectories/cartesian",
           "POST /robots/{robot_id}/motion/replay.html"}  # an HTML page
PLANNING_TAGS = {"motion", "collision", "trajectories"}


def test_every_planning_endpoint_with_a_response_model_is_paired(client):
    typed = {}
    for path, operations in client.app.openapi()["paths"].items():
        for method, op in operations.items():
            if not PLANNING_TAGS & set(op.get("tags", ())):
                continue
            name = f"{method.upper()} {path}"
            schema = op["responses"].get("200", {}).get("content", {}).get(
                "application/json", {}).get("schema") or {}
            # One model, or one of several (a union of models, each of them paired).
            refs = [schema] if "$ref" in schema else schema.get("anyOf", [])
            if refs and all("$ref" in r for r in refs):
                typed[name] = {r["$ref"].rsplit("/", 1)[-1] for r in refs}
            else:
                assert name in UNTYPED, f"{name} answers {schema}: pair it or list it"
    assert typed and set(typed) <= set(PAIRS)
    for name, models in typed.items():
        assert models <= {p.model.__name__ for p in PAIRS[name]}


def _library_fields(classes: tuple[type, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for cls in classes:
        hints = typing.get_type_hints(cls)
        out.update({f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls)})
    return out


@pytest.mark.parametrize("pair", ALL_PAIRS, ids=IDS)
def test_the_model_publishes_the_library_fields_and_says_what_it_adds(pair):
    model = set(pair.model.model_fields)
    library = set(_library_fields(pair.library))
    for sample in pair.samples:
        library |= set(sample.to_dict())
    assert pair.service <= model and not pair.service & library, "service fields"
    assert pair.unpublished <= library and not pair.unpublished & model, "unpublished"
    assert pair.reduced <= model & library, "reduced"
    assert model - pair.service == library - pair.unpublished


@pytest.mark.parametrize("pair", [p for p in ALL_PAIRS if p.samples], ids=[
    i for i, p in zip(IDS, ALL_PAIRS) if p.samples])
def test_to_dict_gives_every_field_the_model_picks_from_it(pair):
    for sample in pair.samples:
        keys = set(sample.to_dict())
        assert set(pair.model.model_fields) - pair.service <= keys
        assert keys - set(pair.model.model_fields) <= pair.unpublished


# ---- JSON types ----------------------------------------------------------------------------
def json_types(tp: Any) -> set[str] | None:
    """The JSON types a Python annotation is written as (None: not derivable, e.g. Any)."""
    origin, args = get_origin(tp), get_args(tp)
    if origin is Annotated:
        return json_types(args[0])
    if origin in (Union, types.UnionType):
        parts = [json_types(a) for a in args]
        return None if any(p is None for p in parts) else set().union(*parts)
    if origin is Literal:
        return {"boolean" if isinstance(a, bool) else "string" if isinstance(a, str)
                else "integer" if isinstance(a, int) else "null" for a in args}
    base = origin or tp
    if base is type(None):
        return {"null"}
    if not isinstance(base, type):
        return None
    if issubclass(base, bool | np.bool_):
        return {"boolean"}
    if issubclass(base, int):
        return {"integer"}
    if issubclass(base, float):
        return {"number"}
    if issubclass(base, enum.Enum | str):
        return {"string"}
    if issubclass(base, list | tuple | np.ndarray):
        return {"array"}
    if issubclass(base, dict):
        return {"object"}
    if issubclass(base, BaseModel) or dataclasses.is_dataclass(base):
        return {"object"}
    return None


def test_json_types_of_annotations():
    assert json_types(float | None) == {"number", "null"}
    assert json_types(np.ndarray) == json_types(list[float]) == {"array"}
    assert json_types(MotionStatus) == json_types(Literal["ok", "no_path"]) == {"string"}
    assert json_types(Any) is None


@pytest.mark.parametrize("pair", ALL_PAIRS, ids=IDS)
def test_shared_fields_have_the_same_json_types(pair):
    library = _library_fields(pair.library)
    checked = 0
    for name, info in pair.model.model_fields.items():
        if name not in library or name in pair.reduced:
            continue
        ours, theirs = json_types(info.annotation), json_types(library[name])
        if ours is None or theirs is None:
            continue
        checked += 1
        if "number" in ours:
            ours = ours | {"integer"}
        assert theirs - {"null"} <= ours, f"{name}: {theirs} published as {ours}"
        status = library[name]
        if isinstance(status, type) and issubclass(status, enum.Enum):
            literal = [a for a in get_args(info.annotation) if get_origin(a) is Literal]
            if get_origin(info.annotation) is Literal:
                literal = [info.annotation]
            if literal:
                assert set(get_args(literal[0])) == {s.value for s in status}, name
    assert checked or not set(pair.model.model_fields) & set(library)


def test_the_motion_status_literal_is_checked_against_the_enum():
    # The check above compares MotionOut.status with MotionStatus: it sees a missing value.
    field_type = motion_kinds.MotionOut.model_fields["status"].annotation
    assert set(get_args(field_type)) == {s.value for s in MotionStatus}
    assert set(get_args(Literal["ok", "timeout"])) != {s.value for s in MotionStatus}
