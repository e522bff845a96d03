"""Job kind ``piles``: a pile plan driven by a piling rig (``planning.cycles.piles``).

The params carry the plan (rows of ``id, x, y, z, inclination | rake, azimuth,
tol_position, tol_angle``, as JSON objects or as CSV text), the carrier's candidate set-ups
(a polygon sampled on a grid, a line of positions, or a list of ``[x, y, heading]``), the
site's obstacles (an inline scene in the site frame) and the rig's figures (base height,
approach, driving time, travel speed). The job finds, for every pile and candidate set-up,
whether the mast reaches the pile aligned within its tolerances; the fewest set-ups that
cover the plan; the order of the set-ups and of the piles at each; the arm's moves, the mast
lowered along each pile's axis, and the times. Conventions and figures: docs/piles.md.

Caps (422 naming the field): at most ``MAX_PILES`` piles, ``MAX_CANDIDATES`` candidate
set-ups (after the polygon's grid is drawn), ``MAX_POLYGON`` polygon corners, and
``MAX_PILES`` x ``MAX_CANDIDATES`` is never all checked: the arm's reach map lets through
only the pairs the arm can reach. A malformed plan row is a 422 at
``["body", "params", "plan", row, column]`` (row counted from 0, the CSV header not counted).
"""

from __future__ import annotations

import io
import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, JsonValue, ValidationError, field_validator, model_validator
from pydantic_core import PydanticCustomError

from kinematics.errors import FieldError
from planning.cycles.piles import (
    DEFAULT_TOL_ANGLE,
    DEFAULT_TOL_POSITION,
    MAX_PILES,
    PLAN_COLUMNS,
    parse_plan,
    plan_piles,
    setup_grid,
)

from ..fields import StrictModel, bounded_list
from .kinds import MAX_SEED, JobKind, Params, Progress, Result, absent_when_none, register
from .motion_kinds import SCENE_KEYS, collision_scene

__all__ = ["PilesParams", "PilesResult", "SetupsIn", "PileOut", "UnreachedOut", "SetupOut",
           "CoverOut", "run_piles", "plot_piles", "MAX_CANDIDATES", "MAX_POLYGON",
           "MAX_PILES_PARAMS_BYTES"]

#: Most candidate set-ups of one job, and corners of a set-up polygon.
MAX_CANDIDATES = 5000
MAX_POLYGON = 200
#: Most bytes of JSON the params take (a 2,000-pile plan with a scene).
MAX_PILES_PARAMS_BYTES = 4 * 1024 * 1024
#: Longest CSV plan (characters).
MAX_CSV_CHARS = 400_000

Coordinate = Annotated[float, Field(ge=-1e8, le=1e8)]
XY = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]
XYH = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]


class LineIn(StrictModel):
    """Candidate set-ups every ``spacing`` mm along a straight line, one heading."""

    start: XY = Field(description="[x, y] mm")
    end: XY = Field(description="[x, y] mm")
    spacing: float = Field(gt=0, le=1e6, description="mm between candidates")
    heading: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi, description="rad")


