"""How close a sampled motion comes to each of its limits.

``limit_ratios`` gives, per sample, ``|value| / limit`` for every joint's velocity,
acceleration and jerk, every cylinder's speed (against its extension or retraction limit,
whichever way it moves) and the pump's flow; ``binding`` names, per sample, the limits at
which the motion runs (ratio within ``BINDING_TOL`` of 1): ``"<joint> velocity"``,
``"<joint> acceleration"``, ``"<joint> jerk"``, ``"<cylinder> extension"``,
``"<cylinder> retraction"``, ``"pump"``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hydraulic import LPM_TO_MM3_PER_S, HydraulicLimits
from .trajectory import PEAK_GRID, Trajectory, _poly_at

__all__ = [
    "BINDING_TOL",
    "Ratios",
    "limit_ratios",
    "binding",
    "hydraulic_peaks",
    "piece_samples",
    "stretch_to_limits",
]

#: A limit binds at a sample where the value is within this fraction of it.
BINDING_TOL = 0.01


@dataclass(frozen=True)
class Ratios:
    """``|value| / limit`` per sample (0 where there is no limit): ``velocity``,
    ``acceleration``, ``jerk (S, dof)``; ``cylinder (S, C)``; ``pump (S,)``. ``speeds``
    (mm/s, ``(S, C)``) and ``flow`` (mm^3/s, ``(S,)``) when the robot has hydraulics."""

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    cylinder: np.ndarray
    pump: np.ndarray
    speeds: np.ndarray | None = None
    flow: np.ndarray | None = None

    def first_order(self) -> np.ndarray:
        """Largest velocity-type ratio per sample (joints, cylinders, pump): ``(S,)``."""
        return np.maximum.reduce([self.velocity.max(axis=1, initial=0.0),
                                  self.cylinder.max(axis=1, initial=0.0), self.pump])

    def worst(self) -> dict[str, float]:
        """The largest ratio of each kind over all samples."""
        return {"velocity": float(self.first_order().max(initial=0.0)),
                "acceleration": float(self.acceleration.max(initial=0.0)),
                "jerk": float(self.jerk.max(initial=0.0))}


def _ratio(values: np.ndarray, limit: np.ndarray | None) -> np.ndarray:
    if limit is None:
        return np.zeros_like(values)
    lim = np.broadcast_to(np.asarray(limit, dtype=float), values.shape[-1:])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(np.isfinite(lim), np.abs(values) / lim, 0.0)
    return r


def limit_ratios(q, qd, qdd, qddd, velocity, acceleration, jerk,
                 hydraulics: HydraulicLimits | None) -> Ratios:
    """Ratios of samples ``q, qd, qdd, qddd (S, dof)`` (``qddd`` may be None) to per-joint
    limits ``(dof,)`` (None: none) and the hydraulic limits."""
    qd = np.asarray(qd, dtype=float)
    S = len(qd)
    jerk_r = np.zeros_like(qd) if qddd is None else _ratio(np.asarray(qddd), jerk)
    if hydraulics is None:
        cyl, pump, speeds, flow = np.zeros((S, 0)), np.zeros(S), None, None
    else:
        speeds = hydraulics.speeds(q, qd)
        flow = hydraulics.flow(speeds)
        cyl = hydraulics.speed_ratios(speeds)
        pump = flow / hydraulics.pump_flow if hydraulics.has_pump else np.zeros(S)
    return Ratios(_ratio(qd, velocity), _ratio(np.asarray(qdd), acceleration), jerk_r, cyl,
                  pump, speeds, flow)


def binding(ratios: Ratios, joint_names: list[str], hydraulics: HydraulicLimits | None,
            tol: float = BINDING_TOL) -> list[list[str]]:
    """Per sample, the names of the limits within ``tol`` of binding (in the order joints'
    velocity, acceleration, jerk, then cylinders, then the pump)."""
    at = 1.0 - tol
    S = len(ratios.velocity)
    cols: list[tuple[np.ndarray, str]] = []
    for kind in ("velocity", "acceleration", "jerk"):
        r = getattr(ratios, kind)
        cols += [(r[:, j] >= at, f"{name} {kind}") for j, name in enumerate(joint_names)]
    if hydraulics is not None:
        v = ratios.speeds
        for c, name in enumerate(hydraulics.names):
            hit = ratios.cylinder[:, c] >= at
            cols.append((hit & (v[:, c] > 0), f"{name} extension"))
            cols.append((hit & (v[:, c] < 0), f"{name} retraction"))
        cols.append((ratios.pump >= at, "pump"))
    if not cols:
        return [[] for _ in range(S)]
    mask = np.stack([m for m, _ in cols], axis=1)
    names = [n for _, n in cols]
    return [[names[k] for k in np.flatnonzero(row)] for row in mask]


def hydraulic_peaks(ratios: Ratios, hydraulics: HydraulicLimits) -> dict:
    """Peak extension and retraction speed of each cylinder (mm/s) with its limits, and the
    peak pump flow (L/min) with the pump's: JSON-ready."""
    v = ratios.speeds
    cylinders = {}
    for c, name in enumerate(hydraulics.names):
        ext, ret = hydraulics.max_extension[c], hydraulics.max_retraction[c]
        cylinders[name] = {
            "peak_extension_speed": max(0.0, float(v[:, c].max(initial=0.0))),
            "peak_retraction_speed": max(0.0, float(-v[:, c].min(initial=0.0))),
            "max_extension_speed": float(ext) if np.isfinite(ext) else None,
            "max_retraction_speed": float(ret) if np.isfinite(ret) else None,
        }
    pump = None
    if hydraulics.has_pump or np.any(hydraulics.piston > 0):
        pump = {"peak_flow": float(ratios.flow.max(initial=0.0)) / LPM_TO_MM3_PER_S,
                "pump_flow": float(hydraulics.pump_flow) / LPM_TO_MM3_PER_S
                if hydraulics.has_pump else None}
    return {"cylinders": cylinders, "pump": pump}


def piece_samples(traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``traj`` at ``PEAK_GRID + 1`` points per piece (the grid its peaks are searched on):
    times ``(S,)``, ``q, qd (S, dof)``."""
    h = np.diff(traj.breaks)
    tau = h[:, None] * np.linspace(0.0, 1.0, PEAK_GRID + 1)[None, :]
    q = _poly_at(traj.coeffs[:, None], tau, 0).reshape(-1, traj.dof)
    qd = _poly_at(traj.coeffs[:, None], tau, 1).reshape(-1, traj.dof)
    return (traj.breaks[:-1, None] + tau).reshape(-1), q, qd


def stretch_to_limits(traj: Trajectory, velocity, acceleration, jerk,
                      hydraulics: HydraulicLimits | None) -> float:
    """The uniform time factor (>= 1) that brings ``traj`` within every limit: per-joint
    ``velocity``, ``acceleration``, ``jerk`` ``(dof,)`` (inf or None: none) and the
    hydraulics. Peaks are searched as ``Trajectory.peaks`` does."""
    k = 1.0
    for m, lim in ((1, velocity), (2, acceleration), (3, jerk)):
        if lim is None:
            continue
        lim = np.asarray(lim, dtype=float)
        finite = np.isfinite(lim)
        if finite.any():
            peak, _ = traj.peaks(m)
            k = max(k, float(np.max(peak[finite] / lim[finite])) ** (1.0 / m))
    if hydraulics is not None:
        _, q, qd = piece_samples(traj)
        r = limit_ratios(q, qd, qd, None, None, None, None, hydraulics)
        k = max(k, float(r.first_order().max(initial=0.0)))
    return k
