"""Job kinds ``sequence`` (drilling order of a face's holes) and ``multiarm`` (a whole face
for a multi-arm jumbo: allocation, sequencing and collision-free moves), paper 002.

Holes are validated here, at the API edge, so a bad hole list is a 422 naming the field and
the hole (``holes[7]: duplicate of holes[2]``, ``holes.left[3]: ... out of reach of the left
arm``): field validators reuse the messages of ``planning.sequencing.check_holes`` and
``planning.drilling.allocation``. Neither kind needs a robot (``needs_robot=False``):
``multiarm`` names a built-in rig. The algorithms' free-form parameters are checked against
their bounded models (``planner_params``): every knob capped, 422 naming it.

``multiarm``'s holes are allocated to the arms once per process, by the params' own check
(``MultiarmParams.allocation()``), with the params' ``balance`` and ``counts``: what the check
accepts is exactly what the run plans.

``sequence`` with ``auto`` divides (``sequence_graph``): the search's runs (each from its own
start hole and generator) are steps, and a last step makes the answer of them
(``planning.sequencing.Auto.combine``): the order, length and history one process finds
when the kick budget, the runs or stalls end the search. Each run has the time limit of its
own (one process shares one among its runs); a run stopped by it ends the search, as the
time limit does in one process, and makes the answer depend on the machine's speed.

Importing this module readies the compiled sequencing search (``planning.warm``'s
``sequencing`` part, ``oropt.warm_up``: numba's
cache loaded in about 0.2 s, or the search compiled, some 15-25 s, the first time on a
machine), so no job pays for it: the local job backend's workers fork from a server that
imported this module.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    WithJsonSchema,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from kinematics.numbers import finite_or_none
from planning.registry import algorithm_names

from ..fields import Point3 as Vec3
from ..fields import StrictModel
from .graph import Ref, Step, run_inline
from .kinds import MAX_SEED, XYZ, JobKind, Params, Progress, Result, absent_when_none, register
from .planner_params import (
    MOVE_PLANNER_KNOBS,
    SEQUENCER_KNOBS,
    knobs_schema,
    move_planner_knobs,
    sequencer_knobs,
)

__all__ = ["SequenceParams", "SequenceResult", "MultiarmParams", "MultiarmResult",
           "run_sequence", "sequence_graph", "run_multiarm", "SEQUENCER_READY_S"]


def _ready_sequencer() -> float:
    """Compile or load the sequencing search once per process; seconds it took."""
    from planning.warm import warm_up

    return warm_up(["sequencing"]).total_seconds


#: Seconds this process spent readying the compiled sequencing search at import.
SEQUENCER_READY_S = _ready_sequencer()

#: Most holes one job takes (sequence) / one face (multiarm).
MAX_HOLES = 2000
MAX_FACE_HOLES = 600
#: The hole sequencers and the move planners: the ``sequencer`` and ``move_planner``
#: families of ``planning.registry``.
Algorithm = Literal[algorithm_names("sequencer")]  # type: ignore[valid-type]
Planner = Literal[algorithm_names("move_planner")]  # type: ignore[valid-type]
#: What a drilling order minimises (``planning.drilling.boom_time.COSTS``).
Cost = Literal["distance", "time"]
COST_DESCRIPTION = ("What the order minimises: 'distance' (tool path, mm) or 'time' (the "
                    "boom's travel time between holes in joint space, each hole's IK branch "
                    "chosen with the order)")

#: JSON schemas of the free-form algorithm parameters: one bounded model per algorithm.
SequencerKnobs = Annotated[dict[str, Any] | None, WithJsonSchema(knobs_schema(
    SEQUENCER_KNOBS, "Sequencer parameters (defaults: paper 002's), by algorithm; see "
    "planning.sequencing"))]
PlannerKnobs = Annotated[dict[str, Any] | None, WithJsonSchema(knobs_schema(
    MOVE_PLANNER_KNOBS, "Move planner parameters, by planner; see planning.drilling"))]


def _sequencer_params(v, algorithm, prefix: str = "params"):
    if v is None or algorithm is None:
        return v
    return sequencer_knobs(algorithm, v, prefix)


def _check_rig(v: str) -> str:
    from kinematics.rigs import BUILTIN_RIG_IDS

    if v not in BUILTIN_RIG_IDS:
        raise ValueError(f"unknown rig {v!r}; built-in: {', '.join(BUILTIN_RIG_IDS)}")
    return v


# ---- sequence --------------------------------------------------------------------------------
class SequenceParams(Params):
    holes: list[Vec3] = Field(min_length=2, max_length=MAX_HOLES,
                              description="Holes [[x, y, z], ...] mm")
    start: Vec3 | None = Field(None, description="Where the drill starts (mm); default: the "
                                                 "first hole, drilled first")
    algorithm: Algorithm = "auto"
    seed: int = Field(0, ge=0, le=MAX_SEED)
    params: SequencerKnobs = None
    cost: Cost = Field("distance", description=COST_DESCRIPTION)
    rig: str = Field("tunnel_jumbo", description="Built-in rig of the drilling arm (cost "
                     "'time'); holes and start in its frame")
    arm: str = Field("middle", description="The rig's arm that drills (cost 'time')")

    @field_validator("holes")
    @classmethod
    def _holes(cls, v):
        from planning.sequencing import check_holes

        check_holes(v, "holes")
        return v

    @field_validator("params")
    @classmethod
    def _params(cls, v, info: ValidationInfo):
        return _sequencer_params(v, info.data.get("algorithm"))

    @field_validator("rig")
    @classmethod
    def _rig(cls, v):
        return _check_rig(v)

    @model_validator(mode="after")
    def _arm_reaches(self):
        """With cost 'time': the arm exists and reaches every hole (and the start) drilling
        perpendicular to the face in its default posture (roll 0)."""
        if self.cost != "time":
            return self
        from kinematics.drilling import drill_ik
        from kinematics.rigs import builtin_rig

        rig = builtin_rig(self.rig)
        if self.arm not in rig.arms:
            raise _error_at("arm", ValueError(f"arm: rig {self.rig!r} has no arm "
                                              f"{self.arm!r} (arms: {', '.join(rig.arms)})"))
        model = rig.arms[self.arm]
        for k, r in enumerate(drill_ik(model, self.holes)):
            if not r.success:
                raise _error_at(("holes", k), ValueError(
                    f"holes[{k}]: out of reach of the {self.arm} arm: "
                    f"{r.message.split(': ', 1)[-1]}"))
        if self.start is not None:
            r = drill_ik(model, self.start)[0]
            if not r.success:
                raise _error_at("start", ValueError(
                    f"start: the {self.arm} arm cannot drill there: "
                    f"{r.message.split(': ', 1)[-1]}"))
        return self


class SequenceResult(Result):
    """A drilling order: an open path from ``start`` (or the first hole) through every hole."""

    order: list[int] = Field(description="Hole indices (into params.holes) in drilling order")
    length: float = Field(description="mm, from the start")
    length_m: float = Field(description="m")
    runtime_s: float
    convergence: list[float] = Field(description="Best length after each iteration, mm")
    algorithm: str = Field(description="The algorithm that ran ('auto' names its method in "
                           "message)")
    iterations: int
    evaluations: int
    message: str
    seed: int
    cost: Cost = Field("distance", description="What the order minimises")
    boom_time_s: float | None = absent_when_none(
        "Cost 'time': the boom's travel time along this order, s")
    boom_time_distance_order_s: float | None = absent_when_none(
        "Cost 'time': the boom's travel time along the shortest-path order (each hole's "
        "branch chosen for it), s")
    boom_time_saved_s: float | None = absent_when_none(
        "Cost 'time': boom_time_distance_order_s - boom_time_s")
    distance_order: list[int] | None = absent_when_none(
        "Cost 'time': the shortest-path order compared with")
    distance_order_length: float | None = absent_when_none(
        "Cost 'time': its tool path length, mm")
    rolls: list[float] | None = absent_when_none(
        "Cost 'time': the roll joint (rad) of each hole's IK branch, in drilling order")
    q: list[list[float]] | None = absent_when_none(
        "Cost 'time': the arm's configuration at each hole, in drilling order (rad / mm)")


def _auto_search(params: SequenceParams) -> tuple[Any, Any] | None:
    """``(Auto, SequencingProblem)`` of a job whose ``auto`` search makes several runs
    (cost 'distance', more holes than it solves exactly), else None."""
    if params.cost != "distance" or params.algorithm != "auto":
        return None
    from planning.sequencing import SequencingProblem, make_sequencer

    auto = make_sequencer("auto", params.params)
    problem = SequencingProblem.from_holes(params.holes, params.start)
    if auto.exact_for(problem) or auto.max_runs(problem.n) < 2:
        return None
    return auto, problem


#: Share of the ``auto`` search's most runs that a sequence job starts at once; the others
#: start once these are known (with the kicks they leave), or not at all when they end it.
FIRST_RUNS_SHARE = 0.4


def sequence_graph(params: SequenceParams) -> list[Step]:
    """The steps of a sequence job: the ``auto`` search's runs (each from its own start hole
    and generator, ``planning.sequencing.Auto.search_run``), a step each, as many as its
    budgets allow: the first ``FIRST_RUNS_SHARE`` of them at once, the others after those
    (skipped when the search ends before them); and a step that makes the answer of them
    (``Auto.combine``: the order one process finds when the kick budget, the runs or stalls
    end the search). Any other job in one step."""
    search = _auto_search(params)
    if search is None:
        return [Step(run_sequence_whole)]
    auto, problem = search
    n, stall = problem.n, auto.stall_budget(problem.n)
    runs = auto.max_runs(n)
    first = min(runs, max(2, math.ceil(FIRST_RUNS_SHARE * runs)))
    # a run stalls after one to a few stall budgets of kicks; a later one may not run; the
    # last step may run one again
    weights = [max(1, min(auto.run_cap(n, r), 2 * stall)) for r in range(runs)]
    steps = [Step(sequence_run_step, (r,), weight=weights[r],
                  label=f"run {r + 1} of at most {runs}") for r in range(first)]
    steps += [Step(sequence_later_run_step, (r, [Ref(i) for i in range(first)]),
                   weight=weights[r] / 2, label=f"run {r + 1} of at most {runs}")
              for r in range(first, runs)]
    steps.append(Step(sequence_result_step, ([Ref(r) for r in range(runs)],),
                      weight=stall, label="shortest of the runs"))
    return steps


def sequence_run_step(params: SequenceParams, index: int, progress: Progress) -> Any:
    """Run ``index`` of the ``auto`` search: a ``planning.sequencing.auto.SearchRun``."""
    auto, problem = _auto_search(params)
    return auto.search_run(problem, params.seed, index,
                           progress=lambda f: progress(f, "searching"))


def sequence_later_run_step(params: SequenceParams, index: int, earlier: list,
                            progress: Progress) -> Any:
    """Run ``index`` of the ``auto`` search with the kicks the ``earlier`` runs leave it,
    or None when the search ends before it."""
    auto, problem = _auto_search(params)
    cap = auto.run_cap(problem.n, index, earlier)
    if cap is None:
        progress(1.0, "not needed")
        return None
    return auto.search_run(problem, params.seed, index, cap,
                           progress=lambda f: progress(f, "searching"))


def sequence_result_step(params: SequenceParams, runs: list, progress: Progress
                         ) -> SequenceResult:
    """The shortest order of the runs, as the ``auto`` search picks it."""
    auto, problem = _auto_search(params)
    res = auto.combine(problem, runs, params.seed, progress=lambda f: progress(f, "combining"))
    progress(1.0, "done")
    return _sequence_result(params, res)


def run_sequence_whole(params: SequenceParams, progress: Progress) -> SequenceResult:
    """Drilling order of the holes in one step: an open path from ``start`` (or the first
    hole)."""
    if params.cost == "time":
        return _run_sequence_by_time(params, progress)
    from planning.sequencing import sequence_holes

    res = sequence_holes(params.holes, params.start, params.algorithm, params.seed,
                         params.params, progress=lambda f: progress(0.99 * f, "sequencing"))
    progress(1.0, "done")
    return _sequence_result(params, res)


def _sequence_result(params: SequenceParams, res: Any) -> SequenceResult:
    return SequenceResult(
        order=res.order.tolist(),
        length=res.length,
        length_m=res.length / 1000.0,
        runtime_s=res.runtime_s,
        convergence=res.history.tolist(),
        algorithm=res.algorithm,
        iterations=res.iterations,
        evaluations=res.evaluations,
        message=res.message,
        seed=params.seed,
    )


def run_sequence(params: SequenceParams, progress: Progress) -> SequenceResult:
    """Drilling order of the holes: an open path from ``start`` (or the first hole); see
    ``sequence_graph``."""
    return run_inline(sequence_graph(params), params, progress)


def _run_sequence_by_time(params: SequenceParams, progress: Progress) -> SequenceResult:
    """The order (and IK branches) of least boom travel time, beside the shortest path's."""
    from kinematics.rigs import builtin_rig
    from planning.drilling.boom_time import sequence_by_boom_time
    from planning.sequencing import sequence_holes

    progress(0.0, "shortest path")
    dist = sequence_holes(params.holes, params.start, params.algorithm, params.seed,
                          params.params)
    progress(0.3, "IK branches and boom time")
    model = builtin_rig(params.rig).arms[params.arm]
    res = sequence_by_boom_time(model, params.holes, start=params.start,
                                algorithm=params.algorithm, params=params.params,
                                seed=params.seed, distance_order=dist.order)
    progress(1.0, "done")
    return SequenceResult(
        order=res.order.tolist(),
        length=res.length,
        length_m=res.length / 1000.0,
        runtime_s=dist.runtime_s + res.runtime_s,
        convergence=[res.length],
        algorithm=params.algorithm,
        iterations=res.rounds,
        evaluations=dist.evaluations,
        message=f"least boom time {res.time_s:.1f} s, {res.saved_s:.1f} s less than the "
                f"shortest path's order ({res.distance_time_s:.1f} s); {res.rounds} rounds "
                "of order and branches",
        seed=params.seed,
        cost="time",
        boom_time_s=res.time_s,
        boom_time_distance_order_s=res.distance_time_s,
        boom_time_saved_s=res.saved_s,
        distance_order=res.distance_order.tolist(),
        distance_order_length=res.distance_length,
        rolls=res.roll.tolist(),
        q=res.q.tolist(),
    )


