"""Monte Carlo workspace of a robot's tool point (papers 000 section 3.7, 004 section 5)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .fk import fk
from .model import RobotModel
from .transforms import invert_pose

__all__ = ["Workspace", "sample_workspace", "workspace_report", "DEFAULT_SAMPLES", "MAX_SAMPLES"]

DEFAULT_SAMPLES = 30_000
MAX_SAMPLES = 2_000_000
#: Configurations per FK call; bounds memory (about 13 MB of poses per chunk).
CHUNK = 50_000
#: Voxel edge used when none is given: the largest extent divided by this.
AUTO_VOXEL_DIVISIONS = 30
#: Largest voxel edge accepted (mm): a kilometre, far beyond any arm.
MAX_VOXEL = 1e6
#: Finest voxel grid accepted for the volume estimate.
MAX_VOXELS_PER_AXIS = 100_000
#: Cells along each axis of the projection images.
PROJECTION_BINS = 64


@dataclass(frozen=True)
class Workspace:
    """Sampled workspace. Points ``(N, 3)`` mm in the world frame.

    ``radial`` and ``vertical`` are measured in the robot's base frame: distance from the
    base z axis and height along it. ``volume`` (mm^3) counts the voxels of edge ``voxel``
    that hold at least one sample: an estimate that grows with the sample count.
    ``projections`` maps "xy", "xz", "yz" to sample counts per cell ``(bins, bins)`` with
    their cell ``edges`` (first axis = first letter).
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


def sample_workspace(
    model: RobotModel,
    samples: int = DEFAULT_SAMPLES,
    *,
    seed: int = 0,
    voxel: float | None = None,
    progress: Callable[[float], None] | None = None,
    max_samples: float = MAX_SAMPLES,
) -> Workspace:
    """Sample ``samples`` configurations uniformly within the joint limits (seeded) and
    collect the tool positions, as the papers' Monte Carlo method does. ``progress(f)`` is
    called after each chunk; ``max_samples`` caps ``samples`` (jobs allow more than calls)."""
    if not 1 <= samples <= max_samples:
        raise ValueError(f"samples must be between 1 and {max_samples}, got {samples}")
    if voxel is not None and not 0 < voxel <= MAX_VOXEL:
        raise ValueError(f"voxel must be in (0, {MAX_VOXEL:g}] mm, got {voxel}")
    rng = np.random.default_rng(seed)
    points = np.empty((samples, 3))
    for start in range(0, samples, CHUNK):
        n = min(CHUNK, samples - start)
        q = rng.uniform(model.lower, model.upper, size=(n, model.dof))
        points[start : start + n] = fk(model, q)[:, :3, 3]
        if progress is not None:
            progress((start + n) / samples)
    lo, hi = points.min(axis=0), points.max(axis=0)

    T_inv = invert_pose(model.base)
    local = points @ T_inv[:3, :3].T + T_inv[:3, 3]
    r = np.hypot(local[:, 0], local[:, 1])

    extent = float(np.max(hi - lo))
    if voxel is None:
        voxel = max(extent / AUTO_VOXEL_DIVISIONS, 1e-6)
    if extent / voxel > MAX_VOXELS_PER_AXIS:
        raise ValueError(
            f"voxel {voxel} mm is too small for a workspace {extent:.1f} mm across: at most "
            f"{MAX_VOXELS_PER_AXIS} voxels per axis"
        )
    cells = np.floor((points - lo) / voxel).astype(np.int64)
    volume = float(len(np.unique(cells, axis=0))) * voxel**3

    projections, edges = {}, {}
    for name, (i, j) in {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}.items():
        H, ei, ej = np.histogram2d(
            points[:, i], points[:, j], bins=PROJECTION_BINS,
            range=[[lo[i], max(hi[i], lo[i] + 1e-9)], [lo[j], max(hi[j], lo[j] + 1e-9)]],
        )
        projections[name] = H.astype(np.int64)
        edges[name] = (ei, ej)
    return Workspace(
        samples=samples, seed=seed, points=points, min=lo, max=hi,
        radial=(float(r.min()), float(r.max())),
        vertical=(float(local[:, 2].min()), float(local[:, 2].max())),
        voxel=float(voxel), volume=volume, projections=projections, edges=edges,
    )


def workspace_report(ws: Workspace, return_points: int, projections: bool) -> dict:
    """The workspace as plain JSON-ready data: extents, ranges, volume, up to
    ``return_points`` points (a seeded subsample, in sampling order) and, optionally, the
    projection images with their cell edges."""
    k = min(return_points, ws.samples)
    idx = np.sort(np.random.default_rng(ws.seed).choice(ws.samples, size=k, replace=False))
    out = {
        "samples": ws.samples,
        "seed": ws.seed,
        "min": ws.min.tolist(),
        "max": ws.max.tolist(),
        "radial": list(ws.radial),
        "vertical": list(ws.vertical),
        "voxel": ws.voxel,
        "volume": ws.volume,
        "points": ws.points[idx].tolist(),
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
