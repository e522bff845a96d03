"""Kinematic calibration: recovers perturbed constants within their standard errors, reports
what the data cannot determine, validates its input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinematics.calibration import calibrate, get_parameters, set_parameters
from kinematics.fk import fk
from kinematics.library import builtin_model

GLT = builtin_model("glt_palletizer")
#: The perturbation to recover (mm, rad).
DELTA = {
    "joints[1].a": 3.0,
    "joints[3].d": -5.0,
    "joints[2].a": 2.0,
    "joints[4].offset": 0.01,
    "base.z": 4.0,
}
SIGMA_POSITION = 0.05  # mm, per axis
SIGMA_ROTATION = 1e-4  # rad, per axis
N_POSES = 40


def _truth() -> dict[str, float]:
    nominal = get_parameters(GLT, list(DELTA))
    return {k: nominal[k] + v for k, v in DELTA.items()}


def _measured(seed: int = 1, position_only: bool = False) -> list[dict]:
    """N_POSES random in-limit configurations, FK of the perturbed arm plus seeded noise."""
    true_model = set_parameters(GLT, _truth())
    rng = np.random.default_rng(seed)
    q = rng.uniform(GLT.lower, GLT.upper, (N_POSES, GLT.dof))
    T = fk(true_model, q)
    T[:, :3, 3] += rng.normal(0.0, SIGMA_POSITION, (N_POSES, 3))
    noise = Rotation.from_rotvec(rng.normal(0.0, SIGMA_ROTATION, (N_POSES, 3))).as_matrix()
    T[:, :3, :3] = noise @ T[:, :3, :3]
    if position_only:
        return [{"q": qk, "position": Tk[:3, 3]} for qk, Tk in zip(q, T)]
    return [{"q": qk, "pose": Tk} for qk, Tk in zip(q, T)]


def _assert_recovered(res, names, abs_length=0.05, abs_angle=1e-4):
    truth = _truth()
    for name in names:
        err = abs(res.values[name] - truth[name])
        se = res.std_errors[name]
        assert np.isfinite(se) and se > 0, name
        assert err < 4 * se, (name, err, se)
        assert err < (abs_angle if name.endswith("offset") else abs_length), (name, err)


def test_recovers_perturbed_constants_from_noisy_poses():
    res = calibrate(GLT, _measured(), list(DELTA),
                    rotation_weight=SIGMA_POSITION / SIGMA_ROTATION)
    assert res.success and res.warnings == () and res.unidentified == ()
    assert res.rank == len(DELTA)
    _assert_recovered(res, DELTA)
    # Residuals at the noise level: 3-D position error ~ sqrt(3) sigma, and the a-posteriori
    # scale ~ sigma (rotation weighted to the same scale).
    n_res, p = 6 * N_POSES, len(DELTA)
    expected = math.sqrt(3) * SIGMA_POSITION * math.sqrt((n_res - p) / n_res)
    assert 0.75 < res.rms_position / expected < 1.25
    assert 0.75 < res.rms_rotation / (math.sqrt(3) * SIGMA_ROTATION) < 1.25
    assert 0.8 < res.sigma / SIGMA_POSITION < 1.2
    assert res.position_residuals.shape == (N_POSES, 3)
    assert res.rotation_residuals.shape == (N_POSES, 3)
    np.testing.assert_allclose(res.position_errors,
                               np.linalg.norm(res.position_residuals, axis=1))
    # The fitted model is a validated model whose FK matches the truth away from the data.
    q = np.random.default_rng(99).uniform(GLT.lower, GLT.upper, (20, GLT.dof))
    dp = np.linalg.norm(fk(res.model, q)[:, :3, 3] - fk(set_parameters(GLT, _truth()), q)[
        :, :3, 3], axis=1)
    assert dp.max() < 0.1
    assert res.model.id == GLT.id and res.model.to_dict()["notes"] == GLT.to_dict()["notes"]
    # Covariance is symmetric with the standard errors on its diagonal.
    np.testing.assert_allclose(res.covariance, res.covariance.T, rtol=1e-9, atol=1e-18)
    np.testing.assert_allclose(np.sqrt(np.diag(res.covariance)), list(res.std_errors.values()))


def test_position_only_measurements_also_work():
    res = calibrate(GLT, _measured(seed=2, position_only=True), list(DELTA))
    assert res.success and res.warnings == ()
    assert np.all(np.isnan(res.rotation_residuals)) and math.isnan(res.rms_rotation)
    _assert_recovered(res, DELTA, abs_angle=3e-4)
    expected = math.sqrt(3) * SIGMA_POSITION
    assert 0.75 < res.rms_position / expected < 1.25


def test_sum_only_parameters_are_reported_not_returned_as_identified():
    """GLT's first axis is vertical: joints[0].d and base.z move the arm along the same line,
    so the data fix only their combination."""
    names = [*DELTA, "joints[0].d"]
    res = calibrate(GLT, _measured(), names, rotation_weight=500.0)
    assert set(res.unidentified) == {"base.z", "joints[0].d"}
    assert res.rank == len(names) - 1
    (warning,) = res.warnings
    assert "base.z" in warning and "joints[0].d" in warning and "not identifiable" in warning
    assert math.isnan(res.std_errors["base.z"]) and math.isnan(res.std_errors["joints[0].d"])
    assert np.all(np.isnan(res.covariance[-1])) and np.all(np.isnan(res.covariance[:, -1]))
    # Everything else is still recovered, and so is the combination: joints[0] has
    # alpha = pi, so its d points down and base.z - d is what the data see.
    _assert_recovered(res, [n for n in DELTA if n != "base.z"])
    combo = res.values["base.z"] - res.values["joints[0].d"]
    assert abs(combo - _truth()["base.z"]) < 0.05
    # Without a regulariser the invisible direction stays where it started (the smallest
    # change that fits): the 4 mm are shared, the sum base.z + d keeps its nominal value.
    start_sum = GLT.base[2, 3] + GLT.joints[0].d
    assert abs(res.values["base.z"] + res.values["joints[0].d"] - start_sum) < 1e-6


def test_regulariser_picks_the_minimum_norm_split():
    names = ["base.z", "joints[0].d", "joints[1].a"]
    res = calibrate(GLT, _measured(), names, rotation_weight=500.0, regularization=1e-2)
    assert set(res.unidentified) == {"base.z", "joints[0].d"}
    assert "regulariser" in res.warnings[0]
    combo = res.values["base.z"] - res.values["joints[0].d"]
    # Minimum norm subject to base.z - d = combo: base.z = -d = combo / 2. The other
    # constants are biased by the perturbations left out of the fit, hence the loose check.
    assert res.values["base.z"] == pytest.approx(combo / 2, abs=1e-3)
    assert res.values["joints[0].d"] == pytest.approx(-combo / 2, abs=1e-3)


def test_parameter_without_effect_is_reported():
    """The tool point lies on the flange's roll axis, so its position ignores that offset."""
    res = calibrate(GLT, _measured(position_only=True), ["joints[1].a", "joints[5].offset"])
    assert res.unidentified == ("joints[5].offset",)
    assert "joints[5].offset is not identifiable" in res.warnings[0]
    assert res.values["joints[5].offset"] == GLT.joints[5].offset


