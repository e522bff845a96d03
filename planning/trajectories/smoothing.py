"""The jerk smoothing pass of ``topp``: from the time-optimal profile to one that also keeps
a jerk limit, by a moving average of the path position.

Each rest-to-rest section of the time-optimal s*(t) (between the path's stops) is
replaced by its average over a window of width tau,

    s(t) = (1 / tau) * integral of s*(t') over [t - tau, t],

extended at rest before and after; the section lasts tau longer. Its derivatives are
differences over the window: ``sdot = (s*(t) - s*(t - tau)) / tau``, ``sddot`` and
``sddd`` likewise from sdot* and sddot*. The time-optimal sddot* is piecewise constant, so
sddd is bounded by the change of sddot* across the window over tau; a trapezoidal speed
profile becomes the classic S-curve this way (a finite-impulse-response filter). The joint
jerk is ``q' sddd + 3 q'' sdot sddot + q''' sdot^3``.

The average can exceed a limit the optimum only touched (the speed at a dip of the
velocity limit, the acceleration next to a switch). Where a sample does, the first-order
bound (x_max) or the acceleration rows of the grid points within the window are lowered by
the excess and the time-optimal profile is recomputed, up to ``SMOOTHING_ITERATIONS``
times; finally one uniform stretch (time x k: velocities / k, accelerations / k^2, jerks /
k^3) takes up any excess that remains, so every limit is kept. Window widths
``SMOOTHING_WIDTHS`` times ``max_j(a_j / j_j)`` are tried and the shortest result kept.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .hermite import hermite7
from .hydraulic import HydraulicLimits
from .joint_path import JointPath
from .limits_check import limit_ratios, stretch_to_limits
from .topp_problem import ToppProblem
from .trajectory import Trajectory

__all__ = ["SmoothedProfile", "smooth_profile", "box_average"]

#: Most re-solves of the jerk smoothing pass.
SMOOTHING_ITERATIONS = 8
#: Window widths tried, as multiples of max_j(a_j / j_j).
SMOOTHING_WIDTHS = (1.0, 1.5, 2.0)
#: Samples per knot interval when the smoothed profile is checked.
CHECK_OVERSAMPLING = 4
#: Knots closer than this fraction of the median knot spacing are merged.
KNOT_MERGE = 0.05
#: Relative excess over a limit the local corrections leave to the final stretch.
LIMIT_SLACK = 1e-3


def box_average(s: np.ndarray, x: np.ndarray, u: np.ndarray, t: np.ndarray, tau: float,
                times: np.ndarray, side: str = "right") -> np.ndarray:
    """The moving average over ``tau`` of one rest-to-rest profile (grid ``s``, squared
    speeds ``x``, accelerations ``u`` per interval, times ``t``, all from 0 at rest) at
    ``times (S,)`` in [0, t[-1] + tau]: ``(4, S)`` = s, sdot, sddot, sddd. sddd jumps
    where a window edge crosses a grid time: ``side`` takes its limit from the right or
    the left there."""

    w = np.sqrt(np.maximum(x, 0.0))
    dt = np.diff(t)
    S_knots = np.concatenate([[0.0], np.cumsum(s[:-1] * dt + w[:-1] * dt**2 / 2
                                                 + u * dt**3 / 6)])

    def raw(tq: np.ndarray) -> np.ndarray:
        """s*, sdot*, sddot* and its integral S at times ``tq`` (rest outside)."""
        i = np.clip(np.searchsorted(t, tq, side=side) - 1, 0, len(u) - 1)
        tl = np.clip(tq, t[0], t[-1]) - t[i]
        pos = s[i] + w[i] * tl + u[i] * tl**2 / 2
        vel = w[i] + u[i] * tl
        moving = (tq >= t[0]) & (tq < t[-1]) if side == "right" else \
            (tq > t[0]) & (tq <= t[-1])
        acc = np.where(moving, u[i], 0.0)
        integ = S_knots[i] + s[i] * tl + w[i] * tl**2 / 2 + u[i] * tl**3 / 6
        before, after = tq < t[0], tq > t[-1]
        integ = np.where(before, s[0] * (tq - t[0]), integ)
        integ = np.where(after, S_knots[-1] + s[-1] * (tq - t[-1]), integ)
        pos = np.where(before, s[0], np.where(after, s[-1], pos))
        vel = np.where(before | after, 0.0, vel)
        return np.stack([integ, pos, vel, acc])

    a, b = raw(times), raw(times - tau)
    return (a - b) / tau


def _sections(path: JointPath, s: np.ndarray) -> list[tuple[int, int]]:
    """Grid index ranges ``[i0, i1]`` between the path's stops."""
    cut = np.flatnonzero(np.isin(s, path.stops))
    edges = [0, *cut.tolist(), len(s) - 1]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _smoothed(path: JointPath, s, x, u, t, tau: float):
    """The smoothed profile as knot times ``(K,)``, knots' path state ``(4, K)`` and the
    check samples' times and state, all sections joined in time."""
    knots_t, knots, check_t, check = [], [], [], []
    offset = 0.0
    for i0, i1 in _sections(path, s):
        ts = t[i0: i1 + 1] - t[i0]
        kt = _merge_close(np.unique(np.concatenate([ts, ts + tau])))
        ct = np.unique(np.concatenate([
            kt, (kt[:-1, None] + np.diff(kt)[:, None]
                 * np.arange(1, CHECK_OVERSAMPLING)[None, :] / CHECK_OVERSAMPLING).ravel()]))
        prof = dict(s=s[i0: i1 + 1], x=x[i0: i1 + 1], u=u[i0: i1], t=ts, tau=tau)
        first = not knots_t
        knots_t.append(offset + (kt if first else kt[1:]))
        right = box_average(times=kt if first else kt[1:], **prof)
        left = box_average(times=kt if first else kt[1:], side="left", **prof)
        knots.append(np.concatenate([right, left[3:]]))
        check_t.append(offset + ct)
        check.append(box_average(times=ct, **prof))
        offset += float(kt[-1])
    return (np.concatenate(knots_t), np.concatenate(knots, axis=1),
            np.concatenate(check_t), np.concatenate(check, axis=1))


