"""Numeric IK for any model: weighted, damped least squares, batched, multi-start.

The step is paper 003's weighted singularity-robust inverse (eqs. 6-13)::

    dq = W^-1 J^T (J W^-1 J^T + lambda I)^-1 e

with the joint-limit objective H (eq. 9) whose gradient (eq. 10, per joint) sets the weights
(eq. 8): ``w_i = 1 + |dH/dq_i|`` while joint i moves towards a limit, 1 otherwise. Two
departures from the paper, both for a solver rather than a tracking controller: the damping
lambda adapts per target (Levenberg-Marquardt: shrink on success, grow on failure), so the
iteration converges quadratically near a solution; and linear errors are divided by the
robot's ``length_scale`` so that mm and rad weigh alike.

Many targets are solved at once: every array carries one row per (target, start). Each target
starts from ``q0`` (if given) and from the nearest of a seeded table of sample poses; targets
still unsolved are restarted from seeded random configurations.

When the compiled kernels are available (``kinematics.fast``) each target is solved on its
own by the same iteration compiled (``_kernels.ik_starts``), its starts taken in the same
order (``q0``, the nearest table sample, the next-nearest, then the random restarts) and the
run stopped at the first start that converges: no numpy overhead per iteration. With
``all_solutions`` (every start run to the end) the batched numpy code is used.

Seeds: the seed table is drawn from its own seed, ``TABLE_SEED`` (``NumericOptions.
table_seed``), and the random restarts from ``NumericOptions.seed`` (0). A benchmark or test
that draws its target poses from either seed would find its answers among the solver's
starts: targets must come from other seeds (benchmarks/bench_single_pose.py checks it).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from ..fast import c_array, chain_of, kernels
from ..fk import fk
from ..jacobian import jacobian_and_pose
from ..model import RobotModel
from ..transforms import pose_errors, rotation_log
from .result import IKResult, IKStatus, order_by_distance

__all__ = ["NumericOptions", "TABLE_SEED", "solve_batch"]

METHOD = "numeric"
#: Weight of the position in the seed-table distance: the arm branch (shoulder, elbow) is
#: what a start must get right; the wrist finds its way from anywhere.
POSITION_FEATURE_WEIGHT = 3.0
#: Squared normalised task error below which the joint-limit weights are switched off.
WEIGHT_OFF_COST = 1e-6
#: Seed of the table of sample configurations the solver starts from (``NumericOptions.
#: table_seed``); distinct from the restart seed so that neither holds the other's draws.
#: Targets drawn from this seed (or from the restart seed) are not unseen: never benchmark
#: on them.
TABLE_SEED = 0x7AB1E_5EED


@dataclass(frozen=True)
class NumericOptions:
    """Tuning of the numeric solver. Tolerances in mm and rad; ``seed`` seeds the random
    restarts, ``table_seed`` the table of ``seed_table`` sample configurations."""

    tol_position: float = 1e-5
    tol_rotation: float = 1e-8
    max_iterations: int = 30
    restarts: int = 64
    restart_batch: int = 8
    lambda0: float = 1e-2
    seed: int = 0
    seed_table: int = 2048
    table_seed: int = TABLE_SEED
    weighted: bool = True
    polish_below: float = 5.0
    polish_iterations: int = 200


def limit_gradient(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Gradient of paper 003's joint-limit objective H (eqs. 9-10) per joint, ``(*, dof)``."""
    span = upper - lower
    return (span**2 * (2 * q - upper - lower)) / (
        q.shape[-1] * (upper - q) ** 2 * (q - lower) ** 2
    )


def _error(model: RobotModel, T: np.ndarray, T_goal: np.ndarray) -> np.ndarray:
    """Task error ``(P, 6)``: position (in length-scale units) then world-frame rotation."""
    e = np.empty(T.shape[:-2] + (6,))
    e[..., :3] = (T_goal[..., :3, 3] - T[..., :3, 3]) / model.length_scale
    e[..., 3:] = rotation_log(T_goal[..., :3, :3] @ np.swapaxes(T[..., :3, :3], -1, -2))
    return e


