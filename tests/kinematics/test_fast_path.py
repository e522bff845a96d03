"""The compiled fast path (``kinematics.fast``) against the batched numpy path it replaces.

Both paths are run on the same inputs, the kernels switched on and off through
``kinematics.fast.ENABLED``: FK and Jacobian of random models (modified and standard D-H,
product of exponentials, revolute and prismatic joints, base and tool transforms) agree to
1e-9; the closed forms return the same statuses, messages and solutions; numeric IK keeps its
contract (flags, residuals, limits) on both paths; nothing compiles after ``warm_up``; with
the kernels off nothing of numba is loaded.
"""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinematics import fast
from kinematics.fk import _fk_numpy, fk
from kinematics.ik import IKResult, NumericOptions, _prepare_one, prepare_targets, solve_ik
from kinematics.ik.numeric import TABLE_SEED, _seed_table
from kinematics.jacobian import jacobian_and_pose
from kinematics.library import builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import pose_errors, rpy_to_matrix

ROOT = Path(__file__).resolve().parents[2]
numba = pytest.importorskip("numba")
#: Tests that compare the two paths need the kernels (``KINOPLAN_JIT=0`` switches them off).
needs_kernels = pytest.mark.skipif(not fast.ENABLED,
                                   reason="compiled kernels switched off (KINOPLAN_JIT=0)")


@pytest.fixture
def kernels_off(monkeypatch):
    """Run the body with the compiled kernels switched off (the numpy path)."""
    monkeypatch.setattr(fast, "ENABLED", False)


@contextlib.contextmanager
def kernels_enabled(flag: bool):
    before = fast.ENABLED
    fast.ENABLED = flag
    try:
        yield
    finally:
        fast.ENABLED = before


def both_paths(call):
    """``call()`` with the kernels on, then off: ``(fast, numpy)``."""
    with kernels_enabled(True):
        assert fast.kernels() is not None
        on = call()
    with kernels_enabled(False):
        off = call()
    return on, off


# ---- random models --------------------------------------------------------------------
lengths = st.floats(-600.0, 600.0, allow_nan=False)
angles = st.one_of(st.sampled_from([0.0, math.pi / 2, -math.pi / 2, math.pi]),
                   st.floats(-math.pi, math.pi, allow_nan=False))


@st.composite
def poses(draw) -> list[list[float]]:
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix([draw(angles), draw(angles), draw(angles)])
    T[:3, 3] = [draw(lengths), draw(lengths), draw(lengths)]
    return T.tolist()


@st.composite
def unit_vectors(draw) -> list[float]:
    v = np.array([draw(st.floats(-1, 1)), draw(st.floats(-1, 1)), draw(st.floats(-1, 1))])
    if np.linalg.norm(v) < 0.1:
        v = np.array([0.0, 0.0, 1.0])
    return (v / np.linalg.norm(v)).tolist()


@st.composite
def models(draw) -> RobotModel:
    convention = draw(st.sampled_from(["mdh", "sdh", "poe"]))
    n = draw(st.integers(1, 9))
    joints = []
    for _ in range(n):
        prismatic = draw(st.booleans()) and draw(st.booleans())  # about one in four
        joint = {"type": "prismatic" if prismatic else "revolute",
                 "offset": draw(lengths) if prismatic else draw(angles)}
        if prismatic:
            lo = draw(st.floats(-300.0, 200.0))
            joint.update(lower=lo, upper=lo + draw(st.floats(10.0, 500.0)))
        else:
            lo = draw(st.floats(-6.0, 2.0))
            joint.update(lower=lo, upper=lo + draw(st.floats(0.2, 6.0)))
        if convention == "poe":
            joint["axis"] = draw(unit_vectors())
            if not prismatic:
                joint["point"] = [draw(lengths), draw(lengths), draw(lengths)]
        else:
            joint.update(a=draw(lengths), alpha=draw(angles), d=draw(lengths),
                         theta=draw(angles))
        joints.append(joint)
    data = {"id": "random_arm", "convention": convention, "joints": joints,
            "base": draw(poses()), "tool": draw(poses())}
    if convention == "poe":
        data["home"] = draw(poses())
    return RobotModel.from_dict(data)


def configurations(model: RobotModel, n: int, seed: int) -> np.ndarray:
    """Configurations within and a little beyond the limits."""
    span = model.upper - model.lower
    rng = np.random.default_rng(seed)
    return rng.uniform(model.lower - 0.2 * span, model.upper + 0.2 * span, (n, model.dof))