class SetupsIn(StrictModel):
    """The carrier's candidate set-ups: exactly one of ``polygon`` (with ``spacing``),
    ``line`` and ``positions``."""

    polygon: bounded_list(XY, MAX_POLYGON, min_length=3) | None = Field(  # type: ignore[valid-type]
        None, description=f"The area the carrier may stand in: 3..{MAX_POLYGON} [x, y] "
        "corners (mm), sampled on a square grid of spacing")
    spacing: float | None = Field(None, gt=0, le=1e6, description="Grid spacing in the "
                                  "polygon, mm")
    headings: bounded_list(Annotated[float, Field(ge=-2 * math.pi, le=2 * math.pi)], 8,  # type: ignore[valid-type]
                           min_length=1) = Field(
        [0.0], description="Carrier headings tried at each grid point, rad")
    line: LineIn | None = Field(None, description="Candidates along a line")
    positions: bounded_list(XYH, MAX_CANDIDATES, min_length=1) | None = Field(  # type: ignore[valid-type]
        None, description=f"At most {MAX_CANDIDATES:,} candidates [x, y, heading] (mm, rad)")

    @model_validator(mode="after")
    def _one(self) -> SetupsIn:
        given = [k for k in ("polygon", "line", "positions") if getattr(self, k) is not None]
        if len(given) != 1:
            raise FieldError(("setups",), "give exactly one of polygon (with spacing), line "
                             "and positions")
        if self.polygon is not None:
            if self.spacing is None:
                raise FieldError(("setups", "spacing"), "a polygon needs spacing (mm)")
            P = np.asarray(self.polygon, dtype=float)
            area = np.prod(P.max(axis=0) - P.min(axis=0))
            if area / self.spacing**2 > 4 * MAX_CANDIDATES:
                raise FieldError(("setups", "spacing"), f"spacing {self.spacing:g} mm draws "
                                 f"more than {MAX_CANDIDATES:,} candidates in the polygon")
        n = len(self.candidates())
        if n == 0:
            raise FieldError(("setups",), "no candidate set-up: the polygon's grid is empty")
        if n > MAX_CANDIDATES:
            raise FieldError(("setups", "spacing" if self.line is None else "line"),
                             f"{n:,} candidate set-ups, at most {MAX_CANDIDATES:,}")
        return self

    def candidates(self) -> np.ndarray:
        """The candidate set-ups ``(M, 3)`` [x, y, heading]."""
        if self.positions is not None:
            return np.asarray(self.positions, dtype=float).reshape(-1, 3)
        if self.line is not None:
            a, b = np.asarray(self.line.start), np.asarray(self.line.end)
            n = int(np.floor(np.linalg.norm(b - a) / self.line.spacing)) + 1
            if n > MAX_CANDIDATES:
                return np.zeros((n, 3))
            t = np.linspace(0.0, 1.0, n)[:, None] if n > 1 else np.zeros((1, 1))
            P = a + t * (b - a)
            return np.concatenate([P, np.full((n, 1), self.line.heading)], axis=1)
        return setup_grid(self.polygon, float(self.spacing), self.headings)


PLAN_DESCRIPTION = (
    f"The piles: at most {MAX_PILES:,} rows {{\"id\", \"x\", \"y\", \"z\" (mm, the pile head "
    "at the ground), \"inclination\" (rad from the vertical) or \"rake\" (\"1:n\", one "
    "horizontal per n vertical), \"azimuth\" (rad, the way the toe leans, from +x towards "
    "+y), \"tol_position\" (mm), \"tol_angle\" (rad)}, or the same as CSV text in plan_csv")


