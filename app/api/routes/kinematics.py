"""Kinematics of one robot: FK, Jacobian, IK, workspace.

Answers are encoded by ``app.responses`` (orjson, arrays written directly; request bodies
decoded by orjson too). With ``Accept: application/x-npy`` the batch endpoints answer with
their main array in NumPy's ``.npy`` format instead (float64):

* ``/fk``: the tool poses ``(N, 4, 4)`` (``N`` = 1 for one configuration); with
  ``frames: "all"``, every frame ``(N, dof + 1, 4, 4)`` (the base, then the frame after each
  joint; the last is the tool pose);
* ``/ik`` and ``/drill-ik``: the best solution of each target ``(N, dof)``, NaN rows where
  there is none;
* ``/jacobian``: the Jacobian ``(6, dof)``;
* ``/workspace``: the returned points ``(M, 3)``.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Depends, Path, Request, Response
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

from ...compute import ComputePool
from ...fields import MAX_JOINT_VALUE
from ...jobs.model_kinds import LearnedIKRefused
from ...responses import (
    NPY_RESPONSE,
    FastJSONRoute,
    answer,
    body_schema,
    dumps,
    npy_bytes,
    request_body,
    validate_body,
    wants_npy,
)
from ..common import joint_rows
from ..errors import conflict, http_error, invalid, not_found, too_large
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

router = APIRouter(prefix="/robots/{robot_id}", tags=["kinematics"], route_class=FastJSONRoute)


def compute(request: Request) -> ComputePool:
    return request.app.state.compute


async def get_robot(
    request: Request,
    robot_id: Annotated[str, Path(description="Robot id, e.g. 'glt_palletizer'")],
) -> RobotModel:
    """The robot of the path; built-in ones looked up on the event loop (a dict read, no
    thread hop: a single FK costs about what ``/health`` does), custom ones in a thread (their
    table may be read again from the store)."""
    registry = request.app.state.registry
    try:
        if registry.is_builtin(robot_id):
            return registry.get(robot_id)
        return await run_in_threadpool(registry.get, robot_id)
    except KeyError:
        raise not_found("robot", robot_id) from None


RobotDep = Annotated[RobotModel, Depends(get_robot)]


#: Above these sizes a request is computed in a worker process (``app.compute``).
HEAVY_FK_CONFIGS = 20_000
HEAVY_FK_FRAMES = 100
HEAVY_IK_POSES = 8
HEAVY_WORKSPACE_SAMPLES = 50_000
HEAVY_DRILL_HOLES = 32
#: Up to this many configurations FK is computed on the event loop itself: microseconds,
#: less than a hop to a thread.
INLINE_FK_CONFIGS = 1


def _fk_answer(robot: RobotModel, q: np.ndarray, frames: str, npy: bool = False) -> bytes:
    within = robot.within_limits(q)
    if frames == "all":
        F = fk_frames(robot, q)
        if npy:
            return npy_bytes(F)
        return dumps({"within_limits": within, "poses": F[:, -1], "frames": F})
    T = fk(robot, q)
    return npy_bytes(T) if npy else dumps({"within_limits": within, "poses": T})


def _plain_fk_body(raw: bytes, data, dof: int) -> tuple[np.ndarray, str] | None:
    """``(q (N, dof), frames)`` when the FK body is plainly valid: only ``q`` (numbers, one
    configuration of ``dof`` values or rows of them, finite and within range, at most the
    per-call cap) and optionally ``frames``. None when anything is unusual: the body then
    goes through ``FKRequest``, whose errors name the field.

    No JSON ``true``/``false`` and no string but the keys and ``frames``'s value may appear
    in ``raw`` (numpy would read booleans and numeric strings as numbers)."""
    if not isinstance(data, dict) or "q" not in data or not data.keys() <= {"q", "frames"}:
        return None
    frames = data.get("frames", "tool")
    if frames not in ("tool", "all") or b"true" in raw or b"false" in raw or \
            raw.count(b'"') != 2 * (2 * len(data) - 1):
        return None
    q = data["q"]
    if not isinstance(q, list) or not q:
        return None
    try:
        arr = np.array(q, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.ndim == 1:
        arr = arr[None]
    cap = MAX_FRAMES_CONFIGS if frames == "all" else MAX_FK_CONFIGS
    if arr.ndim != 2 or arr.shape[1] != dof or len(arr) > cap or \
            not np.all(np.abs(arr) <= MAX_JOINT_VALUE):  # NaN fails it too
        return None
    return arr, frames


async def _fk_request(request: Request, robot: RobotModel) -> tuple[np.ndarray, str]:
    """The FK body as ``(q (N, dof), frames)``: decoded by orjson, taken as it is when
    plainly valid, else validated by ``FKRequest`` (its 422s and 413s)."""
    raw, data = await request_body(request)
    plain = _plain_fk_body(raw, data, robot.dof)
    if plain is not None:
        return plain
    body = validate_body(FKRequest, data)
    n = 1 if not body.q or not isinstance(body.q[0], list) else len(body.q)
    cap = MAX_FRAMES_CONFIGS if body.frames == "all" else MAX_FK_CONFIGS
    if n > cap:
        raise too_large(["q"], f"at most {cap} configurations per call with frames="
                        f"'{body.frames}', got {n}")
    return joint_rows(robot, body.q)[0], body.frames


@router.post("/fk", response_model=FKResponse, responses=NPY_RESPONSE,
             openapi_extra=body_schema(FKRequest))
async def forward_kinematics(robot: RobotDep, request: Request) -> Response:
    """Tool pose (and optionally every link frame) for one or many configurations."""
    q, frames = await _fk_request(request, robot)
    n = len(q)
    npy = wants_npy(request)
    if n <= INLINE_FK_CONFIGS and frames == "tool":
        return answer(_fk_answer(robot, q, frames, npy), npy)
    heavy = n > (HEAVY_FK_FRAMES if frames == "all" else HEAVY_FK_CONFIGS)
    return answer(await compute(request).run(heavy, _fk_answer, robot, q, frames, npy), npy)


def _jacobian_answer(robot: RobotModel, q: np.ndarray, npy: bool) -> bytes:
    J, T = jacobian_and_pose(robot, q)
    if npy:
        return npy_bytes(J)
    dx = dexterity(robot, J)
    return dumps({
        "jacobian": J,
        "manipulability": dx.manipulability,
        "condition": None if math.isinf(dx.condition) else dx.condition,
        "min_singular_value": dx.min_singular_value,
        "pose": T,
    })


@router.post("/jacobian", response_model=JacobianResponse, responses=NPY_RESPONSE)
async def jacobian_endpoint(robot: RobotDep, body: JacobianRequest,
                            request: Request) -> Response:
    """Geometric Jacobian in the world frame (that of fk), manipulability, condition."""
    q, _ = joint_rows(robot, body.q)
    npy = wants_npy(request)
    return answer(await run_in_threadpool(_jacobian_answer, robot, q[0], npy), npy)


def _best_solutions(results, dof: int) -> np.ndarray:
    """``(N, dof)``: each result's ``q``, NaN where there is none."""
    out = np.full((len(results), dof), np.nan)
    for k, r in enumerate(results):
        if r.q is not None:
            out[k] = r.q
    return out


