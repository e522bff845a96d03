"""Obstacle-avoiding paths for a robot's tool, checked for reach and whole-arm clearance
(paper 000, section 4.5: plan the tool path, solve IK along it, convert to cylinder lengths).

Pipeline of ``plan_arm_path``:

1. Both endpoints must be reachable: position IK (the path fixes where the tool point goes,
   not how it is turned) from a seeded table of in-limit configurations. An unreachable
   endpoint is a clear failure naming why (e.g. the paper's goal [1800, 1800, 800] mm lies
   2669 mm from pile_driver's base, beyond its ~1916 mm reach).
2. The tool path is planned among the obstacles with ``paths.plan_path``.
3. The path is sampled densely (``spacing`` mm) and each sample solved by damped least
   squares on the position, starting from the previous sample's joints and projected onto
   the joint limits, so the arm stays on one branch and within its limits. A sample the
   tool cannot reach is a failure naming where.
   The tool path keeps the largest link radius (the last links end at the tool point) and a
   small slack on top of the safety margin.
4. Whole-arm clearance at every sample: each link is a capsule between consecutive
   ``fk_frames`` origins with a radius per link (default 60 mm), and must keep the scene's
   safety margin from every obstacle.
5. A quintic B-spline joint trajectory (``bspline.quintic_bspline``) through joint waypoints
   taken every ``waypoint_spacing`` mm of tool path, timed by arc length over ``duration``
   s, at rest at both ends; it is re-checked (limits, whole-arm clearance) on a fine grid.
6. For robots with cylinders (pile_driver) the cylinder lengths along the path and whether
   they stay within stroke.

Lengths in mm, angles in rad, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from kinematics.cylinders import CylinderError, CylinderSet
from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.jacobian import jacobian_and_pose
from kinematics.model import RobotModel

from .bspline import quintic_bspline
from .optimisers.base import ProgressFn
from .paths import PathResult, plan_path
from .scene import Capsule, Scene
from .status import PlanStatus
from .trajectory import Trajectory

__all__ = ["ArmPathResult", "plan_arm_path", "position_ik", "link_capsules",
           "arm_clearance", "reach"]

#: Default link radius (mm) of the capsules around each link.
DEFAULT_LINK_RADIUS = 60.0
#: Largest tool position error (mm) accepted as reaching a point.
REACH_TOL = 1e-2
#: Fraction of each joint range kept clear of the limits by the IK along a path, so that the
#: spline through the joint waypoints, which can overshoot a waypoint slightly where a joint
#: rides its stop, stays within the limits.
LIMIT_INSET = 0.005
#: Null-space gain towards mid-range while following the path (per IK iteration).
CENTRING = 0.02
#: Configurations in the seeded table that starts the endpoint IK.
SEED_TABLE = 4096


@dataclass(frozen=True)
class ArmPathResult:
    """An arm path. ``tool`` is the planned tool path; ``points (S, 3)`` its dense samples at
    arc lengths ``s (S,)`` mm; ``q (S, dof)`` the joints there; ``trajectory`` the joint
    B-spline (None on failure before it); ``cylinders`` lengths (mm) by name ``(S,)`` for
    robots that have cylinders. ``arm_min_clearance``: least clearance (mm) of any link
    capsule to any obstacle over the samples. ``status``: ``ok``; the tool path's own
    failure; ``unreachable`` (an endpoint or a sample of the path out of reach);
    ``collision`` (a link hits an obstacle, at a sample or along the joint trajectory);
    ``out_of_limits`` (the joint trajectory leaves the joint limits or a cylinder its
    stroke)."""

    tool: PathResult
    points: np.ndarray
    s: np.ndarray
    q: np.ndarray
    trajectory: Trajectory | None
    cylinders: dict[str, np.ndarray] | None
    cylinders_within_stroke: bool | None
    arm_min_clearance: float
    status: PlanStatus
    message: str
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK

    def to_dict(self, dt: float | None = None) -> dict[str, Any]:
        """JSON-ready dict: the tool path's fields plus ``joint_path``, ``trajectory``
        (sampled every ``dt`` s, default duration/200) and ``cylinders``."""
        out = self.tool.to_dict()
        out.update(success=self.success, status=self.status.value, message=self.message,
                   arm_min_clearance=_num(self.arm_min_clearance),
                   joint_path=self.q.tolist(), tool_samples=self.points.tolist())
        if self.trajectory is not None:
            step = dt or self.trajectory.duration / 200
            smp = self.trajectory.sample(step)
            out["trajectory"] = {"t": smp.t.tolist(), "q": smp.q.tolist(),
                                 "qd": smp.qd.tolist(), "qdd": smp.qdd.tolist(),
                                 "waypoints": self.extra.get("waypoints", [])}
        else:
            out["trajectory"] = None
        if self.cylinders is not None:
            out["cylinders"] = {"lengths": {k: v.tolist() for k, v in self.cylinders.items()},
                                "within_stroke": self.cylinders_within_stroke}
        else:
            out["cylinders"] = None
        return out


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


# ---- position IK ---------------------------------------------------------------------------
def _dls(model: RobotModel, Q: np.ndarray, target: np.ndarray, iterations: int,
         tol: float, centring: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares on the tool position for a batch ``Q (B, dof)`` towards
    ``target (3,)`` or ``(B, 3)``, projected onto the joint limits less ``LIMIT_INSET``.

    ``centring`` > 0 adds a null-space step (on the first iteration) of that gain towards
    mid-range (arms with more than 3 joints have freedom left over; using it keeps joints
    off their stops). Returns ``(Q, error mm)``."""
    lam2 = (1e-3 * model.length_scale) ** 2
    mid, span = model.mid_configuration(), model.upper - model.lower
    span = np.where(np.isfinite(span) & (span > 0), span, 1.0)
    lower, upper = model.lower + LIMIT_INSET * span, model.upper - LIMIT_INSET * span
    Q = np.array(Q, dtype=float)
    err = np.full(len(Q), np.inf)
    for it in range(iterations):
        J, T = jacobian_and_pose(model, Q)
        e = target - T[:, :3, 3]
        err = np.linalg.norm(e, axis=1)
        if np.all(err < tol) and (centring == 0 or it > 0):
            break
        Jp = J[:, :3, :]
        A = Jp @ np.swapaxes(Jp, 1, 2) + lam2 * np.eye(3)
        Jpinv = np.swapaxes(Jp, 1, 2) @ np.linalg.inv(A)  # (B, dof, 3)
        dq = np.einsum("bij,bj->bi", Jpinv, e)
        if centring and it == 0:  # one centring step, then converge on the position
            g = centring * (mid - Q) / span * span.min()
            dq += g - np.einsum("bij,bjk,bk->bi", Jpinv, Jp, g)
        Q = np.clip(Q + dq, lower, upper)
    else:
        err = np.linalg.norm(target - fk(model, Q)[:, :3, 3], axis=1)
    return Q, err