@lru_cache(maxsize=64)
def _seed_table(model: RobotModel, size: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded sample configurations ``(size, dof)`` and their tool poses as features."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(model.lower, model.upper, size=(size, model.dof))
    return q, _features(model, fk(model, q))


def _features(model: RobotModel, T: np.ndarray) -> np.ndarray:
    """Pose features for nearest-neighbour seeding: position / length_scale and rotation."""
    return np.concatenate(
        [
            POSITION_FEATURE_WEIGHT * T[..., :3, 3] / model.length_scale,
            T[..., :3, :3].reshape(T.shape[:-2] + (9,)),
        ],
        axis=-1,
    )


def _interior(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    margin = 1e-9 * (model.upper - model.lower)
    return model.lower + margin, model.upper - margin


def _step(
    Ja: np.ndarray, winv: np.ndarray, e: np.ndarray, lam: np.ndarray
) -> np.ndarray:
    """Weighted damped least-squares step ``W^-1 J^T (J W^-1 J^T + lam I)^-1 e`` per row."""
    JW = Ja * winv[:, None, :]
    A = JW @ np.swapaxes(Ja, 1, 2) + lam[:, None, None] * np.eye(6)
    y = np.linalg.solve(A, e[..., None])[..., 0]
    return np.einsum("pij,pi->pj", JW, y)


def _run(
    model: RobotModel,
    q: np.ndarray,
    T_goal: np.ndarray,
    opts: NumericOptions,
    owners: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterate damped least squares on rows ``q (P, dof)`` towards ``T_goal (P, 4, 4)``.

    Returns the final q, position errors (mm) and rotation errors (rad), each per row.
    Rows stop once within tolerance or once their damping says they are stuck; with
    ``owners (P,)`` (target index per row) all rows of a target stop once one has converged.
    """
    lo, hi = _interior(model)
    q = np.clip(q, lo, hi)
    L = model.length_scale
    J, T = jacobian_and_pose(model, q)
    e = _error(model, T, T_goal)
    cost = np.einsum("ij,ij->i", e, e)
    lam = np.full(q.shape[0], opts.lambda0)
    grad_prev = np.abs(limit_gradient(q, model.lower, model.upper))
    dp, dr = pose_errors(T, T_goal)
    active = ~((dp < opts.tol_position) & (dr < opts.tol_rotation))
    weighted = np.full(q.shape[0], opts.weighted)
    for _ in range(opts.max_iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        Ja = J[idx].copy()
        Ja[:, :3] /= L
        qa = q[idx]
        grad = np.abs(limit_gradient(qa, model.lower, model.upper))
        # Near the answer the weights only slow the final Gauss-Newton steps: drop them there.
        far = cost[idx] > WEIGHT_OFF_COST
        towards = (grad >= grad_prev[idx]) & (weighted[idx] & far)[:, None]
        winv = np.where(towards, 1.0 / (1.0 + grad), 1.0)
        grad_prev[idx] = grad
        dq = _step(Ja, winv, e[idx], lam[idx])
        # A joint pinned at a limit and pushed further out is taken out of the step, so the
        # others can still make progress (a projected step rather than a clipped one).
        blocked = ((qa <= lo) & (dq < 0)) | ((qa >= hi) & (dq > 0))
        rows = np.flatnonzero(blocked.any(axis=1))
        if rows.size:
            winv_b = np.where(blocked[rows], 0.0, winv[rows])
            dq[rows] = _step(Ja[rows], winv_b, e[idx[rows]], lam[idx[rows]])
        q_new = np.clip(qa + dq, lo, hi)
        J_new, T_new = jacobian_and_pose(model, q_new)
        e_new = _error(model, T_new, T_goal[idx])
        cost_new = np.einsum("ij,ij->i", e_new, e_new)
        better = cost_new < cost[idx]
        acc = idx[better]
        q[acc], J[acc], T[acc], e[acc], cost[acc] = (
            q_new[better], J_new[better], T_new[better], e_new[better], cost_new[better]
        )
        lam[acc] = np.maximum(lam[acc] * 0.2, 1e-12)
        lam[idx[~better]] *= 8.0
        dpa, dra = pose_errors(T[idx], T_goal[idx])
        dp[idx], dr[idx] = dpa, dra
        done = (dpa < opts.tol_position) & (dra < opts.tol_rotation)
        stuck = lam[idx] > 1e6
        # The limit weights can hold a joint back from a solution that lies close to its
        # limit; a row that stalls weighted gets one more go without them.
        retry = idx[stuck & ~done & weighted[idx]]
        weighted[retry] = False
        lam[retry] = opts.lambda0
        active[idx[done | stuck]] = False
        active[retry] = True
        if owners is not None and done.any():
            active &= ~np.isin(owners, owners[idx[done]])
    return q, dp, dr


def _reach_note(model: RobotModel, T_goal: np.ndarray) -> str:
    dist = float(np.linalg.norm(T_goal[:3, 3] - model.base[:3, 3]))
    if dist > model.length_scale:
        return (
            f"; the target is {dist:.1f} mm from the base, beyond the arm's total link "
            f"length {model.length_scale:.1f} mm: out of reach"
        )
    return "; the target may be out of reach, or reachable only outside the joint limits"


def solve_batch(
    model: RobotModel,
    T_goal: np.ndarray,
    q0: np.ndarray | None = None,
    *,
    all_solutions: bool = False,
    options: NumericOptions | None = None,
) -> list[IKResult]:
    """Numeric IK for targets ``T_goal (B, 4, 4)``; one ``IKResult`` per target.

    ``q0``: ``(dof,)`` or ``(B, dof)`` initial guesses (optional). With ``all_solutions`` every
    start runs to the end and the distinct solutions found are all returned.
    """
    opts = options or NumericOptions()
    T_goal = np.asarray(T_goal, dtype=float)
    B = T_goal.shape[0]
    dof = model.dof
    rng = np.random.default_rng(opts.seed)
    q0b = None if q0 is None else np.broadcast_to(np.asarray(q0, dtype=float), (B, dof))

    K = kernels()
    if K is not None and not all_solutions:
        return [_solve_one(K, model, T_goal[b], None if q0b is None else q0b[b], opts)
                for b in range(B)]

    # First round: q0 (if any) and the nearest sample of the seed table.
    table_q, table_f = _seed_table(model, opts.seed_table, opts.table_seed)
    f = _features(model, T_goal)
    d2 = (
        np.einsum("ij,ij->i", f, f)[:, None]
        - 2.0 * f @ table_f.T
        + np.einsum("ij,ij->i", table_f, table_f)[None, :]
    )
    n_near = min(1 + opts.restart_batch, len(table_q))
    near = np.argpartition(d2, n_near - 1, axis=1)[:, :n_near]
    near = np.take_along_axis(near, np.argsort(np.take_along_axis(d2, near, 1), 1), 1)
    starts = [table_q[near[:, 0]]]
    if q0b is not None:
        starts.insert(0, q0b)
    owners = np.concatenate([np.arange(B)] * len(starts))
    q_start = np.concatenate(starts)

    rounds_q, rounds_dp, rounds_dr, rounds_owner = [], [], [], []
    solved = np.zeros(B, dtype=bool)
    remaining = opts.restarts
    while True:
        q_end, dp, dr = _run(
            model, q_start, T_goal[owners], opts, None if all_solutions else owners
        )
        rounds_q.append(q_end)
        rounds_dp.append(dp)
        rounds_dr.append(dr)
        rounds_owner.append(owners)
        solved[owners[(dp < opts.tol_position) & (dr < opts.tol_rotation)]] = True
        pending = np.arange(B) if all_solutions else np.flatnonzero(~solved)
        if pending.size == 0 or remaining <= 0:
            break
        n = min(opts.restart_batch, remaining)
        owners = np.repeat(pending, n)
        if remaining == opts.restarts and n_near > 1:
            # First restarts: the next-nearest samples of the seed table, which tend to lie
            # on other branches than the nearest one; later restarts are uniformly random.
            q_start = table_q[near[pending, 1 : 1 + n].reshape(-1)]
            owners = np.repeat(pending, near[:, 1 : 1 + n].shape[1])
        else:
            q_start = rng.uniform(model.lower, model.upper, size=(len(owners), dof))
        remaining -= n

    # Polish: a start that ended close but slowly (a narrow valley near a singularity) gets a
    # long unweighted run; only a handful of rows ever need it.
    if not all_solutions and not solved.all():
        q_cat = np.concatenate(rounds_q)
        own_cat = np.concatenate(rounds_owner)
        dp_cat = np.concatenate(rounds_dp)
        # The closest row of each unsolved target, if it is close enough to be worth it.
        order_p = np.lexsort((dp_cat, own_cat))
        first = order_p[np.r_[True, own_cat[order_p][1:] != own_cat[order_p][:-1]]]
        pick = first[(~solved[own_cat[first]]) & (dp_cat[first] < opts.polish_below)]
        if pick.size:
            polish = replace(opts, weighted=False, max_iterations=opts.polish_iterations)
            q_end, dp, dr = _run(model, q_cat[pick], T_goal[own_cat[pick]], polish)
            rounds_q.append(q_end)
            rounds_dp.append(dp)
            rounds_dr.append(dr)
            rounds_owner.append(own_cat[pick])

    all_q = np.concatenate(rounds_q)
    all_dp = np.concatenate(rounds_dp)
    all_dr = np.concatenate(rounds_dr)
    all_owner = np.concatenate(rounds_owner)
    ok = (all_dp < opts.tol_position) & (all_dr < opts.tol_rotation)
    score = all_dp / model.length_scale + all_dr
    # Group rows by target: converged rows first, then by error.
    order = np.lexsort((score, ~ok, all_owner))
    bounds = np.searchsorted(all_owner[order], np.arange(B + 1))
    results = []
    for b in range(B):
        rows = order[bounds[b]:bounds[b + 1]]
        good = rows[ok[rows]]
        qref = None if q0b is None else q0b[b]
        if good.size:
            sols = all_q[good]
            if len(sols) > 1:
                _, first = np.unique(np.round(sols, 6), axis=0, return_index=True)
                sols = sols[np.sort(first)]
                sols = sols[order_by_distance(sols, qref)]
                dp_b, dr_b = pose_errors(fk(model, sols[0]), T_goal[b])
            else:
                dp_b, dr_b = all_dp[good[0]], all_dr[good[0]]
            results.append(
                IKResult(
                    IKStatus.OK, sols[0], sols, float(dp_b), float(dr_b), True, METHOD,
                    f"converged; {len(sols)} distinct solution(s) found",
                )
            )
        else:
            k = rows[0]
            dp_b, dr_b = all_dp[k], all_dr[k]
            results.append(
                IKResult(
                    IKStatus.NOT_CONVERGED, None, np.empty((0, dof)), float(dp_b), float(dr_b),
                    bool(model.within_limits(all_q[k])), METHOD,
                    f"no solution within tolerance from {1 + opts.restarts} starts: best "
                    f"position error {dp_b:.3g} mm, rotation error {dr_b:.3g} rad"
                    + _reach_note(model, T_goal[b]),
                    extra={"best_q": all_q[k]},
                )
            )
    return results


def _solve_one(K, model: RobotModel, T_goal: np.ndarray, q0: np.ndarray | None,
               opts: NumericOptions) -> IKResult:
    """One target ``(4, 4)`` on the compiled kernels: the starts of ``solve_batch`` in the
    same order, each run to the end before the next, stopping at the first that converges."""
    ch = chain_of(model)
    G = c_array(T_goal)
    table_q, table_f = _seed_table(model, opts.seed_table, opts.table_seed)
    n_near = min(1 + opts.restart_batch, len(table_q))
    n_table = min(opts.restart_batch, opts.restarts, n_near - 1)
    n_random = opts.restarts - (min(opts.restart_batch, opts.restarts) if n_near > 1 else 0)
    near = K.nearest_rows(table_f, G, ch.length_scale, POSITION_FEATURE_WEIGHT, n_near)
    starts = table_q[near[: 1 + n_table]]
    if q0 is not None:
        starts = np.concatenate([np.asarray(q0, dtype=float)[None], starts])
    run = (ch.C, ch.prismatic, ch.offset, ch.lower, ch.upper, ch.lo, ch.hi, ch.length_scale,
           G)
    tol = (float(opts.tol_position), float(opts.tol_rotation))

    def attempt(starts: np.ndarray, iterations: int, weighted: bool):
        q_end = np.empty_like(starts)
        err = np.empty((len(starts), 2))
        hit = K.ik_starts(*run, starts, *tol, int(iterations), float(opts.lambda0),
                          bool(weighted), True, q_end, err)
        return hit, q_end, err

    hit, q_all, err_all = attempt(starts, opts.max_iterations, opts.weighted)
    if hit < 0 and n_random > 0:
        rng = np.random.default_rng(opts.seed)
        randoms = rng.uniform(model.lower, model.upper, size=(n_random, model.dof))
        hit, q_r, err_r = attempt(randoms, opts.max_iterations, opts.weighted)
        if hit >= 0:
            hit += len(q_all)
        q_all, err_all = np.concatenate([q_all, q_r]), np.concatenate([err_all, err_r])
    if hit < 0:
        # Polish the closest start, if close enough (as solve_batch does).
        ran = ~np.isnan(err_all[:, 0])
        k = int(np.argmin(np.where(ran, err_all[:, 0], np.inf)))
        if err_all[k, 0] < opts.polish_below:
            hit_p, q_p, err_p = attempt(q_all[k:k + 1].copy(), opts.polish_iterations, False)
            if hit_p >= 0:
                hit = len(q_all)
            q_all, err_all = np.concatenate([q_all, q_p]), np.concatenate([err_all, err_p])
    if hit >= 0:
        q = q_all[hit]
        return IKResult(
            IKStatus.OK, q, q[None, :], float(err_all[hit, 0]), float(err_all[hit, 1]), True,
            METHOD, "converged; 1 distinct solution(s) found",
        )
    score = err_all[:, 0] / model.length_scale + err_all[:, 1]
    k = int(np.argmin(np.where(np.isnan(score), np.inf, score)))
    dp_b, dr_b = float(err_all[k, 0]), float(err_all[k, 1])
    return IKResult(
        IKStatus.NOT_CONVERGED, None, np.empty((0, model.dof)), dp_b, dr_b,
        bool(model.within_limits(q_all[k])), METHOD,
        f"no solution within tolerance from {1 + opts.restarts} starts: best position error "
        f"{dp_b:.3g} mm, rotation error {dr_b:.3g} rad" + _reach_note(model, T_goal),
        extra={"best_q": q_all[k]},
    )
