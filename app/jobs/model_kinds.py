"""Job kinds that work on a robot model itself: calibration and learned-IK training."""

from __future__ import annotations

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
           "RobotModelData"]

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


class IKTrainResult(Result):
    robot: str
    posture: Posture
    fixed: dict[int, float] = Field(description="Joint index -> value held fixed")
    report: TrainingReport
    paper: PaperFigures
    learned: LearnedIKData


def run_ik_train(params: IKTrainParams, progress: Progress) -> IKTrainResult:
    """Train the learned IK; the answer carries the test errors and the model's data."""
    from kinematics.drilling import DRILL_D7, check_drilling_structure
    from kinematics.learned_ik import train_learned_ik

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
                                       progress=progress)
    return IKTrainResult(
        robot=model.id, posture=posture, fixed=fixed,
        report=TrainingReport(**pick(TrainingReport, report.to_dict())),
        paper=PaperFigures(max_relative_joint_error=0.0062, max_position_error=2.94),
        learned=LearnedIKData(**pick(LearnedIKData, learned.to_dict())))


register(JobKind("ik_train", IKTrainParams, IKTrainResult, run_ik_train,
                 "Train the learned (RBF) IK; then method 'learned' works on /ik",
                 needs_robot=True))
