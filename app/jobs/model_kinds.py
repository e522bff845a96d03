"""Job kinds that work on a robot model itself: calibration and learned-IK training."""

from __future__ import annotations

import json
from typing import Annotated, Literal

from pydantic import ConfigDict, Field, model_validator

from kinematics.model import MAX_DOF
from kinematics.numbers import finite_or_none

from ..fields import Coordinate, JointValue, Point3
from .kinds import (
    MAX_SEED,
    XYZ,
    JobKind,
    Params,
    Progress,
    Result,
    absent_when_none,
    pick,
    register,
)

__all__ = ["CalibrateParams", "CalibrateResult", "IKTrainParams", "IKTrainResult",
           "RobotModelData", "LearnedIKRefused", "served_learned_ik", "IK_TRAIN",
           "DEFAULT_MAX_MEAN_POSITION_ERROR"]

#: Most measurements one calibration takes, and the most JSON its params may take: 10,000
#: measured positions, or about 8,000 measured poses, at full float precision.
MAX_MEASUREMENTS = 10_000
MAX_CALIBRATE_PARAMS_BYTES = 4 << 20
#: Most constants one calibration fits.
MAX_FITTED = 200
#: Most samples one learned-IK training takes (its model, stored with the result, grows with
#: them: about 280 bytes of JSON per sample).
MAX_IK_SAMPLES = 100_000
#: Largest share of the samples held out for testing (each is polished by the numeric IK).
MAX_TEST_FRACTION = 0.5
#: Held-out poses a learned IK is validated on by default, and at most.
VALIDATION_SAMPLES = 1000
MAX_VALIDATION_SAMPLES = 20_000
#: The quality gate of a learned IK: the largest mean position error (mm) of its map alone on
#: the validation poses. Measured on the built-in robots (1,000 validation poses, seeds 0-3):
#: the tunnel drilling arm trained as the paper does (10,000 samples) is off by 0.05 mm on
#: average, with 1,000 samples by 1.4-2.3 mm, 500 by 4.5-6.7 mm, 200 by 29 mm, 100 by 88 mm;
#: arms trained in the free posture by 130 mm (pile driver) to 1,000 mm (GLT palletizer, 9-DOF
#: arm) whatever the sample count (10,000 or 40,000), as their maps average the several joint
#: solutions of one pose. The gate sits in the gap, with a margin of 200 for the paper's map.
DEFAULT_MAX_MEAN_POSITION_ERROR = 10.0
#: Largest |value| of a calibrated constant's bound (mm or rad).
MAX_BOUND = 1e7

PoseRow = Annotated[list[Coordinate], Field(min_length=4, max_length=4)]
ParameterName = Annotated[str, Field(min_length=1, max_length=100)]
Bound = Annotated[float, Field(ge=-MAX_BOUND, le=MAX_BOUND)]
Matrix4 = Annotated[list[Annotated[list[float], Field(min_length=4, max_length=4)]],
                    Field(min_length=4, max_length=4)]


class Measurement(Params):
    q: list[JointValue] = Field(min_length=1, max_length=MAX_DOF,
                                description="Joint values, rad / mm")
    pose: list[PoseRow] | None = Field(None, min_length=4, max_length=4,
                                       description="Measured tool pose 4x4, mm")
    position: Point3 | None = Field(None, description="Measured tool position, mm")

    @model_validator(mode="after")
    def _one_of(self) -> Measurement:
        if (self.pose is None) == (self.position is None):
            raise ValueError("give exactly one of 'pose' and 'position'")
        return self


class CalibrateParams(Params):
    robot: str = Field(max_length=200)
    measurements: list[Measurement] = Field(min_length=1, max_length=MAX_MEASUREMENTS)
    parameters: list[ParameterName] = Field(
        min_length=1, max_length=MAX_FITTED,
        description="Constants to fit, e.g. 'joints[1].a', 'joints[3].offset', 'base.z'",
    )
    bounds: Annotated[dict[ParameterName, tuple[Bound, Bound]],
                      Field(max_length=MAX_FITTED)] | None = Field(
        None, description="Optional [low, high] per parameter name (mm or rad)"
    )
    regularization: float = Field(0.0, ge=0, le=1e6,
                                  description="Pull towards the current values")
    seed: int = Field(0, ge=0, le=MAX_SEED)


