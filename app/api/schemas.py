"""Request and response bodies of the REST API (units: mm, rad, s; poses are 4x4 lists)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from kinematics.model import MAX_DOF, MAX_LENGTH_MM
from kinematics.workspace import DEFAULT_SAMPLES, MAX_SAMPLES
from planning.motion.request import MAX_PROBLEMS
from planning.motion.task import TASK_STATUSES

from ..fields import (
    MAX_DURATION_S,
    MAX_NAME_LENGTH,
    Coordinate,
    JointVector,
    Name,
    Point3,
    StrictModel,
    bounded_list,
    joint_input,
    pose_input,
    pose_type,
)
from ..store import COMPACT_MIN_FREE_BYTES

__all__ = [
    "MAX_FK_CONFIGS",
    "MAX_FRAMES_CONFIGS",
    "MAX_IK_POSES",
    "MAX_RETURN_POINTS",
    "Health",
    "JointSummary",
    "RobotSummary",
    "FKRequest",
    "FKResponse",
    "JacobianRequest",
    "JacobianResponse",
    "IKRequest",
    "IKResultOut",
    "IKResponse",
    "WorkspaceRequest",
    "WorkspaceResponse",
    "body_examples",
]

#: Most configurations in one FK call (413 above).
MAX_FK_CONFIGS = 100_000
#: Most configurations in one FK call with ``frames: "all"`` (413 above).
MAX_FRAMES_CONFIGS = 10_000
#: Most target poses in one IK call (413 above).
MAX_IK_POSES = 10_000
#: Most points a workspace answer carries.
MAX_RETURN_POINTS = 200_000

Matrix = list[list[float]]
#: A tool pose in a request: 4x4, every entry bounded.
Pose = pose_type(4)
#: Most holes in one drill-ik call (413 above); a face has a few hundred.
MAX_DRILL_HOLES = 2_000
#: Most seed for random sampling (fits a 32-bit generator seed comfortably).
MAX_SEED = 2**32 - 1


class Body(StrictModel):
    """Request bodies: unknown fields and NaN/inf are rejected (422)."""


def body_examples(*values: dict[str, Any], robot: str | None = None) -> dict[str, Any]:
    """``json_schema_extra`` of a request body: ``values`` as its OpenAPI ``examples``, each
    of which works as it is on a fresh service; ``robot`` (``x-example-robot``) is the
    built-in robot whose id goes in the path of a ``/robots/{robot_id}/...`` route."""
    extra: dict[str, Any] = {"examples": list(values)}
    if robot is not None:
        extra["x-example-robot"] = robot
    return extra


#: The GLT palletizer at the first configuration of its paper's Table 2 (rad), and its pose.
GLT_Q = [0.2618, 0.5236, 0.7854, 1.0472, 1.5708, 2.7925]
GLT_POSE = [[-0.467, -0.5522, -0.6907, 783.71], [0.3022, 0.6344, -0.7115, -336.47],
            [0.831, -0.541, -0.1294, 323.58], [0, 0, 0, 1]]
#: The palletizer's swing of the README's motion plan, past a ball on the tool's way.
GLT_SWING = {"start": [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0],
             "goal": {"q": [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]},
             "scene": {"objects": [{"type": "sphere", "id": "ball", "radius": 150,
                                    "pose": [[1, 0, 0, 1367], [0, 1, 0, 0], [0, 0, 1, 1288],
                                             [0, 0, 0, 1]]}]}}


class StoreHealth(BaseModel):
    ok: bool = Field(description="The store can be read and written")
    error: str | None = Field(None, description="Why not, when it cannot")
    bytes: int | None = Field(None, description="Bytes the store takes on disk: its SQLite "
                              "file, write-ahead log and index (null when it cannot be read)")
    free_bytes: int | None = Field(
        None, description="Of those, bytes of free pages in the file (left by dropped payloads "
        "and deleted jobs): reused for new rows, and given back to the file system within a "
        f"minute once they reach {COMPACT_MIN_FREE_BYTES >> 20} MiB")
    job_counts: dict[str, int] | None = Field(
        None, description="Jobs in the store by status (queued, running, succeeded, failed, "
        "cancelled)")


class JobsHealth(BaseModel):
    ok: bool = Field(description="The job backend works (or has not been started yet)")
    running: bool = Field(description="Its supervisor runs (false until the service starts it)")
    error: str | None = Field(None, description="What is wrong, when something is")
    workers: int | None = Field(None, description="Job steps run at once: the local backend's "
                                "processes, or the Dask cluster's worker threads (0 while "
                                "none is connected)")


class Health(BaseModel):
    status: Literal["ok", "degraded"] = Field(
        description="'ok' (HTTP 200) only when the store and the job backend both work, "
        "else 'degraded' (HTTP 503)")
    version: str
    jobs_backend: str
    store: StoreHealth
    jobs: JobsHealth


class JointSummary(BaseModel):
    name: str
    type: Literal["revolute", "prismatic"]
    lower: float
    upper: float


class RobotSummary(BaseModel):
    id: str
    name: str
    dof: int
    builtin: bool
    convention: Literal["mdh", "sdh", "poe"]
    joints: list[JointSummary]
    ik_methods: list[str]


class FKRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"q": GLT_Q}, {"q": [GLT_Q, [0, 0, 0, 0, 0, 0]], "frames": "all"},
        robot="glt_palletizer"))

    q: joint_input(MAX_FK_CONFIGS) = Field(
        description="One configuration (dof values) or a list of them; rad or mm per joint "
        f"(at most {MAX_FK_CONFIGS} configurations, {MAX_FRAMES_CONFIGS} with frames='all')"
    )
    frames: Literal["tool", "all"] = Field(
        "tool", description="'all' also returns every link frame (base, after each joint, tool)"
    )


class FKResponse(BaseModel):
    poses: list[Matrix]
    frames: list[list[Matrix]] | None = None


class JacobianRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples({"q": GLT_Q},
                                                              robot="glt_palletizer"))

    q: JointVector = Field(description="One configuration (dof values)")


class JacobianResponse(BaseModel):
    jacobian: list[list[float]] = Field(
        description="6 x dof: rows vx, vy, vz (mm per joint unit), wx, wy, wz (rad per joint "
        "unit), world frame (that of fk)"
    )
    manipulability: float = Field(description="sqrt(det(J J^T)) of the raw Jacobian")
    condition: float | None = Field(
        description="Condition number of the unit-normalised Jacobian; null when singular"
    )
    min_singular_value: float = Field(
        description="Smallest singular value of the unit-normalised Jacobian (0 = singular)"
    )
    pose: Matrix


class IKRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"pose": GLT_POSE, "all_solutions": True}, robot="glt_palletizer"))

    pose: pose_input(MAX_IK_POSES) = Field(
        description=f"Target tool pose (4x4) or a list of at most {MAX_IK_POSES}")
    q0: JointVector | None = Field(
        None, description="Initial guess / preferred configuration; solutions nearest it first"
    )
    method: Literal["auto", "analytic", "numeric", "learned"] = "auto"
    all_solutions: bool = Field(
        False, description="Return every solution found (closed forms: every branch and turn)"
    )


class IKResultOut(BaseModel):
    success: bool
    status: Literal["ok", "unreachable", "out_of_limits", "not_converged"]
    q: list[float] | None
    solutions: list[list[float]]
    position_error: float | None = Field(description="mm; null when nothing was computed")
    rotation_error: float | None = Field(description="rad; null when nothing was computed")
    within_limits: bool
    singular: bool
    method: str
    message: str


class IKResponse(BaseModel):
    results: list[IKResultOut]


class WorkspaceRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"samples": 30000, "return_points": 0, "projections": False}, robot="pile_driver"))

    samples: int = Field(
        DEFAULT_SAMPLES, ge=1, json_schema_extra={"maximum": MAX_SAMPLES},
        description=f"Monte Carlo samples (413 above {MAX_SAMPLES:,}: submit a 'workspace' "
        "job for more)",
    )
    seed: int = Field(0, ge=0, le=MAX_SEED, description="Seed of the random joint samples")
    voxel: float | None = Field(
        None, gt=0, le=1e6, description="Voxel edge (mm) of the volume estimate; default "
        "extent/30"
    )
    return_points: int = Field(
        20_000, ge=0, le=MAX_RETURN_POINTS, description="Points to return (subsampled)"
    )
    projections: bool = Field(True, description="Include XY/XZ/YZ occupancy images")


class Projection(BaseModel):
    counts: list[list[int]]
    first_edges: list[float]
    second_edges: list[float]


class WorkspaceResponse(BaseModel):
    samples: int
    seed: int
    min: list[float]
    max: list[float]
    radial: list[float] = Field(description="[min, max] distance from the base z axis, mm")
    vertical: list[float] = Field(description="[min, max] height along the base z axis, mm")
    voxel: float
    volume: float = Field(description="mm^3, voxel estimate")
    points: list[list[float]]
    projections: dict[str, Projection] | None = None


#: Most waypoints, and most trajectory samples, of a motion answer the viewer takes.
MAX_MOTION_SAMPLES = 10_000


class MotionTrajectoryIn(BaseModel):
    """A motion answer's trajectory: the samples the viewer plays (its rates are not read)."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    t: bounded_list(Annotated[float, Field(ge=0, le=MAX_DURATION_S)],  # type: ignore[valid-type]
                    MAX_MOTION_SAMPLES, min_length=1) = Field(description="s")
    q: bounded_list(JointVector, MAX_MOTION_SAMPLES, min_length=1) = Field(  # type: ignore[valid-type]
        description="rad / mm per sample")


