"""Job kind ``pallet``: the palletizing work cycle of a robot (``planning.cycles.pallet``).

The params describe the pallet (size, pose, overhang, stack height limit), the box (size,
optional mass), the pattern (``column``, ``interlocked`` or an explicit list of place poses)
and the pick pose(s), with the cycle's settings (approach and retreat lines, tilt
tolerance, grip offset, clearance, dwell, obstacles, time limit per task). At most
``MAX_BOXES`` (2,000) boxes per job: a pattern whose layers hold more, a ``count`` above it
or a longer list of place poses is a 422 naming the field. Progress is reported per box. The
result says per box its status, where it went, where it rests (FK of the planned
configuration at the place), its carry and return durations (time-optimal within the
robot's limits), its cycle time and the largest tilt of the box along the carry; and the
cycle time per layer and per pallet, boxes per hour. ``GET /jobs/{id}/plot`` draws the
layer map: a top view of each layer, the boxes numbered and coloured by placing order,
those not placed in red (planning failed) or grey outline (not fitting).
"""

from __future__ import annotations

import io
import math
from typing import Annotated, Any

from pydantic import Field, field_validator, model_validator

from kinematics.errors import FieldError
from planning.cycles.pallet import EUR_PALLET, MAX_BOXES, MAX_LAYERS, PATTERNS

from ..fields import JointVector, StrictModel, bounded_list, pose_type
from .kinds import MAX_SEED, XYZ, JobKind, Params, Progress, Result, register

__all__ = ["PalletIn", "BoxIn", "PalletParams", "PalletBoxOut", "PalletJobResult",
           "run_pallet", "plot_pallet", "MAX_PICKS", "MAX_OBSTACLES", "DEFAULT_PALLET_POSE"]

