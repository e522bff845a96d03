"""Path constraints on joint-space motion: the tool's axis, orientation or position held near
a direction, a rotation, a line or a plane, or joints kept in ranges narrower than their
limits, all the way along a collision-free move.

Constraints (frozen dataclasses, bound to the robot model whose forward kinematics measures
them; ``parse_constraint`` reads the JSON form and raises ``FieldError`` naming the field):

* ``axis``: a tool-frame axis (default the tool's z axis, ``axis``) within ``tolerance``
  rad of a world ``direction``;
* ``orientation``: the tool's rotation within ``tolerance = (rx, ry, rz)`` rad of a target
  ``rotation`` (3x3), per axis: the components of the rotation vector of
  ``R_target^T R_tool`` (about the target's axes, as MoveIt's rotation-vector orientation
  constraint). Every tolerance must be > 0 (0 is refused: an exact equality cannot be
  certified at discrete states); a tolerance of pi or more declares that axis **free** (its
  component is not constrained). To keep one tool axis pointing one way whatever the turn
  about it, ``axis`` is the exact form;
* ``position_line``: the tool point within ``tolerance`` mm of the line through ``point``
  along ``direction``;
* ``position_plane``: the tool point within ``tolerance`` mm of the plane through ``point``
  with ``normal``;
* ``joint_range``: each joint within ``[lower, upper]`` (``null`` keeps the joint's own
  limit; the range is intersected with the limits, and must not be empty).

Every constraint answers ``errors(q (N, dof)) -> (N, m)`` (its measured deviations, rad or
mm, one per component), ``violation(q) -> (N,)`` (by how much the worst component exceeds
its tolerance: 0 when satisfied) and ``project(q) -> (q', ok)``: damped least squares
(Gauss-Newton) on the excess of the residual over a quarter of the tolerance, through the
tool's geometric Jacobian (``kinematics.jacobian``; central finite differences of FK when
the model has none), a few iterations, each clipped to the joint limits. A projected state
lies within ``PROJECT_ACCEPT`` of the tolerance, so straight joint-space chords between
nearby projected states have room to bulge without leaving the constraint.

``plan_constrained`` is a projection-based RRT-Connect (the projected state space of OMPL,
Kleinbort et al. 2016 / Kingston et al. 2018): each tree grows by small joint steps
(``step``, weighted rad), every new state projected onto the constraint; a state is refused
when its projection fails, jumps (farther than ``JUMP_FACTOR`` steps from the previous one),
makes no progress towards the target, or when the straight segment to it collides
(``MotionChecker``, the motion planner's checker, at ``resolution``) or leaves the constraint
at a state checked at ``resolution`` (then the step is halved, down to ``MIN_STEP_FRACTION``
of ``step``). Samples are projected before the trees grow towards them. The path found is
shortened by geodesic shortcuts (between two random waypoints, the same projected walk,
accepted only when it arrives, every state on it checked, and is shorter), then thinned
(waypoints dropped where the straight chord between their neighbours passes both checks).
Last, a dense re-check of the answer at ``resolution``: every checked state collision-free
and within every constraint's tolerance; ``worst_violation`` is the largest excess found
(0.0 on success) and ``worst_error`` each constraint's largest deviation. As for collisions
(docs/motion.md), the promise is about the states checked, no joint farther than
``resolution`` from the next: between two of them the tool can bow off the straight chord by
about ``reach x resolution^2 / 8`` (0.0125 mm for a 1 m arm at 0.01 rad), which matters only
for tolerances of that order (the finest accepted are ``MIN_LENGTH_TOLERANCE`` mm and
``MIN_ANGLE_TOLERANCE`` rad); a finer ``resolution`` shrinks it with its square.

Time: the search ends by ``time_limit`` (``timeout`` without a path); the shortcuts have half
of it within what the search left (at least ``SIMPLIFY_MIN_S``); the final re-check is not
cut short. Randomness comes from ``seed`` alone: a problem and a seed give the same path
whenever the time limit does not end a phase.

The start and the goal must satisfy every constraint (``start_violates_constraint``,
``goal_violates_constraint``, naming the constraint, its deviation and tolerance): the
planner does not move them (``project`` does it, on request).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.jacobian import jacobian_and_pose
from kinematics.status import Status
from planning.geometry.fields import vector as _vector3

from .checker import DEFAULT_RESOLUTION, MIN_RESOLUTION, MotionChecker, segment_states
from .planner import joint_vector

__all__ = ["ConstrainedStatus", "ConstrainedResult", "Constraint", "AxisConstraint",
           "OrientationConstraint", "PositionLineConstraint", "PositionPlaneConstraint",
           "JointRangeConstraint", "CONSTRAINT_TYPES", "parse_constraint", "parse_constraints",
           "plan_constrained", "DEFAULT_STEP", "MAX_TIME_LIMIT", "FREE_AXIS",
           "PROJECT_TARGET", "PROJECT_ACCEPT", "JUMP_FACTOR"]

#: Length of one step of a tree on the constraint (weighted joint rad).
DEFAULT_STEP = 0.05
#: Smallest step a walk halves down to, as a share of ``step``.
MIN_STEP_FRACTION = 1.0 / 32.0
#: Longest walk of one extension towards a sample (weighted rad) ...
EXTEND_RANGE = 1.0
#: ... and most steps of a walk that connects a tree to the other's new node.
CONNECT_STEPS = 400
#: A projected state farther than this many steps from the previous one is a jump.
JUMP_FACTOR = 2.0
#: Projection drives each residual to within this share of its tolerance ...
PROJECT_TARGET = 0.25
#: ... stops when every residual is within this share ...
PROJECT_STOP = 0.3
#: ... and succeeds when every one is within this share (the rest is room for chords).
PROJECT_ACCEPT = 0.5
#: Gauss-Newton iterations of one projection, and the largest joint motion of one (weighted
#: rad): a projection is a small correction, never a leap across the space.
PROJECT_ITERATIONS = 25
PROJECT_MAX_MOVE = 0.25
#: A tolerance of pi or more on an orientation axis declares the axis free.
FREE_AXIS = math.pi
#: Smallest tolerances accepted (rad, mm): tighter than the planner's states can certify.
MIN_ANGLE_TOLERANCE = 1e-5
MIN_LENGTH_TOLERANCE = 1e-3
#: Longest time limit (s).
MAX_TIME_LIMIT = 3600.0
#: Least time the shortcut pass gets (s).
SIMPLIFY_MIN_S = 0.2
#: Shortcut attempts, and failures in a row that end the pass.
SHORTCUT_ATTEMPTS = 60
SHORTCUT_PATIENCE = 20
#: States of the final re-check evaluated at once.
_CHUNK = 65536
#: Finite-difference step of the Jacobian's fallback (rad; mm on prismatic joints).
_FD_STEP = 1e-6

class ConstrainedStatus(Status):
    """How a constrained plan ended (a member of the status family, ``kinematics.status``)."""

    OK = "ok"
    #: The start or goal is outside the joint limits.
    OUT_OF_LIMITS = "out_of_limits"
    #: The start (goal) is outside a constraint's tolerance (the message names which).
    START_VIOLATES_CONSTRAINT = "start_violates_constraint"
    GOAL_VIOLATES_CONSTRAINT = "goal_violates_constraint"
    START_IN_COLLISION = "start_in_collision"
    GOAL_IN_COLLISION = "goal_in_collision"
    #: No path on the constraint within the time limit.
    TIMEOUT = "timeout"


# ---- rotations ----------------------------------------------------------------------------
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(N, 3)`` and ``(N, 3)`` or ``(3,)`` (np.cross costs ten
    times more on the small batches a walk measures)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v]x`` of ``v (N, 3)`` -> ``(N, 3, 3)``."""
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def _log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors of ``R (N, 3, 3)`` -> ``(N, 3)``, accurate near 0 and near pi."""
    w = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                        R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sn = np.linalg.norm(w, axis=1)
    cs = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    th = np.arctan2(sn, cs)
    scale = np.where(sn < 1e-9, 1.0 + th * th / 6.0, th / np.where(sn < 1e-9, 1.0, sn))
    out = w * scale[:, None]
    near_pi = th > math.pi - 1e-6
    for b in np.flatnonzero(near_pi):
        B = 0.5 * (R[b] + np.eye(3))
        col = int(np.argmax(np.diag(B)))
        axis = B[:, col] / np.linalg.norm(B[:, col])
        out[b] = axis * (th[b] if float(axis @ w[b]) >= 0 else -th[b])
    return out


def _left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """``J_l^-1(phi)`` of rotation vectors ``(N, 3)`` -> ``(N, 3, 3)``: the rate of the
    rotation vector per angular velocity applied on the left."""
    th = np.linalg.norm(phi, axis=1)
    K = _skew(phi)
    small = th < 1e-6
    ts = np.where(small, 1.0, th)
    s = np.sin(ts)
    s = np.where(np.abs(s) < 1e-9, 1e-9, s)
    c = np.where(small, 1.0 / 12.0, 1.0 / ts ** 2 - (1.0 + np.cos(ts)) / (2.0 * ts * s))
    return np.eye(3) - 0.5 * K + c[:, None, None] * (K @ K)


# ---- the constraint types -----------------------------------------------------------------
@dataclass(frozen=True)
class Constraint:
    """Base of the constraint types (module docstring). ``model``: the robot model whose FK
    measures the constraint (``RobotModel``)."""

    kind: ClassVar[str] = ""
    model: Any = field(kw_only=True, compare=False, repr=False)

    # -- what every type defines --------------------------------------------------------------
    def tolerances(self) -> np.ndarray:
        """``(m,)`` the tolerance of each component (rad or mm)."""
        raise NotImplementedError

    def _errors_from_poses(self, T: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``(N, m)`` deviations (>= 0) of tool poses ``T (N, 4, 4)`` at ``q (N, dof)``."""
        raise NotImplementedError

    def _residual(self, T: np.ndarray, J: np.ndarray, band: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """The excess of each component over ``band (m,)`` (0 within it) ``(N, m)`` and its
        derivative ``(N, m, dof)`` from the tool poses and geometric Jacobians."""
        raise NotImplementedError

    @property
    def uses_fk(self) -> bool:
        return True

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``parse_constraint`` reads it back)."""
        raise NotImplementedError

    # -- shared -------------------------------------------------------------------------------
    def _batch(self, q) -> np.ndarray:
        Q = np.asarray(q, dtype=float)
        Q = Q[None] if Q.ndim == 1 else Q
        if Q.ndim != 2 or Q.shape[1] != self.model.dof:
            raise FieldError(("q",), f"configurations must have {self.model.dof} joint values")
        return Q

    def errors(self, q) -> np.ndarray:
        """``(N, m)`` the deviation of each component at each configuration of ``q (N, dof)``
        (rad or mm, >= 0), measured by forward kinematics."""
        Q = self._batch(q)
        T = fk(self.model, Q) if self.uses_fk else None
        return self._errors_from_poses(T, Q)

    def violation(self, q) -> np.ndarray:
        """``(N,)`` by how much the worst component exceeds its tolerance (0: satisfied)."""
        return np.max(np.maximum(self.errors(q) - self.tolerances(), 0.0), axis=1)

    def project(self, q, lower=None, upper=None) -> tuple[np.ndarray, np.ndarray]:
        """Each configuration of ``q (N, dof)`` moved onto the constraint (module docstring),
        within ``[lower, upper]`` (default: the model's limits): ``(q' (N, dof), ok (N,))``,
        ``ok`` where the result is within ``PROJECT_ACCEPT`` of the tolerance."""
        return project_all([self], self._batch(q), lower, upper)


def _unit(v: tuple[float, float, float], loc: tuple, what: str) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(a))
    if not n > 1e-9:
        raise FieldError(loc, f"{what} must not be the zero vector")
    if abs(n - 1.0) <= 1e-12:   # already unit: kept as given, so a round trip is exact
        return tuple(float(x) for x in a)
    return tuple(float(x) for x in a / n)


@dataclass(frozen=True)
class AxisConstraint(Constraint):
    """The tool-frame ``axis`` (unit) within ``tolerance`` rad of the world ``direction``."""

    kind: ClassVar[str] = "axis"
    direction: tuple[float, float, float]
    tolerance: float
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def tolerances(self) -> np.ndarray:
        return np.array([self.tolerance])

    def _angle(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = T[:, :3, :3] @ np.asarray(self.axis)
        d = np.asarray(self.direction)
        cr = _cross(a, d)
        return np.arctan2(np.linalg.norm(cr, axis=1), a @ d), (a, cr)

    def _errors_from_poses(self, T, q):
        return self._angle(T)[0][:, None]

    def _residual(self, T, J, band):
        th, (a, cr) = self._angle(T)
        sn = np.linalg.norm(cr, axis=1)
        n = cr / np.where(sn > 1e-12, sn, 1.0)[:, None]
        flat = sn <= 1e-12
        if flat.any():   # opposite (or equal) directions: turn about any axis normal to a
            other = np.where(np.abs(a[flat, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
            p = _cross(a[flat], other)
            n[flat] = p / np.linalg.norm(p, axis=1)[:, None]
        # Turning about n shrinks the angle: d theta / dq = -n . J_w.
        g = -np.einsum("bk,bkj->bj", n, J[:, 3:])
        e = np.maximum(th - band[0], 0.0)
        return e[:, None], (g * (e > 0)[:, None])[:, None, :]

    def to_dict(self):
        return {"type": self.kind, "direction": list(self.direction),
                "tolerance": self.tolerance, "axis": list(self.axis)}


@dataclass(frozen=True)
class OrientationConstraint(Constraint):
    """The tool rotation within ``tolerance (rx, ry, rz)`` rad of ``rotation`` per axis (the
    rotation vector of ``R_target^T R_tool``); an axis with a tolerance >= ``FREE_AXIS`` is
    free."""

    kind: ClassVar[str] = "orientation"
    rotation: tuple[tuple[float, float, float], ...]
    tolerance: tuple[float, float, float]

    @property
    def constrained(self) -> np.ndarray:
        """Indices of the axes that are not free."""
        return np.flatnonzero(np.asarray(self.tolerance) < FREE_AXIS)

    def tolerances(self) -> np.ndarray:
        return np.asarray(self.tolerance)[self.constrained]

    def _phi(self, T: np.ndarray) -> np.ndarray:
        Rt = np.asarray(self.rotation)
        return _log(np.einsum("ji,bjk->bik", Rt, T[:, :3, :3]))

    def _errors_from_poses(self, T, q):
        return np.abs(self._phi(T)[:, self.constrained])

    def _residual(self, T, J, band):
        phi = self._phi(T)
        Rt = np.asarray(self.rotation)
        G = _left_jacobian_inverse(phi) @ (Rt.T @ J[:, 3:])     # (N, 3, dof)
        ax = self.constrained
        r, G = phi[:, ax], G[:, ax]
        e = r - np.clip(r, -band, band)
        return e, G * (e != 0)[:, :, None]

    def to_dict(self):
        return {"type": self.kind, "rotation": [list(r) for r in self.rotation],
                "tolerance": list(self.tolerance)}


@dataclass(frozen=True)
class PositionLineConstraint(Constraint):
    """The tool point within ``tolerance`` mm of the line through ``point`` along
    ``direction`` (unit)."""

    kind: ClassVar[str] = "position_line"
    point: tuple[float, float, float]
    direction: tuple[float, float, float]
    tolerance: float

    def tolerances(self) -> np.ndarray:
        return np.array([self.tolerance])

    def _offset(self, T: np.ndarray) -> np.ndarray:
        u = np.asarray(self.direction)
        v = T[:, :3, 3] - np.asarray(self.point)
        return v - (v @ u)[:, None] * u

    def _errors_from_poses(self, T, q):
        return np.linalg.norm(self._offset(T), axis=1)[:, None]

    def _residual(self, T, J, band):
        off = self._offset(T)
        d = np.linalg.norm(off, axis=1)
        n = off / np.where(d > 1e-12, d, 1.0)[:, None]
        # n is normal to the line: n . (I - u u^T) J_v = n . J_v.
        g = np.einsum("bk,bkj->bj", n, J[:, :3])
        e = np.maximum(d - band[0], 0.0)
        return e[:, None], (g * (e > 0)[:, None])[:, None, :]

    def to_dict(self):
        return {"type": self.kind, "point": list(self.point),
                "direction": list(self.direction), "tolerance": self.tolerance}


@dataclass(frozen=True)
class PositionPlaneConstraint(Constraint):
    """The tool point within ``tolerance`` mm of the plane through ``point`` with ``normal``
    (unit)."""

    kind: ClassVar[str] = "position_plane"
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    tolerance: float

    def tolerances(self) -> np.ndarray:
        return np.array([self.tolerance])

    def _height(self, T: np.ndarray) -> np.ndarray:
        return (T[:, :3, 3] - np.asarray(self.point)) @ np.asarray(self.normal)

    def _errors_from_poses(self, T, q):
        return np.abs(self._height(T))[:, None]

    def _residual(self, T, J, band):
        h = self._height(T)
        g = np.einsum("k,bkj->bj", np.asarray(self.normal), J[:, :3])
        e = h - np.clip(h, -band[0], band[0])
        return e[:, None], (g * (e != 0)[:, None])[:, None, :]

    def to_dict(self):
        return {"type": self.kind, "point": list(self.point), "normal": list(self.normal),
                "tolerance": self.tolerance}


@dataclass(frozen=True)
class JointRangeConstraint(Constraint):
    """Each joint within ``[lower[i], upper[i]]`` (rad; mm on prismatic joints), already
    intersected with the joint limits."""

    kind: ClassVar[str] = "joint_range"
    lower: tuple[float, ...]
    upper: tuple[float, ...]

    @property
    def uses_fk(self) -> bool:
        return False

    def tolerances(self) -> np.ndarray:
        return np.zeros(1)

    def _errors_from_poses(self, T, q):
        lo, hi = np.asarray(self.lower), np.asarray(self.upper)
        return np.max(np.maximum(np.maximum(lo - q, q - hi), 0.0), axis=1)[:, None]

    def _residual(self, T, J, band):   # projected by clipping (``project_all``)
        n = 0 if J is None else len(J)
        return np.zeros((n, 0)), np.zeros((n, 0, self.model.dof))

    def to_dict(self):
        return {"type": self.kind, "lower": list(self.lower), "upper": list(self.upper)}


CONSTRAINT_TYPES: dict[str, type[Constraint]] = {
    c.kind: c for c in (AxisConstraint, OrientationConstraint, PositionLineConstraint,
                        PositionPlaneConstraint, JointRangeConstraint)}

_FIELDS = {"axis": ("direction", "tolerance", "axis"),
           "orientation": ("rotation", "tolerance"),
           "position_line": ("point", "direction", "tolerance"),
           "position_plane": ("point", "normal", "tolerance"),
           "joint_range": ("lower", "upper")}


# ---- parsing ------------------------------------------------------------------------------
def _tolerance(value: Any, loc: tuple, least: float, unit: str, most: float = math.inf
               ) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) \
            or not math.isfinite(float(value)):
        raise FieldError(loc, f"{loc[-1]} must be a finite number ({unit})")
    x = float(value)
    if x <= 0:
        raise FieldError(loc, f"{loc[-1]} must be > 0 ({unit}), got {x:g}: an exact equality "
                         "cannot be certified; give the accuracy needed")
    if x < least:
        raise FieldError(loc, f"{loc[-1]} must be at least {least:g} {unit}, got {x:g}")
    if x > most:
        raise FieldError(loc, f"{loc[-1]} must be at most {most:g} {unit}, got {x:g}")
    return x


def _rotation(value: Any, loc: tuple) -> tuple[tuple[float, float, float], ...]:
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise FieldError(loc, "rotation must be a 3x3 matrix of numbers") from None
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise FieldError(loc, f"rotation must be a finite 3x3 matrix, got shape "
                         f"{list(R.shape)}")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise FieldError(loc, "rotation must be a rotation matrix (orthonormal, det +1)")
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-12:
        # Re-orthonormalise the rounding away (a rotation that is one already is kept as
        # given, so a round trip is exact).
        U, _, Vt = np.linalg.svd(R)
        R = U @ Vt
    return tuple(tuple(float(x) for x in row) for row in R)


def _joint_bounds(value: Any, loc: tuple, dof: int, default: np.ndarray) -> np.ndarray:
    if not isinstance(value, list | tuple | np.ndarray) or len(value) != dof:
        raise FieldError(loc, f"{loc[-1]} must be a list of {dof} joint values (null keeps "
                         "the joint's limit)")
    out = np.array(default, dtype=float)
    for i, v in enumerate(value):
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) \
                or not math.isfinite(float(v)):
            raise FieldError(loc + (i,), f"{loc[-1]}[{i}] must be a finite number or null")
        out[i] = float(v)
    return out


def parse_constraint(data: Any, model: Any, loc: Sequence[str | int] = ("constraint",)
                     ) -> Constraint:
    """The constraint of the JSON dict ``data`` (module docstring) for ``model`` (a
    ``RobotModel``); a ``Constraint`` is returned as it is. ``FieldError`` at ``loc +
    (field,)`` for the field at fault (unknown type, unknown field, a vector of the wrong
    length, a tolerance <= 0)."""
    loc = tuple(loc)
    if isinstance(data, Constraint):
        return data
    if not isinstance(data, dict):
        raise FieldError(loc, "a constraint must be an object with a type")
    kind = data.get("type")
    if kind not in CONSTRAINT_TYPES:
        raise FieldError(loc + ("type",), f"type must be one of {', '.join(CONSTRAINT_TYPES)}"
                         f", got {kind!r}")
    allowed = _FIELDS[kind]
    for name in data:
        if name != "type" and name not in allowed:
            raise FieldError(loc + (name,), f"unknown field {name!r} of a {kind} constraint "
                             f"(fields: {', '.join(allowed)})")
    optional = {"axis"}
    for name in allowed:
        if name not in data and name not in optional:
            raise FieldError(loc + (name,), f"{name} is required for a {kind} constraint")
    if kind == "axis":
        return AxisConstraint(
            direction=_unit(_vector3(data["direction"], loc + ("direction",), "direction"),
                            loc + ("direction",), "direction"),
            tolerance=_tolerance(data["tolerance"], loc + ("tolerance",),
                                 MIN_ANGLE_TOLERANCE, "rad", math.pi),
            axis=_unit(_vector3(data.get("axis", [0, 0, 1]), loc + ("axis",), "axis"),
                       loc + ("axis",), "axis"),
            model=model)
    if kind == "orientation":
        rot = _rotation(data["rotation"], loc + ("rotation",))
        tol = data["tolerance"]
        if isinstance(tol, int | float) and not isinstance(tol, bool):
            tol = [tol] * 3
        if not isinstance(tol, list | tuple) or len(tol) != 3:
            raise FieldError(loc + ("tolerance",), "tolerance must be a list of 3 numbers "
                             "(rx, ry, rz rad; pi or more makes an axis free)")
        tols = tuple(_tolerance(t, loc + ("tolerance", i), MIN_ANGLE_TOLERANCE, "rad")
                     for i, t in enumerate(tol))
        if min(tols) >= FREE_AXIS:
            raise FieldError(loc + ("tolerance",), "tolerance leaves every axis free: at "
                             f"least one must be below pi ({FREE_AXIS:.6g})")
        return OrientationConstraint(rotation=rot, tolerance=tols, model=model)
    if kind in ("position_line", "position_plane"):
        point = _vector3(data["point"], loc + ("point",), "point")
        name = "direction" if kind == "position_line" else "normal"
        unit = _unit(_vector3(data[name], loc + (name,), name), loc + (name,), name)
        tol = _tolerance(data["tolerance"], loc + ("tolerance",), MIN_LENGTH_TOLERANCE, "mm")
        if kind == "position_line":
            return PositionLineConstraint(point=point, direction=unit, tolerance=tol,
                                          model=model)
        return PositionPlaneConstraint(point=point, normal=unit, tolerance=tol, model=model)
    # joint_range
    dof = model.dof
    lim_lo = np.asarray(model.lower, dtype=float)
    lim_hi = np.asarray(model.upper, dtype=float)
    lo = np.maximum(_joint_bounds(data["lower"], loc + ("lower",), dof, lim_lo), lim_lo)
    hi = np.minimum(_joint_bounds(data["upper"], loc + ("upper",), dof, lim_hi), lim_hi)
    for i in range(dof):
        if lo[i] > hi[i]:
            raise FieldError(loc + ("upper", i), f"upper[{i}] = {hi[i]:g} is below "
                             f"lower[{i}] = {lo[i]:g} (within the joint limits)")
    return JointRangeConstraint(lower=tuple(map(float, lo)), upper=tuple(map(float, hi)),
                                model=model)


def parse_constraints(data: Any, model: Any, loc: Sequence[str | int] = ("constraints",)
                      ) -> tuple[Constraint, ...]:
    """A list of constraints (or one) -> a tuple; errors at ``loc + (index, field)``."""
    loc = tuple(loc)
    if isinstance(data, dict | Constraint):
        return (parse_constraint(data, model, loc),)
    if not isinstance(data, list | tuple) or not data:
        raise FieldError(loc, "constraints must be a non-empty list of constraints")
    return tuple(parse_constraint(c, model, loc + (i,)) for i, c in enumerate(data))


# ---- projection ---------------------------------------------------------------------------
def _pose_jacobian(model: Any, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tool poses ``(N, 4, 4)`` and geometric Jacobians ``(N, 6, dof)``; by central finite
    differences of FK when the model has no Jacobian."""
    try:
        J, T = jacobian_and_pose(model, Q)
        return T, J
    except (NotImplementedError, AttributeError, TypeError):
        return _fd_pose_jacobian(model, Q)