register(JobKind("sequence", SequenceParams, SequenceResult, run_sequence,
                 "Drilling order of a face's holes (open path, IGA / ACO / AGA / auto), by "
                 "tool path or by boom travel time", graph=sequence_graph))


# ---- multiarm --------------------------------------------------------------------------------
class FaceIn(StrictModel):
    """A generated face (``planning.drilling.patterns.FacePattern``), mm."""

    shape: Literal["horseshoe", "circular"] = "horseshoe"
    width: float = Field(10_000.0, gt=0, le=50_000)
    height: float = Field(8_000.0, gt=0, le=50_000)
    spacing: float = Field(500.0, ge=10, le=10_000, description="Contour hole spacing")
    face_x: float = Field(9_000.0, ge=-1e6, le=1e6, description="Face distance")
    center_y: float = Field(0.0, ge=-1e6, le=1e6)
    floor_z: float = Field(-1_500.0, ge=-1e6, le=1e6)

    @model_validator(mode="after")
    def _valid(self):
        from planning.drilling.patterns import FacePattern

        FacePattern(**self.model_dump())
        return self


class MultiarmParams(Params):
    rig: str = Field("tunnel_jumbo", description="Built-in rig id")
    holes: dict[str, list[Vec3]] | None = Field(
        None, description="Holes per arm {\"left\": [[x, y, z], ...], ...} mm (rig frame)")
    face: FaceIn | None = Field(None, description="Or a generated face, allocated to the arms")
    planner: Planner = "iapf"
    planner_params: PlannerKnobs = None
    sequencer: Algorithm = "auto"
    sequencer_params: SequencerKnobs = None
    cost: Cost = Field("distance", description=COST_DESCRIPTION + "; the transfers hold "
                       "roll at 0, so each hole has one branch here")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    balance: Literal["count", "work"] = "count"
    counts: dict[str, Annotated[int, Field(ge=0, le=MAX_FACE_HOLES)]] | None = None
    radii: dict[str, Annotated[float, Field(ge=0, le=5000)]] | None = Field(
        None, description="Envelope radius per link, mm (planning.drilling.envelopes)")
    standoff: float = Field(300.0, ge=0, le=2000, description="Feed retraction between holes")
    drill_time_s: float = Field(0.0, ge=0, le=3600)
    middle_park: Literal["last_hole", "home"] = "last_hole"
    output_dt: float = Field(0.5, ge=0.01, le=60, description="s between returned samples")

    @field_validator("rig")
    @classmethod
    def _rig(cls, v):
        return _check_rig(v)

    _allocation: Any = PrivateAttr(None)

    @field_validator("holes")
    @classmethod
    def _holes(cls, v):
        if v is not None and sum(len(h) for h in v.values()) > MAX_FACE_HOLES:
            raise ValueError(f"at most {MAX_FACE_HOLES} holes in all")
        return v

    @field_validator("planner_params")
    @classmethod
    def _planner_params(cls, v, info: ValidationInfo):
        if v is None or info.data.get("planner") is None:
            return v
        return move_planner_knobs(info.data["planner"], v)

    @field_validator("sequencer_params")
    @classmethod
    def _seq_params(cls, v, info: ValidationInfo):
        return _sequencer_params(v, info.data.get("sequencer"), "sequencer_params")

    @field_validator("radii")
    @classmethod
    def _radii(cls, v):
        from planning.drilling.envelopes import drill_arm_envelope

        drill_arm_envelope(v)
        return v

    @model_validator(mode="after")
    def _allocate(self):
        """One source of holes, allocated to the arms as the run will plan them."""
        from kinematics.rigs import builtin_rig
        from planning.drilling.allocation import allocate_holes, assign_holes
        from planning.drilling.patterns import face_pattern

        if (self.holes is None) == (self.face is None):
            raise ValueError("give exactly one of 'holes' (per arm) and 'face'")
        if self.face is None and self.counts is not None:
            raise ValueError("counts: only with 'face' (holes given per arm are allocated)")
        rig = builtin_rig(self.rig)
        if self.holes is not None:
            try:
                self._allocation = assign_holes(rig, self.holes)
            except ValueError as exc:
                raise _error_at("holes", exc) from None
            return self
        pattern = face_pattern(**self.face.model_dump())
        if len(pattern.holes) > MAX_FACE_HOLES:
            raise ValueError(f"face: {len(pattern.holes)} holes, at most "
                             f"{MAX_FACE_HOLES}; use a larger spacing")
        try:
            self._allocation = allocate_holes(rig, pattern.holes, balance=self.balance,
                                              counts=self.counts)
        except ValueError as exc:
            raise _error_at("counts" if str(exc).startswith("counts") else "face",
                            exc) from None
        return self

    def allocation(self):
        """The holes allocated to the arms (``planning.drilling.allocation.Allocation``),
        as checked."""
        return self._allocation


