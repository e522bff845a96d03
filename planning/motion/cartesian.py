"""Cartesian segments: the tool along a straight line or a circular arc, joint path by IK.

``plan_line`` moves the tool from its pose at ``q_start`` (FK) to a target pose along a
straight line; ``plan_arc`` along a circular arc through a via point or about a centre and
an axis. The orientation is interpolated to the target's (``slerp``: the shortest rotation,
at a constant rate), held at the start's (``hold``), or, on an arc, turned with the arc
(``rotate``). Lengths mm, angles rad, poses 4x4 ``T_world_tool`` (docs/conventions.md).

The segment is cut into steps of at most ``max_step`` mm of tool travel and ``max_rotation``
rad of tool rotation. Each step's pose is solved by damped least squares (the robot's
geometric Jacobian, ``kinematics.jacobian``; Levenberg-Marquardt damping that grows with
the error, so it stays bounded near singular configurations) started from the previous
step's solution continued by the previous step's motion (a secant predictor), which keeps
the arm on one IK branch and converges in one or two iterations. Arms with more joints than
the six of a pose use the null space of the Jacobian, once per step, to move away from their
joint limits without moving the tool. A step ends the segment when:

* the solve does not reach the pose within ``position_tolerance`` mm and
  ``orientation_tolerance`` rad (``unreachable``), or reaches it only outside a joint's
  limits (``out_of_limits``: the solve within the limits fails where the unconstrained one
  succeeds);
* some joint moves more than ``jump_threshold`` from the previous step (rad on revolute
  joints, ``jump_threshold`` x ``PRISMATIC_SCALE`` mm on prismatic ones, the planners'
  metric): the IK jumped branch, or the arm passes close to a singular configuration where
  the line needs a fast flip (``discontinuous``);
* the step's configuration, or the straight joint-space motion from the previous one,
  collides, checked by the motion planner's checker (``MotionChecker``: the same robot
  model, scene, sphere and exact stages) at the planner's ``resolution`` (``collision``);
* the time limit, if one is given, has passed (``timeout``).

The answer keeps every step before the one that failed: ``fraction`` is the share of the
segment's length (of its rotation, for a pure rotation) reached, as MoveIt's
``computeCartesianPath`` reports it, and ``path`` holds the configurations of the steps
reached, each within the tolerances of its ideal pose and the motions between them free.
A start out of the limits or in collision answers ``out_of_limits`` or ``collision`` with an
empty path; bad input is a ``FieldError`` naming the argument (as the service names fields).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.jacobian import jacobian_and_pose
from kinematics.status import Status

from .checker import DEFAULT_RESOLUTION, MIN_RESOLUTION, MotionChecker

__all__ = ["CartesianStatus", "CartesianResult", "plan_line", "plan_arc", "ORIENTATIONS",
           "DEFAULT_MAX_STEP", "DEFAULT_MAX_ROTATION", "DEFAULT_JUMP_THRESHOLD",
           "DEFAULT_POSITION_TOLERANCE", "DEFAULT_ORIENTATION_TOLERANCE",
           "DEFAULT_LIMIT_AVOIDANCE", "MAX_STEPS", "MAX_TIME_LIMIT"]

#: Largest tool travel between two steps (mm) ...
DEFAULT_MAX_STEP = 5.0
#: ... and largest tool rotation (rad, about 2.9 degrees).
DEFAULT_MAX_ROTATION = 0.05
#: Largest joint motion between two steps (rad; x ``PRISMATIC_SCALE`` mm on prismatic joints).
DEFAULT_JUMP_THRESHOLD = 0.3
#: A step is reached within this distance (mm) ...
DEFAULT_POSITION_TOLERANCE = 0.1
#: ... and this rotation (rad) of its ideal pose.
DEFAULT_ORIENTATION_TOLERANCE = 1e-3
#: Most steps of one segment (a 10 m line at 0.1 mm steps): bounds the work before it starts.
MAX_STEPS = 100_000
#: Longest time limit (s).
MAX_TIME_LIMIT = 3600.0
#: Damped least-squares iterations of one step.
MAX_ITERATIONS = 60
#: Null-space motion away from the joint limits (arms with more than six joints): the share
#: of a joint's half range it moves in one step at a limit, a cubic of the joint's distance
#: from mid-range (0 switches it off). The motion is also kept within a quarter of the jump
#: threshold, so that it never looks like a jump.
DEFAULT_LIMIT_AVOIDANCE = 0.1
#: Orientation strategies: ``slerp`` to the target's, ``hold`` the start's, ``rotate`` with
#: the arc (arcs only).
ORIENTATIONS = ("slerp", "hold", "rotate")
#: States between two steps measured for the deviation from the ideal curve.
_DEVIATION_SAMPLES = 3
_NUMBER = (int, float, np.integer, np.floating)

class CartesianStatus(Status):
    """How a Cartesian segment ended (a member of the status family, ``kinematics.status``)."""

    #: The whole segment was followed.
    OK = "ok"
    #: A step's pose has no IK solution within the tolerances near the previous step's.
    UNREACHABLE = "unreachable"
    #: A step's pose is reached only outside a joint's limits.
    OUT_OF_LIMITS = "out_of_limits"
    #: A joint would move more than the jump threshold between two steps.
    DISCONTINUOUS = "discontinuous"
    #: A step, or the motion to it from the previous one, collides.
    COLLISION = "collision"
    #: The time limit ran out before the end of the segment.
    TIMEOUT = "timeout"


@dataclass(frozen=True)
class CartesianResult:
    """A Cartesian segment (module docstring). Arrays are read-only float64.

    ``path (n, dof)``: the configurations of the steps reached, ``path[0]`` the start (empty
    when the start itself is out of limits or in collision); ``poses (n, 4, 4)``: their tool
    poses (FK); ``s (n,)``: each step's place on the segment, 0 at the start and 1 at the
    target (by length; by rotation for a pure rotation); ``fraction``: ``s[-1]`` (0 with an
    empty path). ``position_error`` (mm) and ``orientation_error`` (rad): the worst distance
    of a reached pose from its ideal pose; ``deviation`` (mm): the worst distance from the
    ideal curve of the tool between two steps when the arm moves straight in joint space
    (sampled). ``length`` (mm) and ``rotation`` (rad): the whole segment's; ``steps``: the
    segment's step count; ``kind``: ``line`` or ``arc``; ``orientation``: the strategy
    followed; ``pairs``: the colliding pairs (link, object or link, link) of a ``collision``
    status, at the step or at the first colliding state of the motion to it;
    ``planning_time_s``; ``stats``: solver iterations and collision checks."""

    status: CartesianStatus
    message: str
    fraction: float
    path: np.ndarray
    poses: np.ndarray
    s: np.ndarray
    position_error: float
    orientation_error: float
    deviation: float
    length: float
    rotation: float
    steps: int
    kind: str = "line"
    orientation: str = "slerp"
    pairs: tuple[tuple[str, str], ...] = ()
    planning_time_s: float = 0.0
    stats: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is CartesianStatus.OK

    def to_dict(self, joint_names: list[str] | None = None) -> dict[str, Any]:
        """JSON-ready (lists and numbers)."""
        out: dict[str, Any] = {
            "status": self.status.value, "message": self.message,
            "fraction": float(self.fraction), "path": self.path.tolist(),
            "poses": self.poses.tolist(), "s": self.s.tolist(),
            "position_error": float(self.position_error),
            "orientation_error": float(self.orientation_error),
            "deviation": float(self.deviation), "length": float(self.length),
            "rotation": float(self.rotation), "steps": int(self.steps), "kind": self.kind,
            "orientation": self.orientation, "pairs": [list(p) for p in self.pairs],
            "planning_time_s": float(self.planning_time_s), "stats": dict(self.stats),
        }
        if joint_names is not None:
            out["joints"] = list(joint_names)
        return out


# ---- rotations -----------------------------------------------------------------------------------
def _exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices of rotation vectors ``w (n, 3)`` -> ``(n, 3, 3)`` (Rodrigues)."""
    w = np.asarray(w, dtype=float).reshape(-1, 3)
    th = np.linalg.norm(w, axis=1)
    small = th < 1e-12
    k = w / np.where(small, 1.0, th)[:, None]
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -k[:, 2], k[:, 1]
    K[:, 1, 0], K[:, 1, 2] = k[:, 2], -k[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -k[:, 1], k[:, 0]
    s, c = np.sin(th)[:, None, None], (1.0 - np.cos(th))[:, None, None]
    return np.eye(3) + s * K + c * (K @ K)


def _log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of one rotation ``(3, 3)`` -> ``(3,)``, accurate near 0 and pi."""
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sn = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    cs = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    th = math.atan2(sn, cs)
    if th > math.pi - 1e-6:
        B = 0.5 * (R + np.eye(3))
        col = int(np.argmax(np.diag(B)))
        axis = B[:, col] / np.linalg.norm(B[:, col])
        return axis * (th if float(axis @ w) >= 0 else -th)
    return w * (1.0 + th * th / 6.0 if sn < 1e-9 else th / sn)


def _angles(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation angle between ``Ra (n, 3, 3)`` and ``Rb (n, 3, 3)`` -> ``(n,)`` rad."""
    M = np.swapaxes(Ra, -1, -2) @ Rb
    w = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]],
                 axis=-1)
    return np.arctan2(np.linalg.norm(w, axis=-1) / 2.0,
                      (np.trace(M, axis1=-2, axis2=-1) - 1.0) / 2.0)


