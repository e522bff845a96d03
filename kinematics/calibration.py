"""Kinematic calibration: identify a model's geometric constants from measured poses.

Given joint values and the tool pose (or only the tool position) that a tracker measured for
each of them, ``calibrate`` finds the constants named in ``parameters`` (link lengths, twists,
joint offsets, base and tool translations) by nonlinear least squares
(``scipy.optimize.least_squares``) and says what the data do *not* determine.

Parameter names (lengths in mm, angles in rad):

* ``"joints[i].a"``, ``"joints[i].alpha"`` (D-H models), ``"joints[i].d"`` (revolute D-H
  joints: for a prismatic joint d is the joint variable), ``"joints[i].theta"`` (prismatic
  D-H joints: for a revolute joint theta is the joint variable, use ``offset``),
  ``"joints[i].offset"`` (every joint, every convention);
* ``"base.x"``, ``"base.y"``, ``"base.z"``: the base translation, in the world frame;
* ``"tool.x"``, ``"tool.y"``, ``"tool.z"``: the tool translation, in the flange frame.

Residuals, per measurement, measured minus model: the position (mm, world frame) and, for a
pose, the rotation vector ``log(R_measured R_model^T)`` (rad, world frame) multiplied by
``rotation_weight`` (mm per rad) so both weigh in mm.

Identifiability: at the solution the residual Jacobian (columns scaled to unit norm, so units
do not matter) is decomposed by SVD. A singular value below ``rank_tol`` times the largest
spans a direction of parameter space the measurements cannot see; every parameter with a
component along such a direction is reported in ``CalibrationResult.unidentified`` and in a
warning that names the group and the invisible combination, and gets a NaN standard error.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from .fk import fk
from .model import RobotModel
from .transforms import rigidity_error, rotation_log

__all__ = [
    "CalibrationResult",
    "calibrate",
    "get_parameters",
    "set_parameters",
]

#: Spread of the random extra starts around the nominal value when a parameter has no finite
#: bounds: this fraction of the model's ``length_scale`` for lengths ...
START_SPREAD_LENGTH = 0.01
#: ... and this many rad for angles.
START_SPREAD_ANGLE = 0.05
#: Relative central-difference step for the Jacobian used in the identifiability analysis.
FD_STEP = 1e-5
#: A parameter whose squared projection onto the null space exceeds this is unidentified.
NULL_PARTICIPATION_TOL = 1e-6
#: Rigidity tolerance for measured poses (they are often printed to a few decimals).
POSE_RIGIDITY_TOL = 2e-3

_NAME_RE = re.compile(r"^(?:joints\[(\d+)\]\.(a|alpha|d|theta|offset)|(base|tool)\.(x|y|z))$")
_ANGULAR = {"alpha", "theta"}
_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


@dataclass(frozen=True)
class _Param:
    """One parsed parameter name."""

    name: str
    target: str  # "joint", "base" or "tool"
    index: int  # joint index, or the translation row 0..2 for base/tool
    attr: str  # joint field name ("a", "alpha", ...) or "" for base/tool
    angular: bool


@dataclass(frozen=True)
class CalibrationResult:
    """What ``calibrate`` found.

    ``values``/``initial``/``std_errors`` map each parameter name to its fitted value, its
    value in the input model and its standard error (mm or rad; NaN if the data do not
    determine it or leave no redundancy). ``model`` is the fitted, validated model.

    Per measurement (in input order): ``position_residuals (M, 3)`` measured minus fitted
    position in mm (world frame); ``rotation_residuals (M, 3)`` the rotation vector
    ``log(R_measured R_fitted^T)`` in rad (world frame), NaN rows for position-only
    measurements. ``rms_position`` (mm) and ``rms_rotation`` (rad, NaN without poses) are root
    mean squares of the residual norms. ``sigma`` is the a-posteriori residual scale
    ``sqrt(SSR / (n_residuals - rank))`` in mm (rotations weighted by ``rotation_weight``).

    ``covariance (P, P)`` is ``sigma^2 (J^T J)^+`` of the measurement rows only (a prior is not
    counted), in the order of ``parameters``; NaN rows and columns for ``unidentified``
    parameters. ``singular_values (P,)`` of the column-scaled Jacobian, largest first, and
    ``rank`` document the identifiability analysis. ``warnings`` lists, in words, parameters
    the data do not determine, parameters stopped at a bound, and convergence trouble.
    """

    parameters: tuple[str, ...]
    values: dict[str, float]
    initial: dict[str, float]
    model: RobotModel
    position_residuals: np.ndarray
    rotation_residuals: np.ndarray
    rms_position: float
    rms_rotation: float
    sigma: float
    covariance: np.ndarray
    std_errors: dict[str, float]
    singular_values: np.ndarray
    rank: int
    unidentified: tuple[str, ...]
    warnings: tuple[str, ...]
    success: bool
    message: str
    cost: float
    nfev: int
    starts: int

    @property
    def position_errors(self) -> np.ndarray:
        """Norm of the position residual per measurement ``(M,)``, mm."""
        return np.linalg.norm(self.position_residuals, axis=1)

    @property
    def rotation_errors(self) -> np.ndarray:
        """Rotation residual angle per measurement ``(M,)``, rad (NaN for positions only)."""
        return np.linalg.norm(self.rotation_residuals, axis=1)


# ---- parameters ---------------------------------------------------------------------------
def _parse(model: RobotModel, names: Sequence[str], field: str = "parameters") -> list[_Param]:
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise ValueError(f"{field}: must be a list of parameter names")
    out: list[_Param] = []
    seen: set[str] = set()
    for k, name in enumerate(names):
        path = f"{field}[{k}]"
        if not isinstance(name, str):
            raise ValueError(f"{path}: must be a string, got {name!r}")
        m = _NAME_RE.match(name)
        if m is None:
            raise ValueError(
                f"{path}: unknown parameter {name!r}; use 'joints[i].a|alpha|d|theta|offset', "
                "'base.x|y|z' or 'tool.x|y|z'"
            )
        if name in seen:
            raise ValueError(f"{path}: parameter {name!r} is listed twice")
        seen.add(name)
        if m.group(1) is None:
            out.append(_Param(name, m.group(3), "xyz".index(m.group(4)), "", False))
            continue
        i, attr = int(m.group(1)), m.group(2)
        if i >= model.dof:
            raise ValueError(
                f"{path}: {name!r}: robot '{model.id}' has joints[0]..joints[{model.dof - 1}]"
            )
        joint = model.joints[i]
        if attr != "offset":
            if model.convention == "poe":
                raise ValueError(
                    f"{path}: {name!r}: product-of-exponentials models have no D-H constants; "
                    "only 'offset' applies to their joints"
                )
            if attr == "d" and not joint.revolute:
                raise ValueError(
                    f"{path}: {name!r}: d is the joint variable of prismatic joint "
                    f"'{joint.name}'; use 'joints[{i}].offset'"
                )
            if attr == "theta" and joint.revolute:
                raise ValueError(
                    f"{path}: {name!r}: theta is the joint variable of revolute joint "
                    f"'{joint.name}'; use 'joints[{i}].offset'"
                )
        angular = attr in _ANGULAR or (attr == "offset" and joint.revolute)
        out.append(_Param(name, "joint", i, attr, angular))
    if not out:
        raise ValueError(f"{field}: name at least one parameter")
    return out


def _values(model: RobotModel, params: Sequence[_Param]) -> np.ndarray:
    out = np.empty(len(params))
    for k, p in enumerate(params):
        if p.target == "joint":
            out[k] = getattr(model.joints[p.index], p.attr)
        else:
            out[k] = getattr(model, p.target)[p.index, 3]
    return out


def _apply(model: RobotModel, params: Sequence[_Param], x: np.ndarray) -> RobotModel:
    """A copy of ``model`` with the parameters set to ``x`` (no validation: the hot path)."""
    joints = list(model.joints)
    base, tool = model.base.copy(), model.tool.copy()
    for p, v in zip(params, x):
        if p.target == "joint":
            joints[p.index] = replace(joints[p.index], **{p.attr: float(v)})
        elif p.target == "base":
            base[p.index, 3] = v
        else:
            tool[p.index, 3] = v
    return replace(model, joints=tuple(joints), base=base, tool=tool)


def get_parameters(model: RobotModel, names: Sequence[str]) -> dict[str, float]:
    """The current values of the named constants of ``model`` (mm, rad)."""
    params = _parse(model, names)
    return {p.name: float(v) for p, v in zip(params, _values(model, params))}


def set_parameters(model: RobotModel, values: Mapping[str, float]) -> RobotModel:
    """A new, validated model with the named constants set (mm, rad).

    Raises ``ValueError`` naming an unknown parameter or a non-finite value.
    """
    params = _parse(model, list(values), field="values")
    x = np.array([_finite(values[p.name], f"values[{p.name!r}]") for p in params])
    return RobotModel.from_dict(_apply(model, params, x).to_dict())


def _finite(value: Any, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{path}: must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{path}: must be finite, got {value!r}")
    return float(value)


def _named(values: Mapping[str, float], names: tuple[str, ...], field: str) -> dict[str, float]:
    if not isinstance(values, Mapping):
        raise ValueError(f"{field}: must map parameter names to numbers")
    out = {}
    for name, v in values.items():
        if name not in names:
            raise ValueError(f"{field}[{name!r}]: not one of the parameters being fitted")
        out[name] = _finite(v, f"{field}[{name!r}]")
    return out


# ---- measurements -------------------------------------------------------------------------
@dataclass(frozen=True)
class _Data:
    q: np.ndarray  # (M, dof)
    position: np.ndarray  # (M, 3) mm
    rotation: np.ndarray  # (M, 3, 3); identity where there is no pose
    has_pose: np.ndarray  # (M,) bool


def _measurements(model: RobotModel, measurements: Sequence[Mapping[str, Any]]) -> _Data:
    if isinstance(measurements, Mapping) or not isinstance(measurements, Sequence):
        raise ValueError("measurements: must be a list of {'q': ..., 'pose'|'position': ...}")
    if not measurements:
        raise ValueError("measurements: the list is empty")
    M = len(measurements)
    Q = np.empty((M, model.dof))
    P = np.empty((M, 3))
    R = np.broadcast_to(np.eye(3), (M, 3, 3)).copy()
    has_pose = np.zeros(M, dtype=bool)
    for k, meas in enumerate(measurements):
        path = f"measurements[{k}]"
        if not isinstance(meas, Mapping):
            raise ValueError(f"{path}: must be a mapping with 'q' and 'pose' or 'position'")
        unknown = set(meas) - {"q", "pose", "position"}
        if unknown:
            raise ValueError(f"{path}.{sorted(unknown)[0]}: unknown field")
        Q[k] = _array(meas.get("q"), (model.dof,), f"{path}.q")
        if ("pose" in meas) == ("position" in meas):
            raise ValueError(f"{path}: give exactly one of 'pose' (4x4) or 'position' (3)")
        if "pose" in meas:
            T = _array(meas["pose"], (4, 4), f"{path}.pose")
            err = float(rigidity_error(T))
            if err > POSE_RIGIDITY_TOL:
                raise ValueError(f"{path}.pose: not a rigid transform (error {err:.3g})")
            # Snap a rounded, printed rotation onto the nearest rotation matrix.
            U, _, Vt = np.linalg.svd(T[:3, :3])
            R[k] = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
            P[k] = T[:3, 3]
            has_pose[k] = True
        else:
            P[k] = _array(meas["position"], (3,), f"{path}.position")
    return _Data(Q, P, R, has_pose)


def _array(value: Any, shape: tuple[int, ...], path: str) -> np.ndarray:
    if value is None:
        raise ValueError(f"{path}: is required")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: must be numbers of shape {list(shape)}") from exc
    if arr.shape != shape:
        raise ValueError(f"{path}: must have shape {list(shape)}, got {list(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{path}: has a NaN or infinite entry")
    return arr


def _bounds(
    params: Sequence[_Param], bounds: Mapping[str, tuple[float, float]] | None
) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(len(params), -np.inf)
    hi = np.full(len(params), np.inf)
    if bounds is None:
        return lo, hi
    if not isinstance(bounds, Mapping):
        raise ValueError("bounds: must map parameter names to (lower, upper)")
    index = {p.name: k for k, p in enumerate(params)}
    for name, pair in bounds.items():
        if name not in index:
            raise ValueError(f"bounds[{name!r}]: not one of the parameters being fitted")
        try:
            a, b = (float(v) for v in pair)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"bounds[{name!r}]: must be a pair (lower, upper)") from exc
        if math.isnan(a) or math.isnan(b) or not a < b:
            raise ValueError(f"bounds[{name!r}]: lower must be below upper, got ({a}, {b})")
        lo[index[name]], hi[index[name]] = a, b
    return lo, hi


# ---- the fit ------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Fit:
    """What is fitted: the parameters, their values in the input model ``x_model (P,)``,
    bounds ``lo``, ``hi (P,)``, the regulariser's prior ``x_prior (P,)`` and weight, and the
    measurements with the weight of their rotation residuals (mm per rad)."""

    model: RobotModel
    params: tuple[_Param, ...]
    data: _Data
    x_model: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    x_prior: np.ndarray
    rotation_weight: float
    regularization: float
    pose_rows: np.ndarray  # indices of the measurements that are poses

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def residual_parts(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured minus model at ``x (P,)``: positions ``(M, 3)`` mm and, for the poses,
        rotation vectors ``(M_pose, 3)`` rad."""
        T = fk(_apply(self.model, self.params, x), self.data.q)
        rows = self.pose_rows
        r_pos = self.data.position - T[:, :3, 3]
        r_rot = rotation_log(self.data.rotation[rows] @ np.swapaxes(T[rows, :3, :3], 1, 2))
        return r_pos, r_rot

    def data_residuals(self, x: np.ndarray) -> np.ndarray:
        """The measurement rows: positions, then weighted rotations (both mm)."""
        r_pos, r_rot = self.residual_parts(x)
        return np.concatenate([r_pos.ravel(), self.rotation_weight * r_rot.ravel()])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """What the solver minimises: the measurement rows and the Tikhonov rows."""
        r = self.data_residuals(x)
        if self.regularization > 0:
            r = np.concatenate([r, self.regularization * (x - self.x_prior)])
        return r


