"""Time-optimal path parameterisation by reachability analysis (TOPP-RA).

Given a joint path q(s) (``JointPath``), find the fastest s(t) that keeps every limit.
With ``x = sdot^2`` and ``u = sddot`` the joint rates are

    qd = q'(s) sdot,    qdd = q'(s) u + q''(s) x,

so a velocity limit ``|q_j' sdot| <= v_j`` (and a cylinder's speed, and the pump's flow:
``hydraulic``) bounds x at each grid point (first order), and an acceleration limit
``|q_j' u + q_j'' x| <= a_j`` is linear in (u, x) (second order). On a grid
``s_0 < ... < s_N`` with u constant on each interval, ``x_{i+1} = x_i + 2 (s_{i+1} - s_i)
u_i`` (Pham & Pham, "A new approach to time-optimal path parameterization based on
reachability analysis", IEEE T-RO 2018):

1. per grid point, vectorised: the first-order bound ``x <= x_max`` and the second-order
   rows ``lo <= A u + B x <= hi``; eliminating u between every pair of rows
   (Fourier-Motzkin) leaves the x each stage allows on its own;
2. backward: the controllable sets ``K_i`` (the x at s_i from which the end can still be
   reached), each from ``K_{i+1}``, a 1-D interval found in closed form;
3. forward: from the start, the largest u that keeps ``x_{i+1}`` in ``K_{i+1}`` (greedy);
   this is time-optimal for the discretised problem.

``scheme="interpolation"`` (default, as TOPP-RA's) also imposes stage i's second-order rows
at ``s_{i+1}`` with ``x_{i+1} = x_i + 2 delta u``; ``"collocation"`` only at ``s_i``.
Between grid points limits hold to the accuracy of the grid (the benchmark measures it).

An optional jerk limit is met by a smoothing pass (``smoothing``): each rest-to-rest section
of the time-optimal s(t) is averaged over a moving window of width tau (a box filter: the
finite-impulse-response way of turning a trapezoidal speed profile into an S-curve), which
bounds sddd by the change of sddot across the window; limits the averaging overshoots are
lowered locally and the profile recomputed, and a last uniform stretch (x k in time:
velocity / k, acceleration / k^2, jerk / k^3) takes up what remains, so the result keeps
every limit. It is no longer time-optimal: its cost against the optimum is reported.

Time in s; joint values in rad or mm; s in the path's unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kinematics.errors import FieldError
from kinematics.status import Status

from .hermite import hermite5
from .hydraulic import HydraulicLimits
from .joint_path import JointPath
from .limits_check import stretch_to_limits
from .smoothing import smooth_profile
from .topp_problem import ToppProblem
from .trajectory import Limits, Trajectory

__all__ = [
    "DEFAULT_GRID",
    "ToppStatus",
    "ToppResult",
    "time_optimal",
    "path_grid",
]

#: Default number of grid intervals along the path.
DEFAULT_GRID = 500
#: Largest x (= sdot^2) treated as finite: above it the path speed is unbounded.
X_CAP = 1e60


class ToppStatus(Status):
    """How a parameterisation ended (a member of the status family, ``kinematics.status``)."""

    OK = "ok"
    #: No s(t) keeps the limits (e.g. the start or end speed asked for is too high).
    INFEASIBLE = "infeasible"
    #: Somewhere no limit bounds the path speed (a moving joint without any limit).
    UNBOUNDED = "unbounded"


@dataclass(frozen=True)
class ToppResult:
    """A parameterisation of ``path``.

    ``s (N+1,)`` the grid, ``x (N+1,)`` the squared path speed there, ``u (N,)`` the path
    acceleration on each interval, ``t (N+1,)`` the time at each grid point (s) — of the
    time-optimal profile. ``trajectory``: the joint trajectory (quintic pieces matching q,
    qd, qdd at the knots; after jerk smoothing when a jerk limit was given); ``duration``
    its length (s), ``optimal_duration`` the time-optimal profile's. ``stretch``: the
    uniform factor the smoothing pass needed at the end (1 without jerk limit).
    """

    status: ToppStatus
    message: str
    path: JointPath
    s: np.ndarray
    x: np.ndarray
    u: np.ndarray
    t: np.ndarray
    trajectory: Trajectory | None
    optimal_duration: float
    smoothing_window: float = 0.0
    stretch: float = 1.0
    info: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is ToppStatus.OK

    @property
    def duration(self) -> float:
        return self.trajectory.duration if self.trajectory is not None else math.nan

    def evaluate_optimal(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The time-optimal profile itself at times ``t (S,)``: ``q, qd, qdd (S, dof)``,
        from s(t) exactly (u constant per interval), not from its quintic pieces."""
        t = np.clip(np.asarray(t, dtype=float), self.t[0], self.t[-1])
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.u) - 1)
        tau = t - self.t[i]
        w = np.sqrt(self.x[i])
        s = np.clip(self.s[i] + w * tau + 0.5 * self.u[i] * tau**2, self.s[i], self.s[i + 1])
        sd = w + self.u[i] * tau
        # Inside interval i: the path piece on its side of a break at either end.
        side_left = s >= self.s[i + 1]
        d = [np.where(side_left[:, None], self.path.evaluate(s, m, "left"),
                      self.path.evaluate(s, m, "right")) for m in range(3)]
        return d[0], d[1] * sd[:, None], d[1] * self.u[i][:, None] + d[2] * (sd**2)[:, None]