def _pose(rpy, xyz) -> list[list[float]]:
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(rpy)
    T[:3, 3] = xyz
    return T.tolist()


BASE, TOOL = _pose([0.3, -0.2, 1.1], [120.0, -40.0, 300.0]), _pose([3.0, 0.1, -0.5], [5, 0, 90])
#: Named cases: every convention with a prismatic joint, offsets, a base and a tool.
EDGE_MODELS = {
    "mdh_prismatic": {"convention": "mdh", "joints": [
        {"a": 0, "alpha": 0, "d": 400, "offset": 0.3, "lower": -3, "upper": 3},
        {"type": "prismatic", "a": 150, "alpha": -math.pi / 2, "theta": 0.4, "offset": 20,
         "lower": 0, "upper": 600},
        {"a": 300, "alpha": math.pi / 2, "d": -30, "lower": -2, "upper": 2},
        {"a": 0, "alpha": math.pi, "d": 80, "offset": math.pi, "lower": -5, "upper": 5}]},
    "sdh_prismatic": {"convention": "sdh", "joints": [
        {"type": "prismatic", "a": 50, "alpha": math.pi / 2, "theta": -0.7, "lower": -100,
         "upper": 400},
        {"a": 250, "alpha": 0.0, "d": 10, "offset": -0.2, "lower": -3, "upper": 3},
        {"a": 0, "alpha": -math.pi / 2, "d": 0, "lower": -3, "upper": 3}]},
    "poe_prismatic": {"convention": "poe", "home": _pose([0, 0.5, 0], [500, 20, 700]),
                      "joints": [
        {"axis": [0, 0, 1], "point": [0, 0, 0], "offset": 0.1, "lower": -3, "upper": 3},
        {"type": "prismatic", "axis": [0.6, 0, 0.8], "offset": 5, "lower": 0, "upper": 400},
        {"axis": [0, 1, 0], "point": [300, 0, 500], "lower": -2, "upper": 2},
        {"axis": [-1, 0, 0], "point": [500, 20, 700], "lower": -3, "upper": 3}]},
}


def fast_equals_batched(model: RobotModel, seed: int) -> None:
    Q = configurations(model, fast.SMALL_BATCH + 7, seed)
    for q in (Q[0], Q[:1], Q[:3], Q[: fast.SMALL_BATCH], Q):  # one, rows and one block
        T_fast, T_numpy = both_paths(lambda q=q: fk(model, q))
        assert T_fast.shape == T_numpy.shape
        np.testing.assert_allclose(T_fast, T_numpy, rtol=0, atol=1e-9)
        (J_fast, P_fast), (J_numpy, P_numpy) = both_paths(
            lambda q=q: jacobian_and_pose(model, q))
        assert J_fast.shape == J_numpy.shape
        np.testing.assert_allclose(J_fast, J_numpy, rtol=0, atol=1e-9)
        np.testing.assert_allclose(P_fast, P_numpy, rtol=0, atol=1e-9)


@needs_kernels
@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(model=models(), seed=st.integers(0, 2**16))
def test_fk_and_jacobian_fast_path_equal_batched_path(model, seed):
    fast_equals_batched(model, seed)


@needs_kernels
@pytest.mark.parametrize("name", sorted(EDGE_MODELS))
def test_fk_and_jacobian_fast_path_equal_batched_path_named_cases(name):
    data = {"id": name, "base": BASE, "tool": TOOL, **EDGE_MODELS[name]}
    fast_equals_batched(RobotModel.from_dict(data), seed=1)


@needs_kernels
@pytest.mark.parametrize("robot_id", ["glt_palletizer", "hyper_redundant_9dof",
                                      "tunnel_drill_arm"])
def test_fk_blocks_equal_batched_path_past_one_block(robot_id):
    """Several blocks and a short last one; both paths against the unchunked numpy FK."""
    model = builtin_model(robot_id)
    Q = configurations(model, 2 * fast.FK_BLOCK + 37, seed=5)
    reference = _fk_numpy(model, Q)
    T_fast, T_numpy = both_paths(lambda: fk(model, Q))
    np.testing.assert_allclose(T_fast, reference, rtol=0, atol=1e-9)
    np.testing.assert_allclose(T_numpy, reference, rtol=0, atol=1e-9)
    # Any leading shape, and inputs the kernels must copy (read-only, strided, integer).
    Q3 = Q[:24].reshape(2, 3, 4, model.dof)
    np.testing.assert_allclose(fk(model, Q3), reference[:24].reshape(2, 3, 4, 4, 4),
                               atol=1e-9)
    ro = Q[:5].copy()
    ro.setflags(write=False)
    np.testing.assert_allclose(fk(model, ro), reference[:5], atol=1e-9)
    np.testing.assert_allclose(fk(model, Q[:10:2]), reference[:10:2], atol=1e-9)
    np.testing.assert_array_equal(fk(model, np.zeros(model.dof, dtype=int)),
                                  fk(model, np.zeros(model.dof)))


