"""Monte Carlo workspace of a robot's tool point (papers 000 section 3.7, 004 section 5).

The samples are taken in parts of ``PART`` samples, each in FK batches of ``CHUNK``, in two
passes, so memory grows with ``PART``, not with the sample count, and the parts of a pass can
be computed anywhere (a workspace job's steps, ``app.jobs.kinds``):

1. ``part_bounds`` (per part): FK of the part's samples; their extents (least and largest
   x, y, z, distance from the base z axis, height along it);
2. ``workspace_grid``: the parts' extents merged; the voxel edge (default: the largest extent
   / ``AUTO_VOXEL_DIVISIONS``) and which samples are returned (a seeded subsample of all);
3. ``part_cells`` (per part): FK of the same samples again (recomputed from the seed, never
   shipped); the voxels they occupy (sorted packed ``int64`` keys), their counts per cell of
   the three projection images over the whole workspace's range, and the part's share of the
   returned points;
4. ``assemble``: the union of the keys (the volume), the images summed, the points in
   sampling order.

``sample_workspace`` runs these in turn (keeping a pass's points for the next when there are
at most ``KEEP_POINTS`` samples, which changes nothing but the time). Sample ``i``'s joint
values are the ``i``-th of the draws of one generator, ``numpy.random.default_rng(seed)``,
whatever part it is in: a part's generator is the seed's PCG64 stream advanced past the
draws of the samples before the part. FK batches start at multiples of ``CHUNK`` whatever the
part size (a multiple of ``CHUNK``). So the figures are the same however many parts there are
and wherever each is computed, and equal those of sampling every point at once in one process.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from .fk import fk
from .model import RobotModel
from .transforms import invert_pose

__all__ = [
    "Workspace",
    "PartBounds",
    "WorkspaceGrid",
    "PartCells",
    "sample_workspace",
    "workspace_report",
    "part_count",
    "part_range",
    "part_bounds",
    "workspace_grid",
    "part_cells",
    "assemble",
    "returned_indices",
    "pass2_work",
    "DEFAULT_SAMPLES",
    "MAX_SAMPLES",
    "PART",
    "CHUNK",
]

DEFAULT_SAMPLES = 30_000
MAX_SAMPLES = 2_000_000
#: Configurations per FK call; bounds memory (about 13 MB of poses per chunk).
CHUNK = 50_000
#: Samples per part (a multiple of ``CHUNK``): one step of a workspace job, about 1 s of FK
#: per pass for a six-joint arm; a part's working memory is about 60 MB at most.
PART = 1_000_000
#: ``sample_workspace`` keeps the first pass's points for the second up to this many samples
#: (24 bytes each); above, it computes them again, as a job's steps do.
KEEP_POINTS = 2_000_000
#: Work of a sample in the second pass relative to the first (FK and extents), measured on
#: a six-joint arm: by (projections counted, the first pass's points kept).
_PASS2_WORK = {(True, False): 1.6, (False, False): 0.9, (True, True): 0.6, (False, True): 0.3}
#: Voxel edge used when none is given: the largest extent divided by this.
AUTO_VOXEL_DIVISIONS = 30
#: Largest voxel edge accepted (mm): a kilometre, far beyond any arm.
MAX_VOXEL = 1e6
#: Finest voxel grid accepted for the volume estimate.
MAX_VOXELS_PER_AXIS = 100_000
#: Bits of a voxel index along one axis in a packed key (``MAX_VOXELS_PER_AXIS`` fits).
_KEY_BITS = 17
#: Cells along each axis of the projection images.
PROJECTION_BINS = 64
#: The projection images: name -> (first axis, second axis).
PROJECTIONS = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}

Progress = Callable[[float], None]


@dataclass(frozen=True)
class Workspace:
    """Sampled workspace; lengths in mm, in the world frame.

    ``points (K, 3)``: the tool positions of samples ``indices (K,)`` (in sampling order):
    every sample, or the seeded subsample asked for (``sample_workspace``'s
    ``return_points``). ``radial`` and ``vertical`` are measured in the robot's base frame:
    distance from the base z axis and height along it. ``volume`` (mm^3) counts the voxels of
    edge ``voxel`` (a grid from ``min``) that hold at least one sample: an estimate that
    grows with the sample count. ``projections`` maps "xy", "xz", "yz" to sample counts per
    cell ``(bins, bins)`` with their cell ``edges`` (first axis = first letter); empty when
    not asked for.
    """

    samples: int
    seed: int
    points: np.ndarray
    min: np.ndarray
    max: np.ndarray
    radial: tuple[float, float]
    vertical: tuple[float, float]
    voxel: float
    volume: float
    projections: dict[str, np.ndarray]
    edges: dict[str, tuple[np.ndarray, np.ndarray]]
    indices: np.ndarray


@dataclass(frozen=True)
class PartBounds:
    """Extents of one part's tool positions: ``lo``, ``hi (3,)`` mm (world frame),
    ``radial`` and ``vertical`` ``(min, max)`` mm (base frame)."""

    lo: np.ndarray
    hi: np.ndarray
    radial: tuple[float, float]
    vertical: tuple[float, float]


@dataclass(frozen=True)
class WorkspaceGrid:
    """The whole workspace's extents (``PartBounds`` merged), the voxel edge (mm) and the
    sorted indices ``(K,)`` of the samples whose points are returned."""

    samples: int
    seed: int
    lo: np.ndarray
    hi: np.ndarray
    radial: tuple[float, float]
    vertical: tuple[float, float]
    voxel: float
    indices: np.ndarray

    def edges(self) -> list[np.ndarray]:
        """Cell edges ``(bins + 1,)`` of the projection images along x, y and z: those
        ``numpy.histogram2d`` uses over the range ``[lo, max(hi, lo + 1e-9)]``."""
        out = []
        for i in range(3):
            rng = (self.lo[i], max(self.hi[i], self.lo[i] + 1e-9))
            _, e, _ = np.histogram2d(np.empty(0), np.empty(0), bins=PROJECTION_BINS,
                                     range=[rng, rng])
            out.append(e)
        return out


@dataclass(frozen=True)
class PartCells:
    """What one part adds: the voxels its samples occupy (``keys``, sorted, unique, packed
    ``int64``), its counts per projection cell (``(bins, bins)`` ``int64`` by name; empty
    without projections) and the tool positions ``(k, 3)`` of its returned samples."""

    keys: np.ndarray
    counts: dict[str, np.ndarray]
    points: np.ndarray


# ---- parts ---------------------------------------------------------------------------------
def part_count(samples: int, part: int | None = None) -> int:
    """Parts of ``samples`` samples (``part`` each, default ``PART``)."""
    return max(1, -(-int(samples) // _part_size(part)))


def part_range(samples: int, index: int, part: int | None = None) -> tuple[int, int]:
    """Samples ``[start, stop)`` of part ``index``."""
    size = _part_size(part)
    if not 0 <= index < part_count(samples, size):
        raise ValueError(f"part {index} out of range for {samples} samples")
    return index * size, min(samples, (index + 1) * size)


def _part_size(part: int | None) -> int:
    size = PART if part is None else int(part)
    if size < CHUNK or size % CHUNK:
        raise ValueError(f"a part must be a multiple of CHUNK ({CHUNK}) samples, got {size}")
    return size


def pass2_work(projections: bool, kept: bool = False) -> float:
    """Work of a sample in ``part_cells`` relative to ``part_bounds`` (progress weights):
    with or without the projections, with the points kept from pass 1 or computed again."""
    return _PASS2_WORK[bool(projections), bool(kept)]


def _tool_points(model: RobotModel, seed: int, start: int, stop: int,
                 progress: Progress | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """``(first sample, tool positions (n, 3))`` of samples ``[start, stop)`` in FK batches
    that start at multiples of ``CHUNK``: the joint values are draws ``start * dof`` on of
    ``default_rng(seed)``'s stream, uniform within the joint limits."""
    bits = np.random.PCG64(seed)  # default_rng(seed)'s bit generator
    bits.advance(start * model.dof)  # one 64-bit draw per uniform value
    rng = np.random.Generator(bits)
    for s, e in _batches(start, stop):
        q = rng.uniform(model.lower, model.upper, size=(e - s, model.dof))
        yield s, fk(model, q)[:, :3, 3]
        if progress is not None:
            progress((e - start) / max(stop - start, 1))