# ---- grid and constraints ---------------------------------------------------------------
def path_grid(path: JointPath, intervals: int = DEFAULT_GRID) -> np.ndarray:
    """``intervals`` equal steps over the path, with its stops and waypoints moved onto the
    grid (each replaces the uniform points within a quarter step of it): ``(M,)``."""
    if not (isinstance(intervals, int | np.integer) and intervals >= 1):
        raise FieldError("grid", "grid: the number of grid intervals must be a positive "
                         "integer")
    s0, s1 = float(path.breaks[0]), float(path.breaks[-1])
    g = np.linspace(s0, s1, intervals + 1)
    required = np.unique(np.concatenate([[s0, s1], path.stops, path.waypoint_s]))
    required = required[(required >= s0) & (required <= s1)]
    h = (s1 - s0) / intervals
    near = np.abs(g[:, None] - required[None, :]).min(axis=1) < 0.25 * h
    return np.unique(np.concatenate([g[~near], required]))


def _rate(limits: Limits, name: str, dof: int) -> np.ndarray:
    """Per-joint limit ``(dof,)`` (inf where none); ``FieldError`` naming ``limits.name``."""
    value = limits.of(name)
    if value is None:
        return np.full(dof, np.inf)
    arr = np.asarray(value, dtype=float)
    arr = np.broadcast_to(arr, (dof,)) if arr.ndim == 0 else arr
    if arr.shape != (dof,):
        raise FieldError(("limits", name), f"limits.{name}: expected one value or {dof} "
                         f"values, got {arr.size}")
    if np.any(np.isnan(arr)) or np.any(arr <= 0):
        raise FieldError(("limits", name), f"limits.{name}: every limit must be positive "
                         "(a zero limit lets the joint never move)")
    return arr.copy()


