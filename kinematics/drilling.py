"""Drilling IK for the tunnel drilling arm (paper 002): put the drill tip on a hole of the
tunnel face with the drill perpendicular to the face.

The face normal is the tunnel axis, the x axis of the arm's base frame (the paper's initial
pose has the drill axis, tool z, along base [1, 0, 0]). The feed joint is held at ``d7``
(paper: 4022 mm) and the roll joint at ``roll``.

The compensation rule (paper 002, Table 3): ``theta5 = -theta2`` and
``theta6 = 90 deg - theta1``, on the D-H angles. Table 3 obeys it as printed
(-(-134.67) = 134.67, 90 - (-46.77) = 136.77), and with ``theta4 = 0`` it keeps the whole
tool orientation fixed at the initial pose's ``[[0, 0, 1], [1, 0, 0], [0, 1, 0]]`` for every
swing and pitch, so the drill stays perpendicular to the face. The tip then lies at::

    p = c + RotZ(theta1) (A + a2 cos(theta2) - d3 sin(theta2), D, -a2 sin(theta2) - d3 cos(theta2))

with ``c = (a0 + d7, a6, d1 + d6)``, ``A = a1 + a5``, ``D = d2 + d5`` (plus the tool
translation, rotated): the horizontal distance from the swing axis gives theta1, the
remaining vertical-plane problem gives d3 and theta2, both in closed form. With ``roll != 0``
the rule no longer keeps the drill perpendicular; theta5 and theta6 are then solved together
with theta1, theta2, d3 by a batched Gauss-Newton iteration started from the roll-0 answer
and continued in roll.

Frames and units (docs/conventions.md): holes in the world frame, in which ``fk`` reports
``T_world_tool``, mm; the face normal is the base frame's x axis; joint values rad / mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import FieldError
from .fk import fk
from .ik.result import IKResult, IKStatus
from .jacobian import jacobian_and_pose
from .model import RobotModel
from .transforms import invert_pose

__all__ = [
    "DRILL_D7",
    "ROLL_JOINT",
    "DrillingJoint",
    "compensation_angles",
    "drill_axis",
    "drill_ik",
    "check_drilling_structure",
    "roll_joint",
]

METHOD = "drilling"
#: Feed joint value while positioning (paper 002, section 3.1), mm.
DRILL_D7 = 4022.0
#: Twists alpha_{i-1} of the tunnel drilling arm (paper 002, Table 1), rad.
ALPHAS = (0.0, -math.pi / 2, -math.pi / 2, 0.0, math.pi / 2, math.pi / 2, math.pi / 2)
TYPES = ("revolute", "revolute", "prismatic", "revolute", "revolute", "revolute", "prismatic")
#: Index of the roll joint (theta4: the drill's turn about the telescope) in ``q``.
ROLL_JOINT = 3
#: Gauss-Newton settings for roll != 0: roll step per continuation stage (rad), iterations
#: per stage, and the tolerances (mm, rad) that end the last stage.
ROLL_STAGE = 0.25
STAGE_ITERATIONS = 8
MAX_ITERATIONS = 50
TOL_POSITION = 1e-9
TOL_AXIS = 1e-13


def compensation_angles(theta1, theta2) -> tuple[np.ndarray, np.ndarray]:
    """Paper 002's compensation rule on D-H angles: ``(theta1, theta2) (*,) rad ->
    (theta5, theta6) (*,)`` with ``theta5 = -theta2``, ``theta6 = pi/2 - theta1``."""
    theta1 = np.asarray(theta1, dtype=float)
    theta2 = np.asarray(theta2, dtype=float)
    return -theta2, math.pi / 2 - theta1


def drill_axis(model: RobotModel, q) -> np.ndarray:
    """Drilling direction (tool z axis) in the world frame: ``q (N, 7) -> (N, 3)``."""
    return fk(model, q)[..., :3, 2]


def check_drilling_structure(model: RobotModel) -> None:
    """Raise ``ValueError`` naming the field if ``model`` lacks the drilling arm's structure.

    Needed: modified D-H, 7 joints R R P R R R P with twists 0, -90, -90, 0, 90, 90, 90 deg,
    ``joints[3].a = joints[3].d = joints[4].a = 0``, zero constant theta on both prismatic
    joints, and a tool transform without rotation.
    """
    if model.convention != "mdh":
        raise ValueError(f"model.convention: drilling IK needs 'mdh', got {model.convention!r}")
    if model.dof != 7:
        raise ValueError(f"model.joints: drilling IK needs 7 joints, got {model.dof}")
    for i, (j, t, alpha) in enumerate(zip(model.joints, TYPES, ALPHAS)):
        if j.type != t:
            raise ValueError(f"joints[{i}].type: the drilling arm has a {t} joint here")
        if abs(j.alpha - alpha) > 1e-12:
            raise ValueError(
                f"joints[{i}].alpha: must be {math.degrees(alpha):.0f} deg for the drilling arm"
            )
    for path, value in (
        ("joints[3].a", model.joints[3].a), ("joints[3].d", model.joints[3].d),
        ("joints[4].a", model.joints[4].a), ("joints[2].theta", model.joints[2].theta),
        ("joints[6].theta", model.joints[6].theta),
    ):
        if value != 0.0:
            raise ValueError(f"{path}: must be 0 for the drilling arm's closed form")
    if np.abs(model.tool[:3, :3] - np.eye(3)).max() > 1e-12:
        raise ValueError("model.tool: drilling IK needs a tool transform without rotation")


@dataclass(frozen=True)
class DrillingJoint:
    """One joint of a drilling arm: its index in ``q``, its name and limits (rad or mm)."""

    index: int
    name: str
    lower: float
    upper: float

    def within(self, value: float) -> bool:
        """Whether ``value`` lies within the joint's limits."""
        return self.lower <= value <= self.upper