class MotionAnswerIn(BaseModel):
    """The answer of ``POST /robots/{id}/motion`` as it was returned. The viewer reads the
    fields below, bounded as every request's numbers are; the answer's others (``stats``,
    ``qd``, ...) are accepted and not read."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False)

    robot: Name
    joints: bounded_list(Name, MAX_DOF, min_length=1)  # type: ignore[valid-type]
    # A task's answer too (its statuses include a move's): it plays as one motion.
    status: Literal[TASK_STATUSES]  # type: ignore[valid-type]
    message: str = Field("", max_length=10_000)
    path: bounded_list(JointVector, MAX_MOTION_SAMPLES) = Field(  # type: ignore[valid-type]
        default_factory=list, description="Waypoints, rad / mm per joint")
    length: float | None = Field(None, ge=0, le=MAX_LENGTH_MM)
    planning_time_s: float | None = Field(None, ge=0, le=MAX_DURATION_S)
    min_clearance: Coordinate | None = None
    goal: JointVector | None = None
    pairs: bounded_list(  # type: ignore[valid-type]
        Annotated[list[Name], Field(min_length=2, max_length=2)], 1_000) = Field(
        default_factory=list)
    planner: str = Field("", max_length=MAX_NAME_LENGTH)
    trajectory: MotionTrajectoryIn | None = None


class ViewerShowRequest(Body):
    """What the viewer shows: a robot (at ``q``), a finished job or a motion answer, and/or a
    stored scene (``"scene": null`` clears the scene shown)."""

    model_config = ConfigDict(json_schema_extra=body_examples(
        {"robot": "glt_palletizer", "q": [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]}))

    robot: str | None = Field(None, max_length=64, description="Robot id to show")
    q: JointVector | None = Field(None, description="Configuration; default mid-limits")
    job: str | None = Field(None, max_length=64,
                            description="A finished job whose result to show")
    problem: int | None = Field(None, ge=0, lt=MAX_PROBLEMS,
                                description="With a motion job of a batch of problems: the "
                                "one to show (0-based); default the first solved one")
    motion: MotionAnswerIn | None = Field(
        None, description="An answer of POST /robots/{id}/motion, as returned: its robot "
        "moves along it (give the stored scene it was planned in as scene)")
    scene: str | None = Field(None, max_length=64, pattern=r"^[A-Za-z0-9_-]{1,64}$",
                              description="A stored scene to show (replacing the one shown); "
                              "null clears it")


class JobRecordOut(BaseModel):
    id: str
    kind: str
    params: dict
    status: Literal["queued", "running", "succeeded", "failed", "cancelled"]
    progress: float = Field(description="0..1")
    message: str
    created: str
    started: str | None
    finished: str | None
    error: str | None
    attempts: int = Field(description="Times the job was started (restarts re-run it)")
    time_limit_s: float | None = Field(
        None, description="Seconds the job may run; past them it fails with 'time limit of "
        "N s exceeded' (null: no limit, jobs queued before limits existed)")


class JobKindOut(BaseModel):
    """A job kind of ``GET /jobs/kinds``."""

    kind: str
    description: str
    params: dict[str, Any] = Field(description="JSON schema of the params (as params_schema; "
                                   "kept for older clients)")
    params_schema: dict[str, Any] = Field(description="JSON schema of the params")
    result_schema: dict[str, Any] = Field(description="JSON schema of the result "
                                          "(GET /jobs/{id}/result)")
    max_params_bytes: int = Field(description="Most bytes of JSON the params may take")
    plot: bool = Field(description="Whether GET /jobs/{id}/plot draws jobs of this kind")




class DrillIKRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"holes": [[9000, 0, -500], [9000, 1000, 1000], [9000, -1000, 1000]], "d7": 4022,
         "roll": 0}, robot="tunnel_drill_arm"))

    holes: bounded_list(Point3, MAX_DRILL_HOLES, min_length=1, what="holes",
                         per_call=True) = Field(
        description=f"Hole positions [x, y, z] on the face, mm (at most {MAX_DRILL_HOLES})"
    )
    d7: float = Field(4022.0, ge=-1e6, le=1e6,
                      description="Feed joint value, mm (paper 002: 4022)")
    roll: float = Field(0.0, ge=-4 * 3.141592653589793, le=4 * 3.141592653589793,
                        description="Roll joint value, rad (within the roll joint's limits)")


class ErrorItem(BaseModel):
    loc: list[str | int]
    msg: str
    type: str


class ErrorOut(BaseModel):
    """Every 4xx/5xx answer: ``detail`` lists what is wrong and where (``loc``)."""

    detail: list[ErrorItem]