class PilesParams(Params):
    """A pile plan job (module docstring)."""

    robot: str = Field("pile_driver", max_length=200, description="The rig's arm (robot id)")
    plan: bounded_list(dict[str, JsonValue], MAX_PILES, min_length=1) | None = Field(  # type: ignore[valid-type]
        None, description=PLAN_DESCRIPTION)
    plan_csv: str | None = Field(None, max_length=MAX_CSV_CHARS, description="The plan as "
                                 "CSV: a header row of " + ", ".join(PLAN_COLUMNS) +
                                 " (id, x, y, z required), one pile a line")
    tol_position: float = Field(DEFAULT_TOL_POSITION, gt=0, le=1e4,
                                description="Default position tolerance, mm")
    tol_angle: float = Field(DEFAULT_TOL_ANGLE, gt=0, le=0.5,
                             description="Default mast angle tolerance, rad")
    setups: SetupsIn = Field(description="Candidate set-ups of the carrier")
    scene: dict[str, Any] | None = Field(None, description="The site's obstacles in the "
                                         "site frame: {\"objects\": [...]} (mm)")
    carrier_radius: float = Field(0.0, ge=0, le=1e5, description="Candidate set-ups whose "
                                  "vertical axis, from the ground to the arm's base, comes "
                                  "closer than this to an obstacle are left out, mm (0: "
                                  "none)")
    base_height: float = Field(500.0, ge=-1e4, le=1e4, description="Height of the arm's "
                               "base above the ground at a set-up, mm")
    approach: float = Field(300.0, gt=0, le=1e4, description="Mast lowered along the pile "
                            "axis over this length onto the pile head, mm")
    mast_axis: Annotated[list[Annotated[float, Field(ge=-1, le=1)]],
                         Field(min_length=3, max_length=3)] = Field(
        [0.0, 1.0, 0.0], description="The mast's axis in the tool frame (unit after "
        "normalising); held along the pile axis, the turn about it free")
    drive_time: float = Field(60.0, ge=0, le=1e5, description="Driving time per pile, s")
    travel_speed: float = Field(500.0, gt=0, le=1e5, description="Carrier speed between "
                                "set-ups, mm/s (straight lines)")
    setup_time: float = Field(0.0, ge=0, le=1e5, description="Time to set up at each "
                              "set-up (levelling, outriggers), s")
    carrier_start: XY | None = Field(None, description="Where the carrier starts, [x, y] "
                                     "mm (default: at the first set-up)")
    exact_max: int = Field(2000, ge=0, le=MAX_CANDIDATES, description="The cover is exact "
                           "(MILP) up to this many distinct candidate set-ups (candidates "
                           "reaching the same piles count once), greedy above")
    cover_time_limit: float = Field(10.0, gt=0, le=600, description="s for the exact cover")
    move_time_limit: float = Field(2.0, gt=0, le=60, description="s of planning for a move "
                                   "whose straight joint motion collides")
    seed: int = Field(0, ge=0, le=MAX_SEED)

    @field_validator("plan")
    @classmethod
    def _plan_rows(cls, v: Any) -> Any:
        if v is not None:
            parse_plan(v)
        return v

    @field_validator("plan_csv")
    @classmethod
    def _plan_text(cls, v: Any) -> Any:
        if v is not None:
            parse_plan(v, loc=("plan_csv",))
        return v

    @field_validator("scene")
    @classmethod
    def _scene_builds(cls, v: Any) -> Any:
        if v is not None:
            if set(v) - set(SCENE_KEYS):
                raise FieldError(("scene", sorted(set(v) - set(SCENE_KEYS))[0]),
                                 "unknown field; a scene has objects")
            collision_scene(v)
        return v

    @field_validator("mast_axis")
    @classmethod
    def _unit(cls, v: list[float]) -> list[float]:
        if math.hypot(*v) < 1e-6:
            raise FieldError(("mast_axis",), "mast_axis must not be zero")
        return v

    @model_validator(mode="after")
    def _one_plan(self) -> PilesParams:
        if (self.plan is None) == (self.plan_csv is None):
            raise ValidationError.from_exception_data("PilesParams", [{
                "type": PydanticCustomError("value_error", "give exactly one of plan (rows) "
                                            "and plan_csv"), "loc": ("plan",), "input": None}])
        return self

    def pile_plan(self) -> Any:
        """The validated ``PilePlan``."""
        if self.plan is not None:
            return parse_plan(self.plan, tol_position=self.tol_position,
                              tol_angle=self.tol_angle)
        return parse_plan(self.plan_csv, tol_position=self.tol_position,
                          tol_angle=self.tol_angle, loc=("plan_csv",))


class PileOut(Result):
    id: str
    setup: int = Field(description="Index into setups (visiting order)")
    order: int = Field(description="Place in the whole plan's driving order, from 0")
    q: list[float] = Field(description="The driving configuration, rad / mm")
    axis_error: float = Field(description="Angle between the mast and the pile axis (FK), rad")
    position_error: float = Field(description="Tool point to pile head (FK), mm")
    move_s: float = Field(description="The arm's move from the previous pile, s")
    lower_s: float = Field(description="Mast lowered along the pile axis, s (lifted: the same)")
    drive_s: float = Field(description="Driving, s")
    start: float = Field(description="s from the start of the plan")
    end: float = Field(description="s from the start of the plan")
    move: Literal["first", "joint", "raised", "planned"] = Field(
        description="first at its set-up; a straight joint move; up to the raised arm, "
        "swung, down; or a planned one (plan_motion)")