#: Most pick poses of one job (used in turn).
MAX_PICKS = 16
#: Most obstacles besides the pallet.
MAX_OBSTACLES = 100
#: Longest planning time of one task (a box's carry or its return), s.
MAX_TASK_TIME_LIMIT_S = 60.0
#: The pallet of the GLT palletizer's cell: its centre 850 mm in front of the robot, its
#: length across (turned 90° about the vertical), on the floor.
DEFAULT_PALLET_POSE = [[0.0, -1.0, 0.0, 850.0], [1.0, 0.0, 0.0, 0.0],
                       [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]

Pose = pose_type(4)
Size = Annotated[list[Annotated[float, Field(gt=0, le=100_000)]],
                 Field(min_length=3, max_length=3)]
#: A place pose: the box centre's T_world_box (4x4) or [x, y, z, yaw] (mm, rad).
PlacePose = Annotated[list[Annotated[float, Field(ge=-100_000, le=100_000)]],
                      Field(min_length=4, max_length=4)] | Pose  # type: ignore[valid-type]


class PalletIn(StrictModel):
    """The pallet: size, pose (the centre of its bottom face), overhang, stack height."""

    size: Size = Field(list(EUR_PALLET), description="Length (along its x), width, height, "
                       "mm (EUR: 1200 x 800 x 144)")
    pose: Pose = Field(DEFAULT_PALLET_POSE,  # type: ignore[valid-type]
                       description="T_world_pallet, 4x4 mm: the centre of its bottom face, "
                       "z vertical (default: the GLT cell's, 850 mm in front, turned 90°)")
    overhang: float = Field(0.0, ge=0, le=1000, description="mm a box may stand out past "
                            "each edge")
    max_height: float | None = Field(None, gt=0, le=100_000, description="mm of boxes above "
                                     "the pallet's top (null: no limit)")


class BoxIn(StrictModel):
    size: Size = Field(description="Length, width, height, mm")
    mass: float | None = Field(None, ge=0, le=100_000, description="kg (reported)")


class PalletParams(Params):
    """A pallet job (module docstring)."""

    robot: str = Field("glt_palletizer", max_length=200, description="Robot id")
    pallet: PalletIn = Field(default_factory=PalletIn)
    box: BoxIn
    pattern: str | bounded_list(  # type: ignore[valid-type]
        PlacePose, MAX_BOXES, min_length=1) = Field(
        "column", description=f"'column' (every layer the same grid), 'interlocked' (every "
        f"other layer turned 90°) or a list of at most {MAX_BOXES:,} place poses (the box "
        "centre: 4x4 or [x, y, z, yaw], world, mm / rad)")
    layers: int = Field(1, ge=1, le=MAX_LAYERS, description="Layers of a pattern")
    count: int | None = Field(None, ge=1, le=MAX_BOXES, description="Boxes to place (default: "
                              f"every place of the layers; at most {MAX_BOXES:,})")
    gap: float = Field(5.0, ge=0, le=1000, description="mm between the boxes of a grid")
    pick: Pose | bounded_list(Pose, MAX_PICKS, min_length=1) = Field(  # type: ignore[valid-type]
        description="T_world_box of the box at the pick station (its centre where it "
        f"rests), or a list of at most {MAX_PICKS} used in turn")
    approach_mm: float = Field(150.0, ge=0, le=5000, description="Straight lift at the pick "
                               "and descent to the place, mm")
    retreat_mm: float = Field(150.0, ge=0, le=5000, description="Straight rise after letting "
                              "go and descent to the next pick, mm")
    tilt_tolerance: float = Field(0.05, gt=0, lt=math.pi, description="The carried box's "
                                  "vertical within this angle along the carry, rad")
    grip_offset_mm: float = Field(65.0, ge=0, le=5000, description="From the tool point to "
                                  "the box's top face, mm (the built-in robots' tool capsule "
                                  "reaches 60 mm past the tool point)")
    clearance_mm: float = Field(5.0, ge=0, le=1000, description="The box is taken and let go "
                                "this far above where it rests, mm")
    dwell_s: float = Field(0.0, ge=0, le=3600, description="s at the pick and at the place "
                           "(gripping, letting go), counted in the cycle time")
    margin_mm: float = Field(0.0, ge=0, le=1000, description="Closer than this to anything "
                             "counts as a collision, mm (keep it below gap and clearance_mm)")
    obstacles: bounded_list(dict[str, Any], MAX_OBSTACLES) = Field(  # type: ignore[valid-type]
        default_factory=list, description="Scene objects besides the pallet (the POST /scenes "
        "format: box, sphere, cylinder, capsule, mesh with vertices), mm")
    start: JointVector | None = Field(None, description="The robot's configuration before the "
                                      "first box (default: at the first pick)")
    time_limit: float = Field(10.0, gt=0, le=MAX_TASK_TIME_LIMIT_S,
                              description="s of planning per task (a box's carry, its return)")
    seed: int = Field(0, ge=0, le=MAX_SEED)

    @field_validator("pattern")
    @classmethod
    def _known_pattern(cls, v: Any) -> Any:
        if isinstance(v, str) and v not in PATTERNS:
            raise ValueError(f"pattern must be one of {', '.join(PATTERNS)} or a list of "
                             "place poses")
        return v

    @model_validator(mode="after")
    def _fits_the_caps(self) -> PalletParams:
        """The pattern's boxes counted (at most ``MAX_BOXES``) and the geometry checked."""
        self.pattern_of()
        if self.obstacles:
            from planning.collision import CollisionScene

            try:
                CollisionScene.from_request({"objects": list(self.obstacles)})
            except FieldError as exc:
                raise _at(("obstacles", *exc.loc[1:]), exc.message) from None
        return self

    def objects(self) -> tuple[Any, Any]:
        """``(Pallet, Box)`` of the params."""
        from planning.cycles.pallet import Box, Pallet

        try:
            pallet = Pallet(tuple(self.pallet.size), self.pallet.pose, self.pallet.overhang,
                            self.pallet.max_height)
            box = Box(tuple(self.box.size), self.box.mass)
        except FieldError as exc:
            raise _at(exc.loc, exc.message) from None
        return pallet, box

    def pattern_of(self) -> Any:
        """The ``PalletPattern`` of the params (``FieldError`` as a 422 naming the field)."""
        from planning.cycles.pallet import pallet_pattern

        pallet, box = self.objects()
        try:
            return pallet_pattern(pallet, box, self.pattern, layers=self.layers,
                                  count=self.count, gap=self.gap)
        except FieldError as exc:
            loc = ("layers",) if exc.loc == ("count",) and self.count is None else exc.loc
            raise _at(loc, exc.message) from None


def _at(loc: tuple, message: str) -> Exception:
    """A validation error at ``loc`` (pydantic keeps a ``FieldError``'s own location)."""
    from pydantic import ValidationError
    from pydantic_core import PydanticCustomError

    return ValidationError.from_exception_data("PalletParams", [
        {"type": PydanticCustomError("value_error", message), "loc": tuple(loc),
         "input": None}])


# ---- results ----------------------------------------------------------------------------
class PalletBoxOut(Result):
    """One box (``planning.cycles.pallet.BoxPlan.summary``)."""

    index: int = Field(description="The box's place in the pattern")
    layer: int | None = Field(description="0: on the pallet (null: a box beyond capacity)")
    status: str = Field(description="placed, not_fitting, not_planned, or the failing "
                        "step's status (collision, timeout, unreachable, ...)")
    reason: str = Field(description="Why it is not placed (empty when placed)")
    position: XYZ | None = Field(description="Where its centre was to rest, world mm")
    yaw: float | None = Field(description="Its turn about the vertical there, rad")
    placed_pose: list[list[float]] | None = Field(
        description="T_world_box where it rests: FK of q_place with the grasp, lowered by "
        "the clearance (null unless placed)")
    q_pick: list[float] | None = Field(description="The configuration at the pick")
    q_place: list[float] | None = Field(description="The configuration at the place")
    carry_s: float = Field(description="Pick to place, time-optimal, s")
    return_s: float = Field(description="Place to the next pick, time-optimal, s")
    cycle_s: float = Field(description="carry_s + return_s + 2 dwell_s (0 unless placed)")
    tilt: float | None = Field(description="Largest tilt of the box along the carry's "
                               "states, rad")
    planning_time_s: float
    attempts: int = Field(description="Carries planned: 1, or 2 when the first failed and "
                          "the box was lifted clear of the stack for a second")
    carry_states: int = Field(description="States of the carry's joint path")
    return_states: int = Field(description="States of the return's joint path")


class PalletJobResult(Result):
    robot: str
    joints: list[str]
    pattern: str = Field(description="column, interlocked or explicit")
    per_layer: list[int] = Field(description="Boxes of each layer that fit")
    boxes: list[PalletBoxOut] = Field(description="One per box, by index")
    placed: int
    total: int
    layer_s: list[float] = Field(description="Cycle time of each layer's placed boxes, s")
    pallet_s: float = Field(description="Cycle time of the pallet's placed boxes, s")
    boxes_per_hour: float
    mass: float | None = Field(description="kg placed (null without the box's mass)")
    tilt_tolerance: float = Field(description="rad")
    pallet_size: XYZ = Field(description="mm")
    pallet_pose: list[list[float]] = Field(description="T_world_pallet")
    box_size: XYZ = Field(description="mm")
    planning_time_s: float


# ---- running -----------------------------------------------------------------------------
def run_pallet(params: PalletParams, progress: Progress) -> PalletJobResult:
    """Plan the pallet (``planning.cycles.pallet.plan_pallet``), progress per box."""
    import numpy as np

    from planning.cycles.pallet import plan_pallet
    from planning.warm import warm_up

    model = params.robot_model()
    progress(0.0, "loading the motion kernels")
    warm_up(["kinematics", "motion"])
    pallet, box = params.objects()
    imported = params.imported()
    pick = np.asarray(params.pick, dtype=float)
    out = plan_pallet(model, pick if pick.ndim == 2 else list(pick), box, pallet,
                      params.pattern, layers=params.layers, count=params.count,
                      gap=params.gap, approach_mm=params.approach_mm,
                      retreat_mm=params.retreat_mm, tilt_tolerance=params.tilt_tolerance,
                      grip_offset_mm=params.grip_offset_mm, clearance_mm=params.clearance_mm,
                      dwell_s=params.dwell_s, margin_mm=params.margin_mm,
                      obstacles=list(params.obstacles),
                      collision_model=None if imported is None else imported[1],
                      start=params.start, time_limit=params.time_limit, seed=params.seed,
                      progress=lambda f, m: progress(0.99 * f, m))
    result = PalletJobResult(
        robot=model.id, joints=[j.name for j in model.joints], pattern=out.pattern.pattern,
        per_layer=out.pattern.per_layer, boxes=[b.summary() for b in out.boxes],
        placed=out.placed, total=len(out.boxes), layer_s=out.layer_s, pallet_s=out.pallet_s,
        boxes_per_hour=out.boxes_per_hour, mass=out.mass, tilt_tolerance=out.tilt_tolerance,
        pallet_size=list(pallet.size), pallet_pose=pallet.pose.tolist(),
        box_size=list(box.size), planning_time_s=out.planning_time_s)
    progress(1.0, f"{out.placed} of {len(out.boxes)} boxes placed")
    return result


def plot_pallet(params: PalletParams, result: PalletJobResult, robot: Any = None) -> bytes:
    """The layer map: a top view of each layer (pallet frame turned into the world's), the
    boxes numbered and coloured by placing order; red: planning failed; grey outline: does
    not fit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.patches import Polygon

    layers = sorted({b.layer for b in result.boxes if b.layer is not None}) or [0]
    n = len(layers)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(max(6.0, 4.2 * cols), 3.8 * rows + 0.6),
                             squeeze=False)
    L, W, _ = result.pallet_size
    P = np.asarray(result.pallet_pose)
    a, b, _ = result.box_size
    half = np.array([[L, W], [-L, W], [-L, -W], [L, -W]]) / 2
    pallet_xy = (P[:2, :2] @ half.T).T + P[:2, 3]
    placed = [x for x in result.boxes if x.status == "placed"]
    order = {x.index: k for k, x in enumerate(placed)}
    cmap = plt.get_cmap("viridis")
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    for ax, layer in zip(axes.ravel(), layers):
        ax.add_patch(Polygon(pallet_xy, closed=True, facecolor="#d9c3a0", edgecolor="#7a5c2e"))
        for x in result.boxes:
            if x.layer != layer or x.position is None:
                continue
            c, s = math.cos(x.yaw or 0.0), math.sin(x.yaw or 0.0)
            rect = np.array([[a, b], [-a, b], [-a, -b], [a, -b]]) / 2 @ np.array([[c, s],
                                                                                  [-s, c]])
            xy = rect + np.asarray(x.position[:2])
            if x.status == "placed":
                colour = cmap(order[x.index] / max(len(placed) - 1, 1))
                ax.add_patch(Polygon(xy, closed=True, facecolor=colour, edgecolor="black",
                                     alpha=0.9))
            elif x.status == "not_fitting":
                ax.add_patch(Polygon(xy, closed=True, fill=False, edgecolor="grey",
                                     linestyle="--"))
            else:
                ax.add_patch(Polygon(xy, closed=True, facecolor="#e04040", edgecolor="black",
                                     hatch="//", alpha=0.8))
            ax.text(x.position[0], x.position[1], str(x.index), ha="center", va="center",
                    fontsize=8, color="white" if x.status == "placed" else "black")
        ax.set_title(f"layer {layer}", fontsize=10)
        ax.set_aspect("equal")
        ax.autoscale_view()
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{result.robot}, {result.pattern}: {result.placed} of {result.total} boxes "
                 f"placed\n{result.boxes_per_hour:.0f} boxes/h, colour: placing order "
                 "(red: failed, dashed: does not fit)", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


register(JobKind("pallet", PalletParams, PalletJobResult, run_pallet,
                 "Palletizing work cycle: boxes picked, carried level around the boxes placed "
                 "and stacked in a pattern, each box's motion timed; boxes per hour",
                 needs_robot=True, plot=plot_pallet, needs_geometry=True))