# ---- closed forms ---------------------------------------------------------------------
def same_result(a, b) -> None:
    assert (a.status, a.message, a.singular, a.within_limits, a.method) == \
        (b.status, b.message, b.singular, b.within_limits, b.method)
    assert a.solutions.shape == b.solutions.shape
    np.testing.assert_allclose(a.solutions, b.solutions, rtol=0, atol=1e-9)
    np.testing.assert_allclose([a.position_error, a.rotation_error],
                               [b.position_error, b.rotation_error], rtol=0, atol=1e-9)
    if a.q is None:
        assert b.q is None
    else:
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-9)


def closed_form_targets(model: RobotModel) -> np.ndarray:
    """Reachable, reachable only beyond the limits, singular wrist, out of reach, and on the
    axis of joint 1."""
    rng = np.random.default_rng(77)
    inside = rng.uniform(model.lower, model.upper, (40, 6))
    wide = rng.uniform(model.lower - 1.0, model.upper + 1.0, (40, 6))
    singular = inside[:10].copy()
    singular[:, 4] = 0.0  # theta5 = 0 or pi: the wrist axes line up
    T = fk(model, np.concatenate([inside, wide, singular]))
    far = T[:5].copy()
    far[:, :3, 3] *= 10.0
    on_axis = T[5:10].copy()
    on_axis[:, :2, 3] = model.base[:2, 3]
    return np.concatenate([T, far, on_axis])


@needs_kernels
@pytest.mark.parametrize("robot_id", ["glt_palletizer", "pile_driver"])
def test_closed_form_fast_path_equals_batched_path(robot_id):
    model = builtin_model(robot_id)
    T = closed_form_targets(model)
    q0 = model.mid_configuration() + 0.1
    for kwargs in ({}, {"q0": q0}):
        fast_all, numpy_all = both_paths(
            lambda kwargs=kwargs: solve_ik(model, T, method="analytic", all_solutions=True,
                                           **kwargs))
        statuses = {str(r.status) for r in fast_all}
        assert {"ok", "out_of_limits", "unreachable"} <= statuses, statuses
        assert any(r.singular for r in fast_all)
        for a, b in zip(fast_all, numpy_all):
            same_result(a, b)
        # One pose per call (the fast path's own input check) gives the same answers.
        for k in range(0, len(T), 7):
            (one,) = solve_ik(model, T[k], method="analytic", all_solutions=True, **kwargs)
            same_result(one, fast_all[k])


def test_best_solution_only_keeps_every_other_field():
    model = builtin_model("glt_palletizer")
    (full,) = solve_ik(model, fk(model, model.mid_configuration() + 0.2), all_solutions=True)
    (best,) = solve_ik(model, fk(model, model.mid_configuration() + 0.2))
    assert len(full.solutions) > 1 and best.solutions.shape == (1, model.dof)
    for f in dataclasses.fields(IKResult):
        if f.name != "solutions":
            a, b = getattr(full, f.name), getattr(best, f.name)
            assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, f.name


@needs_kernels
@pytest.mark.parametrize("robot_id", ["glt_palletizer", "hyper_redundant_9dof"])
def test_one_pose_target_checks_equal_batched_checks(robot_id):
    model = builtin_model(robot_id)
    T = fk(model, model.mid_configuration())
    nan, far, skew = T.copy(), T.copy(), T.copy()
    nan[1, 2] = np.nan
    far[0, 3] = 2e9
    skew[:3, :3] *= 1.01
    for bad, match in ((nan, "NaN"), (far, "beyond"), (skew, "rigid")):
        messages = []
        for enabled in (True, False):
            with kernels_enabled(enabled), pytest.raises(ValueError, match=match) as info:
                solve_ik(model, bad)
            messages.append(str(info.value))
        assert messages[0] == messages[1]
    # Targets printed to four decimals are projected onto the same rigid poses.
    rounded = np.round(T, 4)
    np.testing.assert_allclose(_prepare_one(fast.kernels(), rounded),
                               prepare_targets(rounded[None]), rtol=0, atol=1e-12)


# ---- numeric IK -----------------------------------------------------------------------
#: Target poses of the numeric tests: FK of configurations from this seed, which is neither
#: the seed table's nor the random restarts'.
TARGET_SEED = 31_337