@dataclass(frozen=True)
class _Identifiability:
    """The SVD of the column-scaled measurement Jacobian at a solution (``_identifiability``):
    column norms ``col (P,)``, singular values ``s (P,)`` largest first, ``Vt (P, P)`` and
    the numerical ``rank``."""

    col: np.ndarray
    s: np.ndarray
    Vt: np.ndarray
    rank: int

    @property
    def V_null(self) -> np.ndarray:
        """``(P - rank, P)``: directions the data do not see (scaled coordinates)."""
        return self.Vt[self.rank :]

    @property
    def unidentified(self) -> np.ndarray:
        """``(P,)`` bool: parameters with a component along an unseen direction."""
        return np.sum(self.V_null**2, axis=0) > NULL_PARTICIPATION_TOL


def calibrate(
    model: RobotModel,
    measurements: Sequence[Mapping[str, Any]],
    parameters: Sequence[str],
    *,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    x0: Mapping[str, float] | None = None,
    rotation_weight: float | None = None,
    loss: str = "linear",
    f_scale: float = 1.0,
    regularization: float = 0.0,
    prior: Mapping[str, float] | None = None,
    starts: int = 4,
    rank_tol: float = 1e-6,
    tol: float = 1e-12,
    max_nfev: int | None = None,
    seed: int | np.random.Generator = 0,
) -> CalibrationResult:
    """Fit the named constants of ``model`` to measured tool poses or positions.

    ``measurements``: a list of ``{"q": (dof,), "pose": (4, 4)}`` or
    ``{"q": (dof,), "position": (3,)}``; q in rad / mm, poses and positions of the tool in the
    world frame in mm. ``parameters``: names as in the module docstring.

    ``bounds`` maps a name to ``(lower, upper)``; ``x0`` maps names to a start (then only that
    start is run; names not given start at the model's value). Without ``x0`` the fit runs
    from the model's values and from ``starts - 1`` seeded random starts (uniform within
    finite bounds, else within ``START_SPREAD_*`` of the model's value) and keeps the lowest
    cost. ``rotation_weight`` (mm per rad; default the model's ``length_scale``) makes
    rotation residuals comparable to positions: the ratio of position to rotation noise is
    the statistically right choice. ``loss``/``f_scale`` are passed to ``least_squares``
    (robust losses make the covariance approximate); ``tol`` is its xtol/ftol/gtol.

    ``regularization`` adds Tikhonov rows ``regularization * (x - prior)`` (prior 0 for names
    it does not list): with a small weight the data still fix every direction they can see,
    and the rest goes to the value nearest the prior (minimum norm for a zero prior); when
    the residuals stay large (misfit), raise the weight until ``regularization**2 * |x|**2``
    is not negligible against their cost, or the solver stops before it settles. Without
    it, directions the data cannot see are left at the first start's values (``x0`` or the
    model's), the smallest change that fits. The
    identifiability analysis and the covariance use the measurement rows only.

    Raises ``ValueError`` naming the field at fault: an unknown or inapplicable parameter, a
    q of the wrong length, a NaN, a non-rigid pose, or fewer residuals than parameters.

    The steps: the parameter vector and its residuals (``_set_up``), the starts
    (``_starts``), the solve (``_solve``), the identifiability analysis (``_identify``) and
    the report (``_report``).
    """
    fit = _set_up(model, measurements, parameters, bounds=bounds,
                  rotation_weight=rotation_weight, loss=loss, regularization=regularization,
                  prior=prior, starts=starts)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    start_list = _starts(fit, x0, starts, rng)
    best, nfev = _solve(fit, start_list, loss=loss, f_scale=f_scale, tol=tol,
                        max_nfev=max_nfev)
    x, ident = _identify(fit, best.x, start_list[0], rank_tol)
    return _report(fit, x, ident, best, nfev, len(start_list))


