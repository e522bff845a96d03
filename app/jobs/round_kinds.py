"""Job kind ``round``: a jumbo's whole drilling round (``planning.cycles.round.plan_round``).

A drill plan's holes in (collar and toe, mm, in the rig frame or in the plan's own frame with
``rig_pose``), every boom drilling at once without touching another, each boom's holes in
order with its timed joint trajectory, per hole its boom and times, the cycle time beside
its lower bound, the least boom-boom clearance of the whole round, and the holes no boom can
drill with the reason. ``GET /jobs/{id}/plot`` draws the round as a Gantt chart (PNG).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, JsonValue, PrivateAttr, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from ..fields import Coordinate, StrictModel
from ..fields import Point3 as Vec3
from .kinds import MAX_SEED, JobKind, Params, Progress, Result, absent_when_none, register

__all__ = ["MAX_ROUND_HOLES", "MAX_ROUND_SAMPLES", "RoundHole", "RoundParams",
           "RoundResult", "run_round", "plot_round"]

#: Most holes one round takes.
MAX_ROUND_HOLES = 2000
#: Most trajectory samples returned per boom (``output_dt`` is widened to keep to it).
MAX_ROUND_SAMPLES = 5000
#: Most characters of an IREDES plan.
MAX_PLAN_CHARS = 4_000_000
#: Most scene objects.
MAX_ROUND_OBJECTS = 200
Reason = Literal["out_of_reach", "axis_not_alignable", "blocked"]
PhaseKind = Literal["wait", "transfer", "collar", "drill", "retract"]
Rate = Annotated[float, Field(gt=0, le=100)]
Seconds = Annotated[float, Field(ge=0, le=3600)]
#: ``rig_pose`` as [x, y, z] or [x, y, z, yaw], or as a 4x4 matrix.
#: (Lengths are checked when the pose is read, which names the forms allowed.)
PoseVector = Annotated[list[Coordinate], Field(max_length=16)]
PoseRows = Annotated[list[Annotated[list[Coordinate], Field(max_length=16)]],
                     Field(max_length=16)]
#: A joint's speed or acceleration limit: rad/s (rad/s²) or mm/s (mm/s²).
JointRate = Annotated[float, Field(gt=0, le=1e6)]


class RoundHole(StrictModel):
    """One hole of the plan: collar and toe, mm (rig frame, or the plan's frame with
    ``rig_pose``), its id and optional type (for ``penetration_rate_by_type``)."""

    id: str = Field(min_length=1, max_length=64)
    collar: Vec3
    toe: Vec3
    type: str | None = Field(None, max_length=32)


class RoundLimits(StrictModel):
    """Joint limits of the booms by joint name (swing, pitch, telescope, roll,
    pitch_compensation, swing_compensation, feed): rad/s, mm/s and per s."""

    velocity: dict[str, JointRate] | None = Field(None, max_length=16)
    acceleration: dict[str, JointRate] | None = Field(None, max_length=16)


class RoundParams(Params):
    rig: str = Field("tunnel_jumbo", description="Built-in rig id")
    holes: list[RoundHole] | None = Field(None, min_length=1, max_length=MAX_ROUND_HOLES,
                                          description="The drill plan's holes")
    plan_iredes: str | None = Field(None, min_length=1, max_length=MAX_PLAN_CHARS,
                                    description="Or an IREDES drill plan (DRPPlan XML text)")
    plan_verify_checksum: bool = Field(True, description="Refuse an IREDES plan whose "
                                       "IR:ChkSum does not match")
    rig_pose: PoseVector | PoseRows | None = Field(
        None, description="Pose of the plan frame in the rig frame: a 4x4 matrix, [x, y, z] "
        "(mm) or [x, y, z, yaw] (yaw about z, degrees); default: holes in the rig frame")
    penetration_rate_m_min: float = Field(2.0, gt=0, le=100, description="m/min")
    penetration_rate_by_type: dict[str, Rate] | None = Field(
        None, description="m/min by hole type (the others: penetration_rate_m_min)")
    collaring_s: Seconds = Field(10.0, description="Collaring time per hole, s")
    retract_s: Seconds = Field(8.0, description="Least time of the feed's return, s")
    standoff: float = Field(300.0, gt=0, le=2000, description="Tip before the collar in "
                            "transfers, mm")
    clearance_mm: float = Field(50.0, ge=0, le=1000, description="Least boom-boom and "
                                "boom-scene distance kept, mm")
    limits: RoundLimits | None = None
    booms: list[str] | None = Field(None, min_length=1, max_length=16,
                                    description="Booms used (default: all)")
    priority: list[str] | None = Field(None, max_length=16,
                                       description="Timing order (default: most work first)")
    transfer_time_limit: float = Field(1.0, gt=0, le=30, description="Search time per "
                                       "transfer, s")
    scene: list[dict[str, JsonValue]] | None = Field(
        None, max_length=MAX_ROUND_OBJECTS, description="Scene objects (rig frame), as in "
        "a scene")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    output_dt: float = Field(1.0, ge=0.05, le=60, description="s between returned samples")

    _holes: Any = PrivateAttr(None)

    @model_validator(mode="after")
    def _check(self):
        from kinematics.errors import FieldError
        from kinematics.rigs import BUILTIN_RIG_IDS, builtin_rig

        if self.rig not in BUILTIN_RIG_IDS:
            raise _error_at(("rig",), f"rig: unknown rig {self.rig!r}; built-in: "
                            f"{', '.join(BUILTIN_RIG_IDS)}")
        rig = builtin_rig(self.rig)
        for name in ("booms", "priority"):
            for k, a in enumerate(getattr(self, name) or []):
                if a not in rig.arms:
                    raise _error_at((name, k), f"{name}[{k}]: rig {self.rig!r} has no boom "
                                    f"{a!r} (booms: {', '.join(rig.arms)})")
        names = [j.name for j in next(iter(rig.arms.values())).joints]
        if self.limits is not None:
            for field in ("velocity", "acceleration"):
                for j, v in (getattr(self.limits, field) or {}).items():
                    if j not in names:
                        raise _error_at(("limits", field, j), f"limits.{field}.{j}: no such "
                                        f"joint (joints: {', '.join(names)})")
                    if not 0 < v <= 1e6:
                        raise _error_at(("limits", field, j), f"limits.{field}.{j}: must be "
                                        "in (0, 1e6]")
        if (self.holes is None) == (self.plan_iredes is None):
            raise _error_at((), "give exactly one of 'holes' and 'plan_iredes'")
        holes = self.holes if self.holes is not None else self._read_plan()
        seen: dict[str, int] = {}
        for k, h in enumerate(holes):
            if h.id in seen:
                raise _error_at(("holes", k, "id"), f"holes[{k}].id: {h.id!r} is used twice "
                                f"(holes[{seen[h.id]}])")
            seen[h.id] = k
            if math.dist(h.collar, h.toe) < 1.0:
                raise _error_at(("holes", k, "toe"), f"holes[{k}].toe: must lie at least "
                                "1 mm from the collar")
        T = _rig_pose(self.rig_pose)
        C = np.array([h.collar for h in holes], dtype=float)
        D = np.array([h.toe for h in holes], dtype=float)
        C = C @ T[:3, :3].T + T[:3, 3]
        D = D @ T[:3, :3].T + T[:3, 3]
        if self.scene:
            from planning.collision import CollisionScene

            try:
                CollisionScene.from_dicts(self.scene, prefix=("scene",))
            except FieldError as exc:
                raise _error_at(tuple(exc.loc) if getattr(exc, "loc", None) else ("scene",),
                                str(exc)) from None
        self._holes = (C, D, [h.id for h in holes], [h.type for h in holes])
        return self

    def _read_plan(self) -> list[RoundHole]:
        """The holes of ``plan_iredes`` (``planning.drilling.plans.read_iredes``, mm in the
        plan's frame); 422 at ``plan_iredes`` and where in the file."""
        from kinematics.errors import FieldError
        from planning.drilling.plans import read_iredes

        try:
            plan = read_iredes(self.plan_iredes, verify_checksum=self.plan_verify_checksum)
        except FieldError as exc:
            raise _error_at(("plan_iredes", *(getattr(exc, "loc", None) or ())),
                            f"plan_iredes: {exc}") from None
        if len(plan.holes) > MAX_ROUND_HOLES:
            raise _error_at(("plan_iredes",), f"plan_iredes: {len(plan.holes)} holes, at "
                            f"most {MAX_ROUND_HOLES}")
        if not len(plan.holes):
            raise _error_at(("plan_iredes",), "plan_iredes: the plan has no holes")
        return [RoundHole(id=h.id, collar=h.collar.tolist(), toe=h.toe.tolist(),
                          type=h.type or None) for h in plan.holes]

    def rig_holes(self) -> tuple[np.ndarray, np.ndarray, list[str], list[str | None]]:
        """Collars and toes ``(N, 3)`` mm in the rig frame, the ids and the types."""
        return self._holes


def _rig_pose(value) -> np.ndarray:
    """``rig_pose`` as a 4x4 matrix (identity when None); 422 naming ``rig_pose``."""
    T = np.eye(4)
    if value is None:
        return T
    a = np.asarray(value, dtype=float)
    if a.shape == (4, 4):
        R = a[:3, :3]
        if not (np.allclose(R @ R.T, np.eye(3), atol=1e-6) and np.linalg.det(R) > 0
                and np.allclose(a[3], [0, 0, 0, 1])):
            raise _error_at(("rig_pose",), "rig_pose: the 4x4 matrix must be a rigid "
                            "transform (rotation, translation, last row 0 0 0 1)")
        return a
    if a.shape in ((3,), (4,)):
        T[:3, 3] = a[:3]
        if a.shape == (4,):
            c, s = math.cos(math.radians(a[3])), math.sin(math.radians(a[3]))
            T[:2, :2] = [[c, -s], [s, c]]
        return T
    raise _error_at(("rig_pose",), "rig_pose: must be a 4x4 matrix, [x, y, z] or "
                    "[x, y, z, yaw]")


def _error_at(loc: tuple, message: str) -> ValidationError:
    """A validation error at ``loc`` (under ``body``, as the service names fields)."""
    message = message.replace("{", "(").replace("}", ")")
    return ValidationError.from_exception_data("RoundParams", [
        {"type": PydanticCustomError("value_error", message), "loc": loc, "input": None}])


class RoundPhase(StrictModel):
    kind: PhaseKind
    start_s: float
    end_s: float
    hole: str | None = None


class RoundBoom(Result):
    """One boom: its holes in drilling order, its timed joint trajectory (``t``, ``q``:
    rad / mm) and its phases."""

    holes: list[str]
    priority: int = Field(description="Its place in the timing order (0 first)")
    t: list[float]
    q: list[list[float]]
    phases: list[RoundPhase]
    wait_s: float = Field(description="Time spent waiting for other booms, s")
    end_s: float = Field(description="Back at its park pose, s")


class RoundHolePlan(Result):
    id: str
    boom: str
    start_s: float = Field(description="Collaring starts, s")
    end_s: float = Field(description="Retracted, s")
    depth_mm: float
    drill_s: float = Field(description="Collaring + depth / rate + retraction, s")


class RoundUnreachable(Result):
    id: str
    reason: Reason
    detail: str


class RoundResult(Result):
    rig: str
    booms: dict[str, RoundBoom]
    holes: list[RoundHolePlan]
    unreachable: list[RoundUnreachable]
    cycle_time_s: float = Field(description="Until the last boom is back at park, s")
    lower_bound_s: float = Field(description="Drilling time of the drilled holes summed, "
                                 "over the number of booms, s")
    ratio: float | None = Field(description="cycle_time_s / lower_bound_s")
    min_boom_clearance_mm: float | None = Field(description="Least boom-boom distance over "
                                                "the whole round (exact), mm")
    clearance_pair: str | None
    clearance_t_s: float | None
    checked_instants: int
    max_step_mm: float = Field(description="Largest motion of a boom point between two "
                               "checked instants, mm")
    min_scene_clearance_mm: float | None = absent_when_none("Least boom-scene distance, mm")
    priority: list[str]
    notes: list[str]
    planning_time_s: float


def run_round(params: RoundParams, progress: Progress) -> RoundResult:
    """Plan the round; each boom's trajectory sampled every ``output_dt`` s (wider if it
    would exceed ``MAX_ROUND_SAMPLES``) and at its phase boundaries."""
    from kinematics.rigs import builtin_rig
    from planning.collision import CollisionScene
    from planning.cycles.round import RoundOptions, plan_round

    C, D, ids, types = params.rig_holes()
    lim = params.limits or RoundLimits()
    options = RoundOptions(
        penetration_rate_m_min=params.penetration_rate_m_min,
        rates_by_type=params.penetration_rate_by_type, collaring_s=params.collaring_s,
        retract_s=params.retract_s, standoff=params.standoff,
        booms=tuple(params.booms) if params.booms else None,
        priority=tuple(params.priority) if params.priority else None,
        velocity=lim.velocity, acceleration=lim.acceleration,
        clearance=params.clearance_mm, transfer_time_limit=params.transfer_time_limit,
        scene=CollisionScene.from_dicts(params.scene, prefix=("scene",))
        if params.scene else None, seed=params.seed)
    res = plan_round(builtin_rig(params.rig), C, D, ids, options, types=types,
                     progress=progress)
    booms = {}
    for a, bp in res.booms.items():
        dt = max(params.output_dt, bp.end_s / (MAX_ROUND_SAMPLES - 200 - 6 * len(bp.holes)))
        t, q = bp.samples(dt)
        if len(t) > MAX_ROUND_SAMPLES:
            keep = np.unique(np.linspace(0, len(t) - 1, MAX_ROUND_SAMPLES).round().astype(int))
            t, q = t[keep], q[keep]
        booms[a] = RoundBoom(holes=bp.holes, priority=bp.priority, t=t.tolist(),
                             q=q.tolist(), phases=[RoundPhase(**p) for p in bp.phase_table()],
                             wait_s=bp.wait_s, end_s=bp.end_s)
    ratio = res.ratio

    def finite(x):
        return None if x is None or not math.isfinite(x) else float(x)

    return RoundResult(
        rig=params.rig, booms=booms,
        holes=[RoundHolePlan(id=h.id, boom=h.boom, start_s=h.start_s, end_s=h.end_s,
                             depth_mm=h.depth_mm, drill_s=h.drill_s) for h in res.holes],
        unreachable=[RoundUnreachable(**u) for u in res.unreachable],
        cycle_time_s=res.cycle_time_s, lower_bound_s=res.lower_bound_s,
        ratio=finite(ratio), min_boom_clearance_mm=finite(res.min_boom_clearance_mm),
        clearance_pair=res.clearance_pair, clearance_t_s=res.clearance_t_s,
        checked_instants=res.checked_instants, max_step_mm=res.max_step_mm,
        min_scene_clearance_mm=finite(res.min_scene_clearance_mm),
        priority=list(res.stats["priority"]), notes=res.notes,
        planning_time_s=res.planning_time_s)


#: Bar colour per phase kind of the Gantt chart.
PHASE_COLOURS = {"transfer": "#4c72b0", "collar": "#dd8452", "drill": "#55a868",
                 "retract": "#8172b3", "wait": "#c44e52"}


def plot_round(params: RoundParams, result: RoundResult, robot: Any) -> bytes:
    """A Gantt chart of the round: one row per boom, a bar per phase (transfer, collar,
    drill, retract, wait), the cycle time and the lower bound marked. PNG bytes."""
    import io

    from matplotlib.figure import Figure  # on first use (no pyplot: thread-safe)
    from matplotlib.patches import Patch

    names = list(result.booms)
    fig = Figure(figsize=(10.0, 1.2 + 0.8 * len(names)), dpi=100)
    ax = fig.subplots()
    for row, a in enumerate(names):
        for kind in PHASE_COLOURS:
            spans = [(p.start_s, p.end_s - p.start_s) for p in result.booms[a].phases
                     if p.kind == kind and p.end_s > p.start_s]
            if spans:
                ax.broken_barh(spans, (row - 0.35, 0.7), facecolors=PHASE_COLOURS[kind])
    ax.axvline(result.cycle_time_s, color="k", linewidth=1.0)
    ax.axvline(result.lower_bound_s, color="0.4", linestyle="--", linewidth=1.0)
    ax.set_yticks(range(len(names)), names)
    ax.set_ylim(-0.6, len(names) - 0.4)
    ax.invert_yaxis()
    ax.set_xlabel("time [s]")
    clear = "" if result.min_boom_clearance_mm is None else \
        f", least boom clearance {result.min_boom_clearance_mm:.0f} mm"
    ax.set_title(f"{result.rig}: {len(result.holes)} holes, cycle {result.cycle_time_s:.0f} s"
                 f" (lower bound {result.lower_bound_s:.0f} s){clear}", fontsize=10)
    ax.legend(handles=[Patch(color=c, label=k) for k, c in PHASE_COLOURS.items()],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


register(JobKind("round", RoundParams, RoundResult, run_round,
                 "A jumbo's whole drilling round: holes allocated by reach of the whole hole "
                 "and by time, ordered by boom time, every boom drilling at once with "
                 "prioritised waits so no two booms touch; cycle time and its lower bound",
                 plot=plot_round))
