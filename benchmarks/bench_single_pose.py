"""One pose per call: FK, closed-form IK and numeric IK against compiled references.

Prints, in one run:

1. start-up: the cost of ``kinematics.fast.warm_up()`` in a fresh process with numba's cache
   warm (the usual case) and cold (the first run on a machine: every kernel compiled), and
   what the first FK call costs in a fresh process that skipped the warm-up;
2. FK, one configuration per call: ours, the Robotics Toolbox (``fkine``, and its C++
   ``ETS.eval``) and Pinocchio (``forwardKinematics`` + ``updateFramePlacement``) if
   installed, each robot built from our model's data and checked against our FK first;
3. FK per configuration for 10^4, 10^5 and 10^6 configurations in one call, with the
   compiled kernels and with the numpy path (``kinematics.fast.ENABLED = False``);
4. closed-form IK, one pose per call (``glt_palletizer``'s spherical wrist, ``pile_driver``);
5. numeric IK, one pose per call, on ``glt_palletizer`` and ``hyper_redundant_9dof``: our
   ``solve_ik(method="numeric")`` beside the Toolbox's C++ ``ETS.ik_LM`` on the same poses:
   success rate (the solver's flag AND within limits AND our-FK residuals under 1e-3 mm and
   1e-3 rad), mean and median time per pose.

Targets come from seeds the solver never saw: ``*_SEED`` below are neither the numeric
solver's seed-table seed (``kinematics.ik.numeric.TABLE_SEED``) nor its restart seed
(``NumericOptions().seed``), which the script checks, and it checks that no configuration it
draws is a row of the seed table. Timings are wall-clock on a shared machine: noisy. It is a
report: the exit status is 0 whatever the figures.

Run: ``.venv/bin/python benchmarks/bench_single_pose.py [--ik-poses 1000] [--skip-cold]``
(needs the ``bench`` extra: roboticstoolbox-python, spatialmath-python; pin optional).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from kinematics import fast
from kinematics.fk import fk
from kinematics.ik import NumericOptions, solve_ik
from kinematics.ik.numeric import TABLE_SEED, _seed_table
from kinematics.library import builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import pose_errors, rot_x, rot_z, trans

ROOT = Path(__file__).resolve().parents[1]
#: Seeds of every configuration drawn here (never the solver's own seeds, checked below).
FK_SEED = 101
CLOSED_FORM_SEED = 4242
GLT_POSE_SEED = 2026
ARM9_POSE_SEED = 909
FK_SIZES = (10_000, 100_000, 1_000_000)
ACCEPT_POSITION = 1e-3  # mm: an IK answer counts only if our FK puts the tool this close...
ACCEPT_ROTATION = 1e-3  # rad: ...and this close in orientation
# Goals of the single-pose fast path.
FK_SINGLE_GOAL_US = 10.0
CLOSED_FORM_GOAL_US = 30.0
NUMERIC_GOAL_MS = {"glt_palletizer": 0.5, "hyper_redundant_9dof": 0.3}
TOOLBOX_RATIO_GOAL = 1.5  # our mean time per pose / the Toolbox's ik_LM, at most
FK_FLAT_GOAL = 1.5  # time per configuration at 10^6 / at 10^4, at most

try:
    import roboticstoolbox as rtb
    from spatialmath import SE3
except ImportError:  # the reference columns stay empty
    rtb = None
try:
    import pinocchio as pin
except ImportError:
    pin = None


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fk-calls", type=int, default=20000, help="single FK calls timed")
    ap.add_argument("--cf-poses", type=int, default=1000, help="closed-form IK poses")
    ap.add_argument("--ik-poses", type=int, default=1000, help="numeric IK poses per robot")
    ap.add_argument("--skip-cold", action="store_true",
                    help="skip the cold-cache start-up (it compiles every kernel: ~0.5 min)")
    return ap.parse_args()


def check_seeds() -> None:
    solver = {TABLE_SEED, NumericOptions().seed}
    mine = {FK_SEED, CLOSED_FORM_SEED, GLT_POSE_SEED, ARM9_POSE_SEED}
    if solver & mine:
        raise SystemExit(f"benchmark seeds {sorted(solver & mine)} are the solver's own")


def unseen_configurations(m: RobotModel, seed: int, n: int) -> np.ndarray:
    """``n`` configurations within the limits from ``seed``, none of them in the seed table."""
    Q = np.random.default_rng(seed).uniform(m.lower, m.upper, (n, m.dof))
    opts = NumericOptions()
    table_q, _ = _seed_table(m, opts.seed_table, opts.table_seed)
    t2 = np.einsum("ij,ij->i", table_q, table_q)[None, :]
    for start in range(0, n, 4096):  # (4096, table) distances at a time: memory bounded
        B = Q[start:start + 4096]
        d2 = np.einsum("ij,ij->i", B, B)[:, None] - 2.0 * B @ table_q.T + t2
        if d2.min() < 1e-12:
            raise SystemExit(f"a configuration from seed {seed} is in the seed table")
    return Q


def per_call_us(fn: Callable, inputs, repeats: int = 5) -> tuple[float, float]:
    """Best over ``repeats`` of the mean wall and CPU (this thread's) time, µs, of ``fn(x)``
    over ``inputs``."""
    fn(inputs[0])
    wall = cpu = float("inf")
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.thread_time()
        for x in inputs:
            fn(x)
        cpu = min(cpu, (time.thread_time() - c0) / len(inputs))
        wall = min(wall, (time.perf_counter() - t0) / len(inputs))
    return wall * 1e6, cpu * 1e6


# ---- references ---------------------------------------------------------------------------
def toolbox_dh(m: RobotModel):
    """The Toolbox's twin of a D-H model, from the model's own joint, base and tool data."""
    make = rtb.RevoluteMDH if m.convention == "mdh" else rtb.RevoluteDH
    links = [make(a=j.a, alpha=j.alpha, d=j.d, offset=j.offset, qlim=[j.lower, j.upper])
             for j in m.joints]
    return rtb.DHRobot(links, name=m.id, base=SE3(m.base), tool=SE3(m.tool))


def toolbox_poe(m: RobotModel):
    """The Toolbox's twin of a product-of-exponentials arm whose revolute axes are coordinate
    axes through their points (the 9-DOF arm): translate to each point, turn about the axis."""
    E = rtb.ET
    ets = rtb.ETS([E.SE3(np.asarray(m.base))])
    origin = np.zeros(3)
    for j in m.joints:
        axis = np.asarray(j.axis)
        k = int(np.argmax(np.abs(axis)))
        if not j.revolute or abs(axis[k] - 1.0) > 1e-12 or j.offset:
            raise SystemExit("toolbox_poe builds revolute joints about +x, +y or +z only")
        step = np.asarray(j.point) - origin
        origin = np.asarray(j.point, dtype=float)
        ets *= E.SE3(np.asarray(trans(*step)))
        ets *= (E.Rx, E.Ry, E.Rz)[k](qlim=[j.lower, j.upper])
    ets *= E.SE3(np.asarray(trans(*-origin)) @ m.home @ m.tool)
    return rtb.Robot(ets, name=m.id)


def toolbox_robot(m: RobotModel):
    return toolbox_poe(m) if m.convention == "poe" else toolbox_dh(m)


def pinocchio_model(m: RobotModel):
    """Pinocchio's twin of ``m`` and the id of its tool frame (D-H: each joint's placement
    is the previous joint's fixed part, its own link constants and its offset; screws: the
    step between axis points, base orientation at q = 0)."""
    model = pin.Model()
    parent = 0
    if m.convention == "poe":
        origin = np.zeros(3)
        for j in m.joints:
            if j.offset or not j.revolute:
                raise SystemExit("pinocchio_model builds revolute screws without offsets only")
            step = trans(*(np.asarray(j.point) - origin))
            placement = (np.asarray(m.base) @ step) if parent == 0 else step
            origin = np.asarray(j.point, dtype=float)
            parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(np.asarray(j.axis)),
                                    pin.SE3(placement), j.name)
        tool = trans(*-origin) @ m.home @ m.tool
    else:
        mdh = m.convention == "mdh"
        post = np.asarray(m.base, dtype=float)
        for j in m.joints:
            A = rot_x(j.alpha) @ trans(j.a) if mdh else trans(j.a) @ rot_x(j.alpha)
            pre = post @ A if mdh else post
            if j.revolute:
                placement, joint, after = pre @ rot_z(j.offset), pin.JointModelRZ(), \
                    trans(0, 0, j.d)
            else:
                placement, joint, after = pre @ rot_z(j.theta) @ trans(0, 0, j.offset), \
                    pin.JointModelPZ(), np.eye(4)
            parent = model.addJoint(parent, joint, pin.SE3(placement), j.name)
            post = after if mdh else after @ A
        tool = post @ m.tool
    fid = model.addFrame(pin.Frame("tool", parent, pin.SE3(tool), pin.FrameType.OP_FRAME))
    return model, model.createData(), fid


# ---- sections -----------------------------------------------------------------------------
STARTUP_SNIPPET = """
import json, time
t0 = time.perf_counter()
import kinematics
from kinematics import fast
t1 = time.perf_counter()
if {warm}:
    r = fast.warm_up()
    out = dict(kinematics=t1 - t0, numba=r.import_seconds, kernels=r.kernel_seconds,
               enabled=r.enabled)