def _error_at(field: str | tuple, exc: ValueError) -> ValidationError:
    """``exc`` as a validation error at its own ``loc`` if it carries one, else at
    ``field`` (a name or a path)."""
    loc = tuple(getattr(exc, "loc", None) or (field if isinstance(field, tuple) else (field,)))
    # Braces would be read as placeholders of the message template.
    message = str(exc).replace("{", "(").replace("}", ")")
    return ValidationError.from_exception_data("MultiarmParams", [
        {"type": PydanticCustomError("value_error", message), "loc": loc, "input": None}])


def _window_min(values: np.ndarray, t: np.ndarray, out_t: np.ndarray) -> np.ndarray:
    """Minimum of ``values (S,)`` over each window ``[out_t[k], out_t[k+1])``."""
    idx = np.searchsorted(t, out_t)
    return np.minimum.reduceat(values, np.minimum(idx, len(values) - 1))


class MultiarmArm(Result):
    """One arm's part of a face plan; ``q`` sampled at the plan's ``t``."""

    holes: list[XYZ] = Field(description="Its holes in drilling order, mm")
    hole_ids: list[str] = Field(description="Their names: 'left[3]' (holes given per arm) or "
                                "the index in the generated face")
    q: list[list[float]] = Field(description="Joints (rad / mm) at each of the plan's t")
    move_starts_s: list[float]
    end_s: float
    travel_m: float = Field(description="Tool path length, m")
    sequence_length_m: float = Field(description="Length of the drilling order, m")
    planner_counts: dict[str, int] = Field(description="Moves planned by each planner")
    peak_acceleration: list[float] = Field(description="Peak |acceleration| per joint")
    max_rotational_acceleration: float = Field(description="rad/s^2")
    boom_time_s: float = Field(description="Estimated boom travel time along its drilling "
                               "order (swing, pitch, telescope at the transfer limits), s")
    boom_time_distance_order_s: float = Field(description="The same along the shortest-path "
                                              "order, s")