def _radial_vertical(model: RobotModel, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from the base z axis and height along it ``(n,)`` of points ``P (n, 3)``,
    element by element (the same figures for a point in any batch)."""
    T_base_world = invert_pose(model.base)
    R, t = T_base_world[:3, :3], T_base_world[:3, 3]
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    lx = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z + t[0]
    ly = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z + t[1]
    lz = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z + t[2]
    return np.hypot(lx, ly), lz


def _bounds_pass(model: RobotModel, samples: int, seed: int, index: int, part: int | None,
                 keep: bool, progress: Progress | None
                 ) -> tuple[PartBounds, np.ndarray | None]:
    start, stop = part_range(samples, index, part)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    r_lo = v_lo = math.inf
    r_hi = v_hi = -math.inf
    kept = np.empty((stop - start, 3)) if keep else None
    for s, P in _tool_points(model, seed, start, stop, progress):
        lo, hi = np.minimum(lo, P.min(axis=0)), np.maximum(hi, P.max(axis=0))
        r, v = _radial_vertical(model, P)
        r_lo, r_hi = min(r_lo, float(r.min())), max(r_hi, float(r.max()))
        v_lo, v_hi = min(v_lo, float(v.min())), max(v_hi, float(v.max()))
        if kept is not None:
            kept[s - start : s - start + len(P)] = P
    return PartBounds(lo, hi, (r_lo, r_hi), (v_lo, v_hi)), kept


def part_bounds(model: RobotModel, samples: int, seed: int, index: int, *,
                part: int | None = None, progress: Progress | None = None) -> PartBounds:
    """Pass 1 of part ``index`` of a ``samples``-sample workspace (module docstring)."""
    return _bounds_pass(model, samples, seed, index, part, False, progress)[0]


def returned_indices(samples: int, seed: int, count: int | None) -> np.ndarray:
    """Sorted indices ``(k,)`` of the ``k = min(count, samples)`` samples whose points are
    returned: a seeded choice without replacement (None: every sample)."""
    k = samples if count is None else min(int(count), samples)
    if k >= samples:
        return np.arange(samples, dtype=np.int64)
    return np.sort(np.random.default_rng(seed).choice(samples, size=k, replace=False))


def _check_voxel(voxel: float | None) -> None:
    if voxel is not None and not 0 < voxel <= MAX_VOXEL:
        raise ValueError(f"voxel must be in (0, {MAX_VOXEL:g}] mm, got {voxel}")


def workspace_grid(bounds: Sequence[PartBounds], samples: int, seed: int,
                   voxel: float | None = None, return_points: int | None = None
                   ) -> WorkspaceGrid:
    """The parts' extents merged, the voxel edge (``voxel`` mm, default the largest extent
    / ``AUTO_VOXEL_DIVISIONS``) and the returned samples (``returned_indices``). ValueError
    for a voxel finer than ``MAX_VOXELS_PER_AXIS`` cells across the workspace."""
    _check_voxel(voxel)
    if not bounds:
        raise ValueError("a workspace needs the bounds of at least one part")
    lo = np.minimum.reduce([b.lo for b in bounds])
    hi = np.maximum.reduce([b.hi for b in bounds])
    extent = float(np.max(hi - lo))
    if voxel is None:
        voxel = max(extent / AUTO_VOXEL_DIVISIONS, 1e-6)
    if extent / voxel > MAX_VOXELS_PER_AXIS:
        raise ValueError(
            f"voxel {voxel} mm is too small for a workspace {extent:.1f} mm across: at most "
            f"{MAX_VOXELS_PER_AXIS} voxels per axis"
        )
    return WorkspaceGrid(
        samples=samples, seed=seed, lo=lo, hi=hi,
        radial=(min(b.radial[0] for b in bounds), max(b.radial[1] for b in bounds)),
        vertical=(min(b.vertical[0] for b in bounds), max(b.vertical[1] for b in bounds)),
        voxel=float(voxel), indices=returned_indices(samples, seed, return_points),
    )


def _cell_index(P: np.ndarray, edges: np.ndarray, axis: int) -> np.ndarray:
    """Projection cell ``(n,)`` (0..bins-1) of each point along ``axis``, as
    ``numpy.histogram2d`` bins it (a point on the last edge in the last cell). Points are
    within the range by construction; one a hair outside (FK recomputed on another kind of
    CPU) is counted in the nearest cell rather than lost."""
    x = P[:, axis]
    b = np.searchsorted(edges, x, side="right")
    b[x == edges[-1]] -= 1
    return np.clip(b - 1, 0, PROJECTION_BINS - 1)


def _cells_of(P: np.ndarray, grid: WorkspaceGrid, edges: list[np.ndarray] | None,
              keys: list[np.ndarray], counts: dict[str, np.ndarray]) -> None:
    cells = np.floor((P - grid.lo) / grid.voxel).astype(np.int64)
    np.clip(cells, 0, (1 << _KEY_BITS) - 1, out=cells)
    keys.append(np.unique((cells[:, 0] << (2 * _KEY_BITS)) | (cells[:, 1] << _KEY_BITS)
                          | cells[:, 2]))
    if edges is not None:
        b = [_cell_index(P, edges[i], i) for i in range(3)]
        for name, (i, j) in PROJECTIONS.items():
            counts[name] += np.bincount(b[i] * PROJECTION_BINS + b[j],
                                        minlength=PROJECTION_BINS**2
                                        ).reshape(PROJECTION_BINS, PROJECTION_BINS)


def part_cells(model: RobotModel, grid: WorkspaceGrid, index: int, projections: bool = True,
               *, part: int | None = None, points: np.ndarray | None = None,
               progress: Progress | None = None) -> PartCells:
    """Pass 2 of part ``index`` (module docstring); ``points (n, 3)``: the part's tool
    positions if the caller kept them from pass 1 (else they are computed again)."""
    start, stop = part_range(grid.samples, index, part)
    edges = grid.edges() if projections else None
    keys: list[np.ndarray] = []
    counts = {name: np.zeros((PROJECTION_BINS, PROJECTION_BINS), dtype=np.int64)
              for name in PROJECTIONS} if projections else {}
    lo, hi = np.searchsorted(grid.indices, [start, stop])
    mine = grid.indices[lo:hi]
    returned = np.empty((len(mine), 3))
    if points is not None:
        batches: Iterator[tuple[int, np.ndarray]] = (
            (s, points[s - start : e - start]) for s, e in _batches(start, stop))
    else:
        batches = _tool_points(model, grid.seed, start, stop, progress)
    at = 0
    for s, P in batches:
        _cells_of(P, grid, edges, keys, counts)
        j = np.searchsorted(mine, s + len(P))
        returned[at:j] = P[mine[at:j] - s]
        at = j
        if points is not None and progress is not None:
            progress((s + len(P) - start) / max(stop - start, 1))
    merged = np.unique(np.concatenate(keys)) if keys else np.empty(0, dtype=np.int64)
    return PartCells(merged, counts, returned)


def _batches(start: int, stop: int) -> Iterator[tuple[int, int]]:
    """FK batches ``[s, e)`` of samples ``[start, stop)``: cut at multiples of ``CHUNK``."""
    s = start
    while s < stop:
        e = min(stop, (s // CHUNK + 1) * CHUNK)
        yield s, e
        s = e


def assemble(grid: WorkspaceGrid, parts: Sequence[PartCells], projections: bool = True
             ) -> Workspace:
    """The workspace of every part's cells (in part order)."""
    keys = np.unique(np.concatenate([p.keys for p in parts]))
    images, edges = {}, {}
    if projections:
        e = grid.edges()
        for name, (i, j) in PROJECTIONS.items():
            images[name] = np.sum([p.counts[name] for p in parts], axis=0, dtype=np.int64)
            edges[name] = (e[i], e[j])
    points = np.concatenate([p.points for p in parts]) if parts else np.empty((0, 3))
    return Workspace(
        samples=grid.samples, seed=grid.seed, points=points, min=grid.lo, max=grid.hi,
        radial=grid.radial, vertical=grid.vertical, voxel=grid.voxel,
        volume=float(len(keys)) * grid.voxel**3, projections=images, edges=edges,
        indices=grid.indices,
    )