def test_bounds_multistart_and_seed_are_reproducible():
    bounds = {"joints[1].a": (140.0, 160.0), "joints[4].offset": (3.0, 3.3)}
    a = calibrate(GLT, _measured(), list(DELTA), bounds=bounds, starts=3, seed=7,
                  rotation_weight=500.0)
    b = calibrate(GLT, _measured(), list(DELTA), bounds=bounds, starts=3, seed=7,
                  rotation_weight=500.0)
    assert a.starts == 3 and a.values == b.values
    _assert_recovered(a, DELTA)
    # A single far start (x0) still converges: lengths enter almost linearly.
    far = calibrate(GLT, _measured(), list(DELTA), x0={"joints[2].a": 700.0, "base.z": 300.0},
                    rotation_weight=500.0)
    assert far.starts == 1
    _assert_recovered(far, DELTA)


def test_bound_that_excludes_the_truth_is_warned():
    res = calibrate(GLT, _measured(), list(DELTA), bounds={"joints[3].d": (-860.0, -850.0)},
                    rotation_weight=500.0)
    assert res.values["joints[3].d"] == pytest.approx(-860.0)
    assert any("joints[3].d stopped at a bound" in w for w in res.warnings)


def test_set_and_get_parameters():
    model = set_parameters(GLT, {"joints[2].a": 800.0, "tool.x": 5.0})
    assert model.joints[2].a == 800.0 and model.tool[0, 3] == 5.0
    assert GLT.joints[2].a == 790.385  # the input is untouched
    assert get_parameters(model, ["joints[2].a", "tool.x"]) == {
        "joints[2].a": 800.0, "tool.x": 5.0}
    with pytest.raises(ValueError, match="joints\\[2\\].a"):
        set_parameters(GLT, {"joints[2].a": math.nan})


