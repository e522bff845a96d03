"""A robot model's cylinder mechanisms are checked over their joints' ranges when the model
comes in (POST /robots), and /trajectories never answers 500 for a robot stored before.

The pile driver's four-bar (cylinders[2]) with its rocker L_MN cut from 110 mm cannot close
over the four_bar joint's range: its cylinder lengths, speeds and pump flow are NaN there."""

from __future__ import annotations

import copy

import pytest

from app.api.routes.trajectories import _plan_answer
from app.api.trajectory_schemas import TrajectoryRequest
from kinematics.cylinders import CylinderError, CylinderSet
from kinematics.errors import FieldError
from kinematics.library import builtin_model, builtin_models
from kinematics.model import RobotModel

PILE = builtin_model("pile_driver").to_dict()
#: Boom and stick raised together (the pump binds), the four_bar joint at -0.5 rad.
MOVE = {"waypoints": [[0.0, 0.1, -0.9, -0.5, 0.0, 0.0], [0.0, 0.9, -0.1, -0.5, 0.0, 0.0]],
        "time_scaling": "optimal", "limits": {"acceleration": 5.0}, "dt": 0.1}


def _pile(robot_id: str, **four_bar) -> dict:
    data = copy.deepcopy(PILE)
    data["id"] = robot_id
    data["cylinders"][2].update(four_bar)
    return data


@pytest.mark.parametrize("l_mn", [10, 1, 0.001])
def test_a_four_bar_that_cannot_close_is_422_naming_the_field(client, l_mn):
    r = client.post("/robots", json=_pile("pd_short_rocker", l_mn=l_mn))
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "cylinders", 2, "l_mn"]
    msg = err["msg"]
    assert msg.startswith("cylinder 2 ('four_bar'): ")
    assert "cannot close" in msg and "joint 'four_bar' (q[3])" in msg
    assert f"l_mn = {l_mn:g} is the field most likely at fault" in msg
    # Not stored: the id is free.
    assert client.get("/robots/pd_short_rocker").status_code == 404


@pytest.mark.slow
def test_the_unmodified_copy_is_stored_and_times_optimally(client):
    r = client.post("/robots", json=_pile("pd_copy"))
    assert r.status_code == 201, r.text
    r = client.post("/trajectories", json=MOVE | {"robot": "pd_copy"})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["limits"]["ok"] and 1.0 < body["duration"] < 2.0
    assert body["hydraulics"]["pump"]["peak_flow"] == pytest.approx(40.0, rel=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("path, extra", [
    ("/trajectories", {}),
    ("/trajectories", {"time_scaling": "none", "durations": [2.0]}),
    ("/trajectories/plot", {}),
])
def test_a_bad_robot_already_stored_is_409_not_500(client, path, extra):
    # Stored as a robot of an older service was, past the check POST /robots makes now.
    client.app.state.registry.add(RobotModel.from_dict(_pile("pd_stored", l_mn=10)))
    r = client.post(path, json=MOVE | extra | {"robot": "pd_stored"})
    assert r.status_code == 409, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "robot"]
    assert "robot 'pd_stored' has invalid cylinder data: cylinders[2].l_mn: " in err["msg"]


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_a_non_finite_answer_is_a_field_error_not_a_crash():
    # Past the route's check too: a NaN in the answer (the pump's flow through the four-bar)
    # is named, not left to the JSON encoder to fail on.
    robot = RobotModel.from_dict(_pile("pd_unchecked", l_mn=10))
    with pytest.raises(FieldError) as err:
        _plan_answer(TrajectoryRequest.model_validate(MOVE | {"robot": robot.id}), robot)
    assert err.value.loc == ("robot",)
    assert "the answer's hydraulics." in err.value.message
    assert "came out nan" in err.value.message


def test_every_builtin_robot_with_cylinders_passes():
    checked = [m.id for m in builtin_models().values() if "cylinders" in m.extras]
    assert checked == ["pile_driver"]
    for robot_id in checked:
        CylinderSet.from_model(builtin_model(robot_id)).check_mechanisms()


def _fault(data: dict) -> CylinderError:
    with pytest.raises(CylinderError) as err:
        CylinderSet.from_model(RobotModel.from_dict(data)).check_mechanisms()
    return err.value


@pytest.mark.parametrize("bar, value", [
    ("l_kh", 200.0), ("l_hn", 400.0), ("l_mn", 1000.0), ("l_km", 10.0), ("l_km", 1000.0)])
def test_the_bar_out_of_proportion_is_blamed(bar, value):
    err = _fault(_pile("pd", **{bar: value}))
    assert err.loc == ("cylinders", 2, bar)
    assert "the linkage cannot close" in err.message
    # What would close it, and it does (a closed linkage may still pass a dead point).
    cure = float(err.message.rsplit("is about ", 1)[1].split(" mm")[0])
    four_bar = CylinderSet.from_model(RobotModel.from_dict(_pile("pd", **{bar: cure})))
    fault = four_bar.mechanisms[2].fault()
    assert fault is None or "cannot close" not in fault.reason


def test_where_in_the_range_it_fails():
    # L_KN grows from 129.5 mm at -60 deg to 187.2 mm at 0: an L_MN + L_KM of 130 mm
    # spans it only near the lower limit.
    err = _fault(_pile("pd", l_mn=10))
    assert "from -1.03987 to 0 rad of the joint's range [-1.0472, 0] rad" in err.message


def test_a_dead_point_of_a_swing_cylinder_names_its_side():
    data = copy.deepcopy(PILE)
    data["cylinders"][3]["left"]["phi0"] = 2.9  # pin angle 196 -> 136 deg: through 180
    err = _fault(data)
    assert err.loc == ("cylinders", 3, "left", "phi0")
    assert err.message.startswith("cylinder 3 ('swing_left'): ") and "dead point" in err.message