def unseen_targets(model: RobotModel, n: int) -> tuple[np.ndarray, np.ndarray]:
    assert TARGET_SEED not in (TABLE_SEED, NumericOptions().seed)
    q = np.random.default_rng(TARGET_SEED).uniform(model.lower, model.upper, (n, model.dof))
    return q, fk(model, q)


def check_contract(model: RobotModel, T: np.ndarray, results, opts: NumericOptions) -> None:
    assert all(r.success for r in results), [r.message for r in results if not r.success]
    Q = np.array([r.q for r in results])
    assert model.within_limits(Q, tol=0.0).all()
    dp, dr = pose_errors(fk(model, Q), T)
    assert dp.max() < opts.tol_position and dr.max() < opts.tol_rotation
    reported = np.array([[r.position_error, r.rotation_error] for r in results])
    np.testing.assert_allclose(reported, np.c_[dp, dr], rtol=0, atol=1e-9)
    for r in results:
        assert r.within_limits and r.method == "numeric" and r.status == "ok"
        np.testing.assert_array_equal(r.solutions, r.q[None])


@pytest.mark.parametrize("robot_id", ["glt_palletizer", "hyper_redundant_9dof",
                                      "tunnel_drill_arm"])
def test_numeric_fast_path_solves_unseen_poses_within_limits(robot_id):
    model = builtin_model(robot_id)
    _, T = unseen_targets(model, 150)
    opts = NumericOptions()
    results = [solve_ik(model, Tk, method="numeric")[0] for Tk in T]
    check_contract(model, T, results, opts)
    # A batch goes the same way, pose by pose (its targets are checked by the batched code,
    # whose projection onto rigid poses can differ in the last digit: a redundant arm may then
    # end on another solution).
    check_contract(model, T[:20], solve_ik(model, T[:20], method="numeric"), opts)


def test_numeric_batched_path_keeps_its_contract(kernels_off):
    model = builtin_model("glt_palletizer")
    _, T = unseen_targets(model, 40)
    assert fast.kernels() is None
    check_contract(model, T, solve_ik(model, T, method="numeric"), NumericOptions())


def test_numeric_fast_path_near_limits_and_with_q0():
    """Targets whose configurations sit on a joint limit still solve inside the limits; a
    start ``q0`` next to a solution leads to it."""
    model = builtin_model("hyper_redundant_9dof")
    q_free, T_free = unseen_targets(model, 30)
    q = q_free.copy()
    q[:, ::2] = np.where(q[:, ::2] > 0, model.upper[::2], model.lower[::2])
    T = fk(model, q)
    results = [solve_ik(model, Tk, method="numeric")[0] for Tk in T]
    check_contract(model, T, results, NumericOptions())
    (near,) = solve_ik(model, T_free[0], method="numeric", q0=q_free[0] + 0.01)
    assert near.success and np.abs(near.q - q_free[0]).max() < 0.05


def test_numeric_fast_path_reports_an_unreachable_target():
    model = builtin_model("glt_palletizer")
    T = fk(model, model.mid_configuration())
    T[:3, 3] = [5000.0, 0.0, 0.0]
    opts = NumericOptions(restarts=4)
    (on,), (off,) = both_paths(lambda: solve_ik(model, T, method="numeric", options=opts))
    for r in (on, off):
        assert r.status == "not_converged" and r.q is None and len(r.solutions) == 0
        assert "out of reach" in r.message and "from 5 starts" in r.message
        assert r.position_error > 1000 and r.within_limits
        assert model.within_limits(r.extra["best_q"])
    assert on.position_error == pytest.approx(off.position_error, rel=1e-6)


def test_numeric_fast_path_is_reproducible():
    model = builtin_model("pile_driver")
    _, T = unseen_targets(model, 10)
    a = solve_ik(model, T, method="numeric")
    b = solve_ik(model, T, method="numeric")
    for ra, rb in zip(a, b):
        np.testing.assert_array_equal(ra.q, rb.q)


# ---- seeds ----------------------------------------------------------------------------
def test_seed_table_has_its_own_documented_seed():
    opts = NumericOptions()
    assert opts.table_seed == TABLE_SEED != opts.seed
    model = builtin_model("glt_palletizer")
    table_q, _ = _seed_table(model, opts.seed_table, opts.table_seed)
    restarts = np.random.default_rng(opts.seed).uniform(model.lower, model.upper,
                                                        (opts.seed_table, model.dof))
    assert not np.isin(table_q, restarts).any()


