"""Kinematics of one robot: FK, Jacobian, IK, workspace."""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter, Request, Response
from starlette.concurrency import run_in_threadpool

from kinematics.drilling import drill_ik, roll_joint
from kinematics.errors import FieldError, MethodUnavailableError
from kinematics.fk import fk, fk_frames
from kinematics.ik import prepare_targets, solve_ik
from kinematics.jacobian import dexterity, jacobian_and_pose
from kinematics.model import RobotModel
from kinematics.numbers import finite_or_none
from kinematics.transforms import pose_errors
from kinematics.workspace import MAX_SAMPLES, sample_workspace, workspace_report

from ...compute import ComputePool, encode_json
from ..deps import RobotDep
from ..errors import conflict, http_error, invalid, too_large
from ..schemas import (
    MAX_FK_CONFIGS,
    MAX_FRAMES_CONFIGS,
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



def compute(request: Request) -> ComputePool:
    return request.app.state.compute


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
    # Finite and within ±MAX_JOINT_VALUE already: the request types check every value.
    return np.asarray(rows, dtype=float).reshape(len(rows), model.dof), single


#: Above these sizes a request is computed in a worker process (``app.compute``).
HEAVY_FK_CONFIGS = 1_000
HEAVY_FK_FRAMES = 100
HEAVY_IK_POSES = 8
HEAVY_WORKSPACE_SAMPLES = 50_000
HEAVY_DRILL_HOLES = 32


def _json(body: bytes) -> Response:
    return Response(body, media_type="application/json")


def _fk_answer(robot: RobotModel, q: np.ndarray, frames: str) -> bytes:
    out: dict = {"within_limits": robot.within_limits(q).tolist()}
    if frames == "all":
        F = fk_frames(robot, q)
        out["poses"] = F[:, -1].tolist()
        out["frames"] = F.tolist()
    else:
        out["poses"] = fk(robot, q).tolist()
    return encode_json(out)


@router.post("/fk", response_model=FKResponse)
async def forward_kinematics(robot: RobotDep, body: FKRequest, request: Request) -> Response:
    """Tool pose (and optionally every link frame) for one or many configurations."""
    n = 1 if not body.q or not isinstance(body.q[0], list) else len(body.q)
    cap = MAX_FRAMES_CONFIGS if body.frames == "all" else MAX_FK_CONFIGS
    if n > cap:
        raise too_large(["q"], f"at most {cap} configurations per call with frames="
                        f"'{body.frames}', got {n}")
    q, _ = joint_rows(robot, body.q)
    heavy = n > (HEAVY_FK_FRAMES if body.frames == "all" else HEAVY_FK_CONFIGS)
    return _json(await compute(request).run(heavy, _fk_answer, robot, q, body.frames))


@router.post("/jacobian", response_model=JacobianResponse)
def jacobian_endpoint(robot: RobotDep, body: JacobianRequest) -> JacobianResponse:
    """Geometric Jacobian in the world frame (that of fk), manipulability, condition."""
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


def _ik_answer(robot: RobotModel, T: np.ndarray, method: str, q0: np.ndarray | None,
               all_solutions: bool) -> bytes:
    results = solve_ik(robot, T, method=method, q0=q0, all_solutions=all_solutions)
    return encode_json({"results": [_ik_json(r) for r in results]})


@router.post("/ik", response_model=IKResponse)
async def inverse_kinematics(robot: RobotDep, body: IKRequest, request: Request) -> Response:
    """Joint solutions for one or many target poses; unreachable targets say why."""
    # One 4x4 pose or at most MAX_IK_POSES of them, bounded: checked by ``pose_input``.
    T = np.asarray(body.pose, dtype=float).reshape(-1, 4, 4)
    q0 = None
    if body.q0 is not None:
        q0 = joint_rows(robot, body.q0, "q0")[0][0]
    heavy = T.shape[0] > HEAVY_IK_POSES
    pool = compute(request)
    if body.method == "learned":
        found = await run_in_threadpool(request.app.state.jobs.learned_ik, robot.id)
        if found is None:
            raise conflict(["method"], f"no learned IK is trained for robot '{robot.id}': "
                           "submit an 'ik_train' job first")
        try:
            T = prepare_targets(T)
        except ValueError as exc:
            raise invalid(["pose"], str(exc)) from None
        return _json(await pool.run(heavy, _learned_ik_answer, robot, T, *found))
    try:
        return _json(await pool.run(heavy, _ik_answer, robot, T, body.method, q0,
                                    body.all_solutions))
    except MethodUnavailableError as exc:
        if exc.method == "learned":
            raise conflict(["method"], str(exc)) from None
        raise invalid(["method"], str(exc)) from None
    except ValueError as exc:
        raise invalid(["pose"], str(exc)) from None


def _ik_json(r) -> dict:
    return {
        "success": r.success,
        "status": r.status.value,
        "q": None if r.q is None else r.q.tolist(),
        "solutions": r.solutions.tolist(),
        "position_error": finite_or_none(r.position_error),
        "rotation_error": finite_or_none(r.rotation_error),
        "within_limits": bool(r.within_limits),
        "singular": bool(r.singular),
        "method": r.method,
        "message": r.message,
    }


def _learned_ik_answer(robot: RobotModel, T: np.ndarray, job_id: str, learned) -> bytes:
    """The learned map's guess polished by the numeric IK; both reported."""
    guess, results = learned.polish(robot, T)
    dp, dr = pose_errors(fk(robot, guess), T)
    out = []
    for r, g, p, a in zip(results, guess, dp, dr):
        item = _ik_json(r)
        item["method"] = "learned+numeric"
        item["learned"] = {"q": g.tolist(), "position_error": float(p),
                           "rotation_error": float(a), "model_job": job_id}
        out.append(item)
    return encode_json({"results": out})


def _workspace_answer(robot: RobotModel, samples: int, seed: int, voxel: float | None,
                      return_points: int, projections: bool) -> bytes:
    ws = sample_workspace(robot, samples, seed=seed, voxel=voxel)
    return encode_json(workspace_report(ws, return_points, projections))


@router.post("/workspace", response_model=WorkspaceResponse)
async def workspace(robot: RobotDep, body: WorkspaceRequest, request: Request) -> Response:
    """Monte Carlo workspace: extents, radial and vertical ranges, volume, points."""
    if body.samples > MAX_SAMPLES:
        raise too_large(
            ["samples"], f"at most {MAX_SAMPLES} samples per call, got {body.samples}; "
            "submit a 'workspace' job for more"
        )
    heavy = body.samples > HEAVY_WORKSPACE_SAMPLES or body.return_points > 20_000
    try:
        return _json(await compute(request).run(
            heavy, _workspace_answer, robot, body.samples, body.seed, body.voxel,
            body.return_points, body.projections))
    except ValueError as exc:
        raise invalid(["voxel"], str(exc)) from None


@router.post("/drill-ik", response_model=IKResponse)
async def drilling_ik(robot: RobotDep, body: DrillIKRequest, request: Request) -> Response:
    """Drilling arms: joint values that put the drill tip on each hole, drilling
    perpendicular to the face (the base x axis), feed joint fixed."""
    holes = np.asarray(body.holes, dtype=float)  # at most MAX_DRILL_HOLES: the schema's cap
    try:
        roll = roll_joint(robot)
    except ValueError as exc:
        raise http_error(422, ["path", "robot_id"], f"not a drilling arm: {exc}",
                         "value_error") from None
    if not roll.within(body.roll):
        raise invalid(["roll"], f"outside the {roll.name} joint's limits "
                      f"[{roll.lower:.4g}, {roll.upper:.4g}] rad")
    try:
        return _json(await compute(request).run(len(holes) > HEAVY_DRILL_HOLES,
                                                _drill_ik_answer, robot, holes, body.d7,
                                                body.roll))
    except FieldError:  # drill_ik's checks name holes, d7 or roll: 422 there
        raise
    except ValueError as exc:  # numerics that found no answer for these holes
        raise invalid(["holes"], str(exc)) from None


def _drill_ik_answer(robot: RobotModel, holes: np.ndarray, d7: float, roll: float) -> bytes:
    results = drill_ik(robot, holes, d7=d7, roll=roll)
    return encode_json({"results": [_ik_json(r) for r in results]})
