"""Benchmark kinoplan's kinematics of the GLT palletizer against the Robotics Toolbox for Python.

Runs both libraries in one process on the same seeded inputs (float64) and prints a report:

1. FK: random configurations within the joint limits, ``fk(m, Q)`` vs ``robot.fkine(Q)``.
2. IK: reachable poses (FK of random configurations within limits), solved by our closed form,
   our batched numeric solver (all poses in one call) and the Toolbox's ``ikine_LM`` (one call
   per pose, on a subset). Every answer is checked with our own ``fk``.
3. A plain-text summary with PASS/FAIL per target. It is a report: the exit status is 0 even
   when a target is missed.

The Toolbox robot is built from our model's data (joints, base, tool), never from a second copy
of the numbers, and both FKs must agree before anything is timed.

Inputs the solver never saw: the poses come from ``POSE_SEED``, which is neither the numeric
solver's seed-table seed (``kinematics.ik.numeric.TABLE_SEED``) nor its restart seed
(``NumericOptions().seed``); the script refuses those seeds and checks that no configuration
it draws is a row of the seed table.

Run it with ``make bench`` (installs the ``bench`` extra), or directly:
``.venv/bin/python benchmarks/bench_glt_kinematics.py [--fk-samples N] [--ik-poses N] ...``
"""

# OPENBLAS_CORETYPE may be set on this machine; leave the environment alone (this script only
# reports its value, it never sets or changes it).

from __future__ import annotations

import argparse
import inspect
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import roboticstoolbox as rtb
import spatialmath
from spatialmath import SE3

from kinematics.fk import fk
from kinematics.ik import NumericOptions, solve_ik
from kinematics.ik.numeric import TABLE_SEED, _seed_table
from kinematics.library import builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import pose_errors

ROBOT_ID = "glt_palletizer"
FK_CHECK_SAMPLES = 8
FK_CHECK_TOL = 1e-6  # max abs difference of the 4x4 entries (mm for the translation)
ACCEPT_POSITION = 1e-3  # mm: an IK answer counts only if our FK puts the tool this close...
ACCEPT_ROTATION = 1e-3  # rad: ...and this close in orientation
FK_SPEED_TARGET = 200.0  # Toolbox time / ours
IK_SPEED_TARGET = 10.0  # Toolbox per-pose time / ours
ANALYTIC_SUCCESS_TARGET = 100.0  # %
NUMERIC_SUCCESS_TARGET = 99.9  # %
RTB_SLOW_SECONDS = 10.0  # stop repeating a Toolbox timing once one run takes this long
#: Default seed of every configuration drawn here: not a seed the numeric solver draws from.
POSE_SEED = 2718


@dataclass
class IKRow:
    """Outcome of one IK method on a set of poses."""

    name: str
    poses: int
    seconds: float
    flagged: np.ndarray  # the solver's own success flag, per pose
    accepted: np.ndarray  # flag AND within limits AND our FK residuals under the ACCEPT_* bounds
    dp: np.ndarray  # position residual (mm) by our FK, NaN where there is no q
    dr: np.ndarray  # rotation residual (rad) by our FK, NaN where there is no q

    @property
    def ms_per_pose(self) -> float:
        return 1e3 * self.seconds / self.poses

    @property
    def flag_rate(self) -> float:
        return 100.0 * float(np.mean(self.flagged))

    @property
    def success_rate(self) -> float:
        return 100.0 * float(np.mean(self.accepted))

    def max_residuals(self) -> tuple[float, float]:
        """Largest residuals over the poses the solver reported as solved."""
        if not self.flagged.any():
            return float("nan"), float("nan")
        return float(np.nanmax(self.dp[self.flagged])), float(np.nanmax(self.dr[self.flagged]))


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fk-samples", type=int, default=30000, help="FK configurations")
    parser.add_argument("--ik-poses", type=int, default=1000, help="IK poses for our solvers")
    parser.add_argument(
        "--rtb-ik-poses", type=int, default=200, help="IK poses (a subset) for ikine_LM"
    )
    parser.add_argument("--seed", type=int, default=POSE_SEED,
                        help=f"seed of numpy.random.default_rng (default {POSE_SEED}; the "
                        "solver's own seeds are refused)")
    args = parser.parse_args()
    solver_seeds = {TABLE_SEED, NumericOptions().seed}
    if args.seed in solver_seeds:
        parser.error(f"--seed {args.seed} is one the numeric solver draws its starts from "
                     f"({sorted(solver_seeds)}): its poses would not be unseen")
    return args