class RobotJointData(Result):
    """A joint as in ``GET /robots/{id}/model``: D-H fields (``a``, ``alpha``, and ``d`` or
    ``theta``) or product-of-exponentials fields (``axis``, ``point``), by convention."""

    name: str
    type: Literal["revolute", "prismatic"]
    a: float | None = absent_when_none("mm (D-H)")
    alpha: float | None = absent_when_none("rad (D-H)")
    d: float | None = absent_when_none("mm (D-H, revolute joints)")
    theta: float | None = absent_when_none("rad (D-H, prismatic joints)")
    axis: XYZ | None = absent_when_none("Joint axis (product of exponentials)")
    point: XYZ | None = absent_when_none("A point on the axis, mm (product of "
                                         "exponentials, revolute joints)")
    offset: float
    lower: float
    upper: float
    velocity: float | None = absent_when_none("rad/s or mm/s")


class RobotModelData(Result):
    """A robot model as in ``GET /robots/{id}/model``; further model data (e.g.
    ``cylinders``) rides along as stored."""

    model_config = ConfigDict(extra="allow")

    id: str
    name: str
    convention: Literal["mdh", "sdh", "poe"]
    joints: list[RobotJointData]
    base: Matrix4
    tool: Matrix4
    home: Matrix4 | None = absent_when_none("Home pose (product of exponentials)")


class CalibrateResult(Result):
    """Fitted constants (mm or rad) by parameter name; null where not finite."""

    robot: str
    values: dict[str, float] = Field(description="Fitted value per parameter")
    initial: dict[str, float] = Field(description="Value in the model before the fit")
    std_errors: dict[str, float | None] = Field(
        description="Standard error per parameter (null: not determined by the data)")
    unidentified: list[str] = Field(description="Parameters the data do not determine")
    warnings: list[str]
    rms_position: float | None = Field(description="mm")
    rms_rotation: float | None = Field(description="rad (null without measured poses)")
    position_residuals: list[XYZ] = Field(description="Measured minus fitted position per "
                                          "measurement, mm")
    rotation_residuals: list[Annotated[list[float | None], Field(min_length=3,
                                                                 max_length=3)]] = Field(
        description="Rotation vector per measurement, rad (nulls for positions only)")
    success: bool
    message: str
    model: RobotModelData = Field(description="The fitted model")


def run_calibrate(params: CalibrateParams, progress: Progress) -> CalibrateResult:
    """Fit the named constants; the answer carries values, errors, residuals, warnings."""
    from kinematics.calibration import calibrate

    model = params.robot_model()
    progress(0.05, "fitting")
    measurements = [m.model_dump(exclude_none=True) for m in params.measurements]
    res = calibrate(model, measurements, params.parameters, bounds=params.bounds,
                    regularization=params.regularization, seed=params.seed)
    progress(1.0, "done")

    return CalibrateResult(
        robot=model.id,
        values=res.values,
        initial=res.initial,
        std_errors={k: finite_or_none(v) for k, v in res.std_errors.items()},
        unidentified=list(res.unidentified),
        warnings=list(res.warnings),
        rms_position=finite_or_none(res.rms_position),
        rms_rotation=finite_or_none(res.rms_rotation),
        position_residuals=res.position_residuals.tolist(),
        rotation_residuals=[[finite_or_none(v) for v in row] for row in res.rotation_residuals],
        success=bool(res.success),
        message=res.message,
        model=RobotModelData.model_validate(res.model.to_dict()),
    )


register(JobKind("calibrate", CalibrateParams, CalibrateResult, run_calibrate,
                 "Identify a model's constants from measured (q, pose/position) pairs",
                 needs_robot=True, max_params_bytes=MAX_CALIBRATE_PARAMS_BYTES))


