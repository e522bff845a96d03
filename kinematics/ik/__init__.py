"""Inverse kinematics: closed forms where a model has one, numeric for every model, and
position-only IK (``position``) for the tool point alone.

``solve_ik`` is the entry point; it validates the target poses once and dispatches. With the
compiled kernels (``kinematics.fast``) a single pose is checked, and every pose solved, one at
a time without numpy's per-call overhead; the results are the same (tests/kinematics/
test_fast_path.py).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from typing import Literal

import numpy as np

from ..errors import MethodUnavailableError
from ..fast import c_array, kernels
from ..model import RobotModel
from ..transforms import project_to_rigid, rigidity_error
from . import pile_driver, spherical_wrist
from .numeric import NumericOptions, solve_batch
from .position import position_ik, reach
from .result import IKResult, IKStatus

__all__ = [
    "IKResult",
    "IKStatus",
    "NumericOptions",
    "IKMethod",
    "RIGIDITY_TOL",
    "analytic_solver",
    "available_methods",
    "position_ik",
    "reach",
    "solve_ik",
]

IKMethod = Literal["auto", "analytic", "numeric", "learned"]
AnalyticSolver = Callable[[RobotModel, np.ndarray, "np.ndarray | None"], list[IKResult]]

#: Largest departure from a rigid transform accepted in a target pose. Generous enough for
#: matrices printed to four decimals (as in the papers); the target is then projected onto
#: the nearest rigid pose.
RIGIDITY_TOL = 2e-3

#: Largest |coordinate| (mm) of a target position; beyond it the numbers stop being useful.
MAX_COORDINATE = 1e9

_CLOSED_FORMS = (pile_driver, spherical_wrist)


@lru_cache(maxsize=256)
def analytic_solver(model: RobotModel) -> AnalyticSolver | None:
    """The closed-form solver for ``model``'s structure, or None if it has none."""
    for module in _CLOSED_FORMS:
        if module.supports(model):
            return module.solve
    return None


def available_methods(model: RobotModel) -> list[str]:
    """IK methods that ``model`` supports now."""
    methods = ["auto"]
    if analytic_solver(model) is not None:
        methods.append("analytic")
    methods.append("numeric")
    return methods


def prepare_targets(T: np.ndarray) -> np.ndarray:
    """Check target poses ``(B, 4, 4)`` and snap them onto rigid transforms.

    Raises ``ValueError`` naming the first pose that is not finite or not rigid.
    """
    T = np.asarray(T, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"pose must be 4x4 or a list of 4x4 matrices, got shape {list(T.shape)}")
    bad = ~np.all(np.isfinite(T), axis=(1, 2))
    if bad.any():
        raise ValueError(f"pose[{int(np.argmax(bad))}] has a NaN or infinite entry")
    far = np.abs(T[:, :3, 3]).max(axis=1) > MAX_COORDINATE
    if far.any():
        k = int(np.argmax(far))
        raise ValueError(
            f"pose[{k}] has a position coordinate beyond {MAX_COORDINATE:.0e} mm: no arm "
            "reaches there"
        )
    err = rigidity_error(T)
    if np.any(err > RIGIDITY_TOL):
        k = int(np.argmax(err > RIGIDITY_TOL))
        raise ValueError(
            f"pose[{k}] is not a rigid transform: its rotation part is not orthonormal with "
            f"determinant 1 or its last row is not [0, 0, 0, 1] (error {err[k]:.3g})"
        )
    return project_to_rigid(T)


def _prepare_one(K, T: np.ndarray) -> np.ndarray:
    """``prepare_targets`` of one pose ``(4, 4)`` on the compiled kernels -> ``(1, 4, 4)``;
    a pose it would reject goes to ``prepare_targets`` itself, for the same error."""
    out = np.empty((1, 4, 4))
    code = K.prepare_pose(c_array(T), MAX_COORDINATE, out[0])
    if code < 0.0 or code > RIGIDITY_TOL:
        return prepare_targets(T[None])
    return out


def solve_ik(
    model: RobotModel,
    T_target: np.ndarray,
    *,
    method: IKMethod = "auto",
    q0: np.ndarray | None = None,
    all_solutions: bool = False,
    options: NumericOptions | None = None,
) -> list[IKResult]:
    """Solve IK for target tool poses ``T_world_tool (B, 4, 4)`` or ``(4, 4)`` (world frame,
    as ``fk`` returns them; docs/conventions.md); one result per pose.

    ``method="auto"`` uses the closed form when the model has one, else numeric. Unreachable
    targets give results with ``success == False`` and a message, never an exception;
    invalid input raises ``ValueError`` and an unavailable method ``MethodUnavailableError``.
    """
    T = np.asarray(T_target, dtype=float)
    K = kernels()
    if K is not None and T.shape[-2:] == (4, 4) and T.ndim == 2:
        T = _prepare_one(K, T)
    else:
        T = prepare_targets(T[None] if T.ndim == 2 else T)
    if q0 is not None:
        q0 = np.asarray(q0, dtype=float)
        if q0.shape != (model.dof,):
            raise ValueError(f"q0 must have {model.dof} values, got shape {list(q0.shape)}")
        if not np.all(np.isfinite(q0)):
            raise ValueError("q0 has a NaN or infinite entry")
    if method == "learned":
        raise MethodUnavailableError(
            "learned", f"no learned IK model is trained for robot '{model.id}'"
        )
    closed = analytic_solver(model)
    if method == "analytic" and closed is None:
        raise MethodUnavailableError(
            "analytic",
            f"robot '{model.id}' has no closed-form IK; use method 'numeric' or 'auto'",
        )
    if method not in ("auto", "analytic", "numeric"):
        raise ValueError(f"unknown IK method {method!r}")
    if closed is not None and method in ("auto", "analytic"):
        results = closed(model, T, q0)
    else:
        results = solve_batch(model, T, q0, all_solutions=all_solutions, options=options)
    if not all_solutions:
        results = [_only_best(r) for r in results]
    return results


def _only_best(r: IKResult) -> IKResult:
    if r.q is None or len(r.solutions) <= 1:
        return r
    # The constructor rather than dataclasses.replace, which costs microseconds per call.
    return IKResult(r.status, r.q, r.q[None, :], r.position_error, r.rotation_error,
                    r.within_limits, r.method, r.message, r.singular, r.extra)