def assert_unseen(m: RobotModel, Q: np.ndarray) -> None:
    """No configuration of ``Q`` is a row of the numeric solver's seed table."""
    opts = NumericOptions()
    table_q, _ = _seed_table(m, opts.seed_table, opts.table_seed)
    t2 = np.einsum("ij,ij->i", table_q, table_q)[None, :]
    for start in range(0, len(Q), 4096):  # (4096, table) distances at a time
        B = Q[start:start + 4096]
        d2 = np.einsum("ij,ij->i", B, B)[:, None] - 2.0 * B @ table_q.T + t2
        if d2.min() < 1e-12:
            raise SystemExit("a benchmark configuration is in the solver's seed table")


def toolbox_robot(m: RobotModel) -> rtb.DHRobot:
    """The Toolbox's twin of ``m``, built from the model's own joint, base and tool data."""
    links = [
        rtb.RevoluteMDH(a=j.a, alpha=j.alpha, d=j.d, offset=j.offset, qlim=[j.lower, j.upper])
        for j in m.joints
    ]
    return rtb.DHRobot(links, name=m.id, base=SE3(m.base), tool=SE3(m.tool))


def toolbox_fk(robot: rtb.DHRobot, Q: np.ndarray) -> np.ndarray:
    """``robot.fkine`` as an ``(N, 4, 4)`` array."""
    return np.asarray(robot.fkine(Q).A).reshape(-1, 4, 4)