def _set_up(
    model: RobotModel,
    measurements: Sequence[Mapping[str, Any]],
    parameters: Sequence[str],
    *,
    bounds: Mapping[str, tuple[float, float]] | None,
    rotation_weight: float | None,
    loss: str,
    regularization: float,
    prior: Mapping[str, float] | None,
    starts: int,
) -> _Fit:
    """The parameter vector and the measurements, every input checked (``ValueError``
    naming the field at fault)."""
    params = _parse(model, parameters)
    names = tuple(p.name for p in params)
    data = _measurements(model, measurements)
    n_res = 3 * len(data.q) + 3 * int(data.has_pose.sum())
    if n_res < len(params):
        raise ValueError(
            f"measurements: {len(data.q)} measurement(s) give {n_res} residuals, fewer than "
            f"the {len(params)} parameters to fit"
        )
    if rotation_weight is None:
        rotation_weight = model.length_scale
    rotation_weight = _finite(rotation_weight, "rotation_weight")
    if rotation_weight <= 0:
        raise ValueError("rotation_weight: must be positive")
    if loss not in _LOSSES:
        raise ValueError(f"loss: must be one of {', '.join(_LOSSES)}, got {loss!r}")
    regularization = _finite(regularization, "regularization")
    if regularization < 0:
        raise ValueError("regularization: must be >= 0")
    if isinstance(starts, bool) or not isinstance(starts, int) or starts < 1:
        raise ValueError("starts: must be a positive integer")
    lo, hi = _bounds(params, bounds)
    x_prior = np.zeros(len(params))
    if prior is not None:
        for name, v in _named(prior, names, "prior").items():
            x_prior[names.index(name)] = v
    return _Fit(model, tuple(params), data, _values(model, params), lo, hi, x_prior,
                rotation_weight, regularization, np.flatnonzero(data.has_pose))


