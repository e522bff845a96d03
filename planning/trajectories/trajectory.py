"""Joint trajectories as piecewise polynomials: sampling, continuity, limits, time scaling.

Every trajectory planner here (quintic segments, sextic through a via point, quintic
B-spline) produces a ``Trajectory``: breakpoints ``t (K+1,)`` and, per segment, polynomial
coefficients in local time ``tau = t - t_k``. Positions are in rad (revolute) or mm
(prismatic), time in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline, PPoly

from kinematics.errors import FieldError

__all__ = [
    "Trajectory",
    "Samples",
    "Limits",
    "Violation",
    "QUANTITIES",
    "MAX_SAMPLES",
]

QUANTITIES = ("position", "velocity", "acceleration", "jerk")
#: Most samples one ``sample`` call returns.
MAX_SAMPLES = 200_000
#: Points per segment used to find peak values (on top of the polynomial's own extrema).
PEAK_GRID = 64
#: Joint acceleration limits of an arm's optimal timing when none are given: rad/s² for
#: revolute joints, mm/s² for prismatic ones (a heavy hydraulic arm reaches 1 rad/s in 1 s).
#: Shared by the arm paths (``planning.paths.arm``) and joint-space motion
#: (``planning.motion``).
ARM_ACCELERATION = (1.0, 500.0)
#: Joint jerk limits likewise (rad/s³, mm/s³): the acceleration builds up in 0.2 s.
ARM_JERK = (5.0, 2500.0)


@dataclass(frozen=True)
class Samples:
    """A trajectory sampled at times ``t (S,)``: ``q, qd, qdd, qddd`` each ``(S, dof)``."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray


@dataclass(frozen=True)
class Limits:
    """Per-joint limits ``(dof,)``; ``inf`` (or None) means none. Positions as lower/upper."""

    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    jerk: np.ndarray | None = None

    def of(self, quantity: str) -> np.ndarray | None:
        return {"velocity": self.velocity, "acceleration": self.acceleration,
                "jerk": self.jerk}.get(quantity)


@dataclass(frozen=True)
class Violation:
    """A limit a joint exceeds: ``value`` is the worst value reached, at time ``t``."""

    joint: int
    quantity: str
    value: float
    limit: float
    t: float