def _ik_answer(robot: RobotModel, T: np.ndarray, method: str, q0: np.ndarray | None,
               all_solutions: bool, npy: bool = False) -> bytes:
    results = solve_ik(robot, T, method=method, q0=q0, all_solutions=all_solutions)
    if npy:
        return npy_bytes(_best_solutions(results, robot.dof))
    return dumps({"results": [_ik_json(r) for r in results]})


@router.post("/ik", response_model=IKResponse, responses=NPY_RESPONSE)
async def inverse_kinematics(robot: RobotDep, body: IKRequest, request: Request) -> Response:
    """Joint solutions for one or many target poses; unreachable targets say why."""
    # One 4x4 pose or at most MAX_IK_POSES of them, bounded: checked by ``pose_input``.
    T = np.asarray(body.pose, dtype=float).reshape(-1, 4, 4)
    q0 = None
    if body.q0 is not None:
        q0 = joint_rows(robot, body.q0, "q0")[0][0]
    heavy = T.shape[0] > HEAVY_IK_POSES
    pool = compute(request)
    npy = wants_npy(request)
    if body.method == "learned":
        try:
            found = await run_in_threadpool(request.app.state.jobs.learned_ik, robot.id)
        except LearnedIKRefused as exc:
            raise conflict(["method"], str(exc)) from None
        if found is None:
            raise conflict(["method"], f"no learned IK is trained for robot '{robot.id}': "
                           "submit an 'ik_train' job first")
        try:
            T = prepare_targets(T)
        except ValueError as exc:
            raise invalid(["pose"], str(exc)) from None
        return answer(await pool.run(heavy, _learned_ik_answer, robot, T, *found, npy), npy)
    try:
        return answer(await pool.run(heavy, _ik_answer, robot, T, body.method, q0,
                                     body.all_solutions, npy), npy)
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
        "q": r.q,
        "solutions": r.solutions,
        "position_error": finite_or_none(r.position_error),
        "rotation_error": finite_or_none(r.rotation_error),
        "within_limits": bool(r.within_limits),
        "singular": bool(r.singular),
        "method": r.method,
        "message": r.message,
    }