def _starts(fit: _Fit, x0: Mapping[str, float] | None, starts: int,
            rng: np.random.Generator) -> list[np.ndarray]:
    """Where the solver starts: ``x0`` (over the model's values) alone, else the model's
    values and ``starts - 1`` seeded random starts."""
    if x0 is not None:
        first = fit.x_model.copy()
        for name, v in _named(x0, fit.names, "x0").items():
            first[fit.names.index(name)] = v
        return [first]
    spread = np.array([
        START_SPREAD_ANGLE if p.angular else START_SPREAD_LENGTH * fit.model.length_scale
        for p in fit.params
    ])
    finite = np.isfinite(fit.lo) & np.isfinite(fit.hi)
    out = [fit.x_model.copy()]
    for _ in range(starts - 1):
        x = fit.x_model + rng.normal(0.0, spread)
        x[finite] = rng.uniform(fit.lo[finite], fit.hi[finite])
        out.append(x)
    return out


def _solve(fit: _Fit, start_list: Sequence[np.ndarray], *, loss: str, f_scale: float,
           tol: float, max_nfev: int | None) -> tuple[Any, int]:
    """``least_squares`` from every start (nudged inside the bounds): the lowest-cost
    solution and the residual evaluations of all runs."""
    lo, hi = fit.lo, fit.hi
    margin = 1e-9 * np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    best = None
    nfev = 0
    for x_start in start_list:
        x_start = np.clip(x_start, lo + margin, hi - margin)
        sol = least_squares(
            fit.residuals, x_start, jac="3-point", bounds=(lo, hi), loss=loss,
            f_scale=f_scale, x_scale="jac", xtol=tol, ftol=tol, gtol=tol, max_nfev=max_nfev,
        )
        nfev += sol.nfev
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    return best, nfev