class UnreachedOut(Result):
    id: str
    reason: str


class SetupOut(Result):
    x: float
    y: float
    heading: float
    candidate: int = Field(description="Index among the candidate set-ups")
    piles: int
    arrive: float = Field(description="s from the start of the plan")
    start: float = Field(description="Work starts, s (after setup_time)")
    end: float = Field(description="s")
    relocation_s: float = Field(description="Travel to it and setting up, s")


class CoverOut(Result):
    method: Literal["milp", "greedy", "none"]
    optimal: bool = Field(description="The count is proven least")
    setups: int = Field(description="Set-ups of the cover")
    lower_bound: int = Field(description="No cover has fewer: the optimum when exact, else "
                             "the LP relaxation rounded up")
    lp_value: float = Field(description="The LP relaxation's value")
    candidates: int = Field(description="Candidate set-ups checked")
    note: str


class PilesResult(Result):
    robot: str
    piles_total: int
    piles_reached: int
    piles: list[PileOut] = Field(description="The reached piles, in driving order")
    unreached: list[UnreachedOut] = Field(description="Piles no set-up reaches, and why")
    setups: list[SetupOut] = Field(description="The set-ups used, in visiting order")
    cover: CoverOut
    cycle_time_s: float = Field(description="The whole plan: relocations and work, s")
    work_s: float = Field(description="Time at the set-ups, s")
    relocation_s: float = Field(description="Travel and setting up, s")
    travel_mm: float = Field(description="Carrier travel, mm")
    per_pile_s: float = Field(description="Mean work time per reached pile, s")
    max_axis_error: float | None = absent_when_none("Largest mast angle error, rad")
    max_position_error: float | None = absent_when_none("Largest position error, mm")
    stats: dict[str, float] = Field(description="candidates_blocked (by carrier_radius), "
                                    "extra_setups (beyond the cover), ik_poses, lines, "
                                    "moves, moves_planned, reach_s, runtime_s")


def run_piles(params: PilesParams, progress: Progress) -> PilesResult:
    """Plan the piles (module docstring)."""
    model = params.robot_model()
    plan = params.pile_plan()
    candidates = params.setups.candidates()
    scene = collision_scene(params.scene) if params.scene is not None else None
    progress(0.01, f"{len(plan)} piles, {len(candidates)} candidate set-ups")
    out = plan_piles(model, plan, candidates, base_height=params.base_height,
                     approach=params.approach, mast_axis=params.mast_axis, scene=scene,
                     carrier_radius=params.carrier_radius,
                     drive_time=params.drive_time, travel_speed=params.travel_speed,
                     setup_time=params.setup_time, carrier_start=params.carrier_start,
                     exact_max=params.exact_max, cover_time_limit=params.cover_time_limit,
                     move_time_limit=params.move_time_limit, seed=params.seed,
                     progress=lambda f, m: progress(min(f, 0.99), m))
    done = sorted((p for p in out.piles if p.setup >= 0), key=lambda p: p.order)
    piles = [PileOut(id=plan.ids[p.index], setup=p.setup, order=p.order,
                     q=[float(v) for v in p.q], axis_error=p.axis_error,
                     position_error=p.position_error, move_s=p.move_s, lower_s=p.lower_s,
                     drive_s=p.drive_s, start=p.start, end=p.end, move=p.move)
             for p in done]
    counts = np.bincount([p.setup for p in done], minlength=len(out.setups))
    setups = [SetupOut(x=float(s[0]), y=float(s[1]), heading=float(s[2]),
                       candidate=int(c), piles=int(n), arrive=float(t[0]), start=float(t[1]),
                       end=float(t[2]), relocation_s=float(t[3]))
              for s, c, n, t in zip(out.setups, out.candidates, counts, out.setup_times)]
    cov = out.cover
    result = PilesResult(
        robot=model.id, piles_total=len(plan), piles_reached=len(done), piles=piles,
        unreached=[UnreachedOut(id=plan.ids[p.index], reason=p.reason)
                   for p in out.piles if p.setup < 0],
        setups=setups,
        cover=CoverOut(method=cov.method, optimal=cov.optimal, setups=len(cov.chosen),
                       lower_bound=cov.lower_bound,
                       lp_value=cov.lp_value if math.isfinite(cov.lp_value) else 0.0,
                       candidates=len(candidates), note=cov.note),
        cycle_time_s=out.total_s, work_s=out.work_s, relocation_s=out.relocation_s,
        travel_mm=out.travel_mm, per_pile_s=out.work_s / max(len(done), 1),
        max_axis_error=max((p.axis_error for p in done), default=None),
        max_position_error=max((p.position_error for p in done), default=None),
        stats={k: float(v) for k, v in out.stats.items()})
    progress(1.0, f"{len(done)} of {len(plan)} piles from {len(setups)} set-ups")
    return result