# ---- the whole -----------------------------------------------------------------------------
def sample_workspace(
    model: RobotModel,
    samples: int = DEFAULT_SAMPLES,
    *,
    seed: int = 0,
    voxel: float | None = None,
    return_points: int | None = None,
    projections: bool = True,
    progress: Callable[[float], None] | None = None,
    max_samples: float = MAX_SAMPLES,
) -> Workspace:
    """Sample ``samples`` configurations uniformly within the joint limits (seeded) and
    measure where the tool goes, as the papers' Monte Carlo method does (module docstring).

    ``return_points``: keep the points of that many samples (a seeded subsample, in sampling
    order; None: every sample, 24 bytes each). ``projections``: count the projection images.
    ``progress(f)`` is called after each FK batch; ``max_samples`` caps ``samples`` (jobs
    allow more than calls). ValueError for a sample count or voxel out of range."""
    if not 1 <= samples <= max_samples:
        raise ValueError(f"samples must be between 1 and {max_samples}, got {samples}")
    _check_voxel(voxel)
    n_parts = part_count(samples)
    keep = samples <= KEEP_POINTS
    w1, w2 = 1.0, pass2_work(projections, keep)
    total = samples * (w1 + w2)

    def sub(done: float, weight: float, n: int) -> Progress | None:
        if progress is None:
            return None
        return lambda f: progress(min(1.0, (done + weight * n * f) / total))

    bounds, kept = [], []
    for k in range(n_parts):
        start, stop = part_range(samples, k)
        b, P = _bounds_pass(model, samples, seed, k, None, keep,
                            sub(w1 * start, w1, stop - start))
        bounds.append(b)
        kept.append(P)
    grid = workspace_grid(bounds, samples, seed, voxel, return_points)
    cells = []
    for k in range(n_parts):
        start, stop = part_range(samples, k)
        cells.append(part_cells(model, grid, k, projections, points=kept[k],
                                progress=sub(w1 * samples + w2 * start, w2, stop - start)))
        kept[k] = None
    return assemble(grid, cells, projections)