def _identify(fit: _Fit, x: np.ndarray, x_first: np.ndarray, rank_tol: float
              ) -> tuple[np.ndarray, _Identifiability]:
    """Identifiability from the measurement rows only, at the solution ``x``; without a
    regulariser, directions the data cannot see are first moved back to the first start's
    values ``x_first`` when that keeps the fit. Returns the solution and its analysis."""
    ident = _identifiability(fit.data_residuals, x, rank_tol)
    if ident.rank < len(fit.params) and fit.regularization == 0:
        # The solver may wander anywhere along directions the data cannot see (finite-
        # difference noise steers it there, and each start lands elsewhere): undo that, i.e.
        # leave those directions at the first start's values, if doing so keeps the fit (it
        # does for exact degeneracies such as two lengths that only ever appear as a sum).
        col, V_null = ident.col, ident.V_null
        P_null = V_null.T @ V_null
        x_back = np.clip(x - (P_null @ ((x - x_first) * col)) / col, fit.lo, fit.hi)
        r_now, r_back = fit.data_residuals(x), fit.data_residuals(x_back)
        if r_back @ r_back <= (r_now @ r_now) * (1 + 1e-9) + 1e-18 * len(r_now):
            x = x_back
            ident = _identifiability(fit.data_residuals, x, rank_tol)
    return x, ident