@dataclass(frozen=True)
class Trajectory:
    """A piecewise-polynomial joint trajectory.

    ``breaks (K+1,)`` are the segment boundaries in s (``breaks[0]`` is the start);
    ``coeffs (K, deg+1, dof)`` the coefficients of each segment in ascending powers of local
    time. ``waypoint_breaks`` marks which breakpoints are waypoints (the rest are internal
    knots); ``method`` names the planner.
    """

    breaks: np.ndarray
    coeffs: np.ndarray
    method: str
    waypoint_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    # ---- construction --------------------------------------------------------------------
    @classmethod
    def from_bspline(cls, spline: BSpline, method: str, waypoint_times: np.ndarray) -> Trajectory:
        """Piecewise form of a (vector-valued) B-spline between its distinct interior knots."""
        k = spline.k
        t0, t1 = spline.t[k], spline.t[-k - 1]
        knots = np.unique(spline.t[(spline.t >= t0) & (spline.t <= t1)])
        derivs = [spline.derivative(m)(knots[:-1]) if m else spline(knots[:-1])
                  for m in range(k + 1)]
        coeffs = np.stack([d / math.factorial(m) for m, d in enumerate(derivs)], axis=1)
        idx = np.searchsorted(knots, waypoint_times)
        return cls(knots, coeffs, method, idx)

    # ---- basic facts ---------------------------------------------------------------------
    @property
    def dof(self) -> int:
        return self.coeffs.shape[2]

    @property
    def duration(self) -> float:
        return float(self.breaks[-1] - self.breaks[0])

    @property
    def degree(self) -> int:
        return self.coeffs.shape[1] - 1

    def _ppoly(self, derivative: int = 0) -> PPoly:
        c = self.coeffs[:, ::-1, :].transpose(1, 0, 2)  # descending powers, (deg+1, K, dof)
        p = PPoly(c, self.breaks)
        return p.derivative(derivative) if derivative else p

    # ---- evaluation ----------------------------------------------------------------------
    def evaluate(self, t: np.ndarray, derivative: int = 0) -> np.ndarray:
        """Position (or its ``derivative``-th time derivative) at times ``t (S,)`` -> ``(S, dof)``.
        Times outside the trajectory hold the end values (derivatives zero)."""
        t = np.asarray(t, dtype=float)
        inside = np.clip(t, self.breaks[0], self.breaks[-1])
        out = self._ppoly(derivative)(inside)
        if derivative:
            out[(t < self.breaks[0]) | (t > self.breaks[-1])] = 0.0
        return out

    def sample(self, dt: float) -> Samples:
        """Samples every ``dt`` s from start to end (the end always included)."""
        if not dt > 0:
            raise FieldError("dt", f"dt must be positive, got {dt}")
        n = int(math.floor(self.duration / dt + 1e-9)) + 1
        if n + 1 > MAX_SAMPLES:
            raise FieldError(
                "dt", f"dt = {dt} s over {self.duration:.6g} s gives {n + 1} samples; at most "
                f"{MAX_SAMPLES}"
            )
        t = self.breaks[0] + dt * np.arange(n)
        if self.breaks[-1] - t[-1] > 1e-9:
            t = np.append(t, self.breaks[-1])
        return Samples(t, *(self.evaluate(t, m) for m in range(4)))

    # ---- reports -------------------------------------------------------------------------
    def continuity(self) -> dict[str, float]:
        """Largest jump of position, velocity, acceleration and jerk at any segment join."""
        out = {}
        h = np.diff(self.breaks)
        for m, name in enumerate(QUANTITIES):
            if len(h) < 2:
                out[name] = 0.0
                continue
            left = _poly_at(self.coeffs[:-1], h[:-1], m)  # end of segment k
            right = _poly_at(self.coeffs[1:], np.zeros(len(h) - 1), m)  # start of segment k+1
            out[name] = float(np.abs(left - right).max())
        return out

    def peaks(self, derivative: int) -> tuple[np.ndarray, np.ndarray]:
        """Largest |value| of a derivative per joint and the time it occurs: ``(dof,), (dof,)``.

        Found on a fine grid per segment plus the segment ends; accurate to well under 1 %
        for the polynomial degrees used here.
        """
        h = np.diff(self.breaks)
        u = np.linspace(0.0, 1.0, PEAK_GRID + 1)
        tau = h[:, None] * u[None, :]  # (K, G)
        vals = _poly_at(self.coeffs[:, None], tau, derivative)  # (K, G, dof)
        flat = np.abs(vals).reshape(-1, self.dof)
        i = np.argmax(flat, axis=0)
        times = (self.breaks[:-1, None] + tau).reshape(-1)[i]
        return flat[i, np.arange(self.dof)], times

    def range(self) -> tuple[np.ndarray, np.ndarray]:
        """Smallest and largest position per joint ``(dof,), (dof,)``."""
        h = np.diff(self.breaks)
        tau = h[:, None] * np.linspace(0.0, 1.0, PEAK_GRID + 1)[None, :]
        vals = _poly_at(self.coeffs[:, None], tau, 0).reshape(-1, self.dof)
        return vals.min(axis=0), vals.max(axis=0)

    def violations(self, limits: Limits, tol: float = 1e-9) -> list[Violation]:
        """Every joint limit the trajectory exceeds (position range, velocity, acceleration,
        jerk), with the worst value and when it occurs."""
        out: list[Violation] = []
        if limits.lower is not None or limits.upper is not None:
            h = np.diff(self.breaks)
            tau = h[:, None] * np.linspace(0.0, 1.0, PEAK_GRID + 1)[None, :]
            vals = _poly_at(self.coeffs[:, None], tau, 0).reshape(-1, self.dof)
            times = (self.breaks[:-1, None] + tau).reshape(-1)
            for j in range(self.dof):
                if limits.lower is not None and vals[:, j].min() < limits.lower[j] - tol:
                    k = int(np.argmin(vals[:, j]))
                    out.append(Violation(j, "position", float(vals[k, j]),
                                         float(limits.lower[j]), float(times[k])))
                if limits.upper is not None and vals[:, j].max() > limits.upper[j] + tol:
                    k = int(np.argmax(vals[:, j]))
                    out.append(Violation(j, "position", float(vals[k, j]),
                                         float(limits.upper[j]), float(times[k])))
        for m, name in enumerate(QUANTITIES[1:], start=1):
            lim = limits.of(name)
            if lim is None:
                continue
            peak, when = self.peaks(m)
            for j in np.flatnonzero(peak > np.asarray(lim) * (1 + 1e-9) + tol):
                out.append(Violation(int(j), name, float(peak[j]), float(lim[j]),
                                     float(when[j])))
        return out

    # ---- time scaling --------------------------------------------------------------------
    def scaled(self, factors: np.ndarray | float) -> Trajectory:
        """The same path with segment k lasting ``factors[k]`` times as long (a scalar
        stretches all segments alike). Derivative m scales by ``1 / factor**m``."""
        h = np.diff(self.breaks)
        s = np.broadcast_to(np.asarray(factors, dtype=float), h.shape)
        powers = np.arange(self.degree + 1)
        coeffs = self.coeffs / (s[:, None, None] ** powers[None, :, None])
        breaks = self.breaks[0] + np.concatenate([[0.0], np.cumsum(h * s)])
        return Trajectory(breaks, coeffs, self.method, self.waypoint_index)

    def stretch_factor(self, limits: Limits, segments: np.ndarray | None = None) -> np.ndarray:
        """Per-segment (or, with ``segments=None``, one overall) factor that brings the peak
        velocity, acceleration and jerk down to their limits: max over joints and
        quantities of ``(peak / limit) ** (1 / m)``; values below 1 shrink the time."""
        groups = [np.arange(len(self.breaks) - 1)] if segments is None else segments
        out = []
        for seg in groups:
            sub = Trajectory(self.breaks[seg[0]: seg[-1] + 2], self.coeffs[seg], self.method)
            f = 0.0
            for m, name in enumerate(QUANTITIES[1:], start=1):
                lim = limits.of(name)
                if lim is None:
                    continue
                peak, _ = sub.peaks(m)
                lim = np.asarray(lim, dtype=float)
                finite = np.isfinite(lim) & (lim > 0)
                if finite.any():
                    f = max(f, float(np.max((peak[finite] / lim[finite]) ** (1.0 / m))))
            out.append(f)
        return np.array(out)


def _poly_at(coeffs: np.ndarray, tau: np.ndarray, derivative: int) -> np.ndarray:
    """Evaluate ascending-power polynomials ``coeffs (..., deg+1, dof)`` (derivative m) at local
    times ``tau`` broadcast against the leading axes; returns ``(..., dof)``."""
    deg = coeffs.shape[-2] - 1
    out = np.zeros(np.broadcast_shapes(coeffs.shape[:-2], np.shape(tau)) + coeffs.shape[-1:])
    tau = np.asarray(tau)[..., None]
    for p in range(deg, derivative - 1, -1):
        factor = math.perm(p, derivative)
        out = out * tau + factor * coeffs[..., p, :]
    return out