# ---- the ideal curves ----------------------------------------------------------------------------
class _Curve:
    """A tool path ``s in [0, 1] -> pose``: positions ``p0 + ...`` and rotations
    ``R(s)``; ``length`` mm, ``rotation`` rad (the tool's total turn)."""

    kind = "curve"
    length = 0.0

    def __init__(self, R0: np.ndarray, R1: np.ndarray, mode: str,
                 turn: np.ndarray | None = None) -> None:
        self.R0 = R0
        self.mode = mode
        if mode == "rotate":
            assert turn is not None
            self.w = turn                              # world-frame rotation vector
        elif mode == "slerp":
            self.w = _log(R1 @ R0.T)
        else:
            self.w = np.zeros(3)
        self.rotation = float(np.linalg.norm(self.w))

    def positions(self, s: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def distance(self, P: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def poses(self, s: np.ndarray) -> np.ndarray:
        """Ideal poses ``(n, 4, 4)`` at ``s (n,)``."""
        s = np.asarray(s, dtype=float)
        T = np.zeros((len(s), 4, 4))
        T[:, 3, 3] = 1.0
        T[:, :3, :3] = _exp(s[:, None] * self.w) @ self.R0
        T[:, :3, 3] = self.positions(s)
        return T


class _Line(_Curve):
    kind = "line"

    def __init__(self, p0, p1, R0, R1, mode: str) -> None:
        super().__init__(R0, R1, mode)
        self.p0, self.p1 = p0, p1
        self.length = float(np.linalg.norm(p1 - p0))

    def positions(self, s: np.ndarray) -> np.ndarray:
        return self.p0 + s[:, None] * (self.p1 - self.p0)

    def distance(self, P: np.ndarray) -> np.ndarray:
        d = self.p1 - self.p0
        dd = float(d @ d)
        t = np.zeros(len(P)) if dd == 0.0 else np.clip((P - self.p0) @ d / dd, 0.0, 1.0)
        return np.linalg.norm(P - (self.p0 + t[:, None] * d), axis=1)


class _Arc(_Curve):
    kind = "arc"

    def __init__(self, centre, axis, p0, angle: float, R0, R1, mode: str) -> None:
        super().__init__(R0, R1, mode, turn=axis * angle)
        self.c, self.n, self.angle = centre, axis, float(angle)
        self.a = p0 - centre                      # the start's offset, turned about n
        self.h = float(self.a @ axis)             # its height along the axis
        self.r = float(np.linalg.norm(self.a - self.h * axis))
        self.length = abs(self.angle) * self.r

    def positions(self, s: np.ndarray) -> np.ndarray:
        return self.c + (_exp(np.outer(s * self.angle, self.n)) @ self.a)

    def distance(self, P: np.ndarray) -> np.ndarray:
        v = P - self.c
        h = v @ self.n
        radial = np.linalg.norm(v - h[:, None] * self.n, axis=1)
        return np.hypot(radial - self.r, h - self.h)


# ---- inputs --------------------------------------------------------------------------------------
def _vector(value, n: int, loc: tuple) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise FieldError(loc, f"{loc[-1]} must be a list of {n} numbers") from None
    if v.shape != (n,):
        raise FieldError(loc, f"{loc[-1]} must have {n} values, got shape {list(v.shape)}")
    if not np.all(np.isfinite(v)):
        raise FieldError(loc, f"{loc[-1]} must be finite")
    return v


def _positive(value, loc: tuple, lo: float = 0.0, hi: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, _NUMBER) \
            or not math.isfinite(value) or not lo < value <= hi:
        raise FieldError(loc, f"{loc[-1]} must be a number > {lo}"
                         + ("" if hi == math.inf else f" and <= {hi}"))
    return float(value)


def _target(value, loc: tuple) -> tuple[np.ndarray, np.ndarray | None]:
    """A pose ``(4, 4)`` or a point ``(3,)``: its position and rotation (None for a point)."""
    try:
        T = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise FieldError(loc, f"{loc[-1]} must be a 4x4 pose or a point (3 numbers)") from None
    if T.shape == (3,) and np.all(np.isfinite(T)):
        return T, None
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise FieldError(loc, f"{loc[-1]} must be a finite 4x4 pose or a point (3 numbers)")
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0 \
            or np.abs(T[3] - [0, 0, 0, 1]).max() > 1e-9:
        raise FieldError(loc, f"{loc[-1]}: the rotation part must be a rotation matrix and "
                         "the last row 0, 0, 0, 1")
    # Snap to the nearest rotation so that round-off in the input does not tilt the path.
    U, _, Vt = np.linalg.svd(R)
    return T[:3, 3].copy(), U @ Vt


@dataclass(frozen=True)
class _Options:
    max_step: float
    max_rotation: float
    jump_threshold: float
    tol_p: float
    tol_r: float
    resolution: float
    limit_avoidance: float


def _options(max_step, max_rotation, jump_threshold, position_tolerance,
             orientation_tolerance, resolution, limit_avoidance) -> _Options:
    return _Options(
        max_step=_positive(max_step, ("max_step",), hi=1e6),
        max_rotation=_positive(max_rotation, ("max_rotation",), hi=math.pi),
        jump_threshold=_positive(jump_threshold, ("jump_threshold",), hi=100.0),
        tol_p=_positive(position_tolerance, ("position_tolerance",), hi=1e3),
        tol_r=_positive(orientation_tolerance, ("orientation_tolerance",), hi=1.0),
        resolution=_positive(resolution, ("resolution",), lo=MIN_RESOLUTION * (1 - 1e-12),
                             hi=0.5),
        limit_avoidance=_fraction(limit_avoidance, ("limit_avoidance",)))


def _time_limit(value) -> float | None:
    return None if value is None else _positive(value, ("time_limit",), hi=MAX_TIME_LIMIT)


def _fraction(value, loc: tuple) -> float:
    if isinstance(value, bool) or not isinstance(value, _NUMBER) \
            or not 0.0 <= value <= 1.0:
        raise FieldError(loc, f"{loc[-1]} must be a number from 0 to 1")
    return float(value)


def _check_orientation(orientation: str, allowed: tuple[str, ...]) -> str:
    if orientation not in allowed:
        raise FieldError(("orientation",), f"orientation must be one of {', '.join(allowed)}")
    return orientation


def _start(checker: MotionChecker, model, q_start) -> tuple[Any, np.ndarray, np.ndarray]:
    if not isinstance(checker, MotionChecker):
        raise TypeError("checker must be a MotionChecker")
    model = checker.robot_model if model is None else model
    if int(model.dof) != checker.dof:
        raise FieldError(("model",), f"model has {model.dof} joints, the checker's robot "
                         f"{checker.dof}")
    q0 = _vector(q_start, checker.dof, ("start",))
    return model, q0, fk(model, q0)


# ---- public entry points -------------------------------------------------------------------------
def plan_line(checker: MotionChecker, q_start, target, *, orientation: str = "slerp",
              max_step: float = DEFAULT_MAX_STEP, max_rotation: float = DEFAULT_MAX_ROTATION,
              jump_threshold: float = DEFAULT_JUMP_THRESHOLD,
              position_tolerance: float = DEFAULT_POSITION_TOLERANCE,
              orientation_tolerance: float = DEFAULT_ORIENTATION_TOLERANCE,
              resolution: float = DEFAULT_RESOLUTION,
              limit_avoidance: float = DEFAULT_LIMIT_AVOIDANCE,
              time_limit: float | None = None, model=None) -> CartesianResult:
    """The tool along a straight line from its pose at ``q_start`` to ``target`` (a pose
    ``(4, 4)``, or a point ``(3,)`` whose orientation is the start's), the orientation
    interpolated (``slerp``) or held (``hold``); module docstring. ``checker``: the motion
    planner's checker (robot, scene, joint limits); ``model``: the kinematics (default the
    checker's robot model); ``limit_avoidance``: the null-space motion off the joint limits
    of arms with more than six joints (0 switches it off); ``time_limit`` (s, default none):
    past it the segment ends with ``timeout`` and what it reached. ``FieldError`` naming the
    argument for bad input."""
    t0 = time.perf_counter()
    _check_orientation(orientation, ORIENTATIONS[:2])
    opts = _options(max_step, max_rotation, jump_threshold, position_tolerance,
                    orientation_tolerance, resolution, limit_avoidance)
    limit = _time_limit(time_limit)
    model, q0, T0 = _start(checker, model, q_start)
    p1, R1 = _target(target, ("target",))
    R0 = T0[:3, :3]
    curve = _Line(T0[:3, 3].copy(), p1, R0, R0 if R1 is None else R1, orientation)
    return _follow(checker, model, q0, curve, opts, orientation, t0, limit)


def plan_arc(checker: MotionChecker, q_start, target=None, *, via=None, centre=None,
             axis=None, angle: float | None = None, orientation: str = "slerp",
             max_step: float = DEFAULT_MAX_STEP, max_rotation: float = DEFAULT_MAX_ROTATION,
             jump_threshold: float = DEFAULT_JUMP_THRESHOLD,
             position_tolerance: float = DEFAULT_POSITION_TOLERANCE,
             orientation_tolerance: float = DEFAULT_ORIENTATION_TOLERANCE,
             resolution: float = DEFAULT_RESOLUTION,
             limit_avoidance: float = DEFAULT_LIMIT_AVOIDANCE,
             time_limit: float | None = None, model=None) -> CartesianResult:
    """The tool along a circular arc from its pose at ``q_start``: either through the point
    ``via (3,)`` to ``target`` (a pose, or a point with the start's orientation; the circle
    through the three positions), or about the axis ``axis (3,)`` through ``centre (3,)`` by
    ``angle`` rad (right hand; no ``target``). Orientation: ``slerp`` to the target's (the
    start's when there is no target pose), ``hold`` the start's, or ``rotate`` with the arc
    (the tool turns about the arc's axis as far as the arc does). Otherwise as ``plan_line``;
    ``fraction`` is by arc length."""
    t0 = time.perf_counter()
    _check_orientation(orientation, ORIENTATIONS)
    opts = _options(max_step, max_rotation, jump_threshold, position_tolerance,
                    orientation_tolerance, resolution, limit_avoidance)
    limit = _time_limit(time_limit)
    model, q0, T0 = _start(checker, model, q_start)
    p0, R0 = T0[:3, 3].copy(), T0[:3, :3]
    if via is not None:
        if centre is not None or axis is not None or angle is not None:
            raise FieldError(("via",), "give via and target, or centre, axis and angle")
        if target is None:
            raise FieldError(("target",), "target is required with via")
        pv = _vector(via, 3, ("via",))
        p1, R1 = _target(target, ("target",))
        c, n, ang = _circle(p0, pv, p1)
    else:
        if centre is None or axis is None or angle is None:
            raise FieldError(("via",), "give via and target, or centre, axis and angle")
        if target is not None:
            raise FieldError(("target",), "an arc about a centre ends where its angle does: "
                             "leave target out")
        c = _vector(centre, 3, ("centre",))
        n = _vector(axis, 3, ("axis",))
        if np.linalg.norm(n) < 1e-9:
            raise FieldError(("axis",), "axis must be a non-zero vector")
        n = n / np.linalg.norm(n)
        if isinstance(angle, bool) or not isinstance(angle, _NUMBER) \
                or not math.isfinite(angle) or abs(angle) > 2 * math.pi:
            raise FieldError(("angle",), "angle must be a number in [-2 pi, 2 pi] (rad)")
        ang = float(angle)
        a = p0 - c
        if np.linalg.norm(a - (a @ n) * n) < 1e-6:
            raise FieldError(("centre",), "the tool starts on the arc's axis: no arc to follow")
        R1 = None
    curve = _Arc(c, n, p0, ang, R0, R0 if R1 is None else R1, orientation)
    return _follow(checker, model, q0, curve, opts, orientation, t0, limit)


def _circle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre, unit normal and angle (rad, in (0, 2 pi)) of the arc from ``a`` through ``b``
    to ``c``, turning right-handed about the normal."""
    u, v = b - a, c - a
    n = np.cross(u, v)
    nn = float(n @ n)
    scale = max(float(np.linalg.norm(u)), float(np.linalg.norm(v)), 1e-12)
    if nn <= (1e-6 * scale * scale) ** 2 or min(np.linalg.norm(u), np.linalg.norm(v),
                                                  np.linalg.norm(c - b)) < 1e-6:
        raise FieldError(("via",), "the start, via and target positions must be distinct and "
                         "not on one line (use plan_line for a line)")
    centre = a + (np.cross(n, u) * float(v @ v) + np.cross(v, n) * float(u @ u)) / (2 * nn)
    n = n / math.sqrt(nn)
    e1 = (a - centre) / np.linalg.norm(a - centre)
    e2 = np.cross(n, e1)
    d = c - centre
    ang = math.atan2(float(d @ e2), float(d @ e1)) % (2 * math.pi)
    return centre, n, ang


# ---- following the curve -------------------------------------------------------------------------
class _Solver:
    """Damped least squares to one pose from a nearby configuration, with joint limits."""

    def __init__(self, model, lower: np.ndarray, upper: np.ndarray, weights: np.ndarray,
                 opts: _Options) -> None:
        self.model = model
        self.weights = weights
        self.lower, self.upper = lower, upper
        self.opts = opts
        #: Orientation rows are weighted so that the two tolerances count alike.
        self.rho = opts.tol_p / opts.tol_r
        self.dof = int(model.dof)
        self.redundant = self.dof > 6
        finite = np.isfinite(lower) & np.isfinite(upper)
        self.mid = np.where(finite, 0.5 * (lower + upper), 0.0)
        self.half = np.where(finite, 0.5 * (upper - lower), np.inf)
        self.iterations = 0
        self._eye = np.eye(self.dof)
        #: The most a joint moves in one null-space step (rad, mm).
        self.null_cap = 0.25 * opts.jump_threshold / np.asarray(weights, dtype=float)
        prismatic = np.asarray(weights, dtype=float) < 1.0
        self.null_cap[prismatic] = np.minimum(self.null_cap[prismatic], 0.5 * opts.max_step)

    def _error(self, q: np.ndarray, T_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                  float, float]:
        J, T = jacobian_and_pose(self.model, q)
        e = np.empty(6)
        e[:3] = T_goal[:3, 3] - T[:3, 3]
        e[3:] = _log(T_goal[:3, :3] @ T[:3, :3].T)
        return J, e, math.sqrt(float(e[:3] @ e[:3])), math.sqrt(float(e[3:] @ e[3:]))

    def null_step(self, q: np.ndarray) -> np.ndarray:
        """A motion of ``q`` in the Jacobian's null space away from the joint limits (arms
        with more than six joints; zero otherwise)."""
        gain = self.opts.limit_avoidance
        if not self.redundant or gain == 0.0:
            return q
        bounded = np.isfinite(self.half)
        with np.errstate(invalid="ignore"):
            g = np.where(bounded, (q - self.mid) / self.half, 0.0)
        z = -gain * np.where(bounded, self.half, 0.0) * g ** 3
        if not np.any(z):
            return q
        J, _ = jacobian_and_pose(self.model, np.ascontiguousarray(q))
        J[3:] *= self.rho
        dq = z - np.linalg.pinv(J, rcond=1e-9) @ (J @ z)
        # Never more than a quarter of the jump threshold on any joint, nor half a step's
        # length on a prismatic one (a telescope beside a parallel feed would otherwise
        # trade tens of mm with it in every step); scaled as a whole, it stays in the null
        # space.
        worst = float(np.max(np.abs(dq) / self.null_cap))
        if worst > 1.0:
            dq /= worst
        return np.clip(q + dq, self.lower, self.upper)

    def solve(self, q: np.ndarray, T_goal: np.ndarray, limits: bool
              ) -> tuple[np.ndarray, bool, float, float]:
        """``(q, converged, position error, orientation error)`` from ``q`` towards
        ``T_goal``, within the joint limits when ``limits`` (active joints at a limit are
        held there)."""
        o = self.opts
        lo, hi = self.lower, self.upper
        # Within the limits from the first state on (the best state may be the first).
        q = np.clip(np.array(q, dtype=float), lo, hi) if limits else np.array(q, dtype=float)
        best = (q.copy(), math.inf, math.inf)
        ep = er = math.inf
        last = math.inf
        for _ in range(MAX_ITERATIONS):
            self.iterations += 1
            J, e, ep, er = self._error(q, T_goal)
            err = ep / o.tol_p + er / o.tol_r
            if err < best[1] / o.tol_p + best[2] / o.tol_r:
                best = (q.copy(), ep, er)
            # Done far within the tolerances, or within them and no longer converging fast
            # (near a singular configuration the last digits come slowly).
            if err <= 2e-3 or (ep <= o.tol_p and er <= o.tol_r and err > 0.5 * last):
                break
            last = err
            J[3:] *= self.rho
            e[3:] *= self.rho
            # Levenberg-Marquardt damping that vanishes with the error (Sugihara 2011), plus
            # a small bias that keeps the system regular at a singular configuration.
            A = J.T @ J
            lam = 0.5 * float(e @ e) + 1e-9 * float(np.trace(A)) / self.dof
            g = J.T @ e
            dq = np.linalg.solve(A + lam * self._eye, g)
            if limits:
                stuck = ((q <= lo + 1e-12) & (dq < 0)) | ((q >= hi - 1e-12) & (dq > 0))
                if stuck.any():
                    free = ~stuck
                    dq = np.zeros(self.dof)
                    Af = A[np.ix_(free, free)]
                    dq[free] = np.linalg.solve(Af + lam * np.eye(int(free.sum())), g[free])
                q = np.clip(q + dq, lo, hi)
            else:
                q = q + dq
            if float(np.abs(dq).max()) < 1e-14:
                break
        q, ep, er = best
        return q, (ep <= o.tol_p and er <= o.tol_r), ep, er


def _follow(checker: MotionChecker, model, q0: np.ndarray, curve: _Curve, opts: _Options,
            orientation: str, t0: float, time_limit: float | None) -> CartesianResult:
    """Follow ``curve`` from ``q0`` (module docstring), the checker's deadline set to the
    time limit for the segment checks (and restored after)."""
    saved = checker.deadline
    checker.deadline = None if time_limit is None else t0 + time_limit
    try:
        return _run(checker, model, q0, curve, opts, orientation, t0, time_limit)
    finally:
        checker.deadline = saved


def _run(checker: MotionChecker, model, q0: np.ndarray, curve: _Curve, opts: _Options,
         orientation: str, t0: float, time_limit: float | None) -> CartesianResult:
    deadline = checker.deadline
    dof = checker.dof
    names = [j.name for j in model.joints]
    n = max(1, math.ceil(curve.length / opts.max_step - 1e-9),
            math.ceil(curve.rotation / opts.max_rotation - 1e-9))
    if n > MAX_STEPS:
        raise FieldError(("max_step",), f"the segment needs {n} steps, more than {MAX_STEPS}: "
                         "take larger steps")
    s_all = np.arange(n + 1) / n
    goals = curve.poses(s_all)
    solver = _Solver(model, checker.lower, checker.upper, checker.weights, opts)
    thresholds = opts.jump_threshold / checker.weights   # rad, and mm on prismatic joints
    base = dict(length=curve.length, rotation=curve.rotation, steps=n, kind=curve.kind,
                orientation=orientation)

    def answer(status: CartesianStatus, message: str, Q: list, S: list,
               pairs: tuple = ()) -> CartesianResult:
        P = np.array(Q, dtype=float).reshape(-1, dof)
        s = np.array(S, dtype=float)
        T = fk(model, P) if len(P) else np.empty((0, 4, 4))
        if len(P):
            ideal = curve.poses(s)
            pe = float(np.linalg.norm(T[:, :3, 3] - ideal[:, :3, 3], axis=1).max())
            oe = float(_angles(T[:, :3, :3], ideal[:, :3, :3]).max())
        else:
            pe = oe = 0.0
        dev = 0.0
        if len(P) > 1:
            w = np.arange(1, _DEVIATION_SAMPLES + 1) / (_DEVIATION_SAMPLES + 1)
            M = (P[:-1, None] + w[None, :, None] * (P[1:] - P[:-1])[:, None]).reshape(-1, dof)
            dev = float(curve.distance(fk(model, M)[:, :3, 3]).max())
        for a in (P, T, s):
            a.setflags(write=False)
        frac = float(s[-1]) if len(s) else 0.0
        return CartesianResult(status, message, frac, P, T, s, pe, oe, dev, pairs=pairs,
                               planning_time_s=time.perf_counter() - t0,
                               stats={"iterations": solver.iterations,
                                      "checks": checker.checks}, **base)

    bad = np.flatnonzero((q0 < checker.lower - 1e-9) | (q0 > checker.upper + 1e-9))
    if len(bad):
        i = int(bad[0])
        return answer(CartesianStatus.OUT_OF_LIMITS,
                      f"the start is out of limits: joint '{names[i]}' = {q0[i]:.6g}, limits "
                      f"[{checker.lower[i]:.6g}, {checker.upper[i]:.6g}]", [], [])
    if not checker.free(q0):
        pairs = tuple(checker.pairs(q0))
        return answer(CartesianStatus.COLLISION,
                      f"the start is in collision: {_pairs_text(pairs)}", [], [], pairs)
    Q, S = [q0], [0.0]
    q = q0

    def late(k: int) -> CartesianResult:
        return answer(CartesianStatus.TIMEOUT,
                      f"the time limit ({time_limit:g} s) ran out at step {k} of {n}", Q, S)

    for k in range(1, n + 1):
        if deadline is not None and time.perf_counter() >= deadline:
            return late(k)
        where = f"at {100 * s_all[k]:.1f} % of the {curve.kind} (step {k} of {n})"
        # Started from the previous step's motion continued (a secant predictor: the solve
        # then converges in an iteration or two), moved in the null space off the limits.
        guess = q if len(Q) < 2 else np.clip(2.0 * q - Q[-2], checker.lower, checker.upper)
        start = solver.null_step(guess)
        q_new, ok, ep, er = solver.solve(start, goals[k], limits=True)
        if not ok and start is not q:     # the prediction may have led astray
            q_new, ok, ep, er = solver.solve(q, goals[k], limits=True)
        if not ok:
            q_free, ok_free, _, _ = solver.solve(q, goals[k], limits=False)
            out = np.flatnonzero((q_free < checker.lower - 1e-9)
                                 | (q_free > checker.upper + 1e-9))
            if ok_free and len(out):
                i = int(out[0])
                return answer(CartesianStatus.OUT_OF_LIMITS,
                              f"the {curve.kind} leaves the joint limits {where}: joint "
                              f"'{names[i]}' would be {q_free[i]:.6g}, limits "
                              f"[{checker.lower[i]:.6g}, {checker.upper[i]:.6g}]", Q, S)
            return answer(CartesianStatus.UNREACHABLE,
                          f"the pose {where} is not reached from the previous step: "
                          f"{ep:.3g} mm and {er:.3g} rad off (tolerances {opts.tol_p:g} mm, "
                          f"{opts.tol_r:g} rad)", Q, S)
        jump = np.abs(q_new - q)
        over = np.flatnonzero(jump > thresholds)
        if len(over):
            i = int(over[np.argmax((jump * checker.weights)[over])])
            unit = "mm" if checker.prismatic[i] else "rad"
            return answer(CartesianStatus.DISCONTINUOUS,
                          f"the joint path jumps {where}: joint '{names[i]}' moves "
                          f"{jump[i]:.4g} {unit} in one step (threshold {thresholds[i]:.4g} "
                          f"{unit})", Q, S)
        if not checker.free(q_new):
            pairs = tuple(checker.pairs(q_new))
            return answer(CartesianStatus.COLLISION,
                          f"the {curve.kind} collides {where}: {_pairs_text(pairs)}", Q, S,
                          pairs)
        if not checker.segment_free(q, q_new, opts.resolution):
            if checker.late():
                return late(k)
            pairs = _segment_pairs(checker, q, q_new, opts.resolution)
            return answer(CartesianStatus.COLLISION,
                          f"the motion to the step {where} collides: {_pairs_text(pairs)}",
                          Q, S, pairs)
        Q.append(q_new)
        S.append(float(s_all[k]))
        q = q_new
    return answer(CartesianStatus.OK, "ok", Q, S)


def _segment_pairs(checker: MotionChecker, a: np.ndarray, b: np.ndarray,
                   resolution: float) -> tuple:
    """The colliding pairs of the first colliding state of the segment ``a``-``b`` at
    ``resolution`` (empty if the states checked here are all free)."""
    n = checker.steps(a, b, resolution)
    states = a + (b - a) * (np.arange(1, n) / n)[:, None]
    if not len(states):
        return ()
    bad = np.flatnonzero(~np.atleast_1d(checker.free(states)))
    return tuple(checker.pairs(states[bad[0]])) if len(bad) else ()


def _pairs_text(pairs) -> str:
    return ", ".join(f"{a} - {b}" for a, b in list(pairs)[:4]) + \
        (" ..." if len(pairs) > 4 else "")