def plot_piles(params: PilesParams, result: PilesResult, robot: Any) -> bytes:
    """The site map: piles coloured by set-up (unreached ones as red crosses), the set-ups
    marked and numbered in visiting order, the carrier's route, the obstacles' footprints."""
    from matplotlib.figure import Figure

    plan = params.pile_plan()
    where = {pid: k for k, pid in enumerate(plan.ids)}
    fig = Figure(figsize=(8.0, 7.0), dpi=100)
    ax = fig.subplots()
    if params.scene is not None:
        for o in collision_scene(params.scene).to_dicts():
            pose = np.asarray(o.get("pose", np.eye(4)), dtype=float)
            r = float(o.get("radius", 0.0)) or 0.5 * float(max(o.get("size", [0, 0])[:2]))
            ax.add_patch(_footprint(o, pose, r))
    cmap = fig.colormaps["tab20"] if hasattr(fig, "colormaps") else None
    if cmap is None:
        from matplotlib import colormaps

        cmap = colormaps["tab20"]
    for s, su in enumerate(result.setups):
        P = np.array([plan.heads[where[p.id]] for p in result.piles if p.setup == s])
        c = cmap(s % 20)
        if len(P):
            ax.scatter(P[:, 0], P[:, 1], s=18, color=c, zorder=3)
        ax.scatter([su.x], [su.y], marker="s", s=60, color=c, edgecolor="k", zorder=4)
        ax.annotate(str(s + 1), (su.x, su.y), textcoords="offset points", xytext=(5, 5),
                    fontsize=8)
    if len(result.setups) > 1:
        route = np.array([[s.x, s.y] for s in result.setups])
        ax.plot(route[:, 0], route[:, 1], color="0.5", linewidth=0.8, linestyle="--",
                zorder=2)
    U = np.array([plan.heads[where[u.id]] for u in result.unreached]).reshape(-1, 3)
    if len(U):
        ax.scatter(U[:, 0], U[:, 1], marker="x", s=30, color="red", zorder=5,
                   label=f"unreached ({len(U)})")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{result.piles_reached} of {result.piles_total} piles from "
                 f"{len(result.setups)} set-ups ({result.cover.method}), "
                 f"{result.cycle_time_s / 3600:.2f} h")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def _footprint(obj: dict, pose: np.ndarray, r: float) -> Any:
    """The obstacle's outline seen from above: a rotated rectangle for a box, a circle for
    anything else (its radius, or half its largest side)."""
    from matplotlib.patches import Circle, Polygon

    style = {"facecolor": "0.85", "edgecolor": "0.4", "zorder": 1}
    if obj.get("type") == "box":
        sx, sy = (0.5 * float(v) for v in obj["size"][:2])
        corners = np.array([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]])
        xy = corners @ pose[:3, :3].T + pose[:3, 3]
        return Polygon(xy[:, :2], closed=True, **style)
    return Circle((float(pose[0, 3]), float(pose[1, 3])), max(r, 50.0), **style)


register(JobKind("piles", PilesParams, PilesResult, run_piles,
                 "A pile plan: the fewest carrier set-ups, the order, the mast along each "
                 "pile's axis, cycle times", needs_robot=True,
                 max_params_bytes=MAX_PILES_PARAMS_BYTES, plot=plot_piles))
