"""Job kinds that work on a robot model itself: calibration and learned-IK training."""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, model_validator

from .kinds import JobKind, Params, Progress, register

__all__ = ["CalibrateParams", "IKTrainParams"]

#: Most measurements one calibration takes.
MAX_MEASUREMENTS = 10_000


class Measurement(Params):
    q: list[float] = Field(description="Joint values, rad / mm")
    pose: list[list[float]] | None = Field(None, description="Measured tool pose 4x4, mm")
    position: list[float] | None = Field(None, min_length=3, max_length=3,
                                         description="Measured tool position, mm")

    @model_validator(mode="after")
    def _one_of(self) -> Measurement:
        if (self.pose is None) == (self.position is None):
            raise ValueError("give exactly one of 'pose' and 'position'")
        return self


class CalibrateParams(Params):
    robot: str
    measurements: list[Measurement] = Field(min_length=1, max_length=MAX_MEASUREMENTS)
    parameters: list[str] = Field(
        min_length=1, max_length=200,
        description="Constants to fit, e.g. 'joints[1].a', 'joints[3].offset', 'base.z'",
    )
    bounds: dict[str, tuple[float, float]] | None = Field(
        None, description="Optional [low, high] per parameter name"
    )
    regularization: float = Field(0.0, ge=0, description="Pull towards the current values")
    seed: int = Field(0, ge=0)


def run_calibrate(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Fit the named constants; the answer carries values, errors, residuals, warnings."""
    from kinematics.calibration import calibrate
    from kinematics.model import RobotModel

    model = RobotModel.from_dict(params["_model"])
    progress(0.05, "fitting")
    measurements = [{k: v for k, v in m.items() if v is not None}
                    for m in params["measurements"]]
    res = calibrate(model, measurements, params["parameters"], bounds=params["bounds"],
                    regularization=params["regularization"], seed=params["seed"])
    progress(1.0, "done")

    def finite(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {
        "robot": model.id,
        "values": res.values,
        "initial": res.initial,
        "std_errors": {k: finite(v) for k, v in res.std_errors.items()},
        "unidentified": list(res.unidentified),
        "warnings": list(res.warnings),
        "rms_position": finite(res.rms_position),
        "rms_rotation": finite(res.rms_rotation),
        "position_residuals": res.position_residuals.tolist(),
        "rotation_residuals": [[finite(v) for v in row] for row in res.rotation_residuals],
        "success": bool(res.success),
        "message": res.message,
        "model": res.model.to_dict(),
    }


register(JobKind("calibrate", CalibrateParams, run_calibrate,
                 "Identify a model's constants from measured (q, pose/position) pairs",
                 needs_robot=True))


class IKTrainParams(Params):
    robot: str
    samples: int = Field(10_000, ge=20, le=200_000, description="Monte Carlo samples")
    test_fraction: float = Field(0.12, gt=0, lt=1, description="Held out for testing")
    seed: int = Field(0, ge=0)
    posture: Literal["auto", "free", "drilling"] = Field(
        "auto",
        description="'drilling': the drill kept perpendicular to the face (paper 002); "
        "'auto': drilling for drilling arms, free otherwise",
    )
    fixed: dict[int, float] | None = Field(
        None, description="Joint index -> value held fixed (drilling arms: the feed d7)"
    )


def run_ik_train(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Train the learned IK; the answer carries the test errors and the model's data."""
    from kinematics.drilling import DRILL_D7, check_drilling_structure
    from kinematics.learned_ik import train_learned_ik
    from kinematics.model import RobotModel

    model = RobotModel.from_dict(params["_model"])
    posture = params["posture"]
    fixed = {int(k): float(v) for k, v in (params["fixed"] or {}).items()}
    drilling = True
    try:
        check_drilling_structure(model)
    except ValueError:
        drilling = False
    if posture == "auto":
        posture = "drilling" if drilling else "free"
    if posture == "drilling" and not fixed:
        fixed = {6: DRILL_D7}
    learned, report = train_learned_ik(model, params["samples"], params["test_fraction"],
                                       params["seed"], fixed=fixed, posture=posture,
                                       progress=progress)
    return {"robot": model.id, "posture": posture, "fixed": fixed,
            "report": report.to_dict(),
            "paper": {"max_relative_joint_error": 0.0062, "max_position_error": 2.94},
            "learned": learned.to_dict()}


register(JobKind("ik_train", IKTrainParams, run_ik_train,
                 "Train the learned (RBF) IK; then method 'learned' works on /ik",
                 needs_robot=True))