class MultiarmResult(Result):
    """A whole face: per-arm plans sampled every ``output_dt`` s, checked every ``check_dt``
    s for collisions between the arms' envelopes."""

    rig: str
    planner: Planner
    success: bool
    messages: list[str] = Field(description="Failures (any makes the plan unsuccessful)")
    notes: list[str]
    middle_park: Literal["last_hole", "home"]
    t: list[float] = Field(description="s, every output_dt")
    arms: dict[str, MultiarmArm]
    min_distance: dict[str, list[float]] = Field(
        description="Least envelope distance per arm pair ('left-middle') over each interval "
        "of t, mm")
    min_distance_overall: dict[str, float | None] = Field(description="mm, per arm pair")
    collisions: int = Field(description="Checked samples with overlapping envelopes")
    collisions_by_pair: dict[str, int]
    travel_m: dict[str, float] = Field(description="Tool path length per arm, m")
    total_travel_m: float
    cost: Cost = Field(description="What the drilling orders minimise")
    boom_time_s: float = Field(description="Estimated boom travel time between holes, all "
                               "arms, s")
    boom_time_distance_order_s: float = Field(description="The same for the shortest-path "
                                              "orders, s")
    boom_time_saved_s: float = Field(description="boom_time_distance_order_s - boom_time_s")
    acceleration_bound: float = Field(description="rad/s^2 (paper 002)")
    check_dt: float | None = Field(description="s between collision checks")
    samples: int = Field(description="Samples checked")
    runtime_s: float


