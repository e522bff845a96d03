"""Kinematics of one robot: FK, Jacobian, IK, workspace."""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from kinematics.drilling import check_drilling_structure, drill_ik
from kinematics.errors import MethodUnavailableError
from kinematics.fk import fk, fk_frames
from kinematics.ik import prepare_targets, solve_ik
from kinematics.jacobian import dexterity, jacobian_and_pose
from kinematics.model import RobotModel
from kinematics.transforms import pose_errors
from kinematics.workspace import MAX_SAMPLES, sample_workspace, workspace_report

from ..deps import RobotDep
from ..errors import conflict, http_error, invalid, too_large
from ..schemas import (
    MAX_FK_CONFIGS,
    MAX_FRAMES_CONFIGS,
    MAX_IK_POSES,
    DrillIKRequest,
    FKRequest,
    FKResponse,
    IKRequest,
    IKResponse,
    JacobianRequest,
    JacobianResponse,
    WorkspaceRequest,
    WorkspaceResponse,
)

router = APIRouter(prefix="/robots/{robot_id}", tags=["kinematics"])

#: Largest |joint value| accepted (rad or mm): far beyond any joint, short of float trouble.
MAX_JOINT_VALUE = 1e6
#: Most holes in one drill-ik call (413 above); a face has a few hundred.
MAX_DRILL_HOLES = 2_000


def joint_rows(model: RobotModel, q: list, field: str = "q") -> tuple[np.ndarray, bool]:
    """Body ``q`` (one configuration or a list) -> ``(N, dof)`` array and whether it was one."""
    single = len(q) == 0 or not isinstance(q[0], list)
    rows = [q] if single else q
    for k, row in enumerate(rows):
        if len(row) != model.dof:
            loc = [field] if single else [field, k]
            raise invalid(
                loc, f"expected {model.dof} joint values for robot '{model.id}', got {len(row)}"
            )
    q_arr = np.asarray(rows, dtype=float).reshape(len(rows), model.dof)
    big = np.abs(q_arr) > MAX_JOINT_VALUE
    if big.any():
        k, j = (int(v) for v in np.argwhere(big)[0])
        loc = [field, j] if single else [field, k, j]
        raise invalid(loc, f"joint values beyond {MAX_JOINT_VALUE:.0e} (rad or mm) are not "
                      "physical")
    return q_arr, single


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@router.post("/fk", response_model=FKResponse)
def forward_kinematics(robot: RobotDep, body: FKRequest) -> JSONResponse:
    """Tool pose (and optionally every link frame) for one or many configurations."""
    n = 1 if not body.q or not isinstance(body.q[0], list) else len(body.q)
    cap = MAX_FRAMES_CONFIGS if body.frames == "all" else MAX_FK_CONFIGS
    if n > cap:
        raise too_large(["q"], f"at most {cap} configurations per call with frames="
                        f"'{body.frames}', got {n}")
    q, _ = joint_rows(robot, body.q)
    out: dict = {"within_limits": robot.within_limits(q).tolist()}
    if body.frames == "all":
        F = fk_frames(robot, q)
        out["poses"] = F[:, -1].tolist()
        out["frames"] = F.tolist()
    else:
        out["poses"] = fk(robot, q).tolist()
    return JSONResponse(out)


@router.post("/jacobian", response_model=JacobianResponse)
def jacobian_endpoint(robot: RobotDep, body: JacobianRequest) -> JacobianResponse:
    """Geometric Jacobian in the base frame, with manipulability and condition number."""
    q, _ = joint_rows(robot, body.q)
    J, T = jacobian_and_pose(robot, q[0])
    dx = dexterity(robot, J)
    return JacobianResponse(
        jacobian=J.tolist(),
        manipulability=dx.manipulability,
        condition=None if math.isinf(dx.condition) else dx.condition,
        min_singular_value=dx.min_singular_value,
        pose=T.tolist(),
    )