def _merge_close(knots: np.ndarray, rel: float = KNOT_MERGE) -> np.ndarray:
    """Knots without those closer than ``rel`` times the median spacing to the one kept
    before them (both ends kept): a piece that short would have to join two one-sided
    jerks over almost no time."""
    gap = rel * float(np.median(np.diff(knots)))
    keep = [0]
    for i in range(1, len(knots) - 1):
        if knots[i] - knots[keep[-1]] >= gap:
            keep.append(i)
    if knots[-1] - knots[keep[-1]] < gap and len(keep) > 1:
        keep.pop()
    keep.append(len(knots) - 1)
    return knots[keep]


def _joint_rates(path: JointPath, state: np.ndarray):
    """q, qd, qdd, qddd ``(S, dof)`` from the path state s, sdot, sddot, sddd ``(4, S)``."""
    s, sd, sdd, sddd = state
    d = path.derivatives(s, "right", 3)
    qd = d[1] * sd[:, None]
    qdd = d[1] * sdd[:, None] + d[2] * (sd**2)[:, None]
    qddd = d[1] * sddd[:, None] + 3 * d[2] * (sd * sdd)[:, None] + d[3] * (sd**3)[:, None]
    return d[0], qd, qdd, qddd


def _lower_limits(p: ToppProblem, check_state: np.ndarray, ratios, tau: float) -> ToppProblem:
    """The problem with the bounds near samples over their limits lowered by the excess."""
    s_grid = p.s
    h = float(np.max(np.diff(s_grid)))
    x_max, lo, hi = p.x_max.copy(), p.lo.copy(), p.hi.copy()
    first = ratios.first_order()
    second = np.maximum(ratios.acceleration.max(axis=1, initial=0.0),
                        ratios.jerk.max(axis=1, initial=0.0))
    s, sd = check_state[0], np.abs(check_state[1])
    reach = sd * tau + h
    a = np.searchsorted(s_grid, s - reach, side="left")
    b = np.searchsorted(s_grid, s + reach, side="right")
    # The largest excess whose window covers each grid point (not their product).
    f1 = np.ones(len(s_grid))
    for k in np.flatnonzero(first > 1 + LIMIT_SLACK):
        np.maximum(f1[a[k]: b[k]], first[k] * (1 + LIMIT_SLACK), out=f1[a[k]: b[k]])
    f2 = np.ones(len(s_grid))
    for k in np.flatnonzero(second > 1 + LIMIT_SLACK):
        lo_k = max(a[k] - 1, 0)
        np.maximum(f2[lo_k: b[k]], second[k] * (1 + LIMIT_SLACK), out=f2[lo_k: b[k]])
    x_max /= f1**2
    lo /= f2[:-1, None]
    hi /= f2[:-1, None]
    return dataclasses.replace(p, x_max=x_max, lo=lo, hi=hi)