else:
    import numpy as np
    m = kinematics.builtin_model("glt_palletizer")
    q = m.mid_configuration()
    t2 = time.perf_counter(); kinematics.fk(m, q); t3 = time.perf_counter()
    kinematics.fk(m, q); t4 = time.perf_counter()
    out = dict(kinematics=t1 - t0, first_fk=t3 - t2, second_fk=t4 - t3)
print(json.dumps(out))
"""


def fresh_process(warm: bool, cache_dir: str | None = None) -> dict:
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    done = subprocess.run([sys.executable, "-c", STARTUP_SNIPPET.format(warm=warm)],
                          cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench_startup(skip_cold: bool) -> dict:
    print("\n[1] start-up, fresh processes (numba's import, then loading or compiling kernels)")
    fresh_process(True)  # make sure the cache next to kinematics/_kernels.py is filled
    warm = fresh_process(True)
    print(f"    warm cache: import kinematics {warm['kinematics']:.2f} s, warm_up(): numba "
          f"{warm['numba']:.2f} s + kernels {warm['kernels']:.2f} s = "
          f"{warm['numba'] + warm['kernels']:.2f} s")
    lazy = fresh_process(False)
    print(f"    without warm_up(): first fk call {lazy['first_fk'] * 1e3:.0f} ms (numba's "
          f"import and the FK kernel's load), the next {lazy['second_fk'] * 1e6:.1f} us")
    out = {"warm": warm["numba"] + warm["kernels"], "first_fk": lazy["first_fk"]}
    if skip_cold:
        print("    cold cache: skipped (--skip-cold)")
        return out
    with tempfile.TemporaryDirectory() as cache:
        cold = fresh_process(True, cache)
    print(f"    cold cache (first run on a machine, every kernel compiled): warm_up() "
          f"{cold['numba'] + cold['kernels']:.1f} s")
    out["cold"] = cold["numba"] + cold["kernels"]
    return out


def bench_fk_single(calls: int) -> dict:
    print(f"\n[2] FK, one configuration per call (mean over {calls} calls, best of 5), µs "
          "wall (cpu)")
    print(f"    {'robot':<22}{'ours':>14}{'Toolbox fkine':>16}{'Toolbox eval':>16}"
          f"{'Pinocchio':>14}  (max |ours - ref|)")
    out = {}
    for robot_id in ("glt_palletizer", "hyper_redundant_9dof"):
        m = builtin_model(robot_id)
        Q = unseen_configurations(m, FK_SEED, min(calls, 2000))
        inputs = [Q[k % len(Q)] for k in range(calls)]
        ours = per_call_us(lambda q, m=m: fk(m, q), inputs)
        cols, diffs = [], []
        if rtb is not None:
            robot = toolbox_robot(m)
            ets = robot.ets()
            diffs.append(max(np.abs(robot.fkine(q).A - fk(m, q)).max() for q in Q[:20]))
            cols.append(per_call_us(robot.fkine, inputs[: calls // 4]))
            cols.append(per_call_us(ets.eval, inputs))
        else:
            cols += [(float("nan"), float("nan"))] * 2
        if pin is not None:
            pm, pd, fid = pinocchio_model(m)

            def pin_fk(q, pm=pm, pd=pd, fid=fid):
                pin.forwardKinematics(pm, pd, q)
                return pin.updateFramePlacement(pm, pd, fid)

            diffs.append(max(np.abs(pin_fk(q).homogeneous - fk(m, q)).max() for q in Q[:20]))
            cols.append(per_call_us(pin_fk, inputs))
        else:
            cols.append((float("nan"), float("nan")))
        cells = "".join(f"{f'{w:.2f} ({c:.2f})':>{width}}"
                        for (w, c), width in zip([ours, *cols], (14, 16, 16, 14)))
        print(f"    {robot_id:<22}{cells}  ({', '.join(f'{d:.1e}' for d in diffs)} mm)")
        out[robot_id] = ours[0]
    return out


def bench_fk_sizes() -> dict:
    print("\n[3] FK per configuration, one call for all (best of 10, 5, 3), ns per "
          "configuration")
    m = builtin_model("glt_palletizer")
    print(f"    {'configurations':>16}{'ours (kernels)':>16}{'ours (numpy)':>14}")
    out = {}
    for n in FK_SIZES:
        Q = unseen_configurations(m, FK_SEED, n)
        times = []
        for enabled in (True, False):
            fast.ENABLED = enabled
            try:
                fk(m, Q)
                best = float("inf")
                for _ in range({10_000: 10, 100_000: 5}.get(n, 3)):
                    t0 = time.perf_counter()
                    fk(m, Q)
                    best = min(best, time.perf_counter() - t0)
            finally:
                fast.ENABLED = True
            times.append(best / n * 1e9)
        print(f"    {n:>16,}{times[0]:>16.1f}{times[1]:>14.1f}")
        out[n] = times[0]
    return out


def bench_closed_form(n: int) -> dict:
    print(f"\n[4] closed-form IK, one pose per call ({n} unseen poses, mean over them, best "
          "of 5), µs")
    out = {}
    for robot_id in ("glt_palletizer", "pile_driver"):
        m = builtin_model(robot_id)
        T = fk(m, unseen_configurations(m, CLOSED_FORM_SEED, n))
        solved = [solve_ik(m, Tk, method="analytic")[0] for Tk in T]
        rate = 100.0 * np.mean([r.success for r in solved])
        us, cpu = per_call_us(lambda Tk, m=m: solve_ik(m, Tk, method="analytic"), list(T))
        print(f"    {robot_id:<22}{us:>8.1f} µs wall ({cpu:.1f} cpu)   success {rate:.1f} %")
        out[robot_id] = us
    return out


def accepted(m: RobotModel, T: np.ndarray, qs: list, flags: list) -> np.ndarray:
    ok = np.zeros(len(T), dtype=bool)
    for k, (q, flag) in enumerate(zip(qs, flags)):
        if flag and q is not None and m.within_limits(q):
            dp, dr = pose_errors(fk(m, q), T[k])
            ok[k] = dp < ACCEPT_POSITION and dr < ACCEPT_ROTATION
    return ok


def timed(solve: Callable, T: np.ndarray) -> tuple[list, list, np.ndarray, np.ndarray]:
    """Answers, flags, and per-pose wall and CPU (this thread's) times in ms."""
    solve(T[0])
    qs, flags, wall, cpu = [], [], [], []
    for Tk in T:
        t0, c0 = time.perf_counter(), time.thread_time()
        q, flag = solve(Tk)
        cpu.append(time.thread_time() - c0)
        wall.append(time.perf_counter() - t0)
        qs.append(q)
        flags.append(flag)
    return qs, flags, np.array(wall) * 1e3, np.array(cpu) * 1e3


def bench_numeric(n: int) -> dict:
    print(f"\n[5] numeric IK, one pose per call, {n} unseen reachable poses per robot")
    print("    wall-clock times per pose; 'cpu' is the calling thread's CPU time, which the "
          "other")
    print("    processes on a shared machine do not inflate")
    print(f"    {'robot':<22}{'solver':<20}{'success %':>10}{'mean ms':>9}{'median ms':>11}"
          f"{'p99 ms':>8}{'cpu mean':>10}")
    out = {}
    for robot_id, seed in (("glt_palletizer", GLT_POSE_SEED),
                           ("hyper_redundant_9dof", ARM9_POSE_SEED)):
        m = builtin_model(robot_id)
        T = fk(m, unseen_configurations(m, seed, n))

        def ours(Tk, m=m):
            (r,) = solve_ik(m, Tk, method="numeric")
            return r.q, r.success

        rows = [("ours numeric", *timed(ours, T))]
        if rtb is not None:
            ets = toolbox_robot(m).ets()

            def toolbox(Tk, ets=ets):
                sol = ets.ik_LM(Tk)
                return np.asarray(sol.q, dtype=float), bool(sol.success)

            rows.append(("Toolbox ik_LM (C++)", *timed(toolbox, T)))
        result = {}
        for name, qs, flags, ms, cpu in rows:
            rate = 100.0 * accepted(m, T, qs, flags).mean()
            print(f"    {robot_id:<22}{name:<20}{rate:>10.1f}{ms.mean():>9.3f}"
                  f"{statistics.median(ms):>11.3f}{np.percentile(ms, 99):>8.3f}"
                  f"{cpu.mean():>10.3f}")
            result[name] = (rate, float(ms.mean()), float(cpu.mean()))
        out[robot_id] = result
    return out


def print_summary(startup, fk1, sizes, closed, numeric) -> None:
    checks = []
    for robot_id, us in fk1.items():
        checks.append((f"FK one call <= {FK_SINGLE_GOAL_US:g} us ({robot_id})", f"{us:.2f} us",
                       us <= FK_SINGLE_GOAL_US))
    flat = sizes[FK_SIZES[-1]] / sizes[FK_SIZES[0]]
    checks.append((f"FK per configuration 10^6 / 10^4 <= {FK_FLAT_GOAL:g}", f"{flat:.2f}",
                   flat <= FK_FLAT_GOAL))
    for robot_id, us in closed.items():
        checks.append((f"closed form one pose <= {CLOSED_FORM_GOAL_US:g} us ({robot_id})",
                       f"{us:.1f} us", us <= CLOSED_FORM_GOAL_US))
    for robot_id, rows in numeric.items():
        rate, ms, cpu = rows["ours numeric"]
        goal = NUMERIC_GOAL_MS[robot_id]
        checks.append((f"numeric one pose <= {goal:g} ms at 100 % ({robot_id})",
                       f"{ms:.3f} ms wall ({cpu:.3f} cpu), {rate:.1f} %",
                       ms <= goal and rate >= 100.0))
        if "Toolbox ik_LM (C++)" in rows:
            ratio = ms / rows["Toolbox ik_LM (C++)"][1]
            ratio_cpu = cpu / rows["Toolbox ik_LM (C++)"][2]
            checks.append((f"numeric / Toolbox ik_LM <= {TOOLBOX_RATIO_GOAL:g} ({robot_id})",
                           f"{ratio:.2f} wall ({ratio_cpu:.2f} cpu)",
                           ratio <= TOOLBOX_RATIO_GOAL))
    print("\nSUMMARY")
    for label, value, ok in checks:
        print(f"    {'PASS' if ok else 'over':<5} {label:<52} measured {value}")
    cold = f"{startup['cold']:.1f} s" if "cold" in startup else "not measured"
    print(f"    start-up: warm_up() {startup['warm']:.2f} s with numba's cache warm, {cold} "
          "cold")


def main() -> None:
    args = parse_args()
    check_seeds()
    versions = [f"python {platform.python_version()}", f"numpy {np.__version__}"]
    for name in ("numba", "roboticstoolbox", "pinocchio"):
        module = sys.modules.get(name) or (__import__(name) if name == "numba" else None)
        if module is not None:
            versions.append(f"{name} {module.__version__}")
    print("kinoplan, one pose per call: " + ", ".join(versions))
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"kernels {'on' if fast.kernels() is not None else 'OFF (numpy path)'}; "
          "wall-clock figures on a shared machine are noisy")
    startup = bench_startup(args.skip_cold)
    fast.warm_up()
    fk1 = bench_fk_single(args.fk_calls)
    sizes = bench_fk_sizes()
    closed = bench_closed_form(args.cf_poses)
    numeric = bench_numeric(args.ik_poses)
    print_summary(startup, fk1, sizes, closed, numeric)


if __name__ == "__main__":
    main()