def _assigned_constants(path: Path) -> dict[str, object]:
    out = {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
    return out


@pytest.mark.parametrize("script", ["bench_single_pose.py", "bench_glt_kinematics.py",
                                    "bench_speed_goals.py"])
def test_benchmarks_draw_targets_from_seeds_the_solver_never_saw(script):
    consts = _assigned_constants(ROOT / "benchmarks" / script)
    seeds = [v for k, v in consts.items() if k.endswith("SEED") or k.endswith("SEEDS")]
    seeds = [s for v in seeds for s in (v if isinstance(v, tuple | list) else [v])]
    assert seeds, f"{script} names its seeds in *_SEED / *_SEEDS constants"
    assert not {TABLE_SEED, NumericOptions().seed} & set(seeds)


# ---- start-up and the switch ----------------------------------------------------------
@needs_kernels
def test_warm_up_compiles_every_variant_the_library_uses():
    report = fast.warm_up()
    assert report.enabled
    K = fast.kernels()
    dispatchers = {name: getattr(K, name) for name in dir(K)
                   if isinstance(getattr(K, name), numba.core.registry.CPUDispatcher)
                   and not name.startswith("_")}
    before = {name: len(d.signatures) for name, d in dispatchers.items()}
    assert all(before.values()), before
    glt, arm9, pile = (builtin_model(r) for r in
                       ("glt_palletizer", "hyper_redundant_9dof", "pile_driver"))
    for model in (glt, arm9, pile):
        q = model.mid_configuration()
        for Q in (q, q[None], np.tile(q, (5, 1)), np.tile(q, (3000, 1)), q.astype(np.float32)):
            fk(model, Q)
            jacobian_and_pose(model, Q[:30])
        T = fk(model, q + 0.05)
        solve_ik(model, T, method="numeric", q0=q)
        solve_ik(model, T[None].repeat(2, axis=0), method="numeric")
        solve_ik(model, T, method="auto", all_solutions=True)
    after = {name: len(d.signatures) for name, d in dispatchers.items()}
    assert after == before


@pytest.mark.slow
@needs_kernels
def test_background_warm_up_serves_from_numpy_until_ready():
    code = ("import numpy as np\n"
            "from kinematics import fast, fk, builtin_model\n"
            "m = builtin_model('hyper_redundant_9dof')\n"
            "q = np.linspace(-1, 1, 9)\n"
            "thread = fast.start_warm_up()\n"
            "during = fk(m, q)\n"
            "thread.join()\n"
            "print(fast.kernels() is not None, fast.start_warm_up() is None,"
            " float(np.abs(fk(m, q) - during).max()))\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=600, check=True)
    ready, again, diff = done.stdout.split()
    assert ready == "True" and again == "True" and float(diff) < 1e-9


def test_switched_off_by_environment_loads_no_numba():
    code = ("import sys, numpy as np\n"
            "from kinematics import fast, fk, jacobian, solve_ik, builtin_model\n"
            "m = builtin_model('glt_palletizer')\n"
            "q = m.mid_configuration()\n"
            "T = fk(m, q)\n"
            "J = jacobian(m, q)\n"
            "r = solve_ik(m, T)[0]\n"
            "print(fast.kernels() is None, fast.warm_up().enabled, 'numba' in sys.modules,"
            " r.success, J.shape)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, check=True,
                          env={**os.environ, "KINOPLAN_JIT": "0"})
    assert done.stdout.split() == ["True", "False", "False", "True", "(6,", "6)"]


def test_without_q0_the_branch_nearest_mid_range_comes_first():
    """One answer for one pose without q0: every branch is on the pose (FK), and the one
    answered is the in-limit branch nearest the middle of the joint ranges."""
    model = builtin_model("glt_palletizer")
    q_given = np.array([0.2618, 0.5236, 0.7854, 1.0472, 1.5708, 2.7925])
    T = fk(model, q_given)
    (full,) = solve_ik(model, T, all_solutions=True)
    assert len(full.solutions) > 2
    for q in full.solutions:
        np.testing.assert_allclose(fk(model, q), T, atol=1e-6)
    mid = (np.asarray(model.lower) + np.asarray(model.upper)) / 2
    gaps = np.linalg.norm(full.solutions - mid, axis=1)
    assert np.linalg.norm(full.q - mid) <= gaps.min() + 1e-9
    (best,) = solve_ik(model, T)
    np.testing.assert_allclose(best.q, full.q, atol=1e-12)
    batch = solve_ik(model, np.stack([T, T]))
    np.testing.assert_allclose(batch[1].q, full.q, atol=1e-12)