def roll_joint(model: RobotModel) -> DrillingJoint:
    """The drilling arm's roll joint (the one ``drill_ik``'s ``roll`` sets); ``ValueError``
    naming the field, as ``check_drilling_structure``, if ``model`` is not a drilling arm."""
    check_drilling_structure(model)
    j = model.joints[ROLL_JOINT]
    return DrillingJoint(ROLL_JOINT, j.name, j.lower, j.upper)


def _holes(hole_xyz) -> np.ndarray:
    try:
        P = np.asarray(hole_xyz, dtype=float)
    except (TypeError, ValueError) as exc:
        raise FieldError("holes", "hole_xyz: must be numbers of shape (N, 3) or (3,)") from exc
    P = P[None] if P.ndim == 1 else P
    if P.ndim != 2 or P.shape[1] != 3:
        raise FieldError("holes",
                         f"hole_xyz: must have shape (N, 3) or (3,), got {list(P.shape)}")
    bad = ~np.all(np.isfinite(P), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise FieldError(("holes", k), f"hole_xyz[{k}]: has a NaN or infinite entry")
    return P


def _rule_solution(
    model: RobotModel, P_base: np.ndarray, d7: float
) -> tuple[np.ndarray, list[str | None]]:
    """Closed form with roll 0: ``P_base (N, 3)`` holes in the base frame -> q ``(N, 7)``
    (NaN rows where unreachable) and, per hole, why it is unreachable (or None)."""
    j = model.joints
    t = model.tool[:3, 3]
    d7_dh = d7 + j[6].offset
    # Constant part of the tip under the rule: frame 7 (and the tool frame) keep the
    # orientation R0 = [[0,0,1],[1,0,0],[0,1,0]], so d6, a6, d7 and the tool translation
    # always point the same way in the base frame.
    c = np.array([j[0].a + d7_dh + t[2], j[6].a + t[0], j[0].d + j[5].d + t[1]])
    A = j[1].a + j[5].a  # along the boom's horizontal heading
    D = j[1].d + j[4].d  # along the pitch axis (horizontal, normal to the heading)
    a2 = j[2].a  # offset of the telescope axis from the pitch axis
    u = P_base - c
    r2 = u[:, 0] ** 2 + u[:, 1] ** 2
    reasons: list[str | None] = [None] * len(P_base)
    vx = np.sqrt(np.maximum(r2 - D**2, 0.0))
    theta1 = np.arctan2(u[:, 1], u[:, 0]) - np.arctan2(D, vx)
    X, Z = vx - A, u[:, 2]
    rho2 = X**2 + Z**2
    d3 = np.sqrt(np.maximum(rho2 - a2**2, 0.0))
    psi = np.arctan2(X, Z) + np.arctan2(a2, d3)
    theta2 = np.mod(psi, 2 * math.pi) - math.pi  # psi - pi wrapped into [-pi, pi)
    theta1 = np.mod(theta1 + math.pi, 2 * math.pi) - math.pi
    theta5, theta6 = compensation_angles(theta1, theta2)
    offsets = np.array([jt.offset for jt in j])
    q = np.stack(
        [theta1, theta2, d3, np.zeros_like(d3), theta5, theta6, np.full_like(d3, d7_dh)], axis=1
    ) - offsets
    q[:, 6] = d7
    for k in np.flatnonzero(r2 < D**2):
        reasons[k] = (
            f"the hole is {math.sqrt(r2[k]):.1f} mm from the swing axis, less than the boom's "
            f"lateral offset d2 + d5 = {abs(D):.1f} mm"
        )
    for k in np.flatnonzero((rho2 < a2**2) & (r2 >= D**2)):
        reasons[k] = f"the hole is closer to the pitch axis than the telescope offset |a2| = " \
            f"{abs(a2):.1f} mm"
    q[[r is not None for r in reasons]] = np.nan
    return q, reasons


def _newton_roll(
    model: RobotModel, q: np.ndarray, P: np.ndarray, normal: np.ndarray, roll_q: float
) -> np.ndarray:
    """Solve swing, pitch, telescope and both compensation joints for roll ``roll_q`` (joint
    value, rad), continuing from the roll-0 solutions ``q (N, 7)`` (rows all finite)."""
    free = [0, 1, 2, 4, 5]
    q = q.copy()
    start = q[:, ROLL_JOINT].copy()
    stages = max(1, math.ceil(abs(roll_q - start.mean()) / ROLL_STAGE)) if len(q) else 1
    for s in range(1, stages + 1):
        q[:, ROLL_JOINT] = start + (roll_q - start) * s / stages
        iters = MAX_ITERATIONS if s == stages else STAGE_ITERATIONS
        for _ in range(iters):
            J, T = jacobian_and_pose(model, q)
            z = T[:, :3, 2]
            e = np.concatenate([T[:, :3, 3] - P, z - normal], axis=1)  # (N, 6)
            if s == stages and np.all(
                (np.linalg.norm(e[:, :3], axis=1) < TOL_POSITION)
                & (np.linalg.norm(e[:, 3:], axis=1) < TOL_AXIS)
            ):
                break
            Jf = J[:, :, free]
            Jz = np.cross(np.swapaxes(Jf[:, 3:], 1, 2), z[:, None, :])  # (N, 5, 3)
            G = np.concatenate([Jf[:, :3], np.swapaxes(Jz, 1, 2)], axis=1)  # (N, 6, 5)
            dq = -np.einsum("nij,nj->ni", np.linalg.pinv(G), e)
            q[:, free] += dq
    return q


def drill_ik(
    model: RobotModel,
    hole_xyz,
    *,
    d7: float = DRILL_D7,
    roll: float = 0.0,
) -> list[IKResult]:
    """Joint values that put the drill tip on each hole, drilling along the face normal.

    ``hole_xyz``: ``(N, 3)`` or ``(3,)`` hole positions on the face, world frame, mm. The face
    normal is the base frame's x axis. ``d7`` (mm) and ``roll`` (rad) are the feed and roll
    joint values. Returns one ``IKResult`` per hole: ``q (7,)`` with theta5 = -theta2,
    theta6 = 90 deg - theta1 when ``roll == 0`` (closed form; otherwise Gauss-Newton);
    ``position_error`` in mm and ``rotation_error`` = the angle between the drill axis and
    the face normal, rad.

    Only the branch with the boom pointing forward (positive horizontal reach) and a
    positive telescope length is returned (the others point the boom backwards or through
    its mount). Holes the arm cannot reach give ``IKStatus.UNREACHABLE``; holes reachable only
    outside the joint limits give ``IKStatus.OUT_OF_LIMITS`` with the solution in
    ``solutions`` and a message naming each joint and limit at fault.

    Raises ``ValueError`` naming the field if the model lacks the drilling arm's structure,
    and ``FieldError`` at ``holes`` (the service's name for ``hole_xyz``), ``d7`` or ``roll``
    if an input is malformed.
    """
    check_drilling_structure(model)
    P = _holes(hole_xyz)
    for name, v in (("d7", d7), ("roll", roll)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise FieldError(name, f"{name}: must be a finite number, got {v!r}")
    T_base_world = invert_pose(model.base)
    P_base = P @ T_base_world[:3, :3].T + T_base_world[:3, 3]
    normal = model.base[:3, 0]
    q, reasons = _rule_solution(model, P_base, float(d7))
    ok = np.all(np.isfinite(q), axis=1)
    if float(roll) + model.joints[ROLL_JOINT].offset != 0.0 and ok.any():
        # The closed form has the roll D-H angle at 0; continue from it to the asked roll.
        q[ok] = _newton_roll(model, q[ok], P[ok], normal, float(roll))

    results: list[IKResult] = []
    T = fk(model, np.where(ok[:, None], q, 0.0)) if len(q) else np.empty((0, 4, 4))
    dp = np.linalg.norm(T[:, :3, 3] - P, axis=1)
    cos = np.clip(T[:, :3, 2] @ normal, -1.0, 1.0)
    sin = np.linalg.norm(np.cross(T[:, :3, 2], normal), axis=1)
    dr = np.arctan2(sin, cos)
    for k in range(len(P)):
        if not ok[k]:
            results.append(IKResult(
                IKStatus.UNREACHABLE, None, np.empty((0, 7)), math.nan, math.nan, False,
                METHOD, f"hole[{k}] unreachable: {reasons[k]}",
            ))
            continue
        # A Newton run that did not converge (roll != 0) is reported, never returned.
        if dp[k] > 1e-6 or dr[k] > 1e-9:
            results.append(IKResult(
                IKStatus.NOT_CONVERGED, None, np.empty((0, 7)), float(dp[k]), float(dr[k]),
                bool(model.within_limits(q[k])), METHOD,
                f"hole[{k}]: no drilling configuration found for roll {roll:g} rad: position "
                f"error {dp[k]:.3g} mm, axis error {dr[k]:.3g} rad",
                extra={"best_q": q[k]},
            ))
            continue
        violations = _violations(model, q[k])
        if violations:
            results.append(IKResult(
                IKStatus.OUT_OF_LIMITS, None, q[k][None].copy(), float(dp[k]), float(dr[k]),
                False, METHOD,
                f"hole[{k}] reachable only outside the joint limits: " + "; ".join(violations),
            ))
        else:
            results.append(IKResult(
                IKStatus.OK, q[k].copy(), q[k][None].copy(), float(dp[k]), float(dr[k]), True,
                METHOD, "drill on the hole, perpendicular to the face",
            ))
    return results


def _violations(model: RobotModel, q: np.ndarray, tol: float = 1e-9) -> list[str]:
    """Each joint of ``q (7,)`` outside its limits, with its value and limits in words."""
    out = []
    for j, v in zip(model.joints, q):
        if j.lower - tol <= v <= j.upper + tol:
            continue
        side = "below its lower" if v < j.lower else "above its upper"
        if j.revolute:
            out.append(
                f"{j.name} = {math.degrees(v):.2f} deg is {side} limit (limits "
                f"{math.degrees(j.lower):.2f}..{math.degrees(j.upper):.2f} deg)"
            )
        else:
            out.append(
                f"{j.name} = {v:.1f} mm is {side} limit (limits {j.lower:.1f}..{j.upper:.1f} mm)"
            )
    return out