@router.post("/ik", response_model=IKResponse)
def inverse_kinematics(robot: RobotDep, body: IKRequest, request: Request) -> JSONResponse:
    """Joint solutions for one or many target poses; unreachable targets say why."""
    try:
        T = np.asarray(body.pose, dtype=float)
    except ValueError:
        raise invalid(["pose"], "pose must be a 4x4 matrix or a list of 4x4 matrices") from None
    if T.ndim == 2:
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise invalid(["pose"], "pose must be a 4x4 matrix or a list of 4x4 matrices")
    if T.shape[0] > MAX_IK_POSES:
        raise too_large(["pose"], f"at most {MAX_IK_POSES} poses per call, got {T.shape[0]}")
    q0 = None
    if body.q0 is not None:
        q0 = joint_rows(robot, body.q0, "q0")[0][0]
    if body.method == "learned":
        return _learned_ik(robot, T, request.app.state.jobs)
    try:
        results = solve_ik(
            robot, T, method=body.method, q0=q0, all_solutions=body.all_solutions
        )
    except MethodUnavailableError as exc:
        if exc.method == "learned":
            raise conflict(["method"], str(exc)) from None
        raise invalid(["method"], str(exc)) from None
    except ValueError as exc:
        raise invalid(["pose"], str(exc)) from None
    return JSONResponse({"results": [_ik_json(r) for r in results]})


def _ik_json(r) -> dict:
    return {
        "success": r.success,
        "status": r.status.value,
        "q": None if r.q is None else r.q.tolist(),
        "solutions": r.solutions.tolist(),
        "position_error": _finite_or_none(r.position_error),
        "rotation_error": _finite_or_none(r.rotation_error),
        "within_limits": bool(r.within_limits),
        "singular": bool(r.singular),
        "method": r.method,
        "message": r.message,
    }


def _learned_ik(robot: RobotModel, T: np.ndarray, jobs) -> JSONResponse:
    """The learned map's guess polished by the numeric IK; both reported."""
    found = jobs.learned_ik(robot.id)
    if found is None:
        raise conflict(["method"], f"no learned IK is trained for robot '{robot.id}': submit "
                       "an 'ik_train' job first")
    job_id, learned = found
    try:
        T = prepare_targets(T)
    except ValueError as exc:
        raise invalid(["pose"], str(exc)) from None
    guess, results = learned.polish(robot, T)
    dp, dr = pose_errors(fk(robot, guess), T)
    out = []
    for r, g, p, a in zip(results, guess, dp, dr):
        item = _ik_json(r)
        item["method"] = "learned+numeric"
        item["learned"] = {"q": g.tolist(), "position_error": float(p),
                           "rotation_error": float(a), "model_job": job_id}
        out.append(item)
    return JSONResponse({"results": out})


@router.post("/workspace", response_model=WorkspaceResponse)
def workspace(robot: RobotDep, body: WorkspaceRequest) -> JSONResponse:
    """Monte Carlo workspace: extents, radial and vertical ranges, volume, points."""
    if body.samples > MAX_SAMPLES:
        raise too_large(
            ["samples"], f"at most {MAX_SAMPLES} samples per call, got {body.samples}; "
            "submit a 'workspace' job for more"
        )
    try:
        ws = sample_workspace(robot, body.samples, seed=body.seed, voxel=body.voxel)
    except ValueError as exc:
        raise invalid(["voxel"], str(exc)) from None
    out = workspace_report(ws, body.return_points, body.projections)
    return JSONResponse(out)


@router.post("/drill-ik", response_model=IKResponse)
def drilling_ik(robot: RobotDep, body: DrillIKRequest) -> JSONResponse:
    """Drilling arms: joint values that put the drill tip on each hole, drilling
    perpendicular to the face (the base x axis), feed joint fixed."""
    holes = np.asarray(body.holes, dtype=float)
    if len(holes) > MAX_DRILL_HOLES:
        raise too_large(["holes"], f"at most {MAX_DRILL_HOLES} holes per call, got "
                        f"{len(holes)}")
    try:
        check_drilling_structure(robot)
    except ValueError as exc:
        raise http_error(422, ["path", "robot_id"], f"not a drilling arm: {exc}",
                         "value_error") from None
    roll = robot.joints[3]
    if not roll.lower <= body.roll <= roll.upper:
        raise invalid(["roll"], f"outside the {roll.name} joint's limits "
                      f"[{roll.lower:.4g}, {roll.upper:.4g}] rad")
    try:
        results = drill_ik(robot, holes, d7=body.d7, roll=body.roll)
    except ValueError as exc:
        field = str(exc).split(":", 1)[0]
        raise invalid([field if field in ("d7", "roll") else "holes"], str(exc)) from None
    return JSONResponse({"results": [_ik_json(r) for r in results]})