def _build(path: JointPath, knots_t, knots) -> Trajectory:
    """Degree-7 pieces between the knots matching q, qd, qdd and the one-sided jerk at
    both ends (the smoothed jerk jumps at knots); ``knots (5, K)``: s, sdot, sddot, sddd
    from the right, sddd from the left."""
    q, qd, qdd, jr = _joint_rates(path, knots[:4])
    _, _, _, jl = _joint_rates(path, np.stack([knots[0], knots[1], knots[2], knots[4]]))
    coeffs = hermite7(np.stack([q[:-1], qd[:-1], qdd[:-1], jr[:-1]]),
                      np.stack([q[1:], qd[1:], qdd[1:], jl[1:]]), np.diff(knots_t))
    idx = np.searchsorted(knots[0], path.waypoint_s).clip(0, len(knots_t) - 1)
    return Trajectory(knots_t, coeffs, "optimal", np.unique(idx))


@dataclass(frozen=True)
class SmoothedProfile:
    """The smoothing pass's result: ``trajectory`` (every limit kept), the window ``tau``
    (s), the final uniform ``stretch`` (>= 1) and the re-solves it took."""

    trajectory: Trajectory
    tau: float
    stretch: float
    iterations: int


def smooth_profile(path: JointPath, problem: ToppProblem, x, u, t, vel, acc, jerk,
                   hydraulics: HydraulicLimits | None, solve) -> SmoothedProfile:
    """The time-optimal profile ``x, u, t`` on ``problem``'s grid made to keep the ``jerk``
    limits too (module docstring). ``solve(problem)`` re-solves a lowered problem: ``(x,
    u, t)``, or None when it has no solution."""
    d = path.derivatives(problem.s, "right", 2)
    peak_acc = np.abs(d[1] * np.concatenate([u, u[-1:]])[:, None]
                      + d[2] * x[:, None]).max(axis=0)
    a_eff = np.where(np.isfinite(acc), np.minimum(acc, np.maximum(peak_acc, 1e-300)), peak_acc)
    finite = np.isfinite(jerk)
    tau0 = float(np.max(a_eff[finite] / jerk[finite]))
    tau0 = max(tau0, 1e-6 * max(float(t[-1]), 1e-9))
    best: tuple[float, SmoothedProfile] | None = None
    for width in SMOOTHING_WIDTHS:
        tau = width * tau0
        p, xs, us, ts = problem, x, u, t
        for it in range(SMOOTHING_ITERATIONS + 1):
            knots_t, knots, check_t, check = _smoothed(path, p.s, xs, us, ts, tau)
            q, qd, qdd, qddd = _joint_rates(path, check)
            r = limit_ratios(q, qd, qdd, qddd, vel, acc, jerk, hydraulics)
            if max(r.worst().values()) <= 1 + LIMIT_SLACK or it == SMOOTHING_ITERATIONS:
                break
            lowered = _lower_limits(p, check, r, tau)
            solved = solve(lowered)
            if solved is None:
                break
            p, (xs, us, ts) = lowered, solved
        traj = _build(path, knots_t, knots)
        k = stretch_to_limits(traj, vel, acc, jerk, hydraulics)
        duration = k * traj.duration
        if best is None or duration < best[0]:
            best = (duration, SmoothedProfile(traj.scaled(k) if k > 1 else traj, tau, k, it))
    return best[1]
