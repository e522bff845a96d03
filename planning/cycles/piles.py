"""Pile plans for a piling rig: where the carrier sets up, which piles it drives from each
set-up, in what order, and how long the whole plan takes.

A piling rig is a carrier that drives to a set-up position (x, y, heading) and stands there
while its arm holds the mast over each pile it can reach, lowers the mast along the pile's
axis and drives the pile. The arm is a robot model (the built-in ``pile_driver``) whose base
stands ``base_height`` mm above the ground at the set-up, turned by the heading about the
vertical. Lengths mm, angles rad, times s, the site frame z up (docs/piles.md).

Conventions:

* a pile: its head ``(x, y, z)`` where it enters the ground, and its axis, the unit
  direction it is driven in (downwards): ``(sin i cos a, sin i sin a, -cos i)`` with the
  inclination ``i`` (rad from the vertical) and the azimuth ``a`` (rad, the direction the
  toe leans towards, from +x towards +y). A plan row gives the inclination either as
  ``inclination`` (rad) or as ``rake`` ``"1:n"`` (one horizontal per ``n`` vertical, as
  piling exports give it; the number ``n`` alone also reads), never both; neither is a
  vertical pile;
* the mast: the tool-frame axis ``mast_axis`` (default the tool's y axis, which points down
  at the pile driver's zero configuration) held along the pile axis, the turn about it free
  (the ``axis`` constraint of ``planning.motion.constraints``), the tool point on the pile
  head. A pile is reached from a set-up when IK finds that pose within the joint limits, with
  every cylinder inside its stroke, free of the site's obstacles, and the pose ``approach``
  mm back up the axis too (the mast is lowered from there along a Cartesian line). When the
  exact axis is out of reach, directions within the pile's angle tolerance are tried.

The steps, each a function of its own:

1. ``parse_plan``: rows (dicts or CSV text) -> ``PilePlan``; ``FieldError`` naming the row
   and the column;
2. ``setup_grid``: candidate set-ups on a grid inside a polygon;
3. ``reach_table``: for every pile and candidate set-up whether the mast reaches it, the
   configuration and its errors, batched over every pair (one IK call for all the poses);
4. ``cover_setups``: the fewest set-ups reaching every reachable pile, exactly
   (``scipy.optimize.milp``, HiGHS) when there are at most ``exact_max`` distinct
   candidates, else greedily with the LP relaxation's bound;
5. ``plan_piles``: the whole plan: the cover, each pile assigned to a chosen set-up, the
   set-ups ordered along the site and the piles at each one ordered by the arm's travel
   (``planning.sequencing``), the arm's moves (straight in joint space when the collision
   checker finds the motion free, else ``plan_motion``), the mast lowered and lifted along
   the pile axis (``plan_line``), each motion timed time-optimally within the joint speeds
   and the cylinders' and pump's limits (``planning.trajectories.topp``), the driving time
   per pile, and the carrier's relocations at its travel speed.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.ik import solve_ik
from kinematics.model import RobotModel

__all__ = [
    "PLAN_COLUMNS",
    "DEFAULT_TOL_POSITION",
    "DEFAULT_TOL_ANGLE",
    "MAX_PILES",
    "PilePlan",
    "PileOutcome",
    "ReachTable",
    "CoverResult",
    "PilesPlan",
    "parse_plan",
    "pile_axes",
    "setup_grid",
    "setup_frames",
    "reach_table",
    "cover_setups",
    "plan_piles",
    "mast_errors",
    "axis_ik",
    "mast_line",
    "carrier_clear",
]

#: The columns of a plan row (``id``, ``x``, ``y``, ``z`` required).
PLAN_COLUMNS = ("id", "x", "y", "z", "inclination", "rake", "azimuth", "tol_position",
                "tol_angle")
#: Default tolerances of a pile: position (mm) and mast angle (rad, about 1.1 degrees).
DEFAULT_TOL_POSITION = 50.0
DEFAULT_TOL_ANGLE = 0.02
#: Most piles of one plan.
MAX_PILES = 2000
#: Steepest inclination accepted (rad from the vertical).
MAX_INCLINATION = math.radians(60.0)
#: Turns about the pile axis tried (rad, from the one that puts the tool's reference axis
#: across the arm's vertical plane).
PSI_SAMPLES = np.radians([0.0, -6.0, 6.0, -12.0, 12.0, -24.0, 24.0, 180.0])
#: The numeric pass: iterations, seeds' rotator angles (rad), damping, the weight of a
#: position error (per mm, against 1 per rad of axis error), and the position it must reach
#: (mm; within the pile's tolerance when that is tighter).
NUMERIC_ITERATIONS = 60
SEED_ROTATOR = np.array([-math.pi / 2, 0.0, math.pi / 2, math.pi])
NUMERIC_DAMPING = 1e-3
POSITION_WEIGHT = 0.01
NUMERIC_POSITION_TOL = 0.5
#: Squared weighted residual at which the numeric solve stops (1e-4 mm, 1e-6 rad).
CONVERGED = 1e-12
#: Cells (mm) of the arm's reach map (radius from the base axis, height), and the samples.
REACH_CELL = 50.0
REACH_SAMPLES = 20_000

Progress = Callable[[float, str], None]


def _quiet(fraction: float, message: str) -> None:
    return None


# ---- 1. the plan -------------------------------------------------------------------------
@dataclass(frozen=True)
class PilePlan:
    """Piles: ``ids``, ``heads (N, 3)`` mm, ``axes (N, 3)`` unit driving directions,
    ``inclination (N,)`` and ``azimuth (N,)`` rad, tolerances ``tol_position (N,)`` mm and
    ``tol_angle (N,)`` rad."""

    ids: tuple[str, ...]
    heads: np.ndarray
    axes: np.ndarray
    inclination: np.ndarray
    azimuth: np.ndarray
    tol_position: np.ndarray
    tol_angle: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def pile_axes(inclination, azimuth) -> np.ndarray:
    """Unit driving directions ``(N, 3)`` of piles inclined ``inclination`` rad from the
    vertical towards ``azimuth`` rad (from +x towards +y), pointing down."""
    i = np.asarray(inclination, dtype=float)
    a = np.asarray(azimuth, dtype=float)
    return np.stack([np.sin(i) * np.cos(a), np.sin(i) * np.sin(a), -np.cos(i)], axis=-1)


def _number(value: Any, loc: tuple, lo: float = -math.inf, hi: float = math.inf,
            what: str = "a number") -> float:
    if isinstance(value, bool):
        raise FieldError(loc, f"must be {what}, got {value!r}")
    if isinstance(value, str):
        text = value.strip()
        try:
            value = float(text)
        except ValueError:
            raise FieldError(loc, f"must be {what}, got {text!r}") from None
    if not isinstance(value, int | float):
        raise FieldError(loc, f"must be {what}, got {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v) or not lo <= v <= hi:
        raise FieldError(loc, f"must be {what} in [{lo:g}, {hi:g}], got {value!r}")
    return v


def _rake(value: Any, loc: tuple) -> float:
    """Inclination (rad) of a rake ``"1:n"`` (or ``n``): atan(1 / n); ``n`` >= 1/tan(60°)."""
    if isinstance(value, str) and ":" in value:
        a, _, b = value.partition(":")
        if a.strip() != "1":
            raise FieldError(loc, f"rake must read '1:n' (one horizontal per n vertical), "
                             f"got {value!r}")
        value = b
    n = _number(value, loc, 1.0 / math.tan(MAX_INCLINATION), 1e9,
                "a rake '1:n' with n a positive number")
    return math.atan(1.0 / n)


def _blank(value: Any) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


def parse_plan(rows: Sequence[Mapping[str, Any]] | str, *,
               tol_position: float = DEFAULT_TOL_POSITION,
               tol_angle: float = DEFAULT_TOL_ANGLE, max_piles: int = MAX_PILES,
               loc: tuple = ("plan",)) -> PilePlan:
    """A pile plan from rows (dicts with ``PLAN_COLUMNS``) or CSV text with a header row of
    them. Missing tolerances take ``tol_position`` / ``tol_angle``. ``FieldError`` at
    ``(*loc, row, column)`` (row counted from 0 over the data rows, the CSV header not
    counted) for a missing, unknown or malformed value, a duplicate id, or both
    ``inclination`` and ``rake``; at ``loc`` for an empty plan or one over ``max_piles``."""
    if isinstance(rows, str):
        reader = csv.DictReader(io.StringIO(rows.strip()), skipinitialspace=True)
        unknown = [c for c in (reader.fieldnames or []) if c not in PLAN_COLUMNS]
        if unknown:
            raise FieldError((*loc, "header", unknown[0]), f"unknown column {unknown[0]!r}; "
                             f"the columns are {', '.join(PLAN_COLUMNS)}")
        rows = [{k: v for k, v in r.items() if k is not None and not _blank(v)}
                for r in reader]
    if not isinstance(rows, Sequence) or len(rows) == 0:
        raise FieldError(loc, "the plan must have at least one pile")
    if len(rows) > max_piles:
        raise FieldError(loc, f"at most {max_piles:,} piles per plan, got {len(rows):,}")
    N = len(rows)
    heads = np.empty((N, 3))
    incl, azim, tp, ta = (np.empty(N) for _ in range(4))
    ids: list[str] = []
    seen: dict[str, int] = {}
    for r, row in enumerate(rows):
        where = (*loc, r)
        if not isinstance(row, Mapping):
            raise FieldError(where, "a pile must be an object with id, x, y, z, ...")
        for key in row:
            if key not in PLAN_COLUMNS:
                raise FieldError((*where, key), f"unknown column {key!r}; the columns are "
                                 f"{', '.join(PLAN_COLUMNS)}")
        for key in ("id", "x", "y", "z"):
            if _blank(row.get(key)):
                raise FieldError((*where, key), f"pile {r}: missing {key}")
        pid = row["id"]
        if not isinstance(pid, str | int) or isinstance(pid, bool) or len(str(pid)) > 64:
            raise FieldError((*where, "id"), "id must be a string or integer of at most 64 "
                             "characters")
        pid = str(pid).strip()
        if pid in seen:
            raise FieldError((*where, "id"), f"id {pid!r} repeats row {seen[pid]}")
        seen[pid] = r
        ids.append(pid)
        for k, key in enumerate(("x", "y", "z")):
            heads[r, k] = _number(row[key], (*where, key), -1e8, 1e8, "a coordinate in mm")
        has_i, has_r = not _blank(row.get("inclination")), not _blank(row.get("rake"))
        if has_i and has_r:
            raise FieldError((*where, "rake"), "give inclination (rad) or rake ('1:n'), "
                             "not both")
        incl[r] = (_number(row["inclination"], (*where, "inclination"), 0.0, MAX_INCLINATION,
                           "an angle from the vertical in rad") if has_i
                   else _rake(row["rake"], (*where, "rake")) if has_r else 0.0)
        azim[r] = (_number(row["azimuth"], (*where, "azimuth"), -2 * math.pi, 2 * math.pi,
                           "an angle in rad") if not _blank(row.get("azimuth")) else 0.0)
        tp[r] = (_number(row["tol_position"], (*where, "tol_position"), 1e-3, 1e4,
                         "a distance in mm") if not _blank(row.get("tol_position"))
                 else tol_position)
        ta[r] = (_number(row["tol_angle"], (*where, "tol_angle"), 1e-5, 0.5,
                         "an angle in rad") if not _blank(row.get("tol_angle")) else tol_angle)
    return PilePlan(tuple(ids), heads, pile_axes(incl, azim), incl, azim, tp, ta)


# ---- 2. set-ups -------------------------------------------------------------------------
def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether each point ``(M, 2)`` lies inside ``polygon (K, 2)`` (even-odd rule)."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = polygon, np.roll(polygon, -1, axis=0)
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return np.count_nonzero(crosses & (x < xs), axis=1) % 2 == 1


def setup_grid(polygon, spacing: float, headings: Sequence[float] = (0.0,)) -> np.ndarray:
    """Candidate set-ups ``(M, 3)`` [x, y, heading]: the points of a square grid of
    ``spacing`` mm (anchored at the polygon's lower-left corner of its bounding box, offset
    by half a spacing) inside ``polygon (K, 2)`` mm, each with every heading (rad)."""
    P = np.asarray(polygon, dtype=float)
    if P.ndim != 2 or P.shape[1] != 2 or len(P) < 3 or not np.all(np.isfinite(P)):
        raise FieldError(("polygon",), "polygon: at least 3 finite [x, y] points in mm")
    if not (math.isfinite(spacing) and spacing > 0):
        raise FieldError(("spacing",), "spacing: must be a positive distance in mm")
    lo, hi = P.min(axis=0), P.max(axis=0)
    xs = np.arange(lo[0] + spacing / 2, hi[0], spacing)
    ys = np.arange(lo[1] + spacing / 2, hi[1], spacing)
    G = np.stack(np.meshgrid(xs, ys, indexing="xy"), axis=-1).reshape(-1, 2)
    G = G[_inside(G, P)]
    h = np.asarray(headings, dtype=float)
    return np.concatenate([np.repeat(G, len(h), axis=0), np.tile(h, len(G))[:, None]], axis=1)


def setup_frames(setups: np.ndarray, base_height: float) -> np.ndarray:
    """``T_site_base (M, 4, 4)`` of the arm's base at each set-up [x, y, heading]."""
    S = np.asarray(setups, dtype=float)
    c, s = np.cos(S[:, 2]), np.sin(S[:, 2])
    T = np.zeros((len(S), 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = S[:, 0], S[:, 1], base_height
    return T


# ---- 3. reach -------------------------------------------------------------------------
#: Why a pile is not reached from a set-up, best first (``ReachTable.stage``).
STAGES = ("out of the arm's reach", "the mast cannot align with the pile axis within the "
          "joint limits", "the mast's approach point up the pile axis is out of reach",
          "a cylinder would leave its stroke", "the arm would hit the site", "reached")
REACHED = len(STAGES) - 1


@dataclass(frozen=True)
class ReachTable:
    """Pile x set-up: ``reach (N, M)`` bool; ``q (N, M, dof)`` the driving configuration
    (NaN where not reached); ``axis_error (N, M)`` rad and ``position_error (N, M)`` mm of
    it (FK); ``margin (N, M)``: its least distance to a joint limit, as a share of the
    range (larger is better); ``stage (N, M)``: how far the checks got (index of
    ``STAGES``); ``poses``: the IK poses solved."""

    reach: np.ndarray
    q: np.ndarray
    axis_error: np.ndarray
    position_error: np.ndarray
    margin: np.ndarray
    stage: np.ndarray
    poses: int

    def why(self, pile: int) -> str:
        """Why pile ``pile`` is reached from no set-up (the furthest check any passed)."""
        best = int(self.stage[pile].max()) if self.stage.shape[1] else 0
        return f"from every candidate set-up: {STAGES[best]}" if best < REACHED \
            else "reached"


@lru_cache(maxsize=16)
def _reach_map(model: RobotModel) -> tuple[np.ndarray, float, float]:
    """Cells (radius from the base axis, height) the tool point reaches: an occupancy grid of
    ``REACH_SAMPLES`` seeded samples within the limits, dilated by one cell."""
    rng = np.random.default_rng(0)
    q = rng.uniform(model.lower, model.upper, (REACH_SAMPLES, model.dof))
    p = fk(model, q)[:, :3, 3]
    r, z = np.hypot(p[:, 0], p[:, 1]), p[:, 2]
    z0 = float(z.min()) - 2 * REACH_CELL
    i = (r / REACH_CELL).astype(int) + 1
    j = ((z - z0) / REACH_CELL).astype(int) + 1
    grid = np.zeros((i.max() + 3, j.max() + 3), dtype=bool)
    grid[i, j] = True
    dil = grid.copy()
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            dil[1:-1, 1:-1] |= grid[1 + di:grid.shape[0] - 1 + di, 1 + dj:grid.shape[1] - 1 + dj]
    return dil, z0, REACH_CELL


def _in_map(reach_map: tuple[np.ndarray, float, float], p: np.ndarray) -> np.ndarray:
    grid, z0, cell = reach_map
    i = (np.hypot(p[..., 0], p[..., 1]) / cell).astype(int) + 1
    j = np.floor((p[..., 2] - z0) / cell).astype(int) + 1
    ok = (i >= 0) & (i < grid.shape[0]) & (j >= 0) & (j < grid.shape[1])
    out = np.zeros(p.shape[:-1], dtype=bool)
    out[ok] = grid[i[ok], j[ok]]
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _tool_reference(mast_axis: np.ndarray) -> np.ndarray:
    """The tool-frame axis across the mast that is turned across the arm's vertical plane:
    the tool z axis made normal to the mast (x when the mast is z)."""
    for e in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        b = e - (e @ mast_axis) * mast_axis
        if np.linalg.norm(b) > 1e-6:
            return b / np.linalg.norm(b)
    raise AssertionError("unreachable")


def _target_rotations(p: np.ndarray, d: np.ndarray, psi: np.ndarray,
                      mast_axis: np.ndarray) -> np.ndarray:
    """Rotations ``(B, S, 3, 3)`` putting ``mast_axis`` along ``d (B, 3)`` (base frame), the
    reference axis turned by each ``psi (S,)`` from across the vertical plane through the
    base axis and ``p (B, 3)``."""
    up = np.array([0.0, 0.0, 1.0])
    radial = p * np.array([1.0, 1.0, 0.0])
    radial = np.where(np.linalg.norm(radial, axis=1, keepdims=True) < 1e-9,
                      np.array([1.0, 0.0, 0.0]), radial)
    n = np.cross(up, radial)
    n = n - (n * d).sum(axis=1, keepdims=True) * d
    bad = np.linalg.norm(n, axis=1) < 1e-9
    if bad.any():   # axis along the across direction: any normal will do
        alt = np.cross(d[bad], np.array([1.0, 0.0, 0.0]))
        n[bad] = np.where(np.linalg.norm(alt, axis=1, keepdims=True) < 1e-9,
                          np.cross(d[bad], np.array([0.0, 1.0, 0.0])), alt)
    n = _unit(n)
    m = np.cross(d, n)
    c, s = np.cos(psi), np.sin(psi)
    bw = c[None, :, None] * n[:, None, :] + s[None, :, None] * m[:, None, :]   # (B, S, 3)
    dw = np.broadcast_to(d[:, None, :], bw.shape)
    cw = np.cross(dw, bw)
    W = np.stack([dw, bw, cw], axis=-1)                    # world columns (B, S, 3, 3)
    bt = _tool_reference(mast_axis)
    Tt = np.stack([mast_axis, bt, np.cross(mast_axis, bt)], axis=-1)   # tool columns
    return W @ Tt.T


def _margin(model: RobotModel, Q: np.ndarray) -> np.ndarray:
    lo, hi = np.asarray(model.lower), np.asarray(model.upper)
    span = np.where(np.isfinite(hi - lo) & (hi > lo), hi - lo, 1.0)
    return np.min(np.minimum(Q - lo, hi - Q) / span, axis=-1)


def _strokes_ok(model: RobotModel, Q: np.ndarray) -> np.ndarray:
    """Whether every cylinder of ``model`` is inside its stroke at each ``Q (B, dof)``."""
    if "cylinders" not in model.extras or len(Q) == 0:
        return np.ones(len(Q), dtype=bool)
    from kinematics.cylinders import cylinder_set

    cs = cylinder_set(model)
    inside = cs.within_stroke(cs.lengths(Q))
    return np.all(np.stack([np.asarray(v, dtype=bool).reshape(len(Q))
                            for v in inside.values()]), axis=0)


def mast_errors(model: RobotModel, q: np.ndarray, frames: np.ndarray, heads: np.ndarray,
                axes: np.ndarray, mast_axis=(0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Angle (rad) between the mast and the pile axis, and distance (mm) of the tool point
    from the pile head, by FK of ``q (B, dof)`` at the set-ups ``frames (B, 4, 4)``."""
    T = frames @ fk(model, np.atleast_2d(q))
    a = T[:, :3, :3] @ np.asarray(mast_axis, dtype=float)
    ang = np.arctan2(np.linalg.norm(np.cross(a, axes), axis=1), (a * axes).sum(axis=1))
    return ang, np.linalg.norm(T[:, :3, 3] - heads, axis=1)


def _seeds(model: RobotModel, p: np.ndarray) -> np.ndarray:
    """Starting configurations ``(B, S, dof)`` of the numeric pass: the first joint turned
    towards each target ``p (B, 3)`` (base frame), the others at the middle of their
    ranges, the last one at each of ``SEED_ROTATOR`` (clipped to its limits)."""
    lo, hi = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
    S = np.broadcast_to(mid, (len(p), len(SEED_ROTATOR), model.dof)).copy()
    S[:, :, 0] = np.clip(np.arctan2(p[:, 1], p[:, 0]), lo[0], hi[0])[:, None]
    S[:, :, -1] = np.clip(SEED_ROTATOR, lo[-1], hi[-1])[None, :]
    return S


def axis_ik(model: RobotModel, p: np.ndarray, d: np.ndarray, q0: np.ndarray,
            mast_axis=(0.0, 1.0, 0.0), iterations: int = NUMERIC_ITERATIONS,
            centre: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool point on ``p (B, 3)`` and the tool-frame ``mast_axis`` along ``d (B, 3)``
    (the model's base frame), the turn about the axis free: damped least squares on the
    position and on the axis's cross product with ``d`` (the rotation about the mast
    projected out of the Jacobian), from ``q0 (B, dof)``, each step clipped to the joint
    limits, batched. ``centre`` > 0 also moves the joints towards the middle of their
    ranges in the null space of the task (the turn about the mast and any other
    redundancy), by that share of the way in the first iteration: a line of such steps
    stays off the limits. Returns ``q (B, dof)``, the position error (mm) and the axis angle (rad)
    reached: the nearest the limits allow, which the caller compares with its
    tolerances."""
    from kinematics.jacobian import jacobian_and_pose

    a_t = _unit(np.asarray(mast_axis, dtype=float))
    lo, hi = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    Q = np.clip(np.array(q0, dtype=float), lo, hi)
    eye = np.eye(6)
    span = np.where(np.isfinite(hi - lo) & (hi > lo), hi - lo, 1.0)
    mid = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
    one = len(Q) == 1   # one target: the compiled single-configuration kernel
    for it in range(iterations):
        if one:
            J1, T1 = jacobian_and_pose(model, np.ascontiguousarray(Q[0]))
            J, T = J1[None], T1[None]
        else:
            J, T = jacobian_and_pose(model, Q)
        a = T[:, :3, :3] @ a_t
        r = np.concatenate([POSITION_WEIGHT * (p - T[:, :3, 3]), np.cross(a, d)], axis=1)
        if it > 0 and float(np.max((r * r).sum(axis=1))) < CONVERGED:
            break
        # Rows: weighted linear velocity, and the angular velocity across the mast.
        P = eye[None, :3, :3] - a[:, :, None] * a[:, None, :]
        Jr = np.concatenate([POSITION_WEIGHT * J[:, :3], P @ J[:, 3:]], axis=1)
        err2 = (r * r).sum(axis=1)
        lam = NUMERIC_DAMPING + err2
        A = Jr @ np.swapaxes(Jr, 1, 2) + lam[:, None, None] * eye
        step = np.einsum("bji,bj->bi", Jr, np.linalg.solve(A, r[..., None])[..., 0])
        if centre > 0.0 and it == 0:
            pinv = np.swapaxes(np.linalg.solve(A, Jr), 1, 2)          # (B, dof, 6)
            null = np.eye(Q.shape[1])[None] - pinv @ Jr
            pull = centre * (mid - Q) / span * span.min()
            step = step + np.einsum("bij,bj->bi", null, pull)
        Q = np.clip(Q + step, lo, hi)
    T = fk(model, Q)
    a = T[:, :3, :3] @ a_t
    ang = np.arctan2(np.linalg.norm(np.cross(a, d), axis=1), (a * d).sum(axis=1))
    return Q, np.linalg.norm(T[:, :3, 3] - p, axis=1), ang


def _solve_poses(model: RobotModel, R: np.ndarray, P: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """IK of the poses ``R (B, 3, 3)``, ``P (B, 3)``: every solution within the limits,
    ``(K, dof)``, and the pose each belongs to ``(K,)``."""
    if len(R) == 0:
        return np.empty((0, model.dof)), np.empty(0, dtype=int)
    T = np.zeros((len(R), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, P, 1.0
    sols, owner = [], []
    for b, res in enumerate(solve_ik(model, T, all_solutions=True)):
        if res.success and len(res.solutions):
            S = np.atleast_2d(res.solutions)
            lo, hi = np.asarray(model.lower) - 1e-9, np.asarray(model.upper) + 1e-9
            S = S[np.all((S >= lo) & (S <= hi), axis=1)]
            sols.append(S)
            owner.append(np.full(len(S), b))
    if not sols:
        return np.empty((0, model.dof)), np.empty(0, dtype=int)
    return np.concatenate(sols), np.concatenate(owner)


def reach_table(model: RobotModel, plan: PilePlan, setups: np.ndarray, *,
                base_height: float = 500.0, approach: float = 300.0,
                mast_axis=(0.0, 1.0, 0.0), checkers: Callable[[int], Any] | None = None,
                usable: np.ndarray | None = None, progress: Progress = _quiet) -> ReachTable:
    """Which candidate set-ups reach which piles (module docstring), batched over every
    pile x set-up pair the arm's reach map lets through. ``checkers(m)``: the collision
    checker (``MotionChecker``) of set-up ``m`` (None: no obstacles); ``usable (M,)``: the
    candidates the carrier may stand at (None: all; the others reach nothing)."""
    S = np.asarray(setups, dtype=float).reshape(-1, 3)
    N, M, dof = len(plan), len(S), model.dof
    a_t = _unit(np.asarray(mast_axis, dtype=float))
    frames = setup_frames(S, base_height)
    inv = np.linalg.inv(frames)
    # Heads, approach points and axes in every set-up's base frame: (N, M, 3).
    Rb = inv[None, :, :3, :3]
    head_b = np.einsum("mij,nj->nmi", inv[:, :3, :3], plan.heads) + inv[None, :, :3, 3]
    axis_b = np.einsum("mij,nj->nmi", Rb[0], plan.axes)
    app_b = head_b - approach * axis_b
    rmap = _reach_map(model)
    near = _in_map(rmap, head_b) & _in_map(rmap, app_b)
    if usable is not None:
        near &= np.asarray(usable, dtype=bool)[None, :]
    stage = np.zeros((N, M), dtype=np.int8)
    stage[near] = 1
    q_best = np.full((N, M, dof), np.nan)
    margin = np.full((N, M), -np.inf)
    pairs = np.argwhere(near)
    progress(0.05, f"{len(pairs)} pile-set-up pairs within the arm's reach")
    poses = 0
    # Pass 1: closed-form (or the model's) IK of the exact axis at sampled turns about it;
    # pass 2: the axis-constrained numeric solve for the pairs still unreached.
    for attempt in range(2):
        if attempt == 1:
            pairs = pairs[stage[pairs[:, 0], pairs[:, 1]] < REACHED]
        if len(pairs) == 0:
            break
        n_, m_ = pairs[:, 0], pairs[:, 1]
        d = axis_b[n_, m_]
        p, pa = head_b[n_, m_], head_b[n_, m_] - approach * d
        if attempt == 0:
            R = _target_rotations(p, d, PSI_SAMPLES, a_t)                  # (B, S, 3, 3)
            B, Sn = R.shape[:2]
            Q, own = _solve_poses(model, R.reshape(-1, 3, 3), np.repeat(p, Sn, axis=0))
            poses += B * Sn
            progress(0.3, f"IK of {B * Sn} driving poses")
            # The approach pose of each (pair, turn) with a driving solution.
            cand = np.unique(own)
            _, own_a = _solve_poses(model, R.reshape(-1, 3, 3)[cand],
                                    np.repeat(pa, Sn, axis=0)[cand])
            poses += len(cand)
            app_ok = np.zeros(B * Sn, dtype=bool)
            app_ok[cand[np.unique(own_a)]] = True
            pair = own // Sn
            np.maximum.at(stage, (n_[pair], m_[pair]), 2)
            Q, pair = Q[app_ok[own]], pair[app_ok[own]]
        else:
            tol_p = np.minimum(plan.tol_position[n_], NUMERIC_POSITION_TOL)
            tol_a = plan.tol_angle[n_]
            seeds = _seeds(model, p)
            k = seeds.shape[1]
            rep = np.repeat(np.arange(len(p)), k)
            Q, e_p, e_a = axis_ik(model, p[rep], d[rep], seeds.reshape(-1, dof), a_t)
            poses += len(Q)
            ok = (e_p <= tol_p[rep]) & (e_a <= tol_a[rep])
            Q, pair = Q[ok], rep[ok]
            np.maximum.at(stage, (n_[pair], m_[pair]), 2)
            Qa, e_p, e_a = axis_ik(model, pa[pair], d[pair], Q, a_t)
            poses += len(Q)
            progress(0.6, f"numeric IK of {len(rep)} driving poses")
            ok = (e_p <= tol_p[pair]) & (e_a <= tol_a[pair])
            Q, pair = Q[ok], pair[ok]
        np.maximum.at(stage, (n_[pair], m_[pair]), 3)
        keep = _strokes_ok(model, Q)
        Q, pair = Q[keep], pair[keep]
        np.maximum.at(stage, (n_[pair], m_[pair]), 4)
        if checkers is not None and len(Q):
            free = np.ones(len(Q), dtype=bool)
            for m in np.unique(m_[pair]):
                sel = m_[pair] == m
                chk = checkers(int(m))
                if chk is not None:
                    free[sel] = np.asarray(chk.free(Q[sel]), dtype=bool)
            Q, pair = Q[free], pair[free]
        np.maximum.at(stage, (n_[pair], m_[pair]), REACHED)
        score = _margin(model, Q)
        for k in np.argsort(score):   # ascending: the best of a pair is written last
            i, j = n_[pair[k]], m_[pair[k]]
            if score[k] > margin[i, j]:
                margin[i, j], q_best[i, j] = score[k], Q[k]
    reach = stage == REACHED
    ax_err = np.full((N, M), np.nan)
    pos_err = np.full((N, M), np.nan)
    idx = np.argwhere(reach)
    if len(idx):
        e_a, e_p = mast_errors(model, q_best[idx[:, 0], idx[:, 1]], frames[idx[:, 1]],
                               plan.heads[idx[:, 0]], plan.axes[idx[:, 0]], a_t)
        ax_err[idx[:, 0], idx[:, 1]], pos_err[idx[:, 0], idx[:, 1]] = e_a, e_p
        # Past a tolerance (never, by construction): not reached.
        bad = (e_a > plan.tol_angle[idx[:, 0]] + 1e-12) | \
            (e_p > plan.tol_position[idx[:, 0]])
        reach[idx[bad, 0], idx[bad, 1]] = False
    progress(0.95, f"{int(reach.any(axis=1).sum())} of {N} piles reachable")
    return ReachTable(reach, q_best, ax_err, pos_err, margin, stage, poses)


# ---- 4. the cover ----------------------------------------------------------------------
@dataclass(frozen=True)
class CoverResult:
    """The set-ups chosen (indices into the candidates), how (``milp``: exact, or
    ``greedy``), whether the count is proven least (``optimal``), a lower bound on the least
    count (``lower_bound``: the optimum when exact, else the LP relaxation rounded up) and
    the LP relaxation's value, and a note."""

    chosen: np.ndarray
    method: str
    optimal: bool
    lower_bound: int
    lp_value: float
    note: str = ""


def _lp_bound(A: np.ndarray) -> float:
    from scipy.optimize import linprog

    res = linprog(np.ones(A.shape[1]), A_ub=-A.astype(float), b_ub=-np.ones(len(A)),
                  bounds=(0, 1), method="highs")
    return float(res.fun) if res.status == 0 else float("nan")


def _greedy(A: np.ndarray) -> np.ndarray:
    left = np.ones(len(A), dtype=bool)
    chosen = []
    Af = A.astype(np.int64)
    while left.any():
        gain = left.astype(np.int64) @ Af
        j = int(np.argmax(gain))
        chosen.append(j)
        left &= ~A[:, j]
    # Drop set-ups made redundant by later choices (last chosen kept first).
    chosen_arr = np.array(chosen, dtype=int)
    for j in list(chosen_arr[::-1]):
        rest = chosen_arr[chosen_arr != j]
        if len(rest) and A[:, rest].any(axis=1).all():
            chosen_arr = rest
    return np.sort(chosen_arr)


def cover_setups(A: np.ndarray, *, exact_max: int = 2000, time_limit: float = 10.0
                 ) -> CoverResult:
    """The fewest columns (set-ups) of ``A (N, M)`` bool covering every row with a True
    (rows without one are left out). Exact (``scipy.optimize.milp``, HiGHS, ``time_limit``
    s) when there are at most ``exact_max`` distinct columns; else, or when the MILP stops
    unproven, greedy (largest gain first, then redundant picks dropped) with the LP
    relaxation's bound."""
    A = np.asarray(A, dtype=bool)
    rows = A.any(axis=1)
    A = A[rows]
    if len(A) == 0:
        return CoverResult(np.empty(0, dtype=int), "none", True, 0, 0.0, "no reachable pile")
    used = np.flatnonzero(A.any(axis=0))
    _, first = np.unique(np.packbits(A[:, used], axis=0).T, axis=0, return_index=True)
    cols = used[np.sort(first)]        # one column per distinct coverage
    Ac = A[:, cols]
    lp = _lp_bound(Ac)
    bound = int(math.ceil(lp - 1e-6)) if math.isfinite(lp) else 1
    if len(cols) <= exact_max:
        from scipy.optimize import Bounds, LinearConstraint, milp

        res = milp(np.ones(len(cols)), integrality=np.ones(len(cols)), bounds=Bounds(0, 1),
                   constraints=LinearConstraint(Ac.astype(float), lb=1.0, ub=np.inf),
                   options={"time_limit": float(time_limit)})
        if res.x is not None and res.status == 0:
            pick = np.flatnonzero(res.x > 0.5)
            return CoverResult(np.sort(cols[pick]), "milp", True, len(pick), lp,
                               f"exact over {len(cols)} distinct candidate set-ups")
        note = f"the MILP ended unproven ({res.message}); greedy"
    else:
        note = f"{len(cols)} distinct candidate set-ups > exact_max {exact_max}: greedy"
    pick = _greedy(Ac)
    return CoverResult(np.sort(cols[pick]), "greedy", len(pick) <= bound, bound, lp, note)


# ---- 5. the whole plan ----------------------------------------------------------------
@dataclass
class PileOutcome:
    """One pile in the plan: ``index`` in the plan; ``setup``: index into
    ``PilesPlan.setups`` (-1: not driven, ``reason`` says why); ``order`` in the whole
    plan's driving order; ``q`` the driving configuration and its ``axis_error`` (rad) and
    ``position_error`` (mm) by FK; the times (s) of the arm's move to it, the mast lowered,
    driving and lifted, and its ``start`` and ``end`` from the start of the plan; ``move``:
    how the arm got there (``first`` at its set-up, ``joint``, ``raised``, ``planned``)."""

    index: int
    setup: int = -1
    order: int = -1
    q: np.ndarray | None = None
    axis_error: float = math.nan
    position_error: float = math.nan
    move_s: float = 0.0
    lower_s: float = 0.0
    drive_s: float = 0.0
    lift_s: float = 0.0
    start: float = math.nan
    end: float = math.nan
    reason: str = ""
    move: str = ""


@dataclass
class PilesPlan:
    """The plan (module docstring): ``setups (K, 3)`` the set-ups used in visiting order,
    ``candidates`` their indices among the candidates; ``piles``: per pile its outcome;
    ``setup_times (K, 4)``: arrival, start of work, end, relocation time; totals (s)."""

    plan: PilePlan
    setups: np.ndarray
    candidates: np.ndarray
    piles: list[PileOutcome]
    cover: CoverResult
    table: ReachTable
    setup_times: np.ndarray
    total_s: float
    work_s: float
    relocation_s: float
    travel_mm: float
    stats: dict = field(default_factory=dict)

    @property
    def unreached(self) -> list[PileOutcome]:
        return [p for p in self.piles if p.setup < 0]


def _timing(model: RobotModel):
    """(limits, hydraulics) the arm's motions are timed with: the model's joint speeds, the
    arm accelerations of the motion planner, the cylinders and the pump."""
    from planning.trajectories.hydraulic import hydraulic_limits
    from planning.trajectories.trajectory import ARM_ACCELERATION, Limits

    acc = np.where(model.revolute, ARM_ACCELERATION[0], ARM_ACCELERATION[1])
    return Limits(velocity=np.asarray(model.velocity_limits), acceleration=acc), \
        hydraulic_limits(model)


#: Joint-space deviation (rad) of the blends at the corners of a timed polyline, and the
#: intervals of the time-optimal grid.
BLEND = 0.01
TIMING_GRID = 80


def _duration(path: np.ndarray, timing, blend: float = BLEND) -> float:
    """Time-optimal duration (s) of the joint polyline ``path (n, dof)`` from rest to rest,
    its corners blended within ``blend`` rad (the dense steps of a Cartesian line are one
    smooth motion, not stops); 0 for a path that does not move."""
    from planning.trajectories.joint_path import smooth_polyline
    from planning.trajectories.topp import time_optimal

    P = np.asarray(path, dtype=float)
    if len(P) < 2 or np.max(np.abs(P - P[0])) < 1e-9:
        return 0.0
    res = time_optimal(smooth_polyline(P, blend), *timing, grid=TIMING_GRID)
    if not res.success:
        raise RuntimeError(f"timing failed: {res.message}")
    return float(res.duration)


#: Height step (mm) of the points on a candidate's vertical axis checked for the carrier.
CARRIER_STEP = 250.0


def carrier_clear(scene: Any, setups: np.ndarray, base_height: float,
                  radius: float) -> np.ndarray:
    """Whether the carrier may stand at each set-up ``(M, 3)``: every point of its vertical
    axis from the ground (z = 0) to the arm's base (``CARRIER_STEP`` apart) at least
    ``radius`` mm from every obstacle of ``scene`` (its compiled ``object_distance``).
    All True without a scene or with ``radius`` 0."""
    S = np.asarray(setups, dtype=float).reshape(-1, 3)
    if scene is None or not len(scene) or radius <= 0.0:
        return np.ones(len(S), dtype=bool)
    z = np.linspace(0.0, base_height, max(2, int(math.ceil(abs(base_height) / CARRIER_STEP))
                                          + 1))
    P = np.concatenate([np.repeat(S[:, :2], len(z), axis=0),
                        np.tile(z, len(S))[:, None]], axis=1)
    d = scene.compiled().object_distance(P).min(axis=1).reshape(len(S), len(z))
    return d.min(axis=1) >= radius


#: Steps of the mast's line (mm), the iterations of each step's solve, and the largest
#: joint motion of one step (rad): more is a jump of branch, not a line.
LINE_STEP = 10.0
LINE_ITERATIONS = 40
LINE_JUMP = 0.2
#: The pull towards the middle of the joint ranges along the line (``axis_ik``'s centre).
LINE_CENTRE = 0.1


def mast_line(model: RobotModel, checker: Any, q_drive: np.ndarray, axis: np.ndarray,
              approach: float, mast_axis=(0.0, 1.0, 0.0), *, tol_position: float = 0.5,
              tol_angle: float = DEFAULT_TOL_ANGLE, step: float = LINE_STEP
              ) -> tuple[np.ndarray, str]:
    """The mast lifted from the driving configuration ``q_drive`` by ``approach`` mm up the
    pile ``axis`` (base frame, pointing down) along a straight line, the mast held along
    the axis within ``tol_angle`` rad, the turn about it free (``axis_ik`` at every
    ``step`` mm from the step before), the tool point within ``tol_position`` mm of the
    line (at most ``NUMERIC_POSITION_TOL``); every motion between steps free
    (``checker.segment_free``). Reversed, it is the lowering. Returns the path ``(n, dof)``
    from ``q_drive`` up, and "" or why it stops."""
    a_t = _unit(np.asarray(mast_axis, dtype=float))
    d = _unit(np.asarray(axis, dtype=float))
    p0 = fk(model, q_drive)[:3, 3]
    n = max(1, int(math.ceil(approach / step)))
    tol_p = min(tol_position, NUMERIC_POSITION_TOL)
    path = [np.asarray(q_drive, dtype=float)]
    q = path[0]
    for k in range(1, n + 1):
        p = p0 - d * approach * k / n
        Q, e_p, e_a = axis_ik(model, p[None], d[None], q[None], a_t,
                              iterations=LINE_ITERATIONS, centre=LINE_CENTRE)
        where = f"{approach * k / n:.0f} mm up"
        if e_p[0] > tol_p or e_a[0] > tol_angle:
            return np.array(path), f"the joint limits stop the mast {where} " \
                f"({e_p[0]:.2g} mm, {e_a[0]:.2g} rad off the axis)"
        if np.max(np.abs(Q[0] - q)) > LINE_JUMP:
            return np.array(path), f"the arm would jump branch {where}"
        if not checker.segment_free(q, Q[0], ends=True):
            return np.array(path), f"the arm would hit the site {where}"
        q = Q[0]
        path.append(q)
    return np.array(path), ""


def _raised_routes(model: RobotModel, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
    """Second ways of a move whose straight joint motion collides: ``a``, the arm raised at
    ``a``'s swing, turned to ``b``'s swing raised, ``b`` (``(4, dof)`` each). Raised: the
    boom (joint 2) at the top of its range and the joints between it and the last two
    (stick, linkage) at the ends that stretch the arm up (the top of their ranges) or tuck
    it in (the bottom: the tool near the base axis, passing inside a tall obstacle)."""
    lo, hi = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    routes = []
    for rest in (hi, lo):
        up = np.array([a, b], dtype=float)
        if model.dof < 4 or not np.isfinite(hi[1]):
            return routes
        up[:, 1] = hi[1]
        up[:, 2:-2] = np.where(np.isfinite(rest[2:-2]), rest[2:-2], up[:, 2:-2])
        routes.append(np.stack([a, up[0], up[1], b]))
    return routes


def _travel_costs(model: RobotModel, Q: np.ndarray) -> np.ndarray:
    """Lower bounds of the joint move times between configurations ``Q (n, dof)``: the
    slowest joint at its top speed (symmetric, s)."""
    v = np.asarray(model.velocity_limits, dtype=float)
    v = np.where(np.isfinite(v) & (v > 0), v, 1.0)
    return np.max(np.abs(Q[:, None, :] - Q[None, :, :]) / v, axis=-1)


def _sequence(costs: np.ndarray, start_costs: np.ndarray | None, seed: int) -> np.ndarray:
    """An open-path order over the nodes of the symmetric ``costs`` (from a start with
    ``start_costs``, or from node 0 when None): ``planning.sequencing``'s ``auto``."""
    from planning.sequencing import SequencingProblem, make_sequencer

    n = len(costs)
    if n <= 1:
        return np.arange(n)
    C = 0.5 * (costs + costs.T)
    problem = SequencingProblem.from_costs(C, start_costs)
    seq = make_sequencer("auto", {"time_limit": 2.0})
    order = np.asarray(seq.solve(problem, np.random.default_rng(seed)).order, dtype=int)
    if len(order) < n:   # the free nodes only: node 0 goes first
        order = np.concatenate([[0], order])
    return order


def plan_piles(model: RobotModel, plan: PilePlan, candidates: np.ndarray, *,
               base_height: float = 500.0, approach: float = 300.0,
               mast_axis=(0.0, 1.0, 0.0), scene: Any = None, carrier_radius: float = 0.0,
               drive_time: float = 60.0,
               travel_speed: float = 500.0, setup_time: float = 0.0,
               carrier_start=None, exact_max: int = 2000, cover_time_limit: float = 10.0,
               move_time_limit: float = 2.0, seed: int = 0,
               progress: Progress = _quiet) -> PilesPlan:
    """The whole pile plan (module docstring). ``candidates (M, 3)`` set-ups [x, y,
    heading]; ``scene``: the site's obstacles as a ``CollisionScene`` in the site frame (None:
    none; the arm's self-collision is checked either way); ``drive_time`` s per pile;
    ``travel_speed`` mm/s of the carrier between set-ups (straight lines) and
    ``setup_time`` s at each; ``carrier_start`` [x, y]: where the carrier starts (None: at
    the first set-up); ``carrier_radius`` mm: candidates whose vertical axis, from the
    ground to the arm's base, comes closer than this to an obstacle are left out (the
    carrier stands there; 0: every candidate kept)."""
    from planning.collision import CollisionScene, RobotCollisionModel
    from planning.motion.checker import MotionChecker
    from planning.motion.planner import plan_motion

    t0 = time.perf_counter()
    C = np.asarray(candidates, dtype=float).reshape(-1, 3)
    a_t = _unit(np.asarray(mast_axis, dtype=float))
    frames = setup_frames(C, base_height)
    cm = RobotCollisionModel.from_model(model)
    kept: dict[int, Any] = {}

    def checker(m: int) -> Any:
        chk = kept.get(m)
        if chk is None:
            local = None
            if scene is not None and len(scene):
                inv = np.linalg.inv(frames[m])
                objs = []
                for o in scene.to_dicts():
                    pose = np.asarray(o.get("pose", np.eye(4)), dtype=float)
                    objs.append({**o, "pose": (inv @ pose).tolist()})
                local = CollisionScene.from_request({"objects": objs})
            chk = kept[m] = MotionChecker(cm, local)
        return chk

    usable = carrier_clear(scene, C, base_height, carrier_radius)
    table = reach_table(model, plan, C, base_height=base_height, approach=approach,
                        mast_axis=a_t, checkers=checker, usable=usable,
                        progress=lambda f, m: progress(0.6 * f, m))
    t_reach = time.perf_counter() - t0
    cover = cover_setups(table.reach, exact_max=exact_max, time_limit=cover_time_limit)
    progress(0.65, f"{len(cover.chosen)} set-ups ({cover.method})")
    N = len(plan)
    piles = [PileOutcome(i) for i in range(N)]
    for i in np.flatnonzero(~table.reach.any(axis=1)):
        piles[i].reason = table.why(int(i))
    # Each pile to the chosen set-up that holds it with the most room to the limits.
    chosen = cover.chosen
    score = np.where(table.reach[:, chosen], table.margin[:, chosen], -np.inf)
    assign = np.where(table.reach[:, chosen].any(axis=1), np.argmax(score, axis=1), -1) \
        if len(chosen) else np.full(N, -1)
    # The set-ups along the site.
    start_xy = None if carrier_start is None else np.asarray(carrier_start, dtype=float)
    pos = C[chosen, :2]
    if len(chosen) > 1:
        D = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
        d0 = None if start_xy is None else np.linalg.norm(pos - start_xy, axis=1)
        if d0 is None:   # start at the set-up with the least x (then y)
            first = int(np.lexsort((pos[:, 1], pos[:, 0]))[0])
            perm = np.r_[first, np.delete(np.arange(len(pos)), first)]
            site_order = perm[_sequence(D[np.ix_(perm, perm)], None, seed)]
        else:
            site_order = _sequence(D, d0, seed)
    else:
        site_order = np.arange(len(chosen))
    timing = _timing(model)
    where = start_xy if start_xy is not None else (pos[site_order[0]] if len(pos) else None)
    clock = 0.0
    travel = relocation = work = 0.0
    rows = []
    used_setups, used_cands = [], []
    global_order = 0
    n_lines = n_moves = n_planned = 0
    handed: dict[int, list[int]] = {}
    chosen, site_order = [int(c) for c in chosen], [int(s) for s in site_order]
    tried: set[tuple[int, int]] = set()
    extra = 0

    def hand_on(i: int, k: int) -> None:
        """Pile ``i`` failed at the ``k``-th set-up: on to a later one that reaches it, else
        to a further set-up (beyond the cover: the one that holds it with the most room)."""
        nonlocal extra
        tried.add((i, chosen[site_order[k]]))
        for s2 in site_order[k + 1:]:
            if table.reach[i, chosen[s2]] and (i, chosen[s2]) not in tried:
                handed.setdefault(s2, []).append(i)
                return
        left = table.reach[i] & ~np.isin(np.arange(len(C)), [c for p, c in tried if p == i])
        if left.any():
            c = int(np.argmax(np.where(left, table.margin[i], -np.inf)))
            chosen.append(c)
            site_order.append(len(chosen) - 1)
            handed[len(chosen) - 1] = [i]
            extra += 1

    k = -1
    while k + 1 < len(site_order):
        k += 1
        s = site_order[k]
        members = np.concatenate([np.flatnonzero(assign == s),
                                  np.array(handed.get(int(s), []), dtype=int)])
        m = int(chosen[s])
        progress(0.65 + 0.33 * k / max(len(site_order), 1),
                 f"set-up {k + 1} of {len(site_order)}: {len(members)} piles")
        chk = checker(m)
        # The mast lifted from each pile's driving configuration along its axis (reversed:
        # lowered); a pile whose line fails goes to another chosen set-up later, or fails.
        lines: dict[int, np.ndarray] = {}
        for i in members:
            d_b = frames[m, :3, :3].T @ plan.axes[i]
            path, why = mast_line(model, chk, table.q[i, m], d_b, approach, a_t,
                                  tol_position=float(plan.tol_position[i]),
                                  tol_angle=float(plan.tol_angle[i]))
            n_lines += 1
            if not why:
                lines[int(i)] = path
            else:
                piles[i].reason = f"the mast cannot be lowered along the pile axis: {why}"
                hand_on(int(i), k)
        ok = np.array(sorted(lines), dtype=int)
        if len(ok) == 0:
            continue
        Qa = np.stack([lines[int(i)][-1] for i in ok])
        costs = _travel_costs(model, Qa)
        order = ok[_sequence(costs, np.zeros(len(ok)), seed)]
        dist = float(np.linalg.norm(C[m, :2] - where)) if where is not None else 0.0
        reloc = dist / travel_speed + setup_time
        travel += dist
        relocation += reloc
        arrive = clock + dist / travel_speed
        clock += reloc
        begin = clock
        prev = None
        for i in order:
            P = piles[i]
            lift = lines[int(i)]
            qa = lift[-1]
            P.move_s = 0.0
            P.start = clock
            if prev is not None:
                n_moves += 1
                via = next((r for r in _raised_routes(model, prev, qa)
                            if all(chk.segment_free(a, b, ends=True)
                                   for a, b in zip(r[:-1], r[1:]))), None) \
                    if not chk.segment_free(prev, qa) else None
                if via is None and chk.segment_free(prev, qa):
                    P.move = "joint"
                    P.move_s = _duration(np.stack([prev, qa]), timing)
                elif via is not None:
                    P.move = "raised"
                    P.move_s = _duration(via, timing)
                else:
                    n_planned += 1
                    mr = plan_motion(chk, prev, qa, time_limit=move_time_limit, seed=seed,
                                     trajectory=False)
                    if not mr.success:
                        P.reason = f"no collision-free move to it: {mr.status.value} ({mr.message})"
                        P.start = math.nan
                        hand_on(int(i), k)
                        continue
                    P.move = "planned"
                    P.move_s = _duration(np.asarray(mr.path), timing)
            else:
                P.move = "first"
            P.lower_s = P.lift_s = _duration(lift, timing)
            P.drive_s = drive_time
            clock += P.move_s + P.lower_s + P.drive_s + P.lift_s
            P.end = clock
            P.setup, P.order, P.q = len(used_setups), global_order, table.q[i, m]
            P.axis_error = float(table.axis_error[i, m])
            P.position_error = float(table.position_error[i, m])
            P.reason = ""
            global_order += 1
            prev = qa
        if prev is None:
            continue
        work += clock - begin
        rows.append([arrive, begin, clock, reloc])
        used_setups.append(C[m])
        used_cands.append(m)
        where = C[m, :2]
    stats = {"reach_s": t_reach, "extra_setups": extra,
             "candidates_blocked": int((~usable).sum()), "ik_poses": table.poses, "lines": n_lines,
             "moves": n_moves, "moves_planned": n_planned,
             "runtime_s": time.perf_counter() - t0}
    progress(1.0, "done")
    return PilesPlan(plan, np.array(used_setups).reshape(-1, 3),
                     np.array(used_cands, dtype=int), piles, cover, table,
                     np.array(rows).reshape(-1, 4), clock, work, relocation, travel, stats)