def run_multiarm(params: MultiarmParams, progress: Progress) -> MultiarmResult:
    """Plan a whole face; joint trajectories and distances subsampled every ``output_dt``."""
    from kinematics.rigs import builtin_rig
    from planning.drilling.multiarm import PAPER_ACCELERATION_BOUND, ROTATIONAL_JOINTS, plan_face

    allocation = params.allocation()
    plan = plan_face(builtin_rig(params.rig), None, allocation=allocation,
                     planner=params.planner, planner_params=params.planner_params,
                     sequencer=params.sequencer, sequencer_params=params.sequencer_params,
                     seed=params.seed, radii=params.radii, standoff=params.standoff,
                     drill_time_s=params.drill_time_s, middle_park=params.middle_park,
                     progress=progress, cost=params.cost)
    if params.holes is not None:
        labels = [f"{a}[{k}]" for a in allocation.arms for k in range(len(params.holes[a]))]
    else:
        labels = [f"{k}" for k in range(len(allocation.holes))]
    P = plan.allocation.holes
    dt = params.output_dt
    out_t = np.arange(0.0, plan.t[-1] + 1e-9, dt) if len(plan.t) else np.zeros(1)
    pick = np.minimum(np.searchsorted(plan.t, out_t), len(plan.t) - 1)
    arms = {}
    boom = {a: _boom_times(plan, a) for a in plan.arms}
    for a, ap in plan.arms.items():
        tl = ap.timeline
        acc = plan.accelerations[a]
        arms[a] = MultiarmArm(
            holes=P[ap.order].tolist(),
            hole_ids=[labels[k] for k in ap.order],
            q=plan.q[a][pick].tolist(),
            move_starts_s=tl.starts.tolist(),
            end_s=tl.end,
            travel_m=ap.tool_path_m,
            sequence_length_m=ap.sequence_length_m,
            planner_counts=ap.planner_counts,
            peak_acceleration=acc.tolist(),
            max_rotational_acceleration=float(acc[list(ROTATIONAL_JOINTS)].max()),
            boom_time_s=boom[a][0],
            boom_time_distance_order_s=boom[a][1],
        )
    min_distance = {p: _window_min(d, plan.t, out_t).tolist()
                    for p, d in plan.min_distance.items()}
    return MultiarmResult(
        rig=params.rig,
        planner=plan.planner,
        success=plan.success,
        messages=plan.messages,
        notes=plan.extras["notes"],
        middle_park=plan.middle_park,
        t=out_t.tolist(),
        arms=arms,
        min_distance=min_distance,
        min_distance_overall={p: finite_or_none(d.min()) for p, d in plan.min_distance.items()},
        collisions=plan.total_collisions,
        collisions_by_pair=plan.collisions,
        travel_m={a: ap.tool_path_m for a, ap in plan.arms.items()},
        total_travel_m=plan.tool_path_m(),
        cost=params.cost,
        boom_time_s=sum(b[0] for b in boom.values()),
        boom_time_distance_order_s=sum(b[1] for b in boom.values()),
        boom_time_saved_s=sum(b[1] - b[0] for b in boom.values()),
        acceleration_bound=PAPER_ACCELERATION_BOUND,
        check_dt=float(plan.t[1] - plan.t[0]) if len(plan.t) > 1 else None,
        samples=int(len(plan.t)),
        runtime_s=plan.runtime_s,
    )


def _boom_times(plan, arm: str) -> tuple[float, float]:
    """An arm's boom time along its order and along the shortest-path order, s (one hole:
    the move from the park pose, the same for both; none: 0)."""
    ap = plan.arms[arm]
    if ap.sequence is not None:
        return (float(ap.sequence.extra["boom_time_s"]),
                float(ap.sequence.extra["boom_time_distance_order_s"]))
    moves = ap.timeline.moves
    if not len(ap.order) or not moves:
        return 0.0, 0.0
    from planning.drilling.boom_time import BoomTime
    from planning.drilling.multiarm import MotionLimits

    limits = MotionLimits()
    timing = BoomTime.planned_joints(moves[0].space.model, limits.velocity,
                                     limits.acceleration)
    t = timing.path_time([moves[0].q_goal], moves[0].q_start)
    return t, t


register(JobKind("multiarm", MultiarmParams, MultiarmResult, run_multiarm,
                 "Whole-face plan for a multi-arm jumbo: allocation, sequencing, "
                 "collision-free moves (IAPF or RRT), 10 ms collision check"))