@lru_cache(maxsize=16)
def _table(model: RobotModel, size: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = rng.uniform(model.lower, model.upper, size=(size, model.dof))
    # Joints that do not move the tool point start mid-range rather than anywhere.
    q0 = np.tile(model.mid_configuration(), (1, 1))
    J = jacobian_and_pose(model, q0)[0][0, :3]
    idle = np.all(np.abs(J) < 1e-9, axis=0)
    q[:, idle] = model.mid_configuration()[idle]
    return q, fk(model, q)[:, :3, 3]


def reach(model: RobotModel) -> float:
    """Largest distance (mm) of the tool point from the base origin over a seeded sample of
    in-limit configurations: the arm's reach, to within the sampling."""
    return float(np.max(np.linalg.norm(_table(model, SEED_TABLE, 0)[1] - model.base[:3, 3],
                                       axis=1)))


def position_ik(model: RobotModel, point, q0=None, starts: int = 16,
                iterations: int = 100) -> tuple[np.ndarray | None, float]:
    """Joints ``(dof,)`` within limits that put the tool point at ``point (3,)`` mm, or None;
    also the least position error (mm) found. Starts from ``q0`` (if given) and the
    ``starts`` table configurations nearest the point; returns the solution closest to
    ``q0`` (or to mid-range)."""
    point = np.asarray(point, dtype=float)
    Qt, Pt = _table(model, SEED_TABLE, 0)
    near = np.argsort(np.linalg.norm(Pt - point, axis=1))[:starts]
    Q = Qt[near]
    if q0 is not None:
        Q = np.vstack([np.clip(q0, model.lower, model.upper), Q])
    Q, err = _dls(model, Q, point, iterations, REACH_TOL / 10)
    ok = err < REACH_TOL
    if not ok.any():
        return None, float(err.min())
    ref = model.mid_configuration() if q0 is None else np.asarray(q0, float)
    cand = Q[ok]
    return cand[np.argmin(np.linalg.norm(cand - ref, axis=1))], float(err[ok].min())


# ---- whole-arm clearance ----------------------------------------------------------------
def link_capsules(model: RobotModel, q) -> tuple[np.ndarray, np.ndarray]:
    """Link segments of configurations ``q (N, dof)``: ``(A, B)`` each ``(N, dof, 3)``,
    between consecutive ``fk_frames`` origins (base, after each joint, tool)."""
    F = fk_frames(model, np.atleast_2d(q))[..., :3, 3]  # (N, dof+1, 3)
    return F[:, :-1], F[:, 1:]


def _radii(model: RobotModel, link_radius) -> np.ndarray:
    r = np.broadcast_to(np.asarray(link_radius, dtype=float), (model.dof,)).copy() \
        if np.ndim(link_radius) == 0 else np.asarray(link_radius, dtype=float)
    if r.shape != (model.dof,):
        raise FieldError("link_radius", f"link_radius must be one number or {model.dof} numbers")
    if not np.all(np.isfinite(r)) or np.any(r < 0):
        raise FieldError("link_radius", "link_radius must be finite and non-negative")
    return r


def arm_clearance(model: RobotModel, scene: Scene, q, link_radius=DEFAULT_LINK_RADIUS
                  ) -> np.ndarray:
    """Clearance (mm) of each link capsule to each obstacle: ``q (N, dof) ->
    (N, dof, n_obstacles)`` (negative = overlap)."""
    r = _radii(model, link_radius)
    A, B = link_capsules(model, q)
    N = len(A)
    c = scene.segment_clearance(A.reshape(-1, 3), B.reshape(-1, 3))
    return c.reshape(N, model.dof, -1) - r[None, :, None]


# ---- the pipeline -----------------------------------------------------------------------
def _resample(path: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(S, 3)`` along a polyline at most ``spacing`` apart (every vertex kept) and
    their arc lengths ``(S,)``."""
    pts, s = [path[:1]], [np.zeros(1)]
    cum = 0.0
    for a, b in zip(path[:-1], path[1:]):
        L = float(np.linalg.norm(b - a))
        m = max(1, math.ceil(L / spacing))
        f = np.arange(1, m + 1) / m
        pts.append(a + f[:, None] * (b - a))
        s.append(cum + f * L)
        cum += L
    return np.vstack(pts), np.concatenate(s)


def _fail(tool: PathResult, status: PlanStatus, message: str, **kw) -> ArmPathResult:
    empty = np.empty((0, 3))
    base = dict(points=empty, s=np.empty(0), q=np.empty((0, 0)), trajectory=None,
                cylinders=None, cylinders_within_stroke=None, arm_min_clearance=math.nan)
    base.update(kw)
    return ArmPathResult(tool=tool, status=status, message=message, **base)


def _unreachable(model: RobotModel, name: str, point: np.ndarray, err: float) -> str:
    d = float(np.linalg.norm(point - model.base[:3, 3]))
    R = reach(model)
    where = f"{name} {np.round(point, 3).tolist()} mm is unreachable for {model.id}: "
    if d > R:
        return where + (f"it lies {d:.0f} mm from the base, beyond the arm's reach of about "
                        f"{R:.0f} mm")
    return where + (f"no configuration within the joint limits puts the tool there (the "
                    f"closest found is {err:.1f} mm away)")


def _link_name(model: RobotModel, k: int) -> str:
    return f"link {k} (after joint '{model.joints[k].name}')" if k > 0 else "link 0 (base)"


def plan_arm_path(
    model: RobotModel,
    scene: Scene,
    start,
    goal,
    algorithm: str = "auto",
    seed: int = 0,
    params: dict[str, Any] | None = None,
    progress: ProgressFn | None = None,
    *,
    link_radius=DEFAULT_LINK_RADIUS,
    spacing: float = 10.0,
    waypoint_spacing: float = 25.0,
    clearance_slack: float = 5.0,
    duration: float = 10.0,
    q_start=None,
    keep_out_radius: float | None = None,
) -> ArmPathResult:
    """Plan the tool of ``model`` from ``start`` to ``goal`` (mm, world frame) in ``scene``.

    ``link_radius``: mm, one number or one per link (``dof``); ``spacing``: mm between IK
    samples; ``waypoint_spacing``: mm of tool path between trajectory waypoints;
    ``duration``: s of the joint trajectory; ``clearance_slack``: mm the tool path keeps
    on top of margin and link radius; ``q_start``: joints to start from (default:
    position IK); ``keep_out_radius``: mm, keeps the tool path that far from the base's z
    axis (``base_keep_out``; the arm itself is checked against the scene only). Invalid
    input raises ``FieldError`` naming the field; unreachable endpoints, a tool path the arm
    cannot follow and arm collisions give a failed ``status``.
    """
    if not (isinstance(clearance_slack, int | float) and clearance_slack >= 0):
        raise FieldError("clearance_slack", "clearance_slack must be a non-negative number")
    for name, value in (("spacing", spacing), ("waypoint_spacing", waypoint_spacing),
                        ("duration", duration)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise FieldError(name, f"{name} must be a positive number")
    radii = _radii(model, link_radius)
    start = scene.check_endpoint(start, "start")
    goal = scene.check_endpoint(goal, "goal")
    report = progress or (lambda f: None)
    nothing = PathResult(np.empty((0, 3)), math.inf, math.nan, 0.0, np.empty(0), algorithm,
                         0, PlanStatus.UNREACHABLE, "not planned")
    if q_start is not None:
        q_start = np.asarray(q_start, dtype=float)
        if q_start.shape != (model.dof,) or not np.all(np.isfinite(q_start)):
            raise FieldError("q_start", f"q_start must be {model.dof} finite numbers")
        if not model.within_limits(q_start):
            raise FieldError("q_start", "q_start is outside the joint limits: "
                             + ", ".join(model.limit_violations(q_start)))
        if np.linalg.norm(fk(model, q_start)[:3, 3] - start) > REACH_TOL:
            raise FieldError("q_start", "q_start does not put the tool at start")
        q0 = q_start
    else:
        q0, err = position_ik(model, start)
        if q0 is None:
            return _fail(nothing, PlanStatus.UNREACHABLE,
                         _unreachable(model, "start", start, err))
    q_goal, err = position_ik(model, goal)
    if q_goal is None:
        return _fail(nothing, PlanStatus.UNREACHABLE, _unreachable(model, "goal", goal, err))
    report(0.05)

    # The tool point carries the end of the last links: its path keeps their radius (the
    # largest link radius) on top of the safety margin, plus ``clearance_slack`` for the
    # joint spline's small departures from the path between waypoints.
    tool_scene = Scene(scene.lower, scene.upper, scene.obstacles,
                       scene.safety_margin + float(radii.max()) + clearance_slack)
    if keep_out_radius is not None:
        if not (math.isfinite(keep_out_radius) and keep_out_radius > 0):
            raise FieldError("keep_out_radius", "keep_out_radius must be a positive number")
        tool_scene = tool_scene.with_obstacles([base_keep_out(model, keep_out_radius)])
    tool_scene.check_endpoint(start, "start")
    tool_scene.check_endpoint(goal, "goal")
    tool = plan_path(tool_scene, start, goal, algorithm, seed, params,
                     progress=lambda f: report(0.05 + 0.6 * f))
    if not tool.success:
        return _fail(tool, tool.status, tool.message)
    points, s = _resample(tool.path, spacing)
    Q = np.empty((len(points), model.dof))
    q = q0
    for i, p in enumerate(points):
        qn, e = _dls(model, q[None], p, 50, REACH_TOL / 10, centring=CENTRING)
        if e[0] > REACH_TOL:
            return _fail(tool, PlanStatus.UNREACHABLE,
                         f"the tool path leaves the arm's reach at {s[i]:.0f} mm along "
                               f"it, {np.round(p, 1).tolist()} mm (closest reachable "
                               f"{e[0]:.1f} mm away)", points=points[:i], s=s[:i], q=Q[:i])
        q = qn[0]
        Q[i] = q
    report(0.8)
    C = arm_clearance(model, scene, Q, radii) if scene.obstacles else \
        np.full((len(Q), model.dof, 1), np.inf)
    arm_min = float(C.min())
    if arm_min < scene.safety_margin:
        i, k, j = np.unravel_index(int(np.argmin(C)), C.shape)
        return _fail(tool, PlanStatus.COLLISION,
                     f"the arm hits an obstacle: {_link_name(model, int(k))} comes "
                           f"{C[i, k, j]:.1f} mm from obstacles[{j}] (needs "
                           f"{scene.safety_margin} mm) at {s[i]:.0f} mm along the tool path",
                     points=points, s=s, q=Q, arm_min_clearance=arm_min)
    # Joint trajectory: waypoints every ``waypoint_spacing`` mm, timed by arc length.
    n_wp = max(1, math.ceil(s[-1] / waypoint_spacing)) if s[-1] > 0 else 1
    idx = np.unique(np.searchsorted(s, np.linspace(0, s[-1], n_wp + 1)))
    idx[-1] = len(s) - 1
    idx = np.unique(idx)
    if len(idx) < 2:
        idx = np.array([0, len(s) - 1])
    durations = np.diff(s[idx]) / max(s[-1], 1e-12) * duration
    if np.any(durations <= 0):
        durations = np.full(len(idx) - 1, duration / (len(idx) - 1))
    traj = quintic_bspline(Q[idx], durations)
    t_check = np.linspace(0.0, traj.duration, max(200, 2 * len(s)))
    Qt = traj.evaluate(t_check)
    limits_ok = bool(np.all(model.within_limits(Qt, tol=1e-6)))
    Ct = arm_clearance(model, scene, Qt, radii).min() if scene.obstacles else math.inf
    tool_dev = _deviation(fk(model, Qt)[:, :3, 3], tool.path)
    cyl, cyl_ok = None, None
    try:
        cs = CylinderSet.from_model(model)
    except CylinderError:
        cs = None
    if cs is not None:
        cyl = cs.lengths(Q)
        ok_t = cs.within_stroke(cs.lengths(Qt), tol=1e-6)
        cyl_ok = bool(all(np.all(v) for v in cs.within_stroke(cyl).values())
                      and all(np.all(v) for v in ok_t.values()))
    report(1.0)
    extra = {"waypoints": Q[idx].tolist(), "trajectory_min_clearance": float(Ct),
             "trajectory_within_limits": limits_ok, "trajectory_tool_deviation": tool_dev,
             "q_goal_ik": q_goal.tolist()}
    problems: list[tuple[PlanStatus, str]] = []
    if not limits_ok:
        problems.append((PlanStatus.OUT_OF_LIMITS,
                         "the joint trajectory leaves the joint limits between waypoints"))
    if Ct < scene.safety_margin:
        problems.append((PlanStatus.COLLISION,
                         f"the joint trajectory brings the arm {Ct:.1f} mm from an obstacle "
                         "between waypoints (try a smaller waypoint_spacing)"))
    if cyl_ok is False:
        problems.append((PlanStatus.OUT_OF_LIMITS, "a cylinder leaves its stroke"))
    return ArmPathResult(
        tool=tool, points=points, s=s, q=Q, trajectory=traj, cylinders=cyl,
        cylinders_within_stroke=cyl_ok, arm_min_clearance=arm_min,
        status=problems[0][0] if problems else PlanStatus.OK,
        message="; ".join(why for _, why in problems) if problems else
        "clear tool path, reachable at every sample, whole arm clear", extra=extra)


def _deviation(points: np.ndarray, path: np.ndarray) -> float:
    """Largest distance (mm) from ``points (M, 3)`` to the polyline ``path (n, 3)``."""
    from .scene import segment_point_distance

    d, _ = segment_point_distance(path[None, :-1], path[None, 1:], points[:, None, :])
    return float(d.min(axis=1).max())


def base_keep_out(model: RobotModel, radius: float, height: float | None = None) -> Capsule:
    """A vertical capsule of ``radius`` mm on the base z axis (``height`` mm up and down,
    default twice the reach): an obstacle for the *tool* that keeps its path out of the
    hollow near the base axis that an arm like pile_driver cannot reach."""
    h = 2 * reach(model) if height is None else height
    o = model.base[:3, 3]
    z = model.base[:3, 2]
    return Capsule(o - h * z, o + h * z, radius)