def _problem(path: JointPath, s: np.ndarray, vel: np.ndarray, acc: np.ndarray,
             hydraulics: HydraulicLimits | None, scheme: str) -> ToppProblem:
    right = path.derivatives(s[:-1], "right", 2)  # stage i at its start
    left = path.derivatives(s[1:], "left", 2)  # stage i at its end
    # First order at every grid point, from both sides of it.
    x_max = np.full(len(s), np.inf)
    for q, d1, pts in ((right[0], right[1], slice(0, -1)), (left[0], left[1], slice(1, None))):
        with np.errstate(divide="ignore"):
            bound = np.where(np.abs(d1) > 0, vel / np.abs(d1), np.inf).min(axis=1) ** 2
        if hydraulics is not None:
            bound = np.minimum(bound, hydraulics.path_bounds(q, d1))
        x_max[pts] = np.minimum(x_max[pts], bound)
    stops = np.isin(s, path.stops)
    x_max[stops] = 0.0
    # Second order: joint accelerations with a finite limit.
    finite = np.isfinite(acc)
    A = [right[1][:, finite]]
    B = [right[2][:, finite]]
    if scheme == "interpolation":
        delta = np.diff(s)[:, None]
        A.append(left[1][:, finite] + 2.0 * delta * left[2][:, finite])
        B.append(left[2][:, finite])
    A, B = np.concatenate(A, axis=1), np.concatenate(B, axis=1)
    hi = np.broadcast_to(np.tile(acc[finite], len(A[0]) // max(int(finite.sum()), 1)),
                         A.shape).copy()
    return ToppProblem(s, x_max, A, B, -hi, hi)


@dataclass(frozen=True)
class _Stages:
    """Each stage's second-order rows with u eliminated: the x each allows on its own
    ``[x_lo, x_hi] (N,)``, the lines bounding u from below ``l0 + l1 x`` and above
    ``u0 + u1 x`` ``(N, R)``, and the coefficients of the backward step: bounds on x_i that
    are affine in the next set's ends, ``alpha * K_next + beta``."""

    x_lo: np.ndarray
    x_hi: np.ndarray
    l0: np.ndarray
    l1: np.ndarray
    u0: np.ndarray
    u1: np.ndarray
    up_h: tuple[np.ndarray, np.ndarray]
    up_l: tuple[np.ndarray, np.ndarray]
    dn_h: tuple[np.ndarray, np.ndarray]
    dn_l: tuple[np.ndarray, np.ndarray]


def _stages(p: ToppProblem) -> _Stages:
    A, B, lo, hi = p.A, p.B, p.lo, p.hi
    N = len(p.s) - 1
    scale = np.abs(A).max(initial=0.0)
    flat = np.abs(A) <= 1e-12 * max(scale, 1e-300)
    safe = np.where(flat, 1.0, A)
    with np.errstate(divide="ignore", invalid="ignore"):
        pos = A > 0
        l0 = np.where(flat, -np.inf, np.where(pos, lo, hi) / safe)
        u0 = np.where(flat, np.inf, np.where(pos, hi, lo) / safe)
        l1 = np.where(flat, 0.0, -B / safe)
        u1 = l1
        # Rows without u: B x in [lo, hi].
        xb_hi = np.where(flat & (B > 0), hi / np.where(B > 0, B, 1.0),
                         np.where(flat & (B < 0), lo / np.where(B < 0, B, 1.0), np.inf))
        xb_lo = np.where(flat & (B > 0), lo / np.where(B > 0, B, 1.0),
                         np.where(flat & (B < 0), hi / np.where(B < 0, B, 1.0), -np.inf))
        x_hi = np.minimum(p.x_max[:-1], xb_hi.min(axis=1, initial=np.inf))
        x_lo = np.maximum(0.0, xb_lo.max(axis=1, initial=-np.inf))
        # Every pair (lower row p, upper row q): l0_p + l1_p x <= u0_q + u1_q x.
        c = l1[:, :, None] - u1[:, None, :]
        rhs = u0[:, None, :] - l0[:, :, None]
        big = np.abs(c) > 1e-300
        xb = np.where(big, rhs / np.where(big, c, 1.0), np.nan)
        x_hi = np.minimum(x_hi, np.where(big & (c > 0), xb, np.inf).reshape(N, -1)
                          .min(axis=1, initial=np.inf))
        x_lo = np.maximum(x_lo, np.where(big & (c < 0), xb, -np.inf).reshape(N, -1)
                          .max(axis=1, initial=-np.inf))
        bad = (~big & (rhs < 0)).reshape(N, -1).any(axis=1)
        x_hi = np.where(bad, -1.0, x_hi)
        d = 1.0 / (2.0 * np.diff(p.s))[:, None]
        # Lower u line p against the next set's top: (l1_p + d) x <= d K_hi - l0_p.
        ch = l1 + d
        # The next set's bottom against upper u line q: -(d + u1_q) x <= u0_q - d K_lo.
        cl = -(d + u1)
        up_h = (np.where(ch > 0, d / ch, 0.0), np.where(ch > 0, -l0 / ch, np.inf))
        dn_h = (np.where(ch < 0, d / ch, 0.0), np.where(ch < 0, -l0 / ch, -np.inf))
        up_l = (np.where(cl > 0, -d / cl, 0.0), np.where(cl > 0, u0 / cl, np.inf))
        dn_l = (np.where(cl < 0, -d / cl, 0.0), np.where(cl < 0, u0 / cl, -np.inf))
    return _Stages(x_lo, x_hi, l0, l1, u0, u1, up_h, up_l, dn_h, dn_l)


def _controllable(st: _Stages, x_max_end: float, end: tuple[float, float]
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """Backward pass: ``K_lo, K_hi (N+1,)`` and the first stage found empty (-1: none)."""
    N = len(st.x_hi)
    K_lo, K_hi = np.empty(N + 1), np.empty(N + 1)
    K_lo[N], K_hi[N] = end[0], min(end[1], x_max_end, X_CAP)
    if K_lo[N] > K_hi[N] * (1 + 1e-9) + 1e-12:
        return K_lo, K_hi, N
    # One array op per stage and bound: [alpha_h * K_hi | alpha_l * K_lo] + beta.
    up_a = np.concatenate([st.up_h[0], st.up_l[0]], axis=1)
    up_b = np.concatenate([st.up_h[1], st.up_l[1]], axis=1)
    dn_a = np.concatenate([st.dn_h[0], st.dn_l[0]], axis=1)
    dn_b = np.concatenate([st.dn_h[1], st.dn_l[1]], axis=1)
    R = st.up_h[0].shape[1]
    x_lo, x_hi = st.x_lo.tolist(), np.minimum(st.x_hi, X_CAP).tolist()
    k = np.empty(2 * R)
    khi, klo = K_hi[N], K_lo[N]
    if R == 0:  # no second-order rows: nothing ties a stage to the next but x itself
        up_a, dn_a = np.zeros((N, 1)), np.zeros((N, 1))
        up_b, dn_b = np.full((N, 1), np.inf), np.full((N, 1), -np.inf)
        k = np.zeros(1)
    for i in range(N - 1, -1, -1):
        k[:R], k[R:] = khi, klo
        hi = min(x_hi[i], (up_a[i] * k + up_b[i]).min())
        lo = max(x_lo[i], (dn_a[i] * k + dn_b[i]).max())
        if lo > hi * (1 + 1e-9) + 1e-12:
            K_lo[: i + 1], K_hi[: i + 1] = np.nan, np.nan
            return K_lo, K_hi, i
        khi, klo = hi, min(lo, hi)
        K_hi[i], K_lo[i] = khi, klo
    return K_lo, K_hi, -1


def _forward(st: _Stages, s: np.ndarray, K_lo: np.ndarray, K_hi: np.ndarray, x0: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Greedy forward pass from ``x0``: ``x (N+1,)``, ``u (N,)``."""
    N = len(s) - 1
    x, u = np.empty(N + 1), np.empty(N)
    x[0] = x0
    two_delta = 2.0 * np.diff(s)
    xi = x0
    l0, l1, u0, u1 = st.l0, st.l1, st.u0, st.u1
    has_rows = l0.shape[1] > 0
    K_lo_l, K_hi_l, td = K_lo.tolist(), K_hi.tolist(), two_delta.tolist()
    for i in range(N):
        u_hi = (K_hi_l[i + 1] - xi) / td[i]
        u_lo = (K_lo_l[i + 1] - xi) / td[i]
        if has_rows:
            u_hi = min(u_hi, (u0[i] + u1[i] * xi).min())
            u_lo = max(u_lo, (l0[i] + l1[i] * xi).max())
        ui = u_hi if u_hi >= u_lo else u_lo
        xn = min(max(xi + td[i] * ui, K_lo_l[i + 1], 0.0), K_hi_l[i + 1])
        u[i], x[i + 1] = (xn - xi) / td[i], xn
        xi = xn
    return x, u


def _times(s: np.ndarray, x: np.ndarray) -> np.ndarray:
    w = np.sqrt(np.maximum(x, 0.0))
    den = w[:-1] + w[1:]
    with np.errstate(divide="ignore"):
        dt = np.where(den > 0, 2.0 * np.diff(s) / den, np.inf)
    return np.concatenate([[0.0], np.cumsum(dt)])


def _trajectory(path: JointPath, s, x, u, t) -> Trajectory:
    """Quintic pieces between the grid points of the profile (s, x, u, t)."""
    right = path.derivatives(s[:-1], "right", 2)
    left = path.derivatives(s[1:], "left", 2)
    w = np.sqrt(np.maximum(x, 0.0))
    v0 = right[1] * w[:-1, None]
    v1 = left[1] * w[1:, None]
    a0 = right[1] * u[:, None] + right[2] * x[:-1, None]
    a1 = left[1] * u[:, None] + left[2] * x[1:, None]
    coeffs = hermite5(right[0], left[0], v0, v1, a0, a1, np.diff(t))
    idx = np.searchsorted(s, path.waypoint_s).clip(0, len(s) - 1)
    return Trajectory(t, coeffs, "optimal", np.unique(idx))


# ---- the solver --------------------------------------------------------------------------
def _solve(path: JointPath, p: ToppProblem, x0: float, end: tuple[float, float]
           ) -> tuple[ToppStatus, str, np.ndarray, np.ndarray]:
    st = _stages(p)
    K_lo, K_hi, empty = _controllable(st, p.x_max[-1], end)
    if empty >= 0 or not (K_lo[0] - 1e-9 * max(1.0, x0) <= x0 <= K_hi[0] * (1 + 1e-9) + 1e-12):
        where = "the end speed asked for" if empty == len(p.s) - 1 else (
            f"the path at s = {p.s[max(empty, 0)]:.6g}" if empty >= 0 else
            "the start speed asked for")
        return (ToppStatus.INFEASIBLE, f"no motion keeps the limits: {where} cannot be "
                "reached or left within them", np.zeros(len(p.s)), np.zeros(len(p.s) - 1))
    x, u = _forward(st, p.s, K_lo, K_hi, x0)
    if np.any(x >= 0.5 * X_CAP):
        i = int(np.argmax(x >= 0.5 * X_CAP))
        return (ToppStatus.UNBOUNDED, f"no limit bounds the path speed near s = {p.s[i]:.6g}: "
                "give a velocity or acceleration limit for every moving joint", x, u)
    t = _times(p.s, x)
    if not np.isfinite(t[-1]):
        i = int(np.argmax(~np.isfinite(t))) - 1
        return (ToppStatus.INFEASIBLE, f"the path speed must stay zero between s = "
                f"{p.s[i]:.6g} and {p.s[i + 1]:.6g}: the limits stop the motion there", x, u)
    return ToppStatus.OK, "time-optimal within the limits", x, u


def time_optimal(
    path: JointPath,
    limits: Limits,
    hydraulics: HydraulicLimits | None = None,
    *,
    grid: int | np.ndarray = DEFAULT_GRID,
    scheme: str = "interpolation",
    start_speed: float = 0.0,
    end_speed: float = 0.0,
    keep_limits: bool = True,
) -> ToppResult:
    """The fastest traversal of ``path`` within ``limits`` (per-joint ``velocity``,
    ``acceleration`` and optional ``jerk``, inf or None for none) and the ``hydraulics``.

    ``grid``: number of equal intervals (stops and waypoints added), or the grid itself
    ``(M,)`` from ``path.breaks[0]`` to ``path.breaks[-1]``. ``start_speed``,
    ``end_speed``: path speeds sdot (path units per s) at the ends, default rest. A jerk
    limit needs rest at both ends. The limits are imposed at the grid points; between them
    the motion can exceed a limit slightly (well under 1 % at the default grid):
    ``keep_limits`` stretches the returned trajectory uniformly by the factor its peaks
    need to keep every limit everywhere (``stretch``; ``optimal_duration`` stays that of
    the grid's optimum; a given end speed is divided by it too). Raises ``FieldError``
    naming ``limits.<name>`` for a limit that is not positive, ``start_speed``,
    ``end_speed``, ``grid`` or ``scheme`` for bad values; an unreachable end speed or an
    unbounded path speed is a result ``status``.
    """
    dof = path.dof
    vel, acc, jerk = (_rate(limits, n, dof) for n in ("velocity", "acceleration", "jerk"))
    if scheme not in ("interpolation", "collocation"):
        raise FieldError("scheme", "scheme: 'interpolation' or 'collocation'")
    for name, v in (("start_speed", start_speed), ("end_speed", end_speed)):
        if not (math.isfinite(v) and v >= 0):
            raise FieldError(name, f"{name}: must be a finite path speed >= 0")
    if np.isscalar(grid) or np.ndim(grid) == 0:
        s = path_grid(path, int(grid))
    else:
        s = np.asarray(grid, dtype=float)
        if s.ndim != 1 or len(s) < 2 or np.any(np.diff(s) <= 0) or \
                abs(s[0] - path.breaks[0]) > 1e-12 or abs(s[-1] - path.breaks[-1]) > 1e-9:
            raise FieldError("grid", "grid: must increase from the path's start to its end")
    smooth = bool(np.any(np.isfinite(jerk)))
    if smooth and (start_speed > 0 or end_speed > 0):
        raise FieldError(("limits", "jerk"), "limits.jerk: a jerk-limited profile starts and "
                         "ends at rest")
    p = _problem(path, s, vel, acc, hydraulics, scheme)
    status, message, x, u = _solve(path, p, start_speed**2, (end_speed**2, end_speed**2))
    t = _times(s, x) if status is ToppStatus.OK else np.full(len(s), np.nan)
    if status is not ToppStatus.OK:
        return ToppResult(status, message, path, s, x, u, t, None, math.nan)
    traj = _trajectory(path, s, x, u, t)
    if not smooth:
        k = stretch_to_limits(traj, vel, acc, None, hydraulics) if keep_limits else 1.0
        return ToppResult(status, message, path, s, x, u, t, traj.scaled(k) if k > 1 else traj,
                          float(t[-1]), stretch=k)

    def solve(lowered: ToppProblem):
        st, _, xl, ul = _solve(path, lowered, 0.0, (0.0, 0.0))
        return (xl, ul, _times(s, xl)) if st is ToppStatus.OK else None

    sm = smooth_profile(path, p, x, u, t, vel, acc, jerk, hydraulics, solve)
    cost = sm.trajectory.duration / t[-1] - 1.0 if t[-1] > 0 else 0.0
    return ToppResult(status, f"jerk-limited: {100 * cost:.1f} % longer than the "
                      "time-optimal profile without a jerk limit", path, s, x, u, t,
                      sm.trajectory, float(t[-1]), sm.tau, sm.stretch,
                      {"smoothing_iterations": sm.iterations, "jerk_cost": cost})