def workspace_report(ws: Workspace, return_points: int, projections: bool) -> dict:
    """The workspace as plain JSON-ready data: extents, ranges, volume, up to
    ``return_points`` points (a seeded subsample, in sampling order: ``returned_indices``)
    and, optionally, the projection images with their cell edges. ``ws`` holds every
    sample's point or exactly that subsample (``sample_workspace``'s ``return_points``)."""
    k = min(return_points, ws.samples)
    if len(ws.indices) == ws.samples:
        points = ws.points[returned_indices(ws.samples, ws.seed, k)]
    elif len(ws.indices) == k:
        points = ws.points
    else:
        raise ValueError(f"the workspace keeps {len(ws.indices)} points; sample it with "
                         f"return_points={k}")
    if projections and not ws.projections:
        raise ValueError("the workspace was sampled without its projections")
    out = {
        "samples": ws.samples,
        "seed": ws.seed,
        "min": ws.min.tolist(),
        "max": ws.max.tolist(),
        "radial": list(ws.radial),
        "vertical": list(ws.vertical),
        "voxel": ws.voxel,
        "volume": ws.volume,
        "points": points.tolist(),
    }
    if projections:
        out["projections"] = {
            name: {
                "counts": H.tolist(),
                "first_edges": ws.edges[name][0].tolist(),
                "second_edges": ws.edges[name][1].tolist(),
            }
            for name, H in ws.projections.items()
        }
    return out