class IKTrainParams(Params):
    robot: str = Field(max_length=200)
    samples: int = Field(10_000, ge=20, le=MAX_IK_SAMPLES, description="Monte Carlo samples")
    test_fraction: float = Field(0.12, gt=0, le=MAX_TEST_FRACTION,
                                 description="Held out for testing")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    posture: Literal["auto", "free", "drilling"] = Field(
        "auto",
        description="'drilling': the drill kept perpendicular to the face (paper 002); "
        "'auto': drilling for drilling arms, free otherwise",
    )
    fixed: Annotated[dict[Annotated[int, Field(ge=0, lt=MAX_DOF)], JointValue],
                     Field(max_length=MAX_DOF)] | None = Field(
        None, description="Joint index -> value held fixed (drilling arms: the feed d7)"
    )
    validation_samples: int = Field(
        VALIDATION_SAMPLES, ge=100, le=MAX_VALIDATION_SAMPLES,
        description="Held-out poses the trained map is validated on, drawn from a random "
        "stream of their own (seeded by seed), never trained on")
    max_mean_position_error: float = Field(
        DEFAULT_MAX_MEAN_POSITION_ERROR, gt=0, le=MAX_BOUND,
        description="Quality gate, mm: above this mean position error of the map alone on "
        "the validation poses the model fails (quality 'failed') and method 'learned' "
        "refuses to answer from it")


Posture = Literal["free", "drilling"]


class TrainingReport(Result):
    """Test-set errors of the learned map alone and after numeric polishing
    (``kinematics.learned_ik.TrainingReport``)."""

    samples: int
    train: int
    test: int
    max_relative_joint_error: float = Field(description="Fraction of a joint's range, worst "
                                            "joint")
    mean_relative_joint_error: float
    per_joint: list[float] = Field(description="Largest relative error per joint")
    max_position_error: float = Field(description="mm")
    mean_position_error: float = Field(description="mm")
    max_rotation_error: float = Field(description="rad")
    polished_max_position_error: float = Field(description="mm")
    polished_max_rotation_error: float = Field(description="rad")
    polished_success: float = Field(description="Fraction solved by the numeric polish")


class PaperFigures(Result):
    """Paper 002's figures for the tunnel drilling arm, to compare with."""

    max_relative_joint_error: float
    max_position_error: float = Field(description="mm")


class LearnedIKData(Result):
    """The learned map (``kinematics.learned_ik.LearnedIK.to_dict``): training features and
    targets, which joints are free, the values of the fixed ones and the joint limits."""

    robot_id: str
    features: list[list[float]]
    targets: list[list[float]]
    free: list[bool]
    fixed_values: list[float]
    lower: list[float]
    upper: list[float]
    posture: Posture


class IKValidation(Result):
    """The learned map alone (no numeric polish) on held-out poses drawn from a random
    stream of their own, and the gate it was held to
    (``kinematics.learned_ik.ValidationReport``)."""

    samples: int
    mean_position_error: float = Field(description="mm")
    p95_position_error: float = Field(description="mm, 95th percentile")
    max_position_error: float = Field(description="mm")
    mean_rotation_error: float = Field(description="rad")
    p95_rotation_error: float = Field(description="rad, 95th percentile")
    max_rotation_error: float = Field(description="rad")
    max_mean_position_error: float = Field(description="The gate, mm (the params')")


class IKTrainResult(Result):
    robot: str
    posture: Posture
    fixed: dict[int, float] = Field(description="Joint index -> value held fixed")
    report: TrainingReport
    paper: PaperFigures
    validation: IKValidation
    quality: Literal["ok", "failed"] = Field(
        description="'failed': the validation's mean position error is above "
        "max_mean_position_error, and method 'learned' refuses to answer from this model")
    message: str = Field(description="The validation's verdict in words")
    learned: LearnedIKData