def random_configurations(m: RobotModel, rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(m.lower, m.upper, size=(n, m.dof))


def best_time(fn: Callable[[], object], repeats: int, slow: float = float("inf")) -> float:
    """Best wall time of ``fn()`` over ``repeats`` runs; stops early once a run exceeds ``slow``."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        elapsed = time.perf_counter() - t0
        best = min(best, elapsed)
        if elapsed > slow:
            break
    return best


def check_fk_agreement(m: RobotModel, robot: rtb.DHRobot, rng: np.random.Generator) -> float:
    """Max abs difference between the two FKs on a few random configurations; exits if large."""
    Q = random_configurations(m, rng, FK_CHECK_SAMPLES)
    diff = float(np.abs(fk(m, Q) - toolbox_fk(robot, Q)).max())
    verdict = "OK" if diff < FK_CHECK_TOL else "MISMATCH"
    print(f"FK agreement on {len(Q)} random configurations: max |ours - Toolbox| = "
          f"{diff:.3e} (tolerance {FK_CHECK_TOL:g}) {verdict}")
    if diff >= FK_CHECK_TOL:
        raise SystemExit("the Toolbox robot does not reproduce our FK; nothing to compare")
    return diff


def bench_fk(m: RobotModel, robot: rtb.DHRobot, rng: np.random.Generator, n: int) -> float:
    """Time both FKs on ``n`` configurations; returns the speed ratio Toolbox / ours."""
    Q = random_configurations(m, rng, n)
    ours = best_time(lambda: fk(m, Q), repeats=5)
    theirs = best_time(lambda: robot.fkine(Q), repeats=3, slow=RTB_SLOW_SECONDS)
    ratio = theirs / ours
    print(f"\n[1] FK, {n} configurations within limits (best of 5 ours, best of <=3 Toolbox)")
    print(f"    ours    fk(m, Q)          {ours * 1e3:10.2f} ms  ({ours / n * 1e6:8.3f} us/config)")
    print(f"    Toolbox robot.fkine(Q)    {theirs * 1e3:10.2f} ms  "
          f"({theirs / n * 1e6:8.3f} us/config)")
    print(f"    ratio Toolbox / ours      {ratio:10.1f}x")
    return ratio


def residuals(m: RobotModel, qs: list[np.ndarray | None], T: np.ndarray):
    """Our-FK position (mm) and rotation (rad) residuals of answers ``qs`` to targets ``T``."""
    dp = np.full(len(qs), np.nan)
    dr = np.full(len(qs), np.nan)
    have = np.array([q is not None for q in qs], dtype=bool)
    inside = np.zeros(len(qs), dtype=bool)
    if have.any():
        Q = np.array([q for q in qs if q is not None], dtype=float)
        dp[have], dr[have] = pose_errors(fk(m, Q), T[have])
        inside[have] = m.within_limits(Q)
    return dp, dr, inside


def make_row(name, m, T, qs, flagged, seconds) -> IKRow:
    dp, dr, inside = residuals(m, qs, T)
    flagged = np.asarray(flagged, dtype=bool)
    with np.errstate(invalid="ignore"):
        close = (dp < ACCEPT_POSITION) & (dr < ACCEPT_ROTATION)
    return IKRow(name, len(T), seconds, flagged, flagged & inside & close, dp, dr)


def bench_ours(m: RobotModel, T: np.ndarray, method: str) -> IKRow:
    solve_ik(m, T[:2], method=method)  # warm-up: one-time caches (e.g. the numeric seed table)
    t0 = time.perf_counter()
    results = solve_ik(m, T, method=method)
    seconds = time.perf_counter() - t0
    qs = [r.q if r.success else None for r in results]
    return make_row(f"ours {method}", m, T, qs, [r.success for r in results], seconds)


def ikine_lm_kwargs(robot: rtb.DHRobot) -> dict:
    """``{"joint_limits": True}`` if the installed ``ikine_LM`` takes that argument.

    ``DHRobot.ikine_LM`` may forward ``**kwargs`` to ``ETS.ikine_LM``; look at both.
    """
    for fn in (robot.ikine_LM, getattr(rtb.ETS, "ikine_LM", None)):
        if fn is not None and "joint_limits" in inspect.signature(fn).parameters:
            return {"joint_limits": True}
    return {}


def bench_toolbox(m: RobotModel, robot: rtb.DHRobot, T: np.ndarray, kwargs: dict) -> IKRow:
    robot.ikine_LM(SE3(T[0], check=False), **kwargs)  # warm-up, untimed
    qs: list[np.ndarray | None] = []
    flags: list[bool] = []
    t0 = time.perf_counter()
    for Tk in T:
        sol = robot.ikine_LM(SE3(Tk, check=False), **kwargs)
        flags.append(bool(sol.success))
        qs.append(np.asarray(sol.q, dtype=float).reshape(m.dof) if sol.success else None)
    seconds = time.perf_counter() - t0
    return make_row("Toolbox ikine_LM", m, T, qs, flags, seconds)


def print_ik_table(rows: list[IKRow]) -> None:
    print(f"    {'method':<18}{'poses':>6}{'total s':>10}{'ms/pose':>10}{'flag %':>8}"
          f"{'success %':>11}{'max pos mm':>12}{'max rot rad':>13}")
    for r in rows:
        dp, dr = r.max_residuals()
        print(f"    {r.name:<18}{r.poses:>6}{r.seconds:>10.3f}{r.ms_per_pose:>10.4f}"
              f"{r.flag_rate:>8.1f}{r.success_rate:>11.2f}{dp:>12.2e}{dr:>13.2e}")


def bench_ik(m, robot, rng, n: int, n_rtb: int) -> tuple[IKRow, IKRow, IKRow]:
    Q = random_configurations(m, rng, n)
    assert_unseen(m, Q)
    T = fk(m, Q)
    kwargs = ikine_lm_kwargs(robot)
    analytic = bench_ours(m, T, "analytic")
    numeric = bench_ours(m, T, "numeric")
    toolbox = bench_toolbox(m, robot, T[: min(n_rtb, n)], kwargs)
    print(f"\n[2] IK, {n} reachable poses (FK of random configurations within limits)")
    print(f"    ikine_LM: first {toolbox.poses} poses, one call each, options = defaults + "
          f"{kwargs or 'nothing (no joint_limits argument)'}")
    print("    ours: one solve_ik call for all poses, after an untimed 2-pose warm-up")
    print("    flag % = the solver's own success flag; success % = flag AND q within limits")
    print(f"      AND our-FK residual < {ACCEPT_POSITION:g} mm and < {ACCEPT_ROTATION:g} rad")
    print("    max pos / max rot = largest our-FK residual over the poses the solver flagged")
    print_ik_table([analytic, numeric, toolbox])
    for r in (analytic, numeric):
        ratio = toolbox.ms_per_pose / r.ms_per_pose
        print(f"    ratio Toolbox / {r.name:<14} per pose {ratio:8.1f}x")
    return analytic, numeric, toolbox


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def print_summary(fk_ratio: float, analytic: IKRow, numeric: IKRow, toolbox: IKRow) -> None:
    a_speed = toolbox.ms_per_pose / analytic.ms_per_pose
    n_speed = toolbox.ms_per_pose / numeric.ms_per_pose
    checks = [
        (f"FK ours >= {FK_SPEED_TARGET:g}x faster than fkine", f"{fk_ratio:.2f}x",
         fk_ratio >= FK_SPEED_TARGET),
        (f"IK closed form success = {ANALYTIC_SUCCESS_TARGET:g}%",
         f"{analytic.success_rate:.2f}%", analytic.success_rate >= ANALYTIC_SUCCESS_TARGET),
        (f"IK numeric success >= {NUMERIC_SUCCESS_TARGET:g}%", f"{numeric.success_rate:.2f}%",
         numeric.success_rate >= NUMERIC_SUCCESS_TARGET),
        (f"IK closed form >= {IK_SPEED_TARGET:g}x faster than ikine_LM", f"{a_speed:.2f}x",
         a_speed >= IK_SPEED_TARGET),
        (f"IK numeric >= {IK_SPEED_TARGET:g}x faster than ikine_LM", f"{n_speed:.2f}x",
         n_speed >= IK_SPEED_TARGET),
    ]
    print("\nSUMMARY")
    for label, value, ok in checks:
        print(f"    {verdict(ok)}  {label:<46} measured {value}")


def print_header(m: RobotModel, args: argparse.Namespace) -> None:
    print(f"kinoplan vs Robotics Toolbox for Python: {m.name} ('{m.id}', {m.convention})")
    print(f"python {platform.python_version()}, numpy {np.__version__}, roboticstoolbox "
          f"{rtb.__version__}, spatialmath {spatialmath.__version__}, "
          f"OPENBLAS_CORETYPE={os.environ.get('OPENBLAS_CORETYPE', '(unset)')}")
    print(f"seed {args.seed}, fk-samples {args.fk_samples}, ik-poses {args.ik_poses}, "
          f"rtb-ik-poses {args.rtb_ik_poses}")


def main() -> None:
    args = parse_args()
    rng = np.random.default_rng(args.seed)
    m = builtin_model(ROBOT_ID)
    robot = toolbox_robot(m)
    print_header(m, args)
    check_fk_agreement(m, robot, rng)
    fk_ratio = bench_fk(m, robot, rng, args.fk_samples)
    analytic, numeric, toolbox = bench_ik(m, robot, rng, args.ik_poses, args.rtb_ik_poses)
    print_summary(fk_ratio, analytic, numeric, toolbox)


if __name__ == "__main__":
    main()