def _fd_pose_jacobian(model: Any, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``_pose_jacobian`` by central differences of ``fk``."""
    N, dof = Q.shape
    T = fk(model, Q)
    E = np.eye(dof) * _FD_STEP
    Qp = (Q[:, None, :] + E).reshape(-1, dof)
    Qm = (Q[:, None, :] - E).reshape(-1, dof)
    Tp, Tm = fk(model, Qp).reshape(N, dof, 4, 4), fk(model, Qm).reshape(N, dof, 4, 4)
    J = np.empty((N, 6, dof))
    J[:, :3] = np.swapaxes((Tp[..., :3, 3] - Tm[..., :3, 3]) / (2 * _FD_STEP), 1, 2)
    # World angular velocity: the rotation vector of R+ R-^T over the step.
    dR = np.einsum("bjik,bjlk->bjil", Tp[..., :3, :3], Tm[..., :3, :3]).reshape(-1, 3, 3)
    J[:, 3:] = np.swapaxes(_log(dR).reshape(N, dof, 3) / (2 * _FD_STEP), 1, 2)
    return T, J


def _box(constraints: Sequence[Constraint], model: Any, lower=None, upper=None
         ) -> tuple[np.ndarray, np.ndarray]:
    """The joint box: the limits (or ``lower``/``upper``) narrowed by every joint range."""
    lo = np.array(model.lower if lower is None else lower, dtype=float)
    hi = np.array(model.upper if upper is None else upper, dtype=float)
    for c in constraints:
        if isinstance(c, JointRangeConstraint):
            lo = np.maximum(lo, c.lower)
            hi = np.minimum(hi, c.upper)
    return lo, hi


def project_all(constraints: Sequence[Constraint], Q: np.ndarray, lower=None, upper=None,
                weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Project ``Q (N, dof)`` onto every constraint at once (module docstring): the stacked
    residuals, each scaled by its tolerance, by damped least squares in the joint metric
    ``weights`` (1 per rad), each iteration clipped to the joint box. ``(Q', ok (N,))``."""
    if not constraints:
        raise ValueError("no constraint to project onto")
    model = constraints[0].model
    lo, hi = _box(constraints, model, lower, upper)
    Q = np.minimum(np.maximum(np.array(Q, dtype=float), lo), hi)
    w = np.ones(Q.shape[1]) if weights is None else np.asarray(weights, dtype=float)
    geo = [c for c in constraints if c.uses_fk]
    if not geo:
        return Q, np.ones(len(Q), dtype=bool)
    tols = [c.tolerances() for c in geo]
    bands = [PROJECT_TARGET * t for t in tols]
    inv_w = 1.0 / w
    active = np.arange(len(Q))
    ok = np.zeros(len(Q), dtype=bool)
    for _ in range(PROJECT_ITERATIONS):
        T, J = _pose_jacobian(model, Q[active])
        if len(geo) == 1:
            e, G = geo[0]._residual(T, J, bands[0])
            e = e / tols[0]
            G = G * (inv_w / tols[0][:, None])
        else:
            es, Gs = [], []
            for c, t, b in zip(geo, tols, bands):
                e, G = c._residual(T, J, b)
                es.append(e / t)
                Gs.append(G / t[:, None])
            e = np.concatenate(es, axis=1)
            G = np.concatenate(Gs, axis=1) * inv_w     # in weighted joint coordinates
        done = np.all(np.abs(e) <= PROJECT_STOP - PROJECT_TARGET, axis=1)
        if done.any():
            ok[active[done]] = True
            keep = ~done
            active, e, G = active[keep], e[keep], G[keep]
            if not len(active):
                break
        m = G.shape[1]
        if m == 1:
            g = G[:, 0, :]
            gg = np.einsum("ij,ij->i", g, g)
            dx = -g * (e[:, 0] / (gg * (1.0 + 1e-6) + 1e-9))[:, None]
        else:
            GGt = G @ np.swapaxes(G, 1, 2)
            lam = 1e-9 + 1e-6 * np.trace(GGt, axis1=1, axis2=2) / m
            A = GGt + lam[:, None, None] * np.eye(m)
            y = np.linalg.solve(A, e[:, :, None])
            dx = -(np.swapaxes(G, 1, 2) @ y)[..., 0]    # weighted coordinates
        size = np.sqrt(np.einsum("ij,ij->i", dx, dx))
        dx *= np.minimum(1.0, PROJECT_MAX_MOVE / np.maximum(size, 1e-300))[:, None]
        Q[active] = np.minimum(np.maximum(Q[active] + dx * inv_w, lo), hi)
    else:
        # Out of iterations: those within the acceptance band pass.
        T = fk(model, Q[active])
        good = np.ones(len(active), dtype=bool)
        for c, t in zip(geo, tols):
            good &= np.all(c._errors_from_poses(T, Q[active]) <= PROJECT_ACCEPT * t, axis=1)
        ok[active[good]] = True
    return Q, ok


def _worst(constraints: Sequence[Constraint], Q: np.ndarray
           ) -> tuple[np.ndarray, list[np.ndarray]]:
    """``(N,)`` the largest excess over a tolerance of each state, and each constraint's
    largest deviation per component over the states."""
    model = constraints[0].model
    T = fk(model, Q) if any(c.uses_fk for c in constraints) else None
    excess = np.zeros(len(Q))
    worst = []
    for c in constraints:
        E = c._errors_from_poses(T, Q)
        excess = np.maximum(excess, np.max(np.maximum(E - c.tolerances(), 0.0), axis=1))
        worst.append(E.max(axis=0) if len(E) else np.zeros(E.shape[1]))
    return excess, worst


# ---- the result ---------------------------------------------------------------------------
@dataclass
class ConstrainedResult:
    """A constrained plan (module docstring). ``path (K, dof)``: waypoints whose straight
    segments are collision-free and within every constraint at every state checked at
    ``resolution``; ``worst_violation``: the largest excess of a checked state over a
    tolerance (0.0 on success; nan without a path); ``worst_error``: per constraint, the
    largest deviation of each component over the checked states (rad or mm);
    ``states_checked``: states of the final re-check (each for collision and for every
    constraint); ``length``: the Euclidean length (rad, mm); times in s."""

    status: ConstrainedStatus
    message: str
    path: np.ndarray
    worst_violation: float = math.nan
    worst_error: list[list[float]] = field(default_factory=list)
    planning_time_s: float = 0.0
    states_checked: int = 0
    length: float = math.nan
    resolution: float = DEFAULT_RESOLUTION
    pairs: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is ConstrainedStatus.OK

    def to_dict(self, joint_names: list[str] | None = None) -> dict[str, Any]:
        """JSON-ready (lists and numbers; nan as null)."""
        def num(x):
            return None if x is None or not math.isfinite(float(x)) else float(x)

        out: dict[str, Any] = {
            "status": self.status.value, "message": self.message, "path": self.path.tolist(),
            "worst_violation": num(self.worst_violation),
            "worst_error": [[float(v) for v in e] for e in self.worst_error],
            "planning_time_s": float(self.planning_time_s),
            "states_checked": int(self.states_checked), "length": num(self.length),
            "resolution": float(self.resolution), "pairs": [list(p) for p in self.pairs],
            "stats": dict(self.stats)}
        if joint_names is not None:
            out["joints"] = list(joint_names)
        return out


# ---- input --------------------------------------------------------------------------------
def _number(value: Any, loc: tuple, lo: float, hi: float, open_low: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or (value <= lo if open_low else value < lo) \
            or value > hi:
        low = f"> {lo:g}" if open_low else f">= {lo:g}"
        raise FieldError(loc, f"{loc[-1]} must be a number {low} and <= {hi:g}")
    return float(value)


def _describe(i: int, c: Constraint, err: np.ndarray) -> str:
    tol = c.tolerances()
    k = int(np.argmax(err - tol))
    unit = "mm" if isinstance(c, PositionLineConstraint | PositionPlaneConstraint) else "rad"
    if isinstance(c, JointRangeConstraint):
        return f"constraint {i} ({c.kind}): {float(err[0]):.6g} outside the range"
    part = ""
    if isinstance(c, OrientationConstraint):
        part = f" about {'xyz'[int(c.constrained[k])]}"
    return (f"constraint {i} ({c.kind}): deviation{part} {float(err[k]):.6g} {unit} > "
            f"tolerance {float(tol[k]):.6g} {unit}")


# ---- the search ---------------------------------------------------------------------------
class _Space:
    """The constraint manifold within the joint box, as the search sees it: projection,
    edges checked for collision and for the constraints, walks of projected steps."""

    def __init__(self, checker: MotionChecker, constraints: Sequence[Constraint],
                 resolution: float, step: float, late: Callable[[], bool]) -> None:
        self.checker, self.constraints = checker, tuple(constraints)
        self.resolution, self.step, self.late = resolution, step, late
        self.w = checker.weights
        self.lo, self.hi = _box(constraints, checker.robot_model, checker.lower, checker.upper)
        self.geo = any(c.uses_fk for c in constraints)
        self.projections = 0
        self.constraint_checks = 0

    def dist(self, a: np.ndarray, b: np.ndarray) -> float:
        d = (b - a) * self.w
        return float(np.sqrt(d @ d))

    def project(self, q: np.ndarray) -> tuple[np.ndarray, bool]:
        if not self.geo:
            return np.clip(q, self.lo, self.hi), True
        self.projections += 1
        Q, ok = project_all(self.constraints, q[None], self.lo, self.hi, self.w)
        return Q[0], bool(ok[0])

    def chord_ok(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the interior states of ``a``-``b`` at ``resolution`` satisfy every
        constraint (the joint box is convex: its ends suffice)."""
        if not self.geo:
            return True
        n = self.checker.steps(a, b, self.resolution)
        if n <= 1:
            return True
        s = np.arange(1, n) / n
        Q = a + (b - a) * s[:, None]
        self.constraint_checks += len(Q)
        return not bool(np.any(_worst(self.constraints, Q)[0] > 0.0))

    def edge_ok(self, a: np.ndarray, b: np.ndarray) -> tuple[bool, bool]:
        """``(ok, constraint_failed)`` of the straight segment to a new state ``b``."""
        if not self.chord_ok(a, b):
            return False, True
        ch = self.checker
        return bool(ch.free(b)) and ch.segment_free(a, b, self.resolution), False

    def walk(self, a: np.ndarray, target: np.ndarray, most: int, valid: bool = False
             ) -> tuple[list, bool]:
        """Projected steps from ``a`` towards ``target`` (at most ``most``): the states
        reached, and whether the last is ``target`` itself. A ``valid`` target (a tree node,
        the goal: within the constraints and free) is joined by the straight segment once
        it is within a step; any other is projected like every step."""
        out: list[np.ndarray] = []
        q = a
        h = self.step
        h_min = self.step * MIN_STEP_FRACTION
        d = self.dist(q, target)
        while len(out) < most and d > 0.0:
            if self.late():
                break
            if valid and d <= h:
                good, constraint = self.edge_ok(q, target)
                if good:
                    out.append(target)
                    return out, True
                if not constraint or h <= h_min:
                    break
                h = 0.5 * d
                continue
            cand = target if d <= h else q + (target - q) * (h / d)
            new, ok = self.project(cand)
            if not ok:
                break
            move = self.dist(q, new)
            d_new = self.dist(new, target)
            # A jump: farther than JUMP_FACTOR steps, beyond the projection's correction of
            # the candidate (up to one Gauss-Newton move: a state near the edge of its
            # tolerance, e.g. the start, is pulled into the band in one step).
            correction = min(self.dist(cand, new), PROJECT_MAX_MOVE)
            if move <= 1e-12 or move > JUMP_FACTOR * h + correction or d_new >= d - 1e-3 * h:
                break
            good, constraint = self.edge_ok(q, new)
            if not good:
                if constraint and h > h_min:
                    h *= 0.5
                    continue
                break
            out.append(new)
            q, d = new, d_new
            h = min(self.step, 1.5 * h)
        return out, bool(out) and d == 0.0


class _Tree:
    """A search tree: its states (a list, and an array kept for nearest-neighbour queries)
    and each one's parent (-1 for the root)."""

    def __init__(self, root: np.ndarray) -> None:
        self.X = [root]
        self.parent = [-1]
        self._A = root[None].copy()

    def add(self, x: np.ndarray, parent: int) -> int:
        self.X.append(x)
        self.parent.append(parent)
        if len(self.X) > len(self._A):
            grown = np.empty((2 * len(self._A), self._A.shape[1]))
            grown[:len(self._A)] = self._A
            self._A = grown
        self._A[len(self.X) - 1] = x
        return len(self.X) - 1

    def nearest(self, x: np.ndarray, w: np.ndarray) -> int:
        d = (self._A[:len(self.X)] - x) * w
        return int(np.argmin(np.einsum("ij,ij->i", d, d)))

    def branch(self, i: int) -> list[np.ndarray]:
        out = []
        while i >= 0:
            out.append(self.X[i])
            i = self.parent[i]
        return out


def _grow(tree: _Tree, i: int, states: list) -> int:
    """Append ``states`` as a chain below node ``i``; the last node's index."""
    for x in states:
        i = tree.add(x, i)
    return i


def _rrt_connect(space: _Space, start: np.ndarray, goal: np.ndarray,
                 rng: np.random.Generator, stop: Callable[[], bool]
                 ) -> tuple[np.ndarray | None, dict]:
    """Projection-based RRT-Connect (module docstring)."""
    stats = {"iterations": 0, "nodes": 2}
    if not np.any(goal != start):
        return np.stack([start, goal]), stats
    direct, reached = space.walk(start, goal, CONNECT_STEPS, valid=True)
    if reached:
        return np.array([start] + direct), stats
    ta, tb = _Tree(start), _Tree(goal)
    _grow(ta, 0, direct)     # how far the direct walk got is a branch of the start's
    a_is_start = True
    extend = max(1, int(math.ceil(EXTEND_RANGE / space.step)))
    dof = len(start)
    while not stop():
        stats["iterations"] += 1
        x = space.lo + (space.hi - space.lo) * rng.random(dof)
        x, _ = space.project(x)
        i = ta.nearest(x, space.w)
        states, _ = space.walk(ta.X[i], x, extend)
        if states:
            k = _grow(ta, i, states)
            j = tb.nearest(ta.X[k], space.w)
            states, reached = space.walk(tb.X[j], ta.X[k], CONNECT_STEPS, valid=True)
            j = _grow(tb, j, states[:-1] if reached else states)
            if reached:
                sa, sb = ta.branch(k), tb.branch(j)
                if not a_is_start:
                    sa, sb = sb, sa
                stats["nodes"] = len(ta.X) + len(tb.X)
                return np.array(sa[::-1] + sb), stats
        ta, tb = tb, ta
        a_is_start = not a_is_start
    stats["nodes"] = len(ta.X) + len(tb.X)
    return None, stats


def _length(path: np.ndarray, w: np.ndarray | None = None) -> float:
    if len(path) < 2:
        return 0.0
    d = np.diff(path, axis=0)
    if w is not None:
        d = d * w
    return float(np.sqrt((d * d).sum(1)).sum())


def _shortcut(space: _Space, path: np.ndarray, rng: np.random.Generator,
              stop: Callable[[], bool]) -> tuple[np.ndarray, int]:
    """Geodesic shortcuts between random waypoints (module docstring); kept when the walk
    arrives and is shorter. Answers the path and the shortcuts taken."""
    taken, fails = 0, 0
    for _ in range(SHORTCUT_ATTEMPTS):
        n = len(path)
        if n <= 2 or fails >= SHORTCUT_PATIENCE or stop():
            break
        i, j = np.sort(rng.choice(n, size=2, replace=False))
        if j - i < 2:
            fails += 1
            continue
        old = _length(path[i:j + 1], space.w)
        most = int(math.ceil(old / (space.step * MIN_STEP_FRACTION))) + 2
        states, reached = space.walk(path[i], path[j], most, valid=True)
        if not reached or _length(np.array([path[i]] + states), space.w) >= old - 1e-9:
            fails += 1
            continue
        path = np.concatenate([path[:i + 1], np.array(states[:-1]).reshape(-1, path.shape[1]),
                               path[j:]])
        taken += 1
        fails = 0
    return path, taken


def _thin(space: _Space, path: np.ndarray, stop: Callable[[], bool]) -> np.ndarray:
    """Drop waypoints: from each kept one, the farthest of the next 2, 4, 8 ... waypoints
    whose straight chord passes both checks (doubling while it does)."""
    keep = [0]
    i, n = 0, len(path)
    while i < n - 1:
        best, span = i + 1, 2
        while not stop():
            j = min(i + span, n - 1)
            if j <= best or not space.edge_ok(path[i], path[j])[0]:
                break
            best = j
            span *= 2
        keep.append(best)
        i = best
    return path[keep]


def _recheck(checker: MotionChecker, constraints: Sequence[Constraint], path: np.ndarray,
             resolution: float) -> tuple[bool, float, list[np.ndarray], int]:
    """The final dense check: ``(collision-free, worst excess, worst deviations, states)``
    over every state of the path's segments at ``resolution``."""
    P = path
    steps = [checker.steps(P[i], P[i + 1], resolution) for i in range(len(P) - 1)]
    Q = segment_states(P, steps) if len(P) > 1 else P
    excess = 0.0
    worst = [np.zeros(len(c.tolerances())) for c in constraints]
    for s in range(0, len(Q), _CHUNK):
        ex, wo = _worst(constraints, Q[s:s + _CHUNK])
        excess = max(excess, float(ex.max()))
        worst = [np.maximum(a, b) for a, b in zip(worst, wo)]
    deadline, checker.deadline = checker.deadline, None
    try:
        free = checker.path_free(P, resolution)
    finally:
        checker.deadline = deadline
    return free, excess, worst, len(Q)


def plan_constrained(checker: MotionChecker, start, goal, constraints, *,
                     time_limit: float = 5.0, seed: int = 0,
                     resolution: float = DEFAULT_RESOLUTION, step: float = DEFAULT_STEP,
                     simplify: bool = True, progress=None) -> ConstrainedResult:
    """A collision-free path of ``checker``'s robot from ``start`` to ``goal``
    (configurations) along which every constraint holds at every state checked at
    ``resolution`` (module docstring). ``constraints``: one or a list, as JSON dicts or
    ``Constraint`` objects (bound to ``checker.robot_model`` when parsed here; errors at
    ``("constraints", i, field)``); ``step``: the length of a tree's step on the constraint
    (weighted rad, in ``[resolution, 0.5]``); ``time_limit`` s of search, then shortcuts
    (half of it within what the search left, at least ``SIMPLIFY_MIN_S``) and the final
    re-check. ``progress(fraction)`` is called during the search and may raise to stop."""
    t0 = time.perf_counter()
    model = checker.robot_model
    dof = checker.dof
    q_start = joint_vector(start, dof, ("start",))
    q_goal = joint_vector(goal, dof, ("goal",))
    cons = parse_constraints(constraints, model)
    for i, c in enumerate(cons):
        if c.model is not model and (c.model.dof != dof):
            raise FieldError(("constraints", i), f"constraint {i} is bound to a robot with "
                             f"{c.model.dof} joints, not {dof}")
    time_limit = _number(time_limit, ("time_limit",), 0.0, MAX_TIME_LIMIT)
    resolution = _number(resolution, ("resolution",), MIN_RESOLUTION, 0.5, open_low=False)
    step = _number(step, ("step",), resolution, 0.5, open_low=False)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise FieldError(("seed",), "seed must be an integer")
    rng = np.random.default_rng(int(seed))
    checks0 = checker.checks

    def result(status: ConstrainedStatus, message: str, **kw) -> ConstrainedResult:
        kw.setdefault("path", np.empty((0, dof)))
        return ConstrainedResult(status, message, planning_time_s=time.perf_counter() - t0,
                                 resolution=resolution, **kw)

    names = [j.name for j in model.joints]
    for q, what in ((q_start, "start"), (q_goal, "goal")):
        bad = np.flatnonzero((q < checker.lower - 1e-9) | (q > checker.upper + 1e-9))
        if len(bad):
            i = int(bad[0])
            return result(ConstrainedStatus.OUT_OF_LIMITS,
                          f"the {what} is out of limits: joint '{names[i]}' = {q[i]:.6g}, "
                          f"limits [{checker.lower[i]:.6g}, {checker.upper[i]:.6g}]")
    for q, what, status in ((q_start, "start", ConstrainedStatus.START_VIOLATES_CONSTRAINT),
                            (q_goal, "goal", ConstrainedStatus.GOAL_VIOLATES_CONSTRAINT)):
        for i, c in enumerate(cons):
            err = c.errors(q)[0]
            if np.any(err > c.tolerances()):
                return result(status, f"the {what} violates {_describe(i, c, err)}",
                              stats={"violated": {"constraint": i, "type": c.kind,
                                                  "error": err.tolist(),
                                                  "tolerance": c.tolerances().tolist()}})
    for q, what, status in ((q_start, "start", ConstrainedStatus.START_IN_COLLISION),
                            (q_goal, "goal", ConstrainedStatus.GOAL_IN_COLLISION)):
        if not checker.free(q):
            pairs = checker.pairs(q)
            text = ", ".join(f"{a} - {b}" for a, b in pairs[:4])
            return result(status, f"the {what} is in collision: {text}", pairs=pairs)

    deadline = t0 + time_limit

    def stop() -> bool:
        now = time.perf_counter()
        if progress is not None:
            progress(min(1.0, (now - t0) / time_limit))
        return now >= deadline

    space = _Space(checker, cons, resolution, step, lambda: time.perf_counter() >= deadline)
    old_deadline = checker.deadline
    checker.deadline = deadline
    try:
        raw, stats = _rrt_connect(space, q_start, q_goal, rng, stop)
        if raw is None:
            stats.update(projections=space.projections,
                         constraint_checks=space.constraint_checks,
                         collision_checks=checker.checks - checks0)
            return result(ConstrainedStatus.TIMEOUT,
                          f"no path on the constraints within the time limit of "
                          f"{time_limit:g} s ({stats['nodes']} tree nodes)", stats=stats)
        stats["search_time_s"] = time.perf_counter() - t0
        stats["raw_waypoints"] = len(raw)
        stats["raw_length"] = _length(raw)
        path = raw
        t_s = time.perf_counter()
        if simplify and len(path) > 2:
            s_deadline = t_s + max(SIMPLIFY_MIN_S, min(0.5 * time_limit, deadline - t_s))
            checker.deadline = s_deadline
            space.late = lambda: time.perf_counter() >= s_deadline

            def s_stop() -> bool:
                return time.perf_counter() >= s_deadline

            path, stats["shortcuts"] = _shortcut(space, path, rng, s_stop)
            path = _thin(space, path, s_stop)
        stats["simplify_time_s"] = time.perf_counter() - t_s
    finally:
        checker.deadline = old_deadline
    free, excess, worst, n_states = _recheck(checker, cons, path, resolution)
    if path is not raw and (not free or excess > 0.0):
        # Never expected (every piece kept was checked at these states): the path as found.
        stats["simplified_path_rejected"] = True
        path = raw
        free, excess, worst, n_states = _recheck(checker, cons, path, resolution)
    stats.update(projections=space.projections, constraint_checks=space.constraint_checks,
                 collision_checks=checker.checks - checks0, waypoints=len(path))
    if not free or excess > 0.0:   # pragma: no cover - every edge was checked when added
        raise RuntimeError("a constrained path failed its final check")
    return result(ConstrainedStatus.OK, "ok", path=path, worst_violation=excess,
                  worst_error=[w.tolist() for w in worst], states_checked=n_states,
                  length=_length(path), stats=stats)