def _report(fit: _Fit, x: np.ndarray, ident: _Identifiability, best: Any, nfev: int,
            n_starts: int) -> CalibrationResult:
    """The result at the solution ``x``: residuals, covariance and standard errors from the
    measurement rows, and warnings in words."""
    names, P = fit.names, len(fit.params)
    col, rank, unidentified = ident.col, ident.rank, ident.unidentified
    r_pos, r_rot = fit.residual_parts(x)
    r_data = fit.data_residuals(x)
    dof_res = len(r_data) - rank
    sigma = math.sqrt(float(r_data @ r_data) / dof_res) if dof_res > 0 else math.nan
    cov = np.full((P, P), np.nan)
    if rank:
        V_r = ident.Vt[:rank].T
        cov = (V_r / ident.s[:rank] ** 2) @ V_r.T * sigma**2 / np.outer(col, col)
    cov[unidentified, :] = np.nan
    cov[:, unidentified] = np.nan
    std = np.sqrt(np.diag(cov))

    warnings = _null_space_warnings(names, ident.V_null, col, unidentified,
                                    fit.regularization)
    if dof_res <= 0 and rank:
        warnings.append(
            "the measurements leave no redundancy beyond the identified directions: standard "
            "errors cannot be estimated"
        )
    warnings += _bound_warnings(names, x, fit.lo, fit.hi)
    if best.status <= 0:
        warnings.append(f"least squares did not converge: {best.message}")

    pose_rows = fit.pose_rows
    rot_out = np.full((len(fit.data.q), 3), np.nan)
    rot_out[pose_rows] = r_rot
    rot_norm2 = np.sum(r_rot**2, axis=1)
    return CalibrationResult(
        parameters=names,
        values={n: float(v) for n, v in zip(names, x)},
        initial={n: float(v) for n, v in zip(names, fit.x_model)},
        model=RobotModel.from_dict(_apply(fit.model, fit.params, x).to_dict()),
        position_residuals=r_pos,
        rotation_residuals=rot_out,
        rms_position=float(math.sqrt(np.sum(r_pos**2, axis=1).mean())),
        rms_rotation=float(math.sqrt(rot_norm2.mean())) if len(pose_rows) else math.nan,
        sigma=sigma,
        covariance=cov,
        std_errors={n: float(v) for n, v in zip(names, std)},
        singular_values=ident.s,
        rank=rank,
        unidentified=tuple(n for n, u in zip(names, unidentified) if u),
        warnings=tuple(warnings),
        success=bool(best.status > 0),
        message=str(best.message),
        cost=float(best.cost),
        nfev=int(nfev),
        starts=n_starts,
    )