def _learned_ik_answer(robot: RobotModel, T: np.ndarray, job_id: str, learned,
                       npy: bool = False) -> bytes:
    """The learned map's guess polished by the numeric IK; both reported."""
    guess, results = learned.polish(robot, T)
    if npy:
        return npy_bytes(_best_solutions(results, robot.dof))
    dp, dr = pose_errors(fk(robot, guess), T)
    out = []
    for r, g, p, a in zip(results, guess, dp, dr):
        item = _ik_json(r)
        item["method"] = "learned+numeric"
        item["learned"] = {"q": g, "position_error": finite_or_none(p),
                           "rotation_error": finite_or_none(a), "model_job": job_id}
        out.append(item)
    return dumps({"results": out})


def _workspace_answer(robot: RobotModel, samples: int, seed: int, voxel: float | None,
                      return_points: int, projections: bool, npy: bool = False) -> bytes:
    ws = sample_workspace(robot, samples, seed=seed, voxel=voxel, return_points=return_points,
                          projections=False if npy else projections)
    report = workspace_report(ws, return_points, False if npy else projections)
    if npy:
        return npy_bytes(np.asarray(report["points"], dtype=float).reshape(-1, 3))
    return dumps(report)


@router.post("/workspace", response_model=WorkspaceResponse, responses=NPY_RESPONSE)
async def workspace(robot: RobotDep, body: WorkspaceRequest, request: Request) -> Response:
    """Monte Carlo workspace: extents, radial and vertical ranges, volume, points."""
    if body.samples > MAX_SAMPLES:
        raise too_large(
            ["samples"], f"at most {MAX_SAMPLES} samples per call, got {body.samples}; "
            "submit a 'workspace' job for more"
        )
    heavy = body.samples > HEAVY_WORKSPACE_SAMPLES or body.return_points > 20_000
    npy = wants_npy(request)
    try:
        return answer(await compute(request).run(
            heavy, _workspace_answer, robot, body.samples, body.seed, body.voxel,
            body.return_points, body.projections, npy), npy)
    except ValueError as exc:
        raise invalid(["voxel"], str(exc)) from None


@router.post("/drill-ik", response_model=IKResponse, responses=NPY_RESPONSE)
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
    npy = wants_npy(request)
    try:
        return answer(await compute(request).run(len(holes) > HEAVY_DRILL_HOLES,
                                                 _drill_ik_answer, robot, holes, body.d7,
                                                 body.roll, npy), npy)
    except FieldError:  # drill_ik's checks name holes, d7 or roll: 422 there
        raise
    except ValueError as exc:  # numerics that found no answer for these holes
        raise invalid(["holes"], str(exc)) from None


def _drill_ik_answer(robot: RobotModel, holes: np.ndarray, d7: float, roll: float,
                     npy: bool = False) -> bytes:
    results = drill_ik(robot, holes, d7=d7, roll=roll)
    if npy:
        return npy_bytes(_best_solutions(results, robot.dof))
    return dumps({"results": [_ik_json(r) for r in results]})