def _one(q=None, **kw):
    m = {"q": np.zeros(6) if q is None else q}
    m.update(kw or {"position": [1.0, 2.0, 3.0]})
    return m


@pytest.mark.parametrize(
    "measurements, parameters, kwargs, field",
    [
        ([_one()] * 3, ["joints[9].a"], {}, "parameters[0]"),
        ([_one()] * 3, ["joint[0].a"], {}, "parameters[0]"),
        ([_one()] * 3, ["base.rx"], {}, "parameters[0]"),
        ([_one()] * 3, ["base.x", "base.x"], {}, "parameters[1]"),
        ([_one()] * 3, ["joints[0].theta"], {}, "parameters[0]"),
        ([_one()] * 3, [], {}, "parameters"),
        ([_one(), _one(q=np.zeros(5))], ["base.x"], {}, "measurements[1].q"),
        ([_one(position=[1.0, math.nan, 0.0])], ["base.x"], {}, "measurements[0].position"),
        ([_one(q=[0, 0, math.nan, 0, 0, 0])], ["base.x"], {}, "measurements[0].q"),
        ([_one(pose=np.eye(4) * 2)], ["base.x"], {}, "measurements[0].pose"),
        ([_one(pose=np.eye(4), position=[0, 0, 0])], ["base.x"], {}, "measurements[0]"),
        ([_one(colour="red")], ["base.x"], {}, "measurements[0].colour"),
        ([_one()], ["base.x", "base.y", "base.z", "tool.x"], {}, "measurements"),
        ([], ["base.x"], {}, "measurements"),
        ([_one()], ["base.x"], {"bounds": {"base.y": (0, 1)}}, "bounds['base.y']"),
        ([_one()], ["base.x"], {"bounds": {"base.x": (1, 0)}}, "bounds['base.x']"),
        ([_one()], ["base.x"], {"x0": {"base.x": math.inf}}, "x0['base.x']"),
        ([_one()], ["base.x"], {"rotation_weight": -1.0}, "rotation_weight"),
        ([_one()], ["base.x"], {"loss": "l2"}, "loss"),
        ([_one()], ["base.x"], {"regularization": -1.0}, "regularization"),
    ],
)
def test_invalid_input_names_the_field(measurements, parameters, kwargs, field):
    with pytest.raises(ValueError) as err:
        calibrate(GLT, measurements, parameters, **kwargs)
    assert str(err.value).startswith(field), str(err.value)


def test_joint_variable_is_not_a_constant():
    arm = builtin_model("tunnel_drill_arm")
    with pytest.raises(ValueError, match=r"parameters\[0\].*joint variable.*telescope"):
        calibrate(arm, [{"q": np.zeros(7), "position": [0, 0, 0]}], ["joints[2].d"])
    poe = builtin_model("hyper_redundant_9dof")
    with pytest.raises(ValueError, match="product-of-exponentials"):
        calibrate(poe, [{"q": np.zeros(9), "position": [0, 0, 0]}], ["joints[0].a"])