def _mm(value: float) -> str:
    return f"{value:,.0f} mm" if value >= 100 else f"{value:.3g} mm"


def _verdict(validation: IKValidation, posture: str) -> tuple[str, str]:
    """``(quality, message)`` of a validation against its gate."""
    mean, gate = validation.mean_position_error, validation.max_mean_position_error
    poses = f"on {validation.samples:,} held-out poses"
    if mean <= gate:
        return "ok", f"mean position error {_mm(mean)} ≤ {_mm(gate)} {poses}"
    hint = ""
    if posture == "free":
        hint = (" (a map trained in the free posture averages the joint solutions that share "
                "a pose: an arm with several may not pass at any sample count; a larger "
                "max_mean_position_error serves its guesses as mere starting points)")
    return "failed", (f"mean position error {_mm(mean)} > {_mm(gate)} "
                      f"(max_mean_position_error) {poses}; train again with more samples"
                      f"{hint}")


def run_ik_train(params: IKTrainParams, progress: Progress) -> IKTrainResult:
    """Train the learned IK; the answer carries the test errors and the model's data."""
    from kinematics.drilling import DRILL_D7, check_drilling_structure
    from kinematics.learned_ik import train_learned_ik, validate_learned_ik

    model = params.robot_model()
    posture = params.posture
    fixed = {int(k): float(v) for k, v in (params.fixed or {}).items()}
    drilling = True
    try:
        check_drilling_structure(model)
    except ValueError:
        drilling = False
    if posture == "auto":
        posture = "drilling" if drilling else "free"
    if posture == "drilling" and not fixed:
        fixed = {6: DRILL_D7}
    learned, report = train_learned_ik(model, params.samples, params.test_fraction,
                                       params.seed, fixed=fixed, posture=posture,
                                       progress=lambda f, m: progress(0.9 * f, m))
    progress(0.9, "validating on held-out poses")
    validation = IKValidation(
        **validate_learned_ik(model, learned, params.validation_samples, params.seed,
                              fixed=fixed).to_dict(),
        max_mean_position_error=params.max_mean_position_error)
    quality, message = _verdict(validation, posture)
    progress(1.0, "done")
    return IKTrainResult(
        robot=model.id, posture=posture, fixed=fixed,
        report=TrainingReport(**pick(TrainingReport, report.to_dict())),
        paper=PaperFigures(max_relative_joint_error=0.0062, max_position_error=2.94),
        validation=validation, quality=quality, message=message,
        learned=LearnedIKData(**pick(LearnedIKData, learned.to_dict())))


#: The kind whose latest succeeded job per robot serves ``/ik`` method 'learned'
#: (``JobManager.learned_ik``); retention keeps that job.
IK_TRAIN = register(JobKind("ik_train", IKTrainParams, IKTrainResult, run_ik_train,
                            "Train and validate the learned (RBF) IK; if it passes its quality "
                            "gate, method 'learned' works on /ik",
                            needs_robot=True, keep_latest=True))


class LearnedIKRefused(RuntimeError):
    """The learned IK of a robot may not answer: its latest model failed its validation
    (or was trained before ``ik_train`` validated its models)."""


def served_learned_ik(robot_id: str, job_id: str, text: str):
    """The learned IK (``kinematics.learned_ik.LearnedIK``) in ``text``, the result of
    ``ik_train`` job ``job_id``; ``LearnedIKRefused``, saying why, unless it passed its
    quality gate."""
    from kinematics.learned_ik import LearnedIK

    data = json.loads(text)
    whose = f"the learned IK of robot '{robot_id}' (ik_train job {job_id})"
    if "quality" not in data:  # stored by a service that did not validate its models
        raise LearnedIKRefused(f"{whose} was trained without validation; train it again")
    result = IKTrainResult.model_validate(data)
    if result.quality != "ok":
        raise LearnedIKRefused(f"{whose} failed its validation: {result.message}")
    return LearnedIK.from_dict(result.learned.model_dump())
