"""``diagnose_limits``: for a configuration outside the joint limits, what each joint at fault
asks of the cylinders driving it (out of stroke, past the joint stop, past a dead point, a
linkage that cannot close), as data."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import kinematics
from kinematics.cylinders import (
    CylinderError,
    CylinderLimit,
    JointLimit,
    LimitCause,
    cylinder_set,
    diagnose_limits,
)
from kinematics.library import builtin_model
from kinematics.model import RobotModel

MODEL = builtin_model("pile_driver")
CYL = cylinder_set(MODEL)
INDEX = {j.name: i for i, j in enumerate(MODEL.joints)}


def _with(q_changes: dict[str, float]) -> np.ndarray:
    q = MODEL.mid_configuration().copy()
    for name, value in q_changes.items():
        q[INDEX[name]] = value
    return q


def _model_with(edit) -> RobotModel:
    data = MODEL.to_dict()
    data["cylinders"] = copy.deepcopy(MODEL.extras["cylinders"])
    edit(data["cylinders"])
    return RobotModel.from_dict(data)


def test_a_configuration_within_the_limits_has_nothing_to_say():
    assert diagnose_limits(MODEL, MODEL.mid_configuration()) == ()
    assert diagnose_limits(MODEL, MODEL.upper) == ()  # at the limits is within them


def test_out_of_stroke_on_both_sides_names_the_lengths():
    """Stroke ends are the joint limits on pile_driver: past a limit the cylinder would have
    to be shorter than retracted or longer than extended (the swing pair: one each)."""
    q = _with({"stick": math.radians(10.0), "tilt": math.radians(-40.0)})
    stick, tilt = diagnose_limits(MODEL, q)
    assert (stick.joint, stick.name) == (INDEX["stick"], "stick")
    assert stick.value == pytest.approx(math.radians(10.0))
    assert (stick.lower, stick.upper) == (MODEL.joints[INDEX["stick"]].lower, 0.0)
    lengths = CYL.lengths(q)
    (c,) = stick.cylinders
    lo, hi = CYL.limits("stick")
    assert c == CylinderLimit("stick", c.cause, float(lengths["stick"]), lo, hi)
    assert c.cause is (LimitCause.BEYOND_STROKE if c.length > hi else LimitCause.BELOW_STROKE)
    assert not lo <= c.length <= hi
    assert [x.name for x in tilt.cylinders] == ["swing_left", "swing_right"]
    causes = {x.name: x.cause for x in tilt.cylinders}
    assert set(causes.values()) == {LimitCause.BELOW_STROKE, LimitCause.BEYOND_STROKE}
    for x in tilt.cylinders:
        below = x.length < x.min_length
        assert x.cause is (LimitCause.BELOW_STROKE if below else LimitCause.BEYOND_STROKE)


def test_a_motor_driven_joint_has_no_cylinders():
    (d,) = diagnose_limits(MODEL, _with({"swing": 4.0}))
    assert d == JointLimit(INDEX["swing"], "swing", 4.0, -math.pi, math.pi, ())


def test_a_stroke_longer_than_the_joint_range_leaves_only_the_joint_stop():
    """With 20 mm of stroke beyond what the boom's range needs, a boom angle just past its
    limit is a length the cylinder can take, and that length gives the angle back."""
    lo, hi = CYL.limits("boom")
    upper = MODEL.joints[INDEX["boom"]].upper
    at_upper = float(CYL.lengths(_with({"boom": upper}))["boom"])
    end, more = ("max_length", 20.0) if abs(at_upper - hi) < abs(at_upper - lo) else \
        ("min_length", -20.0)

    def widen(cyl):
        cyl[0][end] += more

    model = _model_with(widen)
    q = _with({"boom": upper + 0.01})
    (d,) = diagnose_limits(model, q)
    (c,) = d.cylinders
    assert c.cause is LimitCause.JOINT_STOP and c.min_length <= c.length <= c.max_length


def test_past_the_dead_point_no_length_gives_the_angle():
    """The stick's pin angle phi = phi0 + theta reflected through 180 deg gives the length of
    an angle inside the range: within the stroke, but it maps back to that other angle."""
    stick = next(m for m in CYL.mechanisms if m.name == "stick")
    inside = math.radians(-30.0)
    beyond = 2 * math.pi - 2 * stick.phi0 - inside  # phi(beyond) = 360 deg - phi(inside)
    q = _with({"stick": beyond})
    (d,) = diagnose_limits(MODEL, q)
    (c,) = d.cylinders
    assert c.cause is LimitCause.DEAD_POINT
    assert c.length == pytest.approx(float(stick.length(inside)), rel=1e-12)


def test_a_linkage_that_cannot_close_has_no_length():
    def short_coupler(cyl):
        cyl[2]["l_km"] = 10.0

    model = _model_with(short_coupler)
    (d,) = diagnose_limits(model, _with({"four_bar": 0.2}))
    (c,) = d.cylinders
    assert d.name == "four_bar" and c.cause is LimitCause.CANNOT_CLOSE
    assert math.isnan(c.length)


def test_bad_input_names_q_and_the_function_is_public():
    with pytest.raises(CylinderError) as err:
        diagnose_limits(MODEL, np.zeros(4))
    assert err.value.field == "q"
    with pytest.raises(CylinderError):
        diagnose_limits(MODEL, np.zeros((2, MODEL.dof)))
    assert kinematics.diagnose_limits is diagnose_limits