def _bound_warnings(names: tuple[str, ...], x: np.ndarray, lo: np.ndarray, hi: np.ndarray
                    ) -> list[str]:
    """One warning per parameter that stopped at (within 1e-9 relative of) a bound."""
    with np.errstate(invalid="ignore"):
        near = 1e-9 * np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))
        at_bound = (x <= lo + near) | (x >= hi - near)
    return [f"{names[k]} stopped at a bound ({x[k]:.6g}): the true value may lie outside it"
            for k in np.flatnonzero(at_bound)]


def _central_jacobian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian ``(R, P)`` of ``fun: (P,) -> (R,)`` at ``x``."""
    cols = []
    for k in range(len(x)):
        h = FD_STEP * max(1.0, abs(x[k]))
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        cols.append((fun(xp) - fun(xm)) / (2 * h))
    return np.stack(cols, axis=1)


def _identifiability(
    fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, rank_tol: float
) -> _Identifiability:
    """SVD of the Jacobian of ``fun`` at ``x`` with columns scaled to unit norm.

    Holds the column norms ``(P,)`` (1 for a column that is identically zero: a parameter
    the residuals ignore), the singular values ``(P,)`` largest first, ``Vt (P, P)`` whose rows
    past ``rank`` span the null space (in scaled coordinates ``x * col``), and the numerical
    rank (singular values above ``rank_tol`` times the largest).
    """
    J = _central_jacobian(fun, x)
    col = np.linalg.norm(J, axis=0)
    col[col == 0.0] = 1.0
    _, s, Vt = np.linalg.svd(J / col, full_matrices=True)
    s_full = np.zeros(len(x))
    s_full[: len(s)] = s
    s_max = s_full[0] if s_full[0] > 0 else 1.0
    rank = int(np.sum(s_full > rank_tol * s_max))
    return _Identifiability(col, s_full, Vt, rank)


def _null_space_warnings(
    names: tuple[str, ...],
    V_null: np.ndarray,
    col: np.ndarray,
    unidentified: np.ndarray,
    regularization: float,
) -> list[str]:
    """One warning per group of parameters that share directions the data cannot see."""
    if not unidentified.any():
        return []
    # Group parameters linked through the null-space projector (independent of the basis).
    linked = np.abs(V_null.T @ V_null) > NULL_PARTICIPATION_TOL
    groups: list[list[int]] = []
    todo = set(np.flatnonzero(unidentified).tolist())
    while todo:
        stack, group = [todo.pop()], []
        while stack:
            k = stack.pop()
            group.append(k)
            for m in np.flatnonzero(linked[k]).tolist():
                if m in todo:
                    todo.remove(m)
                    stack.append(m)
        groups.append(sorted(group))
    how = (
        "the regulariser set their values (nearest the prior)" if regularization > 0
        else "they were left at their starting values along those directions"
    )
    out = []
    for g in sorted(groups):
        group_names = [names[k] for k in g]
        if len(g) == 1:
            out.append(
                f"{group_names[0]} is not identifiable: the measurements do not depend on it; "
                f"{how}"
            )
            continue
        # The invisible directions within the group, in the parameters' own units.
        _, sv, W = np.linalg.svd(V_null[:, g])
        dirs = []
        for w in W[: int(np.sum(sv > 0.5))]:
            raw = w / col[g]
            raw = raw / raw[np.argmax(np.abs(raw))]
            terms = " ".join(
                f"{'+' if c >= 0 else '-'} {abs(c):.3g}*{n}"
                for c, n in zip(raw, group_names) if abs(c) > 1e-6
            )
            dirs.append(terms.removeprefix("+ "))
        out.append(
            f"{', '.join(group_names)} are not identifiable separately: changing them along "
            + "; ".join(f"({d})" for d in dirs)
            + f" leaves every measurement unchanged; {how}"
        )
    return out
